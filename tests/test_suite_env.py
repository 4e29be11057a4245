"""The environment: determinism, the caller's choice of module and goal, rewards that the
vectorised module functions reproduce, the start state, the distractors, and clear errors on bad
input. (The sensory failure is tested with its variant, in test_suite_variants.py.)"""

from __future__ import annotations

import numpy as np
import pytest
from fresh_process import run_fresh

import suite
from suite import layout


def rollout(env, actions, module=None, goal=None):
    """Observations (stacked per key) and rewards of one episode."""
    env.task.set_next_episode(module=module, goal=goal)
    obs = [env.reset().observation]
    rewards = []
    for a in actions:
        ts = env.step(a)
        obs.append(ts.observation)
        rewards.append(ts.reward)
    return {k: np.stack([o[k] for o in obs]) for k in obs[0]}, np.array(rewards, np.float32)


def test_same_seed_same_trajectory_other_seed_another():
    actions = np.random.default_rng(0).uniform(-1, 1, size=(50, 4))
    runs = []
    for seed in (7, 7, 8):
        env = suite.load("default", seed=seed)
        episodes = [rollout(env, actions)[0] for _ in range(2)]
        runs.append(episodes)
    for first, second in zip(runs[0], runs[1], strict=True):
        for key in first:
            np.testing.assert_array_equal(first[key], second[key])
    assert not np.array_equal(runs[0][0]["state"], runs[2][0]["state"])


def test_caller_chooses_module_and_goal_for_the_next_episode_only():
    env = suite.load("default", seed=0)
    task = env.task
    g = np.array([0.1, -0.3, 0.5])
    task.set_next_episode(module="push_cube1", goal=g)
    ts = env.reset()
    assert task.active_module == 1
    np.testing.assert_array_equal(task.goals[1], g.astype(np.float32))
    expected_slot = task.modules[1].goal_slot(g)
    np.testing.assert_array_equal(ts.observation["goal"][3:6], expected_slot)
    np.testing.assert_array_equal(ts.observation["task"], np.eye(7, dtype=np.float32)[1])

    task.set_next_episode(module=3)
    env.reset()
    assert task.active_module == 3

    # Left to the env: over many resets every module comes up, with goals across [-1, 1]^3.
    seen = set()
    goals = []
    for _ in range(60):
        env.reset()
        seen.add(task.active_module)
        goals.append(task.goals)
    assert seen == set(range(7))
    goals = np.concatenate(goals)
    assert goals.min() >= -1 and goals.max() <= 1 and goals.min() < -0.9 and goals.max() > 0.9


@pytest.mark.parametrize("variant", ["default", "distractors_7"])
def test_vectorised_reward_equals_step_reward_on_recorded_trajectories(variant):
    """What the agent does with replayed transitions: recompute each module's reward from the
    recorded outcomes and the goal its slot stands for at each step (`TaskModule.goal`, which
    follows cube 2 for cube1_above_cube2 and stack), in one batched call, and get the env's
    numbers; the `goal` observation is that goal."""
    env = suite.load(variant, seed=3)
    task = env.task
    rng = np.random.default_rng(1)
    seen_rewards = set()
    for i, module in enumerate(task.modules):
        # Aim the gripper at the goal so that the reward changes within the episode.
        env.task.set_next_episode(module=i)
        obs = [env.reset().observation]
        rewards = []
        slot = task.goal_slots[i]
        for t in range(50):
            grip = obs[-1]["state"][:3]
            aim = task.goal_positions()[i] if module.name != "stack" else grip
            action = np.r_[np.clip((aim - grip) / 0.05, -1, 1), 1.0]
            action += rng.normal(0, 0.3 if t % 10 else 1.0, size=4)
            ts = env.step(np.clip(action, -1, 1))
            obs.append(ts.observation)
            rewards.append(ts.reward)
        achieved = np.stack([o["achieved"] for o in obs[1:]])[:, task.outcome_slices[i]]
        goal = module.goal(np.broadcast_to(slot, (50, 3)), achieved)
        observed = np.stack([o["goal"][3 * i : 3 * i + 3] for o in obs[1:]])
        np.testing.assert_array_equal(observed, goal, module.name)
        recomputed = module.reward(achieved, goal)
        np.testing.assert_array_equal(recomputed, np.array(rewards, np.float32), module.name)
        seen_rewards.update(rewards)
        successes = np.stack([o["success"] for o in obs[1:]])
        # success of every module, against that module's goal, from the same outcomes
        for j, other in enumerate(task.modules):
            ach = np.stack([o["achieved"] for o in obs[1:]])[:, task.outcome_slices[j]]
            goal = other.goal(task.goal_slots[j], ach)
            np.testing.assert_array_equal(
                other.success(ach, goal).astype(np.float32), successes[:, j]
            )
    assert seen_rewards == {0.0, -1.0}  # the comparison covered successes too


