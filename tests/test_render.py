"""`curious render`: frames of an episode as PNG files, and a clear error without GL."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image


def _render(tmp_path, gl: str, *extra: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": gl}
    out = f"{tmp_path}/"  # a folder as a shell completes it, with its slash
    cmd = [sys.executable, "-m", "curious.cli", "render", "--out", out, *extra]
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)


def test_render_writes_frames_of_the_scene(tmp_path):
    args = ("--module", "stack", "--steps", "10", "--every", "5", "--width", "96")
    result = _render(tmp_path, "egl", *args, "--height", "64")
    if result.returncode != 0 and "GL context" in result.stderr:
        pytest.skip("no headless GL backend on this machine")
    assert result.returncode == 0, result.stderr
    frames = sorted(tmp_path.glob("default_stack_*.png"))
    assert len(frames) == 3  # steps 0, 5 and 10
    assert f"wrote 3 frames to {tmp_path}/ (default_stack_000.png .." in result.stdout
    pixels = np.asarray(Image.open(frames[0]))
    assert pixels.shape == (64, 96, 3)
    assert pixels.std() > 10  # a scene, not a blank image
    # Cube 1 and the goal marker are drawn red.
    red = (pixels[..., 0] > 150) & (pixels[..., 1] < 90) & (pixels[..., 2] < 90)
    assert red.any()


def test_render_without_gl_says_how_to_get_it(tmp_path):
    result = _render(tmp_path, "disable")
    assert result.returncode != 0
    assert "MUJOCO_GL=egl" in result.stderr
    assert not list(tmp_path.glob("*.png"))
