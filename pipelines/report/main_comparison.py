"""The main comparison's section (C1, C2): Fig. 2a's numbers from the test rollouts, the Welch
test per bin, the area under each seed's curve, the episodes to each level of test success, each
module's test success at the end and over the whole run, the order of learning and the
spontaneous forgetting."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pandas as pd

from curious import analysis
from curious.config import DEFAULT_TEST_EPOCHS
from curious.reproduction.experiments import Experiment
from curious.watching.palette import condition_label, module_label
from pipelines.report.blocks import (
    NO_TESTS,
    ExperimentTables,
    fmt,
    fmt_episodes,
    fmt_p,
    in_order,
    lead_figure,
    markdown_table,
    mean_std,
    other_figures,
    welch_summary,
)
from pipelines.report.spontaneous_forgetting import spontaneous_forgetting
from pipelines.resources import Reproduction

ORDER_LEVEL = 0.5
"""The competence at which the order of learning counts a module as learned."""


def _final_by_condition(e: Experiment, numbers: dict) -> list[str]:
    """The test success of each condition in the last bin of `analysis.main_comparison`."""
    final = numbers["final"]
    episodes = int(final["episodes"].max())
    parts = [
        f"{condition_label(c)} {mean_std(final.loc[final['condition'] == c, 'value'])}"
        for c in e.conditions
    ]
    return [
        f"Test success over achievable modules in the last {numbers['bin_size']:,}-episode bin "
        f"(to {episodes:,} episodes; mean ± std over seeds): {'; '.join(parts)}.",
        "",
    ]


def _welch_points(numbers: dict, better: str, worse: str) -> list[str]:
    """The Welch test per bin of `analysis.main_comparison`, every bin a row."""
    test = numbers["welch"]
    if test.empty:
        return ["No bin is shared by both conditions.", ""]
    lines = welch_summary(test, better, worse, f"{numbers['bin_size']:,}-episode bin", " bins")
    rows = [
        (
            f"{int(r.episodes):,}",
            f"{fmt(r.mean_better)} (n={r.n_better})",
            f"{fmt(r.mean_worse)} (n={r.n_worse})",
            fmt(r.t),
            fmt_p(r.p),
            "yes" if r.significant else "no",
        )
        for r in test.itertuples()
    ]
    header = ("bin end (episodes)", condition_label(better), condition_label(worse), "t", "p")
    return lines + markdown_table((*header, "p < alpha"), rows)


MAIN_COMPARISON = (
    "The numbers below and Fig. 2a come from one computation, `curious.analysis."
    "main_comparison`: each run's test rollouts pooled per {bin:,}-episode bin "
    "(`analysis.binned_success`, {n} bins), the mean ± std across seeds per bin, "
    "the last bin every run completed, and a one-tailed Welch's t-test per bin."
)


def _area_under_success(e: Experiment, tests: pd.DataFrame) -> list[str]:
    """Per condition: each seed's test success averaged over every epoch of the common budget
    (`analysis.area_under_success`), and the one-tailed Welch test on it: a reading of the
    comparison that depends on no bin edges."""
    area = analysis.area_under_success(tests)
    rows = [
        (
            condition_label(condition),
            ", ".join(fmt(v) for v in group.sort_values("seed")["value"]),
            mean_std(group["value"]),
        )
        for condition, group in in_order(area, e).groupby("condition", observed=True, sort=False)
    ]
    budget = int(area["episodes"].iat[0])
    lines = [
        "Test success averaged over every epoch of the first "
        f"{budget:,} episodes, per seed (the area under each seed's Fig. 2a curve over the "
        "budget, `analysis.area_under_success`; no bins):",
        "",
        *markdown_table(("condition", "per seed", "mean ± std"), rows),
    ]
    if e.compare is not None:
        test = analysis.welch_per_bin(area, *e.compare)
        if not test.empty:
            r = test.iloc[0]
            verdict = "significant" if r.significant else "not significant"
            lines += [
                f"One-tailed Welch's t-test, {condition_label(e.compare[0])} > "
                f"{condition_label(e.compare[1])}, on it: t = {fmt(r.t)}, p = {fmt_p(r.p)}, "
                f"{verdict} at alpha = {analysis.ALPHA:g} (n = {r.n_better} and {r.n_worse}).",
                "",
            ]
    return lines


def episodes_to_success_table(e: Experiment, tests: pd.DataFrame) -> list[str]:
    """Per condition and seed: the episodes each achievable module needed to reach each level of
    test success (`analysis.episodes_to_test_success`)."""
    table = analysis.episodes_to_test_success(tests)
    levels = sorted(set(table["level"]))
    modules = list(dict.fromkeys(table["module"].astype(str)))
    rows = []
    for (condition, seed), group in in_order(table, e).groupby(
        ["condition", "seed"], observed=True, sort=False
    ):
        got = group.set_index(["module", "level"])["episodes"]
        cells = [" / ".join(fmt_episodes(got[(m, v)]) for v in levels) for m in modules]
        last = int(group["last_episodes"].max())
        rows.append((condition_label(condition), seed, *cells, f"{last:,}"))
    header = ("condition", "seed", *map(module_label, modules), "tested up to")
    return [
        "Episodes to reach test success "
        f"{' / '.join(fmt(v, 1) for v in levels)} on each achievable module, per seed: the "
        "first epoch whose test rollouts on the module, pooled over the last "
        f"{table.attrs['window']} epochs, succeed that often (– : not within the run). Read "
        "with Fig. 2a's scoring (HER: its whole goal met).",
        "",
        *markdown_table(header, rows),
    ]


OWN_GOAL_TEXT = (
    "Each achievable module's own part of the goal met, over every test rollout of the run that "
    "named the module (`module_success` of tests.parquet, `analysis.module_success_rates(tests, "
    'epochs=None, score="module_success")`; rollouts in brackets). It is the condition\'s score '
    "where the condition scores one module per episode; for HER, scored on its whole goal at "
    "once, it is a per-module view of its rollouts, never the paper's score."
)


def _per_module_table(
    e: Experiment, rates: pd.DataFrame, cell: Callable[[Any], str], last: bool
) -> list[str]:
    """A table of an `analysis.module_success_rates` table: one row per condition and seed,
    `cell(row)` per achievable module in slot order, and with `last` the run's last test."""
    modules = list(dict.fromkeys(rates["module"].astype(str)))
    rows = []
    for (condition, seed), group in in_order(rates, e).groupby(
        ["condition", "seed"], observed=True, sort=False
    ):
        got = {str(r.module): r for r in group.itertuples()}
        cells = [cell(got[m]) if m in got else "–" for m in modules]
        tail = [f"{int(group['episodes'].max()):,}"] if last else []
        rows.append((condition_label(condition), seed, *cells, *tail))
    header = ("condition", "seed", *map(module_label, modules))
    return markdown_table((*header, "last tested at") if last else header, rows)


