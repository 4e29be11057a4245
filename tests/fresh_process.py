"""Python code run in a fresh interpreter, for what a process does once (an import's side
effects, a first compilation) that the test process has done already."""

from __future__ import annotations

import os
import subprocess
import sys


def run_fresh(code: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    """`python -c code` with MUJOCO_GL=disable (nothing renders), its output captured as text."""
    env = {**os.environ, "MUJOCO_GL": "disable"}
    return subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=timeout
    )
