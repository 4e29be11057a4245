"""Headless pictures of the scene: render frames of an episode to PNG.

MuJoCo renders off-screen through EGL or OSMesa; choose one with `MUJOCO_GL=egl` (or `osmesa`)
before MuJoCo is imported. The active module's goal is drawn as a translucent sphere of the
success radius, so a picture shows what the arm is asked to do.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

import numpy as np

from suite import layout

Policy = Callable[[dict[str, np.ndarray]], np.ndarray]

CAMERAS = ("front", "top", "close")
"""Views of the scene: the model's `front` and `top` cameras, and `close`, a free camera on the
reachable workspace (the gripper's start and the cubes around it), for small frames."""

GL_HELP = (
    "Choose a headless GL backend before running: "
    "`export MUJOCO_GL=egl` (Debian/Ubuntu: apt-get install libegl1 libegl-mesa0) or "
    "`export MUJOCO_GL=osmesa` (apt-get install libosmesa6); on a desktop `MUJOCO_GL=glfw` works."
)


def check_gl_backend() -> None:
    """Refuse early, with the fix, where rendering was switched off (`MUJOCO_GL=disable`)."""
    if os.environ.get("MUJOCO_GL", "").lower() in ("disable", "disabled", "off", "false", "0"):
        raise RuntimeError(f"MUJOCO_GL={os.environ['MUJOCO_GL']} switches rendering off. {GL_HELP}")


def render_episode(
    env,
    policy: Policy,
    *,
    steps: int = layout.EPISODE_STEPS,
    every: int = 10,
    camera: str = "front",
    height: int = 480,
    width: int = 640,
) -> list[np.ndarray]:
    """Run one episode of `env` (already told its module and goal) and return RGB frames.

    Args:
        env: a suite environment; `env.reset()` is called here.
        policy: maps the observation dict to an action in [-1, 1]^4.
        steps: control steps to run (at most the episode's 50).
        every: keep one frame every `every` steps (the first and last frames are always kept).
        camera: a view of the scene (`CAMERAS`).
        height, width: frame size in pixels.
    """

    check_gl_backend()
    if every < 1:
        raise ValueError(f"every must be >= 1, got {every}")
    if not 1 <= steps <= layout.EPISODE_STEPS:
        raise ValueError(f"steps must be in 1..{layout.EPISODE_STEPS}, got {steps}")
    physics = env.physics
    renderer = make_renderer(physics.model.ptr, width, height)
    view = scene_camera(physics, camera)
    frames = []
    try:
        timestep = env.reset()
        for t in range(steps + 1):
            if t % every == 0 or t == steps:
                renderer.update_scene(physics.data.ptr, camera=view)
                add_goal_marker(renderer.scene, env.task)
                frames.append(renderer.render().copy())
            if t < steps:
                timestep = env.step(policy(timestep.observation))
    finally:
        renderer.close()
    return frames


def make_renderer(model: Any, width: int, height: int) -> Any:
    """A `mujoco.Renderer` of `model` (an `mjModel`), its off-screen buffer grown to the frame
    size where the model's is smaller; a GL that cannot make a context is one line with the fix."""
    import mujoco

    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # the GL libraries raise a variety of errors here
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise RuntimeError(
            f"MuJoCo could not make an off-screen GL context ({type(exc).__name__}: {first}). "
            f"{GL_HELP}"
        ) from None


def scene_camera(physics, camera: str):
    """What `mujoco.Renderer.update_scene` takes for the view `camera` (one of `CAMERAS`): a
    camera id of the model, or the free camera of `close`."""
    import mujoco

    if camera not in CAMERAS:
        raise ValueError(f"unknown camera {camera!r}; cameras: {', '.join(CAMERAS)}")
    if camera != "close":
        return physics.model.name2id(camera, "camera")
    view = mujoco.MjvCamera()
    view.type = mujoco.mjtCamera.mjCAMERA_FREE
    view.lookat[:] = (layout.GRIP0[0], layout.GRIP0[1], 0.5)
    view.distance, view.azimuth, view.elevation = 1.4, 160.0, -35.0
    return view


def add_goal_marker(scene, task) -> None:
    """Draw the active module's goal as a sphere of the success radius, in the module's colour."""
    import mujoco

    if scene.ngeom >= scene.maxgeom:
        return
    index = task.active_module
    position = task.goal_positions()[index]
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(
        geom,
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        size=np.array([layout.SUCCESS_DISTANCE, 0.0, 0.0]),
        pos=position.astype(np.float64),
        mat=np.eye(3).ravel(),
        rgba=np.array([1.0, 0.2, 0.2, 0.35], dtype=np.float32),
    )
    scene.ngeom += 1
