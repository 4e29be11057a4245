"""A run's modules as its recording names, colours and indexes them, and the arrays of a batch
(`RunRecorder`'s arguments) checked and shaped against them, with errors that say which
argument is off.

A module's entity name and legend label lead with its task number in the paper where it has one
(`T1-reach`, "T1 reach"), and its colour is the figures' (`curious.watching.palette`), so that
the viewer's legends read T1..T7 in the figures' colours.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from curious.watching.palette import module_entity, module_label, module_rgb
from suite import module_index

__all__ = ["RecordedModules", "as_1d"]


def as_1d(name: str, values: Any, n: int | None = None, dtype: Any = None) -> np.ndarray:
    """`values` as a 1-D array; with `n`, of `n` rows (a single value is repeated)."""
    arr = np.atleast_1d(np.asarray(values, dtype=dtype))
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a scalar or a 1-D array, got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        if arr.shape[0] == 1:
            return np.repeat(arr, n)
        raise ValueError(f"{name} has {arr.shape[0]} rows, expected {n} (one per episode)")
    return arr


class RecordedModules:
    """The modules of a run in slot order: their entity names, legend labels and colours."""

    def __init__(self, names: Sequence[str]) -> None:
        self.names: tuple[str, ...] = tuple(names)
        if not self.names:
            raise ValueError("module_names is empty: a run has at least one module")
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"module_names has duplicates: {self.names}")
        self.rgb = np.array([module_rgb(n) for n in self.names], dtype=np.uint8)
        self.labels = [module_label(n) for n in self.names]
        self.entities = [module_entity(n) for n in self.names]

    def __len__(self) -> int:
        return len(self.names)

    def slots(self, module: Any, n: int) -> np.ndarray:
        """(n,) slot indices of modules given by name or index: the suite's rule and its
        errors (`suite.module_index`), applied once per distinct value."""
        values, inverse = np.unique(as_1d("module", module, n), return_inverse=True)
        index = [module_index(self.names, value) for value in values.tolist()]
        return np.asarray(index, np.int64)[inverse.reshape(-1)]

    def per_module(self, name: str, values: Any, n: int) -> np.ndarray:
        """`values` as an (n, modules) float array: one row per episode, one column per module."""
        arr = np.asarray(values, dtype=np.float64)
        m = len(self.names)
        if arr.ndim == 1 and n == 1:
            arr = arr[None]
        if arr.shape != (n, m):
            raise ValueError(
                f"{name} must have shape ({n}, {m}) (episodes x modules), got {arr.shape}"
            )
        return arr
