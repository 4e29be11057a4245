"""Claiming a place before writing there: `folder_lock` keeps a second process out of a run folder
(or a reproduction's output folder) while one works in it and leaves nothing behind;
`check_writable` refuses a path that takes no file before any work is done."""

from __future__ import annotations

import contextlib
import fcntl
import os
import socket
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from curious.runs.folder_errors import RunFolderBusy, RunFolderError


def check_writable(path: str | os.PathLike, option: str, folder: bool = False) -> None:
    """A `RunFolderError` naming `option` where nothing could be written at `path`: the nearest
    folder on the way to it that exists (`path` itself, with `folder`, where it is a folder that
    exists) is a file, or takes no new file (a read-only file system, a folder without write
    permission). Checked by making an empty file there and removing it, the one test that sees
    all of them (`os.access` answers for the permissions alone), before any work is done."""
    target = Path(path).absolute()
    for link in (target, *target.parents):
        if link.is_symlink() and not link.exists():  # mkdir would say only "File exists"
            raise RunFolderError(
                f"{option} {path}: {link} is a link to {os.readlink(link)}, which does not exist"
            )
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
