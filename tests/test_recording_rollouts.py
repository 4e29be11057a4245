"""3-D rollouts in the recording of a training run on the real suite.

`curious train` records every K-th evaluation episode in 3D; the recording is read back with
Rerun's reader (`curious.watching.recording.reader`), so these tests check the file a user opens.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from curious.cli import main
from curious.presets import resolve
from curious.runs.driver import train
from curious.runs.folder_layout import RECORDING_FILE
from curious.watching.palette import module_entity, module_label
from curious.watching.recording.reader import read_component, summarize
from curious.watching.recording.recorder import RunRecorder
from curious.watching.recording.rollout_capture import RolloutObserver, attach_rollout_recording
from curious.watching.recording.settings import RecorderSettings

os.environ.setdefault("MUJOCO_GL", "disable")

STEPS = 51  # the suite's 50 steps and the state after the reset
GRIPPER_LINK = "scene/bodies/fetch_robot0_gripper_link"


def test_curious_train_records_every_kth_evaluation_in_3d(tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["train", "--preset", "smoke", "--out", str(out), "--no-progress"]
    assert main([*args, "--rollout-every", "2", "--set", "torch_threads=1"]) == 0
    path = out / RECORDING_FILE
    summary = summarize(path)
    cubes = {f"scene/bodies/cube{k}" for k in range(1, 6)}
    scene = {"scene/goal", "scene/goal_region", "scene/gripper_path", GRIPPER_LINK}
    assert scene | cubes <= summary.entities
    assert "rollout_frame" in summary.timelines
    assert any(e.startswith(GRIPPER_LINK + "/") for e in summary.static_entities)

    # smoke: 24 episodes, one evaluation in 5 (episodes 4, 9, 14, 19); every 2nd is recorded
    metrics = pq.read_table(out / "metrics.parquet").to_pandas().set_index("episode")
    recorded = [4, 14]
    episodes, labels = read_component(path, "scene/goal", "Points3D:labels", "episode")
    assert episodes.tolist() == recorded
    for e, label in zip(recorded, labels, strict=True):
        outcome = "success" if metrics.loc[e, "success"] else "failure"
        assert label == [f"{module_label(metrics.loc[e, 'module'])}, episode {e}: {outcome}"]

    # the test rollouts of every epoch (smoke: 8 episodes an epoch, 2 tests), as success rates
    tests = pq.read_table(out / "tests.parquet").to_pandas()
    for name, rows in tests.groupby("module", observed=True):
        episodes, rates = read_component(
            path, f"test/{module_entity(name)}", "Scalars:scalars", "episode"
        )
        expected = rows.groupby("episode")["success"].mean()
        assert episodes.tolist() == expected.index.tolist()
        np.testing.assert_allclose([r[0] for r in rates], expected.to_numpy())

    # every step of both episodes, on a dense frame timeline (frame 0: the rest pose)
    frames, cube = read_component(
        path, "scene/bodies/cube1", "Transform3D:translation", "rollout_frame"
    )
    np.testing.assert_array_equal(frames, np.arange(1 + 2 * STEPS))
    assert np.ptp(np.array([c[0] for c in cube])[1:], axis=0).max() < 1.0  # stays on the table
    _, strips = read_component(path, "scene/gripper_path", "LineStrips3D:strips", "rollout_frame")
    assert [len(s[0]) for s in strips] == list(range(1, STEPS + 1)) * 2
    # the path runs through the gripper: grip site a few cm from the gripper link, step by step
    _, link = read_component(path, GRIPPER_LINK, "Transform3D:translation", "rollout_frame")
    link_xyz = np.array([r[0] for r in link])[1:]
    path_xyz = np.concatenate([np.array(strips[k][0][-1:]) for k in range(len(strips))])
    gap = np.linalg.norm(path_xyz - link_xyz, axis=1)
    assert gap.max() < 0.05
    assert np.linalg.norm(np.diff(link_xyz[:STEPS], axis=0), axis=1).max() > 1e-3  # it moves


class Probe:
    """An observer under the rollout observer: reads the goals and grip site itself."""

    def __init__(self) -> None:
        self.calls: list[str] = []
        self.goals: dict[int, list[np.ndarray]] = {}
        self.grip: dict[int, list[np.ndarray]] = {}
        self._eval: list[tuple[int, int, object]] = []

    def watched(self, episodes, evaluation) -> list[int]:
        return [int(i) for i in np.flatnonzero(evaluation)]

    def begin_round(self, episodes, modules, goals, evaluation, envs) -> None:
        self.calls.append("begin")
        self._eval = [
            (int(episodes[i]), int(modules[i]), envs[i]) for i in np.flatnonzero(evaluation)
        ]

    def after_step(self, t: int) -> None:
        self.calls.append(f"step{t}")
        for episode, module, env in self._eval:
            task, physics = env.dm_env.task, env.dm_env.physics
            self.goals.setdefault(episode, []).append(task.goal_positions()[module].copy())
            self.grip.setdefault(episode, []).append(physics.bind(task.robot.grip_site).xpos.copy())

    def end_round(self, info) -> None:
        self.calls.append("end")


def test_rollout_observer_chains_and_logs_the_suites_goal_and_grip_site(tmp_path: Path) -> None:
    probe = Probe()
    installed: list[RolloutObserver] = []

    def make_recorder(trainer, folder):
        recorder = RunRecorder(
            folder.path, trainer.spec.module_names, settings=RecorderSettings(rollout_every=1)
        )
        trainer.observer = probe
        installed.append(attach_rollout_recording(trainer, recorder))
        return recorder

    config = resolve(
        "smoke", "curious", 0, {"total_episodes": 10, "progress": False, "torch_threads": 1}
    )
    train(config, tmp_path / "run", make_recorder=make_recorder)
    observer = installed[0]
    assert observer.inner is probe and observer.logged == 2  # episodes 4 and 9
    rounds = ["begin", *(f"step{t}" for t in range(STEPS)), "end"]
    assert probe.calls == rounds * 5  # 5 rounds of 2 parallel episodes, each handed on whole

    path = tmp_path / "run" / RECORDING_FILE
    _, goal = read_component(path, "scene/goal", "Points3D:positions", "rollout_frame")
    expected = np.concatenate([probe.goals[4], probe.goals[9]])
    np.testing.assert_allclose(np.array([g[0] for g in goal]), expected, atol=1e-6)
    _, strips = read_component(path, "scene/gripper_path", "LineStrips3D:strips", "rollout_frame")
    np.testing.assert_allclose(strips[STEPS - 1][0], np.array(probe.grip[4]), atol=1e-6)
    np.testing.assert_allclose(strips[-1][0], np.array(probe.grip[9]), atol=1e-6)


def test_rollouts_need_suite_environments() -> None:
    class NotSuite:
        pass

    class Due:
        def rollout_due(self, eval_index: int) -> bool:
            return True

    observer = RolloutObserver(Due(), eval_every=5, episode_length=50)
    with pytest.raises(TypeError, match="not a suite environment"):
        observer.begin_round(
            np.array([4]), np.array([0]), np.zeros((1, 1, 3)), np.array([True]), [NotSuite()]
        )
    with pytest.raises(ValueError, match="eval_every"):
        RolloutObserver(Due(), eval_every=0, episode_length=50)


def test_spawn_viewer_and_rollouts_need_the_recording(tmp_path: Path, capsys) -> None:
    out = str(tmp_path / "run")
    for extra in (["--spawn-viewer"], ["--connect", "rerun+http://127.0.0.1:9876/proxy"],
                  ["--rollout-every", "3"]):  # fmt: skip
        assert main(["train", "--preset", "smoke", "--out", out, "--no-record", *extra]) == 2
        assert "need the recording" in capsys.readouterr().err
    # a url Rerun cannot take is refused before the run starts, with a viewer's url to copy
    assert main(["train", "--preset", "smoke", "--out", out, "--connect", "127.0.0.1:9876"]) == 2
    err = capsys.readouterr().err
    assert "--connect '127.0.0.1:9876' is not a Rerun gRPC url" in err
    assert "rerun+http://HOST:9876/proxy" in err
    # a url where nothing listens is refused too: Rerun's first flush would wait minutes for it
    with socket.socket() as free:
        free.bind(("127.0.0.1", 0))
        url = f"rerun+http://127.0.0.1:{free.getsockname()[1]}/proxy"
    assert main(["train", "--preset", "smoke", "--out", out, "--connect", url]) == 2
    err = capsys.readouterr().err
    assert f"--connect {url}: nothing answers at 127.0.0.1:" in err and "start the viewer" in err
    assert main(["train", "--preset", "smoke", "--out", out, "--rollout-every", "-1"]) == 2
    assert "--rollout-every must be from 0 to 10,000,000,000, got -1" in capsys.readouterr().err
    assert not Path(out).exists()
