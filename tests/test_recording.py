"""The run recording: what the training loop logs comes back out of `recording.rrd`.

Recordings are read back with Rerun's own reader (`rerun.chunk.RrdReader`, through
`curious.watching.recording.reader`), so these tests check the file a user opens, not our buffers.
"""

from __future__ import annotations

import contextlib
import errno
import multiprocessing as mp
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import warnings
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np
import pytest
from rerun.chunk import RrdReader

from curious.commands.view import viewer_command
from curious.runs.folder_layout import RECORDING_FILE
from curious.watching.palette import module_entity, module_label, module_rgb
from curious.watching.recording.cost import fetch_model, measure_logging_cost, synthetic_episodes
from curious.watching.recording.reader import read_component, read_scalars, summarize
from curious.watching.recording.recorder import RunRecorder
from curious.watching.recording.rrd_files import RecordingWriteError
from curious.watching.recording.scene import RolloutCapture, SceneLayout, wxyz_to_xyzw
from curious.watching.recording.settings import RecorderSettings
from curious.watching.recording.working_file import APPLICATION_ID

MODULES = ("reach", "push_cube1", "cube1_above_cube2", "stack", "push_cube3")


def _log_in_batches(recorder: RunRecorder, data: dict[str, np.ndarray], batch: int) -> None:
    n = len(data["episode"])
    for start in range(0, n, batch):
        sl = slice(start, start + batch)
        recorder.log_episodes(
            data["episode"][sl],
            data["module"][sl],
            data["success"][sl],
            data["eval"][sl],
            data["competence"][sl],
            data["lp"][sl],
            data["p_lp"][sl],
            wall_time=data["episode"][sl] * 0.5,
        )


