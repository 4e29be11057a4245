"""Spontaneous forgetting (the paper's Fig. 2b/2c, claim C3): drops of a mastered module's
competence with nothing perturbed, the learning progress they raise, and the practice they draw.

The paper (§4, "Results"): in one CURIOUS run the competence on T3, "previously mastered", drops
around episode 250,000 while the agent trains on other modules; the module's absolute LP rises
over that period, "which in turn triggers an additional focus of the agent towards that task",
and the competence comes back. The sensory failure (`curious.analysis.perturbation`) measures the
same response around a known onset; here the onset is read from the competence alone, by a rule
fixed before any shipped run was read for drops. Per run and achievable module, over the
``competence/<m>``, ``lp/<m>`` and ``p_lp/<m>`` columns of ``metrics.parquet`` (the agent's own
measures at each episode) and the practised ``module`` of each episode:

1. **Mastered.** A module's competence counts once it averages a full window of its
   self-evaluations (``lp_window`` of them, as `curious.analysis.milestones.competence_crossings`
   asks; before, one lucky evaluation reads 1.0). The module is *mastered* from the evaluation at
   which its competence has stood at or above `MASTERED_COMPETENCE` (0.9,
   `curious.agent.learning_progress`'s) for `MASTERY_HOLD` (half a window, rounded up) of its
   consecutive self-evaluations: nine in ten of its last evaluations succeed,
   and have for a while, so a competence hovering at the line is not called mastered by one
   lucky reading. 0.9 is the higher of the report's two test-success milestones
   (`milestones.LEVELS`).
2. **Drop.** After mastery, the *peak* is the highest competence since the module was mastered.
   A *drop* is detected at the first episode whose competence is `DROP_DEPTH` (0.2) or more below
   the peak. Why 0.2: the competence of a module succeeding with probability 0.9 over a window of
   100 evaluations (the `laptop` runs' ``lp_window``) has a binomial standard deviation of 0.03,
   so the highest and lowest readings over some fifty independent windows of a stable stretch lie
   about 0.15 apart (2.3 standard deviations either side); 0.2 is above that, and a module at 0.9
   that drops by it has lost more than a fifth of its successes. A smaller decline is not counted.
3. **Descent.** The drop's *start* is the first episode of its final descent: the episode after
   the last one, before the drop, whose competence stood within `DESCENT_BAND` (0.1, half the
   depth) of the peak. The *trough* is the lowest competence from the drop until the module
   recovers (or the run ends); ``depth`` is the peak minus the trough.
4. **Recovered.** At the first episode after the drop whose competence is back at or above
   `MASTERED_COMPETENCE`; ``recovery_episodes`` counts from the drop's episode (NaN: not by the
   run's end).
   From there the module is read again from step 1 (mastered once more after `MASTERY_HOLD`
   evaluations at 0.9), so a run can show several drops of one module.
5. **Response.** Two spans of episodes, as `perturbation.recovery` compares the episodes before
   the failure with as many after it: *after* is the drop's whole course, from its start to the
   recovery (or the run's end), *before* as many episodes just before the start, but none before
   the module was mastered (the mastered stretch). Over each, with `perturbation`'s own measure:
   the module's mean absolute LP (``lp_before``, ``lp_after``) and mean probability of being
   practised (``p_lp_before``, ``p_lp_after``; the ``p_lp/<m>`` column: p_LP in CURIOUS, uniform
   in M-UVFA, in MG-TE 1 in the epochs of the module's turn and 0 in the others); and the share
   of episodes that practised the module (``practice_before``, ``practice_after``).
   ``lp_trough`` is the LP at the trough. The paper's claim reads as: LP up (``lp_after`` and
   ``lp_trough`` above ``lp_before``), and, where modules are chosen by LP, p_LP and practice up
   too, then the competence back.

Runs without self-evaluations (``her``: its competence columns are NaN) and modules never
mastered have no drop; `mastery` lists every (run, achievable module) with its first mastery, the
episodes it was read as mastered, the deepest fall below its peak over those (how near a drop it
came: a number to read the rule by, never part of it) and its drops, so that "none seen" is
visible and weighed. Runs whose sensory failure started are perturbed on
purpose: a drop of the perturbed module is the failure, not forgetting (`perturbation.recovery`
measures it), so callers leave those runs out or read them apart.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pandas as pd

from curious.agent.learning_progress import MASTERED_COMPETENCE
from curious.analysis.loading import require_runs
from curious.analysis.perturbation import _shift
from curious.analysis.statistics import FLOAT32_SLACK, RUN_COLUMNS

__all__ = [
    "DESCENT_BAND",
    "DROP_COLUMNS",
    "DROP_DEPTH",
    "LOWEST_COLUMNS",
    "MASTERED_COMPETENCE",
    "MASTERY_COLUMNS",
    "MASTERY_HOLD",
    "PAPER_FORGETTING_WINDOW",
    "lowest_competence",
    "mastery",
    "mastery_drops",
]

MASTERY_HOLD = 0.5
"""Fraction of ``lp_window`` (rounded up): the consecutive self-evaluations of the module over
which its competence must stay at or above `MASTERED_COMPETENCE` before it counts as mastered."""
DROP_DEPTH = 0.2
"""How far below its peak since mastery the competence must fall for a drop."""
DESCENT_BAND = 0.1
"""A drop's descent starts after the last episode whose competence was within this of the
peak."""
PAPER_FORGETTING_WINDOW = (245_000, 255_000)
"""Episodes [start, stop) around the paper's forgetting event: in its Fig. 2b-c the competence on
T3 (cube 1 above cube 2), mastered, drops "around episode 250,000" (§4, "Results")."""

DROP_COLUMNS: tuple[str, ...] = (
    *RUN_COLUMNS,
    "module",
    "mastered_episode",
    "peak",
    "start_episode",
    "drop_episode",
    "trough_episode",
    "trough",
    "depth",
    "recovered",
    "recovery_episode",
    "recovery_episodes",
    "span_episodes",
    "lp_before",
    "lp_after",
    "lp_trough",
    "p_lp_before",
    "p_lp_after",
    "practice_before",
    "practice_after",
)
"""The columns of `mastery_drops`: one row per drop."""

MASTERY_COLUMNS: tuple[str, ...] = (
    *RUN_COLUMNS,
    "module",
    "evaluated",
    "mastered_episode",
    "mastered_episodes",
    "deepest_fall",
    "n_drops",
    "n_recovered",
)
"""The columns of `mastery`: one row per (run, achievable module)."""


def _check(mastered: float, hold: float, depth: float, band: float) -> None:
    if not 0 < mastered <= 1:
        raise ValueError(f"mastered must be a competence in (0, 1], got {mastered}")
    if not 0 < hold <= 1:
        raise ValueError(f"hold must be a fraction of the window in (0, 1], got {hold}")
    if not 0 < band < depth <= 1:
        raise ValueError(f"need 0 < band < depth <= 1, got band {band}, depth {depth}")


def _first(mask: np.ndarray, start: int = 0) -> int | None:
    """The first index >= ``start`` where ``mask`` holds, or None."""
    hit = np.flatnonzero(mask[start:])
    return int(hit[0]) + start if hit.size else None


def _mastered_from(
    competence: np.ndarray, evaluated: np.ndarray, start: int, level: float, hold: int
) -> int | None:
    """The first row >= ``start`` at which the module has had ``hold`` consecutive
    self-evaluations (from ``start`` on) with competence at or above ``level``."""
    rows = np.flatnonzero(evaluated[start:]) + start
    ok = competence[rows] >= level - FLOAT32_SLACK  # NaN (window not full): not ok
    index = np.arange(rows.size)
    last_bad = np.maximum.accumulate(np.where(ok, -1, index))
    held = _first(index - last_bad >= hold)
    return None if held is None else int(rows[held])


def _drops(
    episodes: np.ndarray,
    values: np.ndarray,
    evaluated: np.ndarray,
    window: int,
    rule: tuple[float, float, float, float],
) -> tuple[dict, list[dict]]:
    """One module of one run: its `mastery` numbers (first mastery, episodes mastered, deepest
    fall) and its drops (see the module doc).
    ``values`` holds competence, LP, p_LP and the practised flag per row, episodes ascending."""
    level, hold, depth, band = rule
    competence = np.where(np.cumsum(evaluated) >= window, values[:, 0], np.nan)
    lp, p_lp, practised = values[:, 1], values[:, 2], values[:, 3]
    n = len(episodes)
    first_mastery, drops, start = None, [], 0
    exposure = {"mastered_episodes": 0, "deepest_fall": np.nan}
    while start < n:
        m = _mastered_from(competence, evaluated, start, level, max(1, math.ceil(hold * window)))
        if m is None:
            break
        first_mastery = episodes[m] if first_mastery is None else first_mastery
        peak = np.maximum.accumulate(competence[m:])
        d = _first(competence[m:] <= peak - depth + FLOAT32_SLACK)
        held = n - m if d is None else d + 1  # the stretch read: to the drop, or the run's end
        fall = float(np.max(peak[:held] - competence[m : m + held]))
        exposure["deepest_fall"] = np.fmax(exposure["deepest_fall"], fall)
        stop = episodes[-1] + 1 if d is None else episodes[m + d]
        exposure["mastered_episodes"] += int(stop - episodes[m])
        if d is None:
            break
        d += m
        top = float(peak[d - m])
        s = m + int(np.flatnonzero(competence[m:d] >= top - band - FLOAT32_SLACK)[-1]) + 1
        r = _first(competence >= level - FLOAT32_SLACK, d + 1)
        end = n if r is None else r
        t = d + int(np.argmin(competence[d:end]))
        end_episode = episodes[-1] + 1 if r is None else episodes[r]
        span = int(end_episode - episodes[s])
        shift = _shift(episodes[m:], lp[m:], p_lp[m:], int(episodes[s]), span)
        before = (episodes[m:s] >= episodes[s] - span).nonzero()[0] + m
        drops.append(
            {
                "mastered_episode": int(episodes[m]),
                "peak": top,
                "start_episode": int(episodes[s]),
                "drop_episode": int(episodes[d]),
                "trough_episode": int(episodes[t]),
                "trough": float(competence[t]),
                "depth": top - float(competence[t]),
                "recovered": r is not None,
                "recovery_episode": None if r is None else int(episodes[r]),
                "recovery_episodes": np.nan if r is None else float(episodes[r] - episodes[d]),
                "span_episodes": span,
                "lp_before": shift["lp_before"],
                "lp_after": shift["lp_after"],
                "lp_trough": float(lp[t]),
                "p_lp_before": shift["p_lp_before"],
                "p_lp_after": shift["p_lp_after"],
                "practice_before": float(practised[before].mean()) if before.size else np.nan,
                "practice_after": float(practised[s:end].mean()),
            }
        )
        if r is None:
            break
        start = r
    mastered = None if first_mastery is None else int(first_mastery)
    return {"mastered_episode": mastered, **exposure}, drops


@dataclass(frozen=True)
class ModuleSeries:
    """One achievable module of one run, episodes ascending: what the drop and dip rules read."""

    identity: dict
    """The run's `RUN_COLUMNS` values."""
    module: str
    episodes: np.ndarray
    values: np.ndarray
    """(rows, 4): competence, LP, p_LP and whether the episode practised the module (1.0)."""
    evaluated: np.ndarray
    """Whether each episode was a self-evaluation of the module."""
    window: int
    """The run's competence window (`lp_window`; 1 where the table has none)."""


