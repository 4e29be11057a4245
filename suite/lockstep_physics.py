"""`LockstepPhysics`: the physics of many copies of one suite model, advanced together in MuJoCo's
own thread pool, one control step per call.

Each copy is a row of a persistent `mujoco.batch.Batch`: its complete `mjSTATE_INTEGRATION`
state (positions, velocities, the constraint solver's warm start, controls, mocap poses), held
in one MjData per copy. `advance` runs a control step of some of the copies in one call on
`nthread` native threads that do not hold the GIL, exactly as `SuiteEnvironment` steps one copy
(composer's legacy stepping: `mj_step2`, `mj_step` for the other substeps, `mj_step1`):

* `Batch.rollout` over the substeps with controls per substep (`mjSTATE_CTRL |
  mjSTATE_MOCAP_POS`). The legacy order finishes, with this step's controls, a step whose
  position stage the previous control step computed, before the task moved the mocap bodies:
  so the first substep gets the new `ctrl` but the mocap positions the rows hold (those of the
  last step, or of the reset), and the other substeps the new ones. `mj_step` recomputes that
  position stage from the same numbers, so the result is bit for bit the legacy one.
* `Batch.forward(stage=mjSTAGE_VEL)`: what the closing `mj_step1` leaves up to date (the
  positions and velocities the observation reads).

That closing stage is the only work beyond the bare substeps (the next step's first substep
computes it again, from the same numbers): about 5% more CPU than `mujoco.rollout` stepping the
same copies, on `default`.

MuJoCo warnings raised in a copy (a diverging simulation) are dm_control's `PhysicsError`
naming the copies, as `SuiteEnvironment` raises it for one.

Why not `mujoco.rollout`: it steps copies in the same thread pool, but starts every call from a
`mjSTATE_FULLPHYSICS` state and returns only such states, so the solver's warm start
(`qacc_warmstart`) is lost between control steps; the Newton solver then converges to
slightly different accelerations (1e-10 in qpos after 20 steps, 1e-8 in the state after 50 on
`default`, growing with contacts), and the positions and velocities the observation reads would
need an `mj_step1` per copy in the calling thread. The batch keeps the whole state and computes
those stages in its threads.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import mujoco
import numpy as np
from dm_control.rl import control
from mujoco import batch as mujoco_batch

_INTEGRATION = mujoco.mjtState.mjSTATE_INTEGRATION
_CONTROLS = int(mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_MOCAP_POS)
_VELOCITY_STAGE = int(mujoco.mjtStage.mjSTAGE_VEL)
_OUTPUTS = ("xpos", "xipos", "xmat", "cvel", "subtree_com", "site_xpos")
"""The derived fields copied out after every call, (n_copies, ...) each."""


class LockstepPhysics:
    """`len(models)` copies of one model (same sizes), `substeps` physics steps per control step,
    on `nthread` threads (the calling one included)."""

    def __init__(self, models: Sequence[mujoco.MjModel], substeps: int, nthread: int) -> None:
        if not models:
            raise ValueError("no copies to step")
        if substeps < 1 or nthread < 1:
            raise ValueError(f"substeps and nthread must be positive, got {substeps}, {nthread}")
        self.models = list(models)
        self.substeps = substeps
        model = self.models[0]
        self._batch: mujoco_batch.Batch | None = mujoco_batch.Batch(
            model, len(self.models), nthread, persistent=True
        )
        self.shared_model = _shared(self.models)
        """The one model every copy runs on where all copies' models are the same (then one
        model in cache serves them all: ~10% less time a step than a model per copy, on
        `default`); None where they differ, and each copy runs on its own."""
        if self.shared_model is None:
            self._batch.set_models(self.models)
        b = self._batch
        self.nthread = b.nthread
        self.state = b.state
        """(n_copies, mj_stateSize(mjSTATE_INTEGRATION)): each copy's complete state."""
        self.qpos, self.qvel = b.bind("qpos"), b.bind("qvel")
        self.ctrl, self.mocap_pos = b.bind("ctrl"), b.bind("mocap_pos")
        self.outputs = {name: b.bind(name) for name in _OUTPUTS}
        """Derived fields after each copy's last call: positions and velocities up to date."""
        self._warnings = b.warning[..., 1]  # (n_copies, mjNWARNING) counts
        width = mujoco.mj_stateSize(model, _CONTROLS)
        if width != model.nu + 3 * model.nmocap:
            raise ValueError(f"unexpected size {width} of the controls (ctrl, mocap_pos)")
        self._control = np.empty((len(self.models), substeps, width))
        self._nu = model.nu

    def __len__(self) -> int:
        return len(self.models)

    def _live(self) -> mujoco_batch.Batch:
        """The batch; a RuntimeError once closed."""
        if self._batch is None:
            raise RuntimeError("the physics was closed")
        return self._batch

    @property
    def closed(self) -> bool:
        return self._batch is None

    def load(self, i: int, data: mujoco.MjData) -> None:
        """Copy i takes the complete state of `data` (an MjData of its model); `refresh` then
        computes what the state implies."""
        self._live()
        mujoco.mj_getState(self.models[i], data, self.state[i], _INTEGRATION)

    def refresh(self, ids: Sequence[int]) -> None:
        """Position- and velocity-dependent fields of copies `ids` from their state."""
        self._check(ids, lambda b, sel: b.forward(sel, stage=_VELOCITY_STAGE))

    def advance(
        self, ctrl: np.ndarray, mocap_pos: np.ndarray, ids: np.ndarray | None = None
    ) -> None:
        """One control step of copies `ids` (default: the first n = len(ctrl)) with this step's
        controls: `ctrl` (n, nu) and `mocap_pos` (n, nmocap, 3), a row per copy of `ids` (see
        the module docstring)."""
        self._live()
        n = len(ctrl)
        if not 0 < n <= len(self):
            raise ValueError(f"can step 1..{len(self)} copies, got {n}")
        sel = np.arange(n) if ids is None else np.asarray(ids, dtype=np.intp)
        c = self._control[:n]
        nu = self._nu
        c[:, :, :nu] = ctrl[:, None]
        c[:, 0, nu:] = self.mocap_pos[sel].reshape(n, -1)
        c[:, 1:, nu:] = mocap_pos.reshape(n, 1, -1)

        def step(b: mujoco_batch.Batch, sel: np.ndarray | None) -> None:
            b.rollout(self.substeps, c, _CONTROLS, record=(), ids=sel)
            b.forward(sel, stage=_VELOCITY_STAGE)

        self._check(sel, step)

    def _check(
        self,
        ids: Sequence[int],
        call: Callable[[mujoco_batch.Batch, np.ndarray | None], None],
    ) -> None:
        """Run `call(batch, selection)` on copies `ids`; a MuJoCo warning raised in any of them
        is a `PhysicsError` naming them."""
        b = self._live()
        sel = np.asarray(ids, dtype=np.int32)
        if len(sel) == 0:
            return
        whole = len(sel) == len(self) and bool(np.all(sel == np.arange(len(self))))
        before = self._warnings[sel].sum(axis=1)
        try:
            call(b, None if whole else sel)
        except mujoco_batch.SimulationError as error:
            raise control.PhysicsError(f"copies {error.ids.tolist()}: {error}") from error
        risen = sel[self._warnings[sel].sum(axis=1) > before]
        if len(risen):
            names = [
                kind
                for kind, count in zip(
                    mujoco.mjtWarning.__members__, self._warnings[risen].sum(axis=0), strict=False
                )
                if count
            ]
            raise control.PhysicsError(
                f"Physics state is invalid in copies {risen.tolist()}. Warning(s) raised: "
                + ", ".join(names)
            )

    def copy_to(self, i: int, data: mujoco.MjData) -> None:
        """Write copy i's whole MjData (state and derived fields) into `data`, for an observer
        that reads the copy's own simulator."""
        self._live().get_data(i, data)

    def close(self) -> None:
        """Release the thread pool (and the copies' MjData); further calls raise."""
        # The bound arrays keep the batch's memory alive; dropping them and the batch lets it
        # join its threads.
        self._batch = None
        none = np.empty(0)
        self.state = self.qpos = self.qvel = self.ctrl = self.mocap_pos = none
        self.outputs = {}
        self._warnings = none


def _shared(models: Sequence[mujoco.MjModel]) -> mujoco.MjModel | None:
    """`models[0]` where every model is the same as it (their binary MJB bytes equal), else
    None."""
    first = _model_bytes(models[0])
    if all(np.array_equal(first, _model_bytes(m)) for m in models[1:]):
        return models[0]
    return None


def _model_bytes(model: mujoco.MjModel) -> np.ndarray:
    buffer = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer
