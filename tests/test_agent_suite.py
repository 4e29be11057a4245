"""The agent on the real suite: the adapter, and a smoke run of every condition."""

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from curious.agent.replay import EpisodeReplay
from curious.cli import main
from curious.envs.batch import LocalEnvs
from curious.envs.goal_env import SuiteEnv, make_suite_envs
from curious.presets import resolve
from curious.runs.trainer import Trainer


@pytest.fixture(scope="module")
def env():
    return SuiteEnv("default", seed=0)


def test_suite_env_spec(env):
    """The success distance is the authors' `distance_threshold` 0.05 (gym_flowers
    envs/robotics/fetch/multi_task_fetch_arm.py, `MultiTaskFetchArmV0`), which the holistic goal
    of `her` is measured against too (multi_task_fetch_arm_v0.py, `compute_reward`)."""
    spec = env.spec
    assert spec.success_distance == 0.05
    assert spec.n_modules == 7 and spec.state_dim == 49 and spec.action_dim == 4
    assert spec.achievable == (True, True, True, True, False, False, False)
    assert spec.achieved_dim == 28 and spec.goal_dim == 3 and spec.episode_length == 50
    assert env.goal_slot(0, np.zeros((5, 2, 3))).shape == (5, 2, 3)


def test_a_module_is_taken_by_name_or_index_and_any_other_is_named(env):
    """`reset("reach", g)` was int()'s error, module 7 a bare IndexError, -1 silently the last
    module and 2.7 module 2; row by row, 9 an IndexError from the suite's evaluator."""
    goal = np.zeros(3)
    reach = env.goal_slot(0, goal)
    np.testing.assert_array_equal(env.goal_slot("reach", goal), reach)
    env.reset("reach", goal)
    for module in (7, -1, 2.7, "pick"):
        with pytest.raises(ValueError, match="module"):
            env.goal_slot(module, goal)
        with pytest.raises(ValueError, match="module"):
            env.reset(module, goal)
    achieved = np.zeros((2, env.spec.achieved_dim), np.float32)
    goals = np.zeros((2, env.spec.goal_dim), np.float32)
    for rows in ([0, 9], [0, -1]):
        with pytest.raises(ValueError, match="out of range"):
            env.row_rewards(np.array(rows), achieved, goals)
    assert env.row_rewards(np.array([0, 6]), achieved, goals).shape == (2,)


@pytest.mark.parametrize("n", [0, -1, 2.0, True])
def test_a_number_of_copies_is_a_count(n):
    """`make_suite_envs("default", 0, -1)` was numpy's "negative dimensions are not allowed"."""
    with pytest.raises(ValueError, match="the number of copies, must be an integer >= 1"):
        make_suite_envs("default", 0, n)


def test_recomputed_suite_rewards_match_reported_success(env):
    spec = env.spec
    n, T = spec.n_modules, spec.episode_length
    rng = np.random.default_rng(0)
    states = np.zeros((n, T + 1, spec.state_dim), np.float32)
    achieved = np.zeros((n, T + 1, spec.achieved_dim), np.float32)
    actions = rng.uniform(-1, 1, (n, T, spec.action_dim)).astype(np.float32)
    goals = np.zeros((n, n, spec.goal_dim), np.float32)
    for module in range(n):
        g = rng.uniform(-1, 1, 3)
        goals[module, module] = env.goal_slot(module, g)
        states[module, 0], achieved[module, 0] = env.reset(module, g)
        for t in range(T):
            obs, success = env.step(actions[module, t])
            states[module, t + 1], achieved[module, t + 1] = obs
            goal = env.goal(module, goals[module, module], obs.achieved)
            reward = env.reward(module, obs.achieved, goal)
            assert (reward == 0) == success[module]
    # the replay's batched rewards equal the suite's reward row by row
    replay = EpisodeReplay(spec, capacity=n)
    replay.store(states, achieved, actions, np.arange(n), goals)
    batch = replay.sample(700, rng, env, np.full(n, 1 / n), her_p=0.8)
    nxt = achieved[batch.episode, batch.step + 1]
    expected = [env.reward(m, nxt[i], batch.goal.slots[i, m]) for i, m in enumerate(batch.module)]
    np.testing.assert_array_equal(batch.reward, np.asarray(expected).reshape(-1))
    assert (batch.reward == 0).any()  # hindsight goals give successes on the real suite


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


