"""The pieces every section of `report.md` is written with: numbers and tables as Markdown,
figures, the order of rows, the Welch summary sentence, and an experiment's combined tables."""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from curious import analysis
from curious.analysis.formatting import format_p, format_value
from curious.reproduction.experiments import Experiment
from curious.reproduction.figures import FigureSpec, figures_of
from curious.watching.palette import condition_label
from pipelines.resources import Reproduction


@dataclass
class ExperimentTables:
    """One experiment's combined tables: the metrics, and the test rollouts where the runs have
    them, with what several parts of the report read drawn from those once."""

    metrics: pd.DataFrame
    tests: pd.DataFrame | None

    @functools.cached_property
    def points(self) -> pd.DataFrame | None:
        """`analysis.epoch_success` of the test rollouts (None without them)."""
        return None if self.tests is None else analysis.epoch_success(self.tests)

    @functools.cached_property
    def final(self) -> pd.DataFrame:
        """`analysis.final_competence` of the runs."""
        return analysis.final_competence(self.metrics)

    @functools.cached_property
    def final_tested(self) -> pd.DataFrame | None:
        """`analysis.final_test_success` of the test rollouts (None without them)."""
        return None if self.tests is None else analysis.final_test_success(self.tests)


def fmt(value: float, digits: int = 2) -> str:
    """A number to `digits` decimals, or – where there is none (`analysis.formatting`)."""
    return format_value(value, digits)


def mean_std(values: Sequence[float]) -> str:
    """``"0.82 ± 0.04 (3 seeds)"`` over the finite values, one seed said as such, none as –."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return "–"
    if v.size == 1:
        return f"{v[0]:.2f} (1 seed)"
    return f"{v.mean():.2f} ± {v.std(ddof=1):.2f} ({v.size} seeds)"


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> list[str]:
    """A Markdown table's lines, with the blank line that ends it."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return [*lines, ""]


def figure(repro: Reproduction, e: Experiment, spec: FigureSpec, tested: bool = True) -> list[str]:
    """A figure of `e`'s image linked relatively (the output folder moves whole) with its
    caption and SVG, or a line saying it has not been drawn; `tested=False`: the runs have no
    test rollouts, so a figure with a test success panel was drawn without it."""
    stem = spec.stem(e.name)
    png = repro.layout.figures / f"{stem}.png"
    if not png.is_file():
        return [f"*Figure `{stem}` has not been drawn yet.*", ""]
    rel = png.relative_to(repro.layout.out).as_posix()
    svg = Path(rel).with_suffix(".svg").as_posix()
    return [f"![{stem}]({rel})", "", f"{spec.caption(tested)} ([SVG]({svg}))", ""]


def lead_figure(repro: Reproduction, e: Experiment, tested: bool = True) -> list[str]:
    """The first figure of `e` the report shows (`curious.reproduction.figures`), which opens
    its section."""
    shown = figures_of(e.name, in_report=True)
    return figure(repro, e, shown[0], tested) if shown else []


def other_figures(repro: Reproduction, e: Experiment, tested: bool = True) -> list[str]:
    """The figures of `e` the report shows after its first, in registration order (a plugin's
    figure of a built-in experiment among them)."""
    return [
        line
        for spec in figures_of(e.name, in_report=True)[1:]
        for line in figure(repro, e, spec, tested)
    ]


def fmt_episodes(value: object) -> str:
    """An episode count, or – where there is none (NaN or NA)."""
    return "–" if pd.isna(value) or not math.isfinite(float(value)) else f"{float(value):,.0f}"


def fmt_p(value: float) -> str:
    """A p-value as every page prints it, or – where untested (`analysis.formatting`)."""
    return format_p(value)


def in_order(frame: pd.DataFrame, e: Experiment) -> pd.DataFrame:
    """Rows by the experiment's order of conditions, then seed."""
    rank = {c: i for i, c in enumerate(e.conditions)}
    key = frame["condition"].astype(str).map(rank).fillna(len(rank))
    return (
        frame.assign(_rank=key).sort_values(["_rank", "seed"], kind="stable").drop(columns="_rank")
    )


def welch_summary(
    test: pd.DataFrame, better: str, worse: str, what: str, unit: str = ""
) -> list[str]:
    """One sentence on a table of `analysis.welch_per_bin` results."""
    tested = int(test["p"].notna().sum())
    text = (
        f"One-tailed Welch's t-test per {what}, {condition_label(better)} > "
        f"{condition_label(worse)}, alpha = {analysis.ALPHA:g}: significant in "
        f"{int(test['significant'].sum())} of {len(test)}{unit}"
    )
    if tested > 1:
        text += (
            f", in {int(test['significant_holm'].sum())} of {len(test)} after Holm's correction "
            f"for the {tested} tests"
        )
    if tested == 0 and len(test):
        few = int(min(test["n_better"].min(), test["n_worse"].min())) < 2
        why = "fewer than two seeds a side" if few else "no variance across seeds"
        text += f" (none could be tested: {why})"
    elif tested < len(test):
        text += f" ({len(test) - tested} could not be tested: fewer than two seeds or no variance)"
    return [text + ".", ""]


NO_TESTS = (
    "These runs have no test rollouts (`tests.parquet`: trained before test rollouts were "
    "logged, or with `test_rollouts_per_worker=0`), so Fig. 2a and its statistics, which the "
    "paper measured on test rollouts, are not reported; retrain the runs."
)