def test_start_state_gripper_and_reachable_cubes():
    env = suite.load("default", seed=5)
    state_layout = env.task.state_layout
    for _ in range(40):
        state = env.reset().observation["state"]
        grip = state[state_layout.gripper_pos]
        cubes = state[state_layout.cube_pos].reshape(5, 3)
        np.testing.assert_allclose(grip, layout.GRIP0, atol=2e-3)
        np.testing.assert_allclose(cubes[:, 2], 0.425, atol=2e-3)
        offsets = cubes[:2, :2] - grip[:2]
        assert np.all(np.abs(offsets) <= 0.15 + 1e-3)
        assert np.all(np.linalg.norm(offsets, axis=1) >= 0.1 - 1e-3)
        assert np.linalg.norm(cubes[0, :2] - cubes[1, :2]) >= 0.1 - 1e-6
        np.testing.assert_allclose(cubes[2:, :2], layout.DISTRACTOR_STARTS[:3], atol=0.021)
        np.testing.assert_allclose(state[state_layout.cube_euler], 0.0, atol=1e-6)


def test_distractors_start_with_the_authors_noise():
    """gym_flowers multi_task_fetch_arm_v0.py `_reset_sim`: each distractor starts at its point
    plus U(-0.01, 0.01) in x and U(-0.02, 0.02) in y."""
    env = suite.load("default", seed=6)
    sl = env.task.state_layout
    offsets = []
    for _ in range(60):
        cubes = env.reset().observation["state"][sl.cube_pos].reshape(5, 3)
        offsets.append(cubes[2:, :2] - layout.DISTRACTOR_STARTS[:3])
    offsets = np.abs(np.concatenate(offsets))
    assert offsets[:, 0].max() <= 0.01 + 1e-6 and offsets[:, 0].max() > 0.009
    assert offsets[:, 1].max() <= 0.02 + 1e-6 and offsets[:, 1].max() > 0.018


def test_reset_does_not_resimulate_the_settled_arm():
    env = suite.load("default", seed=0)
    first = env.reset().observation["state"]
    for _ in range(3):
        for _ in range(20):
            env.step(np.array([1.0, 1.0, 1.0, -1.0]))
        again = env.reset().observation["state"]
        sl = env.task.state_layout
        np.testing.assert_array_equal(again[sl.gripper_pos], first[sl.gripper_pos])
        np.testing.assert_array_equal(again[sl.finger_pos], first[sl.finger_pos])


@pytest.mark.parametrize("variant", ["default", "distractors_4", "distractors_7"])
def test_distractors_random_walk_on_the_table_out_of_reach(variant):
    """gym_flowers multi_task_fetch_arm_v0.py `_get_obs`: every step each distractor's xy moves
    by N(0, 0.005^2), never within 0.05 of another cube; ours also stays in its region."""
    env = suite.load(variant, seed=2)
    n = env.task.n_cubes
    low = np.array([layout.DISTRACTOR_X_RANGE[0], layout.DISTRACTOR_Y_RANGE[0]])
    high = np.array([layout.DISTRACTOR_X_RANGE[1], layout.DISTRACTOR_Y_RANGE[1]])
    moves = []
    for _ in range(4):
        obs, _ = rollout(env, np.random.default_rng(0).uniform(-1, 1, size=(50, 4)))
        cubes = obs["state"][:, 3 : 3 + 3 * n].reshape(51, n, 3)
        xy = cubes[:, 2:, :2]
        assert np.all(xy >= low - 1e-6) and np.all(xy <= high + 1e-6)
        np.testing.assert_allclose(cubes[:, 2:, 2], cubes[0, 2, 2])
        assert cubes[0, 2, 2] == pytest.approx(0.425, abs=2e-3)
        pair = np.linalg.norm(cubes[:, :, None, :2] - cubes[:, None, :, :2], axis=-1)
        pair[:, np.arange(n), np.arange(n)] = np.inf
        assert pair[:, 2:].min() >= layout.DISTRACTOR_MIN_SEPARATION - 1e-6
        moves.append(np.diff(xy, axis=0).reshape(-1))
    moves = np.concatenate(moves)
    assert np.mean(moves != 0) > 0.95  # they move every step
    assert np.std(moves) == pytest.approx(layout.DISTRACTOR_WALK_STD, rel=0.15)


