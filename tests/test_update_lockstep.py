"""Runs' updates gathered into stacked steps (`curious.agent.update_lockstep`)."""

import dataclasses
import threading
import time

import pytest
import torch

from curious.agent.learner import Learner
from curious.agent.update_lockstep import Handed, UpdateLockstep, stack_alike
from curious.config import resolve

torch.set_num_threads(1)
D, A = 6, 4
CONFIG = dataclasses.replace(resolve("smoke"), hidden=16, layers=2)
WAIT = 60.0
"""Seconds a test waits for a thread before calling it stuck."""


def minibatch(seed, n=32):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, D, generator=g)
    action = torch.rand(n, A, generator=g) * 2 - 1
    return x, action, -(torch.rand(n, generator=g) < 0.5).float(), torch.randn(n, D, generator=g)


class Recorded:
    """`stack_alike` that records how many steps each call computed, and can hold its first
    call until `hold_until()` is true (so that a second lane has handed in meanwhile)."""

    def __init__(self, hold_until=None):
        self.sizes = []
        self.hold_until = hold_until
        self.started = threading.Event()

    def __call__(self, handed):
        self.started.set()
        if self.hold_until is not None and not self.sizes:
            deadline = time.monotonic() + WAIT
            while not self.hold_until() and time.monotonic() < deadline:
                time.sleep(0.001)
        self.sizes.append(len(handed))
        return stack_alike(handed)


def in_thread(work):
    """Run `work()` in a thread; its result or error, once it ends (a test failure if it does
    not end within WAIT seconds)."""
    out = {}

    def run():
        try:
            out["result"] = work()
        except BaseException as error:
            out["error"] = error

    thread = threading.Thread(target=run)
    thread.start()
    return thread, out


def finish(thread, out):
    thread.join(WAIT)
    assert not thread.is_alive(), "a thread waited for a lane that never stepped"
    return out


def phase(learner, seeds):
    return [learner.update(*minibatch(s)) for s in seeds]


def test_a_learner_outside_its_updates_is_not_waited_for():
    """One run updates while the other plays (joined, but not in its updates): each step is
    computed at once, alone, and gives the learner's own update."""
    recorded = Recorded()
    lockstep = UpdateLockstep(recorded)
    learners = [Learner(D, A, CONFIG, seed=s) for s in range(2)]
    reference = Learner(D, A, CONFIG, seed=0)
    lockstep.join(learners, updates_per_phase=3)
    out = finish(*in_thread(lambda: phase(learners[0], range(3))))
    assert recorded.sizes == [1, 1, 1]
    for got, seed in zip(out["result"], range(3), strict=True):
        assert torch.equal(got["critic_loss"], reference.update(*minibatch(seed))["critic_loss"])


def test_learners_in_their_updates_step_together():
    """Two runs in their updates: once both have entered, every step of one waits for the
    other's and both are one call (one stacked step); the first run's last step ends its
    phase, and the other's last is computed without waiting. Each learner's losses and weights
    are those of its updates alone."""
    lockstep = UpdateLockstep()
    recorded = Recorded(hold_until=lambda: len(lockstep.meeting._waiting) == 1)
    lockstep.run_steps = recorded
    learners = [Learner(D, A, CONFIG, seed=s) for s in range(2)]
    references = [Learner(D, A, CONFIG, seed=s) for s in range(2)]
    lockstep.join(learners, updates_per_phase=4)
    seeds = [range(0, 4), range(10, 14)]
    first = in_thread(lambda: phase(learners[0], seeds[0]))
    assert recorded.started.wait(WAIT)  # the first run's first step is being computed
    second = in_thread(lambda: phase(learners[1], seeds[1]))
    outs = [finish(*first), finish(*second)]
    assert recorded.sizes == [1, 2, 2, 2, 1]
    assert lockstep.calls == 5 and lockstep.steps == 8
    for learner, reference, out, run_seeds in zip(learners, references, outs, seeds, strict=True):
        wants = phase(reference, run_seeds)
        for want, got in zip(wants, out["result"], strict=True):
            assert torch.equal(got["critic_loss"], want["critic_loss"])
        assert torch.equal(learner.backend.online[0], reference.backend.online[0])


def test_a_run_that_fails_in_its_updates_is_not_waited_for():
    """A run whose thread fails between two of its steps leaves the lockstep (its lanes close
    on the way out): the other run, waiting for it, goes on and ends its phase."""
    lockstep = UpdateLockstep()
    learners = [Learner(D, A, CONFIG, seed=s) for s in range(2)]
    lanes = [lockstep.join([learner], updates_per_phase=3) for learner in learners]
    entered = threading.Event()

    def failing():
        try:
            learners[0].update(*minibatch(0))
            entered.set()
            while not lockstep.meeting._waiting:  # the other run waits for this one's next step
                time.sleep(0.001)
            raise OSError("replay lost")
        finally:
            lanes[0].close()

    bad = in_thread(failing)
    assert entered.wait(WAIT)
    good = finish(*in_thread(lambda: phase(learners[1], range(3))))
    assert isinstance(finish(*bad)["error"], OSError)
    assert len(good["result"]) == 3


def test_a_failing_step_reaches_its_own_learners_only():
    """Steps of learners of other shapes in one call are computed apart: one that raises gives
    its error to its own lane, and the others their losses."""
    lockstep = UpdateLockstep()
    learners = [Learner(D, A, CONFIG, seed=0), Learner(D + 1, A, CONFIG, seed=0)]
    lane, other = lockstep.join(learners, updates_per_phase=1).lanes

    def broken(*args):
        raise FloatingPointError("diverged")

    other.alone = broken
    x, action, reward, x_next = minibatch(0)
    handed = [
        Handed(lane, x, action, reward, x_next, True),
        Handed(other, torch.randn(32, D + 1), action, reward, torch.randn(32, D + 1), True),
    ]
    ok, failed = stack_alike(handed)
    assert isinstance(failed, FloatingPointError)
    assert not isinstance(ok, BaseException) and ok[0].shape == ()


def test_closed_lanes_give_the_learners_their_own_steps_back():
    learner = Learner(D, A, CONFIG, seed=0)
    own = learner.backend.step
    lanes = UpdateLockstep().join([learner], updates_per_phase=2)
    assert learner.backend.step != own
    with pytest.raises(ValueError, match="already go through a lockstep"):
        UpdateLockstep().join([learner], updates_per_phase=2)
    lanes.close()
    assert learner.backend.step == own
    with pytest.raises(ValueError, match="at least one step"):
        UpdateLockstep().join([learner], updates_per_phase=0)
