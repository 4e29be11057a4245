"""Small falls of a mastered module's competence (C3's mechanism at any size): where they come,
how the module's p_LP and practice share move after each against the same module's windows
without a fall, and a test of that excess with the run as the unit.

The drops of `curious.analysis.drops` are the paper's event (a fall of 0.2 or more); none came in
any run of 100,000 episodes. The paper's mechanism, a falling competence raising the module's LP
and so its share of practice, can be read on smaller falls too. The rule, fixed in docs/results.md
(C3, "The long runs and the dips: rules fixed before their runs") before any run was read for
dips:

1. **Read from mastery.** A module's competence counts once it averages a full window of its
   self-evaluations, and is read from its first mastery (`MASTERED_COMPETENCE` held for
   `drops.MASTERY_HOLD` of a window, as `drops.mastery` finds it) to the run's end.
2. **Dip.** The *peak* is the highest competence since mastery, or since the last dip ended. A
   dip of depth d is *detected* at the first episode whose competence is d or more below the
   peak; it *ends* at the first later episode whose competence is back within d/2 of that peak
   (NA: not by the run's end), and the peak starts again from the competence there. Its
   *trough* is its lowest competence in between. Depths: `TEST_DEPTH` (0.1), tested, and 0.05.
3. **Response.** Over the `WINDOW` (5,000) episodes before the detection and the 5,000 from it:
   the change in the module's mean p_LP, mean absolute LP and share of training episodes that
   practised it. A dip whose windows reach before the mastery or past the run's end is not read
   (``status``).
4. **Matched windows.** The same module of the same run at every `WINDOW`-th episode from its
   mastery on whose two windows lie between the mastery and the run's end and meet no dip's
   *exclusion* (from `WINDOW` episodes before its detection to the later of its end and
   `WINDOW` after it). A dip's *excess* is its change minus the mean change over its module's
   matched windows (no excess where the module has none).
5. **Test** (`dip_test`). One number per run: its dips' mean excess; a one-sided exact sign-flip
   permutation test that the mean over runs is above 0 (every run's sign flipped in every
   combination: 2^n for n runs), since a run's dips share one agent and are not independent.
6. **One unit per seed** (`longest_per_seed`). Runs of one condition, variant, preset and seed
   are one run for as long as the shorter lasts (a `long` run retraces the `main` run of its
   seed episode for episode): a pool keeps the longest of them only.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from curious.agent.learning_progress import MASTERED_COMPETENCE
from curious.analysis.drops import (
    MASTERY_HOLD,
    _first,
    _mastered_from,
    achievable_series,
)
from curious.analysis.loading import AnalysisError, require_alpha, require_runs
from curious.analysis.statistics import ALPHA, FLOAT32_SLACK, RUN_COLUMNS

__all__ = [
    "DIP_COLUMNS",
    "DIP_DEPTHS",
    "DIP_WINDOW",
    "TEST_DEPTH",
    "dip_responses",
    "dip_test",
    "longest_per_seed",
    "mastery_dips",
    "shorter_of_seed",
]

TEST_DEPTH = 0.1
"""The dip depth whose excess `dip_test` decides on."""
DIP_DEPTHS: tuple[float, ...] = (TEST_DEPTH, 0.05)
"""The depths read, the tested one first."""
DIP_WINDOW = 5_000
"""Episodes on each side of a dip's detection (and of a matched window's centre): one window
of competence of a module practised a fifth of the time at `laptop` (100 self-evaluations at
one episode in ten)."""
MAX_EXACT_RUNS = 24
"""`dip_test` enumerates 2^n sign flips; above this many runs it refuses (16 million flips)."""
_FLIP_CHUNK = 2**16

DIP_COLUMNS: tuple[str, ...] = (
    *RUN_COLUMNS,
    "module",
    "depth",
    "mastered_episode",
    "peak",
    "detect_episode",
    "trough_episode",
    "trough",
    "end_episode",
    "status",
    "p_lp_change",
    "practice_change",
    "lp_change",
    "n_matched",
    "matched_p_lp_change",
    "matched_practice_change",
    "excess_p_lp",
    "excess_practice",
)
"""The columns of `dip_responses`: one row per dip. ``status``: ``read``, ``before_mastery``
(its first window reaches before the mastery), ``past_end`` (its second reaches past the run's
end) or ``unmatched`` (read, but its module has no matched window: no excess)."""


def _module_dips(
    competence: np.ndarray, start: int, depth: float
) -> list[tuple[int, int, int, float]]:
    """(detection, trough, end) rows and the peak of every dip of depth ``depth`` from row
    ``start`` (the mastery) on; end is len(competence) where the dip had not ended by the run's
    end."""
    n, found, at = len(competence), [], start
    while at < n:
        peak = np.fmax.accumulate(competence[at:])
        hit = _first(competence[at:] <= peak - depth + FLOAT32_SLACK)
        if hit is None:
            break
        detect = at + hit
        top = float(peak[hit])
        back = _first(competence >= top - depth / 2 - FLOAT32_SLACK, detect + 1)
        end = n if back is None else back
        trough = detect + int(np.nanargmin(competence[detect:end]))
        found.append((detect, trough, end, top))
        at = end
    return found


def _window_means(
    episodes: np.ndarray, sums: np.ndarray, starts: np.ndarray, stops: np.ndarray
) -> np.ndarray:
    """Mean of each column of the rows whose episode lies in [start, stop), per window, from the
    running sums (``sums``: a leading row of zeros, then cumulative per row)."""
    lo = np.searchsorted(episodes, starts, side="left")
    hi = np.searchsorted(episodes, stops, side="left")
    counts = np.maximum(hi - lo, 1)[:, None]
    return (sums[hi] - sums[lo]) / counts


def _changes(
    episodes: np.ndarray, sums: np.ndarray, centres: np.ndarray, window: int
) -> np.ndarray:
    """(after - before) of each running-sum column around each centre: (centres, columns)."""
    before = _window_means(episodes, sums, centres - window, centres)
    after = _window_means(episodes, sums, centres, centres + window)
    return after - before


def _read_module(
    episodes: np.ndarray,
    values: np.ndarray,
    evaluated: np.ndarray,
    window: int,
    depth: float,
    span: int,
) -> list[dict]:
    """One module of one run: its dips with their responses. ``values``
    holds competence, LP, p_LP and the practised flag per row, episodes ascending."""
    competence = np.where(np.cumsum(evaluated) >= window, values[:, 0], np.nan)
    hold = max(1, math.ceil(MASTERY_HOLD * window))
    m = _mastered_from(competence, evaluated, 0, MASTERED_COMPETENCE, hold)
    if m is None:
        return []
    mastered, end_of_run = int(episodes[m]), int(episodes[-1]) + 1
    found = _module_dips(competence, m, depth)
    # running sums of p_LP, practice and LP, for every window's mean at once
    columns = np.nan_to_num(values[:, [2, 3, 1]].astype(np.float64))
    sums = np.vstack([np.zeros((1, 3)), np.cumsum(columns, axis=0)])
    detect = np.array([episodes[d] for d, _, _, _ in found], dtype=np.int64)
    ends = np.array([episodes[e] if e < len(episodes) else end_of_run for _, _, e, _ in found])
    excluded = np.column_stack(
        [detect - span, np.maximum(ends, detect + span)] if found else [np.empty(0)] * 2
    )
    centres = np.arange(mastered + span, end_of_run - span + 1, span, dtype=np.int64)
    clear = ~(
        (centres[:, None] - span < excluded[None, :, 1])
        & (centres[:, None] + span > excluded[None, :, 0])
    ).any(axis=1)
    matched = _changes(episodes, sums, centres[clear], span)
    matched_mean = matched.mean(axis=0) if len(matched) else np.full(3, np.nan)
    changes = _changes(episodes, sums, detect, span) if found else np.empty((0, 3))
    rows = []
    for (_, t, e, top), episode, change in zip(found, detect, changes, strict=True):
        status = (
            "before_mastery"
            if episode - span < mastered
            else "past_end"
            if episode + span > end_of_run
            else "read"
            if len(matched)
            else "unmatched"
        )
        read = status == "read"
        rows.append(
            {
                "depth": depth,
                "mastered_episode": mastered,
                "peak": top,
                "detect_episode": int(episode),
                "trough_episode": int(episodes[t]),
                "trough": float(competence[t]),
                "end_episode": int(episodes[e]) if e < len(episodes) else None,
                "status": status,
                "p_lp_change": change[0] if status in ("read", "unmatched") else np.nan,
                "practice_change": change[1] if status in ("read", "unmatched") else np.nan,
                "lp_change": change[2] if status in ("read", "unmatched") else np.nan,
                "n_matched": len(matched),
                "matched_p_lp_change": matched_mean[0],
                "matched_practice_change": matched_mean[1],
                "excess_p_lp": change[0] - matched_mean[0] if read else np.nan,
                "excess_practice": change[1] - matched_mean[1] if read else np.nan,
            }
        )
    return rows


def dip_responses(
    df: pd.DataFrame, depth: float = TEST_DEPTH, window: int = DIP_WINDOW
) -> pd.DataFrame:
    """Every dip of depth ``depth`` of a mastered achievable module in the runs of ``df`` (a
    `load_runs` table), with its response and excess over matched windows of ``window``
    episodes (the module doc's rule). One row per dip with `DIP_COLUMNS`, by run, module and
    episode; HER's runs (no competence) and modules never mastered have none. Runs whose
    sensory failure started are perturbed on purpose: leave them out."""
    require_runs(df)
    if not 0 < depth < 1:
        raise ValueError(f"depth must be in (0, 1), got {depth}")
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise ValueError(f"window must be a number of episodes >= 1, got {window!r}")
    rows: list[dict] = []
    for series in achievable_series(df):
        found = _read_module(
            series.episodes, series.values, series.evaluated, series.window, depth, int(window)
        )
        rows += [{**series.identity, "module": series.module, **dip} for dip in found]
    out = pd.DataFrame(rows, columns=list(DIP_COLUMNS))
    for c in ("mastered_episode", "detect_episode", "trough_episode", "end_episode"):
        out[c] = out[c].astype("Int64")
    out["n_matched"] = out["n_matched"].astype(np.int64)
    return out


def mastery_dips(df: pd.DataFrame, depth: float = TEST_DEPTH) -> pd.DataFrame:
    """Where each dip of depth ``depth`` came (`dip_responses` without the responses)."""
    columns = [*RUN_COLUMNS, "module", "depth", "mastered_episode", "peak", "detect_episode"]
    columns += ["trough_episode", "trough", "end_episode"]
    return dip_responses(df, depth)[columns]


def dip_test(
    responses: pd.DataFrame, column: str = "excess_p_lp", alpha: float = ALPHA
) -> dict[str, object]:
    """The excess of ``column`` over the runs of a `dip_responses` table: each run's mean over
    its read dips, and a one-sided exact sign-flip permutation test that their mean is above 0
    (the module doc, step 5). Returns a dict: ``column``, ``n_runs`` (runs with a read dip),
    ``n_dips`` (read dips), ``n_positive`` (runs whose mean excess is above 0), ``mean`` (over
    runs), ``p`` (NaN without a run), ``alpha``, ``significant`` and ``per_run`` (a Series, run
    -> mean excess)."""
    require_alpha(alpha)
    if column not in ("excess_p_lp", "excess_practice"):
        raise AnalysisError(f"dip_test reads excess_p_lp or excess_practice, got {column!r}")
    if column not in responses:
        raise AnalysisError("this table lacks the excess columns: pass a dip_responses table")
    read = responses.dropna(subset=[column])
    per_run = read.groupby(read["run"].astype(str), sort=True)[column].mean()
    n = len(per_run)
    if n > MAX_EXACT_RUNS:
        raise AnalysisError(
            f"{n} runs: the exact test enumerates 2^n sign flips; pass at most {MAX_EXACT_RUNS}"
        )
    values = per_run.to_numpy(np.float64)
    p = np.nan
    if n:  # sum of the flipped values = total - 2 x (the flipped ones), chunk by chunk
        total, as_high = values.sum(), 0
        for first in range(0, 2**n, _FLIP_CHUNK):
            codes = np.arange(first, min(first + _FLIP_CHUNK, 2**n))
            bits = ((codes[:, None] >> np.arange(n)) & 1).astype(np.float64)
            as_high += int(np.count_nonzero(total - 2 * (bits @ values) >= total - 1e-12))
        p = as_high / 2**n
    return {
        "column": column,
        "n_runs": n,
        "n_dips": len(read),
        "n_positive": int((values > 0).sum()),
        "mean": float(values.mean()) if n else np.nan,
        "p": p,
        "alpha": alpha,
        "significant": bool(p < alpha) if np.isfinite(p) else False,
        "per_run": per_run,
    }


SEED_KEY: tuple[str, ...] = ("condition", "variant", "preset", "seed")
"""What makes runs one run while the shorter lasts: the same agent, task and seed."""


def shorter_of_seed(df: pd.DataFrame) -> pd.DataFrame:
    """The runs of ``df`` (a `load_runs` table) that a longer run of the same `SEED_KEY`
    stands for (the module doc, step 6): one row per run left out, with ``run``, its
    ``episodes`` and the run kept for it (``kept``, ``kept_episodes``). Of runs of one key and
    one length, the first by name is kept."""
    require_runs(df)
    columns = ["run", "episodes", "kept", "kept_episodes"]
    lengths = df.groupby("run", observed=True, sort=False).agg(
        **{c: (c, "first") for c in SEED_KEY}, episodes=("episode", "max")
    )
    lengths = lengths.reset_index()
    lengths["run"] = lengths["run"].astype(str)
    lengths["episodes"] = lengths["episodes"].astype(np.int64) + 1
    lengths = lengths.sort_values(["episodes", "run"], ascending=[False, True], kind="stable")
    by_key = lengths.groupby(list(SEED_KEY), observed=True, sort=False, dropna=False)
    first = by_key[["run", "episodes"]].transform("first")
    lengths["kept"], lengths["kept_episodes"] = first["run"], first["episodes"]
    left = lengths[lengths["run"] != lengths["kept"]]
    return left[columns].sort_values("run", kind="stable").reset_index(drop=True)


def longest_per_seed(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` without the runs `shorter_of_seed` names: one run per condition, variant, preset
    and seed, the longest, for a test whose unit is a run."""
    left_out = set(shorter_of_seed(df)["run"])
    return df[~df["run"].astype(str).isin(left_out)]
