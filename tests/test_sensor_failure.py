"""The sensory-failure schedule (`curious.runs.sensor_failure.FailureSchedule`) on its own: when the
failure starts, which episodes run with it, and that a resumed run keeps its onset."""

from __future__ import annotations

import numpy as np
import pytest
from toy_env import ToyGoalEnv

from curious.agent.learning_progress import CompetenceTracker
from curious.config import ConfigError
from curious.envs.batch import LocalEnvs
from curious.presets import resolve
from curious.runs.sensor_failure import FailureSchedule
from curious.runs.trainer import Trainer

SMALL = dict(total_episodes=40, n_workers=2, episodes_per_worker=2, progress=False)


class FailingToyEnv(ToyGoalEnv):
    """The toy env with a sensory failure that perturbs its `dial` module (only a flag here)."""

    sensor_failure_module = "dial"

    def __init__(self, seed: int = 0) -> None:
        super().__init__(seed)
        self.failing = False

    def set_sensor_failure(self, on: bool) -> None:
        self.failing = on


def copies(n: int = 2, on: bool = False) -> LocalEnvs:
    envs = [FailingToyEnv(seed=i) for i in range(n)]
    for env in envs:
        env.failing = on
    return LocalEnvs(envs)


def schedule(envs: LocalEnvs, **changes: object) -> FailureSchedule:
    config = resolve("smoke", "curious", 0, {**SMALL, **changes})
    return FailureSchedule(config, envs.spec, envs.reference, (envs,))


def test_a_failure_at_an_episode_runs_every_episode_from_it_on():
    envs = copies(on=True)
    failure = schedule(envs, sensor_failure_episode=5)
    assert not any(env.failing for env in envs.envs)  # switched off until it starts
    assert failure.start == 5 and failure.module == envs.spec.module_index("dial")
    np.testing.assert_array_equal(failure.apply(envs, np.array([3, 4])), [False, False])
    assert [env.failing for env in envs.envs] == [False, False]
    np.testing.assert_array_equal(failure.apply(envs, np.array([4, 5])), [False, True])
    assert [env.failing for env in envs.envs] == [False, True]  # a round straddling the onset
    failure.start_if_due(0, CompetenceTracker(3, 4, "absolute"))  # a fixed episode never moves
    assert failure.start == 5


def test_a_failure_on_competence_waits_for_a_full_window_at_the_threshold():
    envs = copies()
    failure = schedule(envs, sensor_failure_competence=0.75, lp_window=4)
    dial = failure.module
    tracker = CompetenceTracker(envs.spec.n_modules, 4, "absolute")
    for _ in range(3):  # competence 1.0 over less than a window: not learned yet
        tracker.add(dial, True)
    failure.start_if_due(10, tracker)
    assert failure.start is None and not failure.on(np.arange(100)).any()
    tracker.add(dial, False)  # a full window at 0.75
    failure.start_if_due(12, tracker)
    assert failure.start == 12
    failure.start_if_due(20, tracker)  # the first onset stays
    assert failure.start == 12
    np.testing.assert_array_equal(failure.on(np.array([11, 12, 13])), [False, True, True])

    below = schedule(envs, sensor_failure_competence=0.75, lp_window=4)
    tracker = CompetenceTracker(envs.spec.n_modules, 4, "absolute")
    for success in (True, True, False, False):  # a full window at 0.5
        tracker.add(dial, success)
    below.start_if_due(10, tracker)
    assert below.start is None


def test_an_env_without_the_failure_is_refused():
    from toy_env import make_toy_envs

    envs = LocalEnvs(make_toy_envs(0, 2))
    with pytest.raises(ConfigError, match="set_sensor_failure"):
        schedule(envs, sensor_failure_episode=5)
    assert schedule(envs).start is None  # a run without the failure needs none


def test_the_onset_survives_a_checkpoint_and_the_resumed_run_keeps_the_failure(tmp_path):
    config = resolve("smoke", "curious", 0, {**SMALL, "sensor_failure_competence": 0.75})
    trainer = Trainer(config, copies())
    try:
        assert not trainer.cycle().rows["sensor_failure"].any()
        for _ in range(config.lp_window):
            trainer.tracker.add(trainer.failure.module, True)
        started_at = trainer.episodes
        assert trainer.cycle().rows["sensor_failure"].all()
        assert trainer.failure.start == started_at
        state, _ = trainer.state_dict()
        assert state["failure_start"] == started_at  # the key checkpoints have always had
        path = trainer.save_checkpoint(tmp_path / "checkpoints")
    finally:
        trainer.close()
    again = Trainer(config, copies())
    try:
        again.load_checkpoint(path)
        assert again.failure.start == started_at
        assert again.cycle().rows["sensor_failure"].all()
        assert all(env.failing for env in again.envs.envs)
    finally:
        again.close()