def achievable_series(df: pd.DataFrame) -> Iterator[ModuleSeries]:
    """Every (run, achievable module) of a `load_runs` table, run by run."""
    require_runs(df)
    all_episodes = df["episode"].to_numpy()
    practised = df["module"].astype(str).to_numpy()
    evaluated = df["eval"].to_numpy(bool)
    columns: dict[str, np.ndarray] = {}  # module -> its competence, LP and p_LP, every row
    for rows in df.groupby("run", observed=True, sort=True).indices.values():
        rows = rows[np.argsort(all_episodes[rows], kind="stable")]
        first = rows[0]
        lp_window = df["lp_window"].iat[first]
        identity = {c: df[c].iat[first] for c in RUN_COLUMNS}
        for module in (m for m in str(df["achievable_modules"].iat[first]).split(",") if m):
            if module not in columns:
                names = [f"{p}{module}" for p in ("competence/", "lp/", "p_lp/")]
                columns[module] = df[names].to_numpy(np.float64)
            own = practised[rows] == module
            yield ModuleSeries(
                identity=identity,
                module=module,
                episodes=all_episodes[rows],
                values=np.column_stack([columns[module][rows], own]),
                evaluated=evaluated[rows] & own,
                window=1 if pd.isna(lp_window) else int(lp_window),
            )


