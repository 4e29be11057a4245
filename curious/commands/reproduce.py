"""`curious reproduce`: train every run a budget asks for and rebuild every figure and the report.

    curious reproduce                                   # budget quick into runs/quick
    curious reproduce --budget smoke --out /tmp/smoke   # seconds per run
    curious reproduce --experiments main,distractors    # a subset of the experiments
    curious reproduce --budget paper --ray-address auto --runs-dir /shared/curious
    curious reproduce --budget paper --device cuda      # one GPU node: a run per core, sharing it
    curious reproduce --from-data data/laptop           # the report and figures from shipped runs

The assets (pipelines/) are materialised in this process on a Dagster instance kept in
OUT/.dagster: no server to start. Training runs go to worker processes (one per core unless
--workers says otherwise), or to Ray tasks with --ray-address, one run to a process or a task.
A second call with the same budget and --out retrains nothing that is finished and resumes what
was interrupted.

The README's job, `curious reproduce` (budget quick), shows the paper's claims first: once its
input is checked, it builds the report and figures of the shipped `laptop` campaign
(data/laptop, committed with the repository) into runs/laptop-shipped beside its own output, in
seconds, and prints where they and the claims' results table are; then it trains the quick
budget, saying what that can and cannot show (the pipeline working on this machine, not the
claims), and ends by saying what each output shows (`SHIPPED_BESIDE`; --no-shipped leaves the
campaign out).

--from-data DATA trains nothing: it reads the runs from a shipped data folder (`curious ship`;
the repository's data/<budget>), every experiment it holds complete unless --experiments says
otherwise (an experiment of several variants, complete for some of them only, from those
variants; one complete for some of its seeds only, from those seeds; the report naming the others
left out), with its budget unless --budget says otherwise, and
builds the same report and figures into --out (default runs/<budget>-shipped). DATA is only
read.

Errors about the input (unknown budget or experiment, an output folder made by another budget, a
run folder holding another run, a Ray address that does not answer, an output folder that
another `curious reproduce` is working in, one that cannot be written, or a number out of its
range) are reported in one line, exit status 2, before anything is written. Ctrl-C stops every
run at once with one line, exit status 130; the same command then goes on where they stopped.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from curious.commands import add_set_option, refuse
from curious.config import PLACEMENT_FIELDS, ConfigError
from curious.overrides import parse_overrides
from curious.reproduction.experiments import (
    BUDGETS,
    DEFAULT_BUDGET,
    ExperimentError,
    experiment_names,
    get_budget,
)
from curious.runs.folder_errors import RunFolderError
from curious.runs.folder_lock import check_writable
from curious.runs.shipped_folder import ShippedError, ShippedFolder
from curious.runs.side_by_side import MAX_WORKERS
from pipelines.executors import PartitionFailed, RayUnavailable, make_pool
from pipelines.reproduce import ReproduceError, reproduce
from pipelines.training import RunFolderMismatch

if TYPE_CHECKING:
    from pipelines.reproduce import ReproduceResult

LOOPBACK = "127.0.0.1"
"""Where the Dagster UI of the closing line listens: this machine only (an SSH tunnel reaches it
from another)."""


class _PresetIsForTrain(argparse.Action):
    """`--preset` given to `curious reproduce`: an error naming `--budget`, its option.

    Reproduce took `--preset` before budgets were named apart from training presets; the hidden
    option turns the old spelling into a clear error instead of "unrecognized arguments".
    """

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: str | None,
        option_string: str | None = None,
    ) -> None:
        parser.error(
            f"reproduce takes --budget {values or 'NAME'} ({', '.join(BUDGETS)}), not --preset; "
            "training presets are for `curious train --preset`"
        )


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious reproduce`."""
    parser = sub.add_parser(
        "reproduce",
        help="train a budget's runs and rebuild every figure and report.md",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="budgets:\n"
        + "\n".join(f"  {name:8s}{b.description}" for name, b in BUDGETS.items()),
    )
    parser.add_argument(
        "--budget",
        default=None,
        help=f"experiments, seeds and episodes: {', '.join(BUDGETS)} (default {DEFAULT_BUDGET}; "
        "with --from-data, the shipped runs' budget)",
    )
    parser.add_argument(
        "--preset",
        nargs="?",
        action=_PresetIsForTrain,
        default=argparse.SUPPRESS,
        help=argparse.SUPPRESS,
    )
    parser.add_argument(
        "--experiments",
        default=None,
        metavar="LIST",
        help="the experiments to reproduce, comma-separated, e.g. main,long (default: all the "
        f"budget's), of: {', '.join(experiment_names())}",
    )
    parser.add_argument(
        "--out",
        default=None,
        help="output folder (default: runs/<budget>; with --from-data, runs/<budget>-shipped)",
    )
    parser.add_argument(
        "--from-data",
        default=None,
        metavar="DATA",
        help="read the runs from a shipped data folder (curious ship) instead of training them",
    )
    parser.add_argument(
        "--runs-dir",
        default=None,
        help="where run folders go, e.g. storage every Ray node sees (default: OUT/runs; for an "
        "OUT made with --runs-dir, the folder it was made with)",
    )
    parser.add_argument(
        "--ray-address",
        default=None,
        metavar="ADDR",
        help="train the runs as Ray tasks on the cluster at HOST:PORT, or `auto`",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes training runs at once on this machine, 1 to "
        f"{MAX_WORKERS:,} (default: one per core, with --device cuda too, the processes sharing "
        "the GPU), given no more runs at a time than fit in its memory together; ignored with Ray",
    )
    parser.add_argument(
        "--cpus-per-run",
        type=float,
        default=None,
        help="Ray CPUs per run (default 1; with --ray-address)",
    )
    parser.add_argument(
        "--gpus-per-run",
        type=float,
        default=0.0,
        help="Ray GPUs per run; > 0 trains the networks with device=cuda (with --ray-address; "
        "on this machine, --device cuda)",
    )
    parser.add_argument(
        "--device",
        choices=("cpu", "cuda"),
        default=None,
        help="where the networks train in local runs (default cpu; Ray runs with GPUs use cuda)",
    )
    add_set_option(
        parser,
        "set where and how fast every run goes (repeatable): device, env_processes, "
        "torch_threads, act_on_cpu, prefetch_minibatches, checkpoint_every_cycles",
    )
    parser.add_argument(
        "--no-record", action="store_true", help="do not write Rerun recordings (recording.rrd)"
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    parser.add_argument(
        "--no-shipped",
        action="store_true",
        help="do not build the shipped campaign's report beside a quick reproduction",
    )
    parser.set_defaults(func=run)


def _experiments(text: str | None) -> list[str] | None:
    if text is None:
        return None
    return [part.strip() for part in text.split(",")]


def placement_overrides(items: list[str]) -> dict[str, object]:
    """`--set KEY=VALUE` items, typed; only settings that leave what a run computes as it is
    (`curious.config.PLACEMENT_FIELDS`), since the budget defines the runs."""
    overrides = parse_overrides(items)
    other = sorted(set(overrides) - PLACEMENT_FIELDS)
    if other:
        raise ConfigError(
            f"reproduce --set takes only {', '.join(sorted(PLACEMENT_FIELDS))}, which change "
            f"where and how fast the runs go, not what they compute; {', '.join(other)} would "
            "change the budget's runs (train such runs one by one with `curious train --set`)"
        )
    return overrides


def run(args: argparse.Namespace) -> int:
    options = (
        ("--out", args.out, "a folder"),
        ("--runs-dir", args.runs_dir, "a folder"),
        ("--from-data", args.from_data, "a folder"),
        ("--ray-address", args.ray_address, "a cluster, HOST:PORT or auto"),
    )
    for option, value, what in options:
        if value is not None and not value.strip():
            print(f"curious reproduce: error: {option} is empty: name {what}", file=sys.stderr)
            return 2
    if args.from_data is not None:
        return _from_data(args)
    args.budget = DEFAULT_BUDGET if args.budget is None else args.budget  # '' is unknown
    if args.workers is not None and not 1 <= args.workers <= MAX_WORKERS:
        print(
            f"curious reproduce: error: --workers must be from 1 to {MAX_WORKERS:,} (worker "
            f"processes on this machine; it has {os.cpu_count() or 1} cores), got {args.workers:,}",
            file=sys.stderr,
        )
        return 2
    cpus = 1.0 if args.cpus_per_run is None else args.cpus_per_run
    resources = (
        ("--cpus-per-run", cpus, cpus > 0, "> 0"),
        ("--gpus-per-run", args.gpus_per_run, args.gpus_per_run >= 0, ">= 0"),
    )
    for option, value, fits, bound in resources:
        if not (fits and math.isfinite(value)):
            print(
                f"curious reproduce: error: {option} must be a number {bound}, got {value}",
                file=sys.stderr,
            )
            return 2
    ray_only = [
        flag
        for flag, given in (
            ("--cpus-per-run", args.cpus_per_run is not None),
            ("--gpus-per-run", args.gpus_per_run > 0),
        )
        if given
    ]
    if ray_only and not args.ray_address:  # on this machine they would do nothing
        gpu = ", or, to train on this machine's GPU, --device cuda" if args.gpus_per_run else ""
        print(
            f"curious reproduce: error: {' and '.join(ray_only)} size the runs' Ray tasks: pass "
            f"--ray-address too{gpu}",
            file=sys.stderr,
        )
        return 2
    args.cpus_per_run = cpus

    try:
        overrides = placement_overrides(args.overrides)
        if args.runs_dir is not None and args.ray_address is None:  # Ray's nodes may see another
            check_writable(args.runs_dir, "--runs-dir", folder=True)
    except (ConfigError, RunFolderError) as exc:
        return refuse("reproduce", exc)
    if args.device:
        overrides["device"] = args.device
    if overrides.get("device") == "cuda" and not args.ray_address:
        import torch

        if not torch.cuda.is_available():
            print("curious reproduce: error: --device cuda, but torch sees no GPU", file=sys.stderr)
            return 2

    def pool():
        return make_pool(args.ray_address, args.workers, args.cpus_per_run, args.gpus_per_run)

    shipped: list[ReproduceResult] = []

    def claims_first() -> None:
        """Between the checks and the training: the shipped campaign's report, then what the
        budget about to train can show."""
        if args.budget not in SHIPPED_BESIDE:
            return
        if not args.no_shipped:
            built = _build_shipped_beside(args.budget, args.out, not args.no_progress)
            shipped.extend([built] if built is not None else [])
        _about_to_train(args.budget)

    try:
        result = reproduce(
            args.budget,
            experiments=_experiments(args.experiments),
            out=args.out,
            runs_dir=args.runs_dir,
            make_pool=pool,
            overrides=overrides or None,
            record=not args.no_record,
            progress=not args.no_progress,
            before_training=claims_first,
        )
    except (ExperimentError, ConfigError, ReproduceError, RunFolderMismatch, RayUnavailable) as exc:
        return refuse("reproduce", exc)
    except PartitionFailed as exc:
        print(f"curious reproduce: a training run failed: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(
            "curious reproduce: interrupted; the runs keep what they had at their last "
            "checkpoint, and the same command goes on from there",
            file=sys.stderr,
        )
        return 130

    result.seconds -= sum(s.seconds for s in shipped)  # its own time, said by its own line
    _done(result)
    if result.budget in SHIPPED_BESIDE:
        _what_each_shows(result, shipped[0] if shipped else None)
    return 0


SHIPPED_BESIDE: dict[str, str] = {"quick": "laptop"}
"""Budget trained -> the shipped campaign (data/<name>) whose report `curious reproduce` builds
beside it: the quick runs cannot show the paper's claims, the shipped campaign's can."""

CLAIMS: dict[str, str] = {
    "main": "C1, CURIOUS learns faster than MG-TE (Fig. 2a, with its Welch test per bin); "
    "C2, the order of learning (Fig. 2b/2c, Table 1)",
    "sensor_failure": "C5 on a module just learned, the refocus and the recovery after a "
    "sensory failure (the sensor_failure figure)",
    "distractors": "C4, CURIOUS against M-UVFA with distracting modules (the distractors figure)",
    "sensor_failure_mastered": "C5, the recovery of a mastered module's test success after a "
    "sensory failure, CURIOUS against M-UVFA (the sensor_failure_mastered figure, with its Welch "
    "test)",
    "long": "C3, spontaneous forgetting of a mastered module over the paper's 300,000 episodes "
    "(the long_runs figure, Fig. 2b-c over each whole run)",
}
"""What each experiment's figures and numbers test, in the paper's claims (in their order)."""


def shipped_data_folder(name: str) -> Path | None:
    """The repository's shipped data folder data/<name> (beside the `curious` package of a
    clone, else in the working directory), or None where neither holds one."""
    here = Path(__file__).resolve().parents[2]
    for root in (here, Path.cwd()):
        folder = ShippedFolder(root / "data" / name)
        if folder.is_shipped:
            return folder.path
    return None


def results_page() -> Path | None:
    """docs/results.md of the clone this package lies in (the claims' results table, each
    verdict with its numbers), or None where there is none (an install without the docs)."""
    page = Path(__file__).resolve().parents[2] / "docs" / "results.md"
    return page if page.is_file() else None


def _build_shipped_beside(budget: str, out: str | None, progress: bool) -> ReproduceResult | None:
    """The shipped campaign's report and figures, into <campaign>-shipped beside OUT (`out`,
    else the budget's default), then where they and the claims' results table are; None (with
    a line saying why) where the budget has none or it cannot be built."""
    name = SHIPPED_BESIDE.get(budget)
    if name is None:
        return None
    data = shipped_data_folder(name)
    if data is None:
        print(
            f"No shipped data/{name} here (it comes with a clone of the repository): the "
            f"shipped campaign's report was not built.\n",
            file=sys.stderr,
        )
        return None
    beside = Path(out or get_budget(budget).default_out).parent / f"{name}-shipped"
    print(f"The paper's claims first: the shipped `{name}` campaign's report, from {data}:")
    try:
        shipped = reproduce(name, out=beside, progress=progress, from_data=data)
    except (ExperimentError, ReproduceError) as exc:
        print(f"curious reproduce: the shipped campaign's report was not built: {exc}\n")
        return None
    _done(shipped)
    page = results_page()
    table = f"\n  results table: {page} (each claim's verdict, with its numbers)" if page else ""
    print(f"  It shows {_claims(shipped)}.{table}\n")
    return shipped


def _claims(shipped: ReproduceResult) -> str:
    """The claims the shipped experiments' figures and numbers test (`CLAIMS`), in order."""
    return "; ".join(text for e, text in CLAIMS.items() if e in shipped.experiments)


def _what_it_can_show(budget: str) -> str:
    """What a budget with a shipped campaign beside it can show, trained here."""
    chosen = get_budget(budget)
    return (
        f"budget `{budget}`, trained here ({chosen.description}). It checks that training, the "
        "analysis and the figures run on this machine; it cannot show the paper's claims. "
        f"{chosen.caption_note}"
    )


def _about_to_train(budget: str) -> None:
    """The line before a budget with a shipped campaign beside it trains: what it can show."""
    print(f"Now the {_what_it_can_show(budget)}")


def _what_each_shows(result: ReproduceResult, shipped: ReproduceResult | None) -> None:
    """The closing lines of a budget with a shipped campaign beside it: where each output is
    and what it can show."""
    print("\nWhat each output can show:")
    print(
        f"  {result.layout.report} and {result.layout.figures}/\n"
        f"    {_what_it_can_show(result.budget)}"
    )
    if shipped is not None:
        print(
            f"  {shipped.layout.report} and {shipped.layout.figures}/\n"
            f"    the shipped `{shipped.budget}` campaign, {len(shipped.results)} runs read from "
            f"{shipped.from_data}: the paper's claims as far as its runs go, each figure with "
            f"its statistics: {_claims(shipped)}."
        )


_TRAINING_OPTIONS = {
    "runs_dir": "--runs-dir",
    "ray_address": "--ray-address",
    "workers": "--workers",
    "device": "--device",
    "overrides": "--set",
}


def _from_data(args: argparse.Namespace) -> int:
    """`--from-data`: the report and figures from shipped runs; nothing is trained."""
    given = [flag for name, flag in _TRAINING_OPTIONS.items() if getattr(args, name)]
    given += ["--cpus-per-run"] if args.cpus_per_run is not None else []
    given += ["--gpus-per-run"] if args.gpus_per_run else []
    if given:
        print(
            f"curious reproduce: error: --from-data trains nothing, so {', '.join(given)} "
            f"would do nothing: leave {'it' if len(given) == 1 else 'them'} out",
            file=sys.stderr,
        )
        return 2
    try:
        budget = args.budget
        folder = ShippedFolder(args.from_data)
        if budget is None and folder.is_shipped:
            budget = folder.read_manifest().budget
        result = reproduce(
            DEFAULT_BUDGET if budget is None else budget,
            experiments=_experiments(args.experiments),
            out=args.out,
            progress=not args.no_progress,
            from_data=args.from_data,
        )
    except (ExperimentError, ReproduceError, RunFolderMismatch, ShippedError) as exc:
        return refuse("reproduce", exc)
    _done(result)
    return 0


def _done(result: ReproduceResult) -> None:
    """The closing lines: what was done, and where the products are."""
    layout = result.layout
    minutes, seconds = divmod(round(result.seconds), 60)
    if result.from_data is not None:
        done = f"{len(result.results)} shipped run(s) read, none trained"
    else:
        done = f"{len(result.trained)} run(s) trained, {len(result.skipped)} already finished"
    print(f"\nDone in {minutes}m{seconds:02d}s: {done}.")
    print(f"  report:  {layout.report}")
    print(f"  figures: {layout.figures}")
    print(f"  runs:    {layout.runs_root}")
    shipped = f"CURIOUS_FROM_DATA={result.from_data} " if result.from_data else ""
    print(
        f"  Dagster: DAGSTER_HOME={layout.dagster_home} CURIOUS_BUDGET={result.budget} "
        f"CURIOUS_OUT={layout.out} {shipped}dagster-webserver -h {LOOPBACK} "
        "-m pipelines.code_location"
    )
