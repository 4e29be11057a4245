"""Runs side by side, each in a process of its own: how `curious train --seeds` trains its seeds.

`run_side_by_side(jobs, workers)` hands each job (a picklable call that trains one run) to one of
`workers` processes, the next as one ends. The processes are started with `spawn`, so that none
inherits the parent's threads, and die with the parent (a killed `curious train` leaves no run
training alone). Each run is the run that `curious train --seed` trains in a process of its own:
nothing of its episodes depends on the runs beside it.

A Ctrl-C asks every run to stop at the end of its cycle, after a checkpoint (`stop_requested`,
which `curious.runs.driver.train` asks after every cycle), and starts no other; a second Ctrl-C
at the terminal stops them at once, each with its last checkpoint. `--resume` goes on from
there. A run that fails leaves the others training; its error comes back in its place.

Why processes and not threads of one process: each process has a core of Python of its own.
Runs as threads of one process, their physics and updates stepped together, trained 0.84-0.87 x
the episodes of the same runs as processes on 2 cores and 0.31 x on a 16-core GPU node, because
the Python around acting, sampling and updating took turns on one lock (docs/scaling.md).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

MAX_WORKERS = 4096
"""The most worker processes a pool of runs is asked for (`curious reproduce --workers`,
`CURIOUS_WORKERS`): more cores than any one machine has, far below what would overflow the
pool's bounded queue (Python's semaphores end at 2**31 - 1)."""

Result = TypeVar("Result")


class Interrupted(KeyboardInterrupt):
    """A Ctrl-C stopped the runs; raised once every run that had begun has ended. `results`
    holds what `run_side_by_side` returns otherwise (see there)."""

    def __init__(self, results: list[Any]) -> None:
        super().__init__("stopped")
        self.results = results


@dataclass(frozen=True)
class Failed:
    """A job that raised: its error as a line (the exception itself may not cross back from
    its process), with its traceback under `CURIOUS_DEBUG`."""

    message: str


class _Worker:
    """A worker process's state: the parent's stop event, the Ctrl-Cs it got, whether a job
    runs in it."""

    stop: Any = None  # multiprocessing.Event, set by the parent on its Ctrl-C
    interrupts = 0
    running = False


def stop_requested() -> bool:
    """Whether the run training in this process should stop at the end of its cycle: a Ctrl-C
    reached this process, or its parent (a terminal sends it to both; `kill -INT` to the parent
    reaches it alone)."""
    return _Worker.interrupts > 0 or (_Worker.stop is not None and _Worker.stop.is_set())


def _on_interrupt(signum: int, frame: object) -> None:
    """SIGINT in a worker: the first asks its run to stop at its next checkpoint; the second
    stops it at once (a `KeyboardInterrupt`, raised once: a third would cut its clean-up
    short). A worker waiting for a job only takes note, instead of dying with a traceback."""
    _Worker.interrupts += 1
    if _Worker.interrupts == 2 and _Worker.running:
        raise KeyboardInterrupt


def die_with_parent() -> None:
    """On Linux, have this process killed when its parent dies: without it, a worker whose
    parent was killed (SIGKILL reaches only the parent) would go on training alone."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL)


@contextlib.contextmanager
def interrupts_ignored() -> Iterator[None]:
    """SIGINT ignored in this process for a moment (the main thread's handler is put back): the
    worker processes started meanwhile inherit it, so that a Ctrl-C while they import their
    modules prints no traceback of theirs; each then installs its own handler."""
    try:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: the workers start as they would
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _start_worker(stop: Any, progress_lock: Any) -> None:
    """A worker's start: no display for MuJoCo, one thread for numpy's and torch's default pools
    (the runs share the cores; a run's own `torch_threads` still applies), the answer to
    Ctrl-C, death with the parent, and the progress bars' shared lock."""
    from tqdm.auto import tqdm  # it picks notebook or console bars, and warns, when imported

    os.environ.setdefault("MUJOCO_GL", "disable")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    _Worker.stop = stop
    signal.signal(signal.SIGINT, _on_interrupt)
    die_with_parent()

    tqdm.set_lock(progress_lock)


class _NotStarted:
    """What a job stopped before it began returns."""


def _call(job: Callable[[], Result]) -> Result | Failed | _NotStarted:
    """A job in its worker: not begun after a stop request, its error as a `Failed`."""
    if stop_requested():
        return _NotStarted()
    _Worker.running = True
    try:
        return job()
    except Exception as exc:
        message = f"{type(exc).__name__}: {exc}"
        if os.environ.get("CURIOUS_DEBUG"):
            message += "\n" + traceback.format_exc()
        return Failed(message)
    finally:
        _Worker.running = False


@dataclass
class _Pool(Generic[Result]):
    """The worker processes and the futures of the jobs handed to them."""

    executor: cf.ProcessPoolExecutor
    stop: Any
    futures: list[cf.Future]

    def wait(self) -> bool:
        """Wait for every job; whether a Ctrl-C came meanwhile (then every run was asked to
        stop, no other began, and every one that had begun has ended)."""
        try:
            cf.wait(self.futures)
            return False
        except KeyboardInterrupt:
            self.stop.set()
            for future in self.futures:
                future.cancel()
        while True:
            try:
                cf.wait(self.futures)
                return True
            except KeyboardInterrupt:  # a second Ctrl-C: the workers stop at once themselves
                continue

    def results(self) -> list[Result | Failed | None]:
        """In order: each job's result, its `Failed`, or None for a job that a Ctrl-C kept
        from beginning or from ending (a second Ctrl-C)."""
        out: list[Result | Failed | None] = []
        for future in self.futures:
            if future.cancelled():
                out.append(None)
                continue
            error = future.exception()
            if isinstance(error, KeyboardInterrupt):
                out.append(None)
            elif error is not None:  # the process died (killed, out of memory)
                out.append(Failed(f"{type(error).__name__}: {error}"))
            else:
                result = future.result()
                out.append(None if isinstance(result, _NotStarted) else result)
        return out


def run_side_by_side(
    jobs: Sequence[Callable[[], Result]], workers: int
) -> list[Result | Failed | None]:
    """Run each of `jobs` in a worker process, at most `workers` at a time, in order; return,
    in order, each job's result or its `Failed`. A Ctrl-C raises `Interrupted` once every job
    that had begun has ended (the module docstring), its `results` None for the jobs it kept
    from beginning or, with a second Ctrl-C, from ending."""
    if not jobs:
        return []
    context = multiprocessing.get_context("spawn")
    stop = context.Event()
    with interrupts_ignored():  # the workers start with SIGINT ignored, then set their own
        executor = cf.ProcessPoolExecutor(
            max_workers=max(1, min(workers, len(jobs))),
            mp_context=context,
            initializer=_start_worker,
            initargs=(stop, context.RLock()),
        )
        pool: _Pool[Result] = _Pool(executor, stop, [executor.submit(_call, j) for j in jobs])
    try:
        interrupted = pool.wait()
    finally:
        executor.shutdown(wait=True, cancel_futures=True)
    results = pool.results()
    if interrupted or any(result is None for result in results):  # a stop came, if not here
        raise Interrupted(results)
    return results