BAD_INPUTS = [
    ("action", np.zeros(3), "shape \\(4,\\)"),
    ("action", np.zeros((1, 4)), "shape \\(4,\\)"),
    ("action", np.array([0.0, np.nan, 0.0, 0.0]), "finite"),
    ("action", np.array([0.0, 0.0, np.inf, 0.0]), "finite"),
    ("module", "fly", "unknown module 'fly'.*reach"),
    ("module", 7, "out of range"),
    ("module", True, "name or an index"),
    ("goal", [0.0, 1.5, 0.0], "\\[-1, 1\\]\\^3"),
    ("goal", [0.0, 0.0], "shape \\(3,\\)"),
    ("goal", [np.nan, 0.0, 0.0], "finite"),
]


@pytest.mark.parametrize(("kind", "value", "message"), BAD_INPUTS)
def test_bad_input_raises_a_clear_error_and_the_env_stays_usable(kind, value, message):
    env = suite.load("default", seed=0)
    env.reset()
    good = np.array([0.3, -0.2, 0.1, 1.0])
    env.step(good)
    with pytest.raises(ValueError, match=message):
        if kind == "action":
            env.step(value)
        elif kind == "module":
            env.task.set_next_episode(module=value)
        else:
            env.task.set_next_episode(module="reach", goal=value)
    # Still usable: the failed call changed nothing, the episode goes on to its 50 steps.
    steps = 1
    while not env.step(good).last():
        steps += 1
    assert steps == 49  # the bad action was not counted as a step
    env.task.set_next_episode(module="stack", goal=[0.0, 0.0, 0.0])
    env.reset()
    assert env.task.active_module == 3


@pytest.mark.parametrize(
    ("module", "message"),
    [(value, message) for kind, value, message in BAD_INPUTS if kind == "module"],
)
def test_the_agent_names_modules_by_the_suites_rule(module, message):
    """The agent's `EnvSpec.module_index` is the suite's: the same index for a name, and the
    same one-line ValueError (the command line's kind) for what names no module."""
    from curious.envs.goal_env import EnvSpec

    task = suite.load("default", seed=0).task
    names = task.module_names
    spec = EnvSpec(names, (True,) * len(names), 49, 4, 3, (slice(0, 3),) * len(names), 50)
    assert [spec.module_index(n) for n in names] == [task.module_index(n) for n in names]
    assert spec.module_index(np.int64(2)) == 2
    with pytest.raises(ValueError, match=message):
        spec.module_index(module)


def test_out_of_range_actions_are_clipped():
    a, b = suite.load("default", seed=1), suite.load("default", seed=1)
    a.reset(), b.reset()
    for _ in range(5):
        oa = a.step(np.array([3.0, -2.0, 1.5, -7.0])).observation["state"]
        ob = b.step(np.array([1.0, -1.0, 1.0, -1.0])).observation["state"]
    np.testing.assert_array_equal(oa, ob)


def test_gripper_follows_the_action():
    env = suite.load("distractors_0", seed=0)
    start = env.reset().observation["state"][:3].copy()
    for _ in range(10):
        state = env.step(np.array([0.0, 1.0, 0.0, 0.0])).observation["state"]
    # At most 5 cm per step; the weld lets the gripper lag its target, and it covers about
    # 0.32 m in 10 full steps, as the gymnasium-robotics Fetch arm does (0.3207 measured there).
    assert 0.29 < state[1] - start[1] < 0.35
    np.testing.assert_allclose(state[[0, 2]], start[[0, 2]], atol=0.01)


