"""Several runs' environment copies stepped together: the physics of a population in one call.

A population trains several runs in one process, each run's loop in a thread of its own
(`curious.runs.population`). Each run steps its copies through a `Lane`, an `EnvBatch` like
any other, so the run's code is the single run's. What the lanes share is a `Lockstep`: a lane
that steps hands its actions in and waits; once every lane that is in a round has handed its
actions in, one call steps all their copies, and each lane gets its own copies' observations
back, or the error its own copies raised. A lane between rounds (its run is updating, writing a
checkpoint, or done) is not waited for: the others go on without it. What steps the copies is
the lockstep's `SharedPhysics`: `OneByOne` (one after the other, as `LocalEnvs`), or
`curious.envs.threaded.ThreadedPhysics` (the suite's copies of one variant in one call on
MuJoCo's native threads).

Each copy's next state depends only on that copy and its action, so which lanes share a call
changes no observation: a run steps exactly as it would alone (a test checks, episode for
episode). A run whose thread fails leaves its lanes (`Lane.leave`), so that the others never
wait for it.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

from curious.envs.batch import LocalEnvs
from curious.envs.goal_env import EnvSpec, GoalEnv

Observations = tuple[np.ndarray, np.ndarray, np.ndarray]
"""(states, achieved, per-module success) of the copies stepped, in their order."""
Group = tuple[Sequence[GoalEnv], np.ndarray]
"""A lane's copies to step in a call, and their actions (len(copies), A)."""


class SharedPhysics(Protocol):
    """What steps the copies of a lockstep's calls (one call at a time)."""

    def loaded(self, copies: Sequence[GoalEnv]) -> None:
        """`copies` were just reset by their own environment (in a lane's thread)."""
        ...

    def watch(self, copies: Sequence[GoalEnv]) -> None:
        """An observer reads the simulators of `copies`: keep them up to date."""
        ...

    def step(self, groups: Sequence[Group]) -> list[Observations | BaseException]:
        """Step every group's copies with its actions; for each group, its observations, or
        the error that stopped its copies."""
        ...

    def close(self) -> None: ...


class OneByOne:
    """The copies stepped one after the other in the calling thread, each by itself (what
    `LocalEnvs` does): a group's failure leaves the other groups alone."""

    def loaded(self, copies: Sequence[GoalEnv]) -> None:
        """Nothing to do: the copies step themselves."""

    def watch(self, copies: Sequence[GoalEnv]) -> None:
        """Nothing to do: the copies' simulators are the ones that step."""

    def step(self, groups: Sequence[Group]) -> list[Observations | BaseException]:
        out: list[Observations | BaseException] = []
        for copies, actions in groups:
            try:
                out.append(LocalEnvs(copies).step(actions))
            except Exception as error:  # that run's copies failed; the others step on
                out.append(error)
        return out

    def close(self) -> None:
        """Nothing to release."""


