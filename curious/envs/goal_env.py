"""The agent's view of an environment: a small array protocol, and the adapter to the suite.

The agent never touches dm_control objects: it trains on anything that implements `GoalEnv`
(the suite through `SuiteEnv`; the tests' toy env directly). Everything here is arrays:

* `reset(module, g)` starts an episode practising module `module` with goal `g` in [-1, 1]^3;
* `step(action)` returns the next `Obs` and the per-module success flags;
* `goal_slot(module, g)` maps goals in [-1, 1]^3 to the module's 3-D goal slot (vectorised),
  fixed for an episode;
* `goal(module, slot, achieved)` is the goal that slot stands for at the step where the full
  `achieved` vector (..., sum of outcome dims) was observed, in the frame of the outcomes: the
  slot itself, except in the suite's `cube1_above_cube2` and `stack`, whose goal follows cube 2's
  xy as in the authors' env (vectorised);
* `reward(module, achieved, goal)` is the module's sparse reward in {-1, 0} for full `achieved`
  vectors against goals (..., goal_dim) in the frame of the outcomes: a hindsight goal, or
  `goal(module, slot, achieved)` for an episode's own goal (never the bare slot of a module whose
  goal follows something). Vectorised over the leading axes: the replay recomputes rewards for
  whole minibatches with it.
* `row_goals(modules, slots, achieved)` and `row_rewards(modules, achieved, goals)` are the
  same row by row, each row (n, .) for its own module `modules[i]`: what a minibatch of
  transitions replayed as different modules needs, in one call (the suite's in one pass over
  all rows; `RowsByModule`, `goals_by_module` and `rewards_by_module` build them from `goal`
  and `reward` for any env).

An environment with a perturbation also offers `set_sensor_failure(on)`, which the trainer
calls before every episode of a run with a sensory failure, and `sensor_failure_module`, the name
of the module it perturbs (whose competence can start it, `Config.sensor_failure_competence`).

A hindsight goal for a module is the first `goal_dim` coordinates of its outcome (the module's
slice of `achieved`, the part comparable with its goals); see `EnvSpec.hindsight_columns`.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol, runtime_checkable

import numpy as np

import suite
from curious.config import ConfigError
from suite import layout
from suite.outcomes import ModuleEvaluator


class Obs(NamedTuple):
    """What the agent observes at one step."""

    state: np.ndarray
    """(state_dim,) float32 state features."""
    achieved: np.ndarray
    """(sum of outcome dims,) float32: every module's outcome, concatenated in module order."""


@dataclass(frozen=True)
class EnvSpec:
    """Static facts about an environment that the agent sizes itself from."""

    module_names: tuple[str, ...]
    achievable: tuple[bool, ...]
    state_dim: int
    action_dim: int
    goal_dim: int
    """Size of every module's goal slot (3 in the suite)."""
    outcome_slices: tuple[slice, ...]
    """One slice per module into the `achieved` vector."""
    episode_length: int
    success_distance: float = 0.05
    """Distance within which an outcome meets its goal (0.05 m in the suite); the holistic goal
    space of the `her` condition measures its one distance against it."""
    sensor_failure_modules: tuple[str, ...] = ()
    """Modules whose outcome the env's sensory failure perturbs (`push_cube3` in the suite's
    `sensor_failure` variant); empty for an env without one. Recorded in the run folder, where
    the recovery analysis reads which module to follow."""

    @property
    def n_modules(self) -> int:
        return len(self.module_names)

    @property
    def achieved_dim(self) -> int:
        return max(s.stop for s in self.outcome_slices)

    def hindsight_columns(self) -> np.ndarray:
        """(n_modules, goal_dim) int: columns of `achieved` that form each module's hindsight goal.

        A module whose outcome is longer than its goal (the suite's `stack` watches cube 1, the
        gripper and cube 2's xy) relabels with the first `goal_dim` numbers of its outcome.
        """
        cols = np.empty((self.n_modules, self.goal_dim), dtype=np.int64)
        for m, sl in enumerate(self.outcome_slices):
            if sl.stop - sl.start < self.goal_dim:
                raise ValueError(
                    f"module {self.module_names[m]!r}: outcome of {sl.stop - sl.start} numbers is "
                    f"shorter than its goal slot ({self.goal_dim})"
                )
            cols[m] = np.arange(sl.start, sl.start + self.goal_dim)
        return cols

    def module_index(self, module: int | str) -> int:
        """Index of a module given by index or name: the suite's rule (`suite.module_index`),
        a ValueError listing the modules otherwise."""
        return suite.module_index(self.module_names, module)


