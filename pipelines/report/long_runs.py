"""The long runs' section (C3 over the paper's episode count): the figure, then spontaneous
forgetting read by the rule fixed before the runs (`analysis.mastery_drops`)."""

from __future__ import annotations

from curious.reproduction.experiments import Experiment
from pipelines.report.blocks import ExperimentTables, figure
from pipelines.report.spontaneous_forgetting import spontaneous_forgetting
from pipelines.resources import Reproduction


def long_runs(repro: Reproduction, e: Experiment, tables: ExperimentTables) -> list[str]:
    """The figure of every long run whole, then each module's mastery, deepest fall and drops."""
    return [*figure(repro, "long_runs"), *spontaneous_forgetting(e, tables.metrics)]
