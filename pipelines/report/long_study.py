"""The long runs' section (C3 over the paper's episode count): the figure, spontaneous forgetting
read by the rules fixed before the runs (`analysis.mastery_drops`, `analysis.dip_responses`),
and the dips' test over every CURIOUS run that nothing perturbs, the long runs and the others."""

from __future__ import annotations

from pathlib import PurePath

import pandas as pd

from curious import analysis
from curious.reproduction.experiments import Experiment
from curious.watching.palette import condition_label, module_label
from pipelines.report.blocks import (
    ExperimentTables,
    fmt,
    in_order,
    lead_figure,
    markdown_table,
    other_figures,
)
from pipelines.report.spontaneous_forgetting import dip_clauses, spontaneous_forgetting
from pipelines.resources import Reproduction

UNPERTURBED = ("main", "distractors", "long")
"""The experiments whose runs nothing perturbs: their CURIOUS runs are pooled for the dips' test."""


DECIDING_SEEDS: dict[str, tuple[int, ...]] = {"long": (0, 1, 2, 3, 4), "distractors": (0, 1, 2)}
"""The runs the dips' test decides on, named before the first long run shipped (docs/results.md,
C3's rules, "While the long runs train"): CURIOUS's long runs of these seeds, each standing for
the main comparison's run of its seed, and these seeds of every distractors variant. A pool that
lacks one of them decides nothing; runs beyond them are read beside the verdict."""

Unit = tuple[str, str, int]
"""A unit of the dips' test: (experiment, variant, seed)."""


def units(pooled: pd.DataFrame) -> dict[Unit, str]:
    """Each run of a `longest_per_seed` pool as its unit, the run's folder the value."""
    runs = pooled.groupby("run", observed=True, sort=True)[["variant", "seed"]].first()
    return {
        (PurePath(str(run)).parts[-3], str(r.variant), int(r.seed)): str(run)
        for run, r in runs.iterrows()
    }


def deciding_units(repro: Reproduction) -> set[Unit]:
    """The units `DECIDING_SEEDS` names, for the variants of each experiment the budget plans
    (those the report holds and those it left out)."""
    named = set()
    for name, seeds in DECIDING_SEEDS.items():
        e = repro.budget.experiments.get(name)
        if e is not None:
            variants = (*e.variants, *e.left_out_variants)
            named |= {(name, v, s) for v in variants for s in seeds}
    return named


def pooled_dips(repro: Reproduction, condition: str = "curious") -> list[str]:
    """The sign-flip test of the dips' excess (at `analysis.TEST_DEPTH`, and at the other
    depths beside), a run of ``condition`` of every unperturbed experiment the report holds
    being one unit; then, where that pool is not the one the test decides on
    (`DECIDING_SEEDS`), what it lacks, or the verdict on the deciding runs alone."""
    present = [name for name in UNPERTURBED if repro.layout.metrics(name).is_file()]
    if not present:
        return []
    tables = [pd.read_parquet(repro.layout.metrics(name)) for name in present]
    pooled = pd.concat([t[t["condition"] == condition] for t in tables], ignore_index=True)
    if pooled.empty:
        return []
    left_out = analysis.shorter_of_seed(pooled)
    pooled = analysis.longest_per_seed(pooled)
    held = units(pooled)
    named = deciding_units(repro) if condition == "curious" else set()
    lacking, beyond = sorted(named - held.keys()), sorted(held.keys() - named)
    whole = bool(named) and not lacking
    read = ", ".join(present)
    lines = [
        f"The dips' test over every {condition_label(condition)} run that nothing perturbs in "
        f"this report ({len(held)} runs of {read}), a run one unit"
        + (f" ({_seed_units(left_out)})" if len(left_out) else "")
        + ":",
        "",
        *_by_depth(pooled, decides=whole and not beyond),
    ]
    if lacking:
        lines += [
            f"It decides nothing: the test decides once, on {len(named)} runs named before the "
            "long runs shipped (docs/results.md, C3's rules), and this report lacks "
            f"{len(lacking)} of them: {_unit_names(lacking)}.",
            "",
        ]
    elif named and beyond:
        kept = [held[u] for u in named]
        lines += [
            f"The verdict, on the {len(named)} runs named before the long runs shipped "
            f"(docs/results.md, C3's rules), without {_unit_names(beyond)}:",
            "",
            *_by_depth(pooled[pooled["run"].astype(str).isin(kept)], decides=True),
        ]
    return lines


def _by_depth(pooled: pd.DataFrame, decides: bool) -> list[str]:
    """The test's clauses at each depth of `analysis.DIP_DEPTHS`, the tested one marked as
    deciding where `decides`."""
    lines = []
    for depth in analysis.DIP_DEPTHS:
        clauses = dip_clauses(analysis.dip_responses(pooled, depth))
        mark = ""
        if depth == analysis.TEST_DEPTH:
            mark = (
                f" (the test that decides, alpha = {analysis.ALPHA:g})"
                if decides
                else " (the depth tested; this reading does not decide)"
            )
        lines += [f"- at a depth of {depth:g}{mark}: {'; '.join(clauses)}.", ""]
    return lines


def _unit_names(found: list[Unit]) -> str:
    """Units as experiment/variant seed K, in a clause."""
    return ", ".join(
        f"{name} seed {seed}" if variant == "default" else f"{name} {variant} seed {seed}"
        for name, variant, seed in found
    )


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
    the dips' test pooled over the unperturbed experiments, then each mastered module's lowest
    competence past the main comparison's end."""
    return [
        *lead_figure(repro, e),
        *other_figures(repro, e),
        *spontaneous_forgetting(e, tables.metrics),
        *pooled_dips(repro),
        *past_the_main_runs(repro, e, tables.metrics),
    ]


def past_the_main_runs(repro: Reproduction, e: Experiment, table: pd.DataFrame) -> list[str]:
    """Per long run and module mastered before the main comparison's end: its lowest competence
    from there to the run's end, and over the episodes where the paper saw T3 forgotten
    (`analysis.lowest_competence`): how near a drop the modules came where no run of the main
    comparison reached, drops or none."""
    main = repro.budget.experiments.get("main")
    start, stop = analysis.PAPER_FORGETTING_WINDOW
    if main is None or e.total_episodes < stop:
        return []
    read = analysis.mastery(table)
    after = analysis.lowest_competence(table, main.total_episodes, read=read)
    window = analysis.lowest_competence(table, start, stop, read=read)
    if after.empty:
        return []
    by_window = window.set_index(["run", "module"])
    rows = []
    for r in in_order(after, e).itertuples():
        key = (r.run, r.module)
        near = by_window.loc[key] if key in by_window.index else None
        rows.append(
            (
                condition_label(r.condition),
                r.seed,
                module_label(str(r.module)),
                f"{r.mastered_episode:,}",
                f"{fmt(r.low)} at {r.low_episode:,}",
                "–" if near is None else f"{fmt(near['low'])} at {int(near['low_episode']):,}",
            )
        )
    header = (
        "condition",
        "seed",
        "module",
        "mastered at",
        f"lowest competence from episode {main.total_episodes:,} (at)",
        f"lowest from {start:,} to {stop:,} (at)",
    )
    return [
        f"#### Past the main comparison's {main.total_episodes:,} episodes",
        "",
        "Per run and module mastered before the main comparison's runs end: the lowest "
        "competence from there to the run's end, and over episodes "
        f"{start:,} to {stop:,}, where the paper saw T3 (cube 1 above cube 2) forgotten "
        "(`curious.analysis.lowest_competence`; a reading beside the drop rule, never part of it).",
        "",
        *markdown_table(header, rows),
    ]
