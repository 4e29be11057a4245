"""The main comparison (paper Fig. 2 and Table 1): `fig2a` from the test rollouts, `fig2b` and
`fig2c` one run's competence and learning progress, `table1` every seed of a condition."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from curious.analysis import palette
from curious.analysis.figures.parts import (
    caption,
    competence_axis,
    conditions_text,
    curve_bin,
    draw_mean_std,
    draw_modules,
    episodes_text,
    finish,
    legend_right,
    line_width,
    lp_axis,
    lp_ceiling,
    one_run,
    ordered_conditions,
    restrict,
    runs_of,
    setting_text,
    test_runs_of,
)
from curious.analysis.loading import (
    AnalysisError,
    require_tests,
)
from curious.analysis.statistics import (
    ALPHA,
    across_seeds,
    check_comparable,
    epoch_success,
    welch_per_bin,
)
from curious.analysis.style import (
    budget_text,
    episodes_axis,
    figure_style,
    new_figure,
    seeds_text,
)


def fig2a(
    tests: pd.DataFrame,
    conditions: Sequence[str] | None = None,
    compare: tuple[str, str] | None = ("curious", "mg-te"),
    variant: str | None = None,
    bin_size: int | None = None,
    alpha: float = ALPHA,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "fig2a",
    title: str = "Fig. 2a — average success over achievable modules",
) -> Figure:
    """Average test success over achievable modules per condition (paper Fig. 2a; `title`
    names other uses of the same plot).

    ``tests`` is a `load_tests` table: the runs' test rollouts, as the paper measured Fig. 2a.
    Mean ± std across seeds of `statistics.epoch_success`: one point per epoch, at the training
    episodes done when its tests ran (``bin_size`` pools the epochs of each ``bin_size``-episode
    bin instead); a condition's curve stops at the last point all its seeds reached.
    ``compare = (better, worse)`` adds a dot above every point where a one-tailed Welch's t-test
    finds ``better`` greater at level ``alpha``; ``None`` draws no test.
    """
    require_tests(tests)
    conditions = ordered_conditions(tests, conditions)
    if compare is not None:
        for c in compare:
            if c not in conditions:
                raise AnalysisError(
                    f"fig2a compares '{compare[0]}' with '{compare[1]}' but there are no runs of "
                    f"'{c}' among {', '.join(conditions)}: pass compare=None or other conditions"
                )
    rows = restrict(tests, conditions, variant)
    check_comparable(rows)
    runs = test_runs_of(rows)
    points = epoch_success(rows, bin_size)
    summary = across_seeds(points)
    n_achievable = len(str(rows["achievable_modules"].iat[0]).split(","))
    n_modules = len(str(rows["modules"].iat[0]).split(","))

    with figure_style():
        fig = new_figure(7.2, 4.4)
        ax = fig.add_subplot()
        for i, c in enumerate(conditions):
            s = summary[summary["condition"] == c]
            s = s[s["n"] == s["n"].max()]
            width = line_width(i, len(conditions))
            draw_mean_std(ax, s, palette.condition_color(c), width, palette.condition_label(c))
        test_text = ""
        if compare is not None:
            better, worse = compare
            test = welch_per_bin(points, better, worse, alpha)
            hits = test[test["significant"]]
            (dots,) = ax.plot(
                hits["episodes"],
                np.full(len(hits), 1.06),
                linestyle="none",
                marker="o",
                markersize=3.5,
                color=palette.condition_color(better),
                label=(
                    f"p < {alpha:g}: {palette.condition_label(better)} > "
                    f"{palette.condition_label(worse)}" + ("" if len(hits) else " (no point)")
                ),
                clip_on=False,
            )
            dots.set_in_layout(False)  # inside the y limits; an empty line would pull in (0, 0)
            test_text = (
                f" Dots: one-tailed Welch's t-test per point, {palette.condition_label(better)} > "
                f"{palette.condition_label(worse)}, p < {alpha:g} "
                f"({len(hits)} of {len(test)} points)."
            )
        ax.set_ylim(-0.03, 1.1)
        ax.set_yticks(np.linspace(0, 1, 6))
        ax.set_ylabel(f"test success over achievable modules ({n_achievable}/{n_modules})")
        episodes_axis(ax)
        ax.set_xlim(0, None)
        legend_right(ax)
        fig.suptitle(title)
        where = (
            "one point per epoch, at the training episodes done when its tests ran"
            if bin_size is None
            else f"the epochs of each {bin_size:,}-episode bin pooled into one point"
        )
        caption(
            fig,
            f"{conditions_text(runs, conditions)}. Budget {budget_text(runs['n_episodes'])} "
            f"({setting_text(runs)}). Mean ± std across seeds of the test success: after every "
            "epoch, noise-free test rollouts on modules drawn uniformly, their success rate "
            f"pooled over those on the {n_achievable} achievable modules "
            f"({points['n_tests'].mean():,.0f} per run and point on average); {where}."
            f"{_her_text(conditions)}{test_text}",
            note,
        )
    return finish(fig, out_dir, name)


def _her_text(conditions: Sequence[str]) -> str:
    """What HER's success is, where its curve is drawn."""
    if "her" not in conditions:
        return ""
    return (
        f" {palette.condition_label('her')}'s success is its holistic goal met (one distance over"
        " every module's goal at once, as the paper's)."
    )


