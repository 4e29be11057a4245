"""A run folder: where one training run (one condition, one seed) keeps everything.

    config.json       the resolved config and what it ran on (see `RunFolder.describe`)
    metrics.parquet   one row per training episode (`curious.metrics`)
    tests.parquet     one row per test rollout (`curious.metrics`)
    recording.rrd     the Rerun recording (written by `curious.recording`)
    checkpoints/      resumable checkpoints (`curious.checkpoint`)

`prepare` checks a folder before anything is written: a non-empty folder is only accepted with
`resume=True`, and then only for the same config (fields in `RESUMABLE_FIELDS` may change), or
with `restart=True` when it holds a run's files and nothing else (`clear` removes them once
every check has passed). A config.json that is not a run's (damaged, hand-edited into another
shape, a setting of the wrong type) is a `RunFolderError` naming the file. `folder_lock` keeps a
second process out of a folder while one trains in it, and leaves nothing behind.
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import json
import os
import platform
import shutil
import socket
import subprocess
from collections.abc import Iterator
from importlib import metadata
from pathlib import Path
from typing import IO, Any

from curious.config import RESUMABLE_FIELDS, Config, ConfigError, setting_names
from curious.envs import EnvSpec

RUN_ENTRIES: tuple[str, ...] = (
    "config.json",
    "metrics.parquet",
    "tests.parquet",
    "recording.rrd",
    "checkpoints",
)
"""What a run writes in its folder (with temporaries named after them, a leading dot aside)."""


class RunFolderError(RuntimeError):
    """A run folder that cannot be used as asked (nothing has been written)."""


class RunFolderBusy(RunFolderError):
    """Another process is training in the run folder right now."""


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
    existing = next(p for p in path.parents if p.exists())
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


def library_versions() -> dict[str, str | None]:
    """Installed versions of the libraries a run's results depend on."""
    versions: dict[str, str | None] = {"python": platform.python_version()}
    for dist in ("curious", "torch", "numpy", "mujoco", "dm-control", "rerun-sdk"):
        try:
            versions[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            versions[dist] = None
    return versions


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


class RunFolder:
    """Paths and checks of one run folder."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)

    @property
    def config_path(self) -> Path:
        return self.path / "config.json"

    @property
    def metrics_path(self) -> Path:
        return self.path / "metrics.parquet"

    @property
    def tests_path(self) -> Path:
        return self.path / "tests.parquet"

    @property
    def recording_path(self) -> Path:
        return self.path / "recording.rrd"

    @property
    def checkpoints(self) -> Path:
        return self.path / "checkpoints"

    def read_stored(self) -> dict[str, Any]:
        """config.json's content, checked to be a run's description: a JSON object whose
        `config` is an object. Anything else is a `RunFolderError` naming the file."""
        path = self.config_path
        try:
            text = path.read_text()
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
            raise RunFolderError(f"{damaged}: it is not JSON ({exc}); {remedy}") from None
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
        if not folder.config_path.exists():
            raise RunFolderError(f"nothing to resume: {folder.config_path} does not exist")
        raw = folder.read_stored()["config"]
        lacking = sorted(set(setting_names()) - set(raw))
        if lacking:
            raise RunFolderError(
                f"cannot resume {folder.path}: it was written by another version of curious "
                f"(its config.json lacks {', '.join(lacking)}); start a new run, or resume "
                "with the version that wrote it"
            )
        stored = folder.read_config()
        diff = config_differences(stored.to_dict(), config.to_dict())
        if diff:
            detail = ", ".join(
                f"{k}: {getattr(stored, k)!r} -> {getattr(config, k)!r}" for k in diff
            )
            raise RunFolderError(
                f"cannot resume {folder.path} with a different config ({detail}); "
                f"only {', '.join(sorted(RESUMABLE_FIELDS))} may change"
            )
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
            "config": config.to_dict(),
            "versions": library_versions(),
            "git": git_commit(),
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
                "config": data["config"],
            }
            for key in ("created", "versions", "git"):
                data[key] = old.get(key, data[key])
            data["resumed"] = [*old.get("resumed", []), resumed]
        write_json_atomic(self.config_path, data)
