"""`curious render`: episodes of the suite rendered headless, as a video or PNG frames.

    curious render --run RUN --module stack --episodes 3 --out stack.mp4
    curious render --run RUN --module reach push_cube1 --out clip.webp --width 320 --height 240
    curious render --module push_cube1 --policy random --out frames

With --run, the run's trained agent plays: its newest readable checkpoint (as --resume and
`curious evaluate` pick it) plays noise-free episodes of each module with goals drawn uniformly
in the module's goal space (MG-TE: the module's expert; HER: its holistic goal, scored as
`curious evaluate` scores it). The episodes are those `curious evaluate RUN --episodes N
--modules ... --seed S` plays and scores with the same N and seed. Without --run, the arm acts
at random or holds still (--policy).

The format follows the suffix of --out: .mp4 (H.264 through imageio-ffmpeg: in the clone,
pip install -e ".[video]"), .gif or .webp (looping, through Pillow), or a folder for PNG frames.
Videos play at the simulation's pace by default (one frame per control step, 25 fps), carry a
caption per episode (module, goal and, for the trained agent, whether it succeeded) and hold each
episode's last frame for --hold seconds; PNG frames are the bare pictures. The goal is drawn as a
translucent sphere of the success radius.

Where there is no display it needs a headless GL backend: with MUJOCO_GL unset it takes EGL
(Mesa EGL: apt-get install libegl1 libegl-mesa0), else OSMesa (apt-get install libosmesa6),
whichever library is installed; MUJOCO_GL=egl or MUJOCO_GL=osmesa chooses. A backend that cannot
load is refused in one line before anything is drawn.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np

import suite
from curious.commands import HelpFormatter, folder_name
from curious.config import MAX_SEED
from curious.runs.folder_lock import check_writable
from curious.watching.evaluation import MAX_EPISODES, check_episodes, check_seed, open_run
from curious.watching.palette import module_label
from curious.watching.video import (
    GREEN,
    MAX_FPS,
    MAX_FRAME_SIDE,
    MAX_HOLD,
    MIN_FPS,
    MIN_FRAME_SIDE,
    RED,
    WHITE,
    EpisodeFilm,
    burn_caption,
    check_timing,
    check_writer,
    goal_text,
    open_writer,
    output_kind,
    real_time_fps,
)
from suite.layout import CONTROL_TIMESTEP, EPISODE_STEPS
from suite.render import check_gl_backend, render_episode

DEFAULT_SPEED = 1.0
"""`--speed` unless given: real time."""
PNG_EVERY = 10
"""`--every` unless given, for PNG frames (a video keeps every frame)."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious render`."""
    parser = sub.add_parser(
        "render",
        help="render episodes headless: a trained run's agent (--run) or a random arm, to "
        "MP4/GIF/WebP or PNG frames",
        formatter_class=HelpFormatter,
        epilog="variants: {variants}\nmodules: {modules}",
        description=__doc__,
    )
    parser.add_argument(
        "--run",
        metavar="RUN",
        type=folder_name,
        help="run folder whose trained agent plays (its newest checkpoint); without it the arm "
        "acts as --policy says",
    )
    parser.add_argument(
        "--module",
        nargs="+",
        metavar="MODULE",
        help="modules to play, one after the other (default: every module of the run with "
        "--run, else push_cube1)",
    )
    parser.add_argument(
        "--episodes",
        type=int,
        default=1,
        help=f"episodes per module, at most {MAX_EPISODES:,} (default: %(default)s)",
    )
    parser.add_argument(
        "--variant", help="suite variant (default: the run's with --run, else default)"
    )
    parser.add_argument(
        "--goal",
        type=float,
        nargs=3,
        metavar=("G0", "G1", "G2"),
        help="goal g in [-1, 1]^3 (random/still policies; default: drawn uniformly)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help=f"seed of the episodes, 0 to {MAX_SEED:,}: with --run, the goals and copies of "
        "`curious evaluate --seed` (default: %(default)s)",
    )
    parser.add_argument(
        "--policy",
        choices=("random", "still"),
        help="without --run: uniform random actions, or still (the arm holds its pose) "
        "(default: random)",
    )
    parser.add_argument(
        "--steps",
        type=int,
        help="random/still policies: control steps, at most 50 (default: 50)",
    )
    parser.add_argument(
        "--every",
        type=int,
        help="keep one frame every N control steps (default: 1 for a video, 10 for PNG frames)",
    )
    parser.add_argument(
        "--camera",
        default="front",
        choices=("front", "top", "close"),
        help="the scene's front or top camera, or close: the reachable workspace, for small "
        "frames (default: %(default)s)",
    )
    sides = f"pixels, {MIN_FRAME_SIDE} to {MAX_FRAME_SIDE:,} (default: %(default)s)"
    parser.add_argument("--width", type=int, default=640, help=sides)
    parser.add_argument("--height", type=int, default=480, help=sides)
    parser.add_argument(
        "--speed",
        type=float,
        default=None,
        help=f"video playback speed against the simulation's time (default: {DEFAULT_SPEED:g}, "
        "real time: 1 / (control timestep x every) frames per second); the frames per second "
        f"it makes must be from {MIN_FPS:g} to {MAX_FPS:g}",
    )
    parser.add_argument(
        "--fps",
        type=float,
        help=f"video frames per second, {MIN_FPS:g} to {MAX_FPS:g} (overrides --speed)",
    )
    parser.add_argument(
        "--hold",
        type=float,
        default=1.0,
        help=f"video: seconds each episode's last frame stays on screen, at most {MAX_HOLD:g} "
        "(default: %(default)s)",
    )
    parser.add_argument("--no-caption", action="store_true", help="video: no caption")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument(
        "--out",
        default="frames",
        help="a .mp4, .gif or .webp file, or a folder for PNG frames (default: %(default)s)",
    )
    parser.set_defaults(func=run)


