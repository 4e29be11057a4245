"""Goals as values that do not need torch: the goal part of the E-UVFA input, each module's goal
box, and the flat baseline's goal space.

`GoalInput` carries a round's or a minibatch's goals (slots, mask, task descriptor) from where
they are drawn (`curious.agent.conditions`) and relabelled (`curious.agent.replay`) to the
encoder (`curious.agent.inputs.InputEncoder`); `GoalBox` is each module's goal space as a fixed
affine box, which the encoder maps slots through; `HolisticGoals` is the `her` condition's one
goal over every module's slot at once. All numpy-only, so that the conditions (and what lists
them: validation, the command line's help) load without torch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

from curious.envs.goal_env import EnvSpec, GoalEnv

A = TypeVar("A")  # numpy arrays, or torch tensors on a device once `Agent` maps them
B = TypeVar("B")


@dataclass(frozen=True)
class GoalInput(Generic[A]):
    """The goal part of the E-UVFA input `[s_t, g, task_d]` (paper §3) of n episodes or
    transitions: what goals are drawn as (`Condition.goals`), what the policy acts on
    (`placed`, at each step), what a relabelled minibatch carries (`Transitions.goal`), and what
    `InputEncoder.encode` turns into the network's goal and task inputs. numpy arrays (float32)
    until `Agent` moves them to its device (`map`).

    * `slots` (n, N, G): the goal vector g as N module slots of G coordinates each: the goal of
      the practised module in its slot, zero elsewhere (the holistic `her` condition fills every
      slot). A slot is the raw goal position (`GoalEnv.goal_slot`); the encoder maps it into its
      module's goal box (`GoalBox`).
    * `mask` (n, N): 1 where a slot carries a goal. The encoder zeroes the other slots *after*
      scaling, so their first-layer weights get no gradient (the paper's masking). The
      practised module's one-hot; all ones in `her`.
    * `task` (n, N): the task descriptor task_d, the one-hot of the practised module; all
      zeros in `her` (one goal over every module, no task).
    """

    slots: A
    mask: A
    task: A

    @staticmethod
    def modular(slots: np.ndarray, modules: np.ndarray) -> GoalInput[np.ndarray]:
        """One module per row, `modules` (n,): its slot of `slots` (n, N, G) carries the goal
        (the others are zero), and it is the task descriptor."""
        n, n_mod = slots.shape[:2]
        task = np.zeros((n, n_mod), np.float32)
        task[np.arange(n), modules] = 1.0
        return GoalInput(slots, task.copy(), task)

    @staticmethod
    def holistic(slots: np.ndarray) -> GoalInput[np.ndarray]:
        """One goal over every slot of `slots` (n, N, G), no task descriptor (`her`)."""
        n, n_mod = slots.shape[:2]
        return GoalInput(slots, np.ones((n, n_mod), np.float32), np.zeros((n, n_mod), np.float32))

    def placed(self, env: GoalEnv, achieved: np.ndarray) -> GoalInput[np.ndarray]:
        """The goals that the slots stand for given the outcomes (n, .) of one step
        (`GoalEnv.goal`: the suite's `cube1_above_cube2` and `stack` goals follow cube 2, as the
        authors' env moves them), zero where the mask is not set: what the policy sees."""
        slots, mask = self.slots, self.mask
        goals = np.zeros_like(slots)
        rows, modules = np.nonzero(mask)
        goals[rows, modules] = env.row_goals(modules, slots[rows, modules], achieved[rows])
        return GoalInput(goals, mask, self.task)

    def map(self, fn: Callable[[A], B]) -> GoalInput[B]:
        """The same input with `fn` applied to each part (e.g. to tensors on a device)."""
        return GoalInput(fn(self.slots), fn(self.mask), fn(self.task))


@dataclass(frozen=True)
class GoalBox:
    """Per-module affine goal spaces: `goal_slot(k, g) = centre[k] + half_width[k] * g`.

    `scale` is what the encoder divides by: the half-width where the goal space spans a
    coordinate, and where it does not (push goals lie on the table, `stack` has one goal), the
    smallest half-width of the whole environment, so that hindsight outcomes that move along that
    coordinate keep a comparable scale.
    """

    centre: np.ndarray  # (N, G)
    half_width: np.ndarray  # (N, G), 0 on coordinates the goal space does not span

    @property
    def scale(self) -> np.ndarray:
        spanned = self.half_width > 0
        if not spanned.any():
            return np.ones_like(self.half_width)
        fallback = self.half_width[spanned].min()
        return np.where(spanned, self.half_width, fallback).astype(np.float32)

    @classmethod
    def of(cls, env: GoalEnv, atol: float = 1e-5) -> GoalBox:
        """Read the box off `env.goal_slot` (centre at g = 0, half-widths at the unit vectors);
        a `ValueError` if some module's map is not affine, since the encoding relies on it."""
        spec = env.spec
        n, g = spec.n_modules, spec.goal_dim
        centre = np.empty((n, g), np.float64)
        half = np.empty((n, g), np.float64)
        probe = np.random.default_rng(0).uniform(-1.0, 1.0, (16, g))
        for k in range(n):
            centre[k] = env.goal_slot(k, np.zeros(g))
            plus = np.asarray(env.goal_slot(k, np.eye(g)), np.float64)
            minus = np.asarray(env.goal_slot(k, -np.eye(g)), np.float64)
            jacobian = (plus - minus) / 2.0  # row d: the slot's change per unit of g_d
            off_diagonal = jacobian - np.diag(np.diag(jacobian))
            predicted = centre[k] + probe * np.diag(jacobian)
            actual = np.asarray(env.goal_slot(k, probe), np.float64)
            if np.abs(off_diagonal).max() > atol or np.abs(predicted - actual).max() > atol:
                raise ValueError(
                    f"module {spec.module_names[k]!r}: goal_slot is not an axis-aligned affine "
                    "map of g, which the goal encoding needs"
                )
            half[k] = np.abs(np.diag(jacobian))
        half[half < atol] = 0.0
        return cls(centre.astype(np.float32), half.astype(np.float32))


class HolisticGoals:
    """The flat baseline's goal space: one goal over every module's goal slot at once.

    A goal is (N, G): a slot per module, placed at each step as every condition's goals are
    (`place`: the suite's cube1_above_cube2 and stack goals follow cube 2). What it is compared
    with is every module's hindsight outcome (the first G numbers of its outcome,
    `EnvSpec.hindsight_columns`), and a goal is met
    when the Euclidean distance over all N x G coordinates is within `spec.success_distance`
    (gym_flowers multi_task_fetch_arm_v0.py, `compute_reward` in its flat branch:
    `-(d > distance_threshold)`). Vectorised over any leading axes.
    """

    def __init__(self, spec: EnvSpec) -> None:
        self.spec = spec
        self.columns = spec.hindsight_columns()  # (N, G)
        self.threshold = float(spec.success_distance)

    def draw(
        self, env: GoalEnv, modules: np.ndarray, raw: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """(n, N, G) goal slots: every module's drawn uniformly in [-1, 1]^G from `rng` (one
        draw over the union of the goal spaces, as the authors' flat goal), except that each
        episode's named module keeps its `raw` goal (n, G)."""
        n, n_mod, g = len(modules), self.spec.n_modules, self.spec.goal_dim
        raw_all = rng.uniform(-1.0, 1.0, (n, n_mod, g))
        raw_all[np.arange(n), modules] = raw
        goals = np.empty((n, n_mod, g), np.float32)
        for k in range(n_mod):
            goals[:, k] = env.goal_slot(k, raw_all[:, k])
        return goals

    def place(self, env: GoalEnv, slots: np.ndarray, achieved: np.ndarray) -> np.ndarray:
        """(n, N, G) the goals that slots (n, N, G) stand for given outcomes (n, achieved_dim)
        of one step (`GoalEnv.goal`: the suite's cube1_above_cube2 and stack goals follow cube
        2, as every condition's do)."""
        n, n_mod = slots.shape[:2]
        modules = np.tile(np.arange(n_mod), n)
        rows = np.repeat(np.asarray(achieved), n_mod, axis=0)
        placed = env.row_goals(modules, slots.reshape(n * n_mod, -1), rows)
        return placed.reshape(slots.shape).astype(slots.dtype, copy=False)

    def hindsight(self, achieved: np.ndarray) -> np.ndarray:
        """(..., N, G): the holistic goal that outcomes (..., achieved_dim) achieve."""
        return np.asarray(achieved)[..., self.columns]

    def distance(self, achieved: np.ndarray, goals: np.ndarray) -> np.ndarray:
        """(...,) Euclidean distance between outcomes (..., achieved_dim) and goals (..., N, G)
        over all N x G coordinates at once."""
        diff = self.hindsight(achieved) - np.asarray(goals)
        return np.sqrt(np.square(diff, dtype=np.float64).sum(axis=(-2, -1)))

    def success(self, achieved: np.ndarray, goals: np.ndarray) -> np.ndarray:
        """(...,) bool: the goal is met (distance within the threshold)."""
        return self.distance(achieved, goals) <= self.threshold

    def reward(self, achieved: np.ndarray, goals: np.ndarray) -> np.ndarray:
        """(...,) float32 sparse reward: 0 where `success`, -1 elsewhere."""
        return np.where(self.success(achieved, goals), 0.0, -1.0).astype(np.float32)
