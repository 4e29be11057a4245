"""Resumable checkpoints, written atomically.

A checkpoint is a folder `checkpoints/ep-<episodes>/` (its name and the listing of the complete
ones are the run folder's format, `curious.run_folder`) holding `state.pt` (networks, optimisers,
normalisers, competence queues, RNG states, counters, the config) and `replay.npz` (the replay
buffer's filled part, uncompressed). It is written under a temporary name and renamed when
complete, so a crash leaves either the previous checkpoint or the new one, never half of one.
The two newest are kept (older ones are removed after the rename), so that a checkpoint damaged
later (a disk error, a truncated copy) is not the end of a run: `load_latest` falls back to the
one before, saying so.
"""

from __future__ import annotations

import errno
import functools
import os
import pickle
import shutil
import warnings
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
import torch

from curious.run_folder import checkpoint_episodes, checkpoint_name, list_checkpoints

KEEP = 2
"""Checkpoints kept in a run folder: the newest and the one before."""
FORMAT_VERSION = 4
"""2: goals enter the networks through a fixed map (no goal statistics), Xavier-initialised
networks, the authors' stack guard and T3 heights; 3: test rollouts' random streams and the
sensory failure's onset; 4: the authors' suite and conditions: outcomes in the world frame (the
replay's `achieved` arrays change size: cube1_above_cube2 and stack carry cube 1's and cube 2's
positions, stack the gripper), goals that follow cube 2, cube velocities relative to the
gripper; her's holistic reward and score, the released code's module rule for
self-evaluations, mg-te's evaluations on its epoch's module, task replay over modules with an
episode to replay. A run of another format cannot go on with this agent."""


class CheckpointError(RuntimeError):
    """A checkpoint that is missing, unreadable or from another run."""


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def save(
    directory: Path, episodes: int, state: dict[str, Any], replay: dict[str, Any], keep: int = KEEP
) -> Path:
    """Write a checkpoint for `episodes` episodes into `directory`; return its path. A failed
    write (a full disk, a read-only folder) is a `CheckpointError` naming the cause and the file,
    and leaves the earlier checkpoints as they were."""
    tmp = directory / f".tmp-{checkpoint_name(episodes)}"
    try:
        return _save(directory, episodes, state, replay, keep)
    except (OSError, RuntimeError) as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise CheckpointError(_write_failure(exc, directory, tmp)) from exc


def _write_failure(exc: OSError | RuntimeError, directory: Path, tmp: Path) -> str:
    """One line on why a checkpoint could not be written, naming the file as the checkpoint
    would have it (its temporary folder is removed)."""
    final = directory / tmp.name.removeprefix(".tmp-")
    if isinstance(exc, OSError):
        target = Path(exc.filename) if exc.filename else final
        if target == tmp or target.parent == tmp:
            target = final if target == tmp else final / target.name
        if exc.errno == errno.ENOSPC:
            return (
                f"No space left on device: cannot write {target}; the checkpoints before it are "
                "kept (free some space, then resume)"
            )
        return f"cannot write {target}: {exc.strerror or exc}"
    return f"cannot write checkpoint {final}: {str(exc).strip().splitlines()[0]}"


def _os_error(exc: BaseException) -> OSError | None:
    """The OSError behind `exc` (torch raises "enforce fail at inline_container.cc ...
    unexpected pos" when its file stops growing, with the OSError in the context)."""
    seen: BaseException | None = exc
    while seen is not None and not isinstance(seen, OSError):
        seen = seen.__cause__ or seen.__context__
    return seen


def _write_file(path: Path, write: Callable[[BinaryIO], object]) -> None:
    """Writes `path` with `write(handle)`, synced to disk; a failure is an OSError naming it."""
    try:
        with open(path, "wb") as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
    except (OSError, RuntimeError) as exc:
        cause = _os_error(exc)
        if cause is None or cause.filename:
            raise
        raise OSError(cause.errno, cause.strerror, str(path)) from exc