@runtime_checkable
class GoalEnv(Protocol):
    """The array protocol the agent trains on (see the module docstring)."""

    spec: EnvSpec

    def reset(self, module: int, g: np.ndarray) -> Obs: ...

    def step(self, action: np.ndarray) -> tuple[Obs, np.ndarray]: ...

    def goal_slot(self, module: int, g: np.ndarray) -> np.ndarray: ...

    def goal(self, module: int, slot: np.ndarray, achieved: np.ndarray) -> np.ndarray: ...

    def reward(self, module: int, achieved: np.ndarray, goal: np.ndarray) -> np.ndarray: ...

    def row_goals(
        self, modules: np.ndarray, slots: np.ndarray, achieved: np.ndarray
    ) -> np.ndarray: ...

    def row_rewards(
        self, modules: np.ndarray, achieved: np.ndarray, goals: np.ndarray
    ) -> np.ndarray: ...

    def get_rng_state(self) -> Any: ...

    def set_rng_state(self, state: Any) -> None: ...


def goals_by_module(
    env: GoalEnv, modules: np.ndarray, slots: np.ndarray, achieved: np.ndarray
) -> np.ndarray:
    """`GoalEnv.row_goals` from `GoalEnv.goal`, one call per module the rows name."""
    modules = np.asarray(modules)
    out = np.empty((len(modules), env.spec.goal_dim), np.float32)
    for k in np.unique(modules):
        sel = np.flatnonzero(modules == k)
        out[sel] = env.goal(int(k), slots[sel], achieved[sel])
    return out


def rewards_by_module(
    env: GoalEnv, modules: np.ndarray, achieved: np.ndarray, goals: np.ndarray
) -> np.ndarray:
    """`GoalEnv.row_rewards` from `GoalEnv.reward`, one call per module the rows name."""
    modules = np.asarray(modules)
    out = np.empty(len(modules), np.float32)
    for k in np.unique(modules):
        sel = np.flatnonzero(modules == k)
        out[sel] = env.reward(int(k), achieved[sel], goals[sel])
    return out


class RowsByModule:
    """`row_goals` and `row_rewards` from an env's own `goal` and `reward`, one call per module
    the rows name: for an env without a route over all rows at once."""

    def row_goals(self, modules: np.ndarray, slots: np.ndarray, achieved: np.ndarray) -> np.ndarray:
        return goals_by_module(self, modules, slots, achieved)  # type: ignore[arg-type]

    def row_rewards(
        self, modules: np.ndarray, achieved: np.ndarray, goals: np.ndarray
    ) -> np.ndarray:
        return rewards_by_module(self, modules, achieved, goals)  # type: ignore[arg-type]


