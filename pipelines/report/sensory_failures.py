"""The sensory failures' sections (C5): the recovery of competence after a failure on a module just
learned, and, on a mastered module, the recovery of test success (primary) and competence
(secondary) with the Welch test on the episodes to recover."""

from __future__ import annotations

import math

import pandas as pd

from curious import analysis
from curious.reproduction.experiments import Experiment
from curious.watching.palette import condition_label
from pipelines.report.blocks import (
    NO_TESTS,
    ExperimentTables,
    fmt,
    fmt_episodes,
    fmt_p,
    in_order,
    lead_figure,
    markdown_table,
    other_figures,
)
from pipelines.resources import Reproduction


def _onsets_text(per_run: pd.DataFrame) -> str:
    """Where the failures started, over the runs."""
    onsets = per_run["perturbation_episode"].dropna().astype(int)
    n = len(per_run)
    if onsets.empty:
        return f"It never started in any of the {n} runs."
    low, high = onsets.min(), onsets.max()
    where = f"episode {low:,}" if low == high else f"episodes {low:,}–{high:,}"
    if len(onsets) == n:
        return f"It started at {where} in every run."
    return f"It started at {where} in {len(onsets)} of {n} runs, and never in the others."


def _recovery_rows(summary: pd.DataFrame) -> list[tuple[str, ...]]:
    """Per condition, over its measured runs: the recovery numbers."""
    return [
        (
            condition_label(r.condition),
            f"{int(r.n_measured)}/{int(r.n_runs)}",
            f"{int(r.n_dropped)}",
            f"{int(r.n_recovered)}",
            fmt(r.pre_competence),
            fmt(r.threshold),
            fmt_episodes(r.mean_recovery_episodes),
            fmt_episodes(r.std_recovery_episodes),
        )
        for r in summary.itertuples()
        if r.n_measured
    ]


def _failure_runs(
    repro: Reproduction, e: Experiment, tables: ExperimentTables
) -> tuple[list[str], pd.DataFrame | None]:
    """A sensory-failure experiment's figures and the opening of its section, with the per-run
    recovery of competence its figure (named as the experiment) wrote beside it (None before it
    is drawn)."""
    tested = tables.tests is not None
    lines = [*lead_figure(repro, e, tested), *other_figures(repro, e, tested)]
    csv = repro.layout.figures / f"{e.name}.csv"
    if not csv.is_file():
        return lines, None
    per_run = pd.read_csv(csv)
    module = str(per_run["module"].iat[0])
    lines += [
        f"Module followed: `{module}`, the one the variant's sensory failure perturbs. The "
        f"failure starts {e.sensor_failure_text}. {_onsets_text(per_run)} A recovery is "
        f"measured only in runs where the failure started and `{module}` was learned before it "
        "(its competence just before the failure at least "
        f"{' or '.join(sorted({fmt(v) for v in per_run['learned_threshold']}))}); the others "
        "say why there is nothing to measure.",
        "",
    ]
    return lines, per_run


def sensor_failure(repro: Reproduction, e: Experiment, tables: ExperimentTables) -> list[str]:
    """The sensory failure on a module just learned: per run, the competence before, the drop,
    LP and p_LP around the onset and the episodes to regain 90 % of it; then per condition."""
    lines, per_run = _failure_runs(repro, e, tables)
    if per_run is None:
        return lines
    rows = [
        (
            condition_label(r.condition),
            r.seed,
            "never" if pd.isna(r.perturbation_episode) else f"{int(r.perturbation_episode):,}",
            fmt(r.onset_competence),
            fmt(r.pre_competence),
            fmt(r.competence_drop),
            f"{fmt(r.lp_before)} → {fmt(r.lp_after)}",
            f"{fmt(r.p_lp_before)} → {fmt(r.p_lp_after)}",
            fmt_episodes(r.recovery_episodes),
            r.note,
        )
        for r in in_order(per_run, e).itertuples()
    ]
    header = (
        "condition",
        "seed",
        "failure from episode",
        "competence at the onset",
        "pre-failure mean",
        "drop from the pre-failure mean",
        "LP before → after",
        "p_LP before → after",
        "recovery (episodes)",
        "outcome",
    )
    lines += [
        "Per run, two levels before the failure: the competence at the onset (its last value "
        "before the failure, the level that started it) and the pre-failure mean (the mean "
        "competence over the last p/10 episodes before a failure at episode p); then the drop from "
        "the pre-failure mean to the trough, the module's mean absolute LP and mean probability "
        "of being practised (p_LP; uniform in M-UVFA) over those episodes before the failure and "
        "as many from it on, and the episodes to regain 90 % of the pre-failure mean (0: it "
        "never fell below).",
        "",
    ]
    lines += markdown_table(header, rows)
    measured = _recovery_rows(analysis.recovery_summary(per_run))
    if not measured:
        return [*lines, "No recovery can be measured in these runs.", ""]
    header = (
        "condition",
        "measured runs",
        "dropped",
        "recovered",
        "pre-failure mean",
        "threshold (90 % of it)",
        "mean recovery (episodes)",
        "std",
    )
    return lines + markdown_table(header, measured)


