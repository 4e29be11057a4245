"""Videos of episodes: frames rendered headless, captioned, written as MP4, GIF, WebP or PNG.

`curious render` uses it for both its policies: the run's trained agent (`--run`, through
`EpisodeFilm`, a round observer that `EvaluationSession.evaluate` calls as training calls the
3-D rollout recorder, so the film shows the very episodes `curious evaluate` scores with the
same seed) and the random or still arm (`suite.render.render_episode`).

* `output_kind(out)` tells the format by the suffix of `--out` (a folder: PNG frames);
* `open_writer(kind, out, fps)` streams MP4 through imageio's ffmpeg plugin (`imageio-ffmpeg`,
  a wheel with its own ffmpeg: `pip install -e ".[video]"` in the clone), and keeps GIF and
  WebP frames in memory until Pillow writes them at `close()`; a writer writes beside the target and
  renames when done, so an interrupted render never leaves half a file under the name asked;
* `burn_caption(frame, lines)` draws a few lines of text on a dark band at the top of a frame;
* `real_time_fps(control_timestep, every, speed)`: the frame rate at which a video plays at the
  simulation's own pace.

Frames come from `mujoco.Renderer` with the active module's goal drawn as a translucent sphere of
the success radius (`suite.render.add_goal_marker`), so every frame shows what the arm is asked.
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from suite.render import add_goal_marker, make_renderer, scene_camera

VIDEO_SUFFIXES: dict[str, str] = {".mp4": "mp4", ".gif": "gif", ".webp": "webp"}
"""Suffixes of `--out` that make a video, and the format of each."""
MIN_FRAME_SIDE = 16
"""Smallest --width and --height: the caption's two lines need about that many pixels."""
MAX_FRAME_SIDE = 4096
"""Largest --width and --height (4K): the GL backend renders into a buffer of that size, which
some implementations cap at 4,096 or 8,192 pixels a side (`GL_MAX_RENDERBUFFER_SIZE`), and an
episode's 51 frames of 4096 x 4096 already hold 2.5 GB."""
MIN_FPS = 0.01
"""Slowest video: a frame on screen for at most 100 s (GIF stores a frame's duration in
hundredths of a second in 16 bits: 655 s at most)."""
MAX_FPS = 100.0
"""Fastest video: GIF stores a frame's duration in hundredths of a second, so no GIF plays
faster (shorter durations round to 0, which players replace by a pace of their own); MP4 and
WebP keep the same range."""
MAX_HOLD = 10.0
"""Longest --hold, in seconds: long enough to read how an episode ended; the last frame is
repeated hold x fps times in the video (and kept in memory that often for GIF and WebP)."""
MP4_HINT = (
    'writing MP4 needs imageio-ffmpeg: in the clone, pip install -e ".[video]" (or write .gif or '
    ".webp, which need nothing more)"
)

Caption = list[tuple[str, tuple[int, int, int]]]
"""Lines of a caption, each with its colour."""
WHITE = (235, 235, 235)
GREEN = (90, 220, 110)
RED = (255, 110, 100)


def output_kind(out: str | os.PathLike[str]) -> str:
    """'mp4', 'gif', 'webp', or 'png' (a folder of PNG frames: a path without a suffix, or a
    folder that exists, unless it bears a video's suffix); a `ValueError` says what to name
    for anything else."""
    path = Path(out)
    if not str(out).strip():
        raise ValueError("--out is empty: name a folder for PNG frames or a .mp4/.gif/.webp file")
    suffix = path.suffix.lower()
    if path.name.lower() in VIDEO_SUFFIXES:  # `.gif` is a hidden name without a suffix
        raise ValueError(f"--out {out} names no file: give it a name, e.g. clip{path.name}")
    if suffix in VIDEO_SUFFIXES:
        if path.is_dir():
            raise ValueError(
                f"--out {out} is a folder: name a {suffix} file, or a folder without a suffix "
                "for PNG frames"
            )
        return VIDEO_SUFFIXES[suffix]
    if not suffix or path.is_dir():
        return "png"
    raise ValueError(
        f"unsupported --out suffix {path.suffix!r}: write {', '.join(VIDEO_SUFFIXES)}, or name a "
        "folder (no suffix) for PNG frames"
    )


