"""`curious train`: train one condition with one seed into a run folder, or several seeds at once.

    curious train --condition curious --seed 0 --preset quick --out runs/curious-0
    curious train --condition curious --seeds 0-4 --preset quick --out runs/curious  # side by side
    curious train ... --set n_workers=8 --set algorithm=td3      # override single settings
    curious train --out runs/curious-0 --resume   # go on from the last checkpoint, as it started
    curious train ... --restart                                   # start the run in --out over
    curious train ... --spawn-viewer --rollout-every 10           # watch it live in Rerun

Errors about the input (unknown condition, preset or setting, a bad value, a non-empty folder
without --resume, a checkpoint from another config, a run that would not fit in memory) are
reported in one line, exit status 2, and nothing in the folder is written. A run whose training
diverges (a learning rate too high) stops with one line, exit status 1, its folder as it was at
its last checkpoint; Ctrl-C stops it with exit status 130.

With `--seeds`, each seed trains in a process of its own, `--workers` of them side by side
(default: as many as the cores hold; `curious.runs.side_by_side`): each run is the run `--seed`
would train, in `--out/seed-N`. Ctrl-C then stops every run at the end of its cycle, after a
checkpoint, and `--resume` goes on with all of them (starting those that never began); one
run's failure leaves the others training, and is reported (exit status 1) once they are done.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import socket
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from curious.commands import HelpFormatter, add_set_option, refuse
from curious.config import MAX_EPISODES, RESUMABLE_FIELDS, Config, ConfigError
from curious.overrides import parse_overrides, parse_seeds
from curious.presets import PRESETS, resolve
from curious.registry import condition_names
from curious.runs.folder import RunFolder
from curious.runs.folder_errors import RunFolderError
from curious.runs.folder_layout import CONFIG_FILE
from curious.runs.folder_lock import check_writable
from curious.runs.memory import check_each_fits, runs_that_fit
from curious.runs.side_by_side import Failed, Interrupted, run_side_by_side, stop_requested
from curious.watching.recording.settings import RecorderSettings

if TYPE_CHECKING:
    from curious.runs.folder import RunFolder
    from curious.runs.hooks import Recorder
    from curious.runs.trainer import Trainer


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
        default=None,
        help=f"{', '.join(conditions[:-1])} or {conditions[-1]} (default curious; with "
        "--resume, the run's own)",
    )
    seeds = parser.add_mutually_exclusive_group()
    seeds.add_argument(
        "--seed",
        type=int,
        default=None,
        help="seeds networks, rollouts and replay (default 0; with --resume, the run's own)",
    )
    seeds.add_argument(
        "--seeds",
        default=None,
        metavar="SEEDS",
        help="train several seeds side by side, each in a process of its own (e.g. 0-4 or "
        "0,2,5): run i goes to --out/seed-i, each the run --seed would train",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="with --seeds: runs trained at once (default: the cores over each run's "
        "env_processes, and no more than fit in memory together)",
    )
    parser.add_argument(
        "--preset",
        default=None,
        help=f"{', '.join(list(PRESETS)[:-1])} or {list(PRESETS)[-1]} (default quick; with "
        "--resume, the run's own)",
    )
    parser.add_argument(
        "--out",
        required=True,
        help="run folder (must be empty unless --resume or --restart); with --seeds, the "
        "folder of the seed-N run folders",
    )
    add_set_option(
        parser,
        "override one setting (repeatable), e.g. --set n_workers=8; the run's length is "
        "--set total_episodes=N (the preset, condition and seed have their own options)",
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --out with the settings it was started with (config.json); "
        f"options given must match them, but for {', '.join(sorted(RESUMABLE_FIELDS))} "
        "(with --seeds, every seed-N run)",
    )
    parser.add_argument(
        "--restart",
        action="store_true",
        help="start the run in --out over from episode 0, deleting what it holds (its metrics, "
        "test rollouts, recording and checkpoints)",
    )
    parser.add_argument(
        "--device",
        choices=("cpu", "cuda"),
        default=None,
        help="where networks train (default cpu; with --resume, the run's own unless given)",
    )
    parser.add_argument(
        "--variant",
        default=None,
        help="suite variant: {variants} (default: default; with --resume, the run's own)",
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
        "--connect",
        metavar="URL",
        help="also stream the recording live to a Rerun viewer or server listening at this gRPC "
        "url, e.g. rerun+http://127.0.0.1:9876/proxy: `rerun` on this machine, `rerun "
        "--serve-web --bind 127.0.0.1` on a headless one (its browser viewer on port 9090), or "
        "a viewer on your own machine through `ssh -R 9876:127.0.0.1:9876 HOST` (recording.rrd "
        "is still written)",
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

    try:
        if not args.out.strip():
            raise ConfigError("--out is empty: name the run folder")
        overrides = parse_overrides(args.overrides)
        for key in ("device", "variant"):  # an option and an override of one setting
            given = getattr(args, key)
            if given is None:
                continue
            if key in overrides and overrides[key] != given:
                raise ConfigError(
                    f"--{key} {given} and --set {key}={overrides[key]} disagree: give one"
                )
            overrides[key] = given
        if args.no_progress:
            overrides["progress"] = False
        seeds = parse_seeds(args.seeds) if args.seeds is not None else (args.seed,)
        configs = [_config(args, seed, overrides) for seed in seeds]
        _warn_if_the_sensor_never_fails(configs[0])
        if args.workers is not None and args.seeds is None:
            raise ConfigError("--workers trains several seeds side by side: name --seeds")
        if args.workers is not None and args.workers < 1:
            raise ConfigError(f"--workers must be >= 1, got {args.workers}")
        if args.seeds is not None and (Path(args.out) / CONFIG_FILE).exists():
            raise ConfigError(
                f"{args.out} holds a run (config.json): --seeds trains each seed in "
                "--out/seed-K, which would nest them in it; choose another --out"
            )
        if args.no_record and (args.spawn_viewer or args.connect or args.rollout_every is not None):
            raise ConfigError(
                "--spawn-viewer, --connect and --rollout-every need the recording: drop --no-record"
            )
        if args.connect is not None:
            _check_viewer_url(args.connect)
        if args.rollout_every is not None and not 0 <= args.rollout_every <= MAX_EPISODES:
            raise ConfigError(
                f"--rollout-every must be from 0 to {MAX_EPISODES:,}, got {args.rollout_every:,} "
                "(why: curious.config.MAX_EPISODES)"
            )
    except ConfigError as exc:
        return refuse("train", exc)

    recording = None
    if not args.no_record:
        recording = _Recording(args.rollout_every, args.spawn_viewer, args.connect)
    if args.seeds is not None:
        return _train_seeds(args, configs, recording)
    from curious.runs.driver import train
    from curious.runs.trainer import TrainingDiverged

    try:
        check_writable(args.out, "--out")  # where its lock lands, beside it
        if Path(args.out).is_dir():  # and the folder itself, where it is one already
            check_writable(args.out, "--out", folder=True)
        trainer = train(
            configs[0], args.out, resume=args.resume, restart=args.restart,
            make_recorder=recording.factory(args.resume) if recording is not None else None,
        )  # fmt: skip
    except TrainingDiverged as exc:
        return refuse("train", exc, status=1)
    except (ConfigError, RunFolderError, CheckpointError) as exc:
        return refuse("train", exc)
    except OSError as exc:  # a folder that cannot be written: read-only, under a file, full disk
        return refuse("train", exc, message=_os_error(exc))
    print(_summary(trainer, args.out))
    return 0


@dataclass(frozen=True)
class _Recording:
    """How the runs are recorded (`--rollout-every`, `--spawn-viewer`, `--connect`), handed to
    each seed's process, which makes its own recorder."""

    rollout_every: int | None
    spawn: bool
    connect: str | None

    def factory(self, resume: bool) -> Callable[[Trainer, RunFolder], Recorder]:
        """The `make_recorder` of a run (`curious.runs.driver.train`)."""
        from curious.watching.recording.rollout_capture import recorder_factory

        settings = RecorderSettings()
        if self.rollout_every is not None:
            settings = RecorderSettings(rollout_every=self.rollout_every)
        return recorder_factory(resume, settings, self.spawn, connect=self.connect)


