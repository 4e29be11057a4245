"""The distractors figure (`distractors`): the self-evaluated competence over the achievable
modules at the end of the runs against the number of distracting modules."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from curious.analysis import palette
from curious.analysis.figures.parts import (
    caption,
    finish,
    legend_right,
    ordered_conditions,
    restrict,
    runs_of,
    setting_text,
)
from curious.analysis.loading import (
    AnalysisError,
)
from curious.analysis.statistics import (
    final_competence,
)
from curious.analysis.style import (
    budget_text,
    figure_style,
    new_figure,
    seeds_text,
)


def distractors(
    df: pd.DataFrame,
    conditions: Sequence[str] | None = None,
    at_episode: int | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "distractors",
) -> Figure:
    """Self-evaluated competence over achievable modules at the end of the runs against the
    number of distracting modules.

    One line per condition, mean ± std across seeds (a lone seed drawn as its value), for every
    number of distractors among the runs (their variants may differ; their achievable modules
    must not); the x ticks say how many seeds each setting has. The value is
    `statistics.final_competence` (the mean over the achievable modules of the agent's own
    competence measure, the success rate of its recent self-evaluations), after episode
    ``at_episode``, by default the last episode every run reached.
    """
    conditions = ordered_conditions(df, conditions)
    rows = restrict(df, conditions, None)
    per_run = rows.groupby("run", observed=True)[["achievable_modules"]].first()
    sets = sorted(per_run["achievable_modules"].astype(str).unique())
    if len(sets) > 1:
        raise AnalysisError(
            "the distractors figure needs runs with the same achievable modules, got "
            + "; ".join(f"[{s}]" for s in sets)
        )
    final = final_competence(rows, at_episode)
    clash = final.groupby(["condition", "n_distractors", "seed"], observed=True).size()
    if (clash > 1).any():
        condition, n_d, seed = clash[clash > 1].index[0]
        raise AnalysisError(
            f"condition '{condition}' with {n_d} distractors has several runs of seed {seed}"
        )
    stats_table = (
        final.groupby(["condition", "n_distractors"], observed=True)["value"]
        .agg(mean="mean", std=lambda v: v.std(ddof=1), n="size")
        .reset_index()
    )
    counts = sorted(int(n) for n in final["n_distractors"].unique())
    n_achievable = len(sets[0].split(","))
    offsets = np.linspace(-0.12, 0.12, len(conditions)) if len(conditions) > 1 else [0.0]
    with figure_style():
        fig = new_figure(6.4, 4.2)
        ax = fig.add_subplot()
        for c, dx in zip(conditions, offsets, strict=True):
            s = stats_table[stats_table["condition"] == c].sort_values("n_distractors")
            ax.errorbar(
                s["n_distractors"].to_numpy(dtype=np.float64) + dx,
                s["mean"].to_numpy(dtype=np.float64),
                yerr=s["std"].fillna(0.0).to_numpy(dtype=np.float64),
                color=palette.condition_color(c),
                marker="o",
                markersize=5,
                capsize=3,
                label=palette.condition_label(c),
            )
        ticks = sorted(set(counts) | set(PAPER_SETTINGS))
        ax.set_xticks(ticks)
        ax.set_xticklabels(
            [f"{n}\n{_seeds_at(final, n) if n in counts else '(no runs)'}" for n in ticks]
        )
        ax.set_xlim(min(min(counts), 0) - 0.6, max(max(counts), 7) + 0.6)
        ax.set_xlabel("distracting modules")
        ax.set_ylim(-0.03, 1.03)
        ax.set_ylabel(f"self-evaluated competence over\nthe {n_achievable} achievable modules")
        legend_right(ax)
        fig.suptitle("Distracting modules — competence at the end of the runs")
        seeds = _distractor_seeds_text(final, conditions, counts)
        episodes = int(final["episodes"].iat[0])
        runs = runs_of(rows)
        caption(
            fig,
            f"{seeds}. Competence after {episodes:,} episodes (the budget every run reached; "
            f"runs of {budget_text(runs['n_episodes'])}, {setting_text(runs)}): the success "
            "rate of the agent's recent self-evaluations on each module, averaged over the "
            f"{n_achievable} achievable modules; mean ± std across seeds (no bar: one seed). "
            f"Settings drawn: {', '.join(map(str, counts))} distracting modules"
            f"{_missing_text(counts)}.",
            note,
        )
    return finish(fig, out_dir, name)


def _distractor_seeds_text(
    final: pd.DataFrame, conditions: Sequence[str], counts: list[int]
) -> str:
    """Seeds per condition, once when they are the same for every number of distractors."""
    parts = []
    for c in conditions:
        mine = final[final["condition"] == c]
        per_count = {n: seeds_text(mine.loc[mine["n_distractors"] == n, "seed"]) for n in counts}
        if len(set(per_count.values())) == 1:
            parts.append(f"{palette.condition_label(c)}: {per_count[counts[0]]} per setting")
        else:
            listed = ", ".join(f"{n} distractors: {t}" for n, t in per_count.items())
            parts.append(f"{palette.condition_label(c)}: {listed}")
    return "; ".join(parts)


def _seeds_at(final: pd.DataFrame, n: int) -> str:
    """The x tick's second line: how many seeds each condition has at ``n`` distractors."""
    seeds = final.loc[final["n_distractors"] == n].groupby("condition", observed=True).size()
    low, high = int(seeds.min()), int(seeds.max())
    many = f"{low}" if low == high else f"{low}–{high}"
    return f"({many} seed{'' if high == 1 else 's'})"


PAPER_SETTINGS = (0, 4, 7)
"""The numbers of distracting modules the paper compares."""


def _missing_text(counts: Sequence[int]) -> str:
    """Which of the paper's settings the runs lack, if any."""
    missing = [n for n in PAPER_SETTINGS if n not in counts]
    if not missing:
        return ""
    return f" (no runs with {' or '.join(map(str, missing))}, which the paper also compares)"
