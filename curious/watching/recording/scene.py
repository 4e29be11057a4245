"""MuJoCo scenes in Rerun: static geometry from an `MjModel`, per-step body poses of an episode.

A scene is drawn as one entity per body under `scene/bodies/<body>`, holding that body's pose in
the world frame, with one child entity per visible geom holding the geom's fixed pose in its
body's frame and its shape (a mesh, or a box, sphere, ellipsoid, cylinder, capsule or plane).
The geometry is logged once, as static data; a rollout then only sends the world poses of the
bodies that can move (those with joints in their chain, or mocap bodies), one row per step. This
keeps a 50-step rollout of a ~30-body arm at a few tens of kilobytes.

`SceneLayout` maps a model to entity paths; `RolloutCapture` copies body poses out of an `MjData`
into preallocated arrays while an episode runs (a few microseconds per step), so that the
recorder can log the whole episode in one batch afterwards.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Protocol

import mujoco
import numpy as np
import rerun as rr

__all__ = [
    "DEFAULT_GEOM_GROUPS",
    "SCENE_ROOT",
    "RolloutCapture",
    "SceneLayout",
    "geom_color",
    "log_scene_geometry",
    "wxyz_to_xyzw",
]

SCENE_ROOT = "scene"
BODIES_ROOT = f"{SCENE_ROOT}/bodies"

# MuJoCo draws a geom in its material's colour when the geom keeps the default rgba.
_DEFAULT_GEOM_RGBA = np.array([0.5, 0.5, 0.5, 1.0], dtype=np.float32)
# Size drawn for an infinite plane (MuJoCo plane size 0 means "infinite").
_INFINITE_PLANE_HALF_SIZE = 2.0
_PLANE_HALF_THICKNESS = 0.001

DEFAULT_GEOM_GROUPS: tuple[int, ...] = (0, 1, 2)
_DRAWN_KINDS = (
    mujoco.mjtGeom.mjGEOM_PLANE,
    mujoco.mjtGeom.mjGEOM_SPHERE,
    mujoco.mjtGeom.mjGEOM_CAPSULE,
    mujoco.mjtGeom.mjGEOM_ELLIPSOID,
    mujoco.mjtGeom.mjGEOM_CYLINDER,
    mujoco.mjtGeom.mjGEOM_BOX,
    mujoco.mjtGeom.mjGEOM_MESH,
)

_UNSAFE = re.compile(r"[^A-Za-z0-9_\-]+")


class _PoseSource(Protocol):
    """What `RolloutCapture.record` reads: an `mujoco.MjData` or dm_control's data wrapper."""

    xpos: np.ndarray
    xquat: np.ndarray


def wxyz_to_xyzw(quat: np.ndarray) -> np.ndarray:
    """Reorders quaternions from MuJoCo's (w, x, y, z) to Rerun's (x, y, z, w), any batch shape."""
    quat = np.asarray(quat)
    if quat.shape[-1] != 4:
        raise ValueError(f"quaternions must have a last axis of size 4, got shape {quat.shape}")
    return quat[..., [1, 2, 3, 0]]


def _safe_part(name: str | None, fallback: str) -> str:
    """An entity-path part from a MuJoCo name: unsafe characters ('/', ':') become '_'."""
    if not name:
        return fallback
    return _UNSAFE.sub("_", name).strip("_") or fallback


def _unique_parts(names: list[str | None], prefix: str) -> list[str]:
    """Safe, unique path parts; a clash after sanitising gets the object's index appended."""
    parts = [_safe_part(n, f"{prefix}{i}") for i, n in enumerate(names)]
    seen: dict[str, int] = {}
    for p in parts:
        seen[p] = seen.get(p, 0) + 1
    return [p if seen[p] == 1 else f"{p}_{i}" for i, p in enumerate(parts)]


def _body_moves(model: mujoco.MjModel) -> np.ndarray:
    """(nbody,) bool: True where a body can move (a joint in its chain, or a mocap body)."""
    return (model.body_weldid != 0) | (model.body_mocapid >= 0)


def _drawn_geoms(model: mujoco.MjModel, geom_groups: tuple[int, ...]) -> np.ndarray:
    """(n,) ids of the geoms drawn: in one of `geom_groups`, not fully transparent, a kind
    Rerun can show."""
    groups = np.isin(model.geom_group, np.asarray(geom_groups))
    alpha = np.array([geom_color(model, g)[3] > 0 for g in range(model.ngeom)], dtype=bool)
    kinds = np.isin(model.geom_type, np.asarray(_DRAWN_KINDS))
    return np.flatnonzero(groups & alpha & kinds).astype(np.int64)