def _forward_fill(times: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """The per-episode value a viewer shows (latest at each episode) from sparse rows."""
    idx = np.searchsorted(times, np.arange(n), side="right") - 1
    assert (idx >= 0).all(), "series must start at the first episode"
    return values[idx]


@pytest.fixture(scope="module")
def fetch() -> mujoco.MjModel:
    return fetch_model()


def _fill_capture(model: mujoco.MjModel, steps: int = 12) -> RolloutCapture:
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    capture = RolloutCapture(model, steps + 1, gripper_body="robot0:gripper_link")
    capture.record(data)
    for _ in range(steps):
        data.mocap_pos[0] += [0.004, -0.003, 0.002]
        mujoco.mj_step(model, data, nstep=20)
        capture.record(data)
    return capture


@pytest.mark.parametrize("on_change", [True, False])
def test_scalars_read_back_equal_what_was_logged(tmp_path: Path, on_change: bool) -> None:
    data = synthetic_episodes(600, len(MODULES), seed=1, window=20, eval_every=10, lp_eps=0.4)
    settings = RecorderSettings(stats_on_change=on_change)
    with RunRecorder(tmp_path, MODULES, settings=settings) as recorder:
        _log_in_batches(recorder, data, batch=37)
    path = tmp_path / RECORDING_FILE
    n = len(data["episode"])
    for m, name in enumerate(MODULES):
        for kind in ("competence", "lp", "p_lp"):
            times, values = read_scalars(path, f"{kind}/{module_entity(name)}")
            np.testing.assert_array_equal(_forward_fill(times, values, n), data[kind][:, m])
            if not on_change:
                np.testing.assert_array_equal(times, data["episode"])
        mine = data["module"] == m
        for split, mask in (("eval", mine & data["eval"]), ("train", mine & ~data["eval"])):
            times, values = read_scalars(path, f"success/{split}/{module_entity(name)}")
            np.testing.assert_array_equal(times, data["episode"][mask])
            np.testing.assert_array_equal(values, data["success"][mask].astype(float))
        times, values = read_scalars(path, f"module/{module_entity(name)}")
        np.testing.assert_array_equal(times, data["episode"][mine])
        assert (values == m).all()
    # the wall-time timeline carries the same rows, in seconds
    seconds, values = read_scalars(
        path, f"competence/{module_entity(MODULES[0])}", timeline="wall_time"
    )
    np.testing.assert_allclose(seconds[0], 0.0)
    assert seconds[-1] == pytest.approx((n - 1) * 0.5)


def test_a_value_that_holds_is_rewritten_so_live_lines_reach_the_present(tmp_path: Path) -> None:
    """Reach's competence sits at 1.0 for most of a run; a viewer watching live (or a recording
    cut short) draws its line only up to the last point written, so that point must be recent."""
    n, every = 3000, 400
    episodes = np.arange(n)
    held = np.ones((n, len(MODULES)))
    held[:10] = 0.0  # one change at episode 10, then nothing
    settings = RecorderSettings(stats_keyframe_every=every, compact_on_close=False)
    with RunRecorder(tmp_path, MODULES, settings=settings) as recorder:
        for start in range(0, n, 64):
            rows = slice(start, start + 64)
            count = len(episodes[rows])
            recorder.log_episodes(
                episodes[rows], np.zeros(count, int), np.ones(count, bool), np.zeros(count, bool),
                held[rows], held[rows] * 0.0, held[rows] / len(MODULES),
            )  # fmt: skip
    times, values = read_scalars(
        tmp_path / RECORDING_FILE, f"competence/{module_entity(MODULES[0])}"
    )
    assert times[0] == 0 and times[1] == 10 and times[-1] == n - 1
    assert np.diff(times).max() <= every + 64  # a point at least once per keyframe interval
    assert len(times) < 3 + n // every + 1  # and only then: the file stays small
    assert (values[1:] == 1.0).all()


def test_changes_only_keeps_the_file_smaller(tmp_path: Path) -> None:
    data = synthetic_episodes(2000, len(MODULES), seed=2, window=30, eval_every=10, lp_eps=0.4)
    sizes = {}
    for on_change in (True, False):
        folder = tmp_path / str(on_change)
        with RunRecorder(
            folder, MODULES, settings=RecorderSettings(stats_on_change=on_change)
        ) as r:
            _log_in_batches(r, data, batch=40)
        sizes[on_change] = (folder / RECORDING_FILE).stat().st_size
    assert sizes[True] < 0.6 * sizes[False]


def test_series_styles_use_the_shared_module_palette(tmp_path: Path) -> None:
    with RunRecorder(tmp_path, MODULES) as recorder:
        recorder.log_episodes(0, 1, True, True, np.zeros((1, 5)), np.zeros((1, 5)), np.ones((1, 5)))
    path = tmp_path / RECORDING_FILE
    for name in MODULES:
        _, names = read_component(
            path, f"competence/{module_entity(name)}", "SeriesLines:names", None
        )
        _, colors = read_component(
            path, f"competence/{module_entity(name)}", "SeriesLines:colors", None
        )
        assert names[-1] == [module_label(name)]
        r, g, b = module_rgb(name)
        assert colors[-1] == [(r << 24) | (g << 16) | (b << 8) | 0xFF]  # Rerun packs RGBA


def test_replay_and_learner_statistics(tmp_path: Path) -> None:
    with RunRecorder(tmp_path, MODULES) as recorder:
        recorder.log_replay([10, 20], [[1, 1, 2, 0, 0], [0, 0, 0, 0, 5]])
        recorder.log_learner([10, 20], losses={"critic": [0.5, 0.25]}, q={"mean": [-3.0, -2.0]})
    path = tmp_path / RECORDING_FILE
    times, shares = read_scalars(path, "replay/T3-cube1_above_cube2")
    np.testing.assert_array_equal(times, [10, 20])
    np.testing.assert_allclose(shares, [0.5, 0.0])
    np.testing.assert_allclose(read_scalars(path, "losses/critic")[1], [0.5, 0.25])
    np.testing.assert_allclose(read_scalars(path, "q/mean")[1], [-3.0, -2.0])


def test_recording_has_ids_timelines_and_blueprint(tmp_path: Path) -> None:
    with RunRecorder(tmp_path, MODULES, recording_id="run-abc") as recorder:
        recorder.log_episodes(
            [0, 1], [0, 1], [0, 1], [1, 0], np.zeros((2, 5)), np.zeros((2, 5)), np.full((2, 5), 0.2)
        )
    path = tmp_path / RECORDING_FILE
    summary = summarize(path)
    assert summary.application_id == APPLICATION_ID
    assert summary.recording_ids == ("run-abc",)
    assert {"episode", "wall_time"} <= summary.timelines
    reader = RrdReader(path)
    assert reader.blueprints(), "the default blueprint travels with the recording"
    blueprint = reader.blueprints()[0]
    assert blueprint.application_id == APPLICATION_ID
    views = {}
    for chunk in reader.stream(store=blueprint):
        batch = chunk.to_record_batch()
        if "ViewBlueprint:space_origin" in batch.schema.names:
            origin = batch.column("ViewBlueprint:space_origin").to_pylist()[0][0]
            views[origin] = batch.column("ViewBlueprint:display_name").to_pylist()[0][0]
    for origin in ("/scene", "/competence", "/lp", "/p_lp", "/success/eval", "/losses"):
        assert origin in views, f"the layout has no view of {origin}"
    assert views["/scene"] == "Rollouts" and views["/lp"] == "Absolute learning progress"


def test_bad_inputs_are_named(tmp_path: Path) -> None:
    with RunRecorder(tmp_path, MODULES) as recorder:
        zeros = np.zeros((2, 5))
        with pytest.raises(ValueError, match=r"competence must have shape \(2, 5\)"):
            recorder.log_episodes([0, 1], [0, 1], [0, 1], [0, 0], np.zeros((2, 4)), zeros, zeros)
        with pytest.raises(ValueError, match="unknown module 'fly'"):
            recorder.log_episodes([0, 1], ["reach", "fly"], [0, 1], [0, 0], zeros, zeros, zeros)
        with pytest.raises(ValueError, match="module index 9 out of range: there are 5 modules"):
            recorder.log_episodes([0, 1], [0, 9], [0, 1], [0, 0], zeros, zeros, zeros)
        with pytest.raises(ValueError, match="success has 3 rows, expected 2"):
            recorder.log_episodes([0, 1], [0, 1], [0, 1, 1], [0, 0], zeros, zeros, zeros)
    with pytest.raises(ValueError, match="duplicates"):
        RunRecorder(tmp_path / "x", ["reach", "reach"])
    with pytest.raises(ValueError, match="rollout_stride"):
        RecorderSettings(rollout_stride=0)


def test_rollout_due_every_k_evaluations(tmp_path: Path) -> None:
    settings = RecorderSettings(rollout_every=3)
    due = [settings.rollout_due(i) for i in range(7)]
    assert due == [True, False, False, True, False, False, True]
    assert not RecorderSettings(rollout_every=0).rollout_due(0)
    with RunRecorder(tmp_path, MODULES, settings=settings) as recorder:
        assert [recorder.rollout_due(i) for i in range(7)] == due


def test_wxyz_to_xyzw() -> None:
    np.testing.assert_array_equal(wxyz_to_xyzw(np.array([1.0, 0, 0, 0])), [0, 0, 0, 1.0])
    q = np.arange(8.0).reshape(2, 4)
    np.testing.assert_array_equal(wxyz_to_xyzw(q), [[1, 2, 3, 0], [5, 6, 7, 4]])
    with pytest.raises(ValueError, match="last axis of size 4"):
        wxyz_to_xyzw(np.zeros(3))


def test_scene_layout_is_fixed_and_poses_only_moving_bodies(fetch: mujoco.MjModel) -> None:
    a, b = SceneLayout.from_model(fetch), SceneLayout.from_model(fetch)
    assert a.body_paths == b.body_paths and a.geom_paths == b.geom_paths
    moving = {a.body_names[i] for i in a.moving_bodies}
    static = {a.body_names[i] for i in a.static_bodies}
    assert {"object0", "robot0:gripper_link", "robot0:shoulder_pan_link"} <= moving
    assert "table0" in static and "table0" not in moving
    # bodies without drawn geometry (camera frames) are not posed at all
    assert "robot0:gripper_camera_link" not in moving | static
    assert all(":" not in p for p in a.body_paths)
    with pytest.raises(ValueError, match="no body named 'hand'"):
        a.body_id("hand")


def test_capture_copies_poses_into_preallocated_rows(fetch: mujoco.MjModel) -> None:
    data = mujoco.MjData(fetch)
    mujoco.mj_forward(fetch, data)
    capture = RolloutCapture(fetch, 2, gripper_body="robot0:gripper_link")
    buffer = capture.xpos
    capture.record(data)
    mujoco.mj_step(fetch, data, nstep=20)
    capture.record(data)
    assert capture.xpos is buffer and capture.n_steps == 2
    np.testing.assert_array_equal(capture.xpos[1], data.xpos[capture.layout.moving_bodies])
    np.testing.assert_array_equal(capture.xquat[1], data.xquat[capture.layout.moving_bodies])
    gripper = fetch.body("robot0:gripper_link").id
    np.testing.assert_array_equal(capture.gripper[1], data.xpos[gripper])
    with pytest.raises(IndexError, match="capture is full"):
        capture.record(data)
    capture.reset()
    assert capture.n_steps == 0


def test_rollout_entities_read_back(tmp_path: Path, fetch: mujoco.MjModel) -> None:
    capture = _fill_capture(fetch, steps=12)
    goal = np.array([1.3, 0.8, 0.43])
    with RunRecorder(tmp_path, MODULES) as recorder:
        recorder.log_rollout(40, "push_cube1", capture, goal=goal, success=True)
        recorder.log_rollout(90, 3, capture, goal=np.tile(goal, (13, 1)), success=False)
    path = tmp_path / RECORDING_FILE
    summary = summarize(path)
    layout = capture.layout
    cube = layout.body_paths[fetch.body("object0").id]
    assert {"scene", "scene/goal", "scene/goal_region", "scene/gripper_path", cube} <= (
        summary.entities
    )
    assert "rollout_frame" in summary.timelines
    # static geometry: every drawn geom, meshes included, with its pose in its body
    for g in layout.drawn_geoms:
        assert layout.geom_paths[g] in summary.static_entities
    arm = layout.geom_paths[fetch.geom("robot0:shoulder_pan_link").id]
    _, vertices = read_component(path, arm, "Mesh3D:vertex_positions", None)
    mesh = fetch.geom_dataid[fetch.geom("robot0:shoulder_pan_link").id]
    assert len(vertices[-1]) == fetch.mesh_vertnum[mesh]
    _, half = read_component(path, cube + "/object0", "Boxes3D:half_sizes", None)
    np.testing.assert_allclose(half[-1][0], fetch.geom_size[fetch.geom("object0").id])
    # per-step poses of the cube: both rollouts, in order, quaternions as xyzw
    j = int(np.flatnonzero(layout.moving_bodies == fetch.body("object0").id)[0])
    frames, trans = read_component(path, cube, "Transform3D:translation", "rollout_frame")
    _, quats = read_component(path, cube, "Transform3D:quaternion", "rollout_frame")
    np.testing.assert_array_equal(frames, np.arange(27))  # frame 0: the rest pose
    np.testing.assert_allclose(np.array(trans)[1:14, 0], capture.xpos[:13, j], rtol=1e-6)
    np.testing.assert_allclose(
        np.array(quats)[1:14, 0], wxyz_to_xyzw(capture.xquat[:13, j]), atol=1e-6
    )
    episodes, _ = read_component(path, cube, "Transform3D:translation", "episode")
    assert sorted(set(episodes.tolist())) == [0, 40, 90]  # 0: the rest pose
    # goal marker coloured and labelled by module, gripper path growing step by step
    _, labels = read_component(path, "scene/goal", "Points3D:labels", "episode")
    assert labels == [
        [f"{module_label('push_cube1')}, episode 40: success"],
        [f"{module_label('stack')}, episode 90: failure"],
    ]
    _, strips = read_component(path, "scene/gripper_path", "LineStrips3D:strips", "rollout_frame")
    assert [len(s[0]) for s in strips[:13]] == list(range(1, 14))
    np.testing.assert_allclose(strips[12][0], capture.gripper[:13], rtol=1e-6)


def test_rollout_stride_keeps_the_last_step(tmp_path: Path, fetch: mujoco.MjModel) -> None:
    capture = _fill_capture(fetch, steps=10)  # 11 rows
    settings = RecorderSettings(rollout_stride=4)
    with RunRecorder(tmp_path, MODULES, settings=settings) as recorder:
        recorder.log_rollout(5, 0, capture, goal=np.zeros(3), success=False)
    cube = capture.layout.body_paths[fetch.body("object0").id]
    frames, trans = read_component(
        tmp_path / RECORDING_FILE, cube, "Transform3D:translation", "rollout_frame"
    )
    j = int(np.flatnonzero(capture.layout.moving_bodies == fetch.body("object0").id)[0])
    np.testing.assert_allclose(np.array(trans)[1:, 0], capture.xpos[[0, 4, 8, 10], j], rtol=1e-6)
    np.testing.assert_array_equal(frames, np.arange(5))


def test_every_moving_body_has_a_pose_from_the_start_of_every_timeline(
    tmp_path: Path, fetch: mujoco.MjModel
) -> None:
    """A geom without its body's pose is drawn in the world frame (the arm in scattered links),
    so the rest pose is on each timeline the recording has, at its start."""
    capture = _fill_capture(fetch, steps=3)
    with RunRecorder(tmp_path, MODULES) as recorder:
        recorder.log_episodes(
            [7], [0], [1], [1], np.zeros((1, 5)), np.zeros((1, 5)), np.zeros((1, 5)), [2.5]
        )
        recorder.log_rollout(7, 0, capture, goal=np.zeros(3), success=True)
    path = tmp_path / RECORDING_FILE
    timelines = summarize(path).timelines
    assert timelines == {"episode", "rollout_frame", "wall_time"}
    for body in capture.layout.moving_bodies:
        for timeline in timelines:
            times, _ = read_component(
                path, capture.layout.body_paths[body], "Transform3D:translation", timeline
            )
            assert times.size and times[0] == 0, (capture.layout.body_names[body], timeline)


PRIMITIVES = """
<mujoco>
  <worldbody>
    <body name="b" pos="0 0 1">
      <freejoint/>
      <geom name="cap" type="capsule" size="0.1 0.3" pos="0.5 0 0"/>
      <geom name="cyl" type="cylinder" size="0.2 0.4"/>
      <geom name="ball" type="sphere" size="0.15" rgba="1 0 0 1"/>
      <geom name="egg" type="ellipsoid" size="0.1 0.2 0.3"/>
      <geom name="ghost" type="box" size="0.1 0.1 0.1" rgba="0 0 0 0"/>
      <geom name="hidden" type="box" size="0.1 0.1 0.1" group="4"/>
    </body>
    <geom name="ground" type="plane" size="0 0 1"/>
  </worldbody>
</mujoco>
"""


def test_primitive_geoms_match_mujoco_sizes(tmp_path: Path) -> None:
    model = mujoco.MjModel.from_xml_string(PRIMITIVES)
    capture = RolloutCapture(model, 1)
    capture.record(mujoco.MjData(model))
    with RunRecorder(tmp_path, MODULES) as recorder:
        recorder.log_rollout(0, 0, capture, goal=np.zeros(3), success=False)
    path = tmp_path / RECORDING_FILE
    entities = summarize(path).entities
    assert "scene/bodies/b/ghost" not in entities  # transparent
    assert "scene/bodies/b/hidden" not in entities  # group 4 is hidden by default
    _, lengths = read_component(path, "scene/bodies/b/cap", "Capsules3D:lengths", None)
    _, offset = read_component(path, "scene/bodies/b/cap", "Capsules3D:translations", None)
    assert lengths[-1] == pytest.approx([0.6]) and offset[-1] == [pytest.approx([0, 0, -0.3])]
    _, cyl = read_component(path, "scene/bodies/b/cyl", "Cylinders3D:lengths", None)
    assert cyl[-1] == pytest.approx([0.8])
    _, ball = read_component(path, "scene/bodies/b/ball", "Ellipsoids3D:half_sizes", None)
    assert ball[-1] == [pytest.approx([0.15, 0.15, 0.15])]
    _, local = read_component(path, "scene/bodies/b/cap", "Transform3D:translation", None)
    assert local[-1] == [pytest.approx([0.5, 0, 0])]
    _, plane = read_component(path, "scene/bodies/world/ground", "Boxes3D:half_sizes", None)
    assert plane[-1][0][:2] == pytest.approx([2.0, 2.0])  # an infinite plane, drawn 4 m wide


def _write_run(folder: str, value: float) -> None:
    with RunRecorder(folder, MODULES) as recorder:
        comp = np.full((1, 5), value)
        recorder.log_episodes(0, 0, True, True, comp, comp, comp)


def test_two_processes_write_two_recordings(tmp_path: Path) -> None:
    ctx = mp.get_context("spawn")
    folders = [str(tmp_path / "a"), str(tmp_path / "b")]
    procs = [
        ctx.Process(target=_write_run, args=(f, v))
        for f, v in zip(folders, (0.25, 0.75), strict=True)
    ]
    for p in procs:
        p.start()
    for p in procs:
        p.join(timeout=60)
        assert p.exitcode == 0
    ids = [summarize(Path(f) / RECORDING_FILE).recording_ids for f in folders]
    assert len(ids[0]) == 1 and len(ids[1]) == 1 and ids[0] != ids[1]
    for folder, value in zip(folders, (0.25, 0.75), strict=True):
        _, values = read_scalars(Path(folder) / RECORDING_FILE, "competence/T1-reach")
        assert values.tolist() == [value]


def test_resume_keeps_the_id_and_drops_episodes_after_the_checkpoint(tmp_path: Path) -> None:
    data = synthetic_episodes(300, len(MODULES), seed=3, window=10, eval_every=10, lp_eps=0.4)
    first = {k: v[:200] for k, v in data.items()}
    with RunRecorder(tmp_path, MODULES, settings=RecorderSettings(stats_on_change=False)) as r:
        _log_in_batches(r, first, batch=50)
        run_id = r.recording_id
    resumed = RunRecorder(
        tmp_path,
        MODULES,
        settings=RecorderSettings(stats_on_change=False),
        resume=True,
        resume_from_episode=150,
    )
    assert resumed.recording_id == run_id
    _log_in_batches(resumed, {k: v[150:] for k, v in data.items()}, batch=50)
    resumed.close()
    path = tmp_path / RECORDING_FILE
    times, values = read_scalars(path, "p_lp/T1-reach")
    np.testing.assert_array_equal(times, np.arange(300))
    np.testing.assert_array_equal(values, data["p_lp"][:, 0])
    assert summarize(path).recording_ids == (run_id,)


def test_spawn_without_display_warns_and_still_writes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    with pytest.warns(RuntimeWarning, match="no display"):
        recorder = RunRecorder(tmp_path, MODULES, spawn=True)
    recorder.log_episodes(0, 0, True, True, np.ones((1, 5)), np.ones((1, 5)), np.ones((1, 5)))
    recorder.close()
    assert read_scalars(tmp_path / RECORDING_FILE, "competence/T1-reach")[1].tolist() == [1.0]


def test_logging_cost_measurement_runs(tmp_path: Path, fetch: mujoco.MjModel) -> None:
    result = measure_logging_cost(tmp_path, n_episodes=200, batch=20, n_rollouts=2, model=fetch)
    assert result["file_bytes"] == (tmp_path / RECORDING_FILE).stat().st_size
    assert result["scalar_us_per_episode"] > 0 and result["rollout_ms"] > 0


def test_bad_rollout_inputs_log_nothing(tmp_path: Path, fetch: mujoco.MjModel) -> None:
    capture = _fill_capture(fetch, steps=3)
    with RunRecorder(tmp_path, MODULES) as recorder:
        with pytest.raises(ValueError, match=r"goal must have shape \(3,\) or \(4, 3\)"):
            recorder.log_rollout(0, 0, capture, goal=np.zeros((3, 3)), success=False)
        with pytest.raises(ValueError, match=r"gripper must have shape \(4, 3\)"):
            recorder.log_rollout(0, 0, capture, goal=np.zeros(3), success=False, gripper=[1, 2])
        capture.reset()
        with pytest.raises(ValueError, match="holds no steps"):
            recorder.log_rollout(0, 0, capture, goal=np.zeros(3), success=False)
    assert "rollout_frame" not in summarize(tmp_path / RECORDING_FILE).timelines


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start_rerun_server(live: Path) -> tuple[subprocess.Popen, str]:
    """A real Rerun server saving what it is sent into `live`, once it listens; and its gRPC
    url."""
    port = _free_port()
    server = subprocess.Popen(
        [*viewer_command(), "--port", str(port), "--save", str(live)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # `rerun` is a Python launcher for the binary: stop both
    )
    deadline = time.monotonic() + 30
    while True:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                break
        if time.monotonic() > deadline:
            _stop_rerun_server(server)
            raise AssertionError("rerun server did not start")
        time.sleep(0.1)
    return server, f"rerun+http://127.0.0.1:{port}/proxy"


def _stop_rerun_server(server: subprocess.Popen, sig: int = signal.SIGTERM) -> None:
    # the viewer saves and exits on SIGTERM; on a loaded machine that can take many seconds
    os.killpg(server.pid, sig)
    try:
        server.wait(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(server.pid, signal.SIGKILL)
        server.wait()


@contextlib.contextmanager
def _rerun_server(live: Path) -> Iterator[str]:
    """`_start_rerun_server`'s url; on leaving, waits for something to arrive, then stops the
    server (it saves as it exits)."""
    server, url = _start_rerun_server(live)
    try:
        yield url
        deadline = time.monotonic() + 10
        while not live.exists() or live.stat().st_size == 0:
            assert time.monotonic() < deadline, "nothing reached the live server"
            time.sleep(0.1)
        time.sleep(0.5)
    finally:
        _stop_rerun_server(server)


def test_a_live_viewer_that_goes_away_is_named_and_the_checkpointed_recording_kept(
    tmp_path: Path,
) -> None:
    """A viewer closed mid-run (or an ssh tunnel dropped) ends the run at the first checkpoint
    whose flush finds it gone, with a message naming the viewer and the way on (`--resume`), not
    the file; the recording stays whole as at the last checkpoint that succeeded, the one the run
    resumes from (a flush or two may still succeed after the viewer died: the severed connection
    shows when the stream next writes to it)."""
    server, url = _start_rerun_server(tmp_path / "live.rrd")
    comp = np.linspace(0, 1, 10)[:, None] * np.ones((1, 5))
    try:
        recorder = RunRecorder(tmp_path / "run", MODULES, connect=url)
        recorder.log_episodes(np.arange(10), 0, 1, 1, comp, comp, comp)
        recorder.checkpoint()
    finally:
        _stop_rerun_server(server, signal.SIGKILL)
    kept = 9  # the last episode of the last checkpoint that succeeded
    stopped = r"the live viewer this recording streams to stopped answering .*--resume"
    with pytest.raises(RecordingWriteError, match=stopped):
        for first in range(10, 510, 10):
            recorder.log_episodes(np.arange(first, first + 10), 0, 1, 1, comp, comp, comp)
            recorder.checkpoint()
            kept = first + 9
            time.sleep(0.1)
    recorder.close_after_error()  # what `curious train` does then
    steps, _ = read_scalars(tmp_path / "run" / RECORDING_FILE, "competence/T1-reach")
    assert steps.max() == kept


def test_a_sink_that_failed_once_is_not_trusted_by_the_end_after_the_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After a failed flush (a viewer gone, a full disk), the recording ends as at the last
    checkpoint even where the sink happens to take the final write: a failed sink may or may
    not drop what it held, so the checkpoint, where `--resume` starts, is what is kept."""
    from curious.watching.recording import working_file

    comp = np.linspace(0, 1, 10)[:, None] * np.ones((1, 5))
    recorder = RunRecorder(tmp_path / "run", MODULES)
    recorder.log_episodes(np.arange(10), 0, 1, 1, comp, comp, comp)
    recorder.checkpoint()
    recorder.log_episodes(np.arange(10, 20), 0, 1, 1, comp, comp, comp)

    def fails_once(*_: object, **__: object) -> None:
        raise RecordingWriteError("the live viewer this recording streams to stopped answering")

    with monkeypatch.context() as patch:
        patch.setattr(working_file, "flush_to_file", fails_once)
        with pytest.raises(RecordingWriteError):
            recorder.checkpoint()
    recorder.close_after_error()  # the sink would take this write: it is not trusted
    steps, _ = read_scalars(tmp_path / "run" / RECORDING_FILE, "competence/T1-reach")
    assert steps.max() == 9


def test_live_stream_gets_the_same_data_as_the_file(tmp_path: Path) -> None:
    live = tmp_path / "live.rrd"
    with _rerun_server(live) as url:
        with RunRecorder(tmp_path / "run", MODULES, connect=url) as recorder:
            assert recorder.live
            comp = np.linspace(0, 1, 10)[:, None] * np.ones((1, 5))
            recorder.log_episodes(np.arange(10), 0, 1, 1, comp, comp, comp)
    expected = read_scalars(tmp_path / "run" / RECORDING_FILE, "competence/T1-reach")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a streamed file has no footer
        got = read_scalars(live, "competence/T1-reach")
    np.testing.assert_array_equal(got[0], expected[0])
    np.testing.assert_array_equal(got[1], expected[1])


def test_train_connect_streams_the_run_to_a_listening_viewer(tmp_path: Path) -> None:
    """`curious train --connect URL`: the run's recording reaches a viewer already listening
    (a headless node's `rerun --serve-web`, a laptop's viewer through an ssh tunnel), and the
    run folder's recording.rrd is written all the same."""
    from curious.cli import main

    live = tmp_path / "live.rrd"
    with _rerun_server(live) as url:
        out = tmp_path / "run"
        assert main(["train", "--preset", "smoke", "--out", str(out), "--no-progress",
                     "--connect", url]) == 0  # fmt: skip
    expected = read_scalars(out / RECORDING_FILE, "competence/T1-reach")
    assert len(expected[0]) > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a streamed file has no footer
        got = read_scalars(live, "competence/T1-reach")
    np.testing.assert_array_equal(got[1], expected[1])


def test_recorded_transforms_put_every_geom_where_mujoco_has_it(
    tmp_path: Path, fetch: mujoco.MjModel
) -> None:
    """Body pose (per step) composed with the geom's local pose (static), as the viewer does,
    gives MuJoCo's own geom_xpos / geom_xmat: quaternion order and hierarchy are right."""
    from scipy.spatial.transform import Rotation

    data = mujoco.MjData(fetch)
    mujoco.mj_forward(fetch, data)
    capture = RolloutCapture(fetch, 9)
    capture.record(data)
    for _ in range(8):
        data.mocap_pos[0] += [0.01, 0.01, -0.005]
        mujoco.mj_step(fetch, data, nstep=20)
        capture.record(data)
    # data.geom_xpos/xmat now come from the same kinematics pass as the last captured row
    with RunRecorder(tmp_path, MODULES) as recorder:
        recorder.log_rollout(3, 0, capture, goal=np.zeros(3), success=False)
    path = tmp_path / RECORDING_FILE
    layout = capture.layout
    checked = 0
    for g in layout.drawn_geoms:
        body = fetch.geom_bodyid[g]
        body_path = layout.body_paths[body]
        timeline = "rollout_frame" if body in layout.moving_bodies else None
        _, t_body = read_component(path, body_path, "Transform3D:translation", timeline)
        _, q_body = read_component(path, body_path, "Transform3D:quaternion", timeline)
        _, t_geom = read_component(path, layout.geom_paths[g], "Transform3D:translation", None)
        _, q_geom = read_component(path, layout.geom_paths[g], "Transform3D:quaternion", None)
        r_body = Rotation.from_quat(q_body[-1][0])  # scipy takes (x, y, z, w), like Rerun
        r_geom = Rotation.from_quat(q_geom[-1][0])
        pos = np.array(t_body[-1][0]) + r_body.apply(t_geom[-1][0])
        np.testing.assert_allclose(pos, data.geom_xpos[g], atol=1e-5)
        np.testing.assert_allclose(
            (r_body * r_geom).as_matrix(), data.geom_xmat[g].reshape(3, 3), atol=1e-5
        )
        checked += 1
    assert checked == len(layout.drawn_geoms) > 20


def test_capture_reads_dm_control_physics(tmp_path: Path) -> None:
    """The suite steps a dm_control Physics: its model pointer and data wrapper plug in as is."""
    from dm_control import mujoco as dm_mujoco

    physics = dm_mujoco.Physics.from_xml_string(PRIMITIVES)
    capture = RolloutCapture(physics.model.ptr, 4, gripper_body="b")
    capture.record(physics.data)
    for _ in range(3):
        physics.step()
        capture.record(physics.data)
    np.testing.assert_array_equal(capture.gripper[3], physics.named.data.xpos["b"])
    assert capture.gripper[3, 2] < capture.gripper[0, 2]  # the free body falls
    with RunRecorder(tmp_path, MODULES) as recorder:
        recorder.log_rollout(0, "reach", capture, goal=np.zeros(3), success=False)
    _, z = read_component(
        tmp_path / RECORDING_FILE, "scene/bodies/b", "Transform3D:translation", "rollout_frame"
    )
    assert z[-1][0] == pytest.approx(capture.xpos[3, 0].tolist())


FULL_DISK_SCRIPT = """
import os
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from curious.watching.recording import rrd_files
import rerun as rr

path = Path(sys.argv[1]) / "recording.rrd"
stream = rr.RecordingStream("full", send_properties=False)
stream.set_sinks(rr.FileSink(str(path)))
for i in range(200):
    stream.set_time("step", sequence=i)
    stream.log("points", rr.Points3D(np.random.default_rng(i).random((500, 3))))
try:  # short waits: a flush on a dead writer either raises at once or waits them out
    rrd_files.end_file(stream, path, timeout=5)
except OSError as exc:
    print(f"curious train: error: {exc}", file=sys.stderr)
    rrd_files.disconnect(stream, timeout=2)  # as the recorder gives up a recording it cannot write
sys.stderr.flush()
os._exit(0)  # a stream whose writer died may wait for it at the interpreter's exit
"""


def test_a_full_disk_under_the_recording_is_reported_by_curious_alone(tmp_path):
    """Rerun's file writer logs its failure on a full disk in its own terms (`ERROR
    re_log_encoding::rrd::file_sink`), then its stream; curious reports it in one line naming
    the file (`RecordingWriteError`), and Rerun's lines are filtered out
    (`curious.watching.recording.RERUN_LOG_FILTER`). A real full disk: a 64 kB tmpfs, mounted in
    a mount namespace of this test's own."""
    script, disk = tmp_path / "full.py", tmp_path / "disk"
    script.write_text(FULL_DISK_SCRIPT)
    disk.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "RUST_LOG"}
    mount = f"mount -t tmpfs -o size=64k tmpfs {disk} || exit 99"
    command = f"{mount}; exec {sys.executable} {script} {disk}"
    try:
        done = subprocess.run(
            ["unshare", "--mount", "--map-root-user", "sh", "-c", command],
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
    except FileNotFoundError:
        pytest.skip("no unshare here")
    if done.returncode == 99 or "unshare:" in done.stderr:
        pytest.skip(f"no tmpfs can be mounted here: {done.stderr.strip()}")
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr[-2000:]
    assert lines[0].startswith("curious train: error: [Errno 28] No space left on device")
    assert f"{disk}/recording.rrd" in lines[0]


class _DeadWriter:
    """A stream whose file writer died: its flush waits out the time it is given, then raises
    (what Rerun's does on a full disk, some of the time), and its disconnect never returns."""

    def __init__(self) -> None:
        self.flushes: list[float] = []

    def flush(self, *, timeout_sec: float) -> None:
        self.flushes.append(timeout_sec)
        time.sleep(timeout_sec)
        raise RuntimeError("flush timed out")

    def disconnect(self) -> None:
        threading.Event().wait()


@pytest.mark.parametrize("disk_full", [True, False])
def test_a_flush_on_a_dead_writer_ends_once_the_disk_is_seen_full(tmp_path, monkeypatch, disk_full):
    """The flush at a checkpoint gives up on a writer that died on a full disk within one
    `FLUSH_POLL_SECONDS` step, not after its whole timeout (five minutes); on a disk with room,
    the same stalled flush is waited for to the end of its timeout."""
    from curious.watching.recording import rrd_files

    monkeypatch.setattr(rrd_files, "FLUSH_POLL_SECONDS", 0.2)
    monkeypatch.setattr(rrd_files, "has_room_for", lambda path, size: not disk_full)
    path = tmp_path / "recording.rrd"
    path.write_bytes(b"chunks")
    stream = _DeadWriter()
    tic = time.monotonic()
    with pytest.raises(rrd_files.RecordingWriteError) as caught:
        rrd_files.flush_to_file(stream, path, timeout=1.0)
    waited = time.monotonic() - tic
    if disk_full:
        assert len(stream.flushes) == 1 and waited < 0.6
        assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(path)
    else:
        assert len(stream.flushes) >= 4 and waited >= 0.95
        assert "the recording could not be written to" in str(caught.value)


def test_a_disconnect_given_up_takes_rerun_off_the_interpreters_exit(monkeypatch):
    """Rerun's shutdown at exit waits for every sink: after a disconnect that never returned,
    it would hold the process forever, so it is unregistered."""
    from curious.watching.recording import rrd_files

    unregistered = []
    monkeypatch.setattr(rrd_files.rr, "unregister_shutdown", lambda: unregistered.append(1))
    assert rrd_files.disconnect(_DeadWriter(), timeout=0.1) is False
    assert unregistered == [1]


def test_a_run_whose_disk_fills_ends_with_one_line(tmp_path):
    """`curious train` recording onto a 1 MiB disk (a tmpfs in a mount namespace of its own):
    one line naming the file that could not be written, exit status 2, and the process ends
    (Rerun's writer dies with the disk, and neither its flush nor its shutdown at exit may
    wait on it)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    train = [sys.executable, "-m", "curious.cli", "train", "--preset", "smoke"]
    train += ["--set", "total_episodes=36", "--rollout-every", "1", "--no-progress"]
    command = f"mount -t tmpfs -o size=1m tmpfs {disk} || exit 99; exec {' '.join(train)} --out "
    env = {**os.environ, "MUJOCO_GL": "disable", "OMP_NUM_THREADS": "1"}
    try:
        done = subprocess.run(
            ["unshare", "--mount", "--map-root-user", "sh", "-c", f"{command}{disk / 'run'}"],
            env=env, capture_output=True, text=True, timeout=240,
        )  # fmt: skip
    except FileNotFoundError:
        pytest.skip("no unshare here")
    if done.returncode == 99 or "unshare:" in done.stderr:
        pytest.skip(f"no tmpfs can be mounted here: {done.stderr.strip()}")
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr[-2000:]
    assert lines[0].startswith("curious train: error: No space left on device"), lines[0]
    assert f"{disk / 'run'}/" in lines[0]
