"""`curious evaluate RUN`: success of a trained run's newest checkpoint, per module.

    curious evaluate ~/curious-runs/curious-s0 --episodes 200
    curious evaluate RUN --modules reach push_cube1 --json

Plays noise-free episodes per module with goals drawn uniformly in each module's goal space,
on environment copies seeded apart from training and from the run's test rollouts, and prints
one row per module: success with its 95 % (Wilson) interval, the mean final distance between
the module's outcome and its goal, and the episodes played. Nothing in the run folder changes.

The checkpoint is the newest readable one (as --resume picks it). MG-TE plays module m with its
expert m. HER is scored as the paper, on its holistic goal (`success`); `module_success`
(whether the named module met its own goal) and the distance to the holistic goal are columns
of their own. A folder without a checkpoint, a checkpoint of another format, or a variant
whose modules differ from the run's is a one-line error.
"""

from __future__ import annotations

import argparse
import json
import sys


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious evaluate`."""
    from curious.commands import HelpFormatter

    parser = sub.add_parser(
        "evaluate",
        help="success per module of a trained run's newest checkpoint (noise-free episodes)",
        description=__doc__,
        formatter_class=HelpFormatter,
    )
    parser.add_argument("run", metavar="RUN", help="run folder (as `curious train --out`)")
    parser.add_argument(
        "--episodes", type=int, default=100, help="episodes per module (default: %(default)s)"
    )
    parser.add_argument(
        "--modules",
        nargs="+",
        metavar="MODULE",
        help="modules to play (default: all the run's; suite modules: {modules})",
    )
    parser.add_argument(
        "--variant",
        help="suite variant to play on (default: the run's; its modules must be the run's; "
        "one of {variants})",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="the evaluation's own seed: its goals and environment copies (default: %(default)s)",
    )
    parser.add_argument(
        "--processes",
        type=int,
        help="worker processes stepping the environment copies (default: the run's "
        "env_processes); the numbers do not depend on it",
    )
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from curious.evaluation import evaluate, evaluation_table

    result = evaluate(
        args.run,
        episodes=args.episodes,
        modules=args.modules,
        variant=args.variant,
        seed=args.seed,
        processes=args.processes,
        progress=not args.no_progress,
    )
    if args.json:
        json.dump(result.to_dict(), sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        sys.stdout.write(evaluation_table(result))
    return 0
