"""Replay: HER 'future' goals, task substitution by p_LP, recomputed rewards, storage."""

import numpy as np
import pytest
from scipy import stats
from toy_env import ToyGoalEnv

from curious.agent.conditions import MUVFA
from curious.agent.goals import HolisticGoals
from curious.agent.replay import GOAL_OWN, EpisodeReplay

SPEC = ToyGoalEnv.spec
T = SPEC.episode_length


def rollouts(n, modules, seed=0, dial_still=()):
    """n random-action episodes, with per-step success; `dial_still` episodes leave the dial."""
    env = ToyGoalEnv(seed)
    rng = np.random.default_rng(seed)
    states = np.zeros((n, T + 1, SPEC.state_dim), np.float32)
    achieved = np.zeros((n, T + 1, SPEC.achieved_dim), np.float32)
    actions = rng.uniform(-1, 1, (n, T, SPEC.action_dim)).astype(np.float32)
    actions[list(dial_still), :, 3] = 0.0
    success = np.zeros((n, T + 1, SPEC.n_modules), bool)
    goals = np.zeros((n, SPEC.n_modules, SPEC.goal_dim), np.float32)
    for i in range(n):
        g = rng.uniform(-1, 1, 3)
        obs = env.reset(modules[i], g)
        goals[i, modules[i]] = env.goal_slot(modules[i], g)
        states[i, 0], achieved[i, 0] = obs
        for t in range(T):
            obs, success[i, t + 1] = env.step(actions[i, t])
            states[i, t + 1], achieved[i, t + 1] = obs
    return states, achieved, actions, np.asarray(modules), goals, success


def filled_replay(n=60, holistic=False, seed=0, **kwargs):
    modules = np.random.default_rng(seed).integers(3, size=n)
    states, achieved, actions, modules, goals, success = rollouts(n, modules, seed)
    if holistic:
        env = ToyGoalEnv(seed)
        raw = np.random.default_rng(seed + 1).uniform(-1, 1, (n, 3, 3))
        goals = np.stack([env.goal_slot(k, raw[:, k]) for k in range(3)], axis=1)
    replay = EpisodeReplay(SPEC, capacity=200, **kwargs)
    replay.store(states, achieved, actions, modules, goals)
    return replay, success


def test_her_goals_come_only_from_later_steps_of_the_same_episode():
    replay, _ = filled_replay()
    rng = np.random.default_rng(1)
    batch = replay.sample(4000, rng, ToyGoalEnv(), np.full(3, 1 / 3), her_p=1.0)
    assert np.all(batch.goal_step > batch.step) and np.all(batch.goal_step <= T)
    assert set(np.unique(batch.goal_step - batch.step)) == set(range(1, T + 1))
    cols = SPEC.hindsight_columns()
    for i in range(len(batch.step)):
        m, e = batch.module[i], batch.episode[i]
        outcomes = replay.achieved[e][:, cols[m]]  # (T+1, 3) this episode's outcomes
        matches = np.flatnonzero(np.all(outcomes == batch.goal.slots[i, m], axis=1))
        assert matches.size and matches.max() > batch.step[i]
        assert np.all(batch.goal.slots[i, np.arange(3) != m] == 0)
        assert batch.goal.mask[i, m] == 1 and batch.goal.mask[i].sum() == 1
    # transitions are the stored ones
    np.testing.assert_array_equal(batch.state, replay.states[batch.episode, batch.step])
    np.testing.assert_array_equal(batch.next_state, replay.states[batch.episode, batch.step + 1])
    np.testing.assert_array_equal(batch.action, replay.actions[batch.episode, batch.step])


@pytest.mark.parametrize("her_p", [0.8, 0.3])
def test_her_probability_is_respected(her_p):
    replay, _ = filled_replay()
    batch = replay.sample(20000, np.random.default_rng(2), ToyGoalEnv(), np.full(3, 1 / 3), her_p)
    her = batch.goal_step >= 0
    assert abs(her.mean() - her_p) < 0.015


@pytest.mark.parametrize("probs", [[0.6, 0.3, 0.1], [0.1333, 0.7334, 0.1333], [0, 0, 1]])
def test_substituted_modules_follow_the_given_probabilities(probs):
    replay, _ = filled_replay()
    probs = np.array(probs)
    batch = replay.sample(30000, np.random.default_rng(3), ToyGoalEnv(), probs, her_p=1.0)
    counts = np.bincount(batch.module, minlength=3)
    used = probs > 0
    assert np.all(counts[~used] == 0)
    if used.sum() > 1:
        result = stats.chisquare(counts[used], probs[used] / probs[used].sum() * counts.sum())
        assert result.pvalue > 1e-3
    np.testing.assert_array_equal(batch.goal.task.argmax(1), batch.module)