class SuiteEnv:
    """A `suite` environment (dm_control composer) seen through the `GoalEnv` protocol.

    Uses only the suite's public interface: `suite.load`, `env.task.modules`,
    `env.task.set_next_episode`, `env.reset`, `env.step`, each module's vectorised
    `goal_slot`, `goal` and `reward`, and `suite.outcomes.ModuleEvaluator` for all modules'
    goals and rewards row by row.
    """

    EPISODE_LENGTH = 50
    """Steps per episode in every suite variant (episodes never end early)."""

    def __init__(self, variant: str = "default", seed: int = 0) -> None:
        if variant not in suite.ALL_VARIANTS:
            raise ConfigError(
                f"unknown suite variant {variant!r}; variants: {', '.join(suite.ALL_VARIANTS)}"
            )
        self._env = suite.load(variant, seed=seed)
        self._task = self._env.task
        self._modules = tuple(self._task.modules)
        self._evaluator = ModuleEvaluator(self._modules, self._task.n_cubes)
        timestep = self._env.reset()
        obs = timestep.observation
        slices, start = [], 0
        for module in self._modules:
            slices.append(slice(start, start + int(module.outcome_dim)))
            start += int(module.outcome_dim)
        if start != obs["achieved"].shape[-1]:
            raise ValueError(
                f"suite reports {obs['achieved'].shape[-1]} outcome numbers, "
                f"modules declare {start}"
            )
        self.spec = EnvSpec(
            module_names=tuple(m.name for m in self._modules),
            achievable=tuple(bool(m.achievable) for m in self._modules),
            state_dim=int(obs["state"].shape[-1]),
            action_dim=int(self._env.action_spec().shape[0]),
            goal_dim=int(self._modules[0].goal_dim),
            outcome_slices=tuple(slices),
            episode_length=self.EPISODE_LENGTH,
            success_distance=float(layout.SUCCESS_DISTANCE),
            sensor_failure_modules=tuple(self._task.sensor_failure_modules),
        )
        self._t = 0

    @property
    def dm_env(self) -> Any:
        """The wrapped composer environment (for rendering and recording)."""
        return self._env

    @staticmethod
    def _obs(observation: dict[str, np.ndarray]) -> Obs:
        return Obs(
            np.asarray(observation["state"], dtype=np.float32),
            np.asarray(observation["achieved"], dtype=np.float32),
        )

    def _index(self, module: int | str) -> int:
        """A module's slot from its index or name (`EnvSpec.module_index`): a ValueError
        listing the modules for any other, where an index of -1 would wrap to the last."""
        if isinstance(module, int | np.integer) and 0 <= module < len(self._modules):
            return int(module)
        return self.spec.module_index(module)

    def _check_rows(self, modules: np.ndarray) -> np.ndarray:
        """`modules` as an array of slots; a ValueError naming the first out of range."""
        modules = np.asarray(modules)
        bad = (modules < 0) | (modules >= len(self._modules))
        if bad.any():
            self._index(int(modules[bad][0]))  # raises, listing the modules
        return modules

    def reset(self, module: int | str, g: np.ndarray) -> Obs:
        index = self._index(module)
        self._task.set_next_episode(module=index, goal=np.asarray(g, dtype=np.float64))
        self._t = 0
        return self._obs(self._env.reset().observation)

    def step(self, action: np.ndarray) -> tuple[Obs, np.ndarray]:
        if self._t >= self.spec.episode_length:
            raise RuntimeError("episode is over: call reset() first")
        timestep = self._env.step(np.asarray(action, dtype=np.float64))
        self._t += 1
        if timestep.last() != (self._t == self.spec.episode_length):
            raise RuntimeError(
                f"suite episode ended at step {self._t}, expected {self.spec.episode_length}"
            )
        obs = timestep.observation
        return self._obs(obs), np.asarray(obs["success"]) > 0.5

    def goal_slot(self, module: int | str, g: np.ndarray) -> np.ndarray:
        module = self._index(module)
        return np.asarray(self._modules[module].goal_slot(np.asarray(g)), dtype=np.float32)

    def goal(self, module: int | str, slot: np.ndarray, achieved: np.ndarray) -> np.ndarray:
        module = self._index(module)
        outcome = np.asarray(achieved)[..., self.spec.outcome_slices[module]]
        return self._modules[module].goal(np.asarray(slot), outcome)

    def reward(self, module: int | str, achieved: np.ndarray, goal: np.ndarray) -> np.ndarray:
        module = self._index(module)
        outcome = np.asarray(achieved)[..., self.spec.outcome_slices[module]]
        return np.asarray(self._modules[module].reward(outcome, np.asarray(goal)), np.float32)

    def row_goals(self, modules: np.ndarray, slots: np.ndarray, achieved: np.ndarray) -> np.ndarray:
        return self._evaluator.row_goals(
            self._check_rows(modules),
            np.asarray(slots, np.float32),
            np.asarray(achieved, np.float32),
        )

    def row_rewards(
        self, modules: np.ndarray, achieved: np.ndarray, goals: np.ndarray
    ) -> np.ndarray:
        success = self._evaluator.row_success(
            self._check_rows(modules),
            np.asarray(achieved, np.float32),
            np.asarray(goals, np.float32),
        )
        return success.astype(np.float32) - np.float32(1.0)

    def set_sensor_failure(self, on: bool) -> None:
        """Switch the variant's sensory failure for the episodes that follow (the suite's
        `task.set_sensor_failure`); a `ConfigError` on a variant that has none."""
        if not self._task.has_sensor_failure:
            raise ConfigError(
                "this suite variant has no sensory failure: use the 'sensor_failure' variant "
                "with sensor_failure_episode or sensor_failure_competence"
            )
        self._task.set_sensor_failure(on)

    @property
    def sensor_failure_module(self) -> str | None:
        """Name of the module whose outcome the variant's sensory failure perturbs."""
        return self._task.sensor_failure_module

    def get_rng_state(self) -> Any:
        return self._env.random_state.get_state()

    def set_rng_state(self, state: Any) -> None:
        self._env.random_state.set_state(state)


@functools.cache
def suite_sensor_failure_modules(variant: str) -> tuple[str, ...]:
    """The modules the sensory failure of a suite variant perturbs, from the variant's own
    definition (the task it builds); empty for a variant without one, or one the suite does not
    know. For run folders written before config.json recorded them (`EnvSpec`)."""
    with warnings.catch_warnings():  # MuJoCo's GL probing warns where nothing renders
        warnings.simplefilter("ignore")

        if variant not in suite.ALL_VARIANTS:
            return ()
        return tuple(suite.load(variant, seed=0).task.sensor_failure_modules)


def suite_env_fns(variant: str, seed: int, n: int, stream: int = 0) -> list[Callable[[], SuiteEnv]]:
    """Picklable constructors of `n` independent copies of a suite variant, seeded from one run
    seed; `stream` 1 gives the test rollouts' copies, independent of the training ones (0)."""
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"n, the number of copies, must be an integer >= 1, got {n!r}")
    key = [seed, 0xE27] if stream == 0 else [seed, 0xE27, stream]
    seeds = np.random.SeedSequence(key).generate_state(n)
    return [functools.partial(SuiteEnv, variant, seed=int(s)) for s in seeds]


def make_suite_envs(variant: str, seed: int, n: int, stream: int = 0) -> list[SuiteEnv]:
    """The copies of `suite_env_fns`, built in this process."""
    return [fn() for fn in suite_env_fns(variant, seed, n, stream)]