RECOVERED_FRACTION = 0.9
"""The share of its level before at which a run's test success counts as back (docs/results.md,
C5's fixed rules)."""


PRIMARY_RULE = (
    "Recovery by test success, the primary measure (rules fixed in docs/results.md before the "
    "runs; `curious.analysis.recovery_by_tests`): `{module}`'s test success pooled over {window} "
    "epochs ({span:,} episodes); its level before is the rate over the {window} epochs tested "
    "before the onset; a run has recovered at the first epoch whose pooled epochs were all "
    "tested after the onset and whose rate is back at {percent:g} % of that level or above, "
    "the episodes to recover counting from the onset; its trough is the lowest pooled rate over "
    "those windows, to the run's end. The competence's return to 90 % of its "
    "pre-failure mean (`curious.analysis.recovery`, as in the other sensory-failure study) is "
    "the secondary measure. LP, p_LP and the share of training episodes that practised the "
    "module are means over the p/10 episodes before a failure at episode p and as many from it."
)


def primary_cell(t: object) -> str:
    """A run's recovery of test success, or why it has no number."""
    if t.status == "no_onset":
        return "no onset"
    if t.status == "no_level":
        return "no level before"
    if bool(t.recovered):
        return f"{fmt_episodes(t.recovery_episodes)} episodes"
    return f"not by its end ({fmt_episodes(t.episodes_left)} episodes after the onset)"


def secondary_cell(r: object) -> str:
    """A run's recovery of competence, or why it has no number."""
    if r.status != "measured":
        return "–"
    if not bool(r.dropped):
        return "never below 90 %"
    if bool(r.recovered):
        return f"{fmt_episodes(r.recovery_episodes)} episodes"
    return "not by its end"


def practice_share(before: float, after: float) -> str:
    """``"25% → 56%"``: the share of episodes that practised the module, before and after."""
    if not (math.isfinite(before) and math.isfinite(after)):
        return "–"
    return f"{before:.0%} → {after:.0%}"


AFTER_ONSET_OFFSETS = (1_000, 2_000, 5_000, 10_000, 15_000, 20_000, 25_000, 30_000)
"""The distances after the onset at which the report gives each run's test success, before the
last column (`followed_by_all`)."""


def followed_by_all(by_tests: pd.DataFrame) -> int | None:
    """The longest stretch after the onset, in whole thousands of episodes, that every recovered
    run was followed (None where no run recovered)."""
    back = by_tests.loc[by_tests["recovered"].astype(bool), "episodes_left"]
    return None if back.empty else int(back.min()) // 1_000 * 1_000


def after_onset_offsets(by_tests: pd.DataFrame) -> list[int]:
    """`AFTER_ONSET_OFFSETS`, then the stretch every recovered run was followed where longer."""
    last = followed_by_all(by_tests)
    return [*AFTER_ONSET_OFFSETS, *([last] if last and last > AFTER_ONSET_OFFSETS[-1] else [])]


def after_onset_rows(e: Experiment, after: pd.DataFrame) -> list[tuple[str, ...]]:
    """A row per run of `analysis.success_after_onset`: its name and onset, then a rate
    per offset (–: not tested that late)."""
    rows = []
    for (_, seed), mine in in_order(after, e).groupby(["condition", "seed"], sort=False):
        label = f"{condition_label(str(mine['condition'].iat[0]))} {seed}"
        rates = ["–" if pd.isna(v) else f"{v:.2f}" for v in mine.sort_values("offset")["value"]]
        rows.append((f"{label} (onset {int(mine['onset'].iat[0]):,})", *rates))
    return rows


