"""The sections beyond the paper (docs/results.md, "Beyond the paper", whose rules were fixed
before the runs): LP's two uses apart (`lp_uses`, read beside the `distractors` experiment's
CURIOUS and M-UVFA runs of the same variant) and signed LP (`signed_lp`, read beside
`sensor_failure_mastered`'s CURIOUS runs)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pandas as pd

from curious import analysis
from curious.analysis.figures.beyond_paper import LP_USE_ORDER
from curious.analysis.lp_ablations import SIGNED_LP
from curious.reproduction.experiments import Experiment
from curious.watching.palette import condition_label
from pipelines.report.blocks import (
    ExperimentTables,
    fmt,
    fmt_p,
    lead_figure,
    markdown_table,
    other_figures,
)
from pipelines.report.distracting_modules import PER_RUN_BINS
from pipelines.report.sensory_failures import (
    RECOVERED_FRACTION,
    practice_share,
    primary_cell,
    recovery_censored,
)
from pipelines.resources import Reproduction


def _figures(repro: Reproduction, e: Experiment, tables: ExperimentTables) -> list[str]:
    tested = tables.tests is not None
    return [*lead_figure(repro, e, tested), *other_figures(repro, e, tested)]


# ----------------------------------------------------------------------------- LP's two uses


def _ordered(frame: pd.DataFrame) -> pd.DataFrame:
    rank = {c: i for i, c in enumerate(LP_USE_ORDER)}
    key = frame["condition"].astype(str).map(rank).fillna(len(rank))
    return frame.assign(_r=key).sort_values(["_r", "seed"], kind="stable").drop(columns="_r")


def _tests_table(tests: pd.DataFrame) -> list[str]:
    rows = [
        (
            f"{condition_label(t.better)} > {condition_label(t.worse)}",
            f"{t.n} ({', '.join(map(str, t.seeds))})",
            f"{fmt(t.mean_better)} vs {fmt(t.mean_worse)}",
            fmt(t.t),
            fmt_p(t.p),
            fmt_p(t.p_holm),
            "yes" if t.significant else "no",
        )
        for t in tests.itertuples()
    ]
    header = ("test", "seeds", "means", "Welch t", "p", "p (Holm, 4 tests)", "significant")
    return markdown_table(header, rows)


def lp_uses(repro: Reproduction, e: Experiment, tables: ExperimentTables) -> list[str]:
    """The four conditions' competence and test success at the end, their practice on
    distracting modules, the four Welch tests per measure and the reading fixed before."""
    lines = _figures(repro, e, tables)
    their_metrics, their_tests = repro.layout.read_tables("distractors")
    metrics, tests = analysis.lp_uses_tables(
        tables.metrics, tables.tests, their_metrics, their_tests, e.variants[0]
    )
    if their_metrics is None:
        lines += [
            "The `distractors` experiment's CURIOUS and M-UVFA runs, which this one is read "
            "against, are not in this reproduction: its tests wait for them.",
            "",
        ]
    final = analysis.final_competence(metrics)
    tested = None if tests is None else analysis.final_test_success(tests)
    episodes = int(final["episodes"].iat[0])
    width = analysis.nice_bin_size(episodes, PER_RUN_BINS)
    practised = _per_bin_and_whole(analysis.distractor_share, metrics, width, episodes)
    learner = analysis.learner_of(metrics)
    replayed: dict[str, str] = {}
    if learner is not None:
        replayed = _per_bin_and_whole(analysis.replay_share, learner, width, episodes)
    tested_by_run = None if tested is None else tested.set_index("run")["value"]
    rows = [
        (
            condition_label(r.condition),
            r.seed,
            fmt(r.value),
            "–" if tested_by_run is None else fmt(tested_by_run.get(r.run, math.nan)),
            practised.get(r.run, "–"),
            replayed.get(r.run, "–"),
        )
        for r in _ordered(final).itertuples()
    ]
    header = (
        "condition",
        "seed",
        f"competence at {episodes:,}",
        "test success, last bin",
        f"episodes on a distracting module, per {width:,} (whole run)",
        f"transitions replayed as a distracting module, per {width:,} (whole run)",
    )
    lines += ["Per run (the comparison reads the seeds all four conditions have):", ""]
    lines += markdown_table(header, rows)
    lines += [_replay_note(final, replayed), ""]
    measures = [("competence at the end (primary)", final)]
    if tested is not None:
        measures.append(("test success in the last bin (secondary, decides nothing)", tested))
    for what, values in measures:
        try:
            result = analysis.compare_lp_uses(values)
        except analysis.AnalysisError as exc:
            lines += [f"The four tests on the {what}: not computed ({exc}).", ""]
            continue
        lines += [
            f"One-tailed Welch's t-tests on the {what}, alpha = {analysis.ALPHA:g} after "
            "Holm's correction over the four:",
            "",
            *_tests_table(result),
        ]
        if values is final:
            readings = analysis.lp_use_readings(result)
            said = "; ".join(f"{use}: {verdict}" for use, verdict in readings.items())
            lines += [f"The reading fixed before the runs: {said}.", ""]
    return lines


def _per_bin_and_whole(
    share: Callable[[pd.DataFrame, int], pd.DataFrame], table: pd.DataFrame, width: int, whole: int
) -> dict[str, str]:
    """Per run of ``table``: ``share`` (`distractor_share` or `replay_share`) in each bin of
    ``width`` episodes up to ``whole``, then over the first ``whole`` episodes in brackets, as
    percentages (– where the run's table does not cover it); a run with neither is left out."""
    over = share(table, whole)
    over = over[over["episodes"] == whole].set_index("run")["value"]
    bins = share(table, width)
    bins = bins[bins["episodes"] <= whole].groupby("run", observed=True)["value"]
    cells = {}
    for run in dict.fromkeys([*bins.groups, *over.index]):
        values = bins.get_group(run) if run in bins.groups else []
        total = f"{100 * over[run]:.0f} %" if run in over.index else "–"
        cells[str(run)] = f"{', '.join(f'{100 * v:.0f} %' for v in values)} ({total})"
    return cells


def _replay_note(final: pd.DataFrame, replayed: dict[str, str]) -> str:
    """What the replay column reads, and which runs it cannot read."""
    covered = [run for run, cell in replayed.items() if not cell.endswith("(–)")]
    runs = final.assign(kept=final["run"].astype(str).isin(covered))
    without = sorted(
        {condition_label(str(c)) for c in runs.loc[~runs["kept"], "condition"]},
        key=str,
    )
    note = (
        "The last two columns are each run's share of its training episodes that practised a "
        "distracting module, and of the transitions its updates replayed as one (the replay "
        "counts of its learner.parquet), per bin and, in brackets, over the whole run"
    )
    if without:
        note += (
            f"; – where a run's replay counts do not cover its whole length ({', '.join(without)}"
            ": runs trained before runs kept them have none)"
        )
    return note + "."


# ----------------------------------------------------------------------------- signed LP


def signed_lp(repro: Reproduction, e: Experiment, tables: ExperimentTables) -> list[str]:
    """Per run of both measures: the onset, the refocus (p_LP and practice) and the recovery by
    test success; the refocus test and the log-rank test on the recoveries."""
    lines = _figures(repro, e, tables)
    csv = repro.layout.figures / f"{e.name}.csv"
    if not csv.is_file():
        return lines
    per_run = pd.read_csv(csv)
    absolute_metrics, absolute_tests = repro.layout.read_tables("sensor_failure_mastered")
    if absolute_metrics is None:
        lines += [
            "The `sensor_failure_mastered` experiment's CURIOUS runs (absolute LP), which this one "
            "is read against, are not in this reproduction: its tests wait for them.",
            "",
        ]
    by_tests = None
    if tables.tests is not None and (absolute_metrics is None or absolute_tests is not None):
        metrics = analysis.signed_beside_absolute(tables.metrics, absolute_metrics)
        tests = analysis.signed_beside_absolute(tables.tests, absolute_tests)
        onsets = analysis.failure_onsets(metrics)["onset"]
        module = str(per_run["module"].iat[0])
        by_tests = analysis.recovery_by_tests(tests, onsets, module, RECOVERED_FRACTION)
    primary = None if by_tests is None else by_tests.set_index(["condition", "seed"])
    rows = []
    for r in per_run.sort_values(["condition", "seed"], kind="stable").itertuples():
        t = None if primary is None else next(primary.loc[[(r.condition, r.seed)]].itertuples())
        rows.append(
            (
                condition_label(r.condition),
                r.seed,
                "never" if pd.isna(r.perturbation_episode) else f"{int(r.perturbation_episode):,}",
                f"{fmt(r.p_lp_before)} → {fmt(r.p_lp_after)}",
                practice_share(r.practice_before, r.practice_after),
                "–" if t is None else primary_cell(t),
            )
        )
    header = (
        "LP",
        "seed",
        "failure from episode",
        "p_LP before → after",
        "practised before → after",
        "recovery by test success",
    )
    lines += markdown_table(header, rows)
    if absolute_metrics is None:
        return lines
    refocus = analysis.compare_refocus(
        per_run[per_run["condition"] == "curious"], per_run[per_run["condition"] == SIGNED_LP]
    )
    reading = analysis.signed_lp_reading(refocus)
    lines += [_refocus_sentence(refocus), "", f"The reading fixed before the runs: {reading}.", ""]
    if by_tests is not None:
        lines += recovery_censored(by_tests, "curious", SIGNED_LP)
    return lines


def _refocus_sentence(test: dict[str, object]) -> str:
    """The refocus test in a sentence, the practice share's rise beside it."""
    rises = {k: np.asarray(test[k], np.float64) for k in ("rise_absolute", "rise_signed")}
    practice = {
        k: np.asarray(test[k], np.float64) for k in ("practice_absolute", "practice_signed")
    }

    def mean(values: np.ndarray) -> str:
        return fmt(float(values.mean())) if values.size else "–"

    def runs(values: np.ndarray) -> str:
        return f"{values.size} run{'' if values.size == 1 else 's'}"

    head = (
        "One-tailed Welch's t-test that absolute LP raises push cube 3's p_LP more after the onset "
        f"than signed LP, alpha = {test['alpha']:g}: mean rise {mean(rises['rise_absolute'])} "
        f"({runs(rises['rise_absolute'])}) against {mean(rises['rise_signed'])} "
        f"({runs(rises['rise_signed'])})"
    )
    if math.isfinite(float(test["p"])):
        verdict = "significant" if test["significant"] else "not significant"
        head += f", t = {fmt(float(test['t']))}, p = {fmt_p(float(test['p']))}, {verdict}"
    else:
        head += ", not tested (fewer than two runs a side, or no variance)"
    rose = f"{mean(practice['practice_absolute'])} and {mean(practice['practice_signed'])}"
    return f"{head}. The share of episodes practising it rose by {rose} (reported, not tested)."
