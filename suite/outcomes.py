"""Every module's outcome, goal and success at once, from the positions of the gripper and cubes.

The env reports all modules' outcomes (`achieved`) and successes every step. Evaluating each
module through its own functions costs a dozen small numpy calls per module; instead, modules
that declare their structure (see `suite.modules.distance_module`) are evaluated together: one
matrix product gives every linear outcome component, one gather moves the goals that follow a
cube, and one distance test gives every "within 0.05 m of the goal" verdict. Modules without
that structure go through their functions. Both routes compute the same float32 numbers:
success is always judged on the float32 outcomes that the env reports, with the goals that
`TaskModule.goal` gives for them, by predicates that do not depend on the batch shape.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from suite.modules import TaskModule, within_distance


class ModuleEvaluator:
    """Outcomes, goals and successes of `modules` in a scene with `n_cubes` cubes."""

    def __init__(self, modules: Sequence[TaskModule], n_cubes: int) -> None:
        self.modules = tuple(modules)
        dims = [m.outcome_dim for m in self.modules]
        starts = [0, *itertools.accumulate(dims)]
        self.slices = tuple(slice(a, b) for a, b in itertools.pairwise(starts))
        self.achieved = np.zeros(starts[-1], np.float32)
        self.success = np.zeros(len(self.modules), np.float32)
        self.goals = np.zeros((len(self.modules), 3), np.float32)
        """Every module's goal at the last `evaluate`, world frame (`TaskModule.goal`)."""
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
        self._one_term = bool(np.all(np.count_nonzero(self._linear_matrix, axis=1) <= 1))

        # Goals that follow an outcome component: goals[row, col] = slot + (achieved[src] - anchor)
        follow = [
            (i, c, self.slices[i].start + k, m.goal_anchor[c])
            for i, m in enumerate(self.modules)
            for c, k in m.goal_follow
        ]
        self._follow_row = np.array([f[0] for f in follow], dtype=np.intp)
        self._follow_col = np.array([f[1] for f in follow], dtype=np.intp)
        self._follow_src = np.array([f[2] for f in follow], dtype=np.intp)
        self._follow_anchor = np.array([f[3] for f in follow], dtype=np.float32)

        reaching = [i for i, m in enumerate(self.modules) if m.reaches_slot]
        self._reaching = np.array(reaching, dtype=np.intp)
        self._reaching_first3 = np.array(
            [np.arange(self.slices[i].start, self.slices[i].start + 3) for i in reaching],
            dtype=np.intp,
        ).reshape(len(reaching), 3)
        self._guards = [
            (j, i, self.modules[i].guard_fn, self.slices[i])
            for j, i in enumerate(reaching)
            if self.modules[i].guard_fn is not None
        ]
        self._custom = [
            (i, m, self.slices[i]) for i, m in enumerate(self.modules) if not m.reaches_slot
        ]

        # Row-wise tables (`row_goals`, `row_success`): per module, the outcome column that each
        # goal coordinate follows (-1: none) and its anchor, and its first three outcome columns.
        n_mod = len(self.modules)
        self._follow_table = np.full((n_mod, 3), -1, np.intp)
        self._anchor_table = np.zeros((n_mod, 3), np.float32)
        for i, c, src, anchor in follow:
            if self._follow_table[i, c] >= 0:
                raise ValueError(f"{self.modules[i].name}: goal coordinate {c} follows twice")
            self._follow_table[i, c], self._anchor_table[i, c] = src, anchor
        self._first3_table = np.array([np.arange(sl.start, sl.start + 3) for sl in self.slices])
        self._reaches = np.array([m.reaches_slot for m in self.modules], bool)

    def set_slots(self, slots: np.ndarray) -> None:
        """The goal slot (n_modules, 3) each module is judged against from now on."""
        self._slots[:] = slots

    def evaluate(self, positions: np.ndarray, gripper: np.ndarray, cubes: np.ndarray) -> None:
        """Fill `achieved`, `goals` and `success` (1.0 / 0.0) from the positions.

        Args:
            positions: [gripper, cube 1, ..., cube n], flat (3 + 3 n_cubes,).
            gripper: (3,) and cubes: (n_cubes, 3), the same numbers (views are fine).
        """
        self._evaluate(
            positions[None], gripper[None], cubes[None], self._slots[None],
            self.achieved[None], self.goals[None], self.success[None],
        )  # fmt: skip

    def row_goals(self, modules: np.ndarray, slots: np.ndarray, achieved: np.ndarray) -> np.ndarray:
        """Each row's goal (n, 3) float32 for its own module: row i's slot (n, 3) for module
        `modules[i]`, placed where outcomes `achieved` (n, sum of outcome dims) put it
        (`TaskModule.goal` row by row, the same float32 numbers, in one pass over all rows)."""
        modules = np.asarray(modules, np.intp)
        goals = np.array(slots, dtype=np.float32)
        src = self._follow_table[modules]  # (n, 3)
        follows = src >= 0
        if follows.any():
            rows, cols = np.nonzero(follows)
            goals[rows, cols] += (
                achieved[rows, src[rows, cols]] - self._anchor_table[modules[rows], cols]
            )
        for i, m, sl in self._custom:
            sel = np.flatnonzero(modules == i)
            if sel.size:
                goals[sel] = m.goal(slots[sel], achieved[sel, sl])
        return goals

    def row_success(
        self, modules: np.ndarray, achieved: np.ndarray, goals: np.ndarray
    ) -> np.ndarray:
        """(n,) bool: whether each row's outcomes (n, sum of outcome dims) meet its goal (n, 3)
        for its own module (`TaskModule.success` row by row, the same verdicts)."""
        modules = np.asarray(modules, np.intp)
        first3 = achieved[np.arange(len(modules))[:, None], self._first3_table[modules]]
        ok = within_distance(first3, goals) & self._reaches[modules]
        for _, i, guard, sl in self._guards:
            sel = np.flatnonzero(modules == i)
            if sel.size:
                ok[sel] &= guard(achieved[sel, sl], goals[sel])
        for i, m, sl in self._custom:
            sel = np.flatnonzero(modules == i)
            if sel.size:
                ok[sel] = m.success_fn(achieved[sel, sl], goals[sel])
        return ok

    def _evaluate(
        self,
        positions: np.ndarray,
        gripper: np.ndarray,
        cubes: np.ndarray,
        slots: np.ndarray,
        achieved: np.ndarray,
        goals: np.ndarray,
        success: np.ndarray,
    ) -> None:
        """Outcomes, goals and successes of n copies into `achieved`, `goals` and `success`
        ((n, ...) each) from their positions (n, 3 + 3 n_cubes), gripper (n, 3), cubes
        (n, n_cubes, 3) and goal slots (n, n_modules, 3).

        A linear component with one term (every suite module's) is one product, rounded once
        whatever the order of the matrix product's sums, so all copies take one product;
        components that sum several terms take each copy's own product, whose rounding depends
        on how it is computed. The rest are element-wise operations over the leading axis."""
        w = self._linear_matrix
        if self._one_term:
            achieved[:, self._linear_rows] = positions @ w.T
        else:
            achieved[:, self._linear_rows] = np.stack([w @ p for p in positions])
        for fn, sl in self._extras:
            achieved[:, sl] = fn(gripper, cubes)
        for fn, sl in self._functional:
            achieved[:, sl] = fn(gripper, cubes)
        goals[:] = slots
        if len(self._follow_row):
            goals[:, self._follow_row, self._follow_col] += (
                achieved[:, self._follow_src] - self._follow_anchor
            )
        if len(self._reaching):
            ok = within_distance(achieved[:, self._reaching_first3], goals[:, self._reaching])
            for j, i, guard, sl in self._guards:
                ok[:, j] &= guard(achieved[:, sl], goals[:, i])
            success[:, self._reaching] = ok
        for i, m, sl in self._custom:
            goals[:, i] = m.goal(slots[:, i], achieved[:, sl])
            success[:, i] = m.success_fn(achieved[:, sl], goals[:, i])
