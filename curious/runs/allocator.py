"""Memory a training process frees goes back to the system instead of piling up in its heap.

Two allocators hold memory a run has freed, unless told otherwise:

* glibc's `malloc` raises its mmap threshold to the size of each large block freed (up to
  32 MiB), after which blocks of that size come from the heap, and the heap keeps what it
  frees unless it is at its top. Measured on a resumed `long` run (docs/benchmarks.md,
  `curious bench heap`): the heap grew by about 0.7 GB over one checkpoint interval while what
  it held in use stayed flat. `return_freed_memory` fixes the threshold at glibc's default of
  128 KiB (`mallopt`), so blocks above it are mapped on their own and unmapped when freed.
* Rerun's `mimalloc` keeps freed pages until its thread next allocates; a resumed run re-sends
  its recording at once and then held about five times that file's size.
  `MIMALLOC_PURGE_DELAY` is set to 0 (`curious.watching.recording`, before Rerun is imported;
  a value the user set wins), so freed pages go back at once.

Neither changes what a run computes: the same episodes, to the bit (`tools/fingerprint.py`).
`release_free_heap` gives the heap's free pages back at once; a run does not call it, the memory
benchmarks do before they count what some work adds (`benchmarks/resume_memory.py`).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import platform

__all__ = [
    "GLIBC_MMAP_THRESHOLD",
    "MIMALLOC_PURGE_DELAY",
    "mmap_threshold",
    "release_free_heap",
    "return_freed_memory",
]

GLIBC_MMAP_THRESHOLD = 128 * 1024
"""Bytes from which glibc maps a block on its own (its default, which `mallopt` then keeps
from rising)."""
MIMALLOC_PURGE_DELAY = "0"
"""Milliseconds mimalloc waits before giving freed pages back (its default is 10, and then only
when the thread allocates again)."""
_M_MMAP_THRESHOLD = -3  # glibc's malloc.h


@functools.cache
def return_freed_memory() -> bool:
    """Fix glibc's mmap threshold at `GLIBC_MMAP_THRESHOLD` for this process; False where the C
    library is not glibc (or refuses), which then keeps its own policy. Once per process: later
    calls return the first answer."""
    return mmap_threshold(GLIBC_MMAP_THRESHOLD)


def mmap_threshold(nbytes: int) -> bool:
    """Fix glibc's mmap threshold at `nbytes` (it no longer moves by itself); False where the C
    library is not glibc or refuses."""
    libc = _glibc()
    return (
        libc is not None
        and hasattr(libc, "mallopt")
        and bool(libc.mallopt(_M_MMAP_THRESHOLD, nbytes))
    )


def release_free_heap() -> bool:
    """Give the pages the heap holds free back to the system now (glibc's `malloc_trim`); False
    where the C library is not glibc. A fixed threshold keeps the heap from growing, but a
    request the heap's free blocks can serve is served there: a measure of the memory some work
    adds starts after this, so that memory freed before it is not already resident."""
    libc = _glibc()
    if libc is None or not hasattr(libc, "malloc_trim"):
        return False
    libc.malloc_trim(0)
    return True


@functools.cache
def _glibc() -> ctypes.CDLL | None:
    """The C library, where it is glibc; None elsewhere."""
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return None
    name = ctypes.util.find_library("c")
    return None if name is None else ctypes.CDLL(name)
