"""`LockstepTask`: many copies of one suite variant stepped together, the task's work around the
physics vectorised over the copies and the physics in MuJoCo's threads.

A control step of some of the copies (the first n, or any `ids`):

1. the actions become mocap targets and finger commands for all copies at once (what
   `MultiTaskFetch.before_step` does for one), and the distractors of all copies take a step of
   their random walks (`suite.distractors.step_walks`: each copy's moves, drawn at its reset,
   in one array; a copy whose move ends too close to another cube redraws from its own random
   state);
2. one call advances every copy's physics by the control step's substeps on native threads
   (`suite.lockstep_physics`);
3. the state features, outcomes and successes of all copies come from the physics' fields
   stacked over the copies, in a few numpy operations (`StackedStateReader`,
   `ModuleEvaluator.evaluate_stacked`).

Why vectorised: per copy, `before_step` costs ~30 us and the observation ~90 us on a 2-core
machine (its physics ~600 us of CPU), so with the physics on two threads the copy-by-copy
Python would add about a third to a step; stacked, it is about a millisecond for 38 copies.

Resets stay each copy's own (`env.reset()` of its composer environment: cube placement, goals,
distractor starts, from the copy's random state, once per episode); `load` then hands the reset
state to the physics. While the copies step here their own MjData fall behind; `sync` brings
one up to date, for an observer that reads it.

A variant is stepped here only if its control step is the task's `before_step`, one physics
call and its `after_step`: nothing else acting at a step or between substeps
(`SuiteEnvironment.single_call_stepping`, `foreign_step_hooks`), composer's legacy stepping,
and `MultiTaskFetch`'s own step hooks. Anything else is a ValueError saying what.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from suite import layout
from suite.distractors import step_walks
from suite.environment import SuiteEnvironment
from suite.features import StackedStateReader
from suite.lockstep_physics import LockstepPhysics
from suite.outcomes import ModuleEvaluator
from suite.task import MultiTaskFetch


def lockstep_problem(env: object) -> str | None:
    """Why `env` cannot be stepped in lockstep, or None if it can."""
    if not isinstance(env, SuiteEnvironment):
        return f"a {type(env).__name__}, not a SuiteEnvironment (stock composer?)"
    task = env.task
    if not isinstance(task, MultiTaskFetch):
        return f"its task is a {type(task).__name__}, not a MultiTaskFetch"
    for hook in ("before_step", "after_step", "before_substep", "after_substep"):
        if getattr(type(task), hook) is not getattr(MultiTaskFetch, hook):
            return f"its task overrides {hook}"
    foreign = env.foreign_step_hooks()
    if foreign:
        return f"something besides the task acts at {', '.join(foreign)}"
    if not env.single_call_stepping:
        return "its control step is not one physics call (substep hooks or observables)"
    if not env.legacy_stepping:
        return "it does not use composer's legacy stepping"
    return None


class LockstepTask:
    """Copies of one suite variant (composer environments from `suite.load`) stepped together on
    `nthread` threads (see the module docstring)."""

    def __init__(self, envs: Sequence[SuiteEnvironment], nthread: int) -> None:
        self.envs = list(envs)
        if not self.envs:
            raise ValueError("no copies to step")
        for i, env in enumerate(self.envs):
            problem = lockstep_problem(env)
            if problem is not None:
                raise ValueError(f"copy {i} cannot be stepped in lockstep: {problem}")
        self.tasks: list[MultiTaskFetch] = [env.task for env in self.envs]
        first = self.tasks[0]
        self.bindings = first.bindings
        key = (first.module_names, first.n_cubes, first.physics_steps_per_control_step)
        for i, task in enumerate(self.tasks):
            other = (task.module_names, task.n_cubes, task.physics_steps_per_control_step)
            if other != key or task.bindings != self.bindings:
                raise ValueError(f"copy {i} is not the same variant as copy 0")
        model = self.envs[0].physics.model.ptr
        self.physics = LockstepPhysics(
            [env.physics.model.ptr for env in self.envs],
            first.physics_steps_per_control_step,
            nthread,
        )
        b = self.bindings
        self._reader = StackedStateReader(
            model,
            grip_site=b.grip_site,
            reach_bodies=b.reach_bodies,
            reach_qpos=b.reach_qpos,
            distractor_mocap=b.distractor_mocap,
            n_distractors=b.n_distractors,
            finger_qpos=b.finger_qpos,
            finger_qvel=b.finger_qvel,
        )
        self._evaluator = ModuleEvaluator(first.modules, first.n_cubes)
        self._slots = np.zeros((len(self.envs), len(first.modules), 3), np.float32)
        self._reach_qpos = slice(b.reach_qpos, b.reach_qpos + 7 * len(b.reach_bodies))
        self._distractors = slice(b.distractor_mocap, b.distractor_mocap + b.n_distractors)
        self._failing = first.has_sensor_failure
        self._walks = [task.distractor_walk for task in self.tasks]
        self._random_states = [env.random_state for env in self.envs]

    def __len__(self) -> int:
        return len(self.envs)

    def load(self, ids: Sequence[int]) -> None:
        """Copies `ids` start from their own MjData, just reset by their environment."""
        if self.physics.closed:
            raise RuntimeError("the lockstep copies were closed")
        for i in ids:
            self.physics.load(i, self.envs[i].physics.data.ptr)
            self._slots[i] = self.tasks[i].goal_slots
        self.physics.refresh(ids)

    def step(
        self, actions: np.ndarray, ids: Sequence[int] | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One control step of copies `ids` (default: the first len(actions)), each with its row
        of `actions`: their (state (n, S) float32, achieved (n, sum of outcome dims) float32,
        success (n, n_modules) bool), in the order of `ids`."""
        if self.physics.closed:
            raise RuntimeError("the lockstep copies were closed")
        a = self._check(actions)
        n = len(a)
        sel = np.arange(n) if ids is None else np.asarray(ids, dtype=np.intp)
        if sel.shape != (n,) or len(np.unique(sel)) != n or sel.min() < 0 or sel.max() >= len(self):
            raise ValueError(f"ids must name {n} distinct copies of 0..{len(self) - 1}")
        order = np.argsort(sel, kind="stable")  # the physics steps copies in ascending order
        if np.any(order != np.arange(n)):
            out = self.step(a[order], sel[order])
            back = np.argsort(order)
            return out[0][back], out[1][back], out[2][back]
        ph, b = self.physics, self.bindings
        mocap = ph.mocap_pos[sel]
        ctrl = ph.ctrl[sel]
        gripper = ph.outputs["xpos"][sel, b.gripper_body]
        mocap[:, b.arm_mocap] = gripper + a[:, :3] * layout.MAX_GRIPPER_DISPLACEMENT
        ctrl[:, b.finger_ctrl] = ph.qpos[sel, b.finger_qpos] + a[:, 3:]
        if b.n_distractors:
            reach_xy = ph.qpos[sel][:, self._reach_qpos].reshape(n, -1, 7)[..., :2]
            walking = mocap[:, self._distractors, :2]
            walks = [self._walks[i] for i in sel]
            states = [self._random_states[i] for i in sel]
            walking[:] = step_walks(walks, reach_xy, walking, states)
        ph.advance(ctrl, mocap, sel)
        fields = {name: values[sel] for name, values in ph.outputs.items()}
        state, positions = self._reader.read(
            fields, ph.qpos[sel], ph.qvel[sel], ph.mocap_pos[sel], self._biases(sel)
        )
        achieved, success = self._evaluator.evaluate_stacked(positions, self._slots[sel])
        return state, achieved, success

    def _check(self, actions: np.ndarray) -> np.ndarray:
        """Actions as `MultiTaskFetch.before_step` takes them: finite, clipped to [-1, 1]."""
        a = np.asarray(actions, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != 4 or not 0 < len(a) <= len(self):
            raise ValueError(
                f"actions must have shape (n, 4) with n in 1..{len(self)}, got {a.shape}"
            )
        if not np.all((a >= -1.0) & (a <= 1.0)):
            bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
            if len(bad):
                raise ValueError(f"actions must be finite; copies {bad.tolist()} are not")
            a = np.clip(a, -1.0, 1.0)
        return a

    def _biases(self, sel: np.ndarray) -> np.ndarray | None:
        """What the sensors of copies `sel` add to the true positions (the sensory failure), or
        None where no copy's failure is on."""
        if not self._failing:
            return None
        biases = [self.tasks[i].position_bias for i in sel]
        if all(bias is None for bias in biases):
            return None
        width = 3 + 3 * self.tasks[0].n_cubes
        zero = np.zeros(width)
        return np.stack([zero if bias is None else bias for bias in biases])

    def sync(self, i: int) -> None:
        """Copy i's own MjData takes the state and derived fields of its last step here."""
        self.physics.copy_to(i, self.envs[i].physics.data.ptr)

    def close(self) -> None:
        """Release the physics' threads."""
        self.physics.close()
