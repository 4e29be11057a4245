"""The paper's figures from a table of runs (`curious.analysis.load_runs`).

Every function takes the loaded table, returns a `matplotlib.figure.Figure` and, given
``out_dir``, also writes ``<out_dir>/<name>.png`` and ``.svg`` (see `style.save_figure`):

============  ===========================================================================
`fig2a`       average success over achievable modules per condition, mean ± std over seeds,
              dots where a one-tailed Welch test finds the first compared condition better
`fig2b`       competence of every module, one run
`fig2c`       absolute learning progress of every module, the same run
`table1`      competence and LP of every seed of a condition, one row per seed
`forgetting`  competence and LP of one module around a perturbation, and the episodes each
              condition takes to regain a fraction of its earlier competence
`distractors` final success over achievable modules against the number of distracting modules
============  ===========================================================================

Every x axis counts episodes (bar the distractors figure's), and every caption names the seeds,
the budget in episodes, the preset and the variant of the runs drawn; ``note`` adds a sentence
at its end (the reproduction says there when a budget is far below the paper's). Colours and
labels of modules and conditions come from `curious.analysis.palette`.
"""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from curious.analysis import palette
from curious.analysis.loading import AnalysisError, _require_identity, run_modules
from curious.analysis.statistics import (
    ALPHA,
    across_seeds,
    bin_runs,
    check_comparable,
    final_competence,
    most_perturbed_module,
    nice_bin_size,
    recovery,
    recovery_summary,
    welch_per_bin,
)
from curious.analysis.style import (
    budget_text,
    episodes_axis,
    figure_style,
    new_figure,
    save_figure,
    seeds_text,
    wrap_caption,
)

__all__ = [
    "CONDITION_ORDER",
    "distractors",
    "fig2a",
    "fig2b",
    "fig2c",
    "forgetting",
    "table1",
]

CONDITION_ORDER: tuple[str, ...] = ("curious", "mg-te", "her", "m-uvfa")
_CURVE_POINTS = 400  # at most this many points per drawn curve of one run
_CAPTION_SIZE = 7.5


# ----------------------------------------------------------------------------- selection helpers


def _ordered_conditions(df: pd.DataFrame, conditions: Sequence[str] | None) -> list[str]:
    present = [str(c) for c in df["condition"].unique()]
    if conditions is None:
        known = [c for c in CONDITION_ORDER if c in present]
        return known + sorted(c for c in present if c not in CONDITION_ORDER)
    missing = [c for c in conditions if c not in present]
    if missing:
        raise AnalysisError(
            f"no runs of condition(s) {', '.join(missing)} (have: {', '.join(sorted(present))})"
        )
    return list(conditions)


def _restrict(df: pd.DataFrame, conditions: Sequence[str], variant: str | None) -> pd.DataFrame:
    _require_identity(df)
    if variant is not None:
        variants = set(df["variant"].astype(str))
        if variant not in variants:
            raise AnalysisError(
                f"no runs of variant '{variant}' (have: {', '.join(sorted(variants))})"
            )
        df = df[df["variant"] == variant]
    return df[df["condition"].isin(list(conditions))]


def _one_run(
    df: pd.DataFrame, condition: str, seed: int | None, variant: str | None
) -> pd.DataFrame:
    """The rows of one run, chosen by condition, seed (lowest if None) and variant."""
    rows = _restrict(df, _ordered_conditions(df, [condition]), variant)
    seeds = sorted(int(s) for s in rows["seed"].unique())
    if seed is None:
        seed = seeds[0]
    elif seed not in seeds:
        raise AnalysisError(
            f"condition '{condition}' has no seed {seed} (seeds: {', '.join(map(str, seeds))})"
        )
    rows = rows[rows["seed"] == seed]
    runs = rows["run"].astype(str).unique()
    if len(runs) > 1:
        variants = ", ".join(sorted(rows["variant"].astype(str).unique()))
        raise AnalysisError(
            f"condition '{condition}' seed {seed} has {len(runs)} runs (variants {variants}): "
            "pass variant= to choose one"
        )
    return rows.sort_values("episode")


def _runs_of(df: pd.DataFrame) -> pd.DataFrame:
    grouped = df.groupby("run", observed=True)
    out = grouped[["condition", "seed", "variant", "preset"]].first()
    out["n_episodes"] = grouped["episode"].max() + 1
    return out