def _scan(
    df: pd.DataFrame, mastered: float, hold: float, depth: float, band: float
) -> tuple[list[dict], list[dict]]:
    """Every (run, achievable module): its `mastery` row and its `mastery_drops` rows."""
    require_runs(df)
    _check(mastered, hold, depth, band)
    modules, drops = [], []
    for series in achievable_series(df):
        read, found = _drops(
            series.episodes,
            series.values,
            series.evaluated,
            series.window,
            (mastered, hold, depth, band),
        )
        identity = {**series.identity, "module": series.module}
        modules.append(
            {
                **identity,
                "evaluated": bool(np.isfinite(series.values[:, 0]).any()),
                **read,
                "n_drops": len(found),
                "n_recovered": sum(d["recovered"] for d in found),
            }
        )
        drops += [{**identity, **d} for d in found]
    return modules, drops


_INT_COLUMNS = ("mastered_episode", "start_episode", "drop_episode", "trough_episode")


def mastery_drops(
    df: pd.DataFrame,
    mastered: float = MASTERED_COMPETENCE,
    hold: float = MASTERY_HOLD,
    depth: float = DROP_DEPTH,
    band: float = DESCENT_BAND,
) -> pd.DataFrame:
    """Every drop of a mastered achievable module's competence in the runs of ``df`` (a
    `load_runs` table), by the rule of the module doc; the keyword arguments are its constants.
    Returns one row per drop with `DROP_COLUMNS`, by run, module and episode: the mastery it
    broke (``mastered_episode``, ``peak``), where it started, was detected, bottomed out and
    recovered (``*_episode``; ``recovery_episode`` NA where it did not), ``depth``, the episodes
    from the drop to the recovery, the length of the spans compared (``span_episodes``) and the
    response over them (LP, p_LP and practice share before and after; LP at the trough)."""
    _, drops = _scan(df, mastered, hold, depth, band)
    out = pd.DataFrame(drops, columns=list(DROP_COLUMNS))
    for c in (*_INT_COLUMNS, "recovery_episode", "span_episodes"):
        out[c] = out[c].astype("Int64")
    out["recovered"] = out["recovered"].astype(bool)
    return out


