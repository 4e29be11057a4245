"""Task modules: what a task watches, how its goals map into the workspace, when it succeeds.

A module is a small frozen definition (`TaskModule`): a name, whether it can be achieved, the
outcome it watches (`achieved(gripper, cubes)`), the map from a goal g in [-1, 1]^3 to its goal
slot (`goal_slot(g)`), and its success predicate and sparse reward. Every function is vectorised
over any leading batch shape and computes in float32, so that the agent's recomputed rewards on
relabelled transitions agree bit for bit with the env's step reward (the env evaluates the same
functions on the float32 outcomes and goal slots that it reports).

The env holds a tuple of modules; adding a module means writing one here (or anywhere) and
passing it to `MultiTaskFetch`, never editing the env.

Every module of the paper is a *distance module* (`distance_module`): its outcome starts with
components linear in the positions (a cube's position, a difference of two), possibly followed by
a few computed ones, and it succeeds when the first three components lie within 0.05 m of the
goal slot (and, for `stack`, a guard on the rest holds). Declaring that structure lets the env
evaluate all such modules together, with one matrix product and one distance test per step;
modules that declare nothing are evaluated through their functions.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from suite import layout

_EPS2 = np.float32(layout.SUCCESS_DISTANCE) ** 2
_AWAY = np.float32(1.2 * layout.SUCCESS_DISTANCE)
"""`stack`'s guard: the gripper at least 0.06 m from the stack target (the authors' 1.2 x 0.05,
gym_flowers multi_task_fetch_arm_v5.py, its stacking reward)."""
_ONE = np.float32(1.0)

SlotFn = Callable[[np.ndarray], np.ndarray]
OutcomeFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
SuccessFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
GuardFn = Callable[[np.ndarray], np.ndarray]
# One outcome component of a linear module: a sum of (point, axis, coefficient) terms, where
# point 0 is the gripper and point k >= 1 is cube k; axis 0, 1, 2 is x, y, z. For the first
# three components of a distance module, the first term is the watched point's coordinate (with
# coefficient 1) and the other terms place the frame the goal slot is expressed in (e.g. minus
# cube 2's x); `goal_frame_matrix` reads the frame from them.
LinearTerms = tuple[tuple[tuple[int, int, float], ...], ...]


@dataclass(frozen=True, eq=False)
class TaskModule:
    """One task of the multi-task env: its outcome, goal slot, success and reward.

    Attributes:
        name: unique name (`reach`, `push_cube1`, ...).
        achievable: False for distractor modules (their cube is out of reach).
        outcome_dim: size of the outcome `achieved` returns.
        cubes: 0-based indices of the cubes the outcome reads (the env checks it has them).
        slot_fn: g (..., 3) float32 -> goal slot (..., 3) float32.
        outcome_fn: (gripper (..., 3), cubes (..., n, 3)) -> outcome (..., outcome_dim).
        success_fn: (outcome (..., outcome_dim), slot (..., 3)) float32 -> bool (...,).
        goal_dim: size of g (3 for every module).
        linear_terms: optional structure: the first `len(linear_terms)` outcome components are
            linear in the positions, given as terms (see `LinearTerms`) ...
        extra_outcome_fn: ... and the remaining ones come from this function (same arguments
            as `outcome_fn`).
        reaches_slot: optional structure: success means "the first three outcome components lie
            within 0.05 m of the goal slot" ...
        guard_fn: ... and `guard_fn(outcome)` holds.
        The optional structure must agree with the functions; `distance_module` builds modules
        where it does by construction.
    """

    name: str
    achievable: bool
    outcome_dim: int
    cubes: tuple[int, ...]
    slot_fn: SlotFn
    outcome_fn: OutcomeFn
    success_fn: SuccessFn
    goal_dim: int = 3
    linear_terms: LinearTerms | None = None
    extra_outcome_fn: OutcomeFn | None = None
    reaches_slot: bool = False
    guard_fn: GuardFn | None = None

    def outcome_matrix(self, n_cubes: int) -> np.ndarray | None:
        """W (len(linear_terms), 3 + 3 n_cubes) with outcome[:len(linear_terms)] =
        W @ [gripper, cube 1, ..., cube n], or None without linear terms."""
        if self.linear_terms is None:
            return None
        return _outcome_matrix(self.linear_terms, n_cubes)

    def goal_frame_matrix(self, n_cubes: int) -> np.ndarray:
        """F (3, 3 + 3 n_cubes) with world goal position = goal slot + F @ positions.

        Zero (the slot is a world position) unless the first three linear components carry
        terms beyond their first, which then place the slot's frame (cube 2 for
        `cube1_above_cube2` and `stack`).
        """
        frame = np.zeros((3, 3 + 3 * n_cubes))
        if self.linear_terms is not None and self.reaches_slot:
            for row, component in enumerate(self.linear_terms[:3]):
                for point, axis, coefficient in component[1:]:
                    frame[row, 3 * point + axis] -= coefficient
        return frame

    def goal_slot(self, g: np.ndarray) -> np.ndarray:
        """Map goals g (..., 3) in [-1, 1] to goal slots (..., 3), float32; pure."""
        g = np.asarray(g, dtype=np.float32)
        if g.shape[-1:] != (self.goal_dim,):
            raise ValueError(
                f"{self.name}: a goal must have last dimension {self.goal_dim}, got shape {g.shape}"
            )
        return self.slot_fn(g)

    def achieved(self, gripper: np.ndarray, cubes: np.ndarray) -> np.ndarray:
        """The outcome from positions: gripper (..., 3), cubes (..., n_cubes, 3)."""
        gripper = np.asarray(gripper)
        cubes = np.asarray(cubes)
        if gripper.shape[-1:] != (3,) or cubes.shape[-1:] != (3,) or cubes.ndim < 2:
            raise ValueError(
                f"{self.name}: expected gripper (..., 3) and cubes (..., n_cubes, 3), got "
                f"shapes {gripper.shape} and {cubes.shape}"
            )
        if cubes.shape[-2] <= max(self.cubes, default=-1):
            raise ValueError(
                f"{self.name} watches cube {max(self.cubes) + 1} but only {cubes.shape[-2]} "
                "cubes were given"
            )
        return self.outcome_fn(gripper, cubes)

    def success(self, achieved: np.ndarray, goal_slot: np.ndarray) -> np.ndarray:
        """Whether outcomes (..., outcome_dim) meet goal slots (..., 3): bool (...,)."""
        achieved = np.asarray(achieved, dtype=np.float32)
        goal_slot = np.asarray(goal_slot, dtype=np.float32)
        if achieved.shape[-1:] != (self.outcome_dim,) or goal_slot.shape[-1:] != (3,):
            raise ValueError(
                f"{self.name}: expected achieved (..., {self.outcome_dim}) and goal_slot (..., 3),"
                f" got shapes {achieved.shape} and {goal_slot.shape}"
            )
        return self.success_fn(achieved, goal_slot)

    def reward(self, achieved: np.ndarray, goal_slot: np.ndarray) -> np.ndarray:
        """Sparse reward (...,) float32: 0 where `success`, -1 elsewhere."""
        return self.success(achieved, goal_slot).astype(np.float32) - _ONE


# -- building blocks ---------------------------------------------------------------------------


@functools.lru_cache(maxsize=256)
def _outcome_matrix(terms: LinearTerms, n_cubes: int) -> np.ndarray:
    w = np.zeros((len(terms), 3 + 3 * n_cubes))
    for row, component in enumerate(terms):
        for point, axis, coefficient in component:
            if not 0 <= point <= n_cubes or axis not in (0, 1, 2):
                raise ValueError(f"bad outcome term {(point, axis, coefficient)}")
            w[row, 3 * point + axis] += coefficient
    w.setflags(write=False)
    return w


def linear_outcome(terms: LinearTerms) -> OutcomeFn:
    """The outcome function `[gripper, cubes...] @ W.T` of linear terms."""

    def outcome(gripper: np.ndarray, cubes: np.ndarray) -> np.ndarray:
        n = cubes.shape[-2]
        batch = np.broadcast_shapes(gripper.shape[:-1], cubes.shape[:-2])
        points = np.concatenate(
            (
                np.broadcast_to(gripper[..., None, :], (*batch, 1, 3)),
                np.broadcast_to(cubes, (*batch, n, 3)),
            ),
            axis=-2,
        )
        return points.reshape(*batch, 3 + 3 * n) @ _outcome_matrix(terms, n).T

    return outcome


def _cubes_in(terms: LinearTerms) -> tuple[int, ...]:
    return tuple(sorted({point - 1 for component in terms for point, _, _ in component if point}))


def distance_module(
    name: str,
    *,
    achievable: bool,
    slot_fn: SlotFn,
    terms: LinearTerms,
    extra_outcome_fn: OutcomeFn | None = None,
    extra_dim: int = 0,
    extra_cubes: tuple[int, ...] = (),
    guard_fn: GuardFn | None = None,
) -> TaskModule:
    """A module whose outcome is `terms` (linear in the positions) followed by `extra_dim`
    components from `extra_outcome_fn` (reading cubes `extra_cubes`, 0-based), and which
    succeeds when the first three components lie within 0.05 m of the goal slot (and
    `guard_fn(outcome)` holds, if given)."""
    terms = tuple(tuple(tuple(t) for t in component) for component in terms)
    if len(terms) < 3:
        raise ValueError(f"{name}: a distance module needs at least 3 linear components")
    if (extra_outcome_fn is None) != (extra_dim == 0):
        raise ValueError(f"{name}: give extra_outcome_fn and extra_dim together")
    linear = linear_outcome(terms)
    if extra_outcome_fn is None:
        outcome_fn = linear
    else:
        extra = extra_outcome_fn

        def outcome_fn(gripper: np.ndarray, cubes: np.ndarray) -> np.ndarray:
            return np.concatenate((linear(gripper, cubes), extra(gripper, cubes)), axis=-1)

    if guard_fn is None:
        success_fn = within_distance
    else:
        guard = guard_fn

        def success_fn(achieved: np.ndarray, goal_slot: np.ndarray) -> np.ndarray:
            return within_distance(achieved, goal_slot) & guard(achieved)

    return TaskModule(
        name=name,
        achievable=achievable,
        outcome_dim=len(terms) + extra_dim,
        cubes=tuple(sorted(set(_cubes_in(terms)) | set(extra_cubes))),
        slot_fn=slot_fn,
        outcome_fn=outcome_fn,
        success_fn=success_fn,
        linear_terms=terms,
        extra_outcome_fn=extra_outcome_fn,
        reaches_slot=True,
        guard_fn=guard_fn,
    )


def _position_of(point: int) -> LinearTerms:
    return tuple(((point, axis, 1.0),) for axis in range(3))


def affine_slot(scale: tuple[float, float, float], offset: tuple[float, float, float]) -> SlotFn:
    """A goal slot `g * scale + offset`, computed in float32."""
    scale_arr = np.asarray(scale, dtype=np.float32)
    offset_arr = np.asarray(offset, dtype=np.float32)

    def slot(g: np.ndarray) -> np.ndarray:
        return g * scale_arr + offset_arr

    return slot


def within_distance(achieved: np.ndarray, goal_slot: np.ndarray) -> np.ndarray:
    """True where the first three outcome coordinates lie within 0.05 m of the goal slot.

    Written component by component so that the result does not depend on the batch shape.
    """
    d = achieved[..., :3] - goal_slot
    d *= d
    s = d[..., 0] + d[..., 1]
    s += d[..., 2]
    return s < _EPS2


def _gripper_away(achieved: np.ndarray) -> np.ndarray:
    """`stack`'s guard: the gripper (outcome component 4) at least 0.06 m from the goal."""
    return achieved[..., 3] >= _AWAY