def test_recomputed_rewards_equal_the_envs():
    replay, _ = filled_replay()
    env = ToyGoalEnv()
    batch = replay.sample(3000, np.random.default_rng(4), env, np.full(3, 1 / 3), her_p=0.8)
    nxt = replay.achieved[batch.episode, batch.step + 1]
    expected = [env.reward(m, nxt[i], batch.goal.slots[i, m]) for i, m in enumerate(batch.module)]
    np.testing.assert_array_equal(batch.reward, expected)
    # hindsight goals reached at the very next step give reward 0
    at_next = batch.goal_step == batch.step + 1
    assert at_next.any() and np.all(batch.reward[at_next] == 0)
    assert set(np.unique(batch.reward)) == {-1.0, 0.0}


def test_own_goals_reproduce_the_rewards_seen_in_the_episode():
    modules = np.zeros(30, np.int64)  # every episode practises `reach`
    states, achieved, actions, modules, goals, success = rollouts(30, modules, seed=5)
    replay = EpisodeReplay(SPEC, capacity=50)
    replay.store(states, achieved, actions, modules, goals)
    batch = replay.sample(2000, np.random.default_rng(6), ToyGoalEnv(), [1, 0, 0], her_p=0.0)
    assert np.all(batch.goal_step == GOAL_OWN)
    seen = np.where(success[batch.episode, batch.step + 1, 0], 0.0, -1.0)
    np.testing.assert_array_equal(batch.reward, seen)


@pytest.mark.parametrize("probs", [[1 / 3, 1 / 3, 1 / 3], [0, 1, 0], [0.1, 0.1, 0.8]])
def test_transitions_not_relabelled_keep_their_episodes_module_and_goal(probs):
    """The authors' sampler (flowersteam/curious, baselines/her/her.py) substitutes a task and a
    future goal only at the HER indices (her_p = 0.8); the other ~20 % of every minibatch keep
    the episode's practised task and its own goal, whatever the replay probabilities."""
    replay, _ = filled_replay()
    batch = replay.sample(20000, np.random.default_rng(8), ToyGoalEnv(), probs, her_p=0.8)
    own = batch.goal_step == GOAL_OWN
    assert abs(own.mean() - 0.2) < 0.015
    practised = replay.modules[batch.episode[own]]
    np.testing.assert_array_equal(batch.module[own], practised)
    np.testing.assert_array_equal(
        batch.goal.slots[own, practised], replay.goals[batch.episode[own], practised]
    )
    np.testing.assert_array_equal(batch.goal.task[own].argmax(1), practised)
    # a real pair is one the episode was run with: its goal is the one the module was given
    assert np.all(np.abs(batch.goal.slots[own, practised]).sum(1) > 0)


def test_modules_replay_only_episodes_where_their_outcome_moved():
    modules = np.zeros(20, np.int64)
    still = range(0, 20, 2)
    states, achieved, actions, modules, goals, _ = rollouts(20, modules, 9, dial_still=still)
    replay = EpisodeReplay(SPEC, capacity=50, active_only=True)
    replay.store(states, achieved, actions, modules, goals)
    np.testing.assert_array_equal(replay.moved[:20, 1], np.arange(20) % 2 == 1)
    batch = replay.sample(2000, np.random.default_rng(10), ToyGoalEnv(), [0.5, 0.5, 0], 0.8)
    assert np.all(batch.episode[batch.module == 1] % 2 == 1)
    assert set(batch.episode[batch.module == 0] % 2) == {0, 1}
    everything = EpisodeReplay(SPEC, capacity=50, active_only=False)
    everything.store(states, achieved, actions, modules, goals)
    batch = everything.sample(2000, np.random.default_rng(10), ToyGoalEnv(), [0, 1, 0], 0.8)
    assert set(batch.episode % 2) == {0, 1}


