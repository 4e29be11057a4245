"""A small multi-module goal environment in numpy, implementing `curious.envs.goal_env.GoalEnv`.

A point "hand" moves in [-1, 1]^3 (actions 0-2, 0.25 per step), a "dial" turns in [-1, 1]
(action 3, 0.25 per step) and a "beacon" drifts on its own far away. Three modules:

* `reach` (achievable): bring the hand within 0.15 of a 3-D goal in [-0.9, 0.9]^3;
* `dial` (achievable): bring the dial within 0.15 of a goal in [-0.9, 0.9] (outcome (dial, 0, 0));
* `beacon` (impossible): the beacon's goals lie in [-0.9, 0.9]^3 but it drifts in [2, 3]^3 and
  no action moves it.

Episodes last 10 steps. Everything is vectorised like the suite's modules, so replay code paths
are exercised the same way; it steps ~100k times a second, so learning tests take seconds.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from curious.envs.goal_env import EnvSpec, Obs, RowsByModule

THRESHOLD = 0.15
STEP = 0.25


class ToyGoalEnv(RowsByModule):
    """See the module docstring."""

    spec = EnvSpec(
        module_names=("reach", "dial", "beacon"),
        achievable=(True, True, False),
        state_dim=7,
        action_dim=4,
        goal_dim=3,
        outcome_slices=(slice(0, 3), slice(3, 6), slice(6, 9)),
        episode_length=10,
        success_distance=THRESHOLD,
    )

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)
        self.hand = np.zeros(3)
        self.dial = 0.0
        self.beacon = np.full(3, 2.5)
        self.module = 0
        self.goals = np.zeros((3, 3))
        self.t = 0

    def _obs(self) -> Obs:
        state = np.concatenate([self.hand, [self.dial], self.beacon]).astype(np.float32)
        achieved = np.concatenate([self.hand, [self.dial, 0.0, 0.0], self.beacon])
        return Obs(state, achieved.astype(np.float32))

    def reset(self, module: int, g: np.ndarray) -> Obs:
        self.hand = self.rng.uniform(-0.2, 0.2, 3)
        self.dial = float(self.rng.uniform(-0.2, 0.2))
        self.beacon = self.rng.uniform(2.0, 3.0, 3)
        self.module = int(module)
        raw = self.rng.uniform(-1.0, 1.0, (3, 3))
        raw[self.module] = g
        self.goals = np.stack([self.goal_slot(m, raw[m]) for m in range(3)])
        self.t = 0
        return self._obs()

    def step(self, action: np.ndarray) -> tuple[Obs, np.ndarray]:
        if self.t >= self.spec.episode_length:
            raise RuntimeError("episode is over: call reset() first")
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        self.hand = np.clip(self.hand + STEP * a[:3], -1.0, 1.0)
        self.dial = float(np.clip(self.dial + STEP * a[3], -1.0, 1.0))
        self.beacon = np.clip(self.beacon + self.rng.normal(0.0, 0.05, 3), 2.0, 3.0)
        self.t += 1
        obs = self._obs()
        success = np.array(
            [self.reward(m, obs.achieved, self.goals[m]) == 0 for m in range(3)], dtype=bool
        )
        return obs, success

    def goal_slot(self, module: int, g: np.ndarray) -> np.ndarray:
        g = np.asarray(g, dtype=np.float32)
        if module == 1:
            slot = np.zeros_like(g)
            slot[..., 0] = 0.9 * g[..., 0]
            return slot
        return 0.9 * g

    def goal(self, module: int, slot: np.ndarray, achieved: np.ndarray) -> np.ndarray:
        """The goal is the slot at every step (no goal here follows an object)."""
        batch = np.broadcast_shapes(np.shape(slot)[:-1], np.shape(achieved)[:-1])
        return np.array(np.broadcast_to(slot, (*batch, 3)), dtype=np.float32)

    def reward(self, module: int, achieved: np.ndarray, goal: np.ndarray) -> np.ndarray:
        outcome = np.asarray(achieved)[..., self.spec.outcome_slices[module]]
        distance = np.linalg.norm(outcome - np.asarray(goal), axis=-1)
        return np.where(distance < THRESHOLD, 0.0, -1.0).astype(np.float32)

    def get_rng_state(self) -> Any:
        return self.rng.bit_generator.state

    def set_rng_state(self, state: Any) -> None:
        self.rng.bit_generator.state = state


def make_toy_envs(seed: int, n: int) -> list[ToyGoalEnv]:
    """`n` independently seeded copies."""
    return [ToyGoalEnv(seed=seed * 1000 + i) for i in range(n)]
