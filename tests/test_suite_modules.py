"""Task modules: goal slots, outcomes, success and reward, vectorised over any batch shape, and
the env's batched evaluation agreeing exactly with the modules' own functions."""

from __future__ import annotations

import numpy as np
import pytest

import suite
import suite.environment
import suite.task
from suite import layout
from suite.modules import TaskModule, affine_slot, within_distance
from suite.outcomes import ModuleEvaluator

MODULES = suite.standard_modules(3)
N_CUBES = 5


def random_positions(rng, batch):
    gripper = rng.uniform([1.1, 0.5, 0.42], [1.6, 1.0, 0.9], size=(*batch, 3))
    cubes = rng.uniform([1.1, 0.5, 0.42], [2.2, 1.0, 0.9], size=(*batch, N_CUBES, 3))
    return gripper, cubes


def test_standard_module_names_and_dims():
    assert [m.name for m in MODULES] == [
        "reach",
        "push_cube1",
        "cube1_above_cube2",
        "stack",
        "push_cube3",
        "push_cube4",
        "push_cube5",
    ]
    assert [m.outcome_dim for m in MODULES] == [3, 3, 5, 8, 3, 3, 3]
    assert all(m.goal_dim == 3 for m in MODULES)


def test_goal_slots_map_the_cube_onto_the_documented_regions():
    corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
    reach, push, above, stack = MODULES[:4]
    gx, gy = layout.GRIP0[:2]
    slots = reach.goal_slot(corners)
    np.testing.assert_allclose(slots[:, 0].min(), gx - 0.15, atol=1e-6)
    np.testing.assert_allclose(slots[:, 1].max(), gy + 0.15, atol=1e-6)
    np.testing.assert_allclose([slots[:, 2].min(), slots[:, 2].max()], [0.426, 0.876], atol=1e-6)
    push_slots = push.goal_slot(corners)
    np.testing.assert_allclose(push_slots[:, 2], 0.426, atol=1e-7)
    np.testing.assert_allclose(push_slots[:, :2], slots[:, :2])
    above_slots = above.goal_slot(corners)
    # The slots of the goals that follow cube 2 are those goals with cube 2 at grip0's xy.
    np.testing.assert_allclose(above_slots[:, :2], np.tile([gx, gy], (8, 1)), atol=1e-6)
    # 0.05 to 0.45 m above a resting cube's centre: gym_flowers multi_task_fetch_arm_v0.py
    # `_compute_goal` (as of its 2018-10-22 revision, kept to the end of v0; v3 has the same),
    # task 2: height_offset + (g_z + 1.25) * 0.45 / 2.25.
    g_z = corners[:, 2]
    np.testing.assert_allclose(above_slots[:, 2], 0.426 + (g_z + 1.25) * 0.45 / 2.25, atol=1e-6)
    # Stacking: one cube height above the table's resting height whatever g (v0.py
    # `_compute_goal`, task 3: height_offset + 0.05).
    np.testing.assert_allclose(stack.goal_slot(corners), np.tile([gx, gy, 0.476], (8, 1)))
    for m in MODULES:
        assert m.goal_slot(corners).dtype == np.float32


@pytest.mark.parametrize("batch", [(), (5,), (2, 3)])
def test_functions_are_vectorised_and_agree_with_one_at_a_time(batch):
    rng = np.random.default_rng(0)
    gripper, cubes = random_positions(rng, batch)
    g = rng.uniform(-1, 1, size=(*batch, 3))
    for m in MODULES:
        outcome = m.achieved(gripper, cubes).astype(np.float32)
        goal = m.goal(m.goal_slot(g), outcome)
        reward = m.reward(outcome, goal)
        success = m.success(outcome, goal)
        assert goal.shape == (*batch, 3) and goal.dtype == np.float32
        assert outcome.shape == (*batch, m.outcome_dim)
        assert reward.shape == batch and reward.dtype == np.float32
        assert success.shape == batch and success.dtype == bool
        assert set(np.unique(reward)) <= {-1.0, 0.0}
        np.testing.assert_array_equal(reward == 0.0, success)
        for index in np.ndindex(*batch):
            one = m.achieved(gripper[index], cubes[index]).astype(np.float32)
            np.testing.assert_array_equal(one, outcome[index])
            one_goal = m.goal(m.goal_slot(g[index]), one)
            np.testing.assert_array_equal(one_goal, goal[index])
            assert m.reward(one, one_goal) == reward[index]


