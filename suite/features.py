"""The `state` observation: its layout and its vectorised computation from MuJoCo's arrays.

The layout (10 + 3 n_cubes + 12 n_reachable features: 49 for the paper's two reachable cubes and
three distractors) follows the paper's description and the Fetch envs' conventions: positions in
the world frame, orientations as (roll, pitch, yaw), and velocities multiplied by the control
timestep (i.e. displacements per env step). Only the reachable cubes (the first n_reachable)
contribute more than their position. docs/suite.md has the table.

The reader reports what the sensors see: the true positions plus an optional bias
(`StateReader.position_bias`, the sensory failure), from which every position-derived feature
and every outcome is computed.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from suite import layout

_SITE = int(mujoco.mjtObj.mjOBJ_SITE)
_BODY = int(mujoco.mjtObj.mjOBJ_BODY)


@dataclass(frozen=True)
class StateLayout:
    """Where each group of features sits in the `state` vector for `n_cubes` cubes, the first
    `n_reachable` of them reachable."""

    n_cubes: int
    n_reachable: int = 2

    def __post_init__(self) -> None:
        if not 0 < self.n_reachable <= self.n_cubes:
            raise ValueError(
                f"need 1 <= n_reachable <= n_cubes, got {self.n_reachable} and {self.n_cubes}"
            )

    @property
    def size(self) -> int:
        return 10 + 3 * self.n_cubes + 12 * self.n_reachable

    @property
    def gripper_pos(self) -> slice:
        """Grip site position (x, y, z)."""
        return slice(0, 3)

    @property
    def cube_pos(self) -> slice:
        """Positions of cubes 1..n, (x, y, z) each."""
        return slice(3, 3 + 3 * self.n_cubes)

    def _after_cubes(self, start: int, width: int) -> slice:
        o = 3 + 3 * self.n_cubes + start
        return slice(o, o + width)

    @property
    def cube_rel_pos(self) -> slice:
        """Each reachable cube minus the gripper position, (x, y, z) each."""
        return self._after_cubes(0, 3 * self.n_reachable)

    @property
    def finger_pos(self) -> slice:
        """Right and left finger joint positions (0 closed, 0.05 open)."""
        return self._after_cubes(3 * self.n_reachable, 2)

    @property
    def cube_euler(self) -> slice:
        """Each reachable cube's orientation as (roll, pitch, yaw) in radians."""
        return self._after_cubes(3 * self.n_reachable + 2, 3 * self.n_reachable)

    @property
    def cube_vel(self) -> slice:
        """Each reachable cube's velocity in the world frame, (angular xyz, linear xyz), times
        the control timestep; the linear one relative to the grip site's (the cube's minus the
        gripper's, as the authors' `object0_velp -= grip_velp`, gym_flowers
        multi_task_fetch_arm_v0.py `_get_obs`)."""
        return self._after_cubes(6 * self.n_reachable + 2, 6 * self.n_reachable)

    @property
    def gripper_vel(self) -> slice:
        """Grip site linear velocity in the world frame, times the control timestep."""
        return self._after_cubes(12 * self.n_reachable + 2, 3)

    @property
    def finger_vel(self) -> slice:
        """Right and left finger joint velocities, times the control timestep."""
        return self._after_cubes(12 * self.n_reachable + 5, 2)

    def cube_x_indices(self, cube: int) -> tuple[int, ...]:
        """Indices of the features that carry cube `cube`'s (0-based) x position: its position
        and, for a reachable cube, its position relative to the gripper."""
        idx = [self.cube_pos.start + 3 * cube]
        if cube < self.n_reachable:
            idx.append(self.cube_rel_pos.start + 3 * cube)
        return tuple(idx)

    def groups(self) -> list[tuple[str, slice]]:
        """(name, slice) of every feature group, in order."""
        return [
            ("gripper_pos", self.gripper_pos),
            ("cube_pos", self.cube_pos),
            ("cube_rel_pos", self.cube_rel_pos),
            ("finger_pos", self.finger_pos),
            ("cube_euler", self.cube_euler),
            ("cube_vel", self.cube_vel),
            ("gripper_vel", self.gripper_vel),
            ("finger_vel", self.finger_vel),
        ]

    def scale(self) -> np.ndarray:
        """Per-feature factors from the raw quantities the reader collects: the control timestep
        for velocities, -1 for the pitch entries (read as atan2(R20, ...))."""
        scale = np.ones(self.size)
        dt = layout.CONTROL_TIMESTEP
        for group in (self.cube_vel, self.gripper_vel, self.finger_vel):
            scale[group] = dt
        scale[self.cube_euler.start + 1 : self.cube_euler.stop : 3] = -1.0  # the pitches
        return scale