def _gripper_to_stack_target(gripper: np.ndarray, cubes: np.ndarray) -> np.ndarray:
    """|gripper - stack target|, shape (..., 1); the target is one cube height above cube 2,
    where `stack`'s goal lies whatever g (the authors measured the guard from the goal)."""
    d = gripper - cubes[..., 1, :]
    d[..., 2] -= 2 * layout.CUBE_HALF_SIZE
    d *= d
    s = d[..., 0:1] + d[..., 1:2]
    s += d[..., 2:3]
    return np.sqrt(s)


# The gripper's start, the centre of the goal region of `reach` and the push modules.
_GX, _GY = (float(v) for v in layout.GRIP0[:2])
_R = layout.OBJECT_RANGE
_Z = layout.CUBE_REST_Z
_TOP = layout.TABLE_TOP_Z


def reach() -> TaskModule:
    """T1: the gripper to a 3-D target: xy = grip0 + 0.15 g_xy, z = 0.426 + 0.225 (g_z + 1)."""
    return distance_module(
        "reach",
        achievable=True,
        terms=_position_of(0),
        slot_fn=affine_slot((_R, _R, 0.225), (_GX, _GY, _Z + 0.225)),
    )


def push_cube(cube: int, *, achievable: bool) -> TaskModule:
    """T2 / T5-7: cube `cube` (1-based) to a 2-D target on the table, xy = grip0 + 0.15 g_xy."""
    if cube < 1:
        raise ValueError(f"cube numbers start at 1, got {cube}")
    return distance_module(
        f"push_cube{cube}",
        achievable=achievable,
        terms=_position_of(cube),
        slot_fn=affine_slot((_R, _R, 0.0), (_GX, _GY, _Z)),
    )