@dataclass(frozen=True)
class _SeedRun:
    """One run of `curious train --seeds`, trained in a process of its own: its summary line."""

    config: Config
    out: Path
    resume: bool
    restart: bool
    recording: _Recording | None
    position: int

    def __call__(self) -> str:
        from curious.runs.driver import train

        trainer = train(
            self.config, self.out, resume=self.resume, restart=self.restart,
            make_recorder=self.recording.factory(self.resume) if self.recording else None,
            stop=stop_requested, position=self.position,
        )  # fmt: skip
        return _summary(trainer, self.out)


def _train_seeds(
    args: argparse.Namespace, configs: list[Config], recording: _Recording | None
) -> int:
    """`--seeds`: every seed's folder checked, then each run in a process of its own, side by
    side (`curious.runs.side_by_side`), its summary line printed once all have ended."""
    from curious.runs.checkpoint import CheckpointError

    outs = [Path(args.out) / f"seed-{config.seed}" for config in configs]
    # With --resume, a seed whose run a stop kept from beginning starts (see `_config`); with
    # no seed's run begun, each is refused as --resume refuses an empty folder.
    begun = [RunFolder(out).has_config for out in outs]
    resumes = [args.resume and (has or not any(begun)) for has in begun]
    try:
        check_writable(args.out, "--out", folder=True)  # the seeds' common folder, first
        for config, out, resume in zip(configs, outs, resumes, strict=True):
            RunFolder.prepare(out, config, resume, args.restart)  # writes nothing
        workers = _workers(args.workers, configs)
    except (ConfigError, RunFolderError, CheckpointError) as exc:
        return refuse("train", exc)
    except OSError as exc:
        return refuse("train", exc, message=_os_error(exc))
    runs = [
        _SeedRun(config, out, resume, args.restart, recording, position)
        for position, (config, out, resume) in enumerate(zip(configs, outs, resumes, strict=True))
    ]
    try:
        results = run_side_by_side(runs, workers)
    except Interrupted as stopped:
        _report_failures(outs, stopped.results)
        print(
            "curious train: stopped; every run ended at a checkpoint: go on with --resume",
            file=sys.stderr,
        )
        return 130
    for result in results:
        if isinstance(result, str):
            print(result)
    return 1 if _report_failures(outs, results) else 0


