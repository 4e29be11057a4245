"""The layout a run's recording opens with in the Rerun viewer.

Left: the 3D rollouts above the success of the test rollouts (per module, every epoch), the
per-episode success (evaluation and training) and the module of each episode. Right: competence,
absolute learning progress and p_LP per module, then the learner's losses, Q statistics and replay
composition in tabs. The time panel starts on the `episode` timeline; switch it to
`rollout_frame` and press play to watch the recorded rollouts one after another.

Legends: the viewer draws a legend inside its plot, at most 80% of the plot's height (it scrolls
beyond), so the layout gives the views with a legend the height for seven modules at 1600x1000:
the side panels and the time panel start collapsed (their buttons top right and the timeline bar
at the bottom open them). A legend sits in the bottom-right corner, away from the start of the
run, where every module's curve begins. Absolute learning progress, p_LP and the replay
composition show no legend of their own: their colours are those of the competence legend above
them (every view draws a module in the same colour). The viewer lists a legend in the order of
the entity paths, so a module's path part leads with the paper's task number
(`competence/T1-reach`, `curious.watching.palette.module_entity`) and the legend reads T1..T7.

Axes of shares and success rates span [-0.05, 1.05], and the module of each episode (its slot
index) -0.5 to n_modules - 0.5, so that points and lines at the ends are drawn whole instead of
half cut by the plot's edge.
"""

from __future__ import annotations

import rerun.blueprint as rrb

__all__ = ["LEGEND_CORNER", "UNIT_RANGE", "default_blueprint"]

UNIT_RANGE = (-0.05, 1.05)
"""Y range of views of values in [0, 1], with a margin so that 0 and 1 are not on the edge."""
LEGEND_CORNER = rrb.Corner2D.RightBottom
"""Where a module legend sits: away from the start of the run, where all curves begin."""


def _series(
    name: str,
    origin: str,
    *,
    unit: bool = False,
    axis: rrb.ScalarAxis | None = None,
    legend: bool = True,
) -> rrb.View:
    """A time-series view of `origin`: `unit` for values in [0, 1] (else `axis`, or the
    viewer's automatic range), with a legend in `LEGEND_CORNER` or (`legend=False`) none."""
    return rrb.TimeSeriesView(
        name=name,
        origin=origin,
        axis_y=rrb.ScalarAxis(range=UNIT_RANGE) if unit else axis,
        plot_legend=rrb.PlotLegend(corner=LEGEND_CORNER, visible=legend),
    )


def default_blueprint(n_modules: int | None = None) -> rrb.Blueprint:
    """The default blueprint sent with every run's recording (entity paths as in `recorder`).

    `n_modules` fixes the y range of the module-per-episode view to the slots; None leaves it
    to the viewer.
    """
    slots = None if n_modules is None else rrb.ScalarAxis(range=(-0.5, n_modules - 0.5))
    left = rrb.Vertical(
        rrb.Spatial3DView(name="Rollouts", origin="/scene"),
        rrb.Tabs(
            _series("Test success (per epoch)", "/test", unit=True),
            _series("Success (evaluation)", "/success/eval", unit=True),
            _series("Success (training)", "/success/train", unit=True),
            _series("Module per episode", "/module", axis=slots),
        ),
        row_shares=[3.0, 2.0],
    )
    right = rrb.Vertical(
        _series("Competence", "/competence", unit=True),
        _series("Absolute learning progress", "/lp", legend=False),
        _series("p_LP (module selection probability)", "/p_lp", unit=True, legend=False),
        rrb.Tabs(
            rrb.TimeSeriesView(name="Losses", origin="/losses"),
            rrb.TimeSeriesView(name="Q", origin="/q"),
            _series("Replay composition", "/replay", unit=True, legend=False),
        ),
        row_shares=[1.3, 1.0, 1.0, 0.8],
    )
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[1.0, 1.0]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(timeline="episode", state="collapsed"),
    )
