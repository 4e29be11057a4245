"""The `state` observation: its layout and its vectorised computation from MuJoCo's arrays.

The layout (34 + 3 n_cubes features; 49 for five cubes) follows the paper's description and the
Fetch envs' feature conventions (velocities are multiplied by the control timestep, i.e. they
are displacements per env step; cube velocities are relative to the gripper's). Only cubes 1
and 2 (the reachable ones) contribute more than their position. docs/suite.md has the table.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from suite import layout


@dataclass(frozen=True)
class StateLayout:
    """Where each group of features sits in the `state` vector for `n_cubes` cubes."""

    n_cubes: int

    @property
    def size(self) -> int:
        return 34 + 3 * self.n_cubes

    @property
    def gripper_pos(self) -> slice:
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
        """Cubes 1 and 2 minus the gripper position."""
        return self._after_cubes(0, 6)

    @property
    def finger_pos(self) -> slice:
        """Right and left finger joint positions (0 closed, 0.05 open)."""
        return self._after_cubes(6, 2)

    @property
    def cube_euler(self) -> slice:
        """Cubes 1 and 2 orientation as (roll, pitch, yaw), radians."""
        return self._after_cubes(8, 6)

    @property
    def cube_rel_vel(self) -> slice:
        """Cubes 1 and 2 linear velocity minus the gripper's, times the control timestep."""
        return self._after_cubes(14, 6)

    @property
    def cube_ang_vel(self) -> slice:
        """Cubes 1 and 2 angular velocity (world frame), times the control timestep."""
        return self._after_cubes(20, 6)

    @property
    def gripper_vel(self) -> slice:
        """Grip site linear velocity, times the control timestep."""
        return self._after_cubes(26, 3)

    @property
    def finger_vel(self) -> slice:
        """Right and left finger joint velocities, times the control timestep."""
        return self._after_cubes(29, 2)

    def cube_x_indices(self, cube: int) -> tuple[int, ...]:
        """Indices of features that carry cube `cube`'s (0-based) observed x position."""
        idx = [self.cube_pos.start + 3 * cube]
        if cube < 2:
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
            ("cube_rel_vel", self.cube_rel_vel),
            ("cube_ang_vel", self.cube_ang_vel),
            ("gripper_vel", self.gripper_vel),
            ("finger_vel", self.finger_vel),
        ]


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
        finger_qpos: slice | np.ndarray,
        finger_qvel: slice | np.ndarray,
    ) -> None:
        """Bind to `model`/`data`.

        Args:
            grip_site: id of the grip site.
            reach_bodies: body ids of cubes 1 and 2.
            reach_qpos: (2, 7) view of their free joints' qpos.
            distractor_pos: (n_distractors, 3) view of the distractors' mocap positions.
            finger_qpos, finger_qvel: where the two finger joints sit in qpos and qvel.
        """
        self._n_reach = len(reach_bodies)
        self.layout = StateLayout(self._n_reach + len(distractor_pos))
        self._model = model
        self._data = data
        self._site_xpos = data.site_xpos
        self._xmat = data.xmat
        self._qpos = data.qpos
        self._qvel = data.qvel
        self._grip_site = int(grip_site)
        self._reach_bodies = np.asarray(reach_bodies, dtype=np.intp)
        self._reach_body_ids = [int(b) for b in reach_bodies]
        self._reach_qpos = reach_qpos
        self._distractor_pos = distractor_pos
        self._finger_qpos = finger_qpos
        self._finger_qvel = finger_qvel
        self._dt = layout.CONTROL_TIMESTEP
        self._vel = np.zeros((3, 6))  # [grip site, cube 1, cube 2] x (angular, linear)
        self.buffer = np.zeros(self.layout.size)
        lay = self.layout
        b = self.buffer
        self._b_positions = b[: lay.cube_pos.stop]
        self._b_grip = b[lay.gripper_pos]
        self._b_pos = b[lay.cube_pos].reshape(-1, 3)
        self._b_rel = b[lay.cube_rel_pos].reshape(2, 3)
        self._b_fingers = b[lay.finger_pos]
        self._b_euler = b[lay.cube_euler].reshape(2, 3)
        self._b_rel_vel = b[lay.cube_rel_vel].reshape(2, 3)
        self._b_ang_vel = b[lay.cube_ang_vel].reshape(2, 3)
        self._b_grip_vel = b[lay.gripper_vel]
        self._b_finger_vel = b[lay.finger_vel]

    def read(self) -> np.ndarray:
        """Compute the state features into `self.buffer` (float64) and return it."""
        m, d, vel, dt = self._model, self._data, self._vel, self._dt
        grip = self._b_grip
        grip[:] = self._site_xpos[self._grip_site]
        pos = self._b_pos
        pos[: self._n_reach] = self._reach_qpos[:, :3]
        pos[self._n_reach :] = self._distractor_pos
        np.subtract(pos[:2], grip, out=self._b_rel)
        self._b_fingers[:] = self._qpos[self._finger_qpos]

        xm = self._xmat[self._reach_bodies]
        euler = self._b_euler
        np.arctan2(xm[:, 7], xm[:, 8], out=euler[:, 0])
        np.arcsin(np.clip(-xm[:, 6], -1.0, 1.0), out=euler[:, 1])
        np.arctan2(xm[:, 3], xm[:, 0], out=euler[:, 2])

        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_SITE, self._grip_site, vel[0], 0)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, self._reach_body_ids[0], vel[1], 0)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, self._reach_body_ids[1], vel[2], 0)
        vel *= dt
        np.subtract(vel[1:, 3:], vel[0, 3:], out=self._b_rel_vel)
        self._b_ang_vel[:] = vel[1:, :3]
        self._b_grip_vel[:] = vel[0, 3:]
        np.multiply(self._qvel[self._finger_qvel], dt, out=self._b_finger_vel)
        return self.buffer

    @property
    def positions(self) -> np.ndarray:
        """[gripper, cube 1, ..., cube n] positions, flat (3 + 3 n_cubes,), from the last `read`
        (a view into the buffer)."""
        return self._b_positions

    @property
    def gripper(self) -> np.ndarray:
        """The grip site position from the last `read` (a view into the buffer)."""
        return self._b_grip

    @property
    def cubes(self) -> np.ndarray:
        """The (n_cubes, 3) cube positions from the last `read` (a view into the buffer)."""
        return self._b_pos
