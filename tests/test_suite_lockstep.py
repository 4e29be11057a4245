"""The suite's lockstep pieces: outcomes of many copies as those of each, the variants that
cannot be stepped in lockstep refused by name, and a diverging copy named in the error."""

from __future__ import annotations

import os

import numpy as np
import pytest
from dm_control.rl import control

import suite
from suite.catalog import BUILT_IN
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