def check_writer(kind: str, width: int, height: int) -> None:
    """Refuse, before anything is rendered, what the writer could not write."""
    for option, side in (("--width", width), ("--height", height)):
        if not MIN_FRAME_SIDE <= side <= MAX_FRAME_SIDE:
            raise ValueError(
                f"{option} must be from {MIN_FRAME_SIDE} to {MAX_FRAME_SIDE:,} pixels, got "
                f"{side:,} (why: curious.watching.video.MAX_FRAME_SIDE)"
            )
    if kind == "mp4":
        try:
            import imageio_ffmpeg  # noqa: F401
        except ImportError:
            raise ValueError(MP4_HINT) from None
        if width % 2 or height % 2:
            raise ValueError(
                f"MP4 (H.264) needs an even --width and --height, got {width}x{height}"
            )


def check_timing(fps: float, options: str, hold: float, derived: bool = True) -> None:
    """A `ValueError` naming `options` (the options with their values that set `fps`: "--fps
    200", or, `derived` from them, "--every 5000 with --speed 2") where a video cannot play at
    `fps` frames per second (`MIN_FPS`, `MAX_FPS`), or naming --hold where `hold` is past
    `MAX_HOLD` seconds."""
    if not MIN_FPS <= fps <= MAX_FPS:
        made = f" makes {fps:g} frames per second" if derived else ""
        raise ValueError(
            f"{options}{made}: videos play at {MIN_FPS:g} to {MAX_FPS:g} frames per "
            "second (why: curious.watching.video.MIN_FPS, MAX_FPS)"
        )
    if hold > MAX_HOLD:
        raise ValueError(
            f"--hold must be at most {MAX_HOLD:g} seconds, got {hold:g} (why: "
            "curious.watching.video.MAX_HOLD)"
        )


def real_time_fps(control_timestep: float, every: int = 1, speed: float = 1.0) -> float:
    """Frames per second that play a video whose frames are `every` control steps apart at
    `speed` times the simulation's pace (1: real time)."""
    if control_timestep <= 0 or every < 1 or speed <= 0:
        raise ValueError("the control timestep, every and speed must be positive")
    return speed / (control_timestep * every)


@functools.cache
def _font(size: int) -> Any:
    """DejaVu Sans at `size` pixels (matplotlib, a dependency, ships it), else Pillow's own."""
    from PIL import ImageFont

    try:
        import matplotlib

        path = Path(matplotlib.get_data_path()) / "fonts" / "ttf" / "DejaVuSans.ttf"
        return ImageFont.truetype(str(path), size)
    except (ImportError, OSError):
        try:
            return ImageFont.load_default(size=size)
        except TypeError:  # Pillow < 10.1: one fixed-size bitmap font
            return ImageFont.load_default()


