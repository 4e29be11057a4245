"""Task modules: what a task watches, where its goals lie, when it succeeds.

A module is a small frozen definition (`TaskModule`): a name, whether it can be achieved, the
outcome it watches (`achieved(gripper, cubes)`), the map from a goal g in [-1, 1]^3 to its goal
slot (`goal_slot(g)`), the goal that slot stands for at a given step (`goal(slot, achieved)`),
and its success predicate and sparse reward against such goals. Every function is vectorised
over any leading batch shape and computes in float32, so that the agent's recomputed rewards on
relabelled transitions agree bit for bit with the env's step reward (the env evaluates the same
functions on the float32 outcomes and goal slots that it reports).

Outcomes and goals are world positions, as in the authors' environment (gym_flowers
multi_task_fetch_arm_v0.py, `tasks_obs_id`): the first three outcome components are the point a
goal is compared with (the gripper, or a cube), and a hindsight goal is those three numbers at a
later step (`hindsight_goal`). A module may read more: `stack` also watches the gripper (its
guard), and the modules whose goal follows cube 2 (`cube1_above_cube2`, `stack`) watch cube 2's
x and y, so that the goal of an episode can be placed at every step from its slot and the
outcome alone (`goal`): the slot is the goal with cube 2 at `goal_anchor` (the centre of its
start region), and the goal moves with cube 2's xy, as the authors' `_update_goals` moves it.

The env holds a tuple of modules; adding a module means writing one here (or anywhere) and
passing it to `MultiTaskFetch`, never editing the env.

Every module of the paper is a *distance module* (`distance_module`): its outcome starts with
components linear in the positions, possibly followed by a few computed ones, and it succeeds
when the first three components lie within 0.05 m of the goal (and, for `stack`, a guard on the
outcome and the goal holds). Declaring that structure lets the env evaluate all such modules
together, with one matrix product and one distance test per step; modules that declare nothing
are evaluated through their functions.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from suite import layout

_EPS2 = np.float32(layout.SUCCESS_DISTANCE) ** 2
_AWAY2 = np.float32(layout.STACK_GRIPPER_AWAY) ** 2
_ONE = np.float32(1.0)

SlotFn = Callable[[np.ndarray], np.ndarray]
OutcomeFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
SuccessFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
GuardFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
# One outcome component of a linear module: a sum of (point, axis, coefficient) terms, where
# point 0 is the gripper and point k >= 1 is cube k; axis 0, 1, 2 is x, y, z.
LinearTerms = tuple[tuple[tuple[int, int, float], ...], ...]
# (goal coordinate, outcome component) pairs: that goal coordinate moves with that component.
GoalFollow = tuple[tuple[int, int], ...]


@dataclass(frozen=True, eq=False)
class TaskModule:
    """One task of the multi-task env: its outcome, goal slot, goal, success and reward.

    Attributes:
        name: unique name (`reach`, `push_cube1`, ...).
        achievable: False for distractor modules (their cube is out of reach).
        outcome_dim: size of the outcome `achieved` returns.
        cubes: 0-based indices of the cubes the outcome reads (the env checks it has them).
        slot_fn: g (..., 3) float32 -> goal slot (..., 3) float32.
        outcome_fn: (gripper (..., 3), cubes (..., n, 3)) -> outcome (..., outcome_dim).
        success_fn: (outcome (..., outcome_dim), goal (..., 3)) float32 -> bool (...,), where
            the goal is a world position (`goal(slot, outcome)` or a `hindsight_goal`).
        goal_dim: size of g (3 for every module).
        linear_terms: optional structure: the first `len(linear_terms)` outcome components are
            linear in the positions, given as terms (see `LinearTerms`) ...
        extra_outcome_fn: ... and the remaining ones come from this function (same arguments
            as `outcome_fn`).
        reaches_slot: optional structure: success means "the first three outcome components lie
            within 0.05 m of the goal" ...
        guard_fn: ... and `guard_fn(outcome, goal)` holds.
        goal_follow: (goal coordinate, outcome component) pairs: during an episode that goal
            coordinate is the slot's plus how far the component has moved from `goal_anchor`
            (empty: the goal is the slot, a fixed world position).
        goal_anchor: (3,) where the followed components sit when the goal equals the slot.
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
    goal_follow: GoalFollow = ()
    goal_anchor: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for coordinate, component in self.goal_follow:
            if not (0 <= coordinate < 3 and 0 <= component < self.outcome_dim):
                raise ValueError(f"{self.name}: bad goal_follow pair {(coordinate, component)}")

    def outcome_matrix(self, n_cubes: int) -> np.ndarray | None:
        """W (len(linear_terms), 3 + 3 n_cubes) with outcome[:len(linear_terms)] =
        W @ [gripper, cube 1, ..., cube n], or None without linear terms."""
        if self.linear_terms is None:
            return None
        return _outcome_matrix(self.linear_terms, n_cubes)

    def goal_slot(self, g: np.ndarray) -> np.ndarray:
        """Map goals g (..., 3) in [-1, 1] to goal slots (..., 3), float32; pure.

        The slot is the goal in the world frame; for a module whose goal follows a cube
        (`goal_follow`), the goal when that cube sits at `goal_anchor`.
        """
        g = np.asarray(g, dtype=np.float32)
        if g.shape[-1:] != (self.goal_dim,):
            raise ValueError(
                f"{self.name}: a goal must have last dimension {self.goal_dim}, got shape {g.shape}"
            )
        return self.slot_fn(g)

    def goal(self, goal_slot: np.ndarray, achieved: np.ndarray) -> np.ndarray:
        """The goal (..., 3) float32 in the world frame that the slot stands for at the step
        where `achieved` (..., outcome_dim) was observed: the slot itself, except that the
        coordinates in `goal_follow` move with their outcome component (cube 2's xy for
        `cube1_above_cube2` and `stack`, as in the authors' env). What `success` and `reward`
        compare an episode's own goal with."""
        slot = np.asarray(goal_slot, dtype=np.float32)
        achieved = np.asarray(achieved, dtype=np.float32)
        if slot.shape[-1:] != (3,) or achieved.shape[-1:] != (self.outcome_dim,):
            raise ValueError(
                f"{self.name}: expected goal_slot (..., 3) and achieved (..., {self.outcome_dim}),"
                f" got shapes {slot.shape} and {achieved.shape}"
            )
        batch = np.broadcast_shapes(slot.shape[:-1], achieved.shape[:-1])
        out = np.array(np.broadcast_to(slot, (*batch, 3)), dtype=np.float32)
        for coordinate, component in self.goal_follow:
            anchor = np.float32(self.goal_anchor[coordinate])
            out[..., coordinate] += achieved[..., component] - anchor
        return out

    def hindsight_goal(self, achieved: np.ndarray) -> np.ndarray:
        """The goal an outcome (..., outcome_dim) achieves: its first three components, the
        part of the outcome comparable with a goal (HER relabels with it)."""
        return np.asarray(achieved, dtype=np.float32)[..., :3]

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

    def success(self, achieved: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """Whether outcomes (..., outcome_dim) meet goals (..., 3), world positions (a
        `hindsight_goal`, or `goal(slot, achieved)` for an episode's own): bool (...,)."""
        achieved = np.asarray(achieved, dtype=np.float32)
        goal = np.asarray(goal, dtype=np.float32)
        if achieved.shape[-1:] != (self.outcome_dim,) or goal.shape[-1:] != (3,):
            raise ValueError(
                f"{self.name}: expected achieved (..., {self.outcome_dim}) and goal (..., 3),"
                f" got shapes {achieved.shape} and {goal.shape}"
            )
        return self.success_fn(achieved, goal)

    def reward(self, achieved: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """Sparse reward (...,) float32: 0 where `success`, -1 elsewhere."""
        return self.success(achieved, goal).astype(np.float32) - _ONE


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
    goal_follow: GoalFollow = (),
    goal_anchor: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> TaskModule:
    """A module whose outcome is `terms` (linear in the positions) followed by `extra_dim`
    components from `extra_outcome_fn` (reading cubes `extra_cubes`, 0-based), and which
    succeeds when the first three components lie within 0.05 m of the goal (and
    `guard_fn(outcome, goal)` holds, if given); `goal_follow` and `goal_anchor` as in
    `TaskModule`."""
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

        def success_fn(achieved: np.ndarray, goal: np.ndarray) -> np.ndarray:
            return within_distance(achieved, goal) & guard(achieved, goal)

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
        goal_follow=tuple((int(c), int(k)) for c, k in goal_follow),
        goal_anchor=tuple(float(v) for v in goal_anchor),
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


def _squared_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b|^2 over the last axis (3), written component by component so that the result
    does not depend on the batch shape."""
    d = a - b
    d *= d
    s = d[..., 0] + d[..., 1]
    s += d[..., 2]
    return s


def within_distance(achieved: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """True where the first three outcome coordinates lie within 0.05 m of the goal."""
    return _squared_distance(achieved[..., :3], goal) < _EPS2


def gripper_away_from_goal(achieved: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """`stack`'s guard: the gripper (outcome components 3-5) at least 0.05 m from the goal,
    the transition's goal whatever it is (gym_flowers multi_task_fetch_arm_v0.py,
    compute_reward: `dgrip < distance_threshold` fails). A relabelled goal, a later position
    of cube 1, thus pays only once the gripper has let go of the cube and moved away."""
    return _squared_distance(achieved[..., 3:6], goal) >= _AWAY2


# The gripper's start, the centre of the goal region of `reach` and the push modules, and of
# cube 2's start region (where the goals that follow cube 2 equal their slot).
_GX, _GY = (float(v) for v in layout.GRIP0[:2])
_R = layout.OBJECT_RANGE
_Z = layout.CUBE_REST_Z
_CUBE2_XY: LinearTerms = (((2, 0, 1.0),), ((2, 1, 1.0),))


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

    Outcome `(x1, y1, z1, x2, y2)`: cube 1's world position (the part compared with goals, as
    T2's), then cube 2's xy, which the goal follows. Goal: cube 2's xy at that step, and
    z = 0.426 + 0.05 + 0.2 (g_z + 1) (gym_flowers multi_task_fetch_arm_v0.py, `_compute_goal`
    and `_update_goals`: `height_offset + (g_z + 1.25) * 0.45 / 2.25`), the lowest one cube 1
    resting on cube 2. The slot is that goal with cube 2 at grip0's xy.
    """
    return distance_module(
        "cube1_above_cube2",
        achievable=True,
        terms=_position_of(1) + _CUBE2_XY,
        slot_fn=affine_slot((0.0, 0.0, 0.2), (_GX, _GY, _Z + 0.05 + 0.2)),
        goal_follow=((0, 3), (1, 4)),
        goal_anchor=(_GX, _GY, 0.0),
    )


def stack() -> TaskModule:
    """T4: cube 1 on cube 2 with the gripper away.

    Outcome `(x1, y1, z1, xg, yg, zg, x2, y2)`: cube 1's and the gripper's world positions
    (the authors' achieved goal for stacking), then cube 2's xy, which the goal follows. Goal:
    cube 2's xy at that step and z = 0.426 + 0.05, one cube height above a resting cube,
    whatever g (gym_flowers multi_task_fetch_arm_v0.py: `height_offset + 0.05`). Success:
    cube 1 within 0.05 of the goal and the gripper at least 0.05 from the goal
    (`gripper_away_from_goal`).
    """
    return distance_module(
        "stack",
        achievable=True,
        terms=_position_of(1) + _position_of(0) + _CUBE2_XY,
        guard_fn=gripper_away_from_goal,
        slot_fn=affine_slot((0.0, 0.0, 0.0), (_GX, _GY, _Z + 2 * layout.CUBE_HALF_SIZE)),
        goal_follow=((0, 6), (1, 7)),
        goal_anchor=(_GX, _GY, 0.0),
    )


def module_index(names: Sequence[str], module: int | str) -> int:
    """Slot index of a module given by name or index among `names`, the modules in slot order;
    a ValueError that lists them otherwise (an unknown name, an index out of range, or neither)."""
    if isinstance(module, str):
        if module not in names:
            raise ValueError(f"unknown module {module!r}; known modules: {', '.join(names)}")
        return list(names).index(module)
    if isinstance(module, (int, np.integer)) and not isinstance(module, bool):
        if not 0 <= module < len(names):
            raise ValueError(
                f"module index {module} out of range: there are {len(names)} modules "
                f"({', '.join(names)})"
            )
        return int(module)
    raise ValueError(f"module must be a name or an index, got {module!r}")


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
