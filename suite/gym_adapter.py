"""A Gymnasium view of one module of the suite: a goal-conditioned env for other libraries.

`ModuleGoalEnv` exposes a single module of a registered variant as a goal-conditioned
`gymnasium.Env` (the shape of gymnasium-robotics' `GoalEnv`): a dict observation with
`observation` (the state features), `achieved_goal` (the module's outcome) and `desired_goal`
(its goal at this step, world frame: `task.goal_positions()`), and a vectorised
`compute_reward`, so that libraries built for goal-conditioned Gymnasium envs
(Stable-Baselines3's HER replay buffer, say) train on our tasks.

HER substitutes an achieved goal for the desired one, so both have the same size. For modules
whose outcome has more entries than the goal (`cube1_above_cube2` also watches cube 2's xy,
`stack` the gripper and cube 2's xy), `desired_goal` is padded with zeros and `compute_reward`
reads the goal's first three entries only: a relabelled goal (an outcome) is then the position
of the module's object at that step, a valid goal for the module, as in the authors' HER.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from suite.variants import load


class ModuleGoalEnv(gymnasium.Env):
    """One module of a suite variant as a goal-conditioned Gymnasium env.

    Args:
        variant: a registered variant name (`suite.ALL_VARIANTS`).
        module: the module to practise, by name (`push_cube1`, ...) or slot index.
        seed: seed of the env's own random draws (reset(seed=...) reseeds it).
        render_mode: None, or "rgb_array" for `render()` frames (needs a GL backend).
        **variant_kwargs: passed on to the variant.

    Each episode lasts the suite's 50 steps and is truncated, never terminated. Goals are drawn
    uniformly in the module's goal space at every reset (or given as `options={"goal": g}`,
    g in [-1, 1]^3).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 25}

    def __init__(
        self,
        variant: str = "default",
        module: str | int = "reach",
        seed: int | None = None,
        render_mode: str | None = None,
        **variant_kwargs: Any,
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self._env = load(variant, seed=seed, **variant_kwargs)
        task = self._env.task
        self._index = task.module_index(module)
        self.module = task.modules[self._index]
        self._outcome = task.outcome_slices[self._index]
        self._goal_slice = slice(3 * self._index, 3 * self._index + 3)
        self._pad = _goal_padding(self.module.outcome_dim, self.module.goal_dim)
        self._renderer = None
        self._needs_reset = True  # before the first reset and after truncation

        state_dim = task.state_layout.size
        goal_dim = self.module.outcome_dim
        action = self._env.action_spec()
        self.action_space = spaces.Box(
            low=np.broadcast_to(action.minimum, action.shape).astype(np.float32),
            high=np.broadcast_to(action.maximum, action.shape).astype(np.float32),
            dtype=np.float32,
        )
        self.observation_space = spaces.Dict(
            {
                "observation": spaces.Box(-np.inf, np.inf, (state_dim,), np.float32),
                "achieved_goal": spaces.Box(-np.inf, np.inf, (goal_dim,), np.float32),
                "desired_goal": spaces.Box(-np.inf, np.inf, (goal_dim,), np.float32),
            }
        )

    # -- the Gymnasium API ---------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start an episode of the module; `options={"goal": g}` fixes g in [-1, 1]^3."""
        super().reset(seed=seed)
        if seed is not None:
            self._env.random_state.seed(seed)
        if unknown := sorted(set(options or {}) - {"goal"}):
            raise ValueError(
                f"unknown reset option(s) {', '.join(map(repr, unknown))}; the one option is 'goal'"
            )
        goal = None if options is None else options.get("goal")
        self._env.task.set_next_episode(module=self._index, goal=goal)
        timestep = self._env.reset()
        self._needs_reset = False
        return self._observation(timestep.observation), {}

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """One control step; truncated after the suite's 50 steps. `gymnasium.error.ResetNeeded`
        before the first `reset` and after truncation (the suite would start an episode of no
        chosen module and goal)."""
        if self._needs_reset:
            raise ResetNeeded(
                "call reset() before step(): the episode has not started or was truncated"
            )
        timestep = self._env.step(action)
        obs = self._observation(timestep.observation)
        info = {"is_success": bool(timestep.observation["success"][self._index])}
        self._needs_reset = bool(timestep.last())
        return obs, float(timestep.reward), False, self._needs_reset, info

    def compute_reward(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any = None
    ) -> np.ndarray:
        """The module's sparse reward (0 on success, -1 otherwise) for any batch of goals."""
        goal = np.asarray(desired_goal, dtype=np.float32)[..., : self.module.goal_dim]
        return self.module.reward(np.asarray(achieved_goal, dtype=np.float32), goal)

    def compute_terminated(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any = None
    ) -> np.ndarray:
        """Never: suite episodes end by truncation only."""
        return np.zeros(np.shape(achieved_goal)[:-1], dtype=bool)

    def compute_truncated(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any = None
    ) -> np.ndarray:
        """Not a function of the goals: truncation comes from the episode's length."""
        return np.zeros(np.shape(achieved_goal)[:-1], dtype=bool)

    def render(self) -> np.ndarray | None:
        """An RGB frame from the suite's front camera, or None without a render mode."""
        if self.render_mode is None:
            return None
        return self._env.physics.render(height=480, width=640, camera_id="front")

    def close(self) -> None:
        """Release the physics (and its rendering context, if one was made)."""
        self._env.close()

    # -- helpers -------------------------------------------------------------------------------

    @property
    def module_index(self) -> int:
        """The module's slot index in the variant (its rows of `task.goal_positions()`)."""
        return self._index

    @property
    def suite_env(self):
        """The underlying dm_control composer environment."""
        return self._env

    def _observation(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        goal = obs["goal"][self._goal_slice]
        return {
            "observation": obs["state"].copy(),
            "achieved_goal": obs["achieved"][self._outcome].copy(),
            "desired_goal": np.concatenate([goal, self._pad]).astype(np.float32),
        }


def _goal_padding(outcome_dim: int, goal_dim: int) -> np.ndarray:
    """Zeros appended to the goal so that desired and achieved goals have one size (the reward
    reads the goal's first `goal_dim` entries only)."""
    extra = outcome_dim - goal_dim
    if extra < 0:
        raise ValueError(f"outcome ({outcome_dim}) smaller than the goal ({goal_dim})")
    return np.zeros(extra, dtype=np.float32)
