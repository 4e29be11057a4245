"""Calls handed in from several threads, made one call: how a population's runs meet.

A population runs each run in a thread of its own (`curious.runs.population`). Where the runs
do the same kind of work (stepping their environment copies, `curious.envs.lockstep`; stepping
their learners, `curious.agent.update_lockstep`), each run's thread hands its part in and
waits; once every member that is *due* (in a phase of such work, computing its next part) has
handed its part in, one call does all the parts handed in, and each member gets its own result
back, or the error its own part raised. A member between phases is not waited for; a member
whose thread fails leaves (`leave`), so that the others never wait for it.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable, Sequence
from typing import Generic, TypeVar

Part = TypeVar("Part")
Result = TypeVar("Result")


class Rendezvous(Generic[Part, Result]):
    """Parts handed in by members (any hashable: a lane) made one call of `run(parts)`, which
    returns for each part its result or the error that stopped it. One call at a time."""

    def __init__(self, run: Callable[[Sequence[Part]], list[Result | BaseException]]) -> None:
        self.run = run
        self._cond = threading.Condition()
        self._due: set[Hashable] = set()  # in a phase, computing their next part
        self._waiting: dict[Hashable, tuple[Part, bool]] = {}  # parts handed in; last of phase?
        self._done: dict[Hashable, Result | BaseException] = {}
        self._calling = False
        self.calls = 0
        """Calls made (each with the parts of every member waiting then)."""
        self.parts = 0
        """Parts done, over all calls."""

    def enter(self, member: Hashable) -> None:
        """`member` starts a phase: it will hand in a part, and the next call waits for it."""
        with self._cond:
            self._due.add(member)

    def is_due(self, member: Hashable) -> bool:
        with self._cond:
            return member in self._due

    def leave(self, member: Hashable) -> None:
        """`member` is no longer waited for (its phase given up: its thread failed or stopped)."""
        with self._cond:
            self._due.discard(member)
            self._waiting.pop(member, None)
            self._done.pop(member, None)
            self._call_if_all_waiting()

    def hand_in(self, member: Hashable, part: Part, last: bool) -> Result:
        """Hand in `member`'s part and wait for its result (raised if it is an error); `last`:
        its phase ends with this part (it is then no longer waited for), else it stays due. A
        member not yet due enters its phase with this part."""
        with self._cond:
            if member in self._waiting or member in self._done:
                raise RuntimeError("a member handed in a part while its last one was pending")
            self._due.discard(member)
            self._waiting[member] = (part, last)
            self._call_if_all_waiting()
            while member not in self._done:
                self._cond.wait()
            out = self._done.pop(member)
        if isinstance(out, BaseException):
            raise out
        return out

    def _call_if_all_waiting(self) -> None:
        """With the condition held: when no due member is still computing its part, do every
        waiting part in one call and hand each member its result. The condition is released
        during the call, so that members may enter phases meanwhile; the members of the call are
        due again (unless their phase ended) before anyone is woken, so the next call waits for
        them."""
        if self._calling or self._due or not self._waiting:
            return
        batch = list(self._waiting.items())
        self._waiting.clear()
        self._calling = True
        self._cond.release()
        try:
            outs = self.run([part for _, (part, _) in batch])
        except BaseException as error:  # beyond any one member's part: every member gets it
            outs = [error] * len(batch)
        finally:
            self._cond.acquire()
            self._calling = False
        self.calls += 1
        self.parts += len(batch)
        for (member, (_, last)), out in zip(batch, outs, strict=True):
            self._done[member] = out
            if not last and not isinstance(out, BaseException):
                self._due.add(member)
        self._cond.notify_all()
        self._call_if_all_waiting()  # members that handed in their parts during the call