def test_sensor_failure_follows_each_episode_index():
    """Each copy runs its episode with the failure exactly when its index has reached the
    configured episode, also when one round straddles it."""
    overrides = {"variant": "sensor_failure", "sensor_failure_episode": 5}
    config = resolve("smoke", "curious", 0, overrides)
    trainer = Trainer(config, LocalEnvs(make_suite_envs("sensor_failure", 0, config.n_workers)))
    seen: list[tuple[int, bool]] = []

    class Watch:
        def watched(self, episodes, evaluation):
            return range(len(episodes))

        def begin_round(self, episodes, modules, goals, evaluation, envs):
            seen.extend(
                (int(e), env.dm_env.task.sensor_failure)
                for e, env in zip(episodes, envs, strict=True)
            )

        def after_step(self, t):
            pass

        def end_round(self, info):
            pass

    trainer.observer = Watch()
    for _ in range(2):  # 8 episodes in rounds of 2: 4-5 straddles episode 5
        trainer.cycle()
    assert seen == [(e, e >= 5) for e in range(8)]


def test_sensor_failure_on_a_variant_without_one_is_refused(tmp_path, capsys):
    args = ["train", "--preset", "smoke", "--out", str(tmp_path / "run"), "--no-progress"]
    assert main([*args, "--set", "sensor_failure_episode=5"]) == 2
    assert "no sensory failure" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
    assert main([*args, "--set", "sensor_failure_episode=-2"]) == 2
    assert "sensor_failure_episode" in capsys.readouterr().err


@pytest.mark.slow
def test_the_quick_preset_learns_reach_on_the_suite(tmp_path):
    """A learning check on the real suite (about 3 minutes on 2 cores): one `quick` run of
    curious (seed 0, 1,200 episodes) learns reach, in its test rollouts and its competence."""
    out = tmp_path / "quick"
    args = ["train", "--preset", "quick", "--out", str(out), "--no-progress", "--no-record"]
    assert main(args) == 0
    metrics = pq.read_table(out / "metrics.parquet").to_pandas()
    assert metrics["competence/reach"].iloc[-1] >= 0.7
    tests = pq.read_table(out / "tests.parquet").to_pandas()
    last = tests[tests["epoch"] >= tests["epoch"].max() - 2]
    assert last.loc[last["module"] == "reach", "success"].mean() >= 0.7


def test_her_places_its_goals_above_cube2_where_cube2_is(env):
    """The flat baseline's goals of cube1_above_cube2 and stack follow cube 2 as every
    condition's do (docs/agent.md, "her's goals of the modules that follow cube 2"): its score
    compares the outcome with the goals placed where cube 2 is at the final step."""
    from curious.agent.conditions import HER
    from curious.envs.rollout import EpisodeData

    spec = env.spec
    her = HER(spec, 0.4, "released", 10)
    space = her.goal_space
    names = spec.module_names
    above, stack = names.index("cube1_above_cube2"), names.index("stack")
    obs = env.reset(above, np.zeros(3))
    start = np.asarray(obs.achieved, np.float32)[None]  # (1, A) at reset
    moved = start.copy()  # cube 2 pushed 0.1 along x
    for k, x2 in ((above, 3), (stack, 6)):
        moved[0, spec.outcome_slices[k].start + x2] += 0.1
    slots = np.stack([env.goal_slot(k, np.zeros((1, 3)))[0] for k in range(spec.n_modules)])[None]
    shift = space.place(env, slots, moved) - space.place(env, slots, start)
    expected = np.zeros_like(shift)
    expected[0, [above, stack], 0] = 0.1
    np.testing.assert_allclose(shift, expected, atol=1e-6)
    # Slots whose placed goals are exactly the moved outcome: met there, not where cube 2 was.
    slots = slots + space.hindsight(moved) - space.place(env, slots, moved)
    assert space.distance(moved, space.place(env, slots, moved))[0] < 1e-5

    def final(achieved):
        return EpisodeData(
            states=np.zeros((1, 2, spec.state_dim), np.float32),
            achieved=np.repeat(achieved[:, None], 2, axis=1),
            actions=np.zeros((1, 1, spec.action_dim), np.float32),
            final_success=np.zeros((1, spec.n_modules), bool),
        )

    modules = np.array([above])
    assert her.success(env, final(moved), modules, slots).tolist() == [True]
    # The same outcome with cube 2 where it started (cube 1 and the gripper unchanged).
    assert her.success(env, final(start), modules, slots).tolist() == [False]
