"""Suite copies stepped together in MuJoCo's threads (`ThreadedEnvs`): the same observations and
successes as `LocalEnvs` bit for bit on every variant, prefixes, random streams, errors, and the
threads released at close."""

from __future__ import annotations

import os

import numpy as np
import pytest

import suite
from curious.envs.batch import LocalEnvs
from curious.envs.goal_env import make_suite_envs
from curious.envs.rollout import run_episodes
from curious.envs.threaded import ThreadedEnvs
from tests.toy_env import ToyGoalEnv

os.environ.setdefault("MUJOCO_GL", "disable")


def _native_threads() -> int:
    return len(os.listdir("/proc/self/task"))


def _same(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape
        np.testing.assert_array_equal(x, y)


def _episode(
    local: LocalEnvs, threaded: ThreadedEnvs, n: int, steps: int, rng: np.random.Generator
) -> np.ndarray:
    """Reset the first n copies of both, step the first `n - 1` (or n) copies `steps` times with
    the same actions, compare everything; return the successes seen."""
    spec = local.spec
    modules, goals = rng.integers(0, spec.n_modules, n), rng.uniform(-1, 1, (n, 3))
    _same(local.reset(modules, goals), threaded.reset(modules, goals))
    seen = np.zeros(spec.n_modules, bool)
    for t in range(steps):
        stepped = n if t % 3 else max(1, n - 1)  # now and then fewer copies than were reset
        # beyond [-1, 1] at times: clipped by both
        actions = rng.uniform(-1.3, 1.3, (stepped, spec.action_dim)).astype(np.float32)
        out = local.step(actions)
        _same(out, threaded.step(actions))
        seen |= out[2].any(axis=0)
    return seen


@pytest.mark.parametrize("variant", suite.ALL_VARIANTS)
def test_threaded_copies_step_like_local_ones_bit_for_bit(variant: str) -> None:
    copies = 4
    local = LocalEnvs(make_suite_envs(variant, 11, copies))
    threaded = ThreadedEnvs(make_suite_envs(variant, 11, copies), threads=2)
    rng = np.random.default_rng(5)
    try:
        if local.reference.spec.sensor_failure_modules:
            on = np.array([True, False, True])  # three of four copies told, two switched on
            local.set_sensor_failure(on)
            threaded.set_sensor_failure(on)
        _episode(local, threaded, copies, local.spec.episode_length, rng)
        _episode(local, threaded, 2, 12, rng)  # a prefix, mid-episode resets of the others
        # copies 2 and 3 ended their episode: stepping them is an error, as for LocalEnvs
        with pytest.raises(RuntimeError, match="episode is over"):
            threaded.step(np.zeros((3, 4)))
    finally:
        threaded.close()


def test_the_sensory_failure_switched_mid_episode_reads_from_the_next_step() -> None:
    local = LocalEnvs(make_suite_envs("sensor_failure", 2, 2))
    threaded = ThreadedEnvs(make_suite_envs("sensor_failure", 2, 2), threads=2)
    rng = np.random.default_rng(0)
    try:
        modules, goals = np.array([3, 0]), rng.uniform(-1, 1, (2, 3))
        _same(local.reset(modules, goals), threaded.reset(modules, goals))
        for t in range(6):
            if t == 3:
                for envs in (local, threaded):
                    envs.set_sensor_failure(np.array([False, True]))
            actions = rng.uniform(-1, 1, (2, 4))
            _same(local.step(actions), threaded.step(actions))
    finally:
        threaded.close()


def test_random_states_round_trip_and_give_the_same_episodes_again() -> None:
    threaded = ThreadedEnvs(make_suite_envs("default", 4, 3), threads=2)
    rng = np.random.default_rng(1)
    modules, goals = rng.integers(0, 7, 3), rng.uniform(-1, 1, (3, 3))
    actions = rng.uniform(-1, 1, (10, 3, 4))
    try:
        states = threaded.get_rng_states()
        first = [threaded.reset(modules, goals), *(threaded.step(a) for a in actions)]
        threaded.set_rng_states(states)
        again = [threaded.reset(modules, goals), *(threaded.step(a) for a in actions)]
        for a, b in zip(first, again, strict=True):
            _same(a, b)
        with pytest.raises(ValueError, match="2 random states for 3 copies"):
            threaded.set_rng_states(states[:2])
    finally:
        threaded.close()


def test_watched_copies_carry_the_batch_physics() -> None:
    local = LocalEnvs(make_suite_envs("distractors_4", 8, 3))
    threaded = ThreadedEnvs(make_suite_envs("distractors_4", 8, 3), threads=2)
    watched = threaded.observed([1])
    rng = np.random.default_rng(2)
    try:
        modules, goals = rng.integers(0, 8, 3), rng.uniform(-1, 1, (3, 3))
        local.reset(modules, goals)
        threaded.reset(modules, goals)
        for _ in range(5):
            actions = rng.uniform(-1, 1, (3, 4))
            local.step(actions)
            threaded.step(actions)
        mine, theirs = watched[1].dm_env.physics.data, local.envs[1].dm_env.physics.data
        for field in ("qpos", "qvel", "mocap_pos", "xpos", "xquat", "time"):
            np.testing.assert_array_equal(getattr(mine, field), getattr(theirs, field))
        np.testing.assert_array_equal(  # what the rollout recorder reads of the task
            watched[1].dm_env.task.goal_positions(), local.envs[1].dm_env.task.goal_positions()
        )
    finally:
        threaded.close()


def test_close_releases_the_threads_and_the_batch_cannot_step_after() -> None:
    before = _native_threads()
    threaded = ThreadedEnvs(make_suite_envs("distractors_0", 0, 3), threads=3)
    assert threaded.threads == 3 and _native_threads() == before + 2  # the caller is the third
    threaded.reset(np.array([0, 1, 2]), np.zeros((3, 3)))
    threaded.step(np.zeros((3, 4)))
    threaded.close()
    assert _native_threads() == before
    with pytest.raises(RuntimeError, match="closed"):
        threaded.step(np.zeros((2, 4)))


def test_bad_input_is_a_clear_error() -> None:
    threaded = ThreadedEnvs(make_suite_envs("default", 0, 2), threads=1)
    try:
        with pytest.raises(RuntimeError, match="call reset"):
            threaded.step(np.zeros((2, 4)))
        threaded.reset(np.array([0, 1]), np.zeros((2, 3)))
        for shape in [(2, 3), (4,), (3, 4), (0, 4), (2, 4, 1)]:
            with pytest.raises(ValueError, match=r"actions must have shape \(n, 4\)"):
                threaded.step(np.zeros(shape))
        with pytest.raises(ValueError, match=r"finite; copies \[1\]"):
            threaded.step(np.array([[0.0, 0, 0, 0], [0, np.nan, 0, 0]]))
        with pytest.raises(ValueError, match=r"can reset 1\.\.2 copies"):
            threaded.reset(np.zeros(3, int), np.zeros((3, 3)))
    finally:
        threaded.close()
    with pytest.raises(TypeError, match="not suite environments"):
        ThreadedEnvs([ToyGoalEnv(0), ToyGoalEnv(1)])
    with pytest.raises(ValueError, match="share one EnvSpec"):
        ThreadedEnvs([*make_suite_envs("default", 0, 1), *make_suite_envs("distractors_0", 0, 1)])


def test_a_round_of_episodes_is_the_same_through_either_batch() -> None:
    """`run_episodes`, as the trainer plays a round, on 3 of 4 copies."""

    def act(states: np.ndarray, achieved: np.ndarray, t: int) -> np.ndarray:
        # a deterministic policy of the observation: towards cube 1, closing late
        push = np.clip(10 * states[:, 3:6] - 10 * states[:, 0:3], -1, 1)
        return np.concatenate([push, np.full((len(states), 1), 1.0 - t / 25)], axis=1)

    rounds = []
    for kind in (LocalEnvs, ThreadedEnvs):
        envs = kind(make_suite_envs("default", 9, 4))
        try:
            modules, goals = np.array([1, 2, 3]), np.full((3, 3), 0.2)
            rounds.append(run_episodes(envs, modules, goals, act))
        finally:
            envs.close()
    for field in ("states", "achieved", "actions", "final_success"):
        np.testing.assert_array_equal(getattr(rounds[0], field), getattr(rounds[1], field))
