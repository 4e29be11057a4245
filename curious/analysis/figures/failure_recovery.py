"""The sensory-failure figure (`sensor_failure`): the perturbed module around the failure, and the
recovery where it can be measured; given the runs' test rollouts, their test success too, the
primary measure of the study on a mastered module (`perturbation.recovery_by_tests`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from os import PathLike

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.transforms import ScaledTranslation

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
from curious.analysis.loading import AnalysisError
from curious.analysis.milestones import module_test_success
from curious.analysis.perturbation import perturbed_module, recovery, recovery_by_tests
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
from curious.config import DEFAULT_TEST_EPOCHS
from curious.watching import palette

_LEGEND_HEIGHT = (0.45, 0.16)
"""Inches the figure grows by for the per-run legend under its panels: its gap and title, then
each run's entry (so that the panels keep their height however many runs are drawn)."""


def sensor_failure(
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
    name: str = "sensor_failure",
    tests: pd.DataFrame | None = None,
) -> tuple[Figure, pd.DataFrame]:
    """Competence and LP of the perturbed module around the sensory failure, and recovery times.

    ``module`` defaults to the module the runs' sensory failure perturbs
    (`perturbation.perturbed_module`); each run's onset is where its failure started
    (`perturbation.failure_onsets`), or ``perturbation_episode`` for every run. The runs whose
    failure started are aligned on their onset and drawn one line per run (so that a run that
    never recovered shows as such): the x axis counts episodes since the failure, from
    ``before`` episodes before it (default: a quarter of what it shows after it) to a fifth
    beyond the latest recovery, or end of a run not recovered (`_horizon`), each run up to its
    own end; a circle marks each recovery, a cross the end of a run that never recovered.
    Where the failure started in no run, the figure shows the module's competence over the
    whole runs, with the competence the failure waited for, and says so. Returns the figure and
    `perturbation.recovery`'s table (one row per run, with its ``status`` and ``note``); the
    legend states, per condition, the mean ± std recovery time over the seeds where it could be
    measured, or why it could not be.

    With ``tests`` (the same runs' `load_tests` table), a panel above the others draws the
    module's test success pooled over `DEFAULT_TEST_EPOCHS` epochs, with each run's recovery by
    `perturbation.recovery_by_tests` (the legend's per-run entries give it first).
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
    tested = None
    if tests is not None:
        tests = tests[tests["run"].isin(per_run["run"])]
        if tests.empty:
            raise AnalysisError(
                "the test rollouts must be those of the same runs as the competence: load both "
                "from the same run folders"
            )
        starts = per_run.set_index("run")["perturbation_episode"]
        tested = _Tested(tests, recovery_by_tests(tests, starts, module, fraction), module)
    grow = _LEGEND_HEIGHT[0] + _LEGEND_HEIGHT[1] * len(onsets) if len(onsets) else 0.0
    with figure_style():
        if tested is None:
            fig = new_figure(9.2, 5.8 + grow)
            top, bottom = fig.subplots(2, 1, sharex=True)
            first = top
        else:
            fig = new_figure(9.2, 8.2 + grow)
            first, top, bottom = fig.subplots(3, 1, sharex=True)
        if onsets.empty:
            text = _draw_unstarted(top, bottom, rows, module, conditions, per_run)
        else:
            text = _draw_aligned(
                top, bottom, rows, module, conditions, per_run, onsets, before, fraction, tested
            )
        if tested is not None:
            text = _draw_tested(first, tested, conditions, onsets, fraction) + " " + text
        competence_axis(top, f"competence of {shown}")
        bottom.set_ylabel(f"absolute LP of {shown}")
        handles = [
            top.plot([], [], color=palette.condition_color(c), linewidth=2.4)[0] for c in conditions
        ]
        labels = [
            _recovery_label(
                c,
                per_run[per_run["condition"] == c],
                fraction,
                None if tested is None else tested.per_run[tested.per_run["condition"] == c],
            )
            for c in conditions
        ]
        first.legend(handles, labels, loc="lower left", bbox_to_anchor=(0.0, 1.02), borderaxespad=0)
        fig.suptitle(f"Sensory failure and recovery — {shown}")
        learned_text = _values_text(per_run["learned_threshold"])
        caption(
            fig,
            f"{conditions_text(runs, conditions)}. Budget {budget_text(runs['n_episodes'])} "
            f"({setting_text(runs)}). Competence and LP of {shown}, the module the sensory "
            f"failure perturbs. {text} A recovery is measured only where the failure started and "
            f"{shown} was learned before it (competence just before it at least {learned_text}): "
            f"the episodes from the failure until the competence, after its lowest point, is back "
            f"at {fraction:.0%} of its pre-failure mean (its mean over the last p/10 episodes "
            "before a failure at episode p).",
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


SEED_STYLES = ("-", "--", ":", "-.", (0, (6, 1.6, 1, 1.6, 1, 1.6)), (0, (12, 3)))
"""Line styles of a condition's runs, in seed order (then again): solid, dashed, dotted,
dash-dot, dash-dot-dot and long dashes, so that the five seeds a side of the study on a mastered
module draw as five lines, and a sixth seed too."""


def _horizon(per_run: pd.DataFrame, remaining: pd.Series) -> int:
    """Episodes after the failure that the x axis covers: a fifth beyond the latest of each
    run's recovery (or, for a run not recovered, its end), so that every recovery and every
    run that never recovered show whole; never beyond the longest run."""
    latest = 0
    for r in per_run.itertuples():
        if r.run not in remaining.index:
            continue
        if bool(r.recovered) and pd.notna(r.recovery_episodes):
            latest = max(latest, int(r.recovery_episodes))
        else:
            latest = max(latest, int(remaining[r.run]))
    return int(min(int(remaining.max()), max(1, math.ceil(latest * 1.2))))


def _run_label(r: object, fraction: float, remaining: int, tested: object = None) -> str:
    """A run's legend entry: its seed and its recovery, or why there is none; with ``tested``
    (its `recovery_by_tests` row), the recovery of its test success first."""
    name = f"{palette.condition_label(r.condition)} seed {int(r.seed)}"
    if tested is None:
        return f"{name}: {_competence_text(r, fraction, remaining)}"
    return f"{name}: {_tested_text(tested)}; competence {_competence_text(r, fraction, remaining)}"


def _tested_text(t: object) -> str:
    """A run's recovery of test success, in a few words."""
    if t.status != "measured":
        return "no level before" if t.status == "no_level" else "no onset"
    if bool(t.recovered):
        return f"tests back after {int(t.recovery_episodes):,}"
    return f"tests not back by its end ({int(t.episodes_left):,} after)"


