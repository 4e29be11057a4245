"""The paper's figures from tables of runs (`curious.analysis.load_runs`, `load_tests`).

Every function takes a loaded table (`fig2a` the test rollouts of `curious.analysis.load_tests`,
the others the episodes of `curious.analysis.load_runs`), returns a `matplotlib.figure.Figure`
and, given ``out_dir``, also writes ``<out_dir>/<name>.png`` and ``.svg`` (see `style.save_figure`):

============  ===========================================================================
`fig2a`       average test success over achievable modules per condition, mean ± std over
              seeds, dots where a one-tailed Welch test finds the first compared condition
              better; drawn from the test rollouts (`curious.analysis.load_tests`)
`fig2b`       competence of every module, one run
`fig2c`       absolute learning progress of every module, the same run
`table1`      competence and LP of every seed of a condition, one row per seed
`forgetting`  competence and LP of the perturbed module around the sensory failure, and the
              episodes each condition takes to regain a fraction of its earlier competence,
              where that can be measured
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
from curious.analysis.loading import (
    AnalysisError,
    _require_identity,
    _require_tests,
    run_modules,
)
from curious.analysis.statistics import (
    ALPHA,
    _run_arrays,
    across_seeds,
    bin_runs,
    check_comparable,
    epoch_success,
    final_competence,
    nice_bin_size,
    perturbed_module,
    recovery,
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


def _test_runs_of(tests: pd.DataFrame) -> pd.DataFrame:
    """One row per run of a tests table; ``n_episodes``: training episodes at its last test."""
    grouped = tests.groupby("run", observed=True)
    out = grouped[["condition", "seed", "variant", "preset"]].first()
    out["n_episodes"] = grouped["episode"].max()
    return out


def _draw_mean_std(ax: Axes, s: pd.DataFrame, color: str, width: float, label: str | None) -> None:
    """One condition's mean curve and, with several seeds, its ± std band."""
    ax.plot(s["episodes"], s["mean"], color=color, linewidth=width, label=label)
    if (s["n"] > 1).any():
        ax.fill_between(
            s["episodes"],
            s["mean"] - s["std"],
            s["mean"] + s["std"],
            color=color,
            alpha=0.2,
            linewidth=0,
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
) -> Figure:
    """Average test success over achievable modules per condition (paper Fig. 2a).

    ``tests`` is a `load_tests` table: the runs' test rollouts, as the paper measured Fig. 2a.
    Mean ± std across seeds of `statistics.epoch_success`: one point per epoch, at the training
    episodes done when its tests ran (``bin_size`` pools the epochs of each ``bin_size``-episode
    bin instead); a condition's curve stops at the last point all its seeds reached.
    ``compare = (better, worse)`` adds a dot above every point where a one-tailed Welch's t-test
    finds ``better`` greater at level ``alpha``; ``None`` draws no test.
    """
    _require_tests(tests)
    conditions = _ordered_conditions(tests, conditions)
    if compare is not None:
        for c in compare:
            if c not in conditions:
                raise AnalysisError(
                    f"fig2a compares '{compare[0]}' with '{compare[1]}' but there are no runs of "
                    f"'{c}' among {', '.join(conditions)}: pass compare=None or other conditions"
                )
    rows = _restrict(tests, conditions, variant)
    check_comparable(rows)
    runs = _test_runs_of(rows)
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
            width = _line_width(i, len(conditions))
            _draw_mean_std(ax, s, palette.condition_color(c), width, palette.condition_label(c))
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
        _legend_right(ax)
        fig.suptitle("Fig. 2a — average success over achievable modules")
        where = (
            "one point per epoch, at the training episodes done when its tests ran"
            if bin_size is None
            else f"the epochs of each {bin_size:,}-episode bin pooled into one point"
        )
        _caption(
            fig,
            f"{_conditions_text(runs, conditions)}. Budget {budget_text(runs['n_episodes'])} "
            f"({_setting_text(runs)}). Mean ± std across seeds of the test success: after every "
            "epoch, noise-free test rollouts on modules drawn uniformly, their success rate "
            f"pooled over those on the {n_achievable} achievable modules "
            f"({points['n_tests'].mean():,.0f} per run and point on average); {where}."
            f"{test_text}",
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
    learned: float | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "forgetting",
) -> tuple[Figure, pd.DataFrame]:
    """Competence and LP of the perturbed module around the sensory failure, and recovery times.

    ``module`` defaults to the module the runs' variant perturbs (`statistics.perturbed_module`);
    each run's onset is where its failure started (`statistics.failure_onsets`), or
    ``perturbation_episode`` for every run. The runs whose failure started are aligned on their
    onset: the x axis counts episodes since the failure, from ``before`` episodes before it
    (default: half of what every such run has after it) to the end that all of them reach.
    Where the failure started in no run, the figure shows the module's competence over the
    whole runs, with the competence the failure waited for, and says so. Returns the figure and
    `statistics.recovery`'s table (one row per run, with its ``status`` and ``note``); the legend
    states, per condition, the mean ± std recovery time over the seeds where it could be
    measured, or why it could not be.
    """
    conditions = _ordered_conditions(df, conditions)
    rows = _restrict(df, conditions, variant)
    check_comparable(rows)
    runs = _runs_of(rows)
    module = module if module is not None else perturbed_module(rows)
    per_run = recovery(rows, module, perturbation_episode, fraction, pre_window, learned)
    onsets = per_run.dropna(subset=["perturbation_episode"]).set_index("run")
    onsets = onsets["perturbation_episode"].astype(np.int64)
    shown = palette.module_name(module)
    with figure_style():
        fig = new_figure(7.6, 5.6)
        top, bottom = fig.subplots(2, 1, sharex=True)
        if onsets.empty:
            text = _draw_unstarted(top, bottom, rows, module, conditions, per_run)
        else:
            text = _draw_aligned(top, bottom, rows, module, conditions, per_run, onsets, before)
        _competence_axis(top, f"competence of {shown}")
        bottom.set_ylabel(f"absolute LP of {shown}")
        handles = [
            top.plot([], [], color=palette.condition_color(c), linewidth=2.4)[0] for c in conditions
        ]
        labels = [
            _recovery_label(c, per_run[per_run["condition"] == c], fraction) for c in conditions
        ]
        top.legend(handles, labels, loc="lower left", bbox_to_anchor=(0.0, 1.02), borderaxespad=0)
        fig.suptitle(f"Forgetting and recovery — {shown}")
        learned_text = _values_text(per_run["learned_threshold"])
        _caption(
            fig,
            f"{_conditions_text(runs, conditions)}. Budget {budget_text(runs['n_episodes'])} "
            f"({_setting_text(runs)}). Competence and LP of {shown}, the module the sensory "
            f"failure perturbs. {text} A recovery is measured only where the failure started and "
            f"{shown} was learned before it (competence just before it at least {learned_text}): "
            f"the episodes from the failure until the competence, after its lowest point, is back "
            f"at {fraction:.0%} of its level before.",
            note,
        )
    return _finish(fig, out_dir, name), per_run


