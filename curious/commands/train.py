"""`curious train`: train one condition with one seed into a run folder.

    curious train --condition curious --seed 0 --preset quick --out runs/curious-0
    curious train ... --set n_workers=8 --set algorithm=td3      # override single settings
    curious train ... --resume                                    # go on from the last checkpoint

Errors about the input (unknown condition, preset or setting, a bad value, a non-empty folder
without --resume, a checkpoint from another config) are reported in one line, exit status 2, and
nothing in the folder is written.
"""

from __future__ import annotations

import argparse
import sys

from curious.config import CONDITIONS, PRESETS, ConfigError, parse_overrides, resolve


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious train`."""
    parser = sub.add_parser(
        "train",
        help="train one condition x seed into a run folder",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=(
            "presets: "
            + ", ".join(PRESETS)
            + "\nconditions: "
            + ", ".join(CONDITIONS)
            + "\nsettings: see curious/config.py (Config)"
        ),
    )
    parser.add_argument("--condition", default="curious", help="curious, m-uvfa, mg-te or her")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--preset", default="quick", help="smoke, quick, laptop or paper")
    parser.add_argument("--out", required=True, help="run folder (must be empty unless --resume)")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one setting (repeatable), e.g. --set n_workers=8",
    )
    parser.add_argument("--resume", action="store_true", help="continue the run in --out")
    parser.add_argument(
        "--device", choices=("cpu", "cuda"), default=None, help="where networks train (default cpu)"
    )
    parser.add_argument("--variant", default=None, help="suite variant (default: default)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument(
        "--no-record", action="store_true", help="do not write the Rerun recording (recording.rrd)"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from curious.checkpoint import CheckpointError
    from curious.run_folder import RunFolderError

    try:
        overrides = parse_overrides(args.overrides)
        if args.device is not None:
            overrides["device"] = args.device
        if args.variant is not None:
            overrides["variant"] = args.variant
        if args.no_progress:
            overrides["progress"] = False
        config = resolve(args.preset, args.condition, args.seed, overrides)
    except ConfigError as exc:
        print(f"curious train: error: {exc}", file=sys.stderr)
        return 2

    from curious.train import train

    make_recorder = None if args.no_record else _recorder_factory(args.resume)
    try:
        trainer = train(config, args.out, resume=args.resume, make_recorder=make_recorder)
    except (ConfigError, RunFolderError, CheckpointError) as exc:
        print(f"curious train: error: {exc}", file=sys.stderr)
        return 2
    competence = trainer.tracker.competence()
    summary = ", ".join(
        f"{name} {c:.2f}" for name, c in zip(trainer.spec.module_names, competence, strict=True)
    )
    print(f"{trainer.episodes} episodes in {args.out}; competence: {summary}")
    return 0


def _recorder_factory(resume: bool):
    """A factory of the run's Rerun recorder (`curious.recording.RunRecorder`)."""

    def make(trainer, folder):
        from curious.recording import RunRecorder

        # A run killed before its first checkpoint starts over, its recording too.
        resumed = resume and trainer.episodes > 0
        return RunRecorder(
            folder.path,
            trainer.spec.module_names,
            resume=resumed,
            resume_after_episode=trainer.episodes - 1 if resumed else None,
        )

    return make
