"""A run folder: where one training run (one condition, one seed) keeps everything, and the one
module that knows its format: the names of its files, what config.json holds (and how older ones
read), writing it, and whether a config may go on with the run it holds.

    config.json       the run's description (`RunFolder.describe`), read back as a `RunInfo`
    metrics.parquet   one row per training episode (`curious.runs.metrics`)
    tests.parquet     one row per test rollout (`curious.runs.metrics`)
    recording.rrd     the Rerun recording (written by `curious.watching.recording`)
    checkpoints/      resumable checkpoints, `ep-<episodes, 12 digits>/` (`curious.runs.checkpoint`)

config.json's keys:

    condition, seed, preset, variant  the run's identity (the same as in `config`)
    modules, achievable               module names in slot order, and whether each is achievable
    sensor_failure_modules            the modules the variant's sensory failure perturbs (empty:
                                      none), from the env (`EnvSpec.sensor_failure_modules`);
                                      config.json written before it was recorded lacks it, and
                                      `RunInfo` derives it from the variant's definition
    config                            the resolved settings (`Config.to_dict`)
    versions, git, created            libraries, source commit and time of the first start
    machine                           the machine of the first start (`machine`): processor,
                                      cores, system, and the GPU where it trains on one
    resumed                           one entry per resume: its time, libraries, commit, machine,
                                      settings

Who reads what: training (`prepare`, `write_config`, the paths), `curious evaluate`
(`read_config`), `curious progress` and the analysis (`read_info`, `episodes_logged`,
`newest_checkpoint`), the reproduction pipeline (`check_resumable`, `finished_at`), `curious ship`
(`read_info`, `finished_at`).

`prepare` checks a folder before anything is written: a non-empty folder is only accepted with
`resume=True`, and then only for the same config (`check_resumable`: fields in
`RESUMABLE_FIELDS` may change), or with `restart=True` when it holds a run's files and nothing
else (`clear` removes them once every check has passed). A config.json that is not a run's
(damaged, hand-edited into another shape, a setting of the wrong type) is a `RunFolderError`
naming the file. `folder_lock` keeps a second process out of a folder while one trains in it, and
leaves nothing behind.
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import functools
import json
import os
import platform
import re
import shutil
import socket
import subprocess
import tempfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from curious.config import RESUMABLE_FIELDS, Config, ConfigError, setting_names

if TYPE_CHECKING:
    from curious.envs.goal_env import EnvSpec

CONFIG_FILE = "config.json"
METRICS_FILE = "metrics.parquet"
TESTS_FILE = "tests.parquet"
RECORDING_FILE = "recording.rrd"
CHECKPOINTS_DIR = "checkpoints"
RUN_ENTRIES: tuple[str, ...] = (
    CONFIG_FILE,
    METRICS_FILE,
    TESTS_FILE,
    RECORDING_FILE,
    CHECKPOINTS_DIR,
)
"""What a run writes in its folder (with temporaries named after them, a leading dot aside)."""
EVALUATION_RECORDING_FILE = "evaluation.rrd"
"""Where `curious evaluate --record` writes without a FILE: the current folder, never a run
folder (a run folder holds a run's files only: `--restart` refuses one with more)."""

CHECKPOINT_PREFIX = "ep-"
_CHECKPOINT_NAME = re.compile(r"ep-(\d{12})")


class RunFolderError(RuntimeError):
    """A run folder that cannot be used as asked (nothing has been written)."""


class RunFolderBusy(RunFolderError):
    """Another process is training in the run folder right now."""


class ConfigMismatch(RunFolderError):
    """The folder holds another run than the config given (`RunFolder.check_resumable`)."""

    def __init__(self, message: str, differences: dict[str, tuple[Any, Any]]) -> None:
        super().__init__(message)
        self.differences = differences
        """Setting -> (value in config.json, value given); None for a side that lacks it."""


def check_writable(path: str | os.PathLike, option: str, folder: bool = False) -> None:
    """A `RunFolderError` naming `option` where nothing could be written at `path`: the nearest
    folder on the way to it that exists (`path` itself, with `folder`, where it is a folder that
    exists) is a file, or takes no new file (a read-only file system, a folder without write
    permission). Checked by making an empty file there and removing it, the one test that sees
    all of them (`os.access` answers for the permissions alone), before any work is done."""
    target = Path(path).absolute()
    existing = _nearest_existing(target if folder else target.parent)
    if not existing.is_dir():
        raise RunFolderError(f"{option} {path}: {existing} is a file, not a folder")
    try:
        handle, probe = tempfile.mkstemp(prefix=".curious-write-check-", dir=existing)
    except OSError as exc:
        raise RunFolderError(
            f"{option} {path} cannot be written: {existing}: {exc.strerror or exc}"
        ) from None
    os.close(handle)
    os.unlink(probe)


def _nearest_existing(path: Path) -> Path:
    """`path`, or the nearest of its parents that exists (where a write or a lock would land)."""
    return next(p for p in (path, *path.parents) if p.exists())


def lock_path(folder: str | os.PathLike) -> Path:
    """The lock file beside a run folder (inside it, it would make a new folder non-empty)."""
    path = Path(folder).absolute()
    return path.with_name(f".{path.name}.lock")


@contextlib.contextmanager
def folder_lock(
    folder: str | os.PathLike, claim: bool = True, activity: str = "trained"
) -> Iterator[None]:
    """Hold the run folder's lock; `RunFolderBusy` if another process holds it.

    An advisory `flock` on a file beside the folder: the system drops it when its process dies,
    however it dies, so a killed run never leaves a stale lock, and two processes never train
    one folder. With `claim`, the file names the holder (host and pid) for the error others get;
    `activity` says what the holder does there ("being trained by ...").

    The lock file is removed when the lock is given back, and so are the folders made to hold
    it when they stayed empty: a refused command leaves nothing behind. The file is removed
    while still locked, and a process that locked a file that is no longer the one at the path
    tries again, so that two processes never both hold "the" lock.
    """
    path = lock_path(folder)
    existing = _nearest_existing(path.parent)
    if not existing.is_dir():
        raise RunFolderError(f"cannot make {Path(folder)}: {existing} is a file, not a folder")
    made = [p for p in path.parents if not p.exists()]  # innermost first
    try:
        handle = _acquire(path, Path(folder), activity)
        try:
            if claim:
                handle.seek(0)
                handle.truncate()
                handle.write(f"{socket.gethostname()} pid {os.getpid()}\n")
                handle.flush()
            yield
        finally:
            path.unlink(missing_ok=True)  # before the unlock: nobody can hold it meanwhile
            fcntl.flock(handle, fcntl.LOCK_UN)
            handle.close()
    finally:
        for parent in made:  # only those this call made, and only while empty
            with contextlib.suppress(OSError):
                parent.rmdir()


def _acquire(path: Path, folder: Path, activity: str) -> IO[str]:
    """The open, locked lock file at `path` (see `folder_lock`)."""
    while True:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle = open(path, "a+")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "another process"
            handle.close()
            raise RunFolderBusy(
                f"{folder} is being {activity} by {holder}; wait for it to end, or stop it, "
                "before starting it again"
            ) from None
        try:  # the holder before may have removed the file between our open and our lock
            current = os.stat(path).st_ino == os.fstat(handle.fileno()).st_ino
        except FileNotFoundError:
            current = False
        if current:
            return handle
        handle.close()


def checkpoint_name(episodes: int) -> str:
    """The name of the checkpoint taken after `episodes` episodes, in `checkpoints/`."""
    return f"{CHECKPOINT_PREFIX}{episodes:012d}"


def checkpoint_episodes(path: str | os.PathLike) -> int | None:
    """The episodes a checkpoint's name says it was taken after; None for another name."""
    match = _CHECKPOINT_NAME.fullmatch(Path(path).name)
    return int(match.group(1)) if match else None


def list_checkpoints(directory: Path) -> list[Path]:
    """Complete checkpoints, oldest first (temporaries, `.tmp-ep-...`, are not listed)."""
    if not directory.exists():
        return []
    found = [p for p in directory.iterdir() if p.is_dir() and checkpoint_episodes(p) is not None]
    return sorted(found, key=lambda p: checkpoint_episodes(p) or 0)


def library_versions() -> dict[str, str | None]:
    """Installed versions of the libraries a run's results depend on."""
    versions: dict[str, str | None] = {"python": platform.python_version()}
    for dist in ("curious", "torch", "numpy", "mujoco", "dm-control", "rerun-sdk"):
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = None
    return versions


def _cpu_model() -> str:
    """The processor's model name (Linux's /proc/cpuinfo), else what `platform` knows."""
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name") and ":" in line:
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def machine(device: str = "cpu") -> dict[str, Any]:
    """What a run starts or resumes on, for the compute an experiment took: the processor, its
    logical cores, the system and, with ``device`` `cuda`, the GPU (no host name)."""
    gpu = None
    if device.startswith("cuda"):
        import torch

        if torch.cuda.is_available():
            gpu = torch.cuda.get_device_name(torch.device(device))
    affinity = getattr(os, "sched_getaffinity", None)  # the cores this process may use (Linux)
    cores = len(affinity(0)) if affinity is not None else os.cpu_count()
    return {
        "cpu": _cpu_model(),
        "cores": cores,
        "system": f"{platform.system()} {platform.release()}",
        "gpu": gpu,
    }


def machine_text(entry: Mapping[str, Any]) -> str:
    """One line for a `machine` entry, e.g. ``AMD EPYC 7B13, 2 cores``; empty where none."""
    if not entry.get("cpu"):
        return ""
    text = str(entry["cpu"])
    if entry.get("cores"):
        text += f", {entry['cores']} cores"
    if entry.get("gpu"):
        text += f", {entry['gpu']}"
    return text


def git_commit() -> dict[str, Any]:
    """Commit (and whether the tree has changes) of the source tree this package runs from."""
    root = Path(__file__).resolve().parent.parent
    try:
        commit = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
        status = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout
        return {"commit": commit, "dirty": bool(status.strip())}
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}


