"""The long runs' section (C3 over the paper's episode count): the figure, spontaneous forgetting
read by the rules fixed before the runs (`analysis.mastery_drops`, `analysis.dip_responses`),
and the dips' test over every CURIOUS run that nothing perturbs, the long runs and the others."""

from __future__ import annotations

from pathlib import PurePath

import pandas as pd

from curious import analysis
from curious.reproduction.experiments import Experiment
from curious.watching.palette import condition_label
from pipelines.report.blocks import ExperimentTables, lead_figure, other_figures
from pipelines.report.spontaneous_forgetting import dip_clauses, spontaneous_forgetting
from pipelines.resources import Reproduction

UNPERTURBED = ("main", "distractors", "long")
"""The experiments whose runs nothing perturbs: their CURIOUS runs are pooled for the dips' test."""


def pooled_dips(repro: Reproduction, condition: str = "curious") -> list[str]:
    """The sign-flip test of the dips' excess (at `analysis.TEST_DEPTH`, and at the other
    depths beside), a run of ``condition`` of every unperturbed experiment the report holds
    being one unit."""
    present = [name for name in UNPERTURBED if repro.layout.metrics(name).is_file()]
    if not present:
        return []
    tables = [pd.read_parquet(repro.layout.metrics(name)) for name in present]
    pooled = pd.concat([t[t["condition"] == condition] for t in tables], ignore_index=True)
    if pooled.empty:
        return []
    left_out = analysis.shorter_of_seed(pooled)
    pooled = analysis.longest_per_seed(pooled)
    runs = pooled["run"].nunique()
    read = ", ".join(present)
    lines = [
        f"The dips' test over every {condition_label(condition)} run that nothing perturbs in "
        f"this report ({runs} runs of {read}), a run one unit"
        + (f" ({_seed_units(left_out)})" if len(left_out) else "")
        + ":",
        "",
    ]
    for depth in analysis.DIP_DEPTHS:
        found = analysis.dip_responses(pooled, depth)
        clauses = dip_clauses(found)
        decides = (
            f" (the test that decides, alpha = {analysis.ALPHA:g})"
            if depth == analysis.TEST_DEPTH
            else ""
        )
        lines += [f"- at a depth of {depth:g}{decides}: {'; '.join(clauses)}.", ""]
    return lines


def _seed_units(left_out: pd.DataFrame) -> str:
    """Which runs the pool leaves out for a longer run of their seed (`analysis.shorter_of_seed`),
    in a clause."""
    pairs = ", ".join(
        f"{_short(r.run)} (for {_short(r.kept)})" for r in left_out.itertuples(index=False)
    )
    return f"one run per condition, variant and seed, the longest; left out: {pairs}"


def _short(run: str) -> str:
    """A run's folder as experiment/condition/seed-K."""
    return "/".join(PurePath(str(run)).parts[-3:])


def long_runs(repro: Reproduction, e: Experiment, tables: ExperimentTables) -> list[str]:
    """The figure of every long run whole, each module's mastery, deepest fall, drops and dips,
    then the dips' test pooled over the unperturbed experiments."""
    return [
        *lead_figure(repro, e),
        *other_figures(repro, e),
        *spontaneous_forgetting(e, tables.metrics),
        *pooled_dips(repro),
    ]
