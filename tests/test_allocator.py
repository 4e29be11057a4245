"""A training process gives the memory it frees back to the system (`curious.runs.allocator`)."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from freed_heap import leave_freed_heap

from benchmarks import anonymous_memory, in_fresh_process
from curious.runs import driver
from curious.runs.allocator import MIMALLOC_PURGE_DELAY, release_free_heap

ROOT = Path(__file__).resolve().parents[1]

# After a block of 8 MiB is freed, glibc's threshold rises to it and a 4 MiB block comes from
# the heap; with the threshold fixed, it is mapped on its own. The heap's growth, in MiB.
_HEAP_GROWTH = textwrap.dedent(
    """
    import sys
    import numpy as np
    from benchmarks import anonymous_memory
    from curious.runs.allocator import return_freed_memory

    def heap():
        return anonymous_memory()[1]

    if sys.argv[1] == "fixed":
        assert return_freed_memory()
    block = np.ones(2**20); del block
    before = heap()
    kept = np.ones(2**19)
    print((heap() - before) / 2**20)
    """
)

glibc_only = pytest.mark.skipif(
    platform.system() != "Linux" or platform.libc_ver()[0] != "glibc", reason="needs glibc"
)


def _heap_growth(kind: str) -> float:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run(
        [sys.executable, "-c", _HEAP_GROWTH, kind],
        capture_output=True,
        text=True,
        check=True,
        env=env,
        cwd=ROOT,
    )
    return float(out.stdout.split()[-1])


@glibc_only
def test_a_large_block_is_mapped_on_its_own_once_the_threshold_is_fixed():
    assert _heap_growth("fixed") < 0.5
    assert _heap_growth("default") > 3.5  # the same block from the heap: what the fix changes


@glibc_only
def test_training_fixes_the_threshold(monkeypatch, tmp_path):
    called = []
    monkeypatch.setattr(driver, "return_freed_memory", lambda: called.append(True))
    from curious.presets import resolve

    config = resolve("smoke", overrides=dict(total_episodes=4, progress=False))
    driver.train(config, tmp_path / "run")
    assert called == [True]


def _released_after_freeing_heap() -> float:
    """MiB of its heap a process gives back on `release_free_heap`, having left 40 MiB freed."""
    above = leave_freed_heap(40)
    held = anonymous_memory()[1]
    assert release_free_heap()
    released = (held - anonymous_memory()[1]) / 2**20
    del above
    return released


@glibc_only
def test_the_heaps_free_pages_go_back_to_the_system_when_released():
    # of the 40 MiB freed, resident until released
    assert in_fresh_process(_released_after_freeing_heap) > 35


def test_rerun_is_loaded_with_freed_pages_purged_at_once_unless_the_user_says_otherwise():
    code = "import curious.watching.recording, os; print(os.environ['MIMALLOC_PURGE_DELAY'])"
    env = {k: v for k, v in os.environ.items() if k != "MIMALLOC_PURGE_DELAY"}
    run = [sys.executable, "-c", code]
    said = subprocess.run(run, capture_output=True, text=True, check=True, env=env, cwd=ROOT)
    assert said.stdout.strip() == MIMALLOC_PURGE_DELAY == "0"
    env["MIMALLOC_PURGE_DELAY"] = "25"
    said = subprocess.run(run, capture_output=True, text=True, check=True, env=env, cwd=ROOT)
    assert said.stdout.strip() == "25"
