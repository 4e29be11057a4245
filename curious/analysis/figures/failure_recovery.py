"""The sensory-failure figure (`forgetting`): the perturbed module around the failure, and the
recovery where it can be measured."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from curious.analysis import palette
from curious.analysis.figures.parts import (
    caption,
    competence_axis,
    conditions_text,
    curve_bin,
    draw_mean_std,
    episodes_text,
    finish,
    line_width,
    lp_axis,
    lp_ceiling,
    ordered_conditions,
    restrict,
    runs_of,
    setting_text,
)
from curious.analysis.perturbation import perturbed_module, recovery
from curious.analysis.statistics import (
    across_seeds,
    bin_runs,
    check_comparable,
    run_arrays,
)
from curious.analysis.style import (
    budget_text,
    episodes_axis,
    figure_style,
    new_figure,
)


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

    ``module`` defaults to the module the runs' sensory failure perturbs
    (`perturbation.perturbed_module`); each run's onset is where its failure started
    (`perturbation.failure_onsets`), or ``perturbation_episode`` for every run. The runs whose
    failure started are aligned on their onset: the x axis counts episodes since the failure,
    from ``before`` episodes before it (default: half of what every such run has after it) to
    the end that all of them reach.
    Where the failure started in no run, the figure shows the module's competence over the
    whole runs, with the competence the failure waited for, and says so. Returns the figure and
    `perturbation.recovery`'s table (one row per run, with its ``status`` and ``note``); the
    legend states, per condition, the mean ± std recovery time over the seeds where it could be
    measured, or why it could not be.
    """
    conditions = ordered_conditions(df, conditions)
    rows = restrict(df, conditions, variant)
    check_comparable(rows)
    runs = runs_of(rows)
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
        competence_axis(top, f"competence of {shown}")
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
        caption(
            fig,
            f"{conditions_text(runs, conditions)}. Budget {budget_text(runs['n_episodes'])} "
            f"({setting_text(runs)}). Competence and LP of {shown}, the module the sensory "
            f"failure perturbs. {text} A recovery is measured only where the failure started and "
            f"{shown} was learned before it (competence just before it at least {learned_text}): "
            f"the episodes from the failure until the competence, after its lowest point, is back "
            f"at {fraction:.0%} of its level before.",
            note,
        )
    return finish(fig, out_dir, name), per_run


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
    for run, first, episodes, values in run_arrays(rows, rows[column].to_numpy(np.float64)):
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


def _draw_conditions(
    top: Axes, bottom: Axes, comp: pd.DataFrame, lp: pd.DataFrame, conditions: Sequence[str]
) -> None:
    """Each condition's mean ± std of competence (top) and LP (bottom), over the points that
    all its seeds reach."""
    for i, c in enumerate(conditions):
        color, width = palette.condition_color(c), line_width(i, len(conditions))
        for ax, table in ((top, comp), (bottom, lp)):
            s = table[table["condition"] == c]
            draw_mean_std(ax, s[s["n"] == s["n"].max()], color, width, None)


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
    step = curve_bin(before + after)
    offsets = np.arange(-(before // step), (after - 1) // step + 1) * step
    comp = across_seeds(_aligned(rows, f"competence/{module}", onsets, offsets))
    lp = across_seeds(_aligned(rows, f"lp/{module}", onsets, offsets))
    _draw_conditions(top, bottom, comp, lp, conditions)
    for c in conditions:
        mine = per_run[(per_run["condition"] == c) & (per_run["status"] == "measured")]
        if not mine.empty:
            color = palette.condition_color(c)
            top.axhline(mine["threshold"].mean(), color=color, linestyle=":", linewidth=1.0)
    lp_axis(bottom, float(np.nanmax(lp["mean"] + lp["std"].fillna(0.0))) if len(lp) else 0.0)
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
        f"sampled every {episodes_text(step)}.{dotted}"
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
    step = curve_bin(n_episodes)
    comp = across_seeds(bin_runs(rows, f"competence/{module}", step))
    lp = across_seeds(bin_runs(rows, f"lp/{module}", step))
    _draw_conditions(top, bottom, comp, lp, conditions)
    waited = rows.groupby("run", observed=True)["failure_competence"].first().dropna()
    for level in sorted(set(waited.astype(float))):
        top.axhline(level, color="black", linestyle=":", linewidth=1.0)
    lp_axis(bottom, lp_ceiling(rows[[f"lp/{module}"]]))
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
        f"Mean ± std across seeds over the whole runs, sampled every {episodes_text(step)}. "
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