class Lockstep:
    """Collects the steps of the lanes in a round and makes them one call (module docstring)."""

    def __init__(self, physics: SharedPhysics | None = None) -> None:
        self.physics: SharedPhysics = physics if physics is not None else OneByOne()
        self._cond = threading.Condition()
        self._acting: set[Lane] = set()  # in a round, computing their next actions
        self._waiting: dict[Lane, tuple[np.ndarray, bool]] = {}  # actions handed in, last step?
        self._done: dict[Lane, Observations | BaseException] = {}
        self._stepping = False  # one physics call at a time
        self.calls = 0
        """Physics calls made (each stepping the copies of every lane waiting then)."""
        self.copies_stepped = 0

    def lane(self, copies: Sequence[GoalEnv]) -> Lane:
        """A run's view of its copies: an `EnvBatch` whose steps go through this lockstep."""
        return Lane(self, copies)

    # the lanes' side ------------------------------------------------------------------------
    def _enter(self, lane: Lane) -> None:
        with self._cond:
            self._acting.add(lane)

    def _leave(self, lane: Lane) -> None:
        with self._cond:
            self._acting.discard(lane)
            self._waiting.pop(lane, None)
            self._done.pop(lane, None)
            self._step_if_all_waiting()

    def _step(self, lane: Lane, actions: np.ndarray, last: bool) -> Observations:
        """Hand in `lane`'s actions and wait for its copies' observations; `last`: the round
        ends with this step (the lane is then no longer waited for)."""
        with self._cond:
            if lane not in self._acting:
                raise RuntimeError("a lane stepped outside a round: reset it first")
            self._acting.discard(lane)
            self._waiting[lane] = (actions, last)
            self._step_if_all_waiting()
            while lane not in self._done:
                self._cond.wait()
            out = self._done.pop(lane)
        if isinstance(out, BaseException):
            raise out
        return out

    def _step_if_all_waiting(self) -> None:
        """With the condition held: when no lane in a round is still computing its actions,
        step every waiting lane's copies in one call and hand each lane its observations. The
        condition is released during the call, so that lanes may start rounds meanwhile;
        the lanes of the call are back among those computing (unless their round ended) before
        anyone is woken, so the next call waits for them."""
        if self._stepping or self._acting or not self._waiting:
            return
        batch = list(self._waiting.items())
        self._waiting.clear()
        groups = [(lane.copies[: len(a)], a) for lane, (a, _) in batch]
        self._stepping = True
        self._cond.release()
        try:
            outs = self.physics.step(groups)
        except BaseException as error:  # beyond any one run's copies: every lane gets it
            outs = [error] * len(batch)
        finally:
            self._cond.acquire()
            self._stepping = False
        self.calls += 1
        self.copies_stepped += sum(len(copies) for copies, _ in groups)
        for (lane, (_, last)), out in zip(batch, outs, strict=True):
            self._done[lane] = out
            if not last and not isinstance(out, BaseException):
                self._acting.add(lane)
        self._cond.notify_all()
        self._step_if_all_waiting()  # lanes that handed in their actions during the call


class Lane:
    """One run's copies, stepped through a `Lockstep` (an `EnvBatch`, `curious.envs.batch`)."""

    def __init__(self, lockstep: Lockstep, copies: Sequence[GoalEnv]) -> None:
        self.lockstep = lockstep
        self.local = LocalEnvs(copies)
        self.copies = self.local.envs
        self.reference = self.local.reference
        self.spec: EnvSpec = self.local.spec
        self._steps_left = 0

    def __len__(self) -> int:
        return len(self.copies)

    def reset(self, modules: np.ndarray, goals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Start a round in the first len(modules) copies (reset here, in the run's thread)."""
        out = self.local.reset(modules, goals)
        self.lockstep.physics.loaded(self.copies[: len(modules)])
        self._steps_left = self.spec.episode_length
        self.lockstep._enter(self)
        return out

    def step(self, actions: np.ndarray) -> Observations:
        if self._steps_left <= 0:
            raise RuntimeError("a lane stepped past its round's last step: reset it first")
        actions = np.asarray(actions)
        if (
            actions.ndim != 2
            or len(actions) > len(self)
            or actions.shape[1] != self.spec.action_dim
        ):
            raise ValueError(
                f"actions of shape {actions.shape}: need (n <= {len(self)}, {self.spec.action_dim})"
            )
        self._steps_left -= 1
        try:
            return self.lockstep._step(self, actions, last=self._steps_left == 0)
        except BaseException:
            self.leave()
            raise

    def leave(self) -> None:
        """Stop being waited for (a round given up: the run's thread failed or stopped)."""
        self._steps_left = 0
        self.lockstep._leave(self)

    def set_sensor_failure(self, on: np.ndarray) -> None:
        self.local.set_sensor_failure(on)

    def observed(self, indices: Sequence[int]) -> list[Any]:
        self.lockstep.physics.watch([self.copies[i] for i in indices])
        return self.local.observed(indices)

    def get_rng_states(self) -> list[Any]:
        return self.local.get_rng_states()

    def set_rng_states(self, states: Sequence[Any]) -> None:
        self.local.set_rng_states(states)

    def close(self) -> None:
        """Leave the lockstep; the copies are the run's and need no release."""
        self.leave()