def test_a_module_with_nothing_to_replay_gets_no_share_of_the_minibatch():
    """flowersteam/curious ddpg.py (`sample_batch`): the proportions cover only the task
    buffers holding an episode (`ind_valid_buffers`); a module whose outcome never moved gets
    none of the minibatch, rather than being replayed on episodes where nothing happened to it."""
    modules = np.zeros(20, np.int64)
    states, achieved, actions, modules, goals, _ = rollouts(20, modules, 9, dial_still=range(20))
    replay = EpisodeReplay(SPEC, capacity=50, active_only=True)
    replay.store(states, achieved, actions, modules, goals)
    np.testing.assert_array_equal(replay.replayable(), [True, False, True])
    probs = MUVFA(SPEC, 0.4, "released", 10).replay_probs(None, 0, replay.replayable())
    batch = replay.sample(3000, np.random.default_rng(3), ToyGoalEnv(), probs, her_p=1.0)
    assert not np.any(batch.module == 1)
    assert np.bincount(batch.module, minlength=3)[[0, 2]].min() > 1300
    everything = EpisodeReplay(SPEC, capacity=50, active_only=False)
    assert not everything.replayable().any()
    everything.store(states, achieved, actions, modules, goals)
    assert everything.replayable().all()


def test_holistic_reward_is_one_distance_over_every_goal_coordinate():
    """gym_flowers multi_task_fetch_arm_v0.py, `compute_reward` in its flat branch (the flat
    agent's reward through flowersteam/curious her.py): 0 only where the Euclidean distance
    between the whole outcome and the whole goal is within the success distance."""
    replay, _ = filled_replay(holistic=True)
    env = ToyGoalEnv()
    batch = replay.sample_holistic(HolisticGoals(SPEC), 3000, np.random.default_rng(11), env, 0.8)
    assert np.all(batch.goal.mask == 1) and np.all(batch.goal.task == 0)
    assert np.all(batch.module == -1)
    nxt = replay.achieved[batch.episode, batch.step + 1]
    cols = SPEC.hindsight_columns()
    joint = np.linalg.norm((nxt[:, cols] - batch.goal.slots).reshape(len(nxt), -1), axis=1)
    np.testing.assert_array_equal(batch.reward == 0, joint <= SPEC.success_distance)
    # every module within its own distance is not enough (the rule this replaced)
    each = np.all([env.reward(k, nxt, batch.goal.slots[:, k]) == 0 for k in range(3)], axis=0)
    assert np.any(each & (batch.reward == -1))
    her = batch.goal_step >= 0
    future = replay.achieved[batch.episode[her], batch.goal_step[her]][:, cols]
    np.testing.assert_array_equal(batch.goal.slots[her], future)
    np.testing.assert_array_equal(batch.goal.slots[~her], replay.goals[batch.episode[~her]])
    assert np.all(batch.reward[batch.goal_step == batch.step + 1] == 0)


def test_storage_is_first_in_first_out_and_round_trips():
    replay = EpisodeReplay(SPEC, capacity=25)
    data = rollouts(40, np.arange(40) % 3, seed=12)
    replay.store(*(a[:20] for a in data[:5]))
    replay.store(*(a[20:] for a in data[:5]))
    assert replay.size == 25 and replay.ptr == 15
    np.testing.assert_array_equal(replay.states[:15], data[0][25:40])  # overwritten oldest
    np.testing.assert_array_equal(replay.states[15:25], data[0][15:25])
    copy = EpisodeReplay(SPEC, capacity=25)
    copy.load_state_dict(replay.state_dict())
    np.testing.assert_array_equal(copy.states, data[0][15:40])  # loaded oldest first
    more = rollouts(5, np.arange(5) % 3, seed=13)
    replay.store(*more[:5])
    copy.store(*more[:5])
    for key in ("states", "achieved", "actions", "modules", "goals", "moved"):  # same evictions
        mine, theirs = getattr(replay, key), getattr(copy, key)
        order_mine = np.roll(mine, -replay.ptr, axis=0)
        np.testing.assert_array_equal(order_mine, np.roll(theirs, -copy.ptr, axis=0))


def test_a_resumed_run_with_more_episodes_keeps_its_replay_and_grows_it():
    replay = EpisodeReplay(SPEC, capacity=20)
    data = rollouts(26, np.arange(26) % 3, seed=14)
    replay.store(*(a[:20] for a in data[:5]))
    bigger = EpisodeReplay(SPEC, capacity=40)
    bigger.load_state_dict(replay.state_dict())
    bigger.store(*(a[20:] for a in data[:5]))
    assert bigger.size == 26
    np.testing.assert_array_equal(bigger.states[:26], data[0])