def _values_text(values: pd.Series) -> str:
    """``"0.50"``, or ``"0.50–0.70"`` where the runs differ."""
    unique = sorted(set(values.dropna().astype(float).round(4)))
    if len(unique) == 1:
        return f"{unique[0]:.2f}"
    return f"{unique[0]:.2f}–{unique[-1]:.2f}"


def _aligned(
    rows: pd.DataFrame, column: str, onsets: pd.Series, offsets: np.ndarray
) -> pd.DataFrame:
    """``column`` of every run in ``onsets`` at episode ``onset + offset`` (the last row at or
    before it), as rows `across_seeds` takes (``episodes`` holds the offset)."""
    parts = []
    for run, first, episodes, values in _run_arrays(rows, rows[column].to_numpy(np.float64)):
        if run not in onsets.index:
            continue
        wanted = int(onsets[run]) + offsets
        at = np.searchsorted(episodes, wanted, side="right") - 1
        ok = (at >= 0) & (wanted <= episodes[-1])
        part = {"run": run, "episodes": offsets[ok], "value": values[at[ok]]}
        parts.append(pd.DataFrame({"condition": rows["condition"].iat[first], **part}))
    return pd.concat(parts, ignore_index=True)


def _onset_text(per_run: pd.DataFrame, onsets: pd.Series) -> str:
    """Where the failures started, e.g. "episode 12 in every run" or "episodes 430–610 (3 of 4
    runs; the others never started)"."""
    low, high = int(onsets.min()), int(onsets.max())
    where = f"episode {low:,}" if low == high else f"episodes {low:,}–{high:,}"
    if len(onsets) == len(per_run):
        return f"{where} in every run"
    return f"{where} ({len(onsets)} of {len(per_run)} runs; in the others it never started)"


