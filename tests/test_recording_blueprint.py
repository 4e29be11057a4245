"""The default layout: whole legends off the start of the run, axes that do not cut 0 and 1.

The viewer itself is not started here; these tests read the `rerun.blueprint` objects and the
blueprint stored in a recording.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import rerun.blueprint as rrb
from rerun.chunk import RrdReader

from curious.runs.folder_layout import RECORDING_FILE
from curious.watching.recording.blueprint import LEGEND_CORNER, UNIT_RANGE, default_blueprint
from curious.watching.recording.recorder import RunRecorder

MODULES = ("reach", "push_cube1", "cube1_above_cube2", "stack", "push_cube3")
WITH_LEGEND = ("/competence", "/test", "/success/eval", "/success/train", "/module")
KEYED_BY_COMPETENCE = ("/lp", "/p_lp", "/replay")
RATES = ("/competence", "/p_lp", "/test", "/success/eval", "/success/train", "/replay")


def _views(container: rrb.Container) -> Iterator[rrb.View]:
    for part in container.contents:
        if isinstance(part, rrb.Container):
            yield from _views(part)
        else:
            yield part


def _by_origin(blueprint: rrb.Blueprint) -> dict[str, rrb.View]:
    return {str(view.origin): view for view in _views(blueprint.root_container)}


def _legend(view: rrb.View) -> tuple[int, bool]:
    legend = view.properties["PlotLegend"]
    (corner,) = legend.corner.as_arrow_array().to_pylist()
    (visible,) = legend.visible.as_arrow_array().to_pylist()
    return corner, visible


def _y_range(view: rrb.View) -> tuple[float, float] | None:
    axis = view.properties.get("ScalarAxis")
    if axis is None:
        return None
    (bounds,) = axis.range.as_arrow_array().to_pylist()
    return tuple(bounds)


def test_module_legends_sit_bottom_right_and_one_per_column_keys_the_rest() -> None:
    views = _by_origin(default_blueprint(7))
    for origin in WITH_LEGEND:
        assert _legend(views[origin]) == (LEGEND_CORNER.value, True), origin
    for origin in KEYED_BY_COMPETENCE:
        assert _legend(views[origin]) == (LEGEND_CORNER.value, False), origin
    assert LEGEND_CORNER == rrb.Corner2D.RightBottom  # away from the start of the run


def test_rates_and_slots_are_drawn_whole_at_their_ends() -> None:
    assert UNIT_RANGE[0] < 0.0 and UNIT_RANGE[1] > 1.0
    views = _by_origin(default_blueprint(7))
    for origin in RATES:
        assert _y_range(views[origin]) == UNIT_RANGE, origin
    assert _y_range(views["/module"]) == (-0.5, 6.5)
    assert _y_range(views["/lp"]) is None  # learning progress keeps the automatic range
    assert _y_range(_by_origin(default_blueprint())["/module"]) is None


def test_side_and_time_panels_start_collapsed_on_the_episode_timeline() -> None:
    blueprint = default_blueprint()
    assert blueprint.blueprint_panel.state == "collapsed"
    assert blueprint.selection_panel.state == "collapsed"
    assert blueprint.time_panel.state == "collapsed"
    assert blueprint.time_panel.timeline == "episode"


def test_the_compacted_recording_keeps_the_runs_module_range(tmp_path: Path) -> None:
    n = len(MODULES)
    with RunRecorder(tmp_path, MODULES) as recorder:
        recorder.log_episodes(
            [0, 1], [0, 1], [0, 1], [1, 0], np.zeros((2, n)), np.zeros((2, n)), np.zeros((2, n))
        )
    reader = RrdReader(tmp_path / RECORDING_FILE)
    origins: dict[str, str] = {}
    ranges: dict[str, list[float]] = {}
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        path = chunk.entity_path
        if "ViewBlueprint:space_origin" in batch.schema.names:
            origins[path] = batch.column("ViewBlueprint:space_origin").to_pylist()[0][0]
        if "ScalarAxis:range" in batch.schema.names:
            ranges[path.removesuffix("/ScalarAxis")] = batch.column("ScalarAxis:range").to_pylist()
    by_origin = {origin: ranges.get(path) for path, origin in origins.items()}
    assert by_origin["/module"] == [[[-0.5, n - 0.5]]]
    assert by_origin["/competence"] == [[list(UNIT_RANGE)]]


def test_module_entity_paths_sort_in_the_papers_order():
    """The viewer lists a legend in entity-path order: T1..T7, then the distractors by cube."""
    from curious.watching.palette import module_entity, module_sort_key

    names = ["stack", "push_cube7", "reach", "push_cube3", "cube1_above_cube2", "push_cube1"]
    names += ["push_cube5", "push_cube4", "push_cube6", "push_cube9", "push_cube8"]
    assert sorted(names, key=module_entity) == sorted(names, key=module_sort_key)
    assert module_entity("reach") == "T1-reach" and module_entity("push_cube9") == "push_cube9"
