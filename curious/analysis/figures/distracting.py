"""The distractors figure (`distractors`): the self-evaluated competence over the achievable
modules at the end of the runs against the number of distracting modules, and beside it, where
the runs' test rollouts are given, their test success at the end."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

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
    final_test_success,
)
from curious.analysis.style import (
    budget_text,
    figure_style,
    new_figure,
    seeds_text,
)
from curious.watching import palette


def distractors(
    df: pd.DataFrame,
    conditions: Sequence[str] | None = None,
    at_episode: int | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "distractors",
    tests: pd.DataFrame | None = None,
) -> Figure:
    """Self-evaluated competence over achievable modules at the end of the runs against the
    number of distracting modules; with ``tests`` (the same runs' `load_tests` table), a second
    panel of their test success at the end.

    One line per condition, mean ± std across seeds (a lone seed drawn as its value), for every
    number of distractors among the runs (their variants may differ; their achievable modules
    must not); the x ticks say how many seeds each setting has. The competence is
    `statistics.final_competence` (the mean over the achievable modules of the agent's own
    competence measure, the success rate of its recent self-evaluations), after episode
    ``at_episode``, by default the last episode every run reached; the test success is
    `statistics.final_test_success` (the noise-free test rollouts on achievable modules, pooled
    over the last of the main comparison's bins every run completed).
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
    tested = None
    if tests is not None:
        tested = final_test_success(restrict(tests, conditions, None))
        runs = set(final["run"].astype(str))
        if set(tested["run"].astype(str)) != runs:
            raise AnalysisError(
                "the distractors figure's test rollouts must be those of the same runs as its "
                "competence: load both from the same run folders"
            )
    counts = sorted(int(n) for n in final["n_distractors"].unique())
    n_achievable = len(sets[0].split(","))
    with figure_style():
        fig = new_figure(6.4 if tested is None else 11.0, 4.2)
        panels = [(final, f"self-evaluated competence over\nthe {n_achievable} achievable modules")]
        if tested is not None:
            panels.append((tested, f"test success over\nthe {n_achievable} achievable modules"))
        axes = fig.subplots(1, len(panels), squeeze=False)[0]
        for ax, (values, ylabel) in zip(axes, panels, strict=True):
            _panel(ax, values, conditions, counts, final)
            ax.set_ylabel(ylabel)
        legend_right(axes[-1])
        fig.suptitle(
            "Distracting modules — competence"
            + (" and test success" if tested is not None else "")
            + " at the end of the runs"
        )
        seeds = _distractor_seeds_text(final, conditions, counts)
        episodes = int(final["episodes"].iat[0])
        runs = runs_of(rows)
        text = (
            f"{seeds}. Competence after {episodes:,} episodes (the budget every run reached; "
            f"runs of {budget_text(runs['n_episodes'])}, {setting_text(runs)}): the success "
            "rate of the agent's recent self-evaluations on each module, averaged over the "
            f"{n_achievable} achievable modules"
        )
        if tested is not None:
            end, width = int(tested["episodes"].iat[0]), int(tested.attrs["bin_size"])
            text += (
                " (left). Test success (right): the noise-free "
                "test rollouts on the achievable modules, pooled per run over episodes "
                f"{max(end - width, 0) + 1:,}–{end:,}"
            )
        caption(
            fig,
            text + "; mean ± std across seeds (no bar: one seed). "
            f"Settings drawn: {', '.join(map(str, counts))} distracting modules"
            f"{_missing_text(counts)}.",
            note,
        )
    return finish(fig, out_dir, name)


def _panel(
    ax: Axes,
    values: pd.DataFrame,
    conditions: Sequence[str],
    counts: list[int],
    final: pd.DataFrame,
) -> None:
    """One measure per run against the number of distracting modules: a line per condition,
    mean ± std across seeds, the x ticks saying how many seeds each setting has (`final`'s)."""
    table = (
        values.groupby(["condition", "n_distractors"], observed=True)["value"]
        .agg(mean="mean", std=lambda v: v.std(ddof=1))
        .reset_index()
    )
    offsets = np.linspace(-0.12, 0.12, len(conditions)) if len(conditions) > 1 else [0.0]
    for c, dx in zip(conditions, offsets, strict=True):
        s = table[table["condition"] == c].sort_values("n_distractors")
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
