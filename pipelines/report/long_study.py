"""The long runs' section (C3 over the paper's episode count): the figure, spontaneous forgetting
read by the rules fixed before the runs (`analysis.mastery_drops`, `analysis.dip_responses`),
and the dips' test over every CURIOUS run that nothing perturbs, the long runs and the others."""

from __future__ import annotations

import pandas as pd

from curious import analysis
from curious.analysis.palette import condition_label
from curious.reproduction.experiments import Experiment
from pipelines.report.blocks import ExperimentTables, figure
from pipelines.report.spontaneous_forgetting import _dip_sentence, spontaneous_forgetting
from pipelines.resources import Reproduction

UNPERTURBED = ("main", "distractors", "long")
"""The experiments whose runs nothing perturbs: their CURIOUS runs are pooled for the dips' test."""


def pooled_dips(repro: Reproduction, condition: str = "curious") -> list[str]:
    """The sign-flip test of the dips' excess (at `analysis.TEST_DEPTH`, and at the other
    depths beside), a run of ``condition`` of every unperturbed experiment the report holds
    being one unit."""
    tables = [
        table[table["condition"] == condition]
        for name in UNPERTURBED
        if repro.layout.metrics(name).is_file()
        for table in [pd.read_parquet(repro.layout.metrics(name))]
    ]
    pooled = pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()
    if pooled.empty:
        return []
    runs = pooled["run"].nunique()
    read = ", ".join(n for n in UNPERTURBED if repro.layout.metrics(n).is_file())
    lines = [
        f"The dips' test over every {condition_label(condition)} run that nothing perturbs in "
        f"this report ({runs} runs of {read}), a run one unit:",
        "",
    ]
    for depth in analysis.DIP_DEPTHS:
        found = analysis.dip_responses(pooled, depth)
        clauses = [
            _dip_sentence(analysis.dip_test(found, column), what)
            for column, what in (("excess_p_lp", "p_LP"), ("excess_practice", "practice"))
        ]
        decides = (
            f" (the test that decides, alpha = {analysis.ALPHA:g})"
            if depth == analysis.TEST_DEPTH
            else ""
        )
        lines += [f"- at a depth of {depth:g}{decides}: {'; '.join(clauses)}.", ""]
    return lines


def long_runs(repro: Reproduction, e: Experiment, tables: ExperimentTables) -> list[str]:
    """The figure of every long run whole, each module's mastery, deepest fall, drops and dips,
    then the dips' test pooled over the unperturbed experiments."""
    return [
        *figure(repro, "long_runs"),
        *spontaneous_forgetting(e, tables.metrics),
        *pooled_dips(repro),
    ]
