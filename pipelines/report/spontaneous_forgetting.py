"""Spontaneous forgetting (C3), read in every experiment whose runs nothing perturbs: each
module's mastery, its deepest fall, and every drop of a mastered module with its response."""

from __future__ import annotations

import math

import pandas as pd

from curious import analysis
from curious.reproduction.experiments import Experiment
from curious.watching.palette import condition_label, module_label
from pipelines.report.blocks import fmt, fmt_episodes, fmt_p, in_order, markdown_table


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
        "its self-evaluations, has stood at or above "
        f"{fmt(analysis.MASTERED_COMPETENCE, 1)} for {hold}; "
        f"a drop is a fall of {fmt(analysis.DROP_DEPTH, 1)} or more below its peak since "
        f"mastery; it recovers when back at {fmt(analysis.MASTERED_COMPETENCE, 1)}. Per run and "
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
        return [*lines, "No drop of a mastered module in these runs.", "", *dips_reading(e, table)]
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
        *dips_reading(e, table),
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


DIPS_RULE = (
    "Dips, C3's mechanism at any size (`curious.analysis.dips`, rule fixed before the runs were "
    "read for dips): from a module's mastery on, a dip of depth d is detected where its "
    "competence falls d below its peak since the mastery (or the last dip), and ends back within "
    "d/2 of it. Its response is the change in the module's mean p_LP and share of practice from "
    "the {window:,} episodes before the detection to the {window:,} from it; its excess, that "
    "change minus the mean change over the same module's windows without a dip (every "
    "{window:,}th episode from its mastery). A dip whose windows reach before the mastery or "
    "past the run's end is not read."
)


def _dip_sentence(test: dict, what: str) -> str:
    """One condition's `analysis.dip_test` in a clause."""
    if not test["n_runs"]:
        return f"{what}: no dip read"
    runs, dips = test["n_runs"], test["n_dips"]
    return (
        f"{what}: mean excess {test['mean']:+.3f} over {runs} run{'s' * (runs != 1)} with a "
        f"read dip ({dips} dip{'s' * (dips != 1)}; above 0 in {test['n_positive']}), exact "
        f"sign-flip p = {fmt_p(test['p'])}"
    )


def dip_clauses(found: pd.DataFrame) -> list[str]:
    """The sign-flip test of a `dip_responses` table's excess in p_LP and in practice, a clause
    each."""
    return [
        _dip_sentence(analysis.dip_test(found, column), what)
        for column, what in (("excess_p_lp", "p_LP"), ("excess_practice", "practice"))
    ]


def dips_reading(e: Experiment, table: pd.DataFrame) -> list[str]:
    """Per depth of `analysis.DIP_DEPTHS`: the dips each rule finds, the read ones with their
    response and excess, and per condition the sign-flip test of the excess by run."""
    lines = ["#### Dips", "", DIPS_RULE.format(window=analysis.DIP_WINDOW), ""]
    with_variant = table["variant"].nunique() > 1
    for depth in analysis.DIP_DEPTHS:
        found = analysis.dip_responses(table, depth)
        counts = found["status"].value_counts()
        tested = " (the depth tested)" if depth == analysis.TEST_DEPTH else ""
        parts = [
            f"{counts.get(status, 0)} {words}"
            for status, words in DIP_STATUS_WORDS.items()
            if counts.get(status, 0)
        ]
        lines += [
            f"At a depth of {depth:g}{tested}: {len(found)} dip{'s' * (len(found) != 1)}"
            + (f" ({', '.join(parts)})." if parts else "."),
            "",
        ]
        read = in_order(found[found["status"] == "read"], e)
        if read.empty:
            continue
        rows = []
        for r in read.itertuples():
            row = [condition_label(r.condition), r.seed, module_label(str(r.module))]
            if with_variant:
                row.insert(1, r.variant)
            rows.append(
                (
                    *row,
                    f"{int(r.detect_episode):,}",
                    f"{fmt(r.peak)} → {fmt(r.trough)}",
                    f"{r.p_lp_change:+.3f} ({r.matched_p_lp_change:+.3f})",
                    f"{r.practice_change:+.3f} ({r.matched_practice_change:+.3f})",
                    f"{r.excess_p_lp:+.3f}",
                    f"{r.excess_practice:+.3f}",
                )
            )
        header: tuple[str, ...] = ("condition", "seed", "module")
        if with_variant:
            header = ("condition", "variant", "seed", "module")
        header += (
            "detected at",
            "peak → trough",
            "p_LP change (matched)",
            "practice change (matched)",
            "excess p_LP",
            "excess practice",
        )
        lines += markdown_table(header, rows)
        for condition in dict.fromkeys(read["condition"].astype(str)):
            own = found[found["condition"] == condition]
            clauses = dip_clauses(own)
            lines += [f"{condition_label(condition)}, by run: {'; '.join(clauses)}.", ""]
    return lines


DIP_STATUS_WORDS = {
    "read": "read",
    "before_mastery": "too soon after the mastery to read",
    "past_end": "too late in the run to read",
    "unmatched": "read but without a matched window",
}
"""How the report counts the dips of each `analysis.dip_responses` status."""