def module_success_tables(e: Experiment, tests: pd.DataFrame) -> list[str]:
    """Per condition and seed: each achievable module's test success over the run's last
    epochs (where it stands at the end, Fig. 2a's scoring), and the share of all the run's test
    rollouts on the module that met the module's own goal (`module_success`: HER's per-module
    view, never the paper's score)."""
    end = analysis.module_success_rates(tests, DEFAULT_TEST_EPOCHS)
    own = analysis.module_success_rates(tests, epochs=None, score="module_success")
    return [
        f"Test success on each achievable module over the last {DEFAULT_TEST_EPOCHS} epochs of "
        "each run, where it stands at the end (`analysis.module_success_rates`; test rollouts in "
        "brackets; Fig. 2a's scoring, HER: its whole goal met):",
        "",
        *_per_module_table(e, end, lambda r: f"{fmt(r.value)} ({r.n_tests})", last=True),
        OWN_GOAL_TEXT,
        "",
        *_per_module_table(
            e,
            own,
            lambda r: "–" if r.n_tests == 0 else f"{100 * r.value:.1f} % ({r.n_tests:,})",
            last=False,
        ),
    ]


def learning_order_table(e: Experiment, table: pd.DataFrame) -> list[str]:
    """Per run: the order in which its modules' competence crossed `ORDER_LEVEL`, against the
    paper's (`analysis.learning_order`)."""
    crossings = analysis.competence_crossings(table, level=ORDER_LEVEL)
    order = analysis.learning_order(crossings)
    first = crossings.set_index(["run", "module"])["episode"]
    modules = list(dict.fromkeys(crossings["module"].astype(str)))
    rows = []
    for r in in_order(order, e).itertuples():
        cells = [fmt_episodes(first[(r.run, m)]) for m in modules]
        verdict = "–" if pd.isna(r.follows_paper) else ("yes" if r.follows_paper else "no")
        rows.append((condition_label(r.condition), r.seed, *cells, r.order or "none", verdict))
    header = ("condition", "seed", *map(module_label, modules), "order", "as the paper")
    paper = " → ".join(" and ".join(group) for group in analysis.PAPER_ORDER)
    return [
        f"Order of learning: the first episode at which each module's competence reached "
        f"{fmt(ORDER_LEVEL, 1)} over a full window of its self-evaluations (– : not within the "
        f"run), and whether the order agrees with the paper's ({paper}, the last two in either "
        "order; a module not reached counts as after those reached).",
        "",
        *markdown_table(header, rows),
    ]


def main(repro: Reproduction, e: Experiment, tables: ExperimentTables) -> list[str]:
    """The main comparison's section: Fig. 2a and its statistics from the test rollouts, Fig.
    2b, 2c and Table 1, the order of learning, then spontaneous forgetting."""
    tested = tables.tests is not None
    lines = [*lead_figure(repro, e, tested)]
    points = tables.points
    if tables.tests is None or points is None:  # both or neither
        lines += [NO_TESTS, ""]
    else:
        compare = e.compare if e.compare is not None else (None, None)
        numbers = analysis.main_comparison(tables.tests, *compare)
        n_bins = numbers["points"]["episodes"].nunique()
        lines += [MAIN_COMPARISON.format(bin=numbers["bin_size"], n=n_bins), ""]
        lines += _final_by_condition(e, numbers)
        if e.compare is not None:
            lines += _welch_points(numbers, *e.compare)
        lines += _area_under_success(e, tables.tests)
        lines += episodes_to_success_table(e, tables.tests)
        lines += module_success_tables(e, tables.tests)
    lines += other_figures(repro, e, tested)
    lines += learning_order_table(e, tables.metrics)
    lines += spontaneous_forgetting(e, tables.metrics)
    return lines