def _setting_text(runs: pd.DataFrame) -> str:
    presets = ", ".join(sorted(runs["preset"].astype(str).unique()))
    variants = ", ".join(sorted(runs["variant"].astype(str).unique()))
    return f"preset {presets}, variant {variants}"


def _conditions_text(runs: pd.DataFrame, conditions: Sequence[str]) -> str:
    parts = []
    for c in conditions:
        seeds = runs.loc[runs["condition"] == c, "seed"]
        parts.append(f"{palette.condition_label(c)}: {seeds_text(seeds)}")
    return "; ".join(parts)


def _episodes_text(n: int) -> str:
    """``"episode"`` for 1, else ``"1,000 episodes"``."""
    return "episode" if n == 1 else f"{n:,} episodes"


def _line_width(i: int, n: int) -> float:
    """Width of the i-th of n condition curves: the first widest, so that curves which coincide
    (as conditions can, early in small runs) show as a wide line with a thinner one inside."""
    return 1.6 + 1.6 * (n - 1 - i) / max(n - 1, 1)


def _caption(fig: Figure, text: str, note: str | None = None) -> None:
    """The caption under the axes; ``note`` (e.g. "Small budget: ...") ends it."""
    if note:
        text = f"{text} {note.strip()}"
    width = fig.get_figwidth()
    fig.supxlabel(wrap_caption(text, width), fontsize=_CAPTION_SIZE, ha="left", x=0.01)


def _legend_right(ax: Axes, handles: list | None = None, labels: list | None = None) -> None:
    """A legend beside ``ax``, top-aligned with it (constrained layout makes room for it)."""
    args = () if handles is None else (handles, labels)
    ax.legend(*args, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)


def _finish(fig: Figure, out_dir: str | PathLike[str] | None, name: str) -> Figure:
    if out_dir is not None:
        save_figure(fig, out_dir, name)
    return fig


def _curve_bin(n_episodes: int) -> int:
    return nice_bin_size(n_episodes, _CURVE_POINTS) if n_episodes > _CURVE_POINTS else 1


