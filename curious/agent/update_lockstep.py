"""Several runs' updates gathered into stacked steps: the learning of a population in one call.

A population trains several runs in one process, each run's loop in a thread of its own
(`curious.runs.population`). Each of a run's learners joins an `UpdateLockstep` through an
`UpdateLane`, which takes the place of its backend's step (`UpdateBackend.step`), so that the
run's code is the single run's: `Agent.update` -> `Learner.update` -> the backend's step. A lane
that steps hands its minibatch in and waits; once every lane that is in its update phase has
handed one in, one call computes all of them, and each lane gets its own learner's losses back,
or the error its own step raised. The call stacks the learners that share a shape
(`curious.agent.stacked_update.stack_key`) and a minibatch size into one `stacked_step`; a
learner with no partner takes its own backend's step, as alone.

A run's update phase is the `n_updates` steps of a cycle (`Trainer._update`): a lane enters it
with its first step and leaves it with its `n_updates`-th. Between two of its steps (drawing
its next minibatch) a lane in its phase is waited for; a lane between phases (its run is
playing episodes, updating its targets, writing a checkpoint, or done) is not: the others step
without it. A run whose thread fails leaves its lanes (`UpdateLane.leave`, from
`UpdateLanes.close`), so that the others never wait for it. The meeting is
`curious.rendezvous.Rendezvous`, as for the runs' environment steps (`curious.envs.lockstep`).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

from curious.agent.stacked_update import stack_key, stacked_step
from curious.agent.update_backends import StepLosses
from curious.rendezvous import Rendezvous

if TYPE_CHECKING:
    from curious.agent.learner import Learner


@dataclass(frozen=True)
class Handed:
    """One lane's step, handed in: its minibatch and whether its actor steps."""

    lane: UpdateLane
    x: torch.Tensor
    action: torch.Tensor
    reward: torch.Tensor
    x_next: torch.Tensor
    step_actor: bool

    def key(self) -> Hashable:
        """What steps that stack together share."""
        return (self.lane.key, tuple(self.x.shape), tuple(self.action.shape), self.x.dtype)


RunSteps = Callable[[Sequence[Handed]], list[StepLosses | BaseException]]
"""`run_steps(handed)`: the steps of a call; for each, its losses or the error its step raised
(which leaves the other steps alone)."""


def stack_alike(
    handed: Sequence[Handed], batched_products: bool | None = None
) -> list[StepLosses | BaseException]:
    """The steps of a call, those of learners alike stacked (`stacked_step`, with its
    `batched_products`), any other its own backend's step."""
    groups: dict[Hashable, list[int]] = {}
    for i, step in enumerate(handed):
        groups.setdefault(step.key(), []).append(i)
    out: list[StepLosses | BaseException] = [RuntimeError("not stepped")] * len(handed)
    for rows in groups.values():
        members = [handed[i] for i in rows]
        try:
            with torch.enable_grad():  # this thread's grad mode is not the runs'
                if len(members) == 1:
                    (s,) = members
                    results = [s.lane.alone(s.x, s.action, s.reward, s.x_next, s.step_actor)]
                else:
                    results = stacked_step(
                        [s.lane.learner for s in members],
                        [(s.x, s.action, s.reward, s.x_next) for s in members],
                        [s.step_actor for s in members],
                        batched_products,
                    )
        except Exception as error:  # those learners' step failed; the others step on
            results = [error] * len(members)
        for i, result in zip(rows, results, strict=True):
            out[i] = result
    return out


class UpdateLockstep:
    """Collects the steps of the lanes in their update phase and makes them one call (module
    docstring)."""

    def __init__(self, run_steps: RunSteps = stack_alike) -> None:
        self.meeting: Rendezvous[Handed, StepLosses] = Rendezvous(run_steps)

    @property
    def run_steps(self) -> RunSteps:
        """What computes a call's steps (`stack_alike` by default)."""
        return self.meeting.run

    @run_steps.setter
    def run_steps(self, run_steps: RunSteps) -> None:
        self.meeting.run = run_steps

    @property
    def calls(self) -> int:
        """Calls made (each computing the steps of every lane waiting then)."""
        return self.meeting.calls

    @property
    def steps(self) -> int:
        """Learner steps computed, over all calls."""
        return self.meeting.parts

    def join(self, learners: Sequence[Learner], updates_per_phase: int) -> UpdateLanes:
        """A run's learners' lanes: from now on their steps go through this lockstep (until
        `UpdateLanes.close`). `updates_per_phase`: the steps of each of the run's update
        phases (its `Config.n_updates`)."""
        return UpdateLanes([UpdateLane(self, lr, updates_per_phase) for lr in learners])


class UpdateLane:
    """One learner's steps, computed through an `UpdateLockstep`: it stands in for the
    learner's backend step (`UpdateBackend.step`), which it keeps as `alone`."""

    def __init__(self, lockstep: UpdateLockstep, learner: Learner, updates_per_phase: int) -> None:
        if updates_per_phase < 1:
            raise ValueError("an update phase has at least one step")
        if isinstance(getattr(learner.backend.step, "__self__", None), UpdateLane):
            raise ValueError("the learner's steps already go through a lockstep")
        self.lockstep = lockstep
        self.learner = learner
        self.key = stack_key(learner)
        self.updates_per_phase = updates_per_phase
        self.alone = learner.backend.step
        self._left = 0  # steps left in the current phase; 0 between phases
        learner.backend.step = self.step

    def step(
        self,
        x: torch.Tensor,
        action: torch.Tensor,
        reward: torch.Tensor,
        x_next: torch.Tensor,
        step_actor: bool,
    ) -> StepLosses:
        """The learner's step (the backend's signature), computed in a call of the lockstep."""
        if self._left == 0:  # the first step of a phase
            self._left = self.updates_per_phase
        self._left -= 1
        handed = Handed(self, x, action, reward, x_next, step_actor)
        try:
            return self.lockstep.meeting.hand_in(self, handed, last=self._left == 0)
        except BaseException:
            self.leave()
            raise

    def leave(self) -> None:
        """Stop being waited for (a phase given up: the run's thread failed or stopped)."""
        self._left = 0
        self.lockstep.meeting.leave(self)

    def close(self) -> None:
        """Leave the lockstep, and give the learner its own backend's step back."""
        self.leave()
        if self.learner.backend.step == self.step:
            self.learner.backend.step = self.alone


class UpdateLanes:
    """A run's lanes, one per learner; `close()` closes them all (on the run's way out,
    failed or not)."""

    def __init__(self, lanes: Sequence[UpdateLane]) -> None:
        self.lanes = list(lanes)

    def close(self) -> None:
        for lane in self.lanes:
            lane.close()