def test_outcomes_are_the_authors_world_positions():
    """gym_flowers multi_task_fetch_arm_v0.py `tasks_obs_id`: T1 the gripper, T2 and T3 cube 1's
    world position, T4 cube 1's then the gripper's, T5-7 the distractors'. Ours add cube 2's xy
    after them for the two modules whose goal follows cube 2; the hindsight goal (the part
    compared with goals) is the first three numbers, as the authors' `tasks_ag_id[:3]`."""
    rng = np.random.default_rng(1)
    gripper, cubes = random_positions(rng, (4,))
    reach, push1, above, stack, push3, _, push5 = MODULES
    c1, c2 = cubes[:, 0], cubes[:, 1]
    np.testing.assert_allclose(reach.achieved(gripper, cubes), gripper)
    np.testing.assert_allclose(push1.achieved(gripper, cubes), c1)
    np.testing.assert_allclose(push3.achieved(gripper, cubes), cubes[:, 2])
    np.testing.assert_allclose(push5.achieved(gripper, cubes), cubes[:, 4])
    np.testing.assert_allclose(above.achieved(gripper, cubes), np.c_[c1, c2[:, :2]])
    np.testing.assert_allclose(stack.achieved(gripper, cubes), np.c_[c1, gripper, c2[:, :2]])
    for m in (push1, above, stack):  # T2, T3 and T4 relabel with the same numbers
        outcome = m.achieved(gripper, cubes).astype(np.float32)
        np.testing.assert_array_equal(m.hindsight_goal(outcome), c1.astype(np.float32))


def test_success_threshold_and_the_stack_guard():
    """gym_flowers multi_task_fetch_arm_v0.py compute_reward: success within
    distance_threshold = 0.05 of the goal; for stacking, failure also where the gripper lies
    within 0.05 of the goal (`dgrip < distance_threshold`)."""
    reach, _, _, stack = MODULES[:4]
    slot = np.array([1.3, 0.7, 0.6], np.float32)
    inside = slot + np.array([0.049, 0, 0], np.float32)
    outside = slot + np.array([0.0, 0.03, 0.041], np.float32)  # 0.0506 away
    assert reach.success(inside, slot) and not reach.success(outside, slot)
    goal = np.array([1.4, 0.8, 0.476], np.float32)
    cube1 = goal + np.array([0.0, 0.0, 0.01], np.float32)
    near = goal + np.array([0.0, 0.03, 0.039], np.float32)  # 0.0492 from the goal
    away = goal + np.array([0.0, 0.03, 0.041], np.float32)  # 0.0506 from the goal
    cube2_xy = goal[:2]
    held = np.r_[cube1, near, cube2_xy]
    released = np.r_[cube1, away, cube2_xy]
    assert not stack.success(held, goal)
    assert stack.success(released, goal)
    assert stack.reward(np.stack([held, released]), goal).tolist() == [-1.0, 0.0]


def test_stack_guard_is_measured_from_the_transitions_goal():
    """The authors measure the gripper's distance from the goal the reward is computed for
    (gym_flowers multi_task_fetch_arm_v0.py compute_reward, `dgrip`): a hindsight goal, a later
    position of cube 1 anywhere on the table, pays only once the gripper has let go of the
    cube and moved away from it, not while it still holds the cube there."""
    stack = MODULES[3]
    cube2 = np.array([1.45, 0.85, 0.425])
    cube1 = np.array([1.25, 0.65, 0.425])  # on the table, far from cube 2
    cubes = np.c_[np.r_[[cube1[:2], cube2[:2]], layout.DISTRACTOR_STARTS[:3]], np.full(5, 0.425)]
    in_hand = stack.achieved(cube1, cubes).astype(np.float32)  # grip site at the cube
    let_go = stack.achieved(cube1 + np.array([0.0, 0.0, 0.1]), cubes).astype(np.float32)
    hindsight = stack.hindsight_goal(in_hand)  # cube 1 where it was placed
    np.testing.assert_array_equal(hindsight, cube1.astype(np.float32))
    assert stack.reward(in_hand, hindsight) == -1.0
    assert stack.reward(let_go, hindsight) == 0.0
    # The episode's own goal (on cube 2) is not met by either: cube 1 is far from it.
    own = stack.goal(stack.goal_slot(np.zeros(3)), let_go)
    np.testing.assert_allclose(own, [1.45, 0.85, 0.476], atol=1e-6)
    assert stack.reward(let_go, own) == -1.0


