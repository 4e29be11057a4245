"""The figures beyond the paper: LP's two uses apart (`lp_uses`) and its sign (`signed_lp`).

`lp_uses` sets the four conditions side by side on `distractors_7`: each run's competence (and
test success) at the end, and the share of its practice spent on distracting modules over the
run, with the share of its replayed transitions assigned to one where its runs kept their replay
counts (`learner.parquet`). `signed_lp` is the sensory-failure figure with CURIOUS's runs
under each LP measure, the signed ones drawn as a condition of their own (`SIGNED_LP`).
"""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from curious.analysis.figures.failure_recovery import sensor_failure
from curious.analysis.figures.parts import (
    caption,
    conditions_text,
    draw_mean_std,
    finish,
    legend_right,
    restrict,
    runs_of,
    setting_text,
)
from curious.analysis.loading import AnalysisError
from curious.analysis.lp_ablations import SIGNED_LP, signed_beside_absolute
from curious.analysis.statistics import (
    across_seeds,
    distractor_share,
    final_competence,
    final_test_success,
    replay_share,
)
from curious.analysis.style import budget_text, episodes_axis, figure_style, new_figure
from curious.watching import palette

LP_USE_ORDER: tuple[str, ...] = ("m-uvfa", "lp-replay", "lp-select", "curious")
"""The conditions of `lp_uses`, from no use of LP to both."""


def lp_uses(
    df: pd.DataFrame,
    tests: pd.DataFrame | None = None,
    at_episode: int | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "lp_uses",
    learner: pd.DataFrame | None = None,
) -> Figure:
    """Each condition's competence over the achievable modules at the end of its runs (and,
    with ``tests``, their test success over the last bin), one dot a run and its mean ± std, and
    the share of training episodes spent on a distracting module over the runs, mean ± std
    across seeds: M-UVFA, `lp-replay`, `lp-select` and CURIOUS (those of them ``df`` holds).
    With ``learner`` (`load_learner` of the runs that kept their replay counts), the share of
    replayed transitions assigned to a distracting module beside it, dashed."""
    present = set(df["condition"].astype(str))
    conditions = [c for c in LP_USE_ORDER if c in present]
    if not conditions:
        raise AnalysisError(
            f"no runs of {', '.join(LP_USE_ORDER)} (have: {', '.join(sorted(present))})"
        )
    rows = restrict(df, conditions, None)
    final = final_competence(rows, at_episode)
    panels = [(final, "competence over the\nachievable modules at the end")]
    if tests is not None:
        tested = final_test_success(restrict(tests, conditions, None))
        panels.append((tested, "test success over the\nachievable modules, last bin"))
    share = distractor_share(rows)
    bin_size = int(share.attrs["bin_size"])
    replayed = None
    kept = None if learner is None else restrict(learner, conditions, None)
    if kept is not None and not kept.empty:
        replayed = replay_share(kept, bin_size)
    runs = runs_of(rows)
    with figure_style():
        fig = new_figure(4.2 * len(panels) + 5.4, 4.4)
        axes = fig.subplots(1, len(panels) + 1, squeeze=False)[0]
        for ax, (values, label) in zip(axes[:-1], panels, strict=True):
            _per_run_panel(ax, values, conditions)
            ax.set_ylabel(label)
        _share_panel(axes[-1], share, conditions, replayed)
        legend_right(axes[-1])
        fig.suptitle("LP's two uses apart — module selection and task replay")
        episodes = int(final["episodes"].iat[0])
        text = (
            f"{conditions_text(runs, conditions)}. Budget {budget_text(runs['n_episodes'])} "
            f"({setting_text(runs)}). Left: each run's competence (the success rate of its recent "
            f"self-evaluations) averaged over the achievable modules after {episodes:,} "
            "episodes, a dot a run, the bar its condition's mean ± std"
        )
        if tests is not None:
            end, width = int(tested["episodes"].iat[0]), int(tested.attrs["bin_size"])
            text += (
                f"; middle: the noise-free test rollouts on the achievable modules, pooled per "
                f"run over episodes {max(end - width, 0) + 1:,}–{end:,}"
            )
        text += (
            f". Right: the share of training episodes that practised a distracting module "
            f"(solid), per {bin_size:,} episodes, mean ± std across seeds"
        )
        text += _replay_text(replayed, conditions) + (
            ". LP-select chooses modules by LP and replays uniformly; LP-replay chooses "
            "uniformly and replays by LP; neither is in the paper."
        )
        caption(fig, text, note)
    return finish(fig, out_dir, name)


