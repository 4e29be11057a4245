"""`report.md` as a whole: the opening, then one section per experiment the tables hold."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from curious.reproduction.experiments import Experiment, ReproduceBudget
from pipelines.from_data import ShippedData
from pipelines.report.blocks import ExperimentTables, lead_figure, other_figures
from pipelines.report.distracting_modules import distractors
from pipelines.report.long_study import long_runs
from pipelines.report.lp_studies import lp_uses, signed_lp
from pipelines.report.main_comparison import main
from pipelines.report.overview import budgets, built_from, compute, runs_table, software
from pipelines.report.sensory_failures import sensor_failure, sensor_failure_mastered
from pipelines.resources import Reproduction

SECTIONS = {
    "main": main,
    "distractors": distractors,
    "sensor_failure": sensor_failure,
    "sensor_failure_mastered": sensor_failure_mastered,
    "long": long_runs,
    "lp_uses": lp_uses,
    "signed_lp": signed_lp,
}
"""The section of each built-in experiment; another (a plugin's) shows its figures
(`figures_only`)."""


def figures_only(repro: Reproduction, e: Experiment, tables: ExperimentTables) -> list[str]:
    """The section of an experiment without one of its own: its figures the report shows."""
    tested = tables.tests is not None
    return [*lead_figure(repro, e, tested), *other_figures(repro, e, tested)]


def _shown_anyway(repro: Reproduction, e: Experiment) -> str:
    """The runs of left-out variants the figure and the table still show, in a sentence."""
    extra = repro.left_out_runs(e)
    if not extra:
        return ""
    names = ", ".join("/".join(p.parts[-3:]) for p in extra)
    return (
        f" The finished runs shipped of those ({names}) are drawn in the figure and listed in "
        "the table below, without a test."
    )


def _not_read(data: ShippedData, budget: ReproduceBudget, missing: list[str]) -> list[str]:
    """What a report built from shipped `data` says of the `budget`'s experiments it does not
    read: those the data holds whole, left out by `--experiments`, apart from those not shipped."""
    shipped = [name for name in missing if not data.missing(budget.experiments[name])]
    unshipped = [name for name in missing if name not in shipped]
    lines = []
    if shipped:
        lines += [
            f"Not in this report (shipped, left out by `--experiments`): {', '.join(shipped)}; "
            "the same command with them in `--experiments`, or without it, reads them.",
            "",
        ]
    if unshipped:
        lines += [
            f"Not in this report (not shipped yet): {', '.join(unshipped)}, whose runs the data "
            "this report was built from does not hold all finished; `curious reproduce --budget "
            f"{budget.name} --experiments {','.join(unshipped)}` trains them.",
            "",
        ]
    return lines


def write_report(repro: Reproduction) -> tuple[Path, list[str]]:
    """Write report.md for every experiment whose metrics table exists; returns (path, names)."""
    layout, budget = repro.layout, repro.budget
    tables = {
        name: pd.read_parquet(layout.metrics(name))
        for name in budget.experiments
        if layout.metrics(name).is_file()
    }
    by_experiment = {
        name: ExperimentTables(
            table,
            pd.read_parquet(layout.tests(name)) if layout.tests(name).is_file() else None,
        )
        for name, table in tables.items()
    }
    included = [budget.experiments[name] for name in tables]
    lines = [
        f"# CURIOUS reproduction — budget `{budget.name}`",
        "",
        *built_from(budget, tables),
        budget.notes,
        "",
    ]
    if budget.omitted:
        lines += [" ".join(budget.why_absent(name) for name in budget.omitted), ""]
    if not included:
        lines += ["No experiment has finished yet.", ""]
    else:
        lines += software(tables)
        lines += ["## Budgets", ""]
        lines += budgets(repro, included)
        lines += compute(tables)
        lines += [
            "Fig. 2a and the main comparison's numbers are the success of the test rollouts "
            "(noise-free, after every epoch, modules drawn uniformly), pooled over those on the "
            "achievable modules, as in the paper; the other figures and numbers read the "
            "competence (the moving success rate of the agent's self-evaluations). x axes count "
            "training episodes (self-evaluations included, test rollouts not).",
            "",
        ]
    for e in included:
        lines += [f"## {e.title}", ""]
        if e.left_out_variants:
            lines += [
                f"Variants left out: {', '.join(e.left_out_variants)}, whose runs the data this "
                f"report was built from does not hold finished; read from "
                f"{', '.join(e.variants)} alone.{_shown_anyway(repro, e)}",
                "",
            ]
        if e.left_out_seeds:
            kept = ", ".join(map(str, e.seeds))
            lines += [
                f"Seeds left out: {', '.join(map(str, e.left_out_seeds))}, whose runs the data "
                f"this report was built from does not hold all finished; read from "
                f"{'seed' if len(e.seeds) == 1 else 'seeds'} {kept} alone.",
                "",
            ]
        if e.extra_seeds:
            extra, own = e.extra_seeds, sorted(e.budget_seeds + e.left_out_seeds)
            lines += [
                f"Seeds beyond the budget's: {', '.join(map(str, extra))} (the budget trains "
                f"{', '.join(map(str, own))}), trained with the budget's settings in all but the "
                f"seed; read with the others, {len(e.seeds)} seeds of every condition.",
                "",
            ]
        if repro.data is not None and (waiting := repro.data.waiting_runs(e)):
            lines += [
                f"Shipped, not read yet: {', '.join(waiting)}, of a seed beyond the budget's "
                "that is read once all its runs of this experiment are shipped finished; "
                f"still to ship: {', '.join(repro.data.awaited_runs(e))}.",
                "",
            ]
        lines += SECTIONS.get(e.name, figures_only)(repro, e, by_experiment[e.name])
        lines += ["### Runs", "", *runs_table(by_experiment[e.name])]
    missing = [name for name in budget.experiments if name not in tables]
    if missing and included and repro.data is not None:
        lines += _not_read(repro.data, budget, missing)
    elif missing and included:
        command = f"`curious reproduce --budget {budget.name} --experiments {','.join(missing)}`"
        lines += [
            f"Not in this report (not reproduced yet): {', '.join(missing)}; run {command}.",
            "",
        ]
    layout.out.mkdir(parents=True, exist_ok=True)
    tmp = layout.report.with_name(f".{layout.report.name}.tmp")
    tmp.write_text("\n".join(lines).rstrip() + "\n", encoding="utf-8")
    tmp.replace(layout.report)
    return layout.report, [e.name for e in included]