def _draw_aligned(
    top: Axes,
    bottom: Axes,
    rows: pd.DataFrame,
    module: str,
    conditions: Sequence[str],
    per_run: pd.DataFrame,
    onsets: pd.Series,
    before: int | None,
) -> str:
    """The runs whose failure started, aligned on it; returns the caption's middle."""
    last = rows.groupby("run", observed=True)["episode"].max()
    after = int((last[onsets.index] + 1 - onsets).min())
    if before is None:
        before = max(1, after // 2)
    before = min(before, int(onsets.min()))
    step = _curve_bin(before + after)
    offsets = np.arange(-(before // step), (after - 1) // step + 1) * step
    comp = across_seeds(_aligned(rows, f"competence/{module}", onsets, offsets))
    lp = across_seeds(_aligned(rows, f"lp/{module}", onsets, offsets))
    for i, c in enumerate(conditions):
        color, width = palette.condition_color(c), _line_width(i, len(conditions))
        for ax, table in ((top, comp), (bottom, lp)):
            s = table[table["condition"] == c]
            _draw_mean_std(ax, s[s["n"] == s["n"].max()], color, width, None)
        mine = per_run[(per_run["condition"] == c) & (per_run["status"] == "measured")]
        if not mine.empty:
            top.axhline(mine["threshold"].mean(), color=color, linestyle=":", linewidth=1.0)
    _lp_axis(bottom, float(np.nanmax(lp["mean"] + lp["std"].fillna(0.0))) if len(lp) else 0.0)
    for ax in (top, bottom):
        ax.axvline(0, color="black", linestyle="--", linewidth=1.0)
        ax.set_xlim(offsets[0], offsets[-1])
    episodes_axis(top, label=False)
    episodes_axis(bottom)
    bottom.set_xlabel("episodes since the sensory failure")
    top.annotate(
        "sensory failure",
        xy=(0, 1.0),
        xytext=(4, 0),
        textcoords="offset points",
        fontsize=7.5,
        va="top",
    )
    dotted = (
        " Dotted lines: each condition's recovery threshold (mean over its measured seeds)."
        if (per_run["status"] == "measured").any()
        else ""
    )
    return (
        f"Each run is aligned on the first episode run with the failure "
        f"({_onset_text(per_run, onsets)}); mean ± std across the seeds where it started, "
        f"sampled every {_episodes_text(step)}.{dotted}"
    )


def _draw_unstarted(
    top: Axes,
    bottom: Axes,
    rows: pd.DataFrame,
    module: str,
    conditions: Sequence[str],
    per_run: pd.DataFrame,
) -> str:
    """The whole runs, where the failure started in none; returns the caption's middle."""
    n_episodes = int(rows.groupby("run", observed=True)["episode"].max().min()) + 1
    step = _curve_bin(n_episodes)
    comp = across_seeds(bin_runs(rows, f"competence/{module}", step))
    lp = across_seeds(bin_runs(rows, f"lp/{module}", step))
    for i, c in enumerate(conditions):
        color, width = palette.condition_color(c), _line_width(i, len(conditions))
        for ax, table in ((top, comp), (bottom, lp)):
            s = table[table["condition"] == c]
            _draw_mean_std(ax, s[s["n"] == s["n"].max()], color, width, None)
    waited = rows.groupby("run", observed=True)["failure_competence"].first().dropna()
    for level in sorted(set(waited.astype(float))):
        top.axhline(level, color="black", linestyle=":", linewidth=1.0)
    _lp_axis(bottom, _lp_top(rows[[f"lp/{module}"]]))
    for ax in (top, bottom):
        ax.set_xlim(0, n_episodes)
    episodes_axis(top, label=False)
    episodes_axis(bottom)
    top.text(
        0.01,
        0.97,
        "the sensory failure never started",
        transform=top.transAxes,
        fontsize=8,
        va="top",
    )
    highest = float(np.nanmax(rows[f"competence/{module}"].to_numpy(np.float64)))
    why = (
        f"the failure was to start when this competence reached {_values_text(waited)} (dotted), "
        f"and it reached at most {highest:.2f}"
        if not waited.empty
        else "every run ended before its planned onset"
    )
    return (
        f"Mean ± std across seeds over the whole runs, sampled every {_episodes_text(step)}. "
        f"The failure never started in any run, so no recovery can be measured: {why}."
    )


def _recovery_label(condition: str, runs: pd.DataFrame, fraction: float) -> str:
    """A condition's legend entry: its recovery over the measured seeds, or why none is."""
    name = palette.condition_label(condition)
    n = len(runs)
    measured = runs[runs["status"] == "measured"]
    m = len(measured)
    if m == 0:
        never = int((runs["status"] == "never_started").sum())
        if never == n:
            return f"{name}: the failure never started ({n} of {n} seeds)"
        if never == 0:
            return f"{name}: not learned before the failure, nothing to forget ({n} of {n} seeds)"
        return (
            f"{name}: nothing to measure (never started in {never}, not learned before it in "
            f"{n - never} of {n} seeds)"
        )
    rest = "" if m == n else f"; {n - m} of {n} seeds not measurable"
    if not measured["dropped"].any():
        return f"{name}: never fell below {fraction:.0%} of its level before ({m} seeds{rest})"
    back = measured[measured["recovered"]]
    if back.empty:
        return f"{name}: {fraction:.0%} not regained by the end (0/{m} seeds{rest})"
    mean = back["recovery_episodes"].mean()
    spread = f" ± {back['recovery_episodes'].std(ddof=1):,.0f}" if len(back) > 1 else ""
    return (
        f"{name}: {fraction:.0%} regained after {mean:,.0f}{spread} episodes "
        f"({len(back)}/{m} seeds{rest})"
    )


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
