"""`curious train`: train one condition with one seed into a run folder.

    curious train --condition curious --seed 0 --preset quick --out runs/curious-0
    curious train ... --set n_workers=8 --set algorithm=td3      # override single settings
    curious train ... --resume                                    # go on from the last checkpoint
    curious train ... --restart                                   # start the run in --out over
    curious train ... --spawn-viewer --rollout-every 10           # watch it live in Rerun

Errors about the input (unknown condition, preset or setting, a bad value, a non-empty folder
without --resume, a checkpoint from another config, a run that would not fit in memory) are
reported in one line, exit status 2, and nothing in the folder is written. A run whose training
diverges (a learning rate too high) stops with one line, exit status 1, its folder as it was at
its last checkpoint; Ctrl-C stops it with exit status 130.
"""

from __future__ import annotations

import argparse
import sys

from curious.commands import HelpFormatter, add_set_option
from curious.config import (
    MAX_EPISODES,
    PRESETS,
    ConfigError,
    condition_names,
    parse_overrides,
    resolve,
)


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious train`."""
    conditions = condition_names()
    parser = sub.add_parser(
        "train",
        help="train one condition x seed into a run folder",
        description=__doc__.split("\n\n")[0],
        formatter_class=HelpFormatter,
        epilog=(
            "presets: "
            + ", ".join(PRESETS)
            + "\nconditions: "
            + ", ".join(conditions)
            + "\nvariants: {variants}"
            + "\nsettings: every field of curious.config.Config (each documented there, with "
            "the authors' value),\n  e.g. --set learner_backend=workspace (the fastest update "
            "on a CPU)"
        ),
    )
    parser.add_argument(
        "--condition",
        default="curious",
        help=f"{', '.join(conditions[:-1])} or {conditions[-1]} (default curious)",
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="seeds networks, rollouts and replay (default 0)"
    )
    parser.add_argument(
        "--preset",
        default="quick",
        help=f"{', '.join(list(PRESETS)[:-1])} or {list(PRESETS)[-1]} (default quick)",
    )
    parser.add_argument("--out", required=True, help="run folder (must be empty unless --resume)")
    add_set_option(parser, "override one setting (repeatable), e.g. --set n_workers=8")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out")
    parser.add_argument(
        "--restart",
        action="store_true",
        help="start the run in --out over from episode 0, deleting what it holds (its metrics, "
        "test rollouts, recording and checkpoints)",
    )
    parser.add_argument(
        "--device", choices=("cpu", "cuda"), default=None, help="where networks train (default cpu)"
    )
    parser.add_argument(
        "--variant", default=None, help="suite variant: {variants} (default: default)"
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument(
        "--no-record", action="store_true", help="do not write the Rerun recording (recording.rrd)"
    )
    parser.add_argument(
        "--spawn-viewer",
        action="store_true",
        help="also stream the recording live to a Rerun viewer (recording.rrd is still written)",
    )
    parser.add_argument(
        "--rollout-every",
        type=int,
        default=None,
        metavar="K",
        help="record every K-th evaluation episode in 3D; 0 records none (default {rollout_every})",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from curious.runs.checkpoint import CheckpointError
    from curious.runs.folder import RunFolderError

    try:
        if not args.out.strip():
            raise ConfigError("--out is empty: name the run folder")
        overrides = parse_overrides(args.overrides)
        if args.device is not None:
            overrides["device"] = args.device
        if args.variant is not None:
            overrides["variant"] = args.variant
        if args.no_progress:
            overrides["progress"] = False
        config = resolve(args.preset, args.condition, args.seed, overrides)
        if args.no_record and (args.spawn_viewer or args.rollout_every is not None):
            raise ConfigError(
                "--spawn-viewer and --rollout-every need the recording: drop --no-record"
            )
        if args.rollout_every is not None and not 0 <= args.rollout_every <= MAX_EPISODES:
            raise ConfigError(
                f"--rollout-every must be from 0 to {MAX_EPISODES:,}, got {args.rollout_every:,} "
                "(why: curious.config.MAX_EPISODES)"
            )
    except ConfigError as exc:
        print(f"curious train: error: {exc}", file=sys.stderr)
        return 2

    from curious.runs.driver import train
    from curious.runs.trainer import TrainingDiverged

    make_recorder = None
    if not args.no_record:
        from curious.watching.recording import RecorderSettings
        from curious.watching.recording.rollout_capture import recorder_factory

        settings = RecorderSettings()
        if args.rollout_every is not None:
            settings = RecorderSettings(rollout_every=args.rollout_every)
        make_recorder = recorder_factory(args.resume, settings, args.spawn_viewer)
    try:
        trainer = train(
            config,
            args.out,
            resume=args.resume,
            restart=args.restart,
            make_recorder=make_recorder,
        )
    except TrainingDiverged as exc:
        print(f"curious train: error: {exc}", file=sys.stderr)
        return 1
    except (ConfigError, RunFolderError, CheckpointError) as exc:
        print(f"curious train: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a folder that cannot be written: read-only, under a file, full disk
        where = f": {exc.filename}" if exc.filename else ""
        print(f"curious train: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2
    if not trainer.condition.self_evaluates:  # her: no competence; its score is in the tables
        print(f"{trainer.episodes} episodes in {args.out}; no self-evaluations (her)")
        return 0
    competence = trainer.tracker.competence()
    summary = ", ".join(
        f"{name} {c:.2f}" for name, c in zip(trainer.spec.module_names, competence, strict=True)
    )
    print(f"{trainer.episodes} episodes in {args.out}; competence: {summary}")
    return 0