def _module_series(run: pd.DataFrame, prefix: str, bin_size: int) -> tuple[np.ndarray, dict]:
    """End-of-bin values of ``<prefix><module>`` for one run: (episodes, {module: values})."""
    modules, _ = run_modules(run, str(run["run"].iat[0]))
    episodes = run["episode"].to_numpy()
    ends = (np.arange((int(episodes[-1]) + 1) // bin_size) + 1) * bin_size
    at = np.searchsorted(episodes, ends - 1, side="right") - 1
    keep = at >= 0
    return ends[keep], {m: run[prefix + m].to_numpy()[at[keep]] for m in modules}


def _draw_modules(ax: Axes, run: pd.DataFrame, prefix: str, bin_size: int) -> None:
    _, achievable = run_modules(run, str(run["run"].iat[0]))
    x, series = _module_series(run, prefix, bin_size)
    for module, values in series.items():
        ax.plot(
            x,
            values,
            color=palette.module_color(module),
            linestyle="-" if module in achievable else "--",
            linewidth=1.5 if module in achievable else 1.1,
            label=palette.module_label(module) + ("" if module in achievable else " (distractor)"),
        )
    episodes_axis(ax)


def _competence_axis(ax: Axes, label: str = "competence (success rate)") -> None:
    ax.set_ylim(-0.03, 1.03)
    ax.set_ylabel(label)


def _lp_axis(ax: Axes, top: float) -> None:
    ax.set_ylim(0.0, max(0.05, top * 1.08))
    ax.set_ylabel("absolute LP (Δ success rate)")


def _lp_top(df: pd.DataFrame) -> float:
    columns = [c for c in df.columns if c.startswith("lp/")]
    top = np.nanmax(df[columns].to_numpy(dtype=np.float64)) if columns else 0.0
    return float(top) if np.isfinite(top) else 0.0


# ----------------------------------------------------------------------------- Fig. 2a


def fig2a(
    df: pd.DataFrame,
    conditions: Sequence[str] | None = None,
    compare: tuple[str, str] | None = ("curious", "mg-te"),
    variant: str | None = None,
    bin_size: int | None = None,
    alpha: float = ALPHA,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "fig2a",
) -> Figure:
    """Average success over achievable modules per condition (paper Fig. 2a).

    Mean ± std across seeds of `statistics.achievable_competence`, read at the end of each
    ``bin_size``-episode bin (default: `nice_bin_size` of the longest run); a condition's curve
    stops at the last bin all its seeds reached. ``compare = (better, worse)`` adds a dot above
    every bin where a one-tailed Welch's t-test finds ``better`` greater at level ``alpha``;
    ``None`` draws no test.
    """
    conditions = _ordered_conditions(df, conditions)
    if compare is not None:
        for c in compare:
            if c not in conditions:
                raise AnalysisError(
                    f"fig2a compares '{compare[0]}' with '{compare[1]}' but there are no runs of "
                    f"'{c}' among {', '.join(conditions)}: pass compare=None or other conditions"
                )
    rows = _restrict(df, conditions, variant)
    check_comparable(rows)
    runs = _runs_of(rows)
    if bin_size is None:
        bin_size = nice_bin_size(int(runs["n_episodes"].max()))
    binned = bin_runs(rows, bin_size=bin_size)
    summary = across_seeds(binned)
    n_achievable = len(str(rows["achievable_modules"].iat[0]).split(","))
    n_modules = len(str(rows["modules"].iat[0]).split(","))

    with figure_style():
        fig = new_figure(7.2, 4.4)
        ax = fig.add_subplot()
        for i, c in enumerate(conditions):
            s = summary[summary["condition"] == c]
            s = s[s["n"] == s["n"].max()]
            color = palette.condition_color(c)
            ax.plot(
                s["episodes"],
                s["mean"],
                color=color,
                linewidth=_line_width(i, len(conditions)),
                label=palette.condition_label(c),
            )
            if (s["n"] > 1).any():
                ax.fill_between(
                    s["episodes"],
                    s["mean"] - s["std"],
                    s["mean"] + s["std"],
                    color=color,
                    alpha=0.2,
                    linewidth=0,
                )
        test_text = ""
        if compare is not None:
            better, worse = compare
            test = welch_per_bin(binned, better, worse, alpha)
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
                    f"{palette.condition_label(worse)}" + ("" if len(hits) else " (no bin)")
                ),
                clip_on=False,
            )
            dots.set_in_layout(False)  # inside the y limits; an empty line would pull in (0, 0)
            test_text = (
                f" Dots: one-tailed Welch's t-test per bin, {palette.condition_label(better)} > "
                f"{palette.condition_label(worse)}, p < {alpha:g} "
                f"({len(hits)} of {len(test)} bins)."
            )
        ax.set_ylim(-0.03, 1.1)
        ax.set_yticks(np.linspace(0, 1, 6))
        ax.set_ylabel(f"success over achievable modules ({n_achievable}/{n_modules})")
        episodes_axis(ax)
        ax.set_xlim(0, None)
        _legend_right(ax)
        fig.suptitle("Fig. 2a — average success over achievable modules")
        _caption(
            fig,
            f"{_conditions_text(runs, conditions)}. Budget {budget_text(runs['n_episodes'])} "
            f"({_setting_text(runs)}). Mean ± std across seeds of the competence (self-evaluation "
            f"success rate) averaged over the {n_achievable} achievable modules, read at the end "
            f"of each {bin_size:,}-episode bin.{test_text}",
            note,
        )
    return _finish(fig, out_dir, name)


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
    run = _one_run(df, condition, seed, variant)
    runs = _runs_of(run)
    n_episodes = int(runs["n_episodes"].iat[0])
    bin_size = _curve_bin(n_episodes)
    with figure_style():
        fig = new_figure(7.2, 4.2)
        ax = fig.add_subplot()
        _draw_modules(ax, run, prefix, bin_size)
        if prefix == "competence/":
            _competence_axis(ax)
        else:
            _lp_axis(ax, _lp_top(run))
        ax.set_xlim(0, None)
        _legend_right(ax)
        seed_value = int(runs["seed"].iat[0])
        fig.suptitle(f"{title} — {palette.condition_label(condition)}, seed {seed_value}")
        sampled = f"every {_episodes_text(bin_size)}"
        _caption(
            fig,
            f"One run: {palette.condition_label(condition)}, seed {seed_value}; "
            f"{budget_text([n_episodes])} ({_setting_text(runs)}). {what} Sampled {sampled}; "
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
    return _finish(fig, out_dir, name)


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
    return _finish(fig, out_dir, name)


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
    rows = _restrict(df, _ordered_conditions(df, [condition]), variant)
    check_comparable(rows)
    runs = _runs_of(rows).sort_values("seed")
    n = len(runs)
    n_episodes = int(runs["n_episodes"].max())
    bin_size = _curve_bin(n_episodes)
    lp_top = _lp_top(rows)
    with figure_style():
        fig = new_figure(8.0, 1.25 + 1.55 * n)
        axes = fig.subplots(n, 2, sharex=True, squeeze=False)
        for i, (run_id, info) in enumerate(runs.iterrows()):
            run = rows[rows["run"] == run_id].sort_values("episode")
            left, right = axes[i]
            _draw_modules(left, run, "competence/", bin_size)
            _draw_modules(right, run, "lp/", bin_size)
            _competence_axis(left, f"seed {int(info['seed'])}\ncompetence")
            _lp_axis(right, lp_top)
            right.set_ylabel("absolute LP")
            for ax in (left, right):
                ax.set_xlim(0, n_episodes)
                if i < n - 1:
                    ax.set_xlabel("")
        axes[0, 0].set_title("competence (success rate)")
        axes[0, 1].set_title("absolute learning progress (Δ success rate)")
        handles, labels = axes[0, 0].get_legend_handles_labels()
        _legend_right(axes[0, 1], handles, labels)
        fig.suptitle(
            f"Table 1 — competence and LP per module, {palette.condition_label(condition)}"
        )
        _caption(
            fig,
            f"{palette.condition_label(condition)}: {seeds_text(runs['seed'])}, one row per seed; "
            f"{budget_text(runs['n_episodes'])} ({_setting_text(runs)}). Dashed: distractor "
            "modules.",
            note,
        )
    return _finish(fig, out_dir, name)


# ----------------------------------------------------------------------------- forgetting


def forgetting(
    df: pd.DataFrame,
    module: str | None = None,
    perturbation_episode: int | None = None,
    fraction: float = 0.9,
    conditions: Sequence[str] | None = None,
    variant: str | None = None,
    before: int | None = None,
    pre_window: int | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "forgetting",
) -> tuple[Figure, pd.DataFrame]:
    """Competence and LP of one module around a perturbation, per condition; and recovery times.

    ``perturbation_episode`` defaults to each run's ``sensor_failure_episode`` (from its config);
    all runs drawn must share it. ``module`` defaults to the achievable module whose competence
    fell most after it (`statistics.most_perturbed_module`). The x axis shows ``before`` episodes
    (default: half the episodes after the perturbation) before the perturbation and everything
    after it. Returns the figure and `statistics.recovery`'s table (one row per run; the
    ``recovery_episodes`` column is the time to regain ``fraction`` of the earlier competence).
    The legend states each condition's mean ± std of that time over the seeds that recovered.
    """
    conditions = _ordered_conditions(df, conditions)
    rows = _restrict(df, conditions, variant)
    check_comparable(rows)
    runs = _runs_of(rows)
    if perturbation_episode is None:
        marks = rows.groupby("run", observed=True)["perturbation_episode"].first()
        if marks.isna().any():
            raise AnalysisError(
                f"run {marks[marks.isna()].index[0]} has no sensor_failure_episode in its "
                "config.json: pass perturbation_episode"
            )
        if marks.nunique() > 1:
            raise AnalysisError(
                "these runs were perturbed at different episodes "
                f"({', '.join(map(str, sorted(marks.unique())))}): select runs that share one"
            )
        perturbation_episode = int(marks.iloc[0])
    p = int(perturbation_episode)
    if module is None:
        module = most_perturbed_module(rows, p)
    window = pre_window if pre_window is not None else max(1, p // 10)
    per_run = recovery(rows, module, p, fraction, window)
    summary = recovery_summary(per_run).set_index("condition")

    n_episodes = int(runs["n_episodes"].min())
    if before is None:
        before = max(1, (n_episodes - p) // 2)
    start = max(0, p - before)
    bin_size = _curve_bin(n_episodes - start)
    shown = rows[rows["episode"] >= start]
    comp = across_seeds(bin_runs(shown, f"competence/{module}", bin_size))
    lp = across_seeds(bin_runs(shown, f"lp/{module}", bin_size))
    lp_top = float(np.nanmax(shown[f"lp/{module}"].to_numpy(dtype=np.float64)))

    with figure_style():
        fig = new_figure(7.6, 5.6)
        top, bottom = fig.subplots(2, 1, sharex=True)
        for i, c in enumerate(conditions):
            color = palette.condition_color(c)
            label = _recovery_label(c, summary.loc[c], fraction)
            width = _line_width(i, len(conditions))
            for ax, table in ((top, comp), (bottom, lp)):
                s = table[(table["condition"] == c) & (table["episodes"] > start)]
                s = s[s["n"] == s["n"].max()]
                ax.plot(
                    s["episodes"],
                    s["mean"],
                    color=color,
                    linewidth=width,
                    label=label if ax is top else None,
                )
                if (s["n"] > 1).any():
                    ax.fill_between(
                        s["episodes"],
                        s["mean"] - s["std"],
                        s["mean"] + s["std"],
                        color=color,
                        alpha=0.2,
                        linewidth=0,
                    )
            threshold = float(summary.loc[c, "threshold"])
            top.axhline(threshold, color=color, linestyle=":", linewidth=1.0)
        for ax in (top, bottom):
            ax.axvline(p, color="black", linestyle="--", linewidth=1.0)
            ax.set_xlim(start, n_episodes)
        top.annotate(
            f"perturbation\n(episode {p:,})",
            xy=(p, 1.0),
            xytext=(4, 0),
            textcoords="offset points",
            fontsize=7.5,
            va="top",
        )
        _competence_axis(top, f"competence of {palette.module_label(module)}")
        _lp_axis(bottom, lp_top)
        bottom.set_ylabel(f"absolute LP of {palette.module_label(module)}")
        episodes_axis(top, label=False)
        episodes_axis(bottom)
        top.legend(loc="lower left", bbox_to_anchor=(0.0, 1.02), borderaxespad=0.0)
        fig.suptitle(f"Forgetting and recovery — {palette.module_label(module)}")
        _caption(
            fig,
            f"{_conditions_text(runs, conditions)}. Budget {budget_text(runs['n_episodes'])} "
            f"({_setting_text(runs)}). Mean ± std across seeds, sampled every "
            f"{_episodes_text(bin_size)}. Dashed line: perturbation at episode {p:,}. "
            f"Dotted lines: {fraction:.0%} of each condition's competence over the "
            f"{_episodes_text(window)} before it (mean over seeds). Recovery time: episodes from "
            f"the perturbation until a run's competence, after its lowest point, is back at "
            f"{fraction:.0%} of its own earlier level.",
            note,
        )
    return _finish(fig, out_dir, name), per_run


def _recovery_label(condition: str, row: pd.Series, fraction: float) -> str:
    name = palette.condition_label(condition)
    n, k = int(row["n_runs"]), int(row["n_recovered"])
    if k == 0 and row["pre_competence"] <= 0:
        return f"{name}: no competence to lose before the perturbation ({n} seeds)"
    if k == 0:
        return f"{name}: {fraction:.0%} not regained by the end (0/{n} seeds)"
    mean = row["mean_recovery_episodes"]
    spread = f" ± {row['std_recovery_episodes']:,.0f}" if k > 1 else ""
    return f"{name}: {fraction:.0%} regained after {mean:,.0f}{spread} episodes ({k}/{n} seeds)"


# ----------------------------------------------------------------------------- distractors


def distractors(
    df: pd.DataFrame,
    conditions: Sequence[str] | None = None,
    at_episode: int | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "distractors",
) -> Figure:
    """Final success over achievable modules against the number of distracting modules.

    One line per condition, mean ± std across seeds, for every number of distractors among the
    runs (their variants may differ; their achievable modules must not). "Final" is after episode
    ``at_episode``, by default the last episode every run reached.
    """
    conditions = _ordered_conditions(df, conditions)
    rows = _restrict(df, conditions, None)
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
        ax.set_xticks(counts)
        ax.set_xlim(min(counts) - 0.6, max(counts) + 0.6)
        ax.set_xlabel("distracting modules")
        ax.set_ylim(-0.03, 1.03)
        ax.set_ylabel(f"final success over achievable modules ({n_achievable})")
        _legend_right(ax)
        fig.suptitle("Distracting modules — final success")
        seeds = _distractor_seeds_text(final, conditions, counts)
        episodes = int(final["episodes"].iat[0])
        runs = _runs_of(rows)
        _caption(
            fig,
            f"{seeds}. Success after {episodes:,} episodes (the budget every run reached; "
            f"runs of {budget_text(runs['n_episodes'])}, {_setting_text(runs)}). Mean ± std "
            f"across seeds of the competence averaged over the {n_achievable} achievable modules.",
            note,
        )
    return _finish(fig, out_dir, name)


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
