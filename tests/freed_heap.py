"""A process's heap holding memory it has freed, resident, as after freeing large blocks."""

from __future__ import annotations

import numpy as np

from curious.runs.allocator import mmap_threshold


def leave_freed_heap(mib: int = 40) -> np.ndarray:
    """Leave `mib` MiB freed in this process's heap and resident: glibc's threshold raised as
    freeing a 32 MiB block raises it, `mib` blocks of 1 MiB taken from the heap, then freed under
    a block still in use, so that freeing them does not trim the heap. Returns that block: keep
    it while the heap is to stay so."""
    mmap_threshold(32 * 2**20)
    freed = [np.ones(2**18, np.float32) for _ in range(mib)]
    above = np.ones(2**16)
    del freed
    return above