def returns_clauses(e: Experiment, returns: pd.DataFrame) -> list[str]:
    """Per recovered run of `analysis.returns_below`: the epochs under its threshold again after
    its crossing, of those tested, and the last of them."""
    clauses = []
    for r in in_order(returns, e).itertuples():
        clause = (
            f"{condition_label(r.condition)} seed {r.seed}, {r.n_below} of {r.n_after} epochs "
            f"(threshold {r.threshold:.2f})"
        )
        if r.n_below:
            clause += f", the last {int(r.last_below):,} episodes after the onset"
        clauses.append(clause)
    return clauses


def after_onset_lines(
    e: Experiment, tests: pd.DataFrame, onsets: pd.Series, by_tests: pd.DataFrame
) -> list[str]:
    """The module's test success at fixed distances after each onset, and the returns below the
    threshold after each crossing: readings beside the fixed rules, sizing the noise of a first
    crossing."""
    module = str(by_tests["module"].iat[0])
    offsets = after_onset_offsets(by_tests)
    after = analysis.success_after_onset(tests, onsets, offsets, module)
    if after.empty:
        return []
    header = ("", *(f"+{d:,}" for d in offsets))
    last = offsets[len(AFTER_ONSET_OFFSETS) :]
    lines = [
        f"`{module}`'s test success after the onset (`curious.analysis.success_after_onset`), "
        f"pooled over the {int(by_tests['window'].max())} epochs ending at the first epoch "
        "tested at or after each point, every window wholly after the onset (–: the run was not "
        "tested that late)"
        + (
            f"; the last column, +{last[0]:,}, is the longest stretch every recovered run was "
            "followed:"
            if last
            else ":"
        ),
        "",
        *markdown_table(header, after_onset_rows(e, after)),
    ]
    returns = analysis.returns_below(tests, by_tests)
    if len(returns):
        lines += [
            "After each crossing, the epochs whose pooled rate was under the run's threshold "
            "again (`curious.analysis.returns_below`; a first crossing of a noisy rate is not a "
            f"return held): {'; '.join(returns_clauses(e, returns))}.",
            "",
        ]
    return lines


def _primary_summary(e: Experiment, by_tests: pd.DataFrame) -> list[str]:
    """Per condition, the runs recovered by test success and their episodes to recover."""
    parts = []
    for c in e.conditions:
        mine = by_tests[by_tests["condition"] == c]
        back = mine.loc[mine["recovered"].astype(bool), "recovery_episodes"]
        text = f"{condition_label(c)} {len(back)} of {len(mine)} runs"
        if len(back) == 1:
            text += f", after {back.iat[0]:,.0f} episodes"
        elif len(back) > 1:
            text += f", after {back.mean():,.0f} ± {back.std(ddof=1):,.0f} episodes (mean ± std)"
        parts.append(text)
    return [f"Recovered by test success: {'; '.join(parts)}.", ""]


def _recovery_welch(e: Experiment, by_tests: pd.DataFrame, faster: str, slower: str) -> list[str]:
    """The one-tailed Welch test on the episodes to recover, and the runs given no number."""
    test = analysis.compare_recoveries(by_tests, faster, slower)
    head = (
        f"One-tailed Welch's t-test on the episodes to recover by test success, "
        f"{condition_label(faster)} faster than {condition_label(slower)}, alpha = "
        f"{test['alpha']:g}: "
    )
    if math.isfinite(test["p"]):
        verdict = "significant" if test["significant"] else "not significant"
        head += (
            f"t = {fmt(test['t'])}, p = {fmt_p(test['p'])}, {verdict} ({test['n_faster']} and "
            f"{test['n_slower']} recovered runs)."
        )
    else:
        head += (
            f"not tested ({test['n_faster']} and {test['n_slower']} recovered runs: fewer than "
            "two a side, or no variance)."
        )
    lines = [head, ""]
    unrecovered = in_order(test["unrecovered"], e)
    if len(unrecovered):
        lines += ["Runs without a recovery by test success, given no number:", ""]
        lines += [
            f"- {condition_label(t.condition)} seed {t.seed}: {t.note}."
            for t in unrecovered.itertuples()
        ]
        lines.append("")
    return lines