def _per_run_panel(ax: Axes, values: pd.DataFrame, conditions: Sequence[str]) -> None:
    """One value per run at each condition's place: the runs as dots, mean ± std as a bar."""
    for x, c in enumerate(conditions):
        mine = values.loc[values["condition"].astype(str) == c, "value"].to_numpy(np.float64)
        color = palette.condition_color(c)
        ax.scatter(np.full(len(mine), x, dtype=np.float64), mine, color=color, s=18, zorder=3)
        std = float(np.std(mine, ddof=1)) if len(mine) > 1 else 0.0
        ax.errorbar(x + 0.18, float(np.mean(mine)), yerr=std, color=color, marker="_",
                    markersize=14, capsize=4)  # fmt: skip
    ax.set_xticks(range(len(conditions)))
    ax.set_xticklabels([palette.condition_label(c) for c in conditions])
    ax.set_xlim(-0.6, len(conditions) - 0.4)
    ax.set_ylim(-0.03, 1.03)


def _share_panel(
    ax: Axes, share: pd.DataFrame, conditions: Sequence[str], replayed: pd.DataFrame | None
) -> None:
    """The distracting modules' share of practice over the runs, a curve per condition, and
    their share of replay (dashed) where ``replayed`` has the condition's runs."""
    table = across_seeds(share)
    for c in conditions:
        s = table[table["condition"].astype(str) == c].sort_values("episodes")
        draw_mean_std(ax, s, palette.condition_color(c), 2.0, palette.condition_label(c))
    if replayed is not None and not replayed.empty:
        table = across_seeds(replayed)
        for c in conditions:
            s = table[table["condition"].astype(str) == c].sort_values("episodes")
            if not s.empty:
                draw_mean_std(ax, s, palette.condition_color(c), 1.4, None, 0.1, "--")
    ax.set_ylim(-0.03, 1.03)
    ax.set_ylabel("share on a distracting module\n(solid: episodes; dashed: replay)")
    episodes_axis(ax)


def _replay_text(replayed: pd.DataFrame | None, conditions: Sequence[str]) -> str:
    """The caption's words for the dashed curves: what they are, and whose runs have none."""
    have = set() if replayed is None else set(replayed["condition"].astype(str))
    without = [palette.condition_label(c) for c in conditions if c not in have]
    if len(without) == len(conditions):
        return "; no share of replay is drawn: no run's replay counts cover a whole bin"
    text = (
        "; dashed, the share of transitions replayed as a distracting module, from the runs' "
        "replay counts"
    )
    if without:
        text += (
            f" ({', '.join(without)}: none drawn, their runs' replay counts covering no whole "
            "bin; runs trained before runs kept them have none)"
        )
    return text


def signed_lp(
    absolute: pd.DataFrame | None,
    signed: pd.DataFrame,
    tests_absolute: pd.DataFrame | None = None,
    tests_signed: pd.DataFrame | None = None,
    note: str | None = None,
    out_dir: str | PathLike[str] | None = None,
    name: str = "signed_lp",
) -> tuple[Figure, pd.DataFrame]:
    """The sensory-failure figure (`sensor_failure`) of CURIOUS's runs under absolute LP
    (``absolute``, e.g. `sensor_failure_mastered`'s) and signed LP (``signed``, drawn as
    `SIGNED_LP`), each table with its test rollouts where given (both or neither; where
    ``absolute`` is None, the signed runs alone with ``tests_signed``). Returns the figure and the
    `recovery` table of every run."""
    if absolute is not None and (tests_absolute is None) != (tests_signed is None):
        raise AnalysisError("give the test rollouts of both measures' runs, or of neither")
    tests = None
    if tests_signed is not None:
        tests = signed_beside_absolute(tests_signed, None if absolute is None else tests_absolute)
    fig, per_run = sensor_failure(
        signed_beside_absolute(signed, absolute),
        conditions=(["curious"] if absolute is not None else []) + [SIGNED_LP],
        note=note,
        tests=tests,
        name=name,
    )
    fig.axes[-1].set_ylabel("LP (absolute; signed: its rise only)")
    measures = "Absolute against signed LP" if absolute is not None else "Signed LP"
    fig.suptitle(f"{measures} — sensory failure on a mastered module")
    return finish(fig, out_dir, name), per_run
