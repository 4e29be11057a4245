"""`curious render --run`: videos of a trained run's agent, and their one-line refusals.

The videos render headless through EGL in a subprocess (MuJoCo reads `MUJOCO_GL` once, at
import); where no EGL context can be made (a machine without libEGL) those tests skip, saying
so. The refusals come before anything is drawn, so they run everywhere.
"""

from __future__ import annotations

import functools
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
import torch

from curious.cli import main as curious_cli
from curious.watching.evaluation import evaluate
from curious.watching.video import Caption, burn_caption, kept_steps, output_kind, real_time_fps


@functools.cache
def _egl_problem() -> str | None:
    """Why an EGL context cannot be made here (None when it can)."""
    probe = "import mujoco; mujoco.GLContext(64, 64).make_current()"
    env = {**os.environ, "MUJOCO_GL": "egl"}
    done = subprocess.run(
        [sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120
    )
    if done.returncode == 0:
        return None
    lines = done.stderr.strip().splitlines()
    return lines[-1] if lines else f"exit status {done.returncode}"


def _needs_gl() -> None:
    problem = _egl_problem()
    if problem is not None:
        pytest.skip(f"no headless GL here (MUJOCO_GL=egl: {problem})")


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    """A smoke run of curious (seed 0): 24 episodes, a checkpoint at each of 12 and 24."""
    out = tmp_path_factory.mktemp("video_run") / "curious"
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MUJOCO_GL", "disable")
        args = ["train", "--preset", "smoke", "--seed", "0", "--out", str(out), "--no-progress"]
        assert curious_cli(args) == 0
    return out


def _render(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": "egl"}
    cmd = [sys.executable, "-m", "curious.cli", "render", "--no-progress", *args]
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)


def _mp4(path) -> tuple[list[np.ndarray], float]:
    import imageio.v2 as imageio

    with imageio.get_reader(str(path)) as reader:
        return [np.asarray(f) for f in reader], float(reader.get_meta_data()["fps"])


def test_a_trained_agent_video_has_a_frame_per_kept_step_of_every_episode(smoke_run, tmp_path):
    _needs_gl()
    out = tmp_path / "clip.mp4"
    args = ["--run", str(smoke_run), "--module", "stack", "reach", "--episodes", "2"]
    args += ["--every", "5", "--width", "96", "--height", "64", "--hold", "0.4", "--out", str(out)]
    done = _render(*args)
    assert done.returncode == 0, done.stderr
    frames, fps = _mp4(out)
    # Real time at one frame every 5 control steps of 0.04 s: 5 fps; the last frame of each
    # episode held 0.4 s: 2 frames. Steps 0, 5, ..., 50: 11 frames an episode.
    assert fps == pytest.approx(5.0)
    assert len(frames) == 2 * 2 * (11 + 2)
    assert frames[0].shape == (64, 96, 3) and frames[0].std() > 10
    # The agent plays curious evaluate's episodes: same seed, same goals, same verdicts.
    scores = evaluate(smoke_run, episodes=2, modules=["stack", "reach"], seed=0)
    said = dict(re.findall(r"(\w+) (\d)/2", done.stdout.split("success:")[1]))
    for row in scores.modules:
        assert int(said[row.module]) == int(row.per_episode["success"].sum())
    assert "at episode 24 (ep-000000000024)" in done.stdout
    assert not list(tmp_path.glob(".*"))  # no partial file left beside it

    # The caption darkens the frame's top band, where the bare frame is the scene's.
    bare = tmp_path / "bare.mp4"
    assert _render(*args[:-1], str(bare), "--no-caption").returncode == 0
    plain, _ = _mp4(bare)
    assert len(plain) == len(frames)
    band = slice(0, 8)
    assert frames[0][band].mean() < 0.6 * plain[0][band].mean()
    np.testing.assert_allclose(frames[0][40:].mean(), plain[0][40:].mean(), atol=3)


def test_gif_and_webp_loop_at_the_simulations_pace(smoke_run, tmp_path):
    _needs_gl()
    from PIL import Image

    for suffix in ("gif", "webp"):
        out = tmp_path / f"clip.{suffix}"
        args = ["--run", str(smoke_run), "--module", "push_cube1", "--every", "10"]
        done = _render(*args, "--width", "80", "--height", "60", "--camera", "close", "--hold", "0",
                       "--out", str(out))  # fmt: skip
        assert done.returncode == 0, done.stderr
        with Image.open(out) as image:
            assert image.size == (80, 60) and image.n_frames > 1
            # the frames the file holds (a run of alike frames is held as one)
            assert f"wrote {image.n_frames} frames to {out}" in done.stdout, done.stdout
            image.seek(1)
            image.load()  # WebP tells a frame's duration once it is decoded
            assert image.info["loop"] == 0
            assert image.info["duration"] == 400  # 10 control steps of 0.04 s a frame


def test_random_arm_video_and_png_frames_stay(tmp_path):
    _needs_gl()
    out = tmp_path / "random.mp4"
    done = _render("--module", "reach", "--width", "64", "--height", "48", "--hold", "0",
                   "--out", str(out))  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert len(_mp4(out)[0]) == 51  # steps 0..50, one frame each
    frames = tmp_path / "frames"
    done = _render("--module", "reach", "--steps", "10", "--width", "64", "--height", "48",
                   "--out", str(frames))  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in frames.iterdir()) == [
        "default_reach_000.png", "default_reach_001.png"
    ]  # fmt: skip


