"""Resumable checkpoints, written atomically.

A checkpoint is a folder `checkpoints/ep-<episodes>/` holding `state.pt` (networks, optimisers,
normalisers, competence queues, RNG states, counters, the config) and `replay.npz` (the replay
buffer's filled part, uncompressed). It is written under a temporary name and renamed when
complete, so a crash leaves either the previous checkpoint or the new one, never half of one;
older checkpoints are removed after the rename.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import torch

PREFIX = "ep-"
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
    directory: Path, episodes: int, state: dict[str, Any], replay: dict[str, Any], keep: int = 1
) -> Path:
    """Write a checkpoint for `episodes` episodes into `directory`; return its path."""
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
    found = [p for p in directory.iterdir() if p.is_dir() and p.name.startswith(PREFIX)]
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
    except (OSError, RuntimeError, ValueError, EOFError) as exc:
        raise CheckpointError(f"cannot read checkpoint {path}: {exc}") from exc
    if state.get("format") != FORMAT_VERSION:
        raise CheckpointError(
            f"checkpoint {path} has format {state.get('format')}, this curious reads format "
            f"{FORMAT_VERSION}: it was written by another version of the agent, so the run "
            "cannot go on here; start a new run (or use the curious version that wrote it)"
        )
    return state, replay
