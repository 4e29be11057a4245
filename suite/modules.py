"""Task modules: what a task watches, how its goals map into the workspace, when it succeeds.

A module is a small frozen definition (`TaskModule`): a name, whether it can be achieved, the
outcome it watches (`achieved(gripper, cubes)`), the map from a goal g in [-1, 1]^3 to its goal
slot (`goal_slot(g)`), and its success predicate and sparse reward. Every function is vectorised
over any leading batch shape and computes in float32, so that the agent's recomputed rewards on
relabelled transitions agree bit for bit with the env's step reward (the env evaluates the same
functions on the float32 outcomes and goal slots that it reports).

The env holds a tuple of modules; adding a module means writing one here (or anywhere) and
passing it to `MultiTaskFetch`, never editing the env.

Most outcomes are linear in the positions (a cube's position, a difference of two). Such a
module lists its outcome as `linear_terms`; its `outcome_fn` is then derived from them, and the
env evaluates all linear modules together with one matrix product per step.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from suite import layout

_EPS2 = np.float32(layout.SUCCESS_DISTANCE) ** 2
_AWAY = np.float32(layout.SUCCESS_DISTANCE)
_ONE = np.float32(1.0)

SlotFn = Callable[[np.ndarray], np.ndarray]
OutcomeFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
SuccessFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
# One outcome component of a linear module: a sum of (point, axis, coefficient) terms, where
# point 0 is the gripper and point k >= 1 is cube k; axis 0, 1, 2 is x, y, z.
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
        linear_terms: for an outcome linear in the positions, its components as terms (see
            `LinearTerms`); `outcome_fn` must then be `linear_outcome(linear_terms)`.
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

    def outcome_matrix(self, n_cubes: int) -> np.ndarray | None:
        """W (outcome_dim, 3 + 3 n_cubes) with outcome = W @ [gripper, cube 1, ...], or None
        for an outcome that is not linear in the positions."""
        if self.linear_terms is None:
            return None
        return _outcome_matrix(self.linear_terms, n_cubes)

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
    """The outcome function of a module whose outcome is linear in the positions."""

    def outcome(gripper: np.ndarray, cubes: np.ndarray) -> np.ndarray:
        n = cubes.shape[-2]
        points = np.concatenate((gripper[..., None, :], cubes), axis=-2)
        flat = points.reshape(*points.shape[:-2], 3 + 3 * n)
        return flat @ _outcome_matrix(terms, n).T

    return outcome


def _cubes_in(terms: LinearTerms) -> tuple[int, ...]:
    return tuple(sorted({point - 1 for component in terms for point, _, _ in component if point}))


def linear_module(
    name: str, *, achievable: bool, terms: LinearTerms, slot_fn: SlotFn, success_fn: SuccessFn
) -> TaskModule:
    """A module whose outcome is linear in the positions, given by its terms."""
    terms = tuple(tuple(tuple(t) for t in component) for component in terms)
    return TaskModule(
        name=name,
        achievable=achievable,
        outcome_dim=len(terms),
        cubes=_cubes_in(terms),
        slot_fn=slot_fn,
        outcome_fn=linear_outcome(terms),
        success_fn=success_fn,
        linear_terms=terms,
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
    d = d * d
    return d[..., 0] + d[..., 1] + d[..., 2] < _EPS2


def _placed_and_released(achieved: np.ndarray, goal_slot: np.ndarray) -> np.ndarray:
    return within_distance(achieved, goal_slot) & (achieved[..., 3] >= _AWAY)


# The gripper's start, the centre of the goal region of `reach` and the push modules.
_GX, _GY = (float(v) for v in layout.GRIP0[:2])
_R = layout.OBJECT_RANGE
_Z = layout.CUBE_REST_Z
_TOP = layout.TABLE_TOP_Z


def reach() -> TaskModule:
    """T1: the gripper to a 3-D target: xy = grip0 + 0.15 g_xy, z = 0.426 + 0.225 (g_z + 1)."""
    return linear_module(
        "reach",
        achievable=True,
        terms=_position_of(0),
        slot_fn=affine_slot((_R, _R, 0.225), (_GX, _GY, _Z + 0.225)),
        success_fn=within_distance,
    )


def push_cube(cube: int, *, achievable: bool) -> TaskModule:
    """T2 / T5-7: cube `cube` (1-based) to a 2-D target on the table, xy = grip0 + 0.15 g_xy."""
    if cube < 1:
        raise ValueError(f"cube numbers start at 1, got {cube}")
    return linear_module(
        f"push_cube{cube}",
        achievable=achievable,
        terms=_position_of(cube),
        slot_fn=affine_slot((_R, _R, 0.0), (_GX, _GY, _Z)),
        success_fn=within_distance,
    )


def cube1_above_cube2() -> TaskModule:
    """T3: cube 1 to a 3-D target above cube 2, 0.05..0.45 m above the table.

    Outcome `(x1 - x2, y1 - y2, z1)` in cube 2's frame, goal slot `(0, 0, 0.45 + 0.2 (g_z + 1))`.
    """
    return linear_module(
        "cube1_above_cube2",
        achievable=True,
        terms=(((1, 0, 1.0), (2, 0, -1.0)), ((1, 1, 1.0), (2, 1, -1.0)), ((1, 2, 1.0),)),
        slot_fn=affine_slot((0.0, 0.0, 0.2), (0.0, 0.0, _TOP + 0.05 + 0.2)),
        success_fn=within_distance,
    )


def _stack_outcome(gripper: np.ndarray, cubes: np.ndarray) -> np.ndarray:
    c1 = cubes[..., 0, :]
    d = gripper - c1
    d *= d
    away = np.sqrt(d[..., 0:1] + d[..., 1:2] + d[..., 2:3])
    return np.concatenate((c1 - cubes[..., 1, :], away), axis=-1)


def stack() -> TaskModule:
    """T4: cube 1 on cube 2 with the gripper away.

    Outcome `(x1 - x2, y1 - y2, z1 - z2, |gripper - cube1|)`; goal slot `(0, 0, 0.05)` whatever
    g; success: the first three within 0.05 of the slot and the gripper >= 0.05 from cube 1.
    """
    return TaskModule(
        name="stack",
        achievable=True,
        outcome_dim=4,
        cubes=(0, 1),
        slot_fn=affine_slot((0.0, 0.0, 0.0), (0.0, 0.0, 2 * layout.CUBE_HALF_SIZE)),
        outcome_fn=_stack_outcome,
        success_fn=_placed_and_released,
    )


def standard_modules(n_distractors: int) -> tuple[TaskModule, ...]:
    """The paper's modules: reach, push_cube1, cube1_above_cube2, stack, push_cube3.. (one per
    distractor)."""
    achievable = (reach(), push_cube(1, achievable=True), cube1_above_cube2(), stack())
    distractors = tuple(push_cube(3 + i, achievable=False) for i in range(n_distractors))
    return achievable + distractors