def burn_caption(frame: np.ndarray, lines: Caption) -> np.ndarray:
    """`frame` (H, W, 3 uint8) with `lines` written on a darkened band across its top, in a
    font of about a 22nd of the frame's height, smaller where a line would not fit its width."""
    from PIL import Image, ImageDraw

    if not lines:
        return frame
    height, width = frame.shape[:2]
    size = max(8, round(height / 22))
    font = _font(size)
    widest = max(font.getlength(text) for text, _ in lines) if hasattr(font, "getlength") else 0
    room = width - 2 * max(2, size // 4) - 2
    if widest > room and size > 8:
        size = max(8, int(size * room / widest))
        font = _font(size)
    pad = max(2, size // 4)
    band = pad + len(lines) * (size + pad) + pad
    out = frame.copy()
    out[:band] = (out[:band].astype(np.uint16) * 2 // 7).astype(np.uint8)
    image = Image.fromarray(out)
    draw = ImageDraw.Draw(image)
    for i, (text, color) in enumerate(lines):
        draw.text((pad + 1, pad + i * (size + pad)), text, fill=color, font=font)
    return np.asarray(image)


class VideoWriter:
    """Frames to one video file (MP4 streamed; GIF and WebP written at `close`)."""

    def __init__(self, kind: str, out: str | os.PathLike[str], fps: float) -> None:
        if kind not in VIDEO_SUFFIXES.values():
            raise ValueError(f"not a video format: {kind!r}")
        self.kind = kind
        self.path = Path(out)
        self.fps = float(fps)
        self.frames = 0
        self.frames_in_file = 0
        """Frames the file holds once closed: GIF and WebP hold a run of identical frames (a held
        last frame) as one longer frame, so fewer than `frames`, the frames added."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._partial = self.path.with_name(f".{self.path.stem}.partial{self.path.suffix}")
        self._images: list[Any] = []
        self._ffmpeg: Any = None
        if kind == "mp4":
            import imageio.v2 as imageio

            self._ffmpeg = imageio.get_writer(
                str(self._partial),
                format="FFMPEG",
                mode="I",
                fps=self.fps,
                codec="libx264",
                pixelformat="yuv420p",
                macro_block_size=1,
                quality=7,
                ffmpeg_log_level="error",
            )

    def add(self, frame: np.ndarray) -> None:
        """Appends one (H, W, 3) uint8 frame."""
        if self._ffmpeg is not None:
            self._ffmpeg.append_data(frame)
        else:
            from PIL import Image

            self._images.append(Image.fromarray(frame))
        self.frames += 1

    def close(self) -> None:
        """Finishes the file and moves it to its name."""
        if self.frames == 0:
            self.abort()
            raise RuntimeError(f"no frames to write to {self.path}")
        if self._ffmpeg is not None:
            self._ffmpeg.close()
        else:
            first, *rest = self._images
            options: dict[str, Any] = {"save_all": True, "append_images": rest, "loop": 0}
            options["duration"] = round(1000.0 / self.fps)
            if self.kind == "webp":
                options.update(quality=70, method=6)
            else:
                options.update(optimize=True, disposal=1)
            first.save(self._partial, format=self.kind.upper(), **options)
            self._images = []
        self.frames_in_file = self._count_frames()
        os.replace(self._partial, self.path)

    def _count_frames(self) -> int:
        """The frames in the finished (partial) file."""
        if self._ffmpeg is not None:
            return self.frames
        from PIL import Image

        with Image.open(self._partial) as image:
            return int(getattr(image, "n_frames", 1))

    def abort(self) -> None:
        """Drops what was written (an error or an interrupt stopped the render)."""
        if self._ffmpeg is not None:
            with contextlib.suppress(Exception):
                self._ffmpeg.close()
        self._images = []
        self._partial.unlink(missing_ok=True)


class PngFrames:
    """Frames to numbered PNG files in a folder, one name prefix per episode. The frames an
    earlier render wrote there (`*_NNN.png`) are removed first, as a video file is replaced:
    else a shorter render would leave the longer one's last frames among its own."""

    def __init__(self, out: str | os.PathLike[str]) -> None:
        self.path = Path(out)
        self.path.mkdir(parents=True, exist_ok=True)
        for stale in self.path.glob("*_[0-9][0-9][0-9].png"):
            stale.unlink()
        self.prefix = "frame"
        self.frames = 0
        self._index = 0
        self.written: list[Path] = []

    def start(self, prefix: str) -> None:
        """The frames that follow are named `<prefix>_000.png`, `<prefix>_001.png`, ..."""
        self.prefix, self._index = prefix, 0

    def add(self, frame: np.ndarray) -> None:
        from PIL import Image

        path = self.path / f"{self.prefix}_{self._index:03d}.png"
        Image.fromarray(frame).save(path)
        self.written.append(path)
        self._index += 1
        self.frames += 1

    @property
    def frames_in_file(self) -> int:
        """The frames written: one file each."""
        return self.frames

    def close(self) -> None:
        """Nothing to finish: every frame is written as it comes."""

    def abort(self) -> None:
        """The frames written so far stay (each is whole)."""


def open_writer(kind: str, out: str | os.PathLike[str], fps: float) -> VideoWriter | PngFrames:
    """The writer for `output_kind(out)`."""
    return PngFrames(out) if kind == "png" else VideoWriter(kind, out, fps)


def kept_steps(episode_length: int, every: int) -> list[int]:
    """The steps filmed: 0, every, 2 * every, ..., and always the last."""
    steps = list(range(0, episode_length + 1, every))
    if steps[-1] != episode_length:
        steps.append(episode_length)
    return steps


class EpisodeFilm:
    """A round observer (`curious.runs.hooks.RoundObserver`) that films every episode of a round.

    At each kept step it renders every copy of the round from `camera`, with the goal marker;
    when the round ends it captions each copy's frames (`caption(episode, module, raw_goal,
    success)`, knowing the episode's success by then), writes them to `writer` episode after
    episode, and repeats each episode's last frame `hold` times, so that a viewer can read how
    it ended. `bar` (a tqdm bar, or None) advances by one per frame rendered.
    """

    def __init__(
        self,
        writer: VideoWriter | PngFrames,
        episode_length: int,
        *,
        camera: str = "front",
        width: int = 640,
        height: int = 480,
        every: int = 1,
        hold: int = 0,
        caption: Callable[[int, int, np.ndarray, bool], Caption] | None = None,
        prefix: Callable[[int, int], str] | None = None,
        bar: Any = None,
    ) -> None:
        if every < 1:
            raise ValueError(f"--every must be at least 1, got {every}")
        if hold < 0:
            raise ValueError(f"hold must be >= 0 frames, got {hold}")
        self.writer = writer
        self.steps = frozenset(kept_steps(episode_length, every))
        self.frames_per_episode = len(self.steps) + hold
        self.camera = camera
        self.width, self.height = width, height
        self.hold = hold
        self.caption = caption
        self.prefix = prefix
        self.bar = bar
        self._renderers: dict[int, Any] = {}
        self._views: Sequence[Any] = ()
        self._frames: list[list[np.ndarray]] = []

    def watched(self, episodes: np.ndarray, evaluation: np.ndarray) -> list[int]:
        return list(range(len(episodes)))

    def begin_round(
        self,
        episodes: np.ndarray,
        modules: np.ndarray,
        goals: np.ndarray,
        evaluation: np.ndarray,
        envs: Sequence[Any],
    ) -> None:
        self._views = list(envs)
        self._frames = [[] for _ in self._views]

    def _render(self, i: int, env: Any) -> np.ndarray:
        physics = env.dm_env.physics
        renderer = self._renderers.get(i)
        if renderer is None or renderer.model is not physics.model.ptr:
            if renderer is not None:
                renderer.close()
            renderer = make_renderer(physics.model.ptr, self.width, self.height)
            self._renderers[i] = renderer
        renderer.update_scene(physics.data.ptr, camera=scene_camera(physics, self.camera))
        add_goal_marker(renderer.scene, env.dm_env.task)
        return renderer.render().copy()

    def after_step(self, t: int) -> None:
        if t not in self.steps:
            return
        for i, env in enumerate(self._views):
            self._frames[i].append(self._render(i, env))
            if self.bar is not None:
                self.bar.update(1)

    def end_round(self, info: Any) -> None:
        for i, frames in enumerate(self._frames):
            episode, module = int(info.episodes[i]), int(info.modules[i])
            lines: Caption = []
            if self.caption is not None:
                lines = self.caption(episode, module, info.raw_goals[i], bool(info.success[i]))
            if self.prefix is not None and isinstance(self.writer, PngFrames):
                self.writer.start(self.prefix(episode, module))
            shown = [burn_caption(f, lines) for f in frames]
            for frame in shown:
                self.writer.add(frame)
            for _ in range(self.hold):
                self.writer.add(shown[-1])
        self._frames = []

    def close(self) -> None:
        """Frees the GL contexts."""
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers = {}


def goal_text(raw_goal: np.ndarray) -> str:
    """A goal in [-1, 1]^G as the caption shows it."""
    return "goal (" + ", ".join(f"{v:+.2f}" for v in np.asarray(raw_goal).ravel()) + ")"