def test_goals_above_cube2_follow_it_and_hindsight_goals_stay_in_the_world():
    """gym_flowers multi_task_fetch_arm_v0.py `_update_goals`: the goal of T3/T4 takes cube 2's
    xy at every step; a hindsight goal is cube 1's world position (her.py `future_ag`), met
    where cube 1 is there, wherever cube 2 went meanwhile, as T2's."""
    push1, above = MODULES[1], MODULES[2]
    rng = np.random.default_rng(2)
    gripper, cubes = random_positions(rng, (3,))
    slot = above.goal_slot(np.zeros((3, 3)))
    cubes[:, 0, :2] = cubes[:, 1, :2]  # cube 1 straight above cube 2 ...
    cubes[:, 0, 2] = slot[:, 2]  # ... at the slot's height
    outcome = above.achieved(gripper, cubes).astype(np.float32)
    goal = above.goal(slot, outcome)
    np.testing.assert_allclose(goal, np.c_[cubes[:, 1, :2], slot[:, 2]], atol=1e-6)
    assert np.all(above.success(outcome, goal))
    # Cube 2 moves away; cube 1 stays: the episode's goal moved with cube 2, the hindsight goal
    # taken before the move did not.
    hindsight = above.hindsight_goal(outcome)
    cubes[:, 1, :2] += 0.2
    moved = above.achieved(gripper, cubes).astype(np.float32)
    assert not np.any(above.success(moved, above.goal(slot, moved)))
    assert np.all(above.success(moved, hindsight))
    pushed = push1.achieved(gripper, cubes).astype(np.float32)
    np.testing.assert_array_equal(push1.reward(pushed, hindsight), above.reward(moved, hindsight))


def test_bad_shapes_raise_clear_errors():
    reach = MODULES[0]
    with pytest.raises(ValueError, match="last dimension 3"):
        reach.goal_slot(np.zeros(2))
    with pytest.raises(ValueError, match="expected achieved"):
        reach.reward(np.zeros(4), np.zeros(3))
    with pytest.raises(ValueError, match="watches cube 5"):
        MODULES[-1].achieved(np.zeros(3), np.zeros((2, 3)))


def test_batched_evaluator_matches_each_module_exactly():
    rng = np.random.default_rng(3)
    evaluator = ModuleEvaluator(MODULES, N_CUBES)
    for trial in range(200):
        gripper, cubes = random_positions(rng, ())
        if trial % 2:  # put things near their goals so that successes happen too
            cubes[0] = cubes[1] + [0.0, 0.0, 0.05]
            gripper = cubes[0] + rng.normal(0, 0.04, 3)
        slots = np.stack([m.goal_slot(rng.uniform(-1, 1, 3)) for m in MODULES])
        if trial % 4 == 1:
            slots[0] = gripper + rng.normal(0, 0.02, 3)
        evaluator.set_slots(slots)
        positions = np.concatenate([gripper, cubes.ravel()])
        evaluator.evaluate(positions, gripper, cubes)
        for i, (m, sl) in enumerate(zip(MODULES, evaluator.slices, strict=True)):
            expected = m.achieved(gripper, cubes).astype(np.float32)
            np.testing.assert_array_equal(evaluator.achieved[sl], expected, err_msg=m.name)
            goal = m.goal(slots[i], expected)
            np.testing.assert_array_equal(evaluator.goals[i], goal, err_msg=m.name)
            assert evaluator.success[i] == float(m.success(expected, goal)), m.name


