"""`curious render`: a few frames of an episode of the suite as PNG files, to see the scene."""

from __future__ import annotations

import argparse
from pathlib import Path

from curious.commands import HelpFormatter


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious render`."""
    parser = sub.add_parser(
        "render",
        help="render frames of an episode to PNG (headless)",
        formatter_class=HelpFormatter,
        epilog="variants: {variants}\nmodules: {modules}",
        description=(
            "Render frames of one episode of a suite variant to PNG files. Needs a headless "
            "GL backend: run with MUJOCO_GL=egl (Mesa EGL: apt-get install libegl1 "
            "libegl-mesa0) or MUJOCO_GL=osmesa (apt-get install libosmesa6). A backend that "
            "cannot load is refused in one line before anything is drawn."
        ),
    )
    parser.add_argument("--variant", default="default", help="suite variant (default: default)")
    parser.add_argument(
        "--module", default="push_cube1", help="module to practise (default push_cube1)"
    )
    parser.add_argument(
        "--goal",
        type=float,
        nargs=3,
        metavar=("G0", "G1", "G2"),
        help="goal g in [-1, 1]^3 (default: drawn uniformly)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the episode (default 0)")
    parser.add_argument(
        "--policy",
        choices=("random", "still"),
        default="random",
        help="actions: uniform random, or still (the arm holds its pose) (default random)",
    )
    parser.add_argument(
        "--steps", type=int, default=50, help="control steps, at most 50 (default 50)"
    )
    parser.add_argument(
        "--every", type=int, default=10, help="keep one frame every N steps (default 10)"
    )
    parser.add_argument(
        "--camera", default="front", choices=("front", "top"), help="(default front)"
    )
    parser.add_argument("--width", type=int, default=640, help="pixels (default 640)")
    parser.add_argument("--height", type=int, default=480, help="pixels (default 480)")
    parser.add_argument("--out", default="frames", help="output folder (default frames)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Render the episode and print where the frames went."""
    import numpy as np

    from curious.config import MAX_SEED

    if not args.out.strip():
        raise ValueError("--out is empty: name the folder for the frames")
    if not 0 <= args.seed <= MAX_SEED:
        raise ValueError(f"--seed must be from 0 to {MAX_SEED:,}, got {args.seed}")

    import suite
    from suite.render import check_gl_backend, render_episode, save_frames

    check_gl_backend()
    env = suite.load(args.variant, seed=args.seed)
    env.task.set_next_episode(module=args.module, goal=args.goal)
    rng = np.random.default_rng(args.seed)
    if args.policy == "random":

        def policy(_obs):
            return rng.uniform(-1.0, 1.0, size=4)
    else:

        def policy(_obs):
            return np.zeros(4)

    frames = render_episode(
        env,
        policy,
        steps=args.steps,
        every=args.every,
        camera=args.camera,
        height=args.height,
        width=args.width,
    )
    paths = save_frames(frames, Path(args.out), prefix=f"{args.variant}_{args.module}")
    print(f"wrote {len(paths)} frames to {args.out}/ ({paths[0].name} .. {paths[-1].name})")
    return 0