class StateReader:
    """Fills a preallocated state vector from one physics, with precomputed indices.

    Expects up-to-date position and velocity stages (after `mj_forward`, or after composer's
    default stepping, which ends every control step with `mj_step1`).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        *,
        grip_site: int,
        reach_bodies: np.ndarray,
        reach_qpos: np.ndarray,
        distractor_pos: np.ndarray,
        finger_qpos: slice,
        finger_qvel: slice,
    ) -> None:
        """Bind to `model`/`data`.

        Args:
            grip_site: id of the grip site.
            reach_bodies: body ids of the reachable cubes (cubes 1, 2, ...).
            reach_qpos: (n_reachable, 7) view of their free joints' qpos.
            distractor_pos: (n_distractors, 3) view of the distractors' mocap positions.
            finger_qpos, finger_qvel: where the two finger joints sit in qpos and qvel
                (consecutive, so that the reader can hold views).
        """
        if not isinstance(finger_qpos, slice) or not isinstance(finger_qvel, slice):
            raise TypeError("the finger joints must be consecutive in qpos and qvel (slices)")
        self._n_reach = n_reach = len(reach_bodies)
        self.layout = StateLayout(n_reach + len(distractor_pos), n_reach)
        self.position_bias: np.ndarray | None = None
        """Added to the true positions as they are read (flat, shaped like `positions`): a
        sensory failure; None reads the truth."""
        self._model = model
        self._data = data
        self._grip_site = int(grip_site)
        self._reach_bodies = np.asarray(reach_bodies, dtype=np.intp)
        self._reach_body_ids = [int(b) for b in reach_bodies]
        self._reach_qpos = reach_qpos
        self._distractor_pos = distractor_pos
        self._grip_vel = np.zeros(6)  # grip site (angular, linear)
        self.raw = np.zeros(self.layout.size)
        self._scale = self.layout.scale()
        lay = self.layout
        b = self.raw
        self._b_positions = b[: lay.cube_pos.stop]
        self._b_grip = b[lay.gripper_pos]
        self._b_pos = b[lay.cube_pos].reshape(-1, 3)
        self._b_reach_pos = self._b_pos[: self._n_reach]
        self._b_distractor_pos = self._b_pos[self._n_reach :]
        self._b_rel = b[lay.cube_rel_pos].reshape(n_reach, 3)
        self._b_fingers = b[lay.finger_pos]
        self._b_euler = b[lay.cube_euler].reshape(n_reach, 3)
        # (body id, its row of the velocity buffer) for mj_objectVelocity.
        self._cube_vel_rows = list(
            zip(self._reach_body_ids, b[lay.cube_vel].reshape(n_reach, 6), strict=True)
        )
        # The linear halves of those rows: made relative to the grip site's velocity.
        self._b_cube_lin_vel = b[lay.cube_vel].reshape(n_reach, 6)[:, 3:]
        self._b_grip_vel = b[lay.gripper_vel]
        self._b_finger_vel = b[lay.finger_vel]
        # Views into MuJoCo's arrays (stable for the life of `data`).
        self._grip_xpos = data.site_xpos[self._grip_site]
        self._reach_pos = reach_qpos[:, :3]
        self._finger_q = data.qpos[finger_qpos]
        self._finger_v = data.qvel[finger_qvel]
        first = int(self._reach_bodies[0])
        consecutive = bool(np.all(np.diff(self._reach_bodies) == 1))
        self._reach_xmat = data.xmat[first : first + n_reach] if consecutive else None

    def read(self, out: np.ndarray) -> np.ndarray:
        """Compute the state features into `out` (float32, layout size) and return it.

        The raw quantities are gathered in float64 (`self.raw`, which also keeps the positions
        as perceived) and scaled into `out` in one pass.
        """
        self._b_grip[:] = self._grip_xpos
        self._b_reach_pos[:] = self._reach_pos
        self._b_distractor_pos[:] = self._distractor_pos
        if self.position_bias is not None:
            self._b_positions += self.position_bias
        np.subtract(self._b_reach_pos, self._b_grip, out=self._b_rel)
        self._b_fingers[:] = self._finger_q

        # Orientation from the rotation matrices R (rows of 9): roll = atan2(R21, R22),
        # pitch = -atan2(R20, hypot(R21, R22)) (the sign comes with the scale), yaw =
        # atan2(R10, R00).
        xm = self._reach_xmat
        if xm is None:
            xm = self._data.xmat[self._reach_bodies]
        euler = self._b_euler
        np.arctan2(xm[:, 7], xm[:, 8], out=euler[:, 0])
        np.hypot(xm[:, 7], xm[:, 8], out=euler[:, 1])
        np.arctan2(xm[:, 6], euler[:, 1], out=euler[:, 1])
        np.arctan2(xm[:, 3], xm[:, 0], out=euler[:, 2])

        m, d = self._model, self._data
        for body, row in self._cube_vel_rows:
            mujoco.mj_objectVelocity(m, d, _BODY, body, row, 0)
        mujoco.mj_objectVelocity(m, d, _SITE, self._grip_site, self._grip_vel, 0)
        self._b_grip_vel[:] = self._grip_vel[3:]
        self._b_cube_lin_vel -= self._b_grip_vel
        self._b_finger_vel[:] = self._finger_v
        np.multiply(self.raw, self._scale, out=out)
        return out

    @property
    def positions(self) -> np.ndarray:
        """[gripper, cube 1, ..., cube n] positions as perceived (the truth plus
        `position_bias`), flat (3 + 3 n_cubes,), float64, from the last `read` (a view)."""
        return self._b_positions

    @property
    def gripper(self) -> np.ndarray:
        """The grip site position as perceived, from the last `read` (a view)."""
        return self._b_grip

    @property
    def cubes(self) -> np.ndarray:
        """The (n_cubes, 3) cube positions as perceived, from the last `read` (a view)."""
        return self._b_pos
