"""The layout a run's recording opens with in the Rerun viewer.

Left: the 3D rollouts above the success of the test rollouts (per module, every epoch), the
per-episode success (evaluation and training) and the module of each episode. Right: competence,
absolute learning progress and p_LP per module, then the learner's losses, Q statistics and replay
composition in tabs. The time panel starts on the `episode` timeline; switch it to
`rollout_frame` and press play to watch the recorded rollouts one after another.
"""

from __future__ import annotations

import rerun.blueprint as rrb

__all__ = ["default_blueprint"]


def default_blueprint() -> rrb.Blueprint:
    """The default blueprint sent with every run's recording (entity paths as in `recorder`)."""
    unit = rrb.ScalarAxis(range=(0.0, 1.0))
    left = rrb.Vertical(
        rrb.Spatial3DView(name="Rollouts", origin="/scene"),
        rrb.Tabs(
            rrb.TimeSeriesView(name="Test success (per epoch)", origin="/test", axis_y=unit),
            rrb.TimeSeriesView(name="Success (evaluation)", origin="/success/eval", axis_y=unit),
            rrb.TimeSeriesView(name="Success (training)", origin="/success/train", axis_y=unit),
            rrb.TimeSeriesView(name="Module per episode", origin="/module"),
        ),
        row_shares=[3.0, 2.0],
    )
    right = rrb.Vertical(
        rrb.TimeSeriesView(name="Competence", origin="/competence", axis_y=unit),
        rrb.TimeSeriesView(name="Absolute learning progress", origin="/lp"),
        rrb.TimeSeriesView(name="p_LP (module selection probability)", origin="/p_lp", axis_y=unit),
        rrb.Tabs(
            rrb.TimeSeriesView(name="Losses", origin="/losses"),
            rrb.TimeSeriesView(name="Q", origin="/q"),
            rrb.TimeSeriesView(name="Replay composition", origin="/replay", axis_y=unit),
        ),
    )
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[1.0, 1.0]),
        rrb.TimePanel(timeline="episode"),
        collapse_panels=False,
    )