def mastery(
    df: pd.DataFrame,
    mastered: float = MASTERED_COMPETENCE,
    hold: float = MASTERY_HOLD,
    depth: float = DROP_DEPTH,
    band: float = DESCENT_BAND,
) -> pd.DataFrame:
    """Per run of ``df`` and achievable module (`MASTERY_COLUMNS`): whether the run has
    self-evaluations of it (``evaluated``: any competence; ``her`` has none), the episode at
    which it was first mastered (NA: never), the episodes it was read as mastered for
    (``mastered_episodes``: from each mastery to its drop or the run's end; 0: never), the
    deepest fall of its competence below the peak over those stretches (``deepest_fall``, a
    drop's own fall included, so at least ``depth`` where there is one; NaN: never mastered),
    and how many drops `mastery_drops` finds in it and how many of those recovered; the
    arguments are `mastery_drops`'."""
    modules, _ = _scan(df, mastered, hold, depth, band)
    out = pd.DataFrame(modules, columns=list(MASTERY_COLUMNS))
    out["mastered_episode"] = out["mastered_episode"].astype("Int64")
    counts = ["mastered_episodes", "n_drops", "n_recovered"]
    out[counts] = out[counts].astype(np.int64)
    return out


LOWEST_COLUMNS: tuple[str, ...] = (*RUN_COLUMNS, "module", "mastered_episode", "low", "low_episode")
"""The columns of `lowest_competence`: one row per (run, module mastered before the stretch)."""


def lowest_competence(
    df: pd.DataFrame, start: int, stop: int | None = None, read: pd.DataFrame | None = None
) -> pd.DataFrame:
    """Per run of ``df`` (a `load_runs` table) and achievable module first mastered (`mastery`)
    before episode ``start``: the lowest competence over episodes [``start``, ``stop``) (``stop``
    None: to the run's end) and the first episode at it (`LOWEST_COLUMNS`; a run that does not
    reach ``start`` has no row). What a run shows of its mastered modules over a stretch where
    the drop rule finds nothing: how near a drop they came there, e.g. past the main
    comparison's end in a long run, or over `PAPER_FORGETTING_WINDOW`. ``read``: ``df``'s
    `mastery` table where the caller has it (a scan of every run), computed here otherwise."""
    if stop is not None and stop <= start:
        raise ValueError(f"need start < stop, got {start} and {stop}")
    first_mastered = (mastery(df) if read is None else read).set_index(["run", "module"])[
        "mastered_episode"
    ]
    rows = []
    for series in achievable_series(df):
        first = first_mastered.get((series.identity["run"], series.module))
        if first is None or pd.isna(first) or first >= start:
            continue
        inside = series.episodes >= start
        if stop is not None:
            inside &= series.episodes < stop
        competence = np.where(inside, series.values[:, 0], np.nan)
        if not np.isfinite(competence).any():
            continue
        at = int(np.nanargmin(competence))
        rows.append(
            {
                **series.identity,
                "module": series.module,
                "mastered_episode": int(first),
                "low": float(competence[at]),
                "low_episode": int(series.episodes[at]),
            }
        )
    out = pd.DataFrame(rows, columns=list(LOWEST_COLUMNS))
    for c in ("mastered_episode", "low_episode"):
        out[c] = out[c].astype(np.int64)
    return out