def test_random_arm_renders_frames_larger_than_the_models_buffer(tmp_path):
    """The model's off-screen buffer is 640x480; both arms grow it to the frame asked for."""
    from PIL import Image

    _needs_gl()
    frames = tmp_path / "big"
    done = _render("--module", "reach", "--steps", "1", "--width", "1280", "--height", "720",
                   "--out", str(frames))  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert {Image.open(p).size for p in frames.iterdir()} == {(1280, 720)}


def _refused(capsys, *args: str) -> str:
    assert curious_cli(["render", "--no-progress", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("curious render: error:") and "\n" not in err, err
    return err


def test_refusals_are_one_line_and_write_nothing(smoke_run, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "egl")  # render's own checks, past the backend's
    out = str(tmp_path / "v.mp4")
    run = ["--run", str(smoke_run)]
    assert "unsupported --out suffix '.avi'" in _refused(capsys, *run, "--out", "x.avi")
    assert "unknown module 'nope'" in _refused(capsys, *run, "--module", "nope", "--out", out)
    err = _refused(capsys, *run, "--variant", "distractors_0", "--out", out)
    assert "the run was trained on" in err
    assert "--policy is for the random" in _refused(capsys, *run, "--policy", "still", "--out", out)
    assert "even --width" in _refused(capsys, *run, "--width", "95", "--out", out)
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(smoke_run / "config.json", bare / "config.json")
    assert "no checkpoint" in _refused(capsys, "--run", str(bare), "--out", out)
    assert "not a run folder" in _refused(capsys, "--run", str(tmp_path), "--out", out)
    old = tmp_path / "old"
    shutil.copytree(smoke_run, old)
    for state_path in (old / "checkpoints").glob("*/state.pt"):
        state = torch.load(state_path, weights_only=False)
        state["format"] = 1
        torch.save(state, state_path)
    assert "has format 1" in _refused(capsys, "--run", str(old), "--out", out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bare", "old"]


def test_render_without_gl_names_the_fix(smoke_run, tmp_path):
    env = {**os.environ, "MUJOCO_GL": "disable"}
    cmd = [sys.executable, "-m", "curious.cli", "render", "--run", str(smoke_run)]
    done = subprocess.run(
        [*cmd, "--out", str(tmp_path / "v.mp4")], env=env, capture_output=True, text=True
    )
    assert done.returncode == 2 and "MUJOCO_GL=egl" in done.stderr
    assert not list(tmp_path.iterdir())


def test_output_kind_by_suffix(tmp_path):
    assert [output_kind(p) for p in ("a.mp4", "b.GIF", "c.webp", "frames")] == [
        "mp4", "gif", "webp", "png"
    ]  # fmt: skip
    (tmp_path / "frames.v2").mkdir()
    assert output_kind(tmp_path / "frames.v2") == "png"  # a folder that exists
    with pytest.raises(ValueError, match="unsupported --out suffix"):
        output_kind("clip.mov")
    (tmp_path / "clip.gif").mkdir()  # a folder with a video's name: no file can be written
    with pytest.raises(ValueError, match=r"clip.gif is a folder: name a \.gif file"):
        output_kind(tmp_path / "clip.gif")
    with pytest.raises(ValueError, match=r"--out \.webp names no file"):  # not a PNG folder
        output_kind(".webp")


def test_real_time_and_kept_steps():
    assert real_time_fps(0.04) == pytest.approx(25.0)
    assert real_time_fps(0.04, every=2, speed=0.5) == pytest.approx(6.25)
    assert kept_steps(50, 1) == list(range(51))
    assert kept_steps(50, 20) == [0, 20, 40, 50]  # the last step always


def test_caption_is_drawn_on_a_dark_band_and_leaves_the_rest():
    frame = np.full((120, 160, 3), 200, np.uint8)
    lines: Caption = [("T1 reach | goal (+0.10, -0.20, +0.30)", (235, 235, 235))]
    out = burn_caption(frame, lines)
    assert out.shape == frame.shape and out.dtype == np.uint8
    np.testing.assert_array_equal(out[30:], frame[30:])
    band = out[:8]
    assert band.min() < 100 and band.max() > 200 - 1  # darkened, with bright text
    np.testing.assert_array_equal(burn_caption(frame, []), frame)


def test_png_frames_replace_an_earlier_renders_frames_and_nothing_else(tmp_path):
    """A second render into the same folder left the first one's later frames among its own
    ("wrote 3 frames", 21 files there); the folder's other files stay."""
    import numpy as np

    from curious.watching.video import PngFrames

    out = tmp_path / "frames"
    out.mkdir()
    for i in range(5):
        (out / f"default_stack_{i:03d}.png").write_bytes(b"old")
    (out / "notes.txt").write_text("mine")
    (out / "cover.png").write_bytes(b"mine")
    frames = PngFrames(out)
    frames.start("default_reach")
    frames.add(np.zeros((4, 4, 3), np.uint8))
    assert sorted(p.name for p in out.iterdir()) == [
        "cover.png", "default_reach_000.png", "notes.txt"
    ]  # fmt: skip