def cube1_above_cube2() -> TaskModule:
    """T3: cube 1 to a 3-D target above cube 2, 0.05..0.45 m above a resting cube's centre.

    Outcome `(x1 - x2, y1 - y2, z1)` in cube 2's frame, goal slot
    `(0, 0, 0.426 + 0.05 + 0.2 (g_z + 1))`: the authors' heights (gym_flowers
    multi_task_fetch_arm_v3.py, `height_offset + (g_z + 1.25) * 0.2`), the lowest one cube 1
    resting on cube 2.
    """
    return distance_module(
        "cube1_above_cube2",
        achievable=True,
        terms=(((1, 0, 1.0), (2, 0, -1.0)), ((1, 1, 1.0), (2, 1, -1.0)), ((1, 2, 1.0),)),
        slot_fn=affine_slot((0.0, 0.0, 0.2), (0.0, 0.0, _Z + 0.05 + 0.2)),
    )


def stack() -> TaskModule:
    """T4: cube 1 on cube 2 with the gripper away.

    Outcome `(x1 - x2, y1 - y2, z1 - z2, |gripper - target|)`, the target one cube height above
    cube 2; goal slot `(0, 0, 0.05)` whatever g; success: the first three within 0.05 of the slot
    and the gripper >= 0.06 from the target (the authors' guard, gym_flowers
    multi_task_fetch_arm_v5.py: `dgrip < 1.2 * distance_threshold` fails).
    """
    return distance_module(
        "stack",
        achievable=True,
        terms=tuple(((1, axis, 1.0), (2, axis, -1.0)) for axis in range(3)),
        extra_outcome_fn=_gripper_to_stack_target,
        extra_dim=1,
        extra_cubes=(1,),
        guard_fn=_gripper_away,
        slot_fn=affine_slot((0.0, 0.0, 0.0), (0.0, 0.0, 2 * layout.CUBE_HALF_SIZE)),
    )


def standard_modules(n_distractors: int) -> tuple[TaskModule, ...]:
    """The paper's modules: reach, push_cube1, cube1_above_cube2, stack, push_cube3.. (one per
    distractor)."""
    achievable = (reach(), push_cube(1, achievable=True), cube1_above_cube2(), stack())
    distractors = tuple(push_cube(3 + i, achievable=False) for i in range(n_distractors))
    return achievable + distractors


def perturbation_modules() -> tuple[TaskModule, ...]:
    """The modules of the authors' perturbation study (gym_flowers multi_task_fetch_arm_v3.py,
    `MultiTaskFetchArm4-v3`): reach, push_cube1, cube1_above_cube2 and push_cube3, all
    achievable (cube 3 is a third reachable cube there)."""
    return (
        reach(),
        push_cube(1, achievable=True),
        cube1_above_cube2(),
        push_cube(3, achievable=True),
    )
