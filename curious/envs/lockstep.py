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
wait for it. The meeting itself is `curious.rendezvous.Rendezvous`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

from curious.envs.batch import LocalEnvs
from curious.envs.goal_env import EnvSpec, GoalEnv
from curious.rendezvous import Rendezvous

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
        self.meeting: Rendezvous[Group, Observations] = Rendezvous(self._call)
        self.copies_stepped = 0

    @property
    def calls(self) -> int:
        """Physics calls made (each stepping the copies of every lane waiting then)."""
        return self.meeting.calls

    def lane(self, copies: Sequence[GoalEnv]) -> Lane:
        """A run's view of its copies: an `EnvBatch` whose steps go through this lockstep."""
        return Lane(self, copies)

    def _call(self, groups: Sequence[Group]) -> list[Observations | BaseException]:
        self.copies_stepped += sum(len(copies) for copies, _ in groups)
        return self.physics.step(groups)


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
        self.lockstep.meeting.enter(self)
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
        if not self.lockstep.meeting.is_due(self):
            raise RuntimeError("a lane stepped outside a round: reset it first")
        self._steps_left -= 1
        group = (self.copies[: len(actions)], actions)
        try:
            return self.lockstep.meeting.hand_in(self, group, last=self._steps_left == 0)
        except BaseException:
            self.leave()
            raise

    def leave(self) -> None:
        """Stop being waited for (a round given up: the run's thread failed or stopped)."""
        self._steps_left = 0
        self.lockstep.meeting.leave(self)

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
