"""The agent on the real suite: the adapter, and a smoke run of every condition."""

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from curious.cli import main
from curious.envs import SuiteEnv
from curious.replay import EpisodeReplay


@pytest.fixture(scope="module")
def env():
    return SuiteEnv("default", seed=0)


def test_suite_env_spec(env):
    spec = env.spec
    assert spec.n_modules == 7 and spec.state_dim == 49 and spec.action_dim == 4
    assert spec.achievable == (True, True, True, True, False, False, False)
    assert spec.achieved_dim == 22 and spec.goal_dim == 3 and spec.episode_length == 50
    assert env.goal_slot(0, np.zeros((5, 2, 3))).shape == (5, 2, 3)


def test_recomputed_suite_rewards_match_reported_success(env):
    rng = np.random.default_rng(0)
    for module in range(env.spec.n_modules):
        g = rng.uniform(-1, 1, 3)
        obs = env.reset(module, g)
        achieved = [obs.achieved]
        for _ in range(env.spec.episode_length):
            obs, success = env.step(rng.uniform(-1, 1, 4))
            achieved.append(obs.achieved)
            reward = env.reward(module, obs.achieved, env.goal_slot(module, g))
            assert (reward == 0) == success[module]
        # a hindsight goal (the final outcome) is met at the final step, in batch form
        replay = EpisodeReplay(env.spec, capacity=1)
        cols = env.spec.hindsight_columns()[module]
        final = np.asarray(achieved)[-1]
        assert env.reward(module, final[None], final[cols][None])[0] == 0


def test_env_rng_state_reproduces_an_episode(env):
    state = env.get_rng_state()
    first = env.reset(2, np.array([0.3, -0.2, 0.5]))
    env.set_rng_state(state)
    again = env.reset(2, np.array([0.3, -0.2, 0.5]))
    np.testing.assert_array_equal(first.state, again.state)


@pytest.mark.parametrize("condition", ["curious", "m-uvfa", "mg-te", "her"])
def test_smoke_run_of_every_condition(tmp_path, condition):
    out = tmp_path / condition
    record = [] if condition == "curious" else ["--no-record"]
    args = ["train", "--condition", condition, "--preset", "smoke", "--out", str(out)]
    assert main([*args, "--no-progress", *record]) == 0
    df = pq.read_table(out / "metrics.parquet").to_pandas()
    np.testing.assert_array_equal(df["episode"], np.arange(24))
    info = json.loads((out / "config.json").read_text())
    assert info["modules"][0] == "reach" and info["variant"] == "default"
    assert (out / "recording.rrd").exists() == (condition == "curious")
    # and it resumes: two more episodes
    assert (
        main([*args, "--no-progress", "--no-record", "--resume", "--set", "total_episodes=26"]) == 0
    )
    assert len(pq.read_table(out / "metrics.parquet")) == 26
