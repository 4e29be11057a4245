"""One partition = one training run in one run folder; what a worker process (or Ray task) runs.

`run_partition(spec, runs_root)` decides from the folder alone what to do:

=============  ===================================================================
state          what happens
=============  ===================================================================
``new``        no folder, or an empty one: train from episode 0
``partial``    config.json of the same run and fewer episodes than the budget (a run
               that was interrupted): `curious.runs.driver.train(..., resume=True)` goes on
               from its last checkpoint
``finished``   a checkpoint at the budget and every episode in metrics.parquet:
               nothing is done
=============  ===================================================================

`run_group(specs, runs_root)` does the same for several runs at once (`curious reproduce
--population`): each folder's state is decided as above, and the runs still to train train as
one population in this process (`curious.runs.population`), each resumed or started as its
folder says, under its own lock, with its own recorder.

A folder holding anything else (another budget's run, another condition, files that are not a
run) raises `RunFolderMismatch` before anything is written, so a finished run is never touched.
While a process trains a run it holds a lock beside the folder (`.seed-<s>.lock`, an advisory
`flock` that dies with the process), so two reproductions never train the same folder at once.

The sensory failure of the `sensor_failure` experiment is a training setting
(`Config.sensor_failure_episode` or `Config.sensor_failure_competence`, set by `RunSpec.config`):
the trainer switches it for each episode and logs it in metrics.parquet (`sensor_failure`), where
the analysis reads when it started; config.json records the setting.

Nothing here imports Dagster: worker processes and Ray tasks only need `curious`.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from curious.reproduction.experiments import RunSpec

if TYPE_CHECKING:
    from curious.runs.folder import RunFolder
    from curious.runs.hooks import Recorder
    from curious.runs.trainer import Trainer

FINISHED, PARTIAL, NEW = "finished", "partial", "new"


class RunFolderMismatch(RuntimeError):
    """A partition's folder holds something other than (a part of) the run it should hold."""


class RunFolderBusy(RunFolderMismatch):
    """Another process is training the partition's run folder right now."""


class RunsFailed(RuntimeError):
    """Runs of a group trained as a population failed (the others trained to their end): the
    message names each failed run and its error, a line each. Only a message, so that it
    crosses from a worker process or a Ray task as it is."""


@dataclass(frozen=True)
class PartitionResult:
    """What one partition's training did."""

    partition_key: str
    path: str
    state_before: str  # new, partial or finished
    episodes: int  # episodes in the folder afterwards
    seconds: float  # wall time of this call
    trained: bool  # False when the run was already finished
    runner: str = ""  # where it ran: "ray node <id>" or "local pid <pid>"


def runner_name() -> str:
    """Where this process runs: a Ray worker's node, or a local process id."""
    ray = sys.modules.get("ray")
    if ray is not None and ray.is_initialized():
        return f"ray node {ray.get_runtime_context().get_node_id()[:12]} pid {os.getpid()}"
    return f"local pid {os.getpid()}"


def run_folder(spec: RunSpec, runs_root: str | os.PathLike) -> Path:
    return Path(runs_root, *spec.relative_path.parts)


def episodes_logged(folder: Path) -> int:
    """Episodes in a run folder's metrics.parquet (0 when there is none yet)."""
    from curious.runs.folder import RunFolder

    return RunFolder(folder).episodes_logged()


def folder_state(spec: RunSpec, runs_root: str | os.PathLike, overrides: dict | None = None) -> str:
    """`new`, `partial` or `finished` (see the module docstring); raises `RunFolderMismatch`.

    Whether the folder holds (a part of) the run is the check a resume makes
    (`curious.runs.folder.RunFolder.check_resumable`)."""
    from curious.config import ConfigError
    from curious.runs.folder import RunFolder
    from curious.runs.folder_errors import ConfigMismatch, RunFolderError

    folder = RunFolder(run_folder(spec, runs_root))
    if folder.path.exists() and not folder.path.is_dir():
        raise RunFolderMismatch(f"{folder.path} exists and is not a folder")
    if not folder.path.exists() or not any(folder.path.iterdir()):
        return NEW
    if not folder.has_config:
        raise RunFolderMismatch(
            f"{folder.path} is not empty but holds no {folder.config_path.name}: it is not a run "
            "folder of this pipeline; move it away or choose another --out"
        )
    try:
        expected = spec.config(overrides)
    except ConfigError as exc:
        raise RunFolderMismatch(f"{spec.label}: {exc}") from None
    try:
        folder.check_resumable(expected)
    except ConfigMismatch as exc:
        if "preset" in exc.differences:
            stored, _ = exc.differences["preset"]
            raise RunFolderMismatch(
                f"{folder.path} holds a run of training preset {stored!r}, not "
                f"{expected.preset!r}: this output folder was made by another budget; choose "
                "another --out"
            ) from None
        detail = ", ".join(f"{k}: {a!r} != {b!r}" for k, (a, b) in exc.differences.items())
        raise RunFolderMismatch(
            f"{folder.path} holds another run ({detail}); choose another --out"
        ) from None
    except RunFolderError as exc:
        raise RunFolderMismatch(f"{exc}; or move the folder away") from None
    if folder.finished_at(expected.total_episodes):
        return FINISHED
    return PARTIAL


