"""`ThreadedEnvs`: suite copies whose physics steps together in MuJoCo's native threads, the task
logic around it vectorised over the copies (an `EnvBatch`, `curious.envs.batch`).

The copies may belong to different runs of one variant (one `EnvSpec`): each keeps its own
random state, draws its own resets and distractor walks, and gets the same observations and
successes as the same copy stepped by `LocalEnvs`, bit for bit (`tests/test_threaded_envs.py`
checks every variant). How a step is split between Python and native threads is the suite's
`suite.lockstep_task`: per copy, only the reset (once per episode, the suite's own) and a rare
redraw of a distractor's move; the actions, the distractors' walk, the observation, outcomes
and successes of all copies in numpy; the physics of all copies in one call on `threads`
threads that do not hold the GIL.

The batch owns its copies: their own `step` must not be used while it holds them. Observers get
the copies themselves (`observed`), whose MuJoCo state is copied from the batch's after every
reset and step, for the watched copies only.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Sequence
from typing import Any

import numpy as np

from curious.envs.goal_env import GoalEnv
from curious.envs.lockstep import Group, Observations


class ThreadedEnvs:
    """Suite copies (`SuiteEnv`s of one `EnvSpec`) stepped on `threads` native threads (default:
    every CPU)."""

    def __init__(self, envs: Sequence[GoalEnv], threads: int | None = None) -> None:
        from suite.lockstep_task import LockstepTask  # MuJoCo only where the suite is used

        self.envs = list(envs)
        if not self.envs:
            raise ValueError("no environment copies")
        self.reference = self.envs[0]
        self.spec = self.reference.spec
        if any(env.spec != self.spec for env in self.envs):
            raise ValueError("all environment copies must share one EnvSpec")
        missing = [i for i, env in enumerate(self.envs) if not hasattr(env, "dm_env")]
        if missing:
            raise TypeError(
                f"copies {missing} are not suite environments (SuiteEnv): only the suite's "
                "physics can be stepped in threads"
            )
        if threads is None:
            threads = os.cpu_count() or 1
        self._lockstep = LockstepTask([env.dm_env for env in self.envs], threads)
        self.threads = self._lockstep.physics.nthread
        self._steps = np.full(len(self.envs), -1)  # steps taken this episode; -1: never reset
        self._watched: list[int] = []

    def __len__(self) -> int:
        return len(self.envs)

    @property
    def lockstep(self) -> Any:
        """The suite's `LockstepTask` stepping the copies (its `physics`: the MuJoCo batch)."""
        return self._lockstep

    def reset(self, modules: np.ndarray, goals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each of the first len(modules) copies resets itself (its suite environment), then the
        batch takes its state."""
        n = len(modules)
        if not 0 < n <= len(self):
            raise ValueError(f"can reset 1..{len(self)} copies, got {n}")
        obs = [env.reset(int(m), g) for env, m, g in zip(self.envs, modules, goals, strict=False)]
        self._lockstep.load(range(n))
        self._steps[:n] = 0
        return np.stack([o.state for o in obs]), np.stack([o.achieved for o in obs])

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Step the first len(actions) copies together."""
        actions = np.asarray(actions)
        expected = (self.spec.action_dim,)
        if actions.ndim != 2 or actions.shape[1:] != expected or not 0 < len(actions) <= len(self):
            raise ValueError(
                f"actions must have shape (n, {self.spec.action_dim}) with n in 1..{len(self)}, "
                f"got {actions.shape}"
            )
        n = len(actions)
        steps = self._steps[:n]
        if np.any(steps < 0) or np.any(steps >= self.spec.episode_length):
            over = np.flatnonzero((steps < 0) | (steps >= self.spec.episode_length))
            raise RuntimeError(f"copies {over.tolist()}: episode is over, call reset() first")
        states, achieved, success = self._lockstep.step(actions)
        steps += 1
        self._sync(n)
        return states, achieved, success

    def _sync(self, n: int) -> None:
        for i in self._watched:
            if i < n:
                self._lockstep.sync(i)

    def set_sensor_failure(self, on: np.ndarray) -> None:
        for env, flag in zip(self.envs, on, strict=False):
            env.set_sensor_failure(bool(flag))

    def observed(self, indices: Sequence[int]) -> list[Any]:
        """The copies; the watched ones carry the batch's MuJoCo state from now on."""
        self._watched = sorted(int(i) for i in indices)
        for i in self._watched:
            if self._steps[i] > 0:
                self._lockstep.sync(i)
        return list(self.envs)

    def get_rng_states(self) -> list[Any]:
        return [env.get_rng_state() for env in self.envs]

    def set_rng_states(self, states: Sequence[Any]) -> None:
        if len(states) != len(self):
            raise ValueError(f"{len(states)} random states for {len(self)} copies")
        for env, state in zip(self.envs, states, strict=True):
            env.set_rng_state(state)

    def close(self) -> None:
        """Release the physics' threads; the batch cannot step after."""
        self._lockstep.close()


class ThreadedPhysics:
    """The physics of a population's suite copies (one variant), for `curious.envs.lockstep`:
    every lockstep call steps the copies of all its lanes in one `LockstepTask` call on native
    threads, whichever copies of the whole set they are.

    A lane's copies reset themselves in the lane's thread (`loaded` notes them); their states
    enter the physics at the next call, which is the only place the physics is touched, so
    that one call runs at a time (the lockstep sees to it). Copies an observer watches have
    their own simulator brought up to date after each call that steps them.
    """

    def __init__(self, envs: Sequence[GoalEnv], threads: int | None = None) -> None:
        batch = ThreadedEnvs(envs, threads)  # checks the copies: suite ones, one variant
        self.task = batch.lockstep
        self.threads = batch.threads
        self._index = {id(env): i for i, env in enumerate(batch.envs)}
        self._pending: set[int] = set()
        self._watched: set[int] = set()
        self._lock = threading.Lock()  # lanes note resets and watches from their threads

    def _ids(self, copies: Sequence[GoalEnv]) -> list[int]:
        try:
            return [self._index[id(env)] for env in copies]
        except KeyError:
            raise ValueError("a copy that this physics was not built with") from None

    def loaded(self, copies: Sequence[GoalEnv]) -> None:
        """`copies` were just reset by their own environment: the next call starts them there."""
        with self._lock:
            self._pending.update(self._ids(copies))

    def watch(self, copies: Sequence[GoalEnv]) -> None:
        """Keep the simulators of `copies` up to date (an observer reads them)."""
        with self._lock:
            self._watched.update(self._ids(copies))

    def step(self, groups: Sequence[Group]) -> list[Observations | BaseException]:
        """Step every group's copies with its actions in one call; a failure of the physics (a
        diverging copy) is every group's error."""
        ids = [self._ids(copies) for copies, _ in groups]
        flat = np.concatenate([np.asarray(i, np.intp) for i in ids])
        with self._lock:
            pending = sorted(self._pending)
            self._pending.clear()
            watched = self._watched & set(flat.tolist())
        try:
            if pending:
                self.task.load(pending)
            out = self.task.step(np.concatenate([a for _, a in groups]), flat)
            for i in sorted(watched):
                self.task.sync(i)
        except Exception as error:
            return [error] * len(groups)
        split = np.cumsum([len(i) for i in ids])[:-1]
        parts = [np.split(part, split) for part in out]
        return [(s, a, ok) for s, a, ok in zip(*parts, strict=True)]

    def close(self) -> None:
        """Release the physics' threads."""
        self.task.close()