def test_sampling_errors_are_clear():
    replay = EpisodeReplay(SPEC, capacity=5)
    with pytest.raises(RuntimeError, match="empty"):
        replay.sample(8, np.random.default_rng(0), ToyGoalEnv(), np.full(3, 1 / 3), her_p=0.8)
    filled, _ = filled_replay()
    with pytest.raises(ValueError, match="module_probs"):
        filled.sample(8, np.random.default_rng(0), ToyGoalEnv(), None, her_p=0.8)


@pytest.fixture(scope="module")
def suite_env():
    from curious.envs.goal_env import SuiteEnv

    return SuiteEnv("default", seed=0)


def suite_outcomes(env, mover):
    """(T+1, achieved) outcomes of the default variant written from positions: the gripper still,
    cube `mover` (0 or 1) sliding 2 mm a step in x, the other cubes still."""
    T = env.spec.episode_length
    gripper = np.tile([1.34, 0.75, 0.6], (T + 1, 1))
    cubes = np.tile(
        np.c_[[[1.25, 0.7], [1.45, 0.8], [2.0, 0.65], [1.9, 0.8], [2.0, 0.9]], np.full(5, 0.425)],
        (T + 1, 1, 1),
    )
    cubes[:, mover, 0] += 0.002 * np.arange(T + 1)
    modules = env.dm_env.task.modules
    return np.concatenate([m.achieved(gripper, cubes) for m in modules], -1).astype(np.float32)


def test_pools_of_modules_above_cube2_hold_episodes_where_cube1_moved(suite_env):
    """flowersteam/curious ddpg.py `store_episode`: an episode enters the buffer of task j when
    `change[-1, tasks_ag_id[j][:3]]`, i.e. where cube 1's world position moved for T2, T3 and
    T4 alike (gym_flowers multi_task_fetch_arm_v0.py `tasks_obs_id`): an episode where only
    cube 2 moved is in none of them."""
    spec = suite_env.spec
    T = spec.episode_length
    achieved = np.stack([suite_outcomes(suite_env, 1), suite_outcomes(suite_env, 0)])
    replay = EpisodeReplay(spec, capacity=4)
    replay.store(
        np.zeros((2, T + 1, spec.state_dim), np.float32),
        achieved,
        np.zeros((2, T, spec.action_dim), np.float32),
        np.array([2, 2]),
        np.zeros((2, spec.n_modules, 3), np.float32),
    )
    names = spec.module_names
    cube1_modules = [names.index(n) for n in ("push_cube1", "cube1_above_cube2", "stack")]
    assert not replay.moved[0, cube1_modules].any()  # only cube 2 moved
    assert replay.moved[1, cube1_modules].all()  # cube 1 moved
    assert not replay.moved[:2, names.index("reach")].any()


def test_own_goals_above_cube2_follow_it_after_each_step(suite_env):
    """The authors' rollout stores at every step the goal after that step (rollout.py
    `self.g[i] = curr_o_new['desired_goal']`), which for T3 follows cube 2's xy
    (multi_task_fetch_arm_v0.py `_update_goals`); a replayed real goal is that, and its reward
    the env's for it."""
    spec = suite_env.spec
    T = spec.episode_length
    k = spec.module_names.index("cube1_above_cube2")
    achieved = suite_outcomes(suite_env, 1)[None]  # cube 2 slides away
    slot = suite_env.goal_slot(k, np.zeros(3))
    goals = np.zeros((1, spec.n_modules, 3), np.float32)
    goals[0, k] = slot
    replay = EpisodeReplay(spec, capacity=2, active_only=False)
    replay.store(
        np.zeros((1, T + 1, spec.state_dim), np.float32),
        achieved,
        np.zeros((1, T, spec.action_dim), np.float32),
        np.array([k]),
        goals,
    )
    probs = np.eye(spec.n_modules)[k]
    batch = replay.sample(500, np.random.default_rng(0), suite_env, probs, her_p=0.0)
    nxt = achieved[0, batch.step + 1]
    expected = suite_env.goal(k, slot, nxt)
    np.testing.assert_array_equal(batch.goal.slots[:, k], expected)
    cube2_x = 1.45 + 0.002 * (batch.step + 1)
    np.testing.assert_allclose(batch.goal.slots[:, k, 0], cube2_x, atol=1e-5)
    np.testing.assert_array_equal(batch.reward, suite_env.reward(k, nxt, expected))