def _competence_text(r: object, fraction: float, remaining: int) -> str:
    """A run's recovery of competence, in a few words."""
    if r.status != "measured":
        return "nothing to measure"
    if not bool(r.dropped):
        return f"never below {fraction:.0%}"
    if bool(r.recovered):
        return f"{fraction:.0%} regained after {int(r.recovery_episodes):,}"
    return f"not regained by its end ({remaining:,} after)"


class _Tested:
    """The test rollouts of a figure's runs: the module's pooled test success per epoch, and
    each run's `recovery_by_tests` row."""

    def __init__(self, tests: pd.DataFrame, per_run: pd.DataFrame, module: str) -> None:
        rates = module_test_success(tests, DEFAULT_TEST_EPOCHS)
        self.rates = rates[rates["module"].astype(str) == module]
        self.per_run = per_run
        self.by_run = {str(r.run): r for r in per_run.itertuples()}
        self.module = module


def _draw_tested(
    ax: Axes, tested: _Tested, conditions: Sequence[str], onsets: pd.Series, fraction: float
) -> str:
    """Each run's pooled test success of the module, aligned on its onset where the failure
    started somewhere (runs without one left out), else over the whole runs; a circle where a
    run's test success came back, a cross at the end of one that did not. Returns the
    caption's sentence."""
    aligned = not onsets.empty
    window = DEFAULT_TEST_EPOCHS
    for i, c in enumerate(conditions):
        color, width = palette.condition_color(c), 0.6 + line_width(i, len(conditions)) / 2
        mine = tested.per_run[tested.per_run["condition"] == c].sort_values("seed")
        for k, t in enumerate(mine.itertuples()):
            if aligned and t.run not in onsets.index:
                continue
            shift = int(onsets[t.run]) if aligned else 0
            run = tested.rates[tested.rates["run"] == t.run]
            x, y = run["episodes"].to_numpy() - shift, run["value"].to_numpy()
            style = SEED_STYLES[k % len(SEED_STYLES)]
            ax.plot(x, y, color=color, linestyle=style, linewidth=width)
            if t.status == "measured" and bool(t.recovered):
                mark = {"marker": "o", "markersize": 6, "markerfacecolor": "white"}
                at = (float(t.recovery_episodes), float(t.threshold))
                ax.plot(*at, markeredgecolor=color, markeredgewidth=1.6, linestyle="none", **mark)
            elif t.status == "measured" and len(x):
                ax.plot(x[-1], y[-1], marker="X", markersize=7, color=color, linestyle="none")
    if aligned:
        ax.axvline(0, color="black", linestyle="--", linewidth=1.0)
    competence_axis(ax, f"test success of {palette.module_name(tested.module)}")
    episodes_axis(ax, label=False)
    epoch = int(tested.per_run["epoch_episodes"].max()) if len(tested.per_run) else 0
    if tested.rates.empty:
        ax.text(
            0.01,
            0.97,
            f"fewer than {window} epochs tested: no pooled test success",
            transform=ax.transAxes,
            fontsize=8,
            va="top",
        )
    return (
        f"Top: its test success (noise-free test rollouts, modules drawn uniformly) pooled over "
        f"{window} epochs ({window * epoch:,} episodes), the primary measure of recovery: a "
        f"circle where a run's rate, pooled over epochs tested wholly after the failure, is back "
        f"at {fraction:.0%} of its rate over the {window} epochs before it, a cross at the end "
        "of a run where it is not (censored there by the log-rank test of the recoveries)."
    )


