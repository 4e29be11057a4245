"""Speed and memory benchmarks, each run side by side with a named peer (see docs/benchmarks.md)."""

from __future__ import annotations

import argparse
import math
import multiprocessing
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class AtLeast:
    """The argparse type of a count option: a whole number no smaller than `minimum`, so that a
    benchmark given 0 rounds or -3 rows names the option before it builds anything."""

    minimum: int
    why: str = ""
    """Why the minimum is what it is, where it is not plain (said in the error)."""

    def __call__(self, text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < self.minimum:
            reason = f" ({self.why})" if self.why else ""
            raise argparse.ArgumentTypeError(
                f"must be at least {self.minimum}{reason}, got {value}"
            )
        return value


def positive_seconds(text: str) -> float:
    """The argparse type of a duration option: a finite number of seconds above 0 (0 would
    time nothing, NaN would never end the timing loop)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text}")
    return value


def check_device(device: str) -> None:
    """A `ValueError` for `--device cuda` where torch sees no CUDA device, before anything is
    built on it."""
    if device == "cuda":
        import torch

        if not torch.cuda.is_available():
            raise ValueError("--device cuda, but torch sees no CUDA device")


@dataclass(frozen=True)
class CountList:
    """The argparse type of a comma-separated list of counts (`2,4`), each at least `minimum`."""

    minimum: int

    def __call__(self, text: str) -> list[int]:
        return [AtLeast(self.minimum)(part.strip()) for part in text.split(",")]


def anonymous_memory() -> tuple[int, int]:
    """This process's anonymous memory, in all and in glibc's heap (`[heap]`), in bytes, counted
    page by page (Linux: /proc/self/smaps), so neither file pages nor the kernel's per-CPU
    counters move it."""
    total = heap = 0
    in_heap = False
    with open("/proc/self/smaps") as handle:
        for line in handle:
            if line[0] in "0123456789abcdef" and "-" in line.split(" ", 1)[0]:
                in_heap = line.rstrip().endswith("[heap]")
            elif line.startswith("Anonymous:"):
                nbytes = int(line.split()[1]) * 1024
                total += nbytes
                heap += nbytes if in_heap else 0
    return total, heap


def in_fresh_process(function: Callable[..., Any], *args: Any) -> Any:
    """`function(*args)` in a spawned process of its own. After a result the pool is closed and
    joined, so that its process ends as a process ends (its finalizers run, its semaphores are
    released) rather than killed as a pool's `with` block kills its workers, which left the
    resource tracker warning of a leaked semaphore. On an error or a Ctrl-C the process is
    stopped at once, as before: joining then would wait for the whole measure, or for a result
    that never comes."""
    pool = multiprocessing.get_context("spawn").Pool(1)
    try:
        result = pool.apply(function, args)
    except BaseException:
        pool.terminate()
        raise
    pool.close()
    pool.join()
    return result