# ----------------------------------------------------------------------------- Fig. 2b / 2c


def _one_run_figure(
    df: pd.DataFrame,
    condition: str,
    seed: int | None,
    variant: str | None,
    prefix: str,
    title: str,
    what: str,
    note: str | None,
) -> Figure:
    run = one_run(df, condition, seed, variant)
    runs = runs_of(run)
    n_episodes = int(runs["n_episodes"].iat[0])
    bin_size = curve_bin(n_episodes)
    with figure_style():
        fig = new_figure(7.2, 4.2)
        ax = fig.add_subplot()
        draw_modules(ax, run, prefix, bin_size)
        if prefix == "competence/":
            competence_axis(ax)
        else:
            lp_axis(ax, lp_ceiling(run))
        ax.set_xlim(0, None)
        legend_right(ax)
        seed_value = int(runs["seed"].iat[0])
        fig.suptitle(f"{title} — {palette.condition_label(condition)}, seed {seed_value}")
        sampled = f"every {episodes_text(bin_size)}"
        caption(
            fig,
            f"One run: {palette.condition_label(condition)}, seed {seed_value}; "
            f"{budget_text([n_episodes])} ({setting_text(runs)}). {what} Sampled {sampled}; "
            "dashed: distractor modules.",
            note,
        )
    return fig


def fig2b(
    df: pd.DataFrame,
    condition: str = "curious",
    seed: int | None = None,
    variant: str | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "fig2b",
) -> Figure:
    """Competence of every module over one run (paper Fig. 2b); ``seed`` defaults to the lowest."""
    fig = _one_run_figure(
        df,
        condition,
        seed,
        variant,
        "competence/",
        "Fig. 2b — competence per module",
        "Competence: success rate of the module's recent self-evaluation episodes.",
        note,
    )
    return finish(fig, out_dir, name)


def fig2c(
    df: pd.DataFrame,
    condition: str = "curious",
    seed: int | None = None,
    variant: str | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "fig2c",
) -> Figure:
    """Absolute learning progress of every module over one run (paper Fig. 2c)."""
    fig = _one_run_figure(
        df,
        condition,
        seed,
        variant,
        "lp/",
        "Fig. 2c — absolute learning progress per module",
        "Absolute LP: |competence over the latest evaluation window − over the window before|.",
        note,
    )
    return finish(fig, out_dir, name)


# ----------------------------------------------------------------------------- Table 1


def table1(
    df: pd.DataFrame,
    condition: str = "curious",
    variant: str | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "table1",
) -> Figure:
    """Competence (left) and absolute LP (right) of every seed of ``condition`` (paper Table 1)."""
    rows = restrict(df, ordered_conditions(df, [condition]), variant)
    check_comparable(rows)
    runs = runs_of(rows).sort_values("seed")
    n = len(runs)
    n_episodes = int(runs["n_episodes"].max())
    bin_size = curve_bin(n_episodes)
    top = lp_ceiling(rows)
    with figure_style():
        fig = new_figure(8.0, 1.25 + 1.55 * n)
        axes = fig.subplots(n, 2, sharex=True, squeeze=False)
        for i, (run_id, info) in enumerate(runs.iterrows()):
            run = rows[rows["run"] == run_id].sort_values("episode")
            left, right = axes[i]
            draw_modules(left, run, "competence/", bin_size)
            draw_modules(right, run, "lp/", bin_size)
            competence_axis(left, f"seed {int(info['seed'])}\ncompetence")
            lp_axis(right, top)
            right.set_ylabel("absolute LP")
            for ax in (left, right):
                ax.set_xlim(0, n_episodes)
                if i < n - 1:
                    ax.set_xlabel("")
        axes[0, 0].set_title("competence (success rate)")
        axes[0, 1].set_title("absolute learning progress (Δ success rate)")
        handles, labels = axes[0, 0].get_legend_handles_labels()
        legend_right(axes[0, 1], handles, labels)
        fig.suptitle(
            f"Table 1 — competence and LP per module, {palette.condition_label(condition)}"
        )
        caption(
            fig,
            f"{palette.condition_label(condition)}: {seeds_text(runs['seed'])}, one row per seed; "
            f"{budget_text(runs['n_episodes'])} ({setting_text(runs)}). Dashed: distractor "
            "modules.",
            note,
        )
    return finish(fig, out_dir, name)


# ----------------------------------------------------------------------------- forgetting
