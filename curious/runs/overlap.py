"""Work a training cycle does in a thread beside its gradient steps, with the same results as
done in turn.

`RoundsAhead` (`Config.overlap_rollouts`) collects the next cycle's rounds of episodes while
this cycle's updates run; `Minibatches` (`Config.prefetch_minibatches`) draws the next minibatch
while the learner steps on this one. Each keeps one thread of its own, started on first use and
stopped by `close()`.
"""

from __future__ import annotations

import concurrent.futures
import time
from collections.abc import Callable, Iterator
from typing import Generic, TypeVar

T = TypeVar("T")


class RoundsAhead(Generic[T]):
    """Rounds collected in a thread: `start(collect)` runs `collect()` there, `take()` waits for
    its result. The caller gives `collect` what must not change while it runs (a frozen copy of
    the policy) and changes nothing else it reads until it has taken the result."""

    def __init__(self) -> None:
        self._pool: concurrent.futures.ThreadPoolExecutor | None = None
        self._pending: concurrent.futures.Future[T] | None = None

    @property
    def in_flight(self) -> bool:
        """Whether rounds are being collected (or collected and not taken yet)."""
        return self._pending is not None

    def start(self, collect: Callable[[], T]) -> None:
        if self._pending is not None:
            raise RuntimeError("rounds are already in flight: take() them first")
        if self._pool is None:
            self._pool = concurrent.futures.ThreadPoolExecutor(1, "rollouts")
        self._pending = self._pool.submit(collect)

    def take(self) -> T | None:
        """The rounds in flight, once collected (their error, if collecting raised); None when
        none are."""
        if self._pending is None:
            return None
        pending, self._pending = self._pending, None
        return pending.result()

    def close(self) -> None:
        """Wait for rounds in flight and stop the thread."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
        self._pool = None


class Minibatches:
    """Minibatches for a cycle's updates, each with the seconds the learner waited for it. With
    `prefetch`, the next one is drawn in a thread while the caller steps on this one: one draw
    at a time, in order, so the minibatches are the same as without."""

    def __init__(self, prefetch: bool) -> None:
        self.prefetch = prefetch
        self._pool: concurrent.futures.ThreadPoolExecutor | None = None

    def __call__(self, draw: Callable[[], T], n: int) -> Iterator[tuple[T, float]]:
        """`n` minibatches from `draw`."""
        if not self.prefetch:
            for _ in range(n):
                tic = time.perf_counter()
                batch = draw()
                yield batch, time.perf_counter() - tic
            return
        if self._pool is None:
            self._pool = concurrent.futures.ThreadPoolExecutor(1, "minibatches")
        ahead = self._pool.submit(draw)
        for i in range(n):
            tic = time.perf_counter()
            batch = ahead.result()
            waited = time.perf_counter() - tic
            if i + 1 < n:
                ahead = self._pool.submit(draw)
            yield batch, waited

    def close(self) -> None:
        """Wait for a draw in flight and stop the thread."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
        self._pool = None