def _save(
    directory: Path, episodes: int, state: dict[str, Any], replay: dict[str, Any], keep: int
) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    final = directory / checkpoint_name(episodes)
    tmp = directory / f".tmp-{final.name}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    state = {"format": FORMAT_VERSION, "episodes": episodes, **state}
    _write_file(tmp / "state.pt", functools.partial(torch.save, state))
    _write_file(tmp / "replay.npz", lambda handle: np.savez(handle, **replay))
    _fsync_dir(tmp)
    if final.exists():
        shutil.rmtree(final)
    os.replace(tmp, final)
    _fsync_dir(directory)
    prune(directory, keep)
    return final


def prune(directory: Path, keep: int = KEEP, spare: Path | None = None) -> None:
    """Remove all but the `keep` newest checkpoints, and never `spare` (the one a run resumed
    from). A kill between a checkpoint's rename and this leaves one too many, which the
    resumed run removes."""
    for old in list_checkpoints(directory)[:-keep]:
        if spare is None or old.resolve() != spare.resolve():
            shutil.rmtree(old, ignore_errors=True)


def remove_partial(directory: Path) -> None:
    """Delete temporary checkpoint folders a crash left behind."""
    if directory.exists():
        for p in directory.iterdir():
            if p.name.startswith(".tmp-"):
                shutil.rmtree(p, ignore_errors=True)


def load(
    path: Path, map_location: str | torch.device = "cpu", replay: bool = True
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(state, replay arrays) of the checkpoint at `path`. With `replay=False` the replay's
    arrays are not read (an evaluation needs only the networks: the replay is most of a
    checkpoint's size): its archive is opened and listed, so that a truncated one is still
    refused, and the arrays come back empty."""
    try:
        state = torch.load(path / "state.pt", map_location=map_location, weights_only=False)
        with np.load(path / "replay.npz") as data:
            arrays = {k: data[k] for k in data.files} if replay else {}
    except (
        OSError,
        RuntimeError,
        ValueError,
        EOFError,
        KeyError,
        pickle.UnpicklingError,
        zipfile.BadZipFile,
    ) as exc:
        raise CheckpointError(f"cannot read checkpoint {path}: {exc}") from exc
    if state.get("format") != FORMAT_VERSION:
        raise CheckpointError(
            f"checkpoint {path} has format {state.get('format')}, this curious reads format "
            f"{FORMAT_VERSION}: it was written by another version of the agent, so the run "
            "cannot go on here; start a new run (or use the curious version that wrote it)"
        )
    return state, arrays


def load_latest(
    directory: Path, map_location: str | torch.device = "cpu", replay: bool = True
) -> tuple[Path, dict[str, Any], dict[str, np.ndarray]] | None:
    """(path, state, replay) of the newest readable checkpoint in `directory`, None when there is
    none. An unreadable newest one is passed over for the one before, with a warning naming
    it; an error when none can be read.

    A checkpoint is taken by its state's own episode counter, which must be the episode its
    folder's name says: one renamed or copied under another name (`ep-000000000999` holding
    episode 24) is passed over like a damaged one, so that a name never sends a run back to an
    older state. `replay=False`: as `load`'s."""
    found = list_checkpoints(directory)
    errors = []
    for path in reversed(found):
        try:
            state, arrays = load(path, map_location, replay)
        except CheckpointError as exc:
            errors.append(str(exc))
            continue
        named = checkpoint_episodes(path)
        if state.get("episodes") != named:
            errors.append(
                f"checkpoint {path} holds the state of episode {state.get('episodes')}, not of "
                f"episode {named} as its name says (renamed or copied?)"
            )
            continue
        if errors:
            warnings.warn(f"{errors[0]}; resuming from the one before, {path.name}", stacklevel=2)
        return path, state, arrays
    if errors:
        raise CheckpointError("; ".join(errors))
    return None