def _check(args: argparse.Namespace) -> str:
    """Refuses bad arguments before anything loads; returns the output format."""
    kind = output_kind(args.out)
    check_writer(kind, args.width, args.height)
    check_seed(args.seed)
    check_episodes(args.episodes)
    if args.every is not None and args.every < 1:
        raise ValueError(f"--every must be at least 1, got {args.every}")
    if args.steps is not None and not 1 <= args.steps <= EPISODE_STEPS:
        raise ValueError(f"--steps must be from 1 to {EPISODE_STEPS}, got {args.steps:,}")
    for option, value in (("--speed", args.speed), ("--fps", args.fps), ("--hold", args.hold)):
        if value is not None and not math.isfinite(value):
            raise ValueError(f"{option} must be a finite number, got {value}")
    for option, value in (("--speed", args.speed), ("--fps", args.fps)):
        if value is not None and value <= 0:
            raise ValueError(f"{option} must be positive, got {value:g}")
    if args.hold < 0:
        raise ValueError(f"--hold must be >= 0 seconds, got {args.hold}")
    if kind != "png":
        if args.fps is not None:
            check_timing(args.fps, f"--fps {args.fps:g}", args.hold, derived=False)
        else:
            every, speed = _every_and_speed(args, kind)
            check_timing(
                real_time_fps(CONTROL_TIMESTEP, every, speed), _timing_options(args), args.hold
            )
    if args.run is not None:
        for name, given in (("--policy", args.policy), ("--goal", args.goal)):
            if given is not None:
                raise ValueError(
                    f"{name} is for the random and still arm: with --run the trained agent "
                    "plays, with goals drawn uniformly (choose them with --seed)"
                )
        if args.steps is not None:
            raise ValueError("--steps is for the random and still arm: with --run episodes run "
                             "their full length")  # fmt: skip
    check_writable(args.out, "--out", folder=kind == "png")
    return kind


def _every_and_speed(args: argparse.Namespace, kind: str) -> tuple[int, float]:
    """`--every` and `--speed` as the output uses them, their defaults where not given."""
    every = args.every if args.every is not None else (PNG_EVERY if kind == "png" else 1)
    return every, DEFAULT_SPEED if args.speed is None else args.speed


def _timing_options(args: argparse.Namespace) -> str:
    """The options given that set a video's frames per second without --fps, with their
    values, for a refusal to name (`--speed 1` where neither was given)."""
    given = [f"--every {args.every}"] if args.every is not None else []
    given += [f"--speed {args.speed:g}"] if args.speed is not None else []
    return " with ".join(given) or f"--speed {DEFAULT_SPEED:g}"


def _timing(args: argparse.Namespace, kind: str, control_timestep: float) -> tuple[int, float, int]:
    """(every, fps, hold frames) of the output."""
    every, speed = _every_and_speed(args, kind)
    fps = args.fps if args.fps is not None else real_time_fps(control_timestep, every, speed)
    hold = 0 if kind == "png" else round(args.hold * fps)
    return every, fps, hold


def _bar(total: int, args: argparse.Namespace, desc: str, unit: str = "frame") -> Any:
    """A progress bar (none with --no-progress)."""
    from tqdm.auto import tqdm  # it picks notebook or console bars, and warns, when imported

    return tqdm(total=total, unit=unit, disable=args.no_progress, dynamic_ncols=True, desc=desc)


def run(args: argparse.Namespace) -> int:
    """Render the episodes and print where they went."""
    kind = _check(args)
    if args.run is not None:
        return _render_run(args, kind)
    return _render_policy(args, kind)


