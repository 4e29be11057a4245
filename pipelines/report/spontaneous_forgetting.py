"""Spontaneous forgetting (C3), read in every experiment whose runs nothing perturbs: each
module's mastery, its deepest fall, and every drop of a mastered module with its response."""

from __future__ import annotations

import math

import pandas as pd

from curious import analysis
from curious.analysis.palette import condition_label, module_label
from curious.reproduction.experiments import Experiment
from pipelines.report.blocks import fmt, fmt_episodes, in_order, markdown_table


def spontaneous_forgetting(e: Experiment, table: pd.DataFrame) -> list[str]:
    """Spontaneous forgetting (`analysis.mastery_drops`): per run, each achievable module's
    mastery and deepest fall after it, and every drop of a mastered module with its response."""
    read = analysis.mastery(table)
    drops = analysis.mastery_drops(table)
    windows = sorted({int(w) for w in table["lp_window"].dropna()})
    hold = (
        f"{math.ceil(analysis.MASTERY_HOLD * windows[0])} consecutive self-evaluations (a "
        f"window: {windows[0]})"
        if len(windows) == 1
        else f"{analysis.MASTERY_HOLD:g} of a window of consecutive self-evaluations"
    )
    lines = [
        "### Spontaneous forgetting",
        "",
        "The paper's Fig. 2b: a mastered module's competence drops, its "
        "LP rises, the agent practises it more. Rule (`curious.analysis.drops`, fixed before "
        "the runs were read): a module is mastered once its competence, over a full window of "
        f"its self-evaluations, has stood at or above {fmt(analysis.MASTERED, 1)} for {hold}; "
        f"a drop is a fall of {fmt(analysis.DROP_DEPTH, 1)} or more below its peak since "
        f"mastery; it recovers when back at {fmt(analysis.MASTERED, 1)}. Per run and "
        "achievable module: the episode it was first mastered and the deepest fall of its "
        "competence below its peak while mastered (– : never mastered; HER has no "
        "self-evaluations, so no competence).",
        "",
    ]
    modules = list(dict.fromkeys(read["module"].astype(str)))
    with_variant = table["variant"].nunique() > 1
    rows = []
    for _, group in in_order(read, e).groupby("run", observed=True, sort=False):
        first = group.iloc[0]
        by_module = group.set_index("module")
        cells = []
        for m in modules:
            if m not in by_module.index or pd.isna(by_module.at[m, "mastered_episode"]):
                cells.append("–")
            else:
                r = by_module.loc[m]
                cells.append(f"{int(r.mastered_episode):,} ({fmt(r.deepest_fall)})")
        evaluated = bool(group["evaluated"].any())
        found = int(group["n_drops"].sum())
        mastered = int(group["mastered_episodes"].sum())
        row = [condition_label(first["condition"]), first["seed"]]
        if with_variant:
            row.insert(1, first["variant"])
        rows.append(
            (
                *row,
                *cells,
                f"{mastered:,}" if evaluated else "–",
                str(found) if evaluated else "no self-evaluations",
            )
        )
    header: tuple[str, ...] = ("condition", "seed")
    if with_variant:
        header = ("condition", "variant", "seed")
    header += (
        *(f"{module_label(m)}: mastered at (deepest fall)" for m in modules),
        "module-episodes mastered",
        "drops",
    )
    lines += markdown_table(header, rows)
    lines += mastery_summary(e, read)
    if drops.empty:
        return [*lines, "No drop of a mastered module in these runs.", ""]
    rows = [
        (
            condition_label(r.condition),
            r.seed,
            module_label(str(r.module)),
            f"{int(r.drop_episode):,}",
            f"{fmt(r.peak)} → {fmt(r.trough)} at {int(r.trough_episode):,}",
            f"{fmt(r.lp_before)} → {fmt(r.lp_trough)}",
            f"{fmt(r.p_lp_before)} → {fmt(r.p_lp_after)}",
            f"{r.practice_before:.0%} → {r.practice_after:.0%}",
            fmt_episodes(r.recovery_episodes) if r.recovered else "not by the run's end",
        )
        for r in in_order(drops, e).itertuples()
    ]
    header = (
        "condition",
        "seed",
        "module",
        "drop at episode",
        "peak → trough",
        "LP before → at trough",
        "p_LP before → after",
        "practised before → after",
        "episodes to recover",
    )
    return [
        *lines,
        "Each drop: where it was detected, its depth, and the module's mean LP, mean p_LP and "
        "share of episodes practising it over its course (start of the fall to recovery) "
        "against as many mastered episodes before it.",
        "",
        *markdown_table(header, rows),
    ]


def mastery_summary(e: Experiment, read: pd.DataFrame) -> list[str]:
    """Per condition and variant of `analysis.mastery`'s table (`read`), the runs that
    self-evaluate: how many of their achievable modules were mastered, the module-episodes read
    as mastered, the deepest fall below a peak while mastered (which module, which seed) and the
    drops."""
    rows = []
    evaluated = read[read["evaluated"].astype(bool)]
    for (condition, variant), group in in_order(evaluated, e).groupby(
        ["condition", "variant"], observed=True, sort=False
    ):
        mastered = group.dropna(subset=["mastered_episode"])
        deepest = "–"
        if not mastered.empty:
            worst = mastered.loc[mastered["deepest_fall"].idxmax()]
            deepest = fmt(worst["deepest_fall"])
            if deepest != fmt(0.0):  # which module fell, where any did
                deepest += f" ({module_label(str(worst['module']))}, seed {int(worst['seed'])})"
        rows.append(
            (
                condition_label(condition),
                variant,
                group["run"].nunique(),
                f"{len(mastered)} of {len(group)}",
                f"{int(group['mastered_episodes'].sum()):,}",
                deepest,
                int(group["n_drops"].sum()),
            )
        )
    header = (
        "condition",
        "variant",
        "runs",
        "achievable modules mastered",
        "module-episodes read as mastered",
        "deepest fall below the peak while mastered",
        "drops",
    )
    return ["Per condition:", "", *markdown_table(header, rows)]