def test_cube_linear_velocities_are_relative_to_the_gripper():
    """gym_flowers multi_task_fetch_arm_v0.py `_get_obs`: `object0_velp -= grip_velp` (both times
    the control timestep)."""
    env = suite.load("default", seed=4)
    task, physics = env.task, env.physics
    sl = task.state_layout
    env.reset()
    joints = [physics.bind(j) for j in task._cube_joints]
    dt = layout.CONTROL_TIMESTEP
    moving = 0
    for t in range(30):
        action = np.array([1.0, 0.2, -0.5, 1.0]) if t < 15 else np.array([-1.0, 0.0, 0.3, -1.0])
        state = env.step(action).observation["state"]
        vel = state[sl.cube_vel].reshape(2, 6)
        grip_vel = state[sl.gripper_vel]
        for k, joint in enumerate(joints):
            qvel = np.asarray(joint.qvel, dtype=np.float64)  # free joint: linear velocity first
            np.testing.assert_allclose(vel[k, 3:], qvel[:3] * dt - grip_vel, atol=1e-6)
        moving += bool(np.abs(grip_vel).max() > 1e-3)
    assert moving > 10  # the gripper moved, so relative and absolute differ


def test_cubes_are_the_authors_bodies():
    """gym_flowers assets/fetch/multi_task_fetch_arm.xml: `object0` ... free joints with
    damping 0.01, boxes of half-size 0.025 and mass 2, condim 3."""
    env = suite.load("default", seed=0)
    physics, task = env.physics, env.task
    for joint in task._cube_joints:  # the reachable cubes' free joints
        bound = physics.bind(joint)
        assert joint.type == "free"
        np.testing.assert_allclose(bound.damping, 0.01)
    for cube in task.cubes:
        geom = physics.bind(cube.geom)
        np.testing.assert_allclose(geom.size, [0.025] * 3)
        assert int(geom.condim) == 3
    for cube in task.cubes[: task.n_reachable]:
        body = physics.model.geom_bodyid[physics.bind(cube.geom).element_id]
        np.testing.assert_allclose(physics.model.body_mass[body], 2.0)


def test_a_blocked_distractor_draws_99_moves_then_stays_put():
    """gym_flowers multi_task_fetch_arm_v0.py `_get_obs`: a move within 0.05 of another cube is
    drawn again, and the loop gives up (the cube stays) when its counter reaches 100: 99 moves
    drawn and checked in all."""
    from suite.distractors import DistractorWalk

    walk = DistractorWalk(n_cubes=2, n_distractors=1, episode_steps=50)
    rng = np.random.RandomState(0)
    walk.reset(rng)
    reference = np.random.RandomState(0)
    reference.normal(0.0, layout.DISTRACTOR_WALK_STD, (50, 1, 2))  # the episode's first draws
    here = np.array([[2.0, 0.8]])
    # A reachable cube on the distractor itself: every move ends within 0.05 of it.
    new = walk.step(here.copy(), here.copy(), rng)
    np.testing.assert_array_equal(new, here)
    reference.normal(0.0, layout.DISTRACTOR_WALK_STD, (98, 2))  # the 98 redraws
    assert rng.uniform() == reference.uniform()


def test_loading_the_suite_leaves_library_deprecation_warnings_hidden():
    """dm_control's composer turns every DeprecationWarning on, process-wide, when imported; a
    program that loads the suite keeps Python's default, which hides those raised in libraries
    (in a fresh process: this one has imported dm_control already)."""
    code = (
        "import warnings\n"
        "import suite\n"
        "suite.load('default', seed=0).reset()\n"
        "with warnings.catch_warnings(record=True) as shown:\n"
        "    warnings.warn_explicit('old', DeprecationWarning, 'lib.py', 1, module='lib')\n"
        "assert not shown, [str(w.message) for w in shown]\n"
    )
    done = run_fresh(code)
    assert done.returncode == 0, done.stderr