def _workers(asked: int | None, configs: list[Config]) -> int:
    """How many seeds train at once: `--workers`, by default the cores over each run's
    environment processes; and no more than fit in this machine's memory together (each run
    checks its own as it starts, and one too big alone is refused here)."""
    check_each_fits(configs)
    cores = os.cpu_count() or 1
    wanted = asked or max(1, cores // max(config.processes for config in configs))
    fit = runs_that_fit(configs)
    if fit < min(wanted, len(configs)):
        print(
            f"curious train: {fit} of the {len(configs)} runs at a time: what fits in this "
            "machine's memory together",
            file=sys.stderr,
        )
    return min(wanted, fit)


def _report_failures(outs: list[Path], results: list[object]) -> bool:
    """A line on stderr for each run that failed (`Failed`); whether one did."""
    failed = [(out, r) for out, r in zip(outs, results, strict=True) if isinstance(r, Failed)]
    for out, result in failed:
        print(f"curious train: error: {out}: {result.message}", file=sys.stderr)
    return bool(failed)


def _os_error(exc: OSError) -> str:
    """An `OSError` as one line: what went wrong and where."""
    where = f": {exc.filename}" if exc.filename else ""
    return f"{exc.strerror or exc}{where}"


def _warn_if_the_sensor_never_fails(config: Config) -> None:
    """A line on stderr where the sensor_failure variant trains without its failure ever
    starting: no onset set, or one at or past the run's end (a control run is a choice, but
    a forgotten setting reads the same in the tables)."""
    if config.variant != "sensor_failure":
        return
    why = None
    if not config.sensor_failure:
        why = "neither sensor_failure_episode nor sensor_failure_competence is set"
    elif config.sensor_failure_episode >= config.total_episodes:
        why = (
            f"sensor_failure_episode {config.sensor_failure_episode:,} is at or past "
            f"total_episodes {config.total_episodes:,}"
        )
    if why is not None:
        print(
            f"curious train: warning: variant sensor_failure, but {why}: the sensor never "
            "fails in this run",
            file=sys.stderr,
        )


def _check_viewer_url(url: str) -> None:
    """A `ConfigError` unless Rerun takes `url` as a gRPC endpoint and something listens there,
    checked before any run starts: Rerun would refuse a bad url only when the recording opens,
    and with nothing listening its first flush waits minutes for a viewer."""
    import rerun as rr

    from curious.watching.recording.working_file import DEFAULT_VIEWER_PORT

    try:
        rr.GrpcSink(url)
    except (RuntimeError, ValueError) as exc:
        raise ConfigError(
            f"--connect {url!r} is not a Rerun gRPC url ({exc}); a viewer's is "
            "rerun+http://HOST:9876/proxy"
        ) from None
    parts = urlsplit(url)
    default_port = 443 if parts.scheme.endswith("https") else DEFAULT_VIEWER_PORT
    address = (parts.hostname or "127.0.0.1", parts.port or default_port)
    try:
        socket.create_connection(address, timeout=VIEWER_CONNECT_SECONDS).close()
    except OSError as exc:
        host, port = address
        raise ConfigError(
            f"--connect {url}: nothing answers at {host}:{port} ({exc.strerror or exc}); "
            "start the viewer first (`rerun`, or `rerun --serve-web --bind 127.0.0.1` on a machine "
            "without a "
            "display; through ssh, `ssh -R 9876:127.0.0.1:9876 HOST` from the viewer's machine), "
            "or drop --connect"
        ) from None


VIEWER_CONNECT_SECONDS = 5.0
"""How long `--connect` waits for the viewer to answer before the run starts."""


def _config(args: argparse.Namespace, seed: int | None, overrides: dict[str, Any]) -> Config:
    """The run's config: the preset's, with the condition, seed and overrides given. With
    --resume, a run folder that holds a run goes on with the settings in its config.json
    (what `--set total_episodes` or a placement setting was then included); the options given
    replace them, and `check_resumable` refuses those a resume cannot change. A seed of
    `--seeds` whose run a stop kept from beginning takes the settings of the first seed's run
    that began, with its own seed."""
    identity = {"preset": args.preset, "condition": args.condition, "seed": seed}

    if args.seeds is None:
        folders = [RunFolder(args.out)]
    else:  # this seed's folder first, then the others'
        seeds = [seed, *parse_seeds(args.seeds)]
        folders = [RunFolder(Path(args.out) / f"seed-{s}") for s in dict.fromkeys(seeds)]
    begun = next((folder for folder in folders if folder.has_config), None)
    if args.resume and begun is not None:
        try:
            stored = begun.read_config()
        except RunFolderError as exc:
            raise ConfigError(str(exc)) from None
        given = {k: v for k, v in identity.items() if v is not None}
        return dataclasses.replace(stored, **{**given, **overrides})
    preset = "quick" if args.preset is None else args.preset  # '' is no preset, not the default
    condition = "curious" if args.condition is None else args.condition
    return resolve(preset, condition, 0 if seed is None else seed, overrides)


def _summary(trainer: Trainer, out: str | Path) -> str:
    """What a finished run reached: its competence per module (none in `her`)."""
    if not trainer.condition.self_evaluates:  # her: no competence; its score is in the tables
        return f"{trainer.episodes} episodes in {out}; no self-evaluations (her)"
    competence = trainer.tracker.competence()
    summary = ", ".join(
        f"{name} {c:.2f}" for name, c in zip(trainer.spec.module_names, competence, strict=True)
    )
    return f"{trainer.episodes} episodes in {out}; competence: {summary}"
