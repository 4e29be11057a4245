"""Recovery after the sensory failure: where the failure started, the module it perturbs, and
how long each run takes to regain its competence on that module.

The failure's onset is read from the data (`failure_onsets`: the first episode whose
``sensor_failure`` flag is True; runs logged before that column existed fall back to the
config's ``sensor_failure_episode``). The module followed is the one the variant's failure
perturbs (`perturbed_module`), as the run folder records it (the table's ``perturbed_modules``
column; `curious.runs.run_info.RunInfo.sensor_failure_modules`). A recovery is measured
(`recovery`) only where the failure started and that module was learned before it: its
competence just before the onset at least the run's own ``sensor_failure_competence``, else
`LEARNED_COMPETENCE`. Other runs get no number, only a sentence saying why (never started, or
nothing to forget). Competence is the ``competence/<module>`` column of ``metrics.parquet``, as
in `curious.analysis.statistics`.

The study on a mastered module (`sensor_failure_mastered`) is read by rules fixed before its runs
(docs/results.md, C5): its primary measure, `recovery_by_tests`, reads the module's test success
(``tests.parquet``, modules drawn uniformly, so both conditions are measured at the same rate)
pooled over 5 epochs, back at 90 % of its level over the 5 epochs before the onset;
`compare_recoveries` is the one-tailed Welch test on the episodes to recover. `recovery` is its
secondary measure.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from curious.analysis.loading import (
    AnalysisError,
    first_clash,
    require_alpha,
    require_count,
    require_episode,
    require_identity,
    require_runs,
    require_tests,
)
from curious.analysis.milestones import module_test_success
from curious.analysis.statistics import (
    ALPHA,
    FLOAT32_SLACK,
    RUN_COLUMNS,
    run_arrays,
    run_identity,
    welch_greater,
)
from curious.config import DEFAULT_TEST_EPOCHS, LEARNED_COMPETENCE

__all__ = [
    "LEARNED_COMPETENCE",
    "RECOVERY_BY_TESTS_COLUMNS",
    "RECOVERY_COLUMNS",
    "compare_recoveries",
    "failure_onsets",
    "perturbed_module",
    "recovery",
    "recovery_by_tests",
    "recovery_summary",
]


def perturbed_module(df: pd.DataFrame) -> str:
    """The module the runs' sensory failure perturbs, as their run folders record it (the
    ``perturbed_modules`` column): one module, the same in every run."""
    require_identity(df)
    per_run = df.groupby("run", observed=True)[["variant", "perturbed_modules"]].first()
    none = per_run[per_run["perturbed_modules"].astype(str) == ""]
    if not none.empty:
        variants = ", ".join(sorted(set(none["variant"].astype(str))))
        raise AnalysisError(
            f"variant(s) {variants} have no sensory failure (run {none.index[0]} records no "
            "perturbed module): pass module="
        )
    modules = sorted(set(per_run["perturbed_modules"].astype(str)))
    if len(modules) > 1 or "," in modules[0]:
        raise AnalysisError(
            f"these runs' sensory failures perturb {' / '.join(modules)}, not one module: "
            "pass module="
        )
    return modules[0]


def failure_onsets(df: pd.DataFrame) -> pd.DataFrame:
    """Per run: the first episode run with the sensory failure, and where it was read.

    ``source`` is ``metrics`` (the first row whose ``sensor_failure`` flag is True; none there:
    the failure never started), ``config`` (a run logged before that column existed: its
    config's ``sensor_failure_episode``, if the run reached it) or ``none`` (no failure
    configured, none logged). Returns one row per run, indexed by ``run``: ``onset`` (nullable
    int), ``source`` and ``n_episodes`` (last episode + 1).
    """
    require_runs(df)
    run = df["run"]
    grouped = df.groupby("run", observed=True, sort=True)
    last = grouped["episode"].max()
    planned = grouped["perturbation_episode"].first().astype("Int64")
    threshold = grouped["failure_competence"].first()
    if "sensor_failure" in df.columns:
        flag = df["sensor_failure"].astype("boolean")
        logged = flag.notna().groupby(run, observed=True).any()
        first_on = df["episode"].where(flag.fillna(False)).groupby(run, observed=True).min()
    else:
        logged = pd.Series(False, index=last.index)
        first_on = pd.Series(np.nan, index=last.index)
    first_on = first_on.astype("Int64")
    reached = planned.where(planned <= last)
    configured = planned.notna() | threshold.notna() | first_on.notna()
    source = np.select([~configured, logged], ["none", "metrics"], "config")
    onset = first_on.where(logged, reached)
    out = pd.DataFrame({"onset": onset, "source": source, "n_episodes": last + 1})
    out.index.name = "run"
    return out


def _check_recovery_arguments(
    fraction: float, pre_window: int | None, learned: float | None
) -> None:
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction must be in (0, 1], got {fraction}")
    if pre_window is not None:
        require_count(pre_window, "pre_window", "episode")
    if learned is not None and not 0 < learned <= 1:
        raise ValueError(f"learned must be a competence in (0, 1], got {learned}")


def _unmeasured(status: str, note: str, onset_competence: float = np.nan) -> dict:
    """The measurement columns of a run whose recovery cannot be measured."""
    return {
        "status": status,
        "onset_competence": onset_competence,
        "pre_competence": np.nan,
        "threshold": np.nan,
        "min_competence": np.nan,
        "trough_episode": pd.NA,
        "dropped": False,
        "recovered": False,
        "recovery_episodes": np.nan,
        "competence_drop": np.nan,
        "note": note,
    }


def _never_started(
    module: str, values: np.ndarray, n_episodes: int, threshold: float, planned: int | None
) -> dict:
    if planned is not None and planned >= n_episodes:
        note = f"the run ended after {n_episodes:,} episodes, before episode {planned:,}"
    elif np.isfinite(threshold):
        note = (
            f"{module} never reached competence {threshold:.2f} over a full window of its "
            f"evaluations within {n_episodes:,} episodes (highest {np.nanmax(values):.2f}, early "
            "values over fewer evaluations included)"
        )
    else:
        note = f"no episode of its {n_episodes:,} ran with it"
    return _unmeasured("never_started", f"the failure never started: {note}")


def _measure(
    module: str,
    episodes: np.ndarray,
    values: np.ndarray,
    p: int,
    bar: float,
    fraction: float,
    pre_window: int | None,
) -> dict:
    """The recovery columns of a run whose failure started at episode ``p``."""
    start = int(np.searchsorted(episodes, p, side="left"))
    if start == 0:
        note = "the failure started with the run's first episode: nothing was learned before it"
        return _unmeasured("not_learned", note)
    onset_competence = float(values[start - 1])
    if onset_competence < bar - FLOAT32_SLACK:
        note = (
            f"not learned before the failure: {module} had competence {onset_competence:.2f} "
            f"< {bar:.2f} at episode {p:,}, so there was nothing to forget"
        )
        return _unmeasured("not_learned", note, onset_competence)
    window = _window(pre_window, p)
    pre = float(np.mean(values[:start][episodes[:start] >= p - window]))
    threshold = fraction * pre
    after = values[start:]
    trough = int(np.nanargmin(after))
    dropped = bool(after[trough] < threshold)
    back = np.flatnonzero(after[trough:] >= threshold)
    if not dropped:
        recovered_at = 0.0
        note = f"competence never fell below {fraction:.0%} of its pre-failure mean ({pre:.2f})"
    elif back.size:
        recovered_at = float(episodes[start + trough + back[0]] - p + 1)
        note = (
            f"{fraction:.0%} of its pre-failure mean ({pre:.2f}) regained "
            f"{recovered_at:,.0f} episodes after the failure"
        )
    else:
        recovered_at = np.nan
        note = (
            f"{fraction:.0%} of its pre-failure mean ({pre:.2f}) not regained within the "
            f"{int(episodes[-1]) - p + 1:,} episodes after the failure"
        )
    return {
        "status": "measured",
        "onset_competence": onset_competence,
        "pre_competence": pre,
        "threshold": threshold,
        "min_competence": float(after[trough]),
        "trough_episode": int(episodes[start + trough]),
        "dropped": dropped,
        "recovered": bool(np.isfinite(recovered_at)),
        "recovery_episodes": recovered_at,
        "competence_drop": pre - float(after[trough]),
        "note": note,
    }


def _window(pre_window: int | None, p: int) -> int:
    """Episodes averaged on each side of the onset ``p``: ``pre_window``, else ``p // 10``."""
    return pre_window if pre_window is not None else max(1, p // 10)


def _shift(
    episodes: np.ndarray,
    lp: np.ndarray,
    p_lp: np.ndarray,
    p: int,
    window: int,
    practised: np.ndarray | None = None,
) -> dict:
    """Mean LP and p_LP of the module over the ``window`` episodes before the onset ``p`` and
    the ``window`` episodes from it (NaN where a side has no episode); with ``practised`` (1.0
    where an episode practised the module), the share of those episodes that practised it."""
    before = (episodes >= p - window) & (episodes < p)
    after = (episodes >= p) & (episodes < p + window)

    def mean(values: np.ndarray, rows: np.ndarray) -> float:
        return float(values[rows].mean()) if rows.any() else np.nan

    out = {
        "lp_before": mean(lp, before),
        "lp_after": mean(lp, after),
        "p_lp_before": mean(p_lp, before),
        "p_lp_after": mean(p_lp, after),
    }
    if practised is not None:
        out.update(practice_before=mean(practised, before), practice_after=mean(practised, after))
    return out


_NO_SHIFT = dict.fromkeys(
    ("lp_before", "lp_after", "p_lp_before", "p_lp_after", "practice_before", "practice_after"),
    np.nan,
)


def _learned_bar(learned: float | None, own: float) -> float:
    """The competence the module must have had before the failure: ``learned`` if given, else
    the run's own ``sensor_failure_competence`` (the one that started its failure), else
    `LEARNED_COMPETENCE`."""
    if learned is not None:
        return float(learned)
    return LEARNED_COMPETENCE if pd.isna(own) else float(own)


RECOVERY_COLUMNS: tuple[str, ...] = (
    "run",
    "condition",
    "seed",
    "variant",
    "module",
    "status",
    "perturbation_episode",
    "onset_source",
    "learned_threshold",
    "onset_competence",
    "pre_competence",
    "threshold",
    "min_competence",
    "trough_episode",
    "dropped",
    "recovered",
    "recovery_episodes",
    "competence_drop",
    "lp_before",
    "lp_after",
    "p_lp_before",
    "p_lp_after",
    "practice_before",
    "practice_after",
    "note",
)


def recovery(
    df: pd.DataFrame,
    module: str | None = None,
    perturbation_episode: int | None = None,
    fraction: float = 0.9,
    pre_window: int | None = None,
    learned: float | None = None,
) -> pd.DataFrame:
    """Episodes each run takes to regain ``fraction`` of a module's competence after the failure.

    ``module`` defaults to the one the runs' sensory failure perturbs (`perturbed_module`). The
    onset ``p`` of each run is where its failure started (`failure_onsets`);
    ``perturbation_episode`` imposes one on every run instead (to study another moment).
    ``status`` says what could be measured:

    - ``never_started``: the failure never started (``note`` says why: the module never reached
      the run's threshold, or the run ended before the planned episode);
    - ``not_learned``: the module's competence just before ``p`` (``onset_competence``) was below
      ``learned`` (default: the run's ``sensor_failure_competence``, else `LEARNED_COMPETENCE`),
      or the failure started with the run: nothing to forget, so nothing to recover;
    - ``measured``: ``pre_competence`` is the mean competence over the ``pre_window`` episodes
      before ``p`` (default ``max(1, p // 10)``; one noisy reading does not set the bar),
      ``threshold = fraction * pre_competence``; the *trough* is the lowest competence at or after
      ``p``; the run *dropped* if the trough is below the threshold, and *recovered* at the first
      episode ``e`` after the trough back at or above it: ``recovery_episodes = e - p + 1``
      (counting from the trough keeps a noisy dip on the way down from passing for a recovery).
      A run that never dropped has ``recovery_episodes = 0``; one not back by its end, NaN.
      ``competence_drop`` is ``pre_competence`` minus the trough's competence.

    Wherever the failure started (``measured`` and ``not_learned``), ``lp_before``/``lp_after``
    and ``p_lp_before``/``p_lp_after`` are the module's mean absolute LP and mean probability of
    being practised (the ``p_lp/<module>`` column: p_LP where the condition selects modules by
    LP, uniform in M-UVFA) over the ``pre_window`` episodes before ``p`` and as many from ``p``
    on: the paper's refocus on a module whose competence drops shows as LP and p_LP rising.
    ``practice_before``/``practice_after`` are the shares of those episodes that practised it
    (the ``module`` column; NaN in a table without it).

    Only ``measured`` runs have recovery numbers; every run has a ``note``, one sentence on its
    outcome.
    Returns one row per run with `RECOVERY_COLUMNS`.
    """
    require_runs(df)
    _check_recovery_arguments(fraction, pre_window, learned)
    if perturbation_episode is not None:
        require_episode(perturbation_episode, "perturbation_episode")
    module = module if module is not None else perturbed_module(df)
    column = f"competence/{module}"
    if column not in df.columns:
        raise KeyError(f"no module {module!r} in these runs (no column {column!r})")
    onsets = failure_onsets(df)
    columns = [column, f"lp/{module}", f"p_lp/{module}"]
    if "module" in df.columns:
        practised = (df["module"].astype(str) == module).to_numpy(np.float64)
    else:
        practised = np.full(len(df), np.nan)
    data = np.column_stack([df[columns].to_numpy(np.float64), practised])
    rows = []
    for run, first, episodes, arrays in run_arrays(df, data):
        values, lp, p_lp, practice = arrays.T
        onset = onsets.loc[run]
        if perturbation_episode is None and onset["source"] == "none":
            raise AnalysisError(
                f"run {run} has no sensory failure: its config.json sets neither "
                "sensor_failure_episode nor sensor_failure_competence and no episode ran with "
                "it (pass perturbation_episode to study another moment)"
            )
        own = df["failure_competence"].iat[first]  # the run's own threshold, or NA
        bar = _learned_bar(learned, own)
        given = perturbation_episode is not None
        p = int(perturbation_episode) if given else onset["onset"]
        if pd.isna(p) or p > episodes[-1]:
            planned = p if given else df["perturbation_episode"].iat[first]
            planned = None if pd.isna(planned) else int(planned)
            threshold = np.nan if given or pd.isna(own) else float(own)
            n_episodes = int(episodes[-1]) + 1
            measured = {
                **_never_started(module, values, n_episodes, threshold, planned),
                **_NO_SHIFT,
            }
            p = pd.NA
        else:
            measured = _measure(module, episodes, values, int(p), bar, fraction, pre_window)
            window = _window(pre_window, int(p))
            measured.update(_shift(episodes, lp, p_lp, int(p), window, practice))
        row = {c: df[c].iat[first] for c in ("run", "condition", "seed", "variant")}
        row.update(
            module=module,
            perturbation_episode=p,
            onset_source="given" if given else onset["source"],
            learned_threshold=bar,
            **measured,
        )
        rows.append(row)
    out = pd.DataFrame(rows, columns=list(RECOVERY_COLUMNS))
    out["perturbation_episode"] = out["perturbation_episode"].astype("Int64")
    out["trough_episode"] = out["trough_episode"].astype("Int64")
    return out


def recovery_summary(per_run: pd.DataFrame) -> pd.DataFrame:
    """Per condition: runs, runs where the failure started, runs measured (started, module
    learned before it), dropped and recovered among those, and the mean/std (ddof=1) of
    ``recovery_episodes``, competence before and threshold over the measured runs."""
    needed = ("condition", "status", "dropped", "recovered", "recovery_episodes")
    needed += ("pre_competence", "threshold")
    if missing := [c for c in needed if c not in per_run]:
        raise AnalysisError(
            f"this table lacks {', '.join(missing)}: pass a recovery table (curious.analysis."
            "recovery of load_runs' sensory-failure runs)"
        )
    _check_one_run_per_seed(per_run)
    measured = per_run["status"] == "measured"
    data = per_run.assign(
        started=per_run["status"] != "never_started",
        measured=measured,
        dropped=per_run["dropped"].astype(bool) & measured,
        recovered=per_run["recovered"].astype(bool) & measured,
    )
    grouped = data.groupby("condition", observed=True, sort=True)
    out = pd.DataFrame(
        {
            "n_runs": grouped.size(),
            "n_started": grouped["started"].sum(),
            "n_measured": grouped["measured"].sum(),
            "n_dropped": grouped["dropped"].sum(),
            "n_recovered": grouped["recovered"].sum(),
            "mean_recovery_episodes": grouped["recovery_episodes"].mean(),
            "std_recovery_episodes": grouped["recovery_episodes"].std(ddof=1),
            "pre_competence": grouped["pre_competence"].mean(),
            "threshold": grouped["threshold"].mean(),
        }
    )
    counts = ["n_runs", "n_started", "n_measured", "n_dropped", "n_recovered"]
    out[counts] = out[counts].astype(np.int64)
    return out.reset_index()


RECOVERY_BY_TESTS_COLUMNS: tuple[str, ...] = (
    *RUN_COLUMNS,
    "module",
    "status",
    "onset",
    "epoch_episodes",
    "window",
    "level_before",
    "n_before",
    "threshold",
    "trough",
    "trough_episode",
    "recovered",
    "recovered_episode",
    "recovery_episodes",
    "episodes_left",
    "note",
)
"""The columns of `recovery_by_tests`, one row per run."""

_RATE_SLACK = 1e-9
"""Pooled rates are ratios of counts, and ``fraction`` times a level is computed in floating
point: a rate this close below the threshold counts as reaching it."""


def _epoch_grid(tests: pd.DataFrame, onsets: pd.Series) -> pd.DataFrame:
    """One row per (run, epoch) of ``tests``: ``episodes`` (training episodes done when its
    tests ran), ``position`` (its rank in the run) and the run's ``onset``, with ``before``
    (tested before the onset) and ``after`` (after it). An epoch tested at the onset's own
    episode count is neither: whether its tests ran with the failure depends on how the rounds
    were collected."""
    grid = tests.groupby(["run", "epoch"], observed=True, sort=True)["episode"].max()
    grid = grid.rename("episodes").reset_index()
    grid["run"] = grid["run"].astype(str)
    grid["position"] = grid.groupby("run", sort=False).cumcount()
    grid["onset"] = grid["run"].map(onsets).astype("Float64")
    grid["before"] = (grid["episodes"] < grid["onset"]).fillna(False).astype(bool)
    grid["after"] = (grid["episodes"] > grid["onset"]).fillna(False).astype(bool)
    return grid


def _onsets_by_run(onsets: pd.Series | Mapping[str, object]) -> pd.Series:
    """``onsets`` (run -> first episode with the failure, NA where it never started) as a
    nullable-int Series indexed by the run's path as text."""
    if not isinstance(onsets, Mapping | pd.Series):
        raise AnalysisError(
            "onsets takes each run's onset by run (failure_onsets(runs)['onset'], or a mapping "
            f"run -> episode), got a {type(onsets).__name__}"
        )
    series = pd.Series(onsets, dtype="object") if isinstance(onsets, Mapping) else onsets
    try:
        out = pd.to_numeric(series, errors="raise").astype("Int64")
    except (TypeError, ValueError):
        raise AnalysisError("onsets must be episodes (integers, or NA where none)") from None
    out.index = out.index.astype(str)
    return out


def _identity_by_path(tests: pd.DataFrame) -> pd.DataFrame:
    """Each run's identity columns (`run_identity`), indexed by the run's path as text, as the
    readings after an onset key their runs."""
    out = run_identity(tests)
    out.index = out.index.astype(str)
    return out


def recovery_by_tests(
    tests: pd.DataFrame,
    onsets: pd.Series | Mapping[str, object],
    module: str | None = None,
    fraction: float = 0.9,
    window: int = DEFAULT_TEST_EPOCHS,
) -> pd.DataFrame:
    """Episodes each run takes to bring the module's test success back after the failure.

    C5's primary measure (docs/results.md, "The study as it will be rerun"), read from the
    noise-free test rollouts (``tests``, a `load_tests` table: modules drawn uniformly, so every
    condition is measured at the same rate whatever it practises). ``onsets`` gives each run's
    first episode with the failure (``failure_onsets(runs)["onset"]``; NA: it never started);
    ``module`` defaults to the one the runs' failure perturbs (`perturbed_module`).

    The module's test success is pooled over ``window`` consecutive epochs (`module_test_success`:
    5 epochs, 1,000 episodes at the `laptop` preset). The *level before* is the rate pooled over
    the ``window`` epochs tested before the onset; the threshold is ``fraction`` of it. The run
    is *recovered* at the first epoch whose pooled window lies wholly after the onset (no
    rollout from before the failure counts towards a recovery) with a rate at or above the
    threshold; ``recovery_episodes`` counts the training episodes from the onset to that epoch's
    tests. ``status`` says what could be measured:

    - ``no_onset``: the failure never started (the module never reached the run's threshold);
    - ``no_level``: it started before ``window`` epochs had been tested, or none of their
      rollouts was on the module: there is no level to come back to;
    - ``measured``: ``level_before`` (over ``n_before`` rollouts), ``threshold``, the lowest
      pooled rate after the onset (``trough``, at ``trough_episode``), ``recovered`` and, where
      it is, ``recovered_episode`` and ``recovery_episodes``; a run not back by its end has
      NaN there, and ``episodes_left`` (from the onset to its last tests) says how long it had.

    ``epoch_episodes`` is the run's epoch length read from its tests (the median step between
    epochs). Every run has a ``note``, one sentence on its outcome. Returns one row per run with
    `RECOVERY_BY_TESTS_COLUMNS`.
    """
    require_tests(tests)
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction must be in (0, 1], got {fraction}")
    require_count(window, "window", "epoch")
    module = module if module is not None else perturbed_module(tests)
    pooled = module_test_success(tests, window)
    pooled = pooled[pooled["module"].astype(str) == module]
    if pooled.empty and not (tests["module"].astype(str) == module).any():
        raise KeyError(f"no module {module!r} in these runs' test rollouts")
    by_run = _onsets_by_run(onsets)
    runs = tests["run"].astype(str).unique()
    if not by_run.index.isin(runs).any():
        raise AnalysisError(
            f"onsets name none of these test rollouts' runs (they are keyed by the run's resolved "
            f"path, as load_tests writes it, e.g. {runs[0]}): take them from failure_onsets of "
            "the same runs"
        )
    grid = _epoch_grid(tests, by_run)
    per_run = grid.groupby("run", sort=True)
    last_before = grid["position"].where(grid["before"]).groupby(grid["run"]).max()
    first_after = grid["position"].where(grid["after"]).groupby(grid["run"]).min()
    steps = per_run["episodes"].diff().groupby(grid["run"]).median()
    out = _identity_by_path(tests)
    out["onset"] = per_run["onset"].first().astype("Int64")
    out["last"] = per_run["episodes"].max()
    out["epoch_episodes"] = steps.fillna(per_run["episodes"].min()).round().astype(np.int64)
    out["threshold_competence"] = tests.groupby("run", observed=True)["failure_competence"].first()

    bounds = pd.DataFrame({"last_before": last_before, "first_after": first_after})
    rates = pooled.assign(run=pooled["run"].astype(str)).merge(
        grid[["run", "epoch", "position"]], on=["run", "epoch"]
    )
    rates = rates.join(bounds, on="run").sort_values(["run", "position"])
    level = rates[rates["position"] == rates["last_before"]].set_index("run")
    out["level_before"] = level["value"]
    out["n_before"] = level["n_tests"].astype("Int64")
    out["threshold"] = fraction * out["level_before"]
    later = rates[rates["position"] >= rates["first_after"] + window - 1]
    later = later.dropna(subset=["value"]).join(out["threshold"], on="run")
    trough = later.loc[later.groupby("run")["value"].idxmin()].set_index("run")
    out["trough"] = trough["value"]
    out["trough_episode"] = trough["episodes"].astype("Int64")
    back = later[later["value"] >= later["threshold"] - _RATE_SLACK]
    out["recovered_episode"] = back.groupby("run")["episodes"].first().astype("Int64")
    out["episodes_left"] = (out["last"] - out["onset"]).astype("Int64")
    out["status"] = np.select(
        [out["onset"].isna().to_numpy(bool), out["level_before"].isna().to_numpy(bool)],
        ["no_onset", "no_level"],
        "measured",
    )
    measured = out["status"] == "measured"
    for name in ("threshold", "trough", "trough_episode", "recovered_episode"):
        out[name] = out[name].where(measured)
    out["recovered"] = out["recovered_episode"].notna()
    since = out["recovered_episode"].astype("Float64") - out["onset"].astype("Float64")
    out["recovery_episodes"] = since.to_numpy(np.float64, na_value=np.nan)
    out["before_epochs"] = (last_before + 1).reindex(out.index).fillna(0).astype(np.int64)
    out["module"] = module
    out["window"] = window
    out["note"] = [_test_note(r, module, fraction) for r in out.itertuples()]
    out = out.rename_axis("run").reset_index()
    out["run"] = out["run"].astype(tests["run"].dtype)
    return out[list(RECOVERY_BY_TESTS_COLUMNS)]


def _test_note(r: object, module: str, fraction: float) -> str:
    """One sentence on a run's outcome in `recovery_by_tests`."""
    span = f"{r.window} epochs ({r.window * r.epoch_episodes:,} episodes)"
    if r.status == "no_onset":
        waited = (
            f"{module}'s competence never reached {r.threshold_competence:g}"
            if pd.notna(r.threshold_competence)
            else "the failure never started"
        )
        return f"no onset: {waited} within the {int(r.last):,} episodes tested"
    onset = int(r.onset)
    if r.status == "no_level":
        if r.before_epochs < r.window:
            return (
                f"no level before: the failure started at episode {onset:,}, after "
                f"{r.before_epochs} epoch(s) of tests, fewer than the {span} its level pools"
            )
        return (
            f"no level before: no test rollout of {module} in the {span} before episode {onset:,}"
        )
    level = f"{fraction:.0%} of its level before ({r.level_before:.2f})"
    if r.recovered:
        return f"test success back at {level} {r.recovery_episodes:,.0f} episodes after the onset"
    return (
        f"test success not back at {level} by the run's end, {int(r.episodes_left):,} episodes "
        "after the onset"
    )


def compare_recoveries(
    per_run: pd.DataFrame, faster: str, slower: str, alpha: float = ALPHA
) -> dict[str, object]:
    """One-tailed Welch's t-test that ``faster`` recovers in fewer episodes than ``slower``.

    ``per_run`` is a `recovery_by_tests` or `recovery` table (or any with ``condition``,
    ``recovered`` and ``recovery_episodes``). Only recovered runs have a number; the others are
    listed, not given one (``unrecovered``: their rows). The test is `welch_greater` on the
    recovered runs' ``recovery_episodes``, with ``slower``'s mean the greater under the
    alternative. Returns a dict: ``faster``, ``slower``, ``alpha``, ``n_faster``, ``n_slower``
    (recovered runs), ``mean_faster``, ``mean_slower``, ``std_faster``, ``std_slower``, ``t``,
    ``p`` (NaN with fewer than two recovered runs a side, or no variance), ``significant`` and
    ``unrecovered``.
    """
    require_alpha(alpha)
    if faster == slower:
        raise AnalysisError(f"compare_recoveries compares two conditions, got '{faster}' twice")
    missing = [c for c in ("condition", "recovered", "recovery_episodes") if c not in per_run]
    if missing:
        raise AnalysisError(
            f"this table lacks {', '.join(missing)}: pass a recovery_by_tests or recovery table"
        )
    present = set(per_run["condition"].astype(str))
    for name in (faster, slower):
        if name not in present:
            raise AnalysisError(
                f"no runs of condition '{name}' (have: {', '.join(sorted(present)) or 'none'})"
            )
    _check_one_run_per_seed(per_run)
    recovered = per_run[per_run["recovered"].astype(bool)]
    out: dict[str, object] = {"faster": faster, "slower": slower, "alpha": alpha}
    episodes = {}
    for side, condition in (("faster", faster), ("slower", slower)):
        values = recovered.loc[recovered["condition"] == condition, "recovery_episodes"]
        episodes[side] = values.to_numpy(np.float64)
        out[f"n_{side}"] = len(values)
        out[f"mean_{side}"] = float(episodes[side].mean()) if len(values) else np.nan
        out[f"std_{side}"] = float(episodes[side].std(ddof=1)) if len(values) > 1 else np.nan
    t, p = welch_greater(episodes["slower"], episodes["faster"])  # faster: the fewer episodes
    out.update(t=t, p=p, significant=bool(p < alpha) if np.isfinite(p) else False)
    out["unrecovered"] = per_run[
        per_run["condition"].isin([faster, slower]) & ~per_run["recovered"].astype(bool)
    ]
    return out


def _check_one_run_per_seed(per_run: pd.DataFrame) -> None:
    """An `AnalysisError` where a condition's seed has several rows (the runs of two
    experiments, `sensor_failure` and `sensor_failure_mastered`, or a table concatenated
    twice): each seed would count as several."""
    if "seed" not in per_run:
        return
    rows = first_clash(per_run, ["condition", "seed"])
    if rows.empty:
        return
    condition, seed = rows.iloc[0][["condition", "seed"]]
    named = f" ({', '.join(map(str, rows['run']))})" if "run" in rows else ""
    raise AnalysisError(
        f"condition '{condition}' seed {seed} has {len(rows)} rows{named}: each seed must "
        "count once; read one experiment's runs at a time"
    )