@dataclass(frozen=True)
class SceneLayout:
    """Entity paths of a model's bodies and geoms, which geoms are drawn, which bodies move.

    Built from the model's names, so the same model always gives the same paths (recordings of
    two runs on the same environment line up entity by entity). Only bodies that carry a drawn
    geom are posed: a camera frame or an empty mocap body costs nothing per step.
    """

    body_names: tuple[str, ...]
    body_paths: tuple[str, ...]
    geom_paths: tuple[str, ...]
    drawn_geoms: np.ndarray = field(repr=False)  # (n_drawn,) int geom ids
    moving_bodies: np.ndarray = field(repr=False)  # (n_moving,) int body ids with drawn geoms
    static_bodies: np.ndarray = field(repr=False)  # (n_static,) int body ids with drawn geoms

    @classmethod
    def from_model(
        cls, model: mujoco.MjModel, geom_groups: tuple[int, ...] = DEFAULT_GEOM_GROUPS
    ) -> SceneLayout:
        """The layout of `model`: one path per body under `scene/bodies`, geoms below them.

        `geom_groups`: the MuJoCo geom groups drawn (groups 0-2 are MuJoCo's visible default).
        """
        body_names = [
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "" for b in range(model.nbody)
        ]
        body_parts = _unique_parts(body_names, "body")
        body_paths = tuple(f"{BODIES_ROOT}/{p}" for p in body_parts)
        geom_names = [
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(model.ngeom)
        ]
        geom_parts = _unique_parts(geom_names, "geom")
        geom_paths = tuple(
            f"{body_paths[model.geom_bodyid[g]]}/{geom_parts[g]}" for g in range(model.ngeom)
        )
        drawn = _drawn_geoms(model, geom_groups)
        has_geom = np.zeros(model.nbody, dtype=bool)
        has_geom[model.geom_bodyid[drawn]] = True
        moves = _body_moves(model)
        return cls(
            body_names=tuple(body_names),
            body_paths=body_paths,
            geom_paths=geom_paths,
            drawn_geoms=drawn,
            moving_bodies=np.flatnonzero(has_geom & moves).astype(np.int64),
            static_bodies=np.flatnonzero(has_geom & ~moves).astype(np.int64),
        )

    def body_id(self, body: str | int) -> int:
        """A body's id from its name (or id); a clear error names the bodies that exist."""
        if isinstance(body, int | np.integer):
            if not 0 <= int(body) < len(self.body_names):
                raise ValueError(f"body id {body} out of range [0, {len(self.body_names)})")
            return int(body)
        try:
            return self.body_names.index(body)
        except ValueError:
            known = ", ".join(n for n in self.body_names if n)
            raise ValueError(f"no body named {body!r} in the model; bodies: {known}") from None