def _draw_aligned(
    top: Axes,
    bottom: Axes,
    rows: pd.DataFrame,
    module: str,
    conditions: Sequence[str],
    per_run: pd.DataFrame,
    onsets: pd.Series,
    before: int | None,
    fraction: float,
    tested: _Tested | None = None,
) -> str:
    """The runs whose failure started, aligned on it, one line per run; returns the caption's
    middle. With ``tested``, the x axis covers the recoveries of test success too, and each
    run's legend entry gives both."""
    last = rows.groupby("run", observed=True)["episode"].max()
    remaining = (last[onsets.index] + 1 - onsets).astype(np.int64)
    marks = per_run
    if tested is not None:
        columns = ["run", "recovered", "recovery_episodes"]
        marks = pd.concat([per_run[columns], tested.per_run[columns]], ignore_index=True)
    after = _horizon(marks, remaining)
    if before is None:
        before = max(1, after // 4)
    before = min(before, int(onsets.min()))
    step = curve_bin(before + after)
    offsets = np.arange(-(before // step), (after - 1) // step + 1) * step
    comp = _aligned(rows, f"competence/{module}", onsets, offsets)
    lp = _aligned(rows, f"lp/{module}", onsets, offsets)
    handles, labels = [], []
    lp_top = 0.0
    for i, c in enumerate(conditions):
        color, width = palette.condition_color(c), 0.6 + line_width(i, len(conditions)) / 2
        mine = per_run[(per_run["condition"] == c) & per_run["run"].isin(onsets.index)]
        for k, r in enumerate(mine.sort_values("seed").itertuples()):
            style = SEED_STYLES[k % len(SEED_STYLES)]
            c_run, l_run = comp[comp["run"] == r.run], lp[lp["run"] == r.run]
            (line,) = top.plot(
                c_run["episodes"], c_run["value"], color=color, linestyle=style, linewidth=width
            )
            bottom.plot(
                l_run["episodes"], l_run["value"], color=color, linestyle=style, linewidth=width
            )
            lp_top = max(lp_top, float(np.nanmax(l_run["value"])) if len(l_run) else 0.0)
            if r.status == "measured" and bool(r.recovered) and bool(r.dropped):
                top.plot(
                    [int(r.recovery_episodes)],
                    [float(r.threshold)],
                    marker="o",
                    markersize=6,
                    markerfacecolor="white",
                    markeredgecolor=color,
                    markeredgewidth=1.6,
                    linestyle="none",
                )
            elif r.status == "measured" and bool(r.dropped) and len(c_run):
                top.plot(
                    [c_run["episodes"].iat[-1]],
                    [c_run["value"].iat[-1]],
                    marker="X",
                    markersize=7,
                    color=color,
                    linestyle="none",
                )
            handles.append(line)
            own = None if tested is None else tested.by_run.get(str(r.run))
            labels.append(_run_label(r, fraction, int(remaining[r.run]), own))
    lp_axis(bottom, lp_top)
    for ax in (top, bottom):
        ax.axvline(0, color="black", linestyle="--", linewidth=1.0)
        ax.set_xlim(offsets[0], offsets[-1])
    episodes_axis(top, label=False)
    episodes_axis(bottom)
    bottom.set_xlabel("episodes since the sensory failure")
    # under the x axis's label (a fixed 32 points below the axes, whatever the figure's size),
    # where its width does not narrow the panels; constrained layout makes room for it
    below = bottom.transAxes + ScaledTranslation(0, -32 / 72, bottom.get_figure().dpi_scale_trans)
    bottom.legend(
        handles,
        labels,
        loc="upper left",
        bbox_to_anchor=(0.0, 0.0),
        bbox_transform=below,
        borderaxespad=0.0,
        title="each run",
        alignment="left",
        fontsize=7.5,
        handlelength=5.0,  # long enough to show a whole dash-dot-dot and long-dash period
        title_fontsize=8,
    )
    top.annotate(
        "sensory failure",
        xy=(0, 1.0),
        xytext=(4, 0),
        textcoords="offset points",
        fontsize=7.5,
        va="top",
    )
    drawn = per_run[per_run["run"].isin(onsets.index) & (per_run["status"] == "measured")]
    crossed = (drawn["dropped"].astype(bool) & ~drawn["recovered"].astype(bool)).any()
    ended = " A cross: a run that ended before regaining it." if crossed else ""
    return (
        f"Each run is aligned on the first episode run with the failure "
        f"({_onset_text(per_run, onsets)}) and drawn as its own line (line style: seed) up to "
        f"its end or {after:,} episodes after the failure, sampled every "
        f"{episodes_text(step)}. A circle: where a run regained {fraction:.0%} of its pre-failure "
        f"mean.{ended}"
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


def _recovery_label(
    condition: str, runs: pd.DataFrame, fraction: float, tested: pd.DataFrame | None = None
) -> str:
    """A condition's legend entry: its recovery over the measured seeds, or why none is; with
    ``tested`` (its runs' `recovery_by_tests` rows), the recovery of test success first."""
    name = palette.condition_label(condition)
    if tested is None:
        return f"{name}: {_competence_summary(runs, fraction)}"
    return f"{name}: {_tested_summary(tested)}; competence {_competence_summary(runs, fraction)}"


def _spread(episodes: pd.Series) -> str:
    """``"1,200"`` or ``"1,200 ± 300"`` (mean, and std over several runs)."""
    spread = f" ± {episodes.std(ddof=1):,.0f}" if len(episodes) > 1 else ""
    return f"{episodes.mean():,.0f}{spread}"


def _tested_summary(tested: pd.DataFrame) -> str:
    """A condition's recovery of test success over its runs, in a few words."""
    back = tested.loc[tested["recovered"].astype(bool), "recovery_episodes"]
    if back.empty:
        return f"test success not back (0/{len(tested)} seeds)"
    return f"test success back after {_spread(back)} episodes ({len(back)}/{len(tested)} seeds)"


def _competence_summary(runs: pd.DataFrame, fraction: float) -> str:
    """A condition's recovery of competence over the measured seeds, or why none is."""
    n = len(runs)
    measured = runs[runs["status"] == "measured"]
    m = len(measured)
    if m == 0:
        never = int((runs["status"] == "never_started").sum())
        if never == n:
            return f"the failure never started ({n} of {n} seeds)"
        if never == 0:
            return f"not learned before the failure, nothing to forget ({n} of {n} seeds)"
        return (
            f"nothing to measure (never started in {never}, not learned before it in "
            f"{n - never} of {n} seeds)"
        )
    rest = "" if m == n else f"; {n - m} of {n} seeds not measurable"
    if not measured["dropped"].any():
        return f"never fell below {fraction:.0%} of its pre-failure mean ({m} seeds{rest})"
    back = measured[measured["recovered"]]
    if back.empty:
        return f"{fraction:.0%} not regained by the end (0/{m} seeds{rest})"
    return (
        f"{fraction:.0%} regained after {_spread(back['recovery_episodes'])} episodes "
        f"({len(back)}/{m} seeds{rest})"
    )


# ----------------------------------------------------------------------------- distractors
