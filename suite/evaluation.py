"""Every module's outcome and success at once, from the positions of the gripper and the cubes.

The env reports all modules' outcomes (`achieved`) and successes every step. Evaluating each
module through its own functions costs a dozen small numpy calls per module; instead, modules
that declare their structure (see `suite.modules.distance_module`) are evaluated together: one
matrix product gives every linear outcome component, and one distance test gives every
"within 0.05 m of the goal slot" verdict. Modules without that structure go through their
functions. Both routes compute the same float32 numbers: success is always judged on the
float32 outcomes that the env reports, with predicates that do not depend on the batch shape.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from suite.modules import TaskModule, within_distance


class ModuleEvaluator:
    """Outcomes and successes of `modules` in a scene with `n_cubes` cubes."""

    def __init__(self, modules: Sequence[TaskModule], n_cubes: int) -> None:
        self.modules = tuple(modules)
        dims = [m.outcome_dim for m in self.modules]
        starts = [0, *itertools.accumulate(dims)]
        self.slices = tuple(slice(a, b) for a, b in itertools.pairwise(starts))
        self.achieved = np.zeros(starts[-1], np.float32)
        self.success = np.zeros(len(self.modules), np.float32)
        self._slots = np.zeros((len(self.modules), 3), np.float32)

        rows, matrices = [], []
        self._extras = []  # (fn, slice of achieved) for components after the linear ones
        self._functional = []  # (outcome_fn, slice) for modules without linear terms
        for m, sl in zip(self.modules, self.slices, strict=True):
            w = m.outcome_matrix(n_cubes)
            if w is None:
                self._functional.append((m.outcome_fn, sl))
                continue
            rows.append(np.arange(sl.start, sl.start + len(w)))
            matrices.append(w)
            if m.extra_outcome_fn is not None:
                self._extras.append((m.extra_outcome_fn, slice(sl.start + len(w), sl.stop)))
        width = 3 + 3 * n_cubes
        self._linear_rows = np.concatenate(rows) if rows else np.zeros(0, np.intp)
        self._linear_matrix = np.concatenate(matrices) if matrices else np.zeros((0, width))

        reaching = [i for i, m in enumerate(self.modules) if m.reaches_slot]
        self._reaching = np.array(reaching, dtype=np.intp)
        self._reaching_first3 = np.array(
            [np.arange(self.slices[i].start, self.slices[i].start + 3) for i in reaching],
            dtype=np.intp,
        ).reshape(len(reaching), 3)
        self._reaching_slots = np.zeros((len(reaching), 3), np.float32)
        self._guards = [
            (j, self.modules[i].guard_fn, self.slices[i])
            for j, i in enumerate(reaching)
            if self.modules[i].guard_fn is not None
        ]
        self._goal_frames = np.concatenate(
            [m.goal_frame_matrix(n_cubes) for m in self.modules]
        ).reshape(len(self.modules), 3, width)
        self._custom = [
            (i, m.success_fn, self.slices[i])
            for i, m in enumerate(self.modules)
            if not m.reaches_slot
        ]

    def set_slots(self, slots: np.ndarray) -> None:
        """The goal slot (n_modules, 3) each module is judged against from now on."""
        self._slots[:] = slots
        self._reaching_slots[:] = self._slots[self._reaching]

    def evaluate(self, positions: np.ndarray, gripper: np.ndarray, cubes: np.ndarray) -> None:
        """Fill `achieved` and `success` (1.0 / 0.0) from the positions.

        Args:
            positions: [gripper, cube 1, ..., cube n], flat (3 + 3 n_cubes,).
            gripper: (3,) and cubes: (n_cubes, 3), the same numbers (views are fine).
        """
        achieved, success = self.achieved, self.success
        achieved[self._linear_rows] = self._linear_matrix @ positions
        for fn, sl in self._extras:
            achieved[sl] = fn(gripper, cubes)
        for fn, sl in self._functional:
            achieved[sl] = fn(gripper, cubes)
        if len(self._reaching):
            ok = within_distance(achieved[self._reaching_first3], self._reaching_slots)
            for j, guard, sl in self._guards:
                ok[j] &= guard(achieved[sl])
            success[self._reaching] = ok
        for i, fn, sl in self._custom:
            success[i] = fn(achieved[sl], self._slots[i])

    def goal_positions(self, positions: np.ndarray) -> np.ndarray:
        """World positions (n_modules, 3) of the goal slots set by `set_slots`, given the
        positions [gripper, cube 1, ...] (flat): slots expressed in a cube's frame follow it."""
        return self._slots + self._goal_frames @ positions