def config_differences(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """Keys whose values differ between two config dicts, ignoring resumable fields; a setting
    present on one side only differs (a run saved before the setting existed is another run)."""
    keys = (set(a) | set(b)) - RESUMABLE_FIELDS
    missing = object()
    return sorted(k for k in keys if a.get(k, missing) != b.get(k, missing))


def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n")
    os.replace(tmp, path)


@dataclass(frozen=True)
class RunInfo:
    """What a run folder's config.json says about its run (`RunFolder.read_info`)."""

    path: Path
    condition: str
    seed: int
    variant: str
    preset: str
    module_names: tuple[str, ...]
    achievable: tuple[bool, ...]
    perturbation_episode: int | None = None
    """The setting `sensor_failure_episode` (None: never, or not set)."""
    failure_competence: float | None = None
    """The setting `sensor_failure_competence`: the perturbed module's competence at which the
    failure was to start (None: not used)."""
    recorded_failure_modules: tuple[str, ...] | None = None
    """config.json's `sensor_failure_modules`; None where it predates that record."""
    settings: Mapping[str, Any] | None = None
    """The resolved settings (config.json's `config`)."""
    versions: Mapping[str, Any] | None = None
    """Library versions of the first start."""
    git: Mapping[str, Any] | None = None
    """Source commit of the first start: `commit` and `dirty` (local changes)."""
    resumed: tuple[Mapping[str, Any], ...] = ()
    """One entry per resume: `at`, `versions`, `git`, `machine`, `config`."""
    machine: Mapping[str, Any] | None = None
    """The machine of the first start (`machine`; None where config.json predates it)."""

    @property
    def achievable_modules(self) -> tuple[str, ...]:
        """The achievable modules, in slot order."""
        return tuple(m for m, a in zip(self.module_names, self.achievable, strict=True) if a)

    @functools.cached_property
    def sensor_failure_modules(self) -> tuple[str, ...]:
        """The modules the variant's sensory failure perturbs (empty: none): as config.json
        records them, else (a run written before they were recorded) from the variant's own
        definition, `curious.envs.goal_env.suite_sensor_failure_modules`."""
        if self.recorded_failure_modules is not None:
            return self.recorded_failure_modules
        from curious.envs.goal_env import suite_sensor_failure_modules

        found = suite_sensor_failure_modules(self.variant)
        return tuple(m for m in found if m in self.module_names)

    @property
    def total_episodes(self) -> int:
        """The run's budget in episodes (its latest `total_episodes`; 0 where not set)."""
        return int((self.settings or {}).get("total_episodes", 0))

    @property
    def machines(self) -> tuple[str, ...]:
        """The machines the run trained on, first start then resumes (`machine_text`), without
        repeats; starts that predate the record are left out."""
        entries = [self.machine or {}, *(r.get("machine", {}) for r in self.resumed)]
        texts = (machine_text(e) for e in entries if isinstance(e, Mapping))
        return tuple(dict.fromkeys(t for t in texts if t))

    @property
    def commits(self) -> tuple[str, ...]:
        """Short commits the run was trained from, first start then resumes, without repeats; a
        commit with local changes is marked with '+'."""
        out: list[str] = []
        for entry in [self.git or {}, *(r.get("git", {}) for r in self.resumed)]:
            commit = entry.get("commit") if isinstance(entry, Mapping) else None
            if commit:
                text = commit[:7] + ("+" if entry.get("dirty") else "")
                if text not in out:
                    out.append(text)
        return tuple(out)


def _parse_info(data: dict[str, Any], folder: Path, config_path: Path) -> RunInfo:
    """`RunInfo` from config.json's content, checked; a `RunFolderError` naming the file."""

    def need(key: str, kind: type, what: str) -> Any:
        if key not in data:
            raise RunFolderError(f"{config_path} has no '{key}' ({what})")
        value = data[key]
        if not isinstance(value, kind) or (isinstance(value, bool) and kind is int):
            raise RunFolderError(f"{config_path}: '{key}' must be {what}, got {value!r}")
        return value

    condition = need("condition", str, "a string")
    seed = need("seed", int, "an integer")
    variant = need("variant", str, "a string")
    preset = need("preset", str, "a string")
    names = need("modules", list, "a list of module names in slot order")
    achievable = need("achievable", list, "a list of booleans, one per module")
    if not names or not all(isinstance(n, str) and n for n in names):
        raise RunFolderError(f"{config_path}: 'modules' must be non-empty strings: {names!r}")
    if len(set(names)) != len(names):
        raise RunFolderError(f"{config_path}: 'modules' repeats a name: {names!r}")
    if any("," in n for n in names):
        raise RunFolderError(f"{config_path}: module names may not contain commas: {names!r}")
    if len(achievable) != len(names) or not all(isinstance(a, bool) for a in achievable):
        raise RunFolderError(
            f"{config_path}: 'achievable' must be {len(names)} booleans (one per module in "
            f"'modules'), got {achievable!r}"
        )
    recorded = data.get("sensor_failure_modules")
    if recorded is not None and (
        not isinstance(recorded, list) or not all(m in names for m in recorded)
    ):
        raise RunFolderError(
            f"{config_path}: 'sensor_failure_modules' must list modules of 'modules', got "
            f"{recorded!r}"
        )
    settings = data["config"]
    resumed = data.get("resumed")
    return RunInfo(
        path=folder.resolve(),
        condition=condition,
        seed=seed,
        variant=variant,
        preset=preset,
        module_names=tuple(names),
        achievable=tuple(achievable),
        perturbation_episode=_failure_episode(settings, config_path),
        failure_competence=_failure_competence(settings, config_path),
        recorded_failure_modules=None if recorded is None else tuple(recorded),
        settings=settings,
        versions=_mapping(data.get("versions")),
        git=_mapping(data.get("git")),
        resumed=tuple(_mapping(r) for r in resumed) if isinstance(resumed, list) else (),
        machine=_mapping(data.get("machine")),
    )


def _mapping(value: Any) -> Mapping[str, Any]:
    """A provenance entry of config.json, or an empty one where it is not an object (provenance
    is for reading; a hand-edited entry does not make the run unreadable)."""
    return value if isinstance(value, dict) else {}


def _failure_episode(settings: Mapping[str, Any], config_path: Path) -> int | None:
    """The setting `sensor_failure_episode` (None where absent, null or -1: never)."""
    value = settings.get("sensor_failure_episode")
    if value is None or value == -1:
        return None
    if not isinstance(value, int) or isinstance(value, bool) or value < 0:
        raise RunFolderError(
            f"{config_path}: 'sensor_failure_episode' must be a non-negative integer, -1 or "
            f"null, got {value!r}"
        )
    return value


def _failure_competence(settings: Mapping[str, Any], config_path: Path) -> float | None:
    """The setting `sensor_failure_competence` (None where absent, null or -1: not used)."""
    value = settings.get("sensor_failure_competence")
    if value is None or value == -1:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= 1:
        raise RunFolderError(
            f"{config_path}: 'sensor_failure_competence' must be a number in (0, 1], -1 or "
            f"null, got {value!r}"
        )
    return float(value)


class RunFolder:
    """Paths, reading, writing and checks of one run folder."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)

    @property
    def config_path(self) -> Path:
        return self.path / CONFIG_FILE

    @property
    def metrics_path(self) -> Path:
        return self.path / METRICS_FILE

    @property
    def tests_path(self) -> Path:
        return self.path / TESTS_FILE

    @property
    def recording_path(self) -> Path:
        return self.path / RECORDING_FILE

    @property
    def checkpoints(self) -> Path:
        return self.path / CHECKPOINTS_DIR

    @property
    def has_config(self) -> bool:
        """Whether the folder holds a config.json: a run, started or not."""
        return self.config_path.is_file()

    @property
    def started(self) -> bool:
        """Whether the run has logged episodes: config.json and metrics.parquet are there."""
        return self.has_config and self.metrics_path.is_file()

    def episodes_logged(self) -> int:
        """Rows of metrics.parquet, read from its footer (0 where there is none yet, or where it
        cannot be read)."""
        if not self.metrics_path.is_file():
            return 0
        import pyarrow.parquet as pq

        try:
            return int(pq.read_metadata(self.metrics_path).num_rows)
        except (OSError, ValueError):
            return 0

    def newest_checkpoint(self) -> int | None:
        """Episodes of the newest complete checkpoint, by its name (None: none)."""
        found = list_checkpoints(self.checkpoints)
        return checkpoint_episodes(found[-1]) if found else None

    def finished_at(self, total_episodes: int) -> bool:
        """Whether the run has reached `total_episodes`: that many episodes logged, and a
        checkpoint taken at (or after) them, so that nothing is left to train."""
        logged = self.episodes_logged() >= total_episodes
        return logged and (self.newest_checkpoint() or 0) >= total_episodes

    def read_stored(self) -> dict[str, Any]:
        """config.json's content, checked to be a run's description: a JSON object whose
        `config` is an object. Anything else is a `RunFolderError` naming the file."""
        path = self.config_path
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise RunFolderError(
                f"{self.path} is not a run folder: it has no {CONFIG_FILE}"
            ) from None
        except (OSError, UnicodeDecodeError) as exc:
            cause = getattr(exc, "strerror", None) or exc
            raise RunFolderError(f"cannot read {path}: {cause}") from None
        damaged = f"{path} is damaged"
        remedy = "restore it, or start a new run in another --out"
        if not text.strip():
            raise RunFolderError(f"{damaged}: it is empty; {remedy}")
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise RunFolderError(f"{damaged}: it is not valid JSON ({exc}); {remedy}") from None
        if not isinstance(data, dict) or not isinstance(data.get("config"), dict):
            raise RunFolderError(
                f"{damaged}: it holds no run's settings (a JSON object with a `config` object); "
                f"{remedy}"
            )
        return data

    def read_config(self) -> Config:
        """The config stored in config.json; a `RunFolderError` naming the file when it is not
        one this curious can run (a damaged file, a setting of the wrong type or value)."""
        raw = self.read_stored()["config"]
        try:
            return Config.from_dict(raw)
        except ConfigError as exc:
            raise RunFolderError(
                f"{self.config_path} holds settings this curious cannot run ({exc}); restore "
                "it, or start a new run in another --out"
            ) from None

    def read_info(self) -> RunInfo:
        """What config.json says about the run (`RunInfo`), checked: its identity, modules,
        sensory failure and provenance; a `RunFolderError` naming the file otherwise. Reads
        every config.json curious has written (see the module docstring)."""
        return _parse_info(self.read_stored(), self.path, self.config_path)

    def check_resumable(self, config: Config) -> None:
        """A `RunFolderError` unless `config` may go on with the run in this folder: config.json
        is there and is a run's, written by a curious that had every setting this one has, with
        settings this curious can run, equal to `config`'s but for `RESUMABLE_FIELDS` (a
        `ConfigMismatch` naming the differences otherwise)."""
        if not self.config_path.exists():
            raise RunFolderError(f"nothing to resume: {self.config_path} does not exist")
        raw = self.read_stored()["config"]
        lacking = sorted(set(setting_names()) - set(raw))
        if lacking:
            raise RunFolderError(
                f"cannot resume {self.path}: it was written by another version of curious "
                f"(its config.json lacks {', '.join(lacking)}); start a new run, or resume "
                "with the version that wrote it"
            )
        self.read_config()  # settings of the wrong type or value
        given = config.to_dict()
        differences = {k: (raw.get(k), given.get(k)) for k in config_differences(raw, given)}
        if differences:
            detail = ", ".join(f"{k}: {a!r} -> {b!r}" for k, (a, b) in differences.items())
            raise ConfigMismatch(
                f"cannot resume {self.path} with a different config ({detail}); "
                f"only {', '.join(sorted(RESUMABLE_FIELDS))} may change",
                differences,
            )

    def foreign_entries(self) -> list[str]:
        """Names in the folder that no run writes (what `--restart` would not remove)."""
        if not self.path.is_dir():
            return []
        return sorted(
            entry.name
            for entry in self.path.iterdir()
            if not entry.name.lstrip(".").startswith(RUN_ENTRIES)
        )

    def clear(self) -> None:
        """Remove what a run wrote in the folder (`--restart`), after `prepare` checked that it
        holds nothing else."""
        for entry in self.path.iterdir():
            if entry.name.lstrip(".").startswith(RUN_ENTRIES):
                if entry.is_dir() and not entry.is_symlink():
                    shutil.rmtree(entry)
                else:
                    entry.unlink()

    @classmethod
    def prepare(
        cls, path: str | os.PathLike, config: Config, resume: bool, restart: bool = False
    ) -> RunFolder:
        """Check that `path` can hold (or go on with) a run of `config`; writes nothing. With
        `restart`, a folder holding a run (and nothing else) is accepted for a new run: `clear`
        then removes the old one."""
        folder = cls(path)
        exists = folder.path.exists()
        if exists and not folder.path.is_dir():
            raise RunFolderError(f"{folder.path} exists and is not a folder")
        if resume and restart:
            raise RunFolderError(
                "--resume goes on with a run and --restart starts it over: pass one of them"
            )
        non_empty = exists and any(folder.path.iterdir())
        if restart:
            foreign = folder.foreign_entries()
            if foreign:
                raise RunFolderError(
                    f"{folder.path} holds files that are not a run's ({', '.join(foreign[:5])}); "
                    "--restart removes only a run's files: move them away, or choose another --out"
                )
            return folder
        if not resume:
            if non_empty:
                raise RunFolderError(
                    f"{folder.path} is not empty; pass --resume to continue the run in it, "
                    "--restart to start it over, or choose another --out"
                )
            return folder
        folder.check_resumable(config)
        return folder

    def describe(self, config: Config, spec: EnvSpec) -> dict[str, Any]:
        """The content of config.json."""
        return {
            "condition": config.condition,
            "seed": config.seed,
            "preset": config.preset,
            "variant": config.variant,
            "modules": list(spec.module_names),
            "achievable": list(spec.achievable),
            "sensor_failure_modules": list(spec.sensor_failure_modules),
            "config": config.to_dict(),
            "versions": library_versions(),
            "git": git_commit(),
            "machine": machine(config.device),
            "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        }

    def write_config(self, config: Config, spec: EnvSpec) -> None:
        """Create the folder and write config.json (a resumed run records its new settings)."""
        self.path.mkdir(parents=True, exist_ok=True)
        data = self.describe(config, spec)
        if self.config_path.exists():
            old = json.loads(self.config_path.read_text())
            resumed = {
                "at": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                "versions": data["versions"],
                "git": data["git"],
                "machine": data["machine"],
                "config": data["config"],
            }
            for key in ("created", "versions", "git"):
                data[key] = old.get(key, data[key])
            data["machine"] = old.get("machine")  # None: the first start predates the record
            data["resumed"] = [*old.get("resumed", []), resumed]
        write_json_atomic(self.config_path, data)
