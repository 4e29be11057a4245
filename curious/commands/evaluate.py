"""`curious evaluate RUN`: success of a trained run's newest checkpoint, per module.

    curious evaluate ~/curious-runs/curious-s0 --episodes 200
    curious evaluate RUN --modules reach push_cube1 --json
    curious evaluate RUN --episodes 20 --record       # and ./evaluation.rrd: `curious view` it

Plays noise-free episodes per module with goals drawn uniformly in each module's goal space,
on environment copies seeded apart from training and from the run's test rollouts, and prints
one row per module: success with its 95 % (Wilson) interval, the mean final distance between
the module's outcome and its goal, and the episodes played. Nothing in the run folder changes.

The checkpoint is the newest readable one (as --resume picks it). MG-TE plays module m with its
expert m. HER is scored as the paper, on its holistic goal (`success`); `module_success`
(whether the named module met its own goal) and the distance to the holistic goal are columns
of their own. A folder without a checkpoint, a checkpoint of another format, or a variant
whose modules differ from the run's is a one-line error.

--record [FILE] also writes a Rerun recording of the evaluation (default: evaluation.rrd in the
current folder; never in the run folder unless FILE says so, and never over a run's
recording.rrd): the first --record-episodes episodes of each module in 3-D, as the training
recording shows its rollouts, and every episode's success, under the training recording's
layout. Its `episode` timeline counts the evaluation's episodes. Open it with `curious view
FILE` or `rerun FILE`. To watch the agent as a video instead: `curious render --run RUN`.
"""

from __future__ import annotations

import argparse
import json
import sys

from curious.commands import HelpFormatter, folder_name
from curious.config import MAX_SEED
from curious.runs.folder_layout import EVALUATION_RECORDING_FILE as DEFAULT_FILE
from curious.watching.evaluation import MAX_EPISODES, evaluate, evaluation_table, open_run

RECORD_EPISODES = 2
"""`--record-episodes` unless given: each module's first episodes kept in 3-D."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious evaluate`."""
    parser = sub.add_parser(
        "evaluate",
        help="success per module of a trained run's newest checkpoint (noise-free episodes)",
        description=__doc__,
        formatter_class=HelpFormatter,
    )
    parser.add_argument(
        "run", metavar="RUN", type=folder_name, help="run folder (as `curious train --out`)"
    )
    parser.add_argument(
        "--episodes",
        type=int,
        default=100,
        help=f"episodes per module, at most {MAX_EPISODES:,} (default: %(default)s)",
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
        help=f"the evaluation's own seed: its goals and environment copies, 0 to {MAX_SEED:,} "
        "(default: %(default)s)",
    )
    parser.add_argument(
        "--processes",
        type=int,
        help="worker processes stepping the environment copies (default: the run's "
        "env_processes); the numbers do not depend on it",
    )
    parser.add_argument(
        "--record",
        nargs="?",
        const=DEFAULT_FILE,
        metavar="FILE",
        help=f"also write a Rerun recording of the evaluation to FILE (.rrd; without FILE: "
        f"./{DEFAULT_FILE}, not in the run folder)",
    )
    parser.add_argument(
        "--record-episodes",
        type=int,
        default=None,
        metavar="N",
        help=f"with --record: episodes of each module recorded in 3-D (default: {RECORD_EPISODES})",
    )
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.record is None:
        if args.record_episodes is not None:
            raise ValueError("--record-episodes is for --record: add --record [FILE]")
        result = evaluate(
            args.run,
            episodes=args.episodes,
            modules=args.modules,
            variant=args.variant,
            seed=args.seed,
            processes=args.processes,
            progress=not args.no_progress,
        )
    else:
        result = _evaluate_and_record(args)
        print(f"wrote {args.record}: open it with `curious view {args.record}`", file=sys.stderr)
    if args.json:
        json.dump(result.to_dict(), sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        sys.stdout.write(evaluation_table(result))
    return 0


def _evaluate_and_record(args: argparse.Namespace):
    """`evaluate` with its episodes recorded in 3-D
    (`curious.watching.recording.evaluation_rrd`)."""
    from curious.watching.recording.evaluation_rrd import EvaluationRecording, check_target

    target = check_target(args.record, args.run)
    per_module = RECORD_EPISODES if args.record_episodes is None else args.record_episodes
    with open_run(
        args.run, args.episodes, args.variant, args.seed, None, args.processes
    ) as session:
        modules = session.modules(args.modules)
        name = f"evaluation of {session.folder.path.name} at episode {session.episode:,}"
        recording = EvaluationRecording(
            target,
            session.spec.module_names,
            args.episodes,
            min(per_module, args.episodes),
            session.spec.episode_length,
            name,
        )
        try:
            result = session.evaluate(
                args.episodes, modules, observer=recording.observer, progress=not args.no_progress
            )
        except BaseException:
            recording.abandon()
            raise
        recording.finish(result)
    return result
