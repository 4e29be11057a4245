"""The Gymnasium adapter: a valid goal-conditioned env that other libraries can train on."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from suite.gym_adapter import ModuleGoalEnv


@pytest.fixture(scope="module")
def stack_env():
    env = ModuleGoalEnv("default", "stack", seed=0)
    yield env
    env.close()


# The observation is unbounded by design (positions and velocities, as in gymnasium-robotics'
# Fetch tasks): the checker's advice on infinite Box bounds is expected, not a finding.
@pytest.mark.filterwarnings("ignore:.*A Box observation space (minimum|maximum) value is")
def test_passes_gymnasium_env_checker():
    env = ModuleGoalEnv("default", "push_cube1", seed=0)
    check_env(env, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("module", ["reach", "push_cube1", "cube1_above_cube2", "push_cube3"])
def test_compute_reward_matches_step_reward(module):
    env = ModuleGoalEnv("default", module, seed=1)
    obs, _ = env.reset(seed=2)
    rng = np.random.default_rng(0)
    achieved, desired, rewards = [], [], []
    truncated = False
    while not truncated:
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, 4))
        assert not terminated
        assert info["is_success"] == (reward == 0.0)
        achieved.append(obs["achieved_goal"])
        desired.append(obs["desired_goal"])
        rewards.append(reward)
    batch = env.compute_reward(np.stack(achieved), np.stack(desired), None)
    np.testing.assert_array_equal(batch, np.array(rewards, dtype=np.float32))
    assert len(rewards) == 50
    env.close()


def test_stack_goal_is_padded_to_the_outcome_size(stack_env):
    obs, _ = stack_env.reset(seed=0)
    assert obs["achieved_goal"].shape == obs["desired_goal"].shape == (8,)
    assert stack_env.observation_space.contains(obs)
    # The desired goal is the goal now: cube 2's xy, one cube height above the table.
    cube2 = stack_env.suite_env.task.goal_positions()[stack_env.module_index]
    np.testing.assert_allclose(obs["desired_goal"][:3], cube2, atol=1e-6)
    np.testing.assert_array_equal(obs["desired_goal"][3:], 0.0)
    # A goal relabelled from an outcome where cube 1 was placed and let go, gripper away, is a
    # success; the same place with the gripper still at the cube is not.
    cube1, cube2_xy = np.array([1.3, 0.7, 0.425]), np.array([1.45, 0.85])
    placed = np.r_[cube1, cube1 + np.array([0.0, 0.0, 0.1]), cube2_xy].astype(np.float32)
    held = np.r_[cube1, cube1, cube2_xy].astype(np.float32)
    rewards = stack_env.compute_reward(np.stack([placed, held]), np.stack([placed, placed]), None)
    np.testing.assert_array_equal(rewards, [0.0, -1.0])


def test_reset_takes_a_goal_and_rejects_one_outside_the_goal_space():
    env = ModuleGoalEnv("default", "reach", seed=0)
    obs, _ = env.reset(options={"goal": [0.0, 0.0, -1.0]})
    expected = env.module.goal_slot(np.array([0.0, 0.0, -1.0]))
    np.testing.assert_allclose(obs["desired_goal"], expected)
    with pytest.raises(ValueError, match=r"\[-1, 1\]"):
        env.reset(options={"goal": [0.0, 0.0, 2.0]})
    with pytest.raises(ValueError, match="unknown reset option\\(s\\) 'gaol'"):
        env.reset(options={"gaol": [0.0, 0.0, -1.0]})  # a typo drew a random goal, silently
    obs, _ = env.reset()  # still usable
    assert env.observation_space.contains(obs)
    env.close()


def test_unknown_module_is_a_clear_error():
    with pytest.raises(ValueError, match="unknown module 'pick'"):
        ModuleGoalEnv("default", "pick")


def test_stepping_before_reset_or_after_truncation_asks_for_a_reset():
    """dm_env would start an episode of no chosen module and goal; Gymnasium's answer is
    `ResetNeeded`."""
    from gymnasium.error import ResetNeeded

    env = ModuleGoalEnv("default", "reach", seed=0)
    action = np.zeros(env.action_space.shape, np.float32)
    with pytest.raises(ResetNeeded, match="call reset"):
        env.step(action)
    env.reset(seed=0)
    truncated = False
    steps = 0
    while not truncated:
        *_, truncated, _ = env.step(action)
        steps += 1
    assert steps == 50
    with pytest.raises(ResetNeeded, match="truncated"):
        env.step(action)
    env.reset()
    env.step(action)  # a new episode steps again
    env.close()


def test_stable_baselines3_her_trains_on_a_module():
    sb3 = pytest.importorskip("stable_baselines3")
    from stable_baselines3.her.her_replay_buffer import HerReplayBuffer

    env = ModuleGoalEnv("default", "reach", seed=0)
    model = sb3.DDPG(
        "MultiInputPolicy",
        env,
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
        learning_starts=100,
        batch_size=32,
        policy_kwargs={"net_arch": [32, 32]},
        seed=0,
    )
    model.learn(total_timesteps=150)
    assert model.replay_buffer.size() > 0
    env.close()


@pytest.mark.slow
def test_stable_baselines3_td3_her_learns_reach_through_the_adapter():
    """An independent library learns a module of the suite through `suite.gym_adapter` (about
    5 minutes on 2 cores): Stable-Baselines3 TD3 + HER ('future', 4 goals), 20,000 steps (400
    episodes), then 50 noise-free episodes on new goals."""
    sb3 = pytest.importorskip("stable_baselines3")
    import torch
    from stable_baselines3.her.her_replay_buffer import HerReplayBuffer

    torch.set_num_threads(1)
    env = ModuleGoalEnv("default", "reach", seed=0)
    model = sb3.TD3(
        "MultiInputPolicy",
        env,
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
        learning_starts=1000,
        batch_size=256,
        policy_kwargs={"net_arch": [256, 256, 256]},
        gamma=0.98,
        seed=0,
    )
    model.learn(total_timesteps=20_000)
    test = ModuleGoalEnv("default", "reach", seed=123)
    successes = 0
    for _ in range(50):
        obs, _ = test.reset()
        for _ in range(50):
            action, _ = model.predict(obs, deterministic=True)
            obs, _, _, _, info = test.step(action)
        successes += info["is_success"]
    assert successes >= 40
