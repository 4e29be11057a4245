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
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from curious.config import ConfigError
from curious.reproduction.experiments import RunSpec
from curious.runs.folder import RunFolder
from curious.runs.folder_errors import ConfigMismatch, RunFolderError
from curious.runs.folder_errors import RunFolderBusy as Busy
from curious.runs.folder_lock import folder_lock
from curious.runs.folder_lock import lock_path as folder_lock_path

FINISHED, PARTIAL, NEW = "finished", "partial", "new"


class RunFolderMismatch(RuntimeError):
    """A partition's folder holds something other than (a part of) the run it should hold."""


class RunFolderBusy(RunFolderMismatch):
    """Another process is training the partition's run folder right now."""


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
    return RunFolder(folder).episodes_logged()


def folder_state(spec: RunSpec, runs_root: str | os.PathLike, overrides: dict | None = None) -> str:
    """`new`, `partial` or `finished` (see the module docstring); raises `RunFolderMismatch`.

    Whether the folder holds (a part of) the run is the check a resume makes
    (`curious.runs.folder.RunFolder.check_resumable`)."""
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
    return folder_lock_path(run_folder(spec, runs_root))


@contextlib.contextmanager
def training_lock(
    spec: RunSpec, runs_root: str | os.PathLike, claim: bool = True
) -> Iterator[None]:
    """Hold the run's lock (`curious.runs.folder_lock.folder_lock`, the one `train` takes while it
    trains); raise `RunFolderBusy` if another process holds it."""
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
    """Bring one partition's run folder to its budget (see the module docstring): a finished
    run is left as it is, a partial one resumes, a new one starts, as `curious train` trains
    it, with its own recorder."""
    from curious.runs.driver import train

    os.environ.setdefault("MUJOCO_GL", "disable")
    tic = time.perf_counter()
    folder = run_folder(spec, runs_root)
    state = folder_state(spec, runs_root, overrides)
    if state == FINISHED:
        episodes = episodes_logged(folder)
        return PartitionResult(
            spec.partition_key, str(folder), state, episodes, 0.0, False, runner_name()
        )
    resume = state == PARTIAL
    try:  # `train` holds the run folder's lock while it trains
        trainer = train(
            spec.config(overrides),
            folder,
            resume=resume,
            make_recorder=_make_recorder(spec, record, resume),
            stop_after_cycles=stop_after_cycles,
        )
    except Busy as exc:
        raise RunFolderBusy(str(exc)) from None
    seconds = time.perf_counter() - tic
    return PartitionResult(
        spec.partition_key, str(folder), state, trainer.episodes, seconds, True, runner_name()
    )