def geom_color(model: mujoco.MjModel, geom: int) -> np.ndarray:
    """The geom's RGBA as MuJoCo draws it (its material's colour where the geom has the default)."""
    rgba = model.geom_rgba[geom]
    matid = model.geom_matid[geom]
    if matid >= 0 and np.allclose(rgba, _DEFAULT_GEOM_RGBA):
        rgba = model.mat_rgba[matid]
    return np.clip(np.round(np.asarray(rgba) * 255.0), 0, 255).astype(np.uint8)


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (smooth shading in the viewer), vectorised."""
    tri = vertices[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals = np.zeros_like(vertices)
    for corner in range(3):
        np.add.at(normals, faces[:, corner], face_n)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return normals / np.where(length > 0, length, 1.0)


def _geom_shape(model: mujoco.MjModel, geom: int) -> Any | None:
    """The Rerun archetype for one geom in its own frame, or None for kinds not drawn."""
    kind = model.geom_type[geom]
    size = model.geom_size[geom].astype(np.float32)
    color = geom_color(model, geom)
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = model.geom_dataid[geom]
        v0, nv = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        f0, nf = model.mesh_faceadr[mesh], model.mesh_facenum[mesh]
        vertices = model.mesh_vert[v0 : v0 + nv].astype(np.float32)
        faces = model.mesh_face[f0 : f0 + nf].astype(np.uint32)
        return rr.Mesh3D(
            vertex_positions=vertices,
            triangle_indices=faces,
            vertex_normals=_vertex_normals(vertices, faces).astype(np.float32),
            albedo_factor=color,
        )
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size], colors=[color], fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[size[[0, 0, 0]]], colors=[color], fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size], colors=[color], fill_mode="solid")
    if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        return rr.Cylinders3D(
            lengths=[2.0 * size[1]], radii=[size[0]], colors=[color], fill_mode="solid"
        )
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        # Rerun's capsule runs from its origin along +z; MuJoCo's is centred on the geom frame.
        return rr.Capsules3D(
            lengths=[2.0 * size[1]],
            radii=[size[0]],
            translations=[[0.0, 0.0, -size[1]]],
            colors=[color],
            fill_mode="solid",
        )
    if kind == mujoco.mjtGeom.mjGEOM_PLANE:
        hx = size[0] if size[0] > 0 else _INFINITE_PLANE_HALF_SIZE
        hy = size[1] if size[1] > 0 else _INFINITE_PLANE_HALF_SIZE
        return rr.Boxes3D(
            half_sizes=[[hx, hy, _PLANE_HALF_THICKNESS]],
            centers=[[0.0, 0.0, -_PLANE_HALF_THICKNESS]],
            colors=[color],
            fill_mode="solid",
        )
    return None  # height fields, SDFs and the like are not drawn


def _rest_poses(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """World poses (xpos, xquat wxyz) of every body at the model's reference configuration."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return data.xpos.copy(), data.xquat.copy()