def _render_run(args: argparse.Namespace, kind: str) -> int:
    """The run's trained agent, through `curious evaluate`'s episodes."""
    with open_run(args.run, args.episodes, args.variant, args.seed, processes=1) as session:
        modules = session.modules(args.module)
        names = session.spec.module_names
        every, fps, hold = _timing(args, kind, session.envs.reference.dm_env.control_timestep())
        total = len(modules) * args.episodes

        def caption(episode: int, module: int, raw: Any, success: bool):
            name = names[module]
            head = f"{module_label(name)} | {goal_text(raw)}"
            where = f"episode {episode % args.episodes + 1}/{args.episodes}"
            verdict = "success" if success else "failure"
            tail = f"{verdict} | {where} | agent at training episode {session.episode:,}"
            return [(head, WHITE), (tail, GREEN if success else RED)]

        def prefix(episode: int, module: int) -> str:
            return f"{session.variant}_{names[module]}_ep{episode % args.episodes}"

        writer = open_writer(kind, args.out, fps)
        film = EpisodeFilm(
            writer,
            session.spec.episode_length,
            camera=args.camera,
            width=args.width,
            height=args.height,
            every=every,
            hold=hold,
            caption=None if args.no_caption or kind == "png" else caption,
            prefix=prefix,
        )
        film.bar = _bar(total * (film.frames_per_episode - hold), args, f"render {args.run}")
        try:
            result = session.evaluate(args.episodes, modules, observer=film)
            writer.close()
        except BaseException:
            writer.abort()
            raise
        finally:
            film.close()
            film.bar.close()
    scores = ", ".join(
        f"{r.module} {round(r.success * r.episodes)}/{r.episodes}" for r in result.modules
    )
    print(
        f"{_wrote(writer, args.out, kind, fps)}: {result.condition} at episode "
        f"{result.episode:,} ({result.checkpoint}); success: {scores}"
    )
    return 0


def _wrote(writer: Any, out: str, kind: str, fps: float) -> str:
    """The line `wrote N frames to OUT (...)`: the frames the output holds (a GIF or WebP holds
    a run of alike frames as one: `VideoWriter.frames_in_file`), a video's frame rate and
    length."""
    length = f"{fps:g} fps, {writer.frames / fps:.1f} s" if kind != "png" else "PNG frames"
    return f"wrote {writer.frames_in_file} frames to {out} ({length})"


def _render_policy(args: argparse.Namespace, kind: str) -> int:
    """The random or still arm, one episode after another."""
    check_gl_backend()
    variant = "default" if args.variant is None else args.variant  # '' is no variant
    modules = args.module or ["push_cube1"]
    env = suite.load(variant, seed=args.seed)
    for name in modules:
        env.task.module_index(name)  # the suite's error for a name the variant lacks
    steps = args.steps if args.steps is not None else suite.layout.EPISODE_STEPS
    every, fps, hold = _timing(args, kind, env.control_timestep())
    policy_name = args.policy or "random"
    rng = np.random.default_rng(args.seed)

    def policy(_obs):
        return rng.uniform(-1.0, 1.0, size=4) if policy_name == "random" else np.zeros(4)

    writer = open_writer(kind, args.out, fps)
    bar = _bar(len(modules) * args.episodes, args, f"render {policy_name}", unit="ep")
    single = len(modules) == 1 and args.episodes == 1
    try:
        for name in modules:
            for j in range(args.episodes):
                env.task.set_next_episode(module=name, goal=args.goal)
                frames = render_episode(
                    env,
                    policy,
                    steps=steps,
                    every=every,
                    camera=args.camera,
                    height=args.height,
                    width=args.width,
                )
                if kind == "png":
                    writer.start(f"{variant}_{name}" if single else f"{variant}_{name}_ep{j}")
                else:
                    raw = env.task.goals[env.task.active_module]
                    lines = _policy_caption(module_label(name), raw, policy_name, j, args.episodes)
                    lines = [] if args.no_caption else lines
                    frames = [burn_caption(f, lines) for f in frames]
                    frames += [frames[-1]] * hold
                for frame in frames:
                    writer.add(frame)
                bar.update(1)
        writer.close()
    except BaseException:
        writer.abort()
        raise
    finally:
        bar.close()
    if kind == "png":
        paths = writer.written
        folder = f"{str(args.out).rstrip('/')}/"
        print(f"wrote {len(paths)} frames to {folder} ({paths[0].name} .. {paths[-1].name})")
    else:
        print(_wrote(writer, args.out, kind, fps))
    return 0


def _policy_caption(label: str, raw: Any, policy: str, j: int, episodes: int) -> Any:
    """The caption of an episode of the random or still arm."""
    where = f"episode {j + 1}/{episodes}"
    return [(f"{label} | {goal_text(raw)}", WHITE), (f"{policy} arm | {where}", WHITE)]
