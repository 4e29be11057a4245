"""The long runs (paper Fig. 2b-c over a whole run): every module's competence and absolute LP,
one row of panels per run, with each drop of a mastered module (`drops.mastery_drops`) shaded
over its course, so that what the paper's Fig. 2b shows in one run (a mastered module forgotten
near episode 250,000, its LP rising) can be looked for in each."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from curious.analysis.drops import DROP_DEPTH, mastery_drops
from curious.analysis.figures.parts import (
    caption,
    competence_axis,
    curve_bin,
    draw_modules,
    drawn_ceiling,
    episodes_text,
    finish,
    legend_right,
    lp_axis,
    one_run,
    require_self_evaluated,
    restrict,
    runs_of,
    setting_text,
)
from curious.analysis.loading import AnalysisError, require_runs
from curious.analysis.style import budget_text, figure_style, new_figure, seeds_text
from curious.watching import palette

DIP_MARKER = "v"
"""How a dip (a fall smaller than a drop, `dips`) is marked: a triangle at its trough."""


def long_runs(
    df: pd.DataFrame,
    condition: str = "curious",
    seeds: Sequence[int] | None = None,
    variant: str | None = None,
    dips: pd.DataFrame | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "long_runs",
) -> Figure:
    """Competence (left) and absolute LP (right) of every module over each whole run of
    ``condition`` (``seeds``: all of the table's where None), one row per seed. Each drop of a
    mastered module by `drops.mastery_drops`' rule is shaded in the module's colour from the
    start of its descent to its recovery (or the run's end), on both panels. ``dips``: rows
    with ``run``, ``module``, ``trough_episode`` and ``trough`` (the falls of a smaller depth
    read apart, docs/results.md C3), each marked by a triangle at its trough."""
    require_runs(df)
    rows = restrict(df, [condition], variant)
    if rows.empty:
        raise AnalysisError(f"no runs of condition '{condition}'")
    present = sorted(int(s) for s in rows["seed"].unique())
    chosen = present if seeds is None else [int(s) for s in seeds]
    if missing := [s for s in chosen if s not in present]:
        raise AnalysisError(
            f"condition '{condition}' has no seed(s) {', '.join(map(str, missing))} "
            f"(seeds: {', '.join(map(str, present))})"
        )
    require_self_evaluated(rows, condition)
    picked = [one_run(rows, condition, seed, variant) for seed in chosen]
    runs = runs_of(pd.concat(picked))
    drops = mastery_drops(pd.concat(picked))
    with figure_style():
        fig = new_figure(11.0, 1.0 + 2.4 * len(picked))
        axes = np.atleast_2d(fig.subplots(len(picked), 2, sharex=True, squeeze=False))
        for (left, right), run in zip(axes, picked, strict=True):
            key = str(run["run"].iat[0])
            n_episodes = int(run["episode"].max()) + 1
            bin_size = curve_bin(n_episodes)
            draw_modules(left, run, "competence/", bin_size)
            draw_modules(right, run, "lp/", bin_size)
            competence_axis(left, f"seed {int(run['seed'].iat[0])}\ncompetence")
            lp_axis(right, drawn_ceiling(run, "lp/", bin_size))
            right.set_ylabel("absolute LP")
            for drop in drops[drops["run"] == key].itertuples():
                end = n_episodes if pd.isna(drop.recovery_episode) else drop.recovery_episode
                for ax in (left, right):
                    ax.axvspan(
                        drop.start_episode,
                        end,
                        color=palette.module_color(drop.module),
                        alpha=0.18,
                        linewidth=0,
                    )
            if dips is not None:
                for dip in dips[dips["run"] == key].itertuples():
                    left.plot(
                        dip.trough_episode,
                        dip.trough,
                        DIP_MARKER,
                        color=palette.module_color(dip.module),
                        markersize=5,
                        markeredgecolor="black",
                        markeredgewidth=0.4,
                    )
            left.set_xlim(0, n_episodes)
        legend_right(axes[0, 1])
        label = palette.condition_label(condition)
        fig.suptitle(f"Fig. 2b-c over whole runs — {label}, competence and absolute LP per module")
        n_drops = len(drops)
        drops_text = (
            f"{n_drops} drop{'s' * (n_drops != 1)} of a mastered module by {DROP_DEPTH:g} or "
            "more, shaded in the module's colour from the start of its descent to its recovery"
            if n_drops
            else f"No mastered module's competence fell by {DROP_DEPTH:g} or more below its peak "
            "(nothing shaded)"
        )
        dips_text = (
            ""
            if dips is None
            else f" Triangles: the troughs of the {len(dips)} dip{'s' * (len(dips) != 1)} "
            "(smaller falls, read apart: docs/results.md, C3)."
        )
        caption(
            fig,
            f"{label}: {seeds_text(runs['seed'])}; {budget_text(runs['n_episodes'])} "
            f"({setting_text(runs)}), each run whole, sampled every "
            f"{episodes_text(curve_bin(int(runs['n_episodes'].max())))}. Competence: success "
            "rate of the module's recent self-evaluations; absolute LP: |competence over the "
            f"latest window − over the window before|. {drops_text}.{dips_text} Dashed: "
            "distractor modules.",
            note,
        )
    return finish(fig, out_dir, name)


__all__ = ["long_runs"]
