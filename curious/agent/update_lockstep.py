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
`UpdateLanes.close`), so that the others never wait for it. This mirrors
`curious.envs.lockstep.Lockstep`, which does the same for the runs' environment steps.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

from curious.agent.stacked_update import stack_key, stacked_step
from curious.agent.update_backends import StepLosses

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
        self.run_steps = run_steps
        self._cond = threading.Condition()
        self._updating: set[UpdateLane] = set()  # in their phase, drawing their next minibatch
        self._waiting: dict[UpdateLane, tuple[Handed, bool]] = {}  # handed in, last step?
        self._done: dict[UpdateLane, StepLosses | BaseException] = {}
        self._stepping = False  # one call at a time
        self.calls = 0
        """Calls made (each computing the steps of every lane waiting then)."""
        self.steps = 0
        """Learner steps computed, over all calls."""

    def join(self, learners: Sequence[Learner], updates_per_phase: int) -> UpdateLanes:
        """A run's learners' lanes: from now on their steps go through this lockstep (until
        `UpdateLanes.close`). `updates_per_phase`: the steps of each of the run's update
        phases (its `Config.n_updates`)."""
        return UpdateLanes([UpdateLane(self, lr, updates_per_phase) for lr in learners])

    # the lanes' side ------------------------------------------------------------------------
    def _leave(self, lane: UpdateLane) -> None:
        with self._cond:
            self._updating.discard(lane)
            self._waiting.pop(lane, None)
            self._done.pop(lane, None)
            self._step_if_all_waiting()

    def _step(self, handed: Handed, last: bool) -> StepLosses:
        """Hand in a lane's step and wait for its losses; `last`: its update phase ends with
        this step (the lane is then no longer waited for). A lane not in its phase enters it."""
        lane = handed.lane
        with self._cond:
            if lane in self._waiting or lane in self._done:
                raise RuntimeError("a lane handed in a step while its last one was pending")
            self._updating.discard(lane)
            self._waiting[lane] = (handed, last)
            self._step_if_all_waiting()
            while lane not in self._done:
                self._cond.wait()
            out = self._done.pop(lane)
        if isinstance(out, BaseException):
            raise out
        return out

    def _step_if_all_waiting(self) -> None:
        """With the condition held: when no lane in its phase is still drawing its minibatch,
        compute every waiting lane's step in one call and hand each its losses. The condition
        is released during the call, so that lanes may enter their phases meanwhile; the lanes
        of the call are back among those in their phase (unless it ended) before anyone is
        woken, so the next call waits for them."""
        if self._stepping or self._updating or not self._waiting:
            return
        batch = list(self._waiting.items())
        self._waiting.clear()
        self._stepping = True
        self._cond.release()
        try:
            outs = self.run_steps([handed for _, (handed, _) in batch])
        except BaseException as error:  # beyond any one learner's step: every lane gets it
            outs = [error] * len(batch)
        finally:
            self._cond.acquire()
            self._stepping = False
        self.calls += 1
        self.steps += len(batch)
        for (lane, (_, last)), out in zip(batch, outs, strict=True):
            self._done[lane] = out
            if not last and not isinstance(out, BaseException):
                self._updating.add(lane)
        self._cond.notify_all()
        self._step_if_all_waiting()  # lanes that handed in their steps during the call


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
            return self.lockstep._step(handed, last=self._left == 0)
        except BaseException:
            self.leave()
            raise

    def leave(self) -> None:
        """Stop being waited for (a phase given up: the run's thread failed or stopped)."""
        self._left = 0
        self.lockstep._leave(self)

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
