"""Environment copies stepped in worker processes: the same episodes as in one process, the same
3-D rollouts in the recording, and a dead worker named in a clear error."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from curious.cli import main
from curious.envs.batch import LocalEnvs, ProcessEnvs
from curious.envs.goal_env import suite_env_fns
from curious.presets import resolve
from curious.runs.driver import _environments
from curious.runs.folder_layout import RECORDING_FILE
from curious.watching.recording.reader import read_component

os.environ.setdefault("MUJOCO_GL", "disable")


def train_smoke(out: Path, processes: int) -> None:
    args = ["train", "--preset", "smoke", "--out", str(out), "--no-progress"]
    args += ["--rollout-every", "1", "--set", f"env_processes={processes}"]
    assert main([*args, "--set", "n_workers=3", "--set", "torch_threads=1"]) == 0


def test_worker_processes_give_the_same_run_as_one_process(tmp_path: Path) -> None:
    train_smoke(tmp_path / "one", 1)
    train_smoke(tmp_path / "two", 2)
    for table in ("metrics.parquet", "tests.parquet"):
        a = pq.read_table(tmp_path / "one" / table).to_pandas().drop(columns="wall_time")
        b = pq.read_table(tmp_path / "two" / table).to_pandas().drop(columns="wall_time")
        assert len(a) and a.equals(b), table
    # the recorded rollouts read shadow copies synced from the workers: the same poses
    entity, component = "scene/bodies/cube1", "Transform3D:translation"
    read = {
        name: read_component(tmp_path / name / RECORDING_FILE, entity, component, "rollout_frame")
        for name in ("one", "two")
    }
    (frames_a, poses_a), (frames_b, poses_b) = read["one"], read["two"]
    assert len(frames_a) > 10
    np.testing.assert_array_equal(frames_a, frames_b)
    np.testing.assert_allclose(np.array(poses_a, float), np.array(poses_b, float), atol=1e-9)


@pytest.mark.parametrize("processes", [1, 2])
def test_the_test_rollouts_copies_step_where_the_training_copies_do(processes: int) -> None:
    """With env_processes > 1 the test copies step in worker processes of their own as well
    (at `paper` size, stepped in the training process, they took a third of an epoch)."""
    config = resolve("smoke", overrides=dict(n_workers=3, env_processes=processes))
    train, tests, condition = _environments(config, None)
    assert condition.name == config.condition  # built once, here
    try:
        kind = ProcessEnvs if processes > 1 else LocalEnvs
        assert isinstance(train, kind) and isinstance(tests, kind)
        assert len(train) == len(tests) == 3 and train is not tests
    finally:
        for copies in (train, tests):
            if isinstance(copies, ProcessEnvs):
                copies.close()


def test_process_copies_step_like_local_ones_and_keep_their_random_streams() -> None:
    fns = suite_env_fns("default", 3, 3)
    local, remote = LocalEnvs([fn() for fn in fns]), ProcessEnvs(fns, processes=2)
    try:
        assert remote.shares == [range(0, 2), range(2, 3)] and len(remote) == 3
        states = remote.get_rng_states()
        modules, goals = np.array([0, 1]), np.array([[0.1, 0.2, 0.3], [-0.5, 0.0, 0.0]])
        actions = np.random.default_rng(0).uniform(-1, 1, (2, 4))
        # two copies of three: the last one is not touched
        np.testing.assert_array_equal(
            local.reset(modules, goals)[0], remote.reset(modules, goals)[0]
        )
        for a, b in zip(local.step(actions), remote.step(actions), strict=True):
            np.testing.assert_array_equal(a, b)
        remote.set_rng_states(states)  # back to the first episode's random draws
        local.set_rng_states(states)
        np.testing.assert_array_equal(
            local.reset(modules, goals)[0], remote.reset(modules, goals)[0]
        )
    finally:
        remote.close()


def test_a_dead_worker_is_a_clear_error_naming_its_copies() -> None:
    remote = ProcessEnvs(suite_env_fns("default", 0, 2), processes=2)
    remote._procs[1].kill()
    remote._procs[1].join()
    with pytest.raises(RuntimeError, match=r"worker 1 \(copies 1\.\.1\) .*--resume"):
        remote.step(np.zeros((2, 4)))
    assert all(not p.is_alive() for p in remote._procs)  # the others were stopped too