def log_scene_geometry(
    recording: rr.RecordingStream, model: mujoco.MjModel, layout: SceneLayout
) -> int:
    """Logs a model's drawn geometry as static data; returns the number of geoms logged.

    Bodies that never move get their world pose as a static transform. Moving bodies get their
    reference pose at episode 0 / rollout frame 0 / wall time 0, so the scene is in place before
    the first rollout and on every timeline; rollouts then add their poses on `episode` and
    `rollout_frame`. (A geom is static data in its body's frame: where its body has no pose at
    the viewer's time, the viewer draws it in the world frame, and the arm falls apart into
    links around the origin. A static pose cannot stand in, as static data hides the body's
    poses on the timelines.)
    """
    recording.log(SCENE_ROOT, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    xpos, xquat = _rest_poses(model)
    for b in layout.static_bodies:
        recording.log(
            layout.body_paths[b],
            rr.Transform3D(translation=xpos[b], quaternion=wxyz_to_xyzw(xquat[b])),
            static=True,
        )
    index = [
        rr.TimeColumn("episode", sequence=[0]),
        rr.TimeColumn("rollout_frame", sequence=[0]),
        rr.TimeColumn("wall_time", duration=[0.0]),
    ]
    for b in layout.moving_bodies:
        recording.send_columns(
            layout.body_paths[b],
            indexes=index,
            columns=rr.Transform3D.columns(
                translation=xpos[b][None], quaternion=wxyz_to_xyzw(xquat[b])[None]
            ),
        )
    logged = 0
    for g in layout.drawn_geoms:
        shape = _geom_shape(model, int(g))
        if shape is None:
            continue
        local = rr.Transform3D(
            translation=model.geom_pos[g], quaternion=wxyz_to_xyzw(model.geom_quat[g])
        )
        recording.log(layout.geom_paths[g], local, shape, static=True)
        logged += 1
    return logged


class RolloutCapture:
    """Preallocated per-step body poses of one episode, filled from an `MjData` as it runs.

    Usage in a rollout (one capture per worker, reused across episodes)::

        capture = RolloutCapture(model, max_steps=51, gripper_body="robot0:gripper_link")
        capture.reset()
        capture.record(data)          # after reset
        for t in range(50):
            ...step...
            capture.record(data)      # after each step
        recorder.log_rollout(episode, module, capture, goal=goal_xyz, success=ok)

    `model` is a `mujoco.MjModel` (dm_control: `physics.model.ptr`); `data` any object with
    `xpos` (nbody, 3) and `xquat` (nbody, 4) arrays (`mujoco.MjData`, or dm_control's
    `physics.data`). Only the bodies that can move and carry a drawn geom are copied;
    `geom_groups` chooses the MuJoCo geom groups drawn. (After a bare `mujoco.mj_step` the
    poses are those of the state before the last physics step, 2 ms earlier; dm_control's
    `physics.step()` leaves them current.)
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        max_steps: int,
        *,
        gripper_body: str | int | None = None,
        geom_groups: tuple[int, ...] = DEFAULT_GEOM_GROUPS,
    ) -> None:
        if max_steps < 1:
            raise ValueError(f"max_steps must be >= 1, got {max_steps}")
        self.model = model
        self.layout = SceneLayout.from_model(model, geom_groups)
        self.max_steps = int(max_steps)
        n = len(self.layout.moving_bodies)
        self.xpos = np.zeros((self.max_steps, n, 3), dtype=np.float64)
        self.xquat = np.zeros((self.max_steps, n, 4), dtype=np.float64)
        self.gripper_id = None if gripper_body is None else self.layout.body_id(gripper_body)
        self.gripper = np.zeros((self.max_steps, 3), dtype=np.float64)
        self.n_steps = 0

    def reset(self) -> None:
        """Starts a new episode (keeps the buffers)."""
        self.n_steps = 0

    def record(self, data: _PoseSource) -> None:
        """Copies the current body poses (and the gripper position) into the next row."""
        t = self.n_steps
        if t >= self.max_steps:
            raise IndexError(
                f"capture is full ({self.max_steps} steps); call reset() or raise max_steps"
            )
        np.take(data.xpos, self.layout.moving_bodies, axis=0, out=self.xpos[t])
        np.take(data.xquat, self.layout.moving_bodies, axis=0, out=self.xquat[t])
        if self.gripper_id is not None:
            self.gripper[t] = data.xpos[self.gripper_id]
        self.n_steps = t + 1


def send_rollout(
    stream: rr.RecordingStream,
    capture: RolloutCapture,
    keep: np.ndarray,
    frames: np.ndarray,
    episode: int,
    goal: np.ndarray,
    gripper: np.ndarray | None,
    *,
    label: str,
    color: np.ndarray,
    goal_radius: float,
    path_radius: float,
) -> None:
    """Sends one captured episode's rows `keep` as columns on the `rollout_frame` timeline
    (`frames`, one per kept row) and at its `episode`: body poses, the goal (`goal`, one row per
    kept step) with its region and label, and the gripper's path (`gripper`, or none)."""
    f = keep.size
    index = [
        rr.TimeColumn("rollout_frame", sequence=frames),
        rr.TimeColumn("episode", sequence=np.full(f, episode, dtype=np.int64)),
    ]
    first = [
        rr.TimeColumn("rollout_frame", sequence=frames[:1]),
        rr.TimeColumn("episode", sequence=[episode]),
    ]
    layout = capture.layout
    quats = wxyz_to_xyzw(capture.xquat[keep])
    for j, body in enumerate(layout.moving_bodies):
        stream.send_columns(
            layout.body_paths[body],
            indexes=index,
            columns=rr.Transform3D.columns(
                translation=capture.xpos[keep, j], quaternion=quats[:, j]
            ),
        )

    stream.send_columns(
        f"{SCENE_ROOT}/goal", indexes=index, columns=rr.Points3D.columns(positions=goal)
    )
    stream.send_columns(
        f"{SCENE_ROOT}/goal",
        indexes=first,
        columns=rr.Points3D.columns(
            colors=[color], radii=[0.012], labels=[label], show_labels=[True]
        ),
    )
    stream.send_columns(
        f"{SCENE_ROOT}/goal_region",
        indexes=index,
        columns=rr.Ellipsoids3D.columns(centers=goal, half_sizes=np.full((f, 3), goal_radius)),
    )
    stream.send_columns(
        f"{SCENE_ROOT}/goal_region",
        indexes=first,
        columns=rr.Ellipsoids3D.columns(colors=[color], line_radii=[0.001]),
    )

    if gripper is not None:
        pts = gripper.astype(np.float32)
        stream.send_columns(
            f"{SCENE_ROOT}/gripper_path",
            indexes=index,
            columns=rr.LineStrips3D.columns(strips=[pts[: k + 1] for k in range(f)]),
        )
        stream.send_columns(
            f"{SCENE_ROOT}/gripper_path",
            indexes=first,
            columns=rr.LineStrips3D.columns(colors=[color], radii=[path_radius]),
        )
