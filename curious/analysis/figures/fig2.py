"""The main comparison (paper Fig. 2 and Table 1): `fig2a` from the test rollouts, `fig2b` and
`fig2c` one run's competence and learning progress, `table1` every seed of a condition."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from curious.analysis.figures.parts import (
    caption,
    competence_axis,
    conditions_text,
    curve_bin,
    draw_mean_std,
    draw_modules,
    drawn_ceiling,
    episodes_text,
    finish,
    legend_right,
    line_width,
    lp_axis,
    one_run,
    ordered_conditions,
    require_self_evaluated,
    restrict,
    runs_of,
    setting_text,
    test_runs_of,
)
from curious.analysis.loading import (
    AnalysisError,
    require_runs,
    require_tests,
)
from curious.analysis.statistics import (
    ALPHA,
    check_comparable,
    main_comparison,
)
from curious.analysis.style import (
    budget_text,
    episodes_axis,
    figure_style,
    new_figure,
    seeds_text,
)
from curious.watching import palette


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
    Drawn from `statistics.main_comparison`, the computation the report quotes: each run's test
    rollouts pooled per episode bin (``bin_size``, default `statistics.comparison_bin_size`:
    5,000 episodes for runs of 100,000), one marker per bin at its end; a thick line for the
    mean across seeds, a band for ± std and a thin line per seed, so that the spread shows; a
    condition's curve stops at the last bin all its seeds completed.
    ``compare = (better, worse)`` adds a marker above every bin where a one-tailed Welch's t-test
    finds ``better`` greater at level ``alpha``, and the caption counts them; ``None`` draws no
    test.
    """
    require_tests(tests)
    conditions = ordered_conditions(tests, conditions)
    if compare is not None:
        if isinstance(compare, str) or len(compare) != 2:
            raise AnalysisError(
                f"compare takes two conditions, e.g. ('curious', 'mg-te'), got {compare!r}"
            )
        for c in compare:
            if c not in conditions:
                raise AnalysisError(
                    f"fig2a compares '{compare[0]}' with '{compare[1]}' but there are no runs of "
                    f"'{c}' among {', '.join(conditions)}: pass compare=None or other conditions"
                )
    rows = restrict(tests, conditions, variant)
    check_comparable(rows)
    runs = test_runs_of(rows)
    pair = compare if compare is not None else (None, None)
    numbers = main_comparison(rows, *pair, alpha=alpha, bin_size=bin_size)
    points: pd.DataFrame = numbers["points"]  # type: ignore[assignment]
    if not points["n_tests"].any():
        raise AnalysisError(
            "none of these test rollouts is on an achievable module: Fig. 2a has nothing to "
            "draw (were they filtered by module?)"
        )
    summary: pd.DataFrame = numbers["summary"]  # type: ignore[assignment]
    width_episodes = int(numbers["bin_size"])  # type: ignore[arg-type]
    n_achievable = len(str(rows["achievable_modules"].iat[0]).split(","))
    n_modules = len(str(rows["modules"].iat[0]).split(","))

    with figure_style():
        fig = new_figure(7.2, 4.4)
        ax = fig.add_subplot()
        for i, c in enumerate(conditions):
            color = palette.condition_color(c)
            s = summary[summary["condition"] == c]
            s = s[s["n"] == s["n"].max()]
            mine = points[(points["condition"] == c) & points["episodes"].isin(s["episodes"])]
            for _run, seed in mine.groupby("run", observed=True, sort=True):
                ax.plot(
                    seed["episodes"],
                    seed["value"],
                    color=color,
                    linewidth=0.7,
                    alpha=0.55,
                    label="_seed",
                )
            width = line_width(i, len(conditions))
            draw_mean_std(ax, s, color, width, palette.condition_label(c), alpha=0.25)
            ax.plot(
                s["episodes"],
                s["mean"],
                linestyle="none",
                marker="o",
                markersize=3.0,
                color=color,
                label="_bins",
            )
        test_text = ""
        if compare is not None:
            better, worse = compare
            test: pd.DataFrame = numbers["welch"]  # type: ignore[assignment]
            hits = test[test["significant"]]
            (dots,) = ax.plot(
                hits["episodes"],
                np.full(len(hits), 1.06),
                linestyle="none",
                marker="*",
                markersize=6,
                color=palette.condition_color(better),
                label=(
                    f"p < {alpha:g}: {palette.condition_label(better)} > "
                    f"{palette.condition_label(worse)} ({len(hits)} of {len(test)} bins)"
                ),
                clip_on=False,
            )
            dots.set_in_layout(False)  # inside the y limits; an empty line would pull in (0, 0)
            test_text = (
                f" Stars: one-tailed Welch's t-test per bin, {palette.condition_label(better)} > "
                f"{palette.condition_label(worse)}, p < {alpha:g}: significant in {len(hits)} of "
                f"{len(test)} bins."
            )
        ax.set_ylim(-0.03, 1.1)
        ax.set_yticks(np.linspace(0, 1, 6))
        ax.set_ylabel(f"test success over achievable modules ({n_achievable}/{n_modules})")
        episodes_axis(ax)
        ax.set_xlim(0, None)
        legend_right(ax)
        fig.suptitle(title)
        caption(
            fig,
            f"{conditions_text(runs, conditions)}. Budget {budget_text(runs['n_episodes'])} "
            f"({setting_text(runs)}). Test success: after every epoch, noise-free test rollouts "
            f"on modules drawn uniformly, their success rate pooled over those on the "
            f"{n_achievable} achievable modules and over the epochs of each "
            f"{width_episodes:,}-episode bin ({points['n_tests'].mean():,.0f} rollouts per run "
            "and bin on average), drawn at the bin's end. Thick line and band: mean ± std across "
            f"seeds; thin lines: each seed.{_her_text(conditions)}{test_text}",
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
            lp_axis(ax, drawn_ceiling(run, prefix, bin_size))
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
    require_runs(df)
    rows = restrict(df, ordered_conditions(df, [condition]), variant)
    check_comparable(rows)
    require_self_evaluated(rows, condition)
    runs = runs_of(rows).sort_values("seed")
    n = len(runs)
    n_episodes = int(runs["n_episodes"].max())
    bin_size = curve_bin(n_episodes)
    top = max(
        drawn_ceiling(rows[rows["run"] == r].sort_values("episode"), "lp/", bin_size)
        for r in runs.index
    )
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


# ----------------------------------------------------------------------------- sensory failure