@pytest.mark.parametrize("goal_kind", ["own", "hindsight"])
def test_row_wise_goals_and_success_match_each_module_exactly(goal_kind):
    """`row_goals` and `row_success` (the replay's relabelling of a whole minibatch, every row
    its own module) give each module's own `goal` and `success`, bit for bit."""
    rng = np.random.default_rng(11)
    evaluator = ModuleEvaluator(MODULES, N_CUBES)
    n = 600
    gripper, cubes = random_positions(rng, (n,))
    near = rng.random(n) < 0.5  # cube 1 on cube 2 and the gripper near it: successes happen
    cubes[near, 0] = cubes[near, 1] + [0.0, 0.0, 0.05]
    gripper[near] = cubes[near, 0] + rng.normal(0, 0.04, (int(near.sum()), 3))
    achieved = np.concatenate(
        [m.achieved(gripper, cubes).astype(np.float32) for m in MODULES], axis=-1
    )
    modules = rng.integers(len(MODULES), size=n)
    slots = np.stack([MODULES[k].goal_slot(rng.uniform(-1, 1, 3)) for k in modules])
    if goal_kind == "own":
        goals = evaluator.row_goals(modules, slots, achieved)
    else:  # a hindsight goal: the row's own outcome where `near`, another row's elsewhere
        source = np.where(near, np.arange(n), rng.permutation(n))
        goals = np.stack(
            [
                MODULES[k].hindsight_goal(achieved[j, evaluator.slices[k]])
                for j, k in zip(source, modules, strict=True)
            ]
        )
    success = evaluator.row_success(modules, achieved, goals)
    assert success.any() and not success.all()
    for i, k in enumerate(modules):
        m, sl = MODULES[k], evaluator.slices[k]
        if goal_kind == "own":
            np.testing.assert_array_equal(goals[i], m.goal(slots[i], achieved[i, sl]))
        assert success[i] == m.success(achieved[i, sl], goals[i]), m.name


def test_goal_positions_follow_cube2():
    evaluator = ModuleEvaluator(MODULES, N_CUBES)
    slots = np.stack([m.goal_slot(np.zeros(3)) for m in MODULES])
    evaluator.set_slots(slots)
    gripper = np.array([1.3, 0.75, 0.6])
    cubes = np.array([[1.2, 0.7], [1.4, 0.8], *layout.DISTRACTOR_STARTS[:3]])
    cubes = np.c_[cubes, np.full(5, 0.425)]
    evaluator.evaluate(np.concatenate([gripper, cubes.ravel()]), gripper, cubes)
    world = evaluator.goals
    np.testing.assert_allclose(world[0], slots[0])
    np.testing.assert_allclose(world[2], [1.4, 0.8, slots[2][2]], rtol=1e-6)
    np.testing.assert_allclose(world[3], [1.4, 0.8, 0.476], rtol=1e-6)


def lift_cube1() -> TaskModule:
    """A module without declared structure: lift cube 1 to a height (judged on z only)."""

    def success(achieved, slot):
        return np.abs(achieved[..., 0] - slot[..., 2]) < np.float32(0.02)

    return TaskModule(
        name="lift_cube1",
        achievable=True,
        outcome_dim=1,
        cubes=(0,),
        slot_fn=affine_slot((0.0, 0.0, 0.1), (0.0, 0.0, 0.55)),
        outcome_fn=lambda gripper, cubes: cubes[..., 0, 2:3].copy(),
        success_fn=success,
    )


def test_a_new_module_plugs_in_without_touching_the_env():
    modules = (*suite.standard_modules(0), lift_cube1())
    env = suite.environment.SuiteEnvironment(
        suite.task.MultiTaskFetch(modules, n_cubes=2), random_state=0
    )
    env.task.set_next_episode(module="lift_cube1", goal=[0.0, 0.0, -1.0])  # 0.45 m
    ts = env.reset()
    assert ts.observation["achieved"].shape == (20,)
    z = ts.observation["achieved"][-1]
    assert z == pytest.approx(0.425, abs=2e-3)
    assert ts.observation["success"][-1] == 0.0  # on the table, 2.5 cm short of 0.45
    ts = env.step(np.zeros(4))
    assert ts.reward == -1.0


def test_within_distance_does_not_depend_on_batch_layout():
    rng = np.random.default_rng(4)
    a = rng.normal(0, 0.03, size=(1000, 4)).astype(np.float32)
    s = rng.normal(0, 0.001, size=(1000, 3)).astype(np.float32)
    full = within_distance(a, s)
    strided = within_distance(a[::-1], s[::-1])[::-1]
    np.testing.assert_array_equal(full, strided)
    np.testing.assert_array_equal(full, [within_distance(x, y) for x, y in zip(a, s, strict=True)])


def test_module_list_must_be_valid():
    with pytest.raises(ValueError, match="unique"):
        suite.task.MultiTaskFetch((MODULES[0], MODULES[0]), n_cubes=5)
    with pytest.raises(ValueError, match="watches cube 5"):
        suite.task.MultiTaskFetch(MODULES, n_cubes=4)
    with pytest.raises(ValueError, match="at least one module"):
        suite.task.MultiTaskFetch((), n_cubes=2)
