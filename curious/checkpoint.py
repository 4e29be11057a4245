"""Resumable checkpoints, written atomically.

A checkpoint is a folder `checkpoints/ep-<episodes>/` holding `state.pt` (networks, optimisers,
normalisers, competence queues, RNG states, counters, the config) and `replay.npz` (the replay
buffer's filled part, uncompressed). It is written under a temporary name and renamed when
complete, so a crash leaves either the previous checkpoint or the new one, never half of one.
The two newest are kept (older ones are removed after the rename), so that a checkpoint damaged
later (a disk error, a truncated copy) is not the end of a run: `load_latest` falls back to the
one before, saying so.
"""

from __future__ import annotations

import os
import pickle
import re
import shutil
import warnings
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import torch

PREFIX = "ep-"
_NAME = re.compile(r"ep-(\d{12})")
KEEP = 2
"""Checkpoints kept in a run folder: the newest and the one before."""
FORMAT_VERSION = 3
"""2: goals enter the networks through a fixed map (no goal statistics), Xavier-initialised
networks, the authors' stack guard and T3 heights; 3: test rollouts' random streams and the
sensory failure's onset. A run of another format cannot go on with this agent."""


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
    write (a full disk, a read-only folder) is a `CheckpointError` naming the cause, and leaves
    the earlier checkpoints as they were."""
    try:
        return _save(directory, episodes, state, replay, keep)
    except (OSError, RuntimeError) as exc:
        shutil.rmtree(directory / f".tmp-{PREFIX}{episodes:012d}", ignore_errors=True)
        cause = "the disk is full" if getattr(exc, "errno", None) == 28 else str(exc).strip()
        if "enforce fail" in cause or "inline_container" in cause:
            cause = f"torch could not write state.pt ({cause.splitlines()[0]}); is the disk full?"
        raise CheckpointError(f"cannot write a checkpoint in {directory}: {cause}") from exc


def _save(
    directory: Path, episodes: int, state: dict[str, Any], replay: dict[str, Any], keep: int
) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    final = directory / f"{PREFIX}{episodes:012d}"
    tmp = directory / f".tmp-{PREFIX}{episodes:012d}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    torch.save({"format": FORMAT_VERSION, "episodes": episodes, **state}, tmp / "state.pt")
    with open(tmp / "replay.npz", "wb") as handle:
        np.savez(handle, **replay)
        handle.flush()
        os.fsync(handle.fileno())
    _fsync_dir(tmp)
    if final.exists():
        shutil.rmtree(final)
    os.replace(tmp, final)
    _fsync_dir(directory)
    for old in list_checkpoints(directory)[:-keep]:
        shutil.rmtree(old, ignore_errors=True)
    return final


def list_checkpoints(directory: Path) -> list[Path]:
    """Complete checkpoints, oldest first."""
    if not directory.exists():
        return []
    found = [p for p in directory.iterdir() if p.is_dir() and _NAME.fullmatch(p.name)]
    return sorted(found, key=lambda p: int(p.name[len(PREFIX) :]))


def remove_partial(directory: Path) -> None:
    """Delete temporary checkpoint folders a crash left behind."""
    if directory.exists():
        for p in directory.iterdir():
            if p.name.startswith(".tmp-"):
                shutil.rmtree(p, ignore_errors=True)


def load(
    path: Path, map_location: str | torch.device = "cpu"
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(state, replay arrays) of the checkpoint at `path`."""
    try:
        state = torch.load(path / "state.pt", map_location=map_location, weights_only=False)
        with np.load(path / "replay.npz") as data:
            replay = {k: data[k] for k in data.files}
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
    return state, replay


def load_latest(
    directory: Path, map_location: str | torch.device = "cpu"
) -> tuple[Path, dict[str, Any], dict[str, np.ndarray]] | None:
    """(path, state, replay) of the newest readable checkpoint in `directory`, None when there is
    none. An unreadable newest one is passed over for the one before, with a warning naming
    it; an error when none can be read.

    A checkpoint is taken by its state's own episode counter, which must be the episode its
    folder's name says: one renamed or copied under another name (`ep-000000000999` holding
    episode 24) is passed over like a damaged one, so that a name never sends a run back to an
    older state."""
    found = list_checkpoints(directory)
    errors = []
    for path in reversed(found):
        try:
            state, replay = load(path, map_location)
        except CheckpointError as exc:
            errors.append(str(exc))
            continue
        named = int(path.name[len(PREFIX) :])
        if state.get("episodes") != named:
            errors.append(
                f"checkpoint {path} holds the state of episode {state.get('episodes')}, not of "
                f"episode {named} as its name says (renamed or copied?)"
            )
            continue
        if errors:
            warnings.warn(f"{errors[0]}; resuming from the one before, {path.name}", stacklevel=2)
        return path, state, replay
    if errors:
        raise CheckpointError("; ".join(errors))
    return None
