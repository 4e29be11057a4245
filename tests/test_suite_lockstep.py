"""The suite's lockstep pieces: outcomes of many copies as those of each, the variants that
cannot be stepped in lockstep refused by name, and a diverging copy named in the error."""

from __future__ import annotations

import os

import numpy as np
import pytest
from dm_control.rl import control

import suite
from suite.catalog import BUILT_IN
from suite.distractors import DistractorWalk, start_positions, step_walks
from suite.layout import CUBE_REST_Z, GRIP0
from suite.lockstep_physics import LockstepPhysics
from suite.lockstep_task import LockstepTask
from suite.outcomes import ModuleEvaluator

os.environ.setdefault("MUJOCO_GL", "disable")


@pytest.mark.parametrize("variant", list(BUILT_IN))
def test_stacked_outcomes_are_each_copys_bit_for_bit(variant: str) -> None:
    spec = BUILT_IN[variant]
    modules, n_cubes = spec.modules(), spec.task_options["n_cubes"]
    rng = np.random.default_rng(0)
    n = 400
    # gripper and cubes in a small box around the gripper's start, goals drawn near it: every
    # module succeeds in some copies and fails in others (stack's guard included)
    positions = np.tile(GRIP0, 1 + n_cubes) + rng.uniform(-0.06, 0.06, (n, 3 + 3 * n_cubes))
    positions[:, 2::3] = CUBE_REST_Z + rng.uniform(0.0, 0.08, (n, 1 + n_cubes))
    g = rng.uniform(-0.3, 0.3, (n, len(modules), 3)).astype(np.float32)
    g[..., 2] = -1.0
    slots = np.stack([m.goal_slot(g[:, i]) for i, m in enumerate(modules)], axis=1)

    stacked = ModuleEvaluator(modules, n_cubes).evaluate_stacked(positions, slots)
    one = ModuleEvaluator(modules, n_cubes)
    for i in range(n):
        one.set_slots(slots[i])
        one.evaluate(positions[i], positions[i, :3], positions[i, 3:].reshape(-1, 3))
        np.testing.assert_array_equal(stacked[0][i], one.achieved)
        np.testing.assert_array_equal(stacked[1][i], one.success > 0.5)
    achievable = [i for i, m in enumerate(modules) if m.achievable]
    assert stacked[1][:, achievable].any(axis=0).all() and not stacked[1].all(axis=0).any()


def _loads(variant: str, n: int, **kwargs) -> list:
    envs = [suite.load(variant, seed=i, **kwargs) for i in range(n)]
    for env in envs:
        env.reset()
    return envs


def test_what_cannot_be_stepped_in_lockstep_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match="copy 1 cannot be stepped in lockstep: a Environment"):
        LockstepTask([*_loads("default", 1), *_loads("default", 1, stock=True)], 1)
    hooked = _loads("default", 2)
    hooked[1].add_extra_hook("before_substep", lambda physics, action, random_state: None)
    with pytest.raises(ValueError, match=r"copy 1 .* acts at before_substep"):
        LockstepTask(hooked, 1)
    with pytest.raises(ValueError, match="copy 1 is not the same variant as copy 0"):
        LockstepTask([*_loads("default", 1), *_loads("distractors_4", 1)], 1)


def test_a_diverging_copy_is_a_physics_error_naming_it() -> None:
    envs = _loads("distractors_0", 3)
    physics = LockstepPhysics([env.physics.model.ptr for env in envs], 20, 2)
    assert physics.shared_model is envs[0].physics.model.ptr  # copies of one variant: one model
    try:
        for i, env in enumerate(envs):
            physics.load(i, env.physics.data.ptr)
        physics.refresh(range(3))
        physics.advance(physics.ctrl.copy(), physics.mocap_pos.copy())  # all well
        physics.qvel[1] = 1e12  # copy 1 blows up
        with pytest.raises(control.PhysicsError, match=r"copies \[1\]"):
            physics.advance(physics.ctrl.copy(), physics.mocap_pos.copy())
    finally:
        physics.close()


def test_stacked_walks_move_as_each_walk_redraws_and_all() -> None:
    n_cubes, n = 9, 40
    walks = [[DistractorWalk(n_cubes, 7, 20) for _ in range(n)] for _ in range(2)]
    states = [[np.random.RandomState(i) for i in range(n)] for _ in range(2)]
    for copies, randoms in zip(walks, states, strict=True):
        for walk, random_state in zip(copies, randoms, strict=True):
            walk.reset(random_state)
    redraws = []
    for walk in walks[1]:  # count the stacked path's redraws
        walk.redraw = lambda *args, walk=walk: redraws.append(1) or type(walk).redraw(walk, *args)
    rng = np.random.default_rng(0)
    # the distractors crowded together (0.03 apart), the reachable cubes far away
    xy = start_positions(7, np.random.RandomState(0))[None].repeat(n, 0) * 0.4 + 0.7
    xy += rng.uniform(-0.01, 0.01, xy.shape)
    others = rng.uniform(-0.2, 0.2, (n, 2, 2))
    for _ in range(25):  # past the episode's 20 drawn moves
        one = np.stack(
            [walk.step(others[i], xy[i], states[0][i]).copy() for i, walk in enumerate(walks[0])]
        )
        np.testing.assert_array_equal(step_walks(walks[1], others, xy, states[1]), one)
        xy = one
    assert len(redraws) > 10


def test_copies_on_models_of_their_own_step_as_each_alone() -> None:
    alone, together = _loads("default", 2), _loads("default", 2)
    for envs in (alone, together):
        envs[1].physics.model.ptr.geom_friction[:, 0] *= 0.5  # copy 1 slides more
    lockstep = LockstepTask(together, 2)
    try:
        assert lockstep.physics.shared_model is None
        for env in (*alone, *together):
            env.task.set_next_episode(module="push_cube1")
            env.reset()
        lockstep.load(range(2))
        rng = np.random.default_rng(3)
        for _ in range(15):
            actions = rng.uniform(-1, 1, (2, 4))
            state, achieved, success = lockstep.step(actions)
            for i, env in enumerate(alone):
                obs = env.step(actions[i]).observation
                np.testing.assert_array_equal(state[i], obs["state"])
                np.testing.assert_array_equal(achieved[i], obs["achieved"])
                np.testing.assert_array_equal(success[i], obs["success"] > 0.5)
    finally:
        lockstep.close()
