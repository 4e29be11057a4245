"""The E-UVFA input: [normalised state, masked scaled goal vector, task descriptor].

`GoalInput` is the goal part (slots, mask, task descriptor) as one value, from where goals are
drawn (`curious.agent.conditions`) and relabelled (`curious.agent.replay`) to `InputEncoder`, which
builds the network input from it.

The goal vector has one 3-D slot per module. Modular conditions fill only the practised module's
slot and set the one-hot task descriptor; the holistic `her` condition fills every slot and leaves
the descriptor at zero. Inactive slots are zero *after* scaling, so that their first-layer weights
receive no gradient (the masking of paper §3).

States are normalised with running statistics (mean and std of every step's state, the OpenAI
Baselines rule, clip 5). Goals are not: each module's goal space is a known box (the module maps
g in [-1, 1]^3 affinely into it), and a slot is fed to the networks as its coordinates in that box,
`(slot - centre) / half_width`, a fixed map (`GoalBox`). A goal anywhere in the goal space gives
the g it was drawn from: distinct goals give distinct inputs, none clipped, from the first cycle of
a run to its last. Hindsight goals outside the box (a cube pushed far) get values beyond 1, clipped
at `norm_clip` half-widths.

Why not running statistics for goals: taken from every step's hindsight outcome (where relabelled
goals come from) they follow cubes that mostly rest on the table, whose spread is tiny; then goals
of `cube1_above_cube2` at different heights all encoded to the clip value. The authors' release
trained without any normalisation (`--normalize_obs` defaults to False in its train.py), which
keeps goals distinct too; the fixed map keeps that property and gives inputs of unit scale.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np
import torch

from curious.agent.normalizer import RunningNormalizer, device_copies
from curious.envs.goal_env import EnvSpec, GoalEnv

A = TypeVar("A", np.ndarray, torch.Tensor)
B = TypeVar("B", np.ndarray, torch.Tensor)


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
        for k in np.flatnonzero(mask.any(axis=0)):
            rows = np.flatnonzero(mask[:, k])
            goals[rows, k] = env.goal(int(k), slots[rows, k], achieved[rows])
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


class InputEncoder:
    """Owns the state normaliser and the goal map; builds network inputs from raw arrays."""

    def __init__(
        self, spec: EnvSpec, goal_box: GoalBox, norm_eps: float = 0.01, norm_clip: float = 5.0
    ) -> None:
        self.spec = spec
        self.state_norm = RunningNormalizer((spec.state_dim,), eps=norm_eps, clip=norm_clip)
        expected = (spec.n_modules, spec.goal_dim)
        if goal_box.centre.shape != expected or goal_box.half_width.shape != expected:
            raise ValueError(f"goal box of shape {goal_box.centre.shape}, spec needs {expected}")
        self.goal_box = goal_box
        self.clip = float(norm_clip)
        self._goal_centre = goal_box.centre.astype(np.float32)
        self._goal_scale = goal_box.scale
        self._torch: dict[str, tuple[torch.Tensor, ...]] = {}
        n, g = spec.n_modules, spec.goal_dim
        self.input_dim = spec.state_dim + n * g + n

    def update_stats(self, states: np.ndarray) -> None:
        """Add the states of a batch of episodes, (E, T+1, S), to the state statistics."""
        self.state_norm.update(states.reshape(-1, self.spec.state_dim))

    def encode_goals(self, goal: GoalInput[torch.Tensor]) -> torch.Tensor:
        """(B, N * G) network goal inputs: each slot's coordinates in its module's goal box,
        clipped, zero where the mask is not set."""
        slots = goal.slots
        centre, scale = device_copies(
            self._torch, slots.device, self._goal_centre, self._goal_scale
        )
        scaled = torch.clamp((slots - centre) / scale, -self.clip, self.clip)
        return (scaled * goal.mask.unsqueeze(-1)).flatten(1)

    def encode(self, state: torch.Tensor, goal: GoalInput[torch.Tensor]) -> torch.Tensor:
        """(B, input_dim) `[s_t, g, task_d]` from states (B, S) and their goal input."""
        s = self.state_norm.normalize(state)
        return torch.cat([s, self.encode_goals(goal), goal.task], dim=1)

    def encode_pair(
        self, state: torch.Tensor, next_state: torch.Tensor, goal: GoalInput[torch.Tensor]
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """`encode` of a transition's two states with one goal part (half the work)."""
        n = state.shape[0]
        s = self.state_norm.normalize(torch.cat([state, next_state]))
        g = self.encode_goals(goal)
        task = goal.task
        return torch.cat([s[:n], g, task], dim=1), torch.cat([s[n:], g, task], dim=1)

    def state_dict(self) -> dict:
        return {"state": self.state_norm.state_dict()}

    def load_state_dict(self, state: dict) -> None:
        self.state_norm.load_state_dict(state["state"])
