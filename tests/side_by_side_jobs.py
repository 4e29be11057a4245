"""Jobs for `curious.runs.side_by_side`'s tests: module-level, so that a spawned worker process
imports them by name."""

from __future__ import annotations

import os
import time
from pathlib import Path


def meet(folder: str, others: int) -> int:
    """Note this process in `folder`, wait until `others` more have (or 60 s), and return its
    process id: jobs that end only when they all run at the same time."""
    Path(folder, str(os.getpid())).touch()
    deadline = time.monotonic() + 60
    while len(list(Path(folder).iterdir())) <= others and time.monotonic() < deadline:
        time.sleep(0.01)
    return os.getpid()


def pid() -> int:
    return os.getpid()


def fail(message: str) -> None:
    raise OSError(message)