def recovery_censored(by_tests: pd.DataFrame, faster: str, slower: str) -> list[str]:
    """The log-rank test on the recoveries by test success, the runs not recovered censored at
    the episodes they had after their onset (`analysis.compare_censored_recoveries`)."""
    test = analysis.compare_censored_recoveries(by_tests, faster, slower)
    counts = (
        f"{test['recovered_faster']} of {test['n_faster']} {condition_label(faster)} runs and "
        f"{test['recovered_slower']} of {test['n_slower']} {condition_label(slower)} runs "
        "recovered, the others censored at the episodes they had after their onset"
    )
    head = (
        f"One-sided log-rank test on the episodes to recover by test success, "
        f"{condition_label(faster)} sooner than {condition_label(slower)}, alpha = "
        f"{test['alpha']:g} ({counts}): "
    )
    if math.isfinite(test["p"]):
        verdict = "significant" if test["significant"] else "not significant"
        smallest = 1 / test["splits"]
        head += (
            f"Z = {fmt(test['z'])}, exact permutation p = {fmt_p(test['p'])} over the "
            f"{test['splits']:,} splits of the runs (the smallest it can be: {fmt_p(smallest)}), "
            f"{verdict}; normal approximation p = {fmt_p(test['p_normal'])}. Gehan's generalised "
            f"Wilcoxon, as a check: {fmt(test['gehan'], 0)}, exact p = {fmt_p(test['p_gehan'])}."
        )
    else:
        head += "not tested (no recovery, or a condition without runs to compare)."
    lines = [head, ""]
    if len(test["left_out"]):
        lines += [
            "Left out, with nothing to recover: "
            + "; ".join(
                f"{condition_label(t.condition)} seed {t.seed} ({t.note})"
                for t in test["left_out"].itertuples()
            )
            + ".",
            "",
        ]
    return lines


def sensor_failure_mastered(
    repro: Reproduction, e: Experiment, tables: ExperimentTables
) -> list[str]:
    """The study on a mastered module: per run, its recovery by test success (primary) and by
    competence (secondary), with the refocus, the Welch test on the episodes to recover (the
    recovered runs), and the log-rank test with the others censored."""
    lines, per_run = _failure_runs(repro, e, tables)
    if per_run is None:
        return lines
    if tables.tests is None:
        return [*lines, NO_TESTS, ""]
    module = str(per_run["module"].iat[0])
    onsets = analysis.failure_onsets(tables.metrics)["onset"]
    by_tests = analysis.recovery_by_tests(tables.tests, onsets, module, RECOVERED_FRACTION)
    window = int(by_tests["window"].max())
    span = window * int(by_tests["epoch_episodes"].max())
    rule = PRIMARY_RULE.format(
        module=module, window=window, span=span, percent=RECOVERED_FRACTION * 100
    )
    lines += [rule, ""]
    secondary = per_run.set_index(["condition", "seed"])
    rows = []
    for t in in_order(by_tests, e).itertuples():
        r = next(secondary.loc[[(t.condition, t.seed)]].itertuples())
        rows.append(
            (
                condition_label(t.condition),
                t.seed,
                "never" if pd.isna(t.onset) else f"{int(t.onset):,}",
                "–" if pd.isna(t.level_before) else f"{t.level_before:.2f} ({t.n_before})",
                "–" if pd.isna(t.trough) else f"{t.trough:.2f} at {int(t.trough_episode):,}",
                f"{fmt(r.lp_before)} → {fmt(r.lp_after)}",
                f"{fmt(r.p_lp_before)} → {fmt(r.p_lp_after)}",
                practice_share(r.practice_before, r.practice_after),
                primary_cell(t),
                secondary_cell(r),
            )
        )
    header = (
        "condition",
        "seed",
        "failure from episode",
        "test success before (rollouts)",
        "test success trough",
        "LP before → after",
        "p_LP before → after",
        "practised before → after",
        "recovery by test success (primary)",
        "recovery by competence (secondary)",
    )
    lines += markdown_table(header, rows)
    lines += _primary_summary(e, by_tests)
    lines += after_onset_lines(e, tables.tests, onsets, by_tests)
    if e.compare is not None:
        lines += _recovery_welch(e, by_tests, *e.compare)
        lines += recovery_censored(by_tests, *e.compare)
    return lines