def _make_recorder(spec: RunSpec, record: bool, resume: bool):
    """The `make_recorder` hook of `train()`: the run's Rerun recorder (with 3-D rollouts), as
    `curious train` makes it, or none."""
    if not record:
        return None
    from curious.watching.recording.rollout_capture import recorder_factory

    return recorder_factory(resume, run_name=spec.label)


def lock_path(spec: RunSpec, runs_root: str | os.PathLike) -> Path:
    """The lock file beside a run folder (`curious.runs.folder_lock.lock_path`)."""
    from curious.runs.folder_lock import lock_path as folder_lock_path

    return folder_lock_path(run_folder(spec, runs_root))


@contextlib.contextmanager
def training_lock(
    spec: RunSpec, runs_root: str | os.PathLike, claim: bool = True
) -> Iterator[None]:
    """Hold the run's lock (`curious.runs.folder_lock.folder_lock`, the one `train` takes while it
    trains); raise `RunFolderBusy` if another process holds it."""
    from curious.runs.folder_errors import RunFolderBusy as Busy
    from curious.runs.folder_lock import folder_lock

    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(folder_lock(run_folder(spec, runs_root), claim=claim))
        except Busy as exc:
            raise RunFolderBusy(str(exc)) from None
        yield


def check_not_busy(spec: RunSpec, runs_root: str | os.PathLike) -> None:
    """Raise `RunFolderBusy` if some process is training this run right now."""
    if lock_path(spec, runs_root).exists():
        with training_lock(spec, runs_root, claim=False):
            pass


def run_partition(
    spec: RunSpec,
    runs_root: str | os.PathLike,
    overrides: dict | None = None,
    record: bool = True,
    stop_after_cycles: int | None = None,
) -> PartitionResult:
    """Bring one partition's run folder to its budget (see the module docstring): a group of
    one run (`run_group`)."""
    return run_group((spec,), runs_root, overrides, record, stop_after_cycles)[0]


def run_group(
    specs: Sequence[RunSpec],
    runs_root: str | os.PathLike,
    overrides: dict | None = None,
    record: bool = True,
    stop_after_cycles: int | None = None,
) -> list[PartitionResult]:
    """Bring the run folders of `specs` to their budgets, each as `run_partition` would (the
    module docstring: a finished run is left as it is, a partial one resumes, a new one starts),
    the runs still to train trained at once in this process: a population
    (`curious.runs.population`), or one run alone as `curious train` trains it. One result per
    run, in the order of `specs`; runs of the population that fail raise `RunsFailed` naming
    them, once the others have trained."""
    from curious.runs.folder_errors import RunFolderBusy as Busy

    os.environ.setdefault("MUJOCO_GL", "disable")
    tic = time.perf_counter()
    folders = [run_folder(spec, runs_root) for spec in specs]
    states = [folder_state(spec, runs_root, overrides) for spec in specs]
    todo = [i for i, state in enumerate(states) if state != FINISHED]
    try:  # `train` holds each run folder's lock while it trains
        trainers = _train_runs(
            [specs[i] for i in todo],
            [folders[i] for i in todo],
            [states[i] == PARTIAL for i in todo],
            overrides,
            record,
            stop_after_cycles,
        )
    except Busy as exc:
        raise RunFolderBusy(str(exc)) from None
    episodes = dict(zip(todo, (t.episodes for t in trainers), strict=True))
    seconds = time.perf_counter() - tic
    return [
        PartitionResult(
            spec.partition_key,
            str(folder),
            state,
            episodes[i] if i in episodes else episodes_logged(folder),
            seconds if i in episodes else 0.0,
            i in episodes,
            runner_name(),
        )
        for i, (spec, folder, state) in enumerate(zip(specs, folders, states, strict=True))
    ]


def _train_runs(
    specs: Sequence[RunSpec],
    folders: Sequence[Path],
    resumes: Sequence[bool],
    overrides: dict | None,
    record: bool,
    stop_after_cycles: int | None,
) -> list[Trainer]:
    """Train the runs of `specs` in `folders` (resuming where `resumes` says): one alone, so
    that its copies may step in worker processes (`env_processes`); several as a population,
    each with its own recorder."""
    from curious.runs.driver import train
    from curious.runs.population import PopulationError, train_population

    if not specs:
        return []
    configs = [spec.config(overrides) for spec in specs]
    recorders = [
        _make_recorder(spec, record, resume) for spec, resume in zip(specs, resumes, strict=True)
    ]
    if len(specs) == 1:
        trainer = train(
            configs[0],
            folders[0],
            resume=resumes[0],
            make_recorder=recorders[0],
            stop_after_cycles=stop_after_cycles,
        )
        return [trainer]
    by_folder = {folder.resolve(): make for folder, make in zip(folders, recorders, strict=True)}

    def make_recorder(trainer: Trainer, folder: RunFolder) -> Recorder:
        """The recorder of the run in `folder`, made as that run alone makes it."""
        return by_folder[folder.path.resolve()](trainer, folder)

    labels = {folder.resolve(): spec.label for folder, spec in zip(folders, specs, strict=True)}
    try:
        return train_population(
            configs,
            folders,
            resume=resumes,
            make_recorder=make_recorder if record else None,
            stop_after_cycles=stop_after_cycles,
        )
    except PopulationError as exc:
        lines = [f"{labels[p]} failed: {type(e).__name__}: {e}" for p, e in exc.failures.items()]
        raise RunsFailed("\n".join(lines)) from None
