"""`MUJOCO_GL` for the command line: only `curious render` draws pictures, so only it needs GL.

MuJoCo and dm_control read `MUJOCO_GL` once, when they are imported, and fail at import on a
value they do not know (`RuntimeError`) or on a backend whose library is missing (`osmesa`
without libOSMesa ends in an `AttributeError` deep in PyOpenGL). Every other command only
steps the physics, so the command line switches GL off for them before anything imports
MuJoCo (`gl_for_command`), and `curious render` first checks that the backend loads
(`rendering_problem`), refusing in one line with the fix when it does not. With `MUJOCO_GL`
unset on a machine without a display (a server, a container, CI), dm_control would try GLFW,
warn that DISPLAY is missing and fail to make a context; `curious render` then takes the
headless backend whose library is installed, EGL before OSMesa (`headless_default`). An empty
`MUJOCO_GL` (`export MUJOCO_GL=`) is unset here as it is for MuJoCo and dm_control, which both
take their default, GLFW, for it.

Nothing here imports MuJoCo at module level: this runs before the argument parser is built.
"""

from __future__ import annotations

import ctypes
import os

GL_FIX = (
    "choose a headless GL backend: `export MUJOCO_GL=egl` (Debian/Ubuntu: apt-get install "
    "libegl1 libegl-mesa0) or `export MUJOCO_GL=osmesa` (apt-get install libosmesa6); on a "
    "desktop `MUJOCO_GL=glfw` works"
)
OFF = ("disable", "disabled", "off", "false", "0")
"""Values of `MUJOCO_GL` that switch rendering off."""
LIBRARIES = {"osmesa": "libOSMesa (libosmesa6)", "egl": "libEGL (libegl1 libegl-mesa0)"}
"""The system library each headless backend loads."""


def renders(argv: list[str]) -> bool:
    """Whether this command line draws pictures: `curious render`, not asking for its help."""
    words = [a for a in argv if a[:1] != "-"]
    asks_help = any(a in ("-h", "--help") for a in argv)
    return bool(words) and words[0] == "render" and not asks_help


def gl_for_command(argv: list[str]) -> None:
    """Switch GL off (`MUJOCO_GL=disable`) for every command line that does not render, whatever
    the variable said: stepping the physics needs no GL, and a value MuJoCo cannot load would
    otherwise fail the import of MuJoCo, and so the command. A command line that renders gets
    `headless_default` where `MUJOCO_GL` is unset or empty."""
    if not renders(argv):
        os.environ["MUJOCO_GL"] = "disable"
    elif _chosen() is None:
        backend = headless_default()
        if backend is not None:
            os.environ["MUJOCO_GL"] = backend


def headless_default() -> str | None:
    """The backend to render with where `MUJOCO_GL` is unset: None on a machine with a display
    (dm_control's own choice, GLFW, works there), else `egl` or `osmesa`, the first whose system
    library loads, else None (render then refuses with `GL_FIX`)."""
    if _has_display():
        return None

    for backend, names in (
        ("egl", ("libEGL.so.1", "libEGL.so")),
        ("osmesa", ("libOSMesa.so.8", "libOSMesa.so")),
    ):
        for name in names:
            try:
                ctypes.CDLL(name)
            except OSError:
                continue
            return backend
    return None


def rendering_problem() -> str | None:
    """Why MuJoCo cannot render with this `MUJOCO_GL`, in one line with the fix; None when its
    backend loads (a context that fails later is reported where it is made)."""
    value = _chosen()
    shown = f"MUJOCO_GL={value}" if value is not None else "MUJOCO_GL (unset)"
    if value is not None and value.strip().lower() in OFF:
        return f"{shown} switches rendering off; {GL_FIX}"
    if value is None and not _has_display():  # `gl_for_command` found no headless library
        return f"{shown}, no display, and neither libEGL nor libOSMesa loads here; {GL_FIX}"
    try:
        import mujoco  # noqa: F401  (loads the backend's library)
        from dm_control import _render  # noqa: F401  (dm_control's own check of the value)
    except Exception as exc:  # a bad value or a missing library: many kinds of error
        cause = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        library = LIBRARIES.get((value or "").strip().lower())
        hint = f", is {library} installed?" if library else ""
        return f"{shown} cannot be used here ({type(exc).__name__}: {cause}{hint}); {GL_FIX}"
    return None


def _chosen() -> str | None:
    """The backend `MUJOCO_GL` names; None where it is unset or empty."""
    value = os.environ.get("MUJOCO_GL")
    return value if value is not None and value.strip() else None


def _has_display() -> bool:
    """Whether a desktop session is reachable (X11 or Wayland), where GLFW can make a context."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
