"""Resumable checkpoints, written atomically.

A checkpoint is a folder `checkpoints/ep-<episodes>/` (its name and the listing of the complete
ones are the run folder's layout: `curious.runs.folder_layout`) holding `state.pt` (networks,
optimisers, normalisers, competence queues, RNG states, counters, the config) and the replay
buffer's filled part. It is written under a temporary name and renamed when complete, so a crash
leaves either the previous checkpoint or the new one, never half of one, and a Ctrl-C that comes
while one is written is taken once it is written (`curious.runs.signals`). The two newest are kept
(older ones are removed after the rename), so that a checkpoint damaged later (a disk error, a
truncated copy) is not the end of a run: `load_latest` falls back to the one before, saying so.

The replay only grows until it first stores an episode over another (a run keeps every episode
by default), so a checkpoint writes only the episodes stored since the one before: each lands
once, in a segment `checkpoints/replay/episodes-<first>-<end>.npz` written atomically, and a
checkpoint's `replay.json` lists the segments that make up its replay. The checkpoints share
their older segments (the disk holds the replay once, not once per checkpoint kept), and a
segment goes when no kept checkpoint lists it. A replay that has evicted an episode, or a
checkpoint with no earlier one of its run to build on, is written whole (a first segment, or
`replay.npz` in the checkpoint's folder where episodes were evicted). The newest checkpoint's
own segment damaged still falls back to the one before, which does not list it; a damaged
older segment, shared by both, does not.
"""

from __future__ import annotations

import errno
import functools
import json
import os
import pickle
import shutil
import warnings
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
import torch

from curious.runs.folder_layout import checkpoint_episodes, checkpoint_name, list_checkpoints
from curious.runs.signals import signals_held

KEEP = 2
"""Checkpoints kept in a run folder: the newest and the one before."""
SEGMENTS = "replay"
"""The folder, beside the checkpoints, of the replay segments they share."""
MANIFEST = "replay.json"
"""A checkpoint's list of the replay segments that make up its replay."""
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
    directory: Path,
    episodes: int,
    state: dict[str, Any],
    replay: dict[str, Any],
    keep: int = KEEP,
    base: Path | None = None,
) -> Path:
    """Write a checkpoint for `episodes` episodes into `directory`; return its path.

    `replay` is the replay's `state_dict`. `base` is the checkpoint this run last wrote or
    resumed from: where it lists segments and nothing was evicted since, only the episodes after
    it are written (module docstring). A failed write (a full disk, a read-only folder) is a
    `CheckpointError` naming the cause and the file, and leaves the earlier checkpoints as they
    were. A Ctrl-C (or SIGTERM, SIGHUP) that comes while it is written is taken once it is
    written (`curious.runs.signals`): a checkpoint begun is a checkpoint kept."""
    tmp = directory / f".tmp-{checkpoint_name(episodes)}"
    with signals_held():
        try:
            return _save(directory, episodes, state, replay, keep, base)
        except (OSError, RuntimeError) as exc:
            shutil.rmtree(tmp, ignore_errors=True)
            _remove_temporary_segments(directory)
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
    directory: Path,
    episodes: int,
    state: dict[str, Any],
    replay: dict[str, Any],
    keep: int,
    base: Path | None,
) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    final = directory / checkpoint_name(episodes)
    tmp = directory / f".tmp-{final.name}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    state = {"format": FORMAT_VERSION, "episodes": episodes, **state}
    _write_file(tmp / "state.pt", functools.partial(torch.save, state))
    if _grows_only(replay):
        manifest = _write_segments(directory, replay, base)
        text = json.dumps(manifest, indent=1)
        _write_file(tmp / MANIFEST, lambda handle: handle.write(text.encode()))
    else:
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
    _prune_segments(directory)


def _grows_only(replay: dict[str, Any]) -> bool:
    """Whether `replay` is a replay's `state_dict` that has evicted nothing: its per-episode
    arrays then hold every episode stored, oldest first, and a checkpoint can be written as
    segments."""
    if "evicted" not in replay or "size" not in replay or bool(replay["evicted"]):
        return False
    size = int(replay["size"])
    return all(len(v) == size for v in replay.values() if np.ndim(v) > 0)


def _segment_name(first: int, end: int) -> str:
    return f"episodes-{first:012d}-{end:012d}.npz"


def _read_manifest(path: Path) -> dict[str, Any]:
    """A checkpoint's `replay.json`: `size` (episodes), `scalars` (the replay's other counters)
    and `segments` (`[name, first, end]` rows, in order, covering episodes 0 to `size`)."""
    manifest = json.loads((path / MANIFEST).read_text())
    if not isinstance(manifest, dict) or not {"size", "scalars", "segments"} <= manifest.keys():
        raise ValueError(f"{path / MANIFEST} is not a replay manifest")
    return manifest


def _write_segments(directory: Path, replay: dict[str, Any], base: Path | None) -> dict[str, Any]:
    """Write the episodes of `replay` that `base`'s segments lack as a new segment (all of them
    where `base` lists none or cannot be read), and return the new checkpoint's manifest."""
    size = int(replay["size"])
    arrays = {k: np.asarray(v) for k, v in replay.items() if np.ndim(v) > 0}
    scalars = {k: np.asarray(v).item() for k, v in replay.items() if np.ndim(v) == 0}
    segments: list[list[Any]] = []
    folder = directory / SEGMENTS
    if base is not None:
        try:
            earlier = _read_manifest(base)
            if earlier["size"] <= size and all(
                (folder / n).is_file() for n, *_ in earlier["segments"]
            ):
                segments = [list(row) for row in earlier["segments"]]
        except (OSError, ValueError):
            segments = []  # nothing to build on: the whole replay goes into one segment
    first = segments[-1][2] if segments else 0
    if size > first:
        folder.mkdir(exist_ok=True)
        name = _segment_name(first, size)
        tmp = folder / f".tmp-{name}"
        part = {k: v[first:size] for k, v in arrays.items()}
        _write_file(tmp, lambda handle: np.savez(handle, **part))
        os.replace(tmp, folder / name)
        _fsync_dir(folder)
        segments.append([name, first, size])
    return {"size": size, "scalars": scalars, "segments": segments}


def _read_segments(
    path: Path, replay: bool, into: Mapping[str, np.ndarray] | None = None
) -> dict[str, np.ndarray]:
    """The replay arrays a checkpoint's manifest lists, filled in order into one array each (the
    memory of the replay and one segment at most; empty with `replay` False, once every segment
    has been opened and listed). An array of `into` of the same name that holds them (as many
    episodes or more, the same shape and type otherwise) is filled in place of a new one, and
    its first episodes come back."""
    manifest = _read_manifest(path)
    folder = path.parent / SEGMENTS
    size = manifest["size"]
    arrays: dict[str, np.ndarray] = {}
    expected = 0
    for name, first, end in manifest["segments"]:
        if first != expected or end > size:
            raise ValueError(
                f"{path / MANIFEST}: segment {name} does not follow episode {expected}"
            )
        with np.load(folder / name) as data:
            if arrays and set(data.files) != set(arrays):
                raise ValueError(f"segment {folder / name} holds other arrays than the one before")
            for key in data.files if replay else ():
                part = data[key]
                if len(part) != end - first:
                    raise ValueError(
                        f"segment {folder / name}: {key} holds {len(part)} episodes, "
                        f"not {end - first}"
                    )
                if key not in arrays:
                    arrays[key] = _first_episodes(into, key, size, part)
                arrays[key][first:end] = part
        expected = end
    if expected != size:
        raise ValueError(f"{path / MANIFEST}: segments end at {expected}, not {size}")
    if not replay:
        return arrays  # empty: every segment was opened and listed
    return {**arrays, **{k: np.asarray(v) for k, v in manifest["scalars"].items()}}


def _first_episodes(
    into: Mapping[str, np.ndarray] | None, key: str, size: int, part: np.ndarray
) -> np.ndarray:
    """The array a segmented replay's `key` is read into: the first `size` episodes of
    `into[key]` where they fit `part`'s episodes, else a new array."""
    target = into.get(key) if into is not None else None
    fits = (
        target is not None
        and len(target) >= size
        and target.shape[1:] == part.shape[1:]
        and target.dtype == part.dtype
    )
    return target[:size] if fits else np.empty((size, *part.shape[1:]), part.dtype)


def _remove_temporary_segments(directory: Path) -> None:
    """Remove half-written segments, and the segments' folder if that leaves it empty."""
    folder = directory / SEGMENTS
    if folder.is_dir():
        for p in folder.glob(".tmp-*"):
            p.unlink(missing_ok=True)
        if not any(folder.iterdir()):
            folder.rmdir()


def _prune_segments(directory: Path) -> None:
    """Remove the segments (and temporaries) that no checkpoint left lists; none while a
    checkpoint's manifest cannot be read (it might list any of them)."""
    folder = directory / SEGMENTS
    if not folder.is_dir():
        return
    listed: set[str] = set()
    for path in list_checkpoints(directory):
        if (path / MANIFEST).exists():
            try:
                listed.update(name for name, *_ in _read_manifest(path)["segments"])
            except (OSError, ValueError):
                return
    for p in folder.iterdir():
        if p.is_file() and p.name not in listed:
            p.unlink(missing_ok=True)


def remove_partial(directory: Path) -> None:
    """Delete temporary checkpoint folders a crash left behind."""
    if directory.exists():
        for p in directory.iterdir():
            if p.name.startswith(".tmp-"):
                shutil.rmtree(p, ignore_errors=True)
        _remove_temporary_segments(directory)


def load(
    path: Path,
    map_location: str | torch.device = "cpu",
    replay: bool = True,
    into: Mapping[str, np.ndarray] | None = None,
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(state, replay arrays) of the checkpoint at `path`. With `replay=False` the replay's
    arrays are not read (an evaluation needs only the networks: the replay is most of a
    checkpoint's size): its archive is opened and listed, so that a truncated one is still
    refused, and the arrays come back empty. `into`: the arrays of the replay that will take
    them (`EpisodeReplay.arrays`), read into where they fit, so that a resume holds the replay
    once rather than twice while it loads (segmented replays; one that evicted episodes is read
    whole, as written)."""
    try:
        state = torch.load(path / "state.pt", map_location=map_location, weights_only=False)
        if (path / MANIFEST).exists():
            arrays = _read_segments(path, replay, into)
        else:
            with np.load(path / "replay.npz") as data:
                arrays = {k: data[k] for k in data.files} if replay else {}
    except (
        OSError,
        RuntimeError,
        ValueError,
        EOFError,
        KeyError,
        TypeError,
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
    directory: Path,
    map_location: str | torch.device = "cpu",
    replay: bool = True,
    into: Mapping[str, np.ndarray] | None = None,
) -> tuple[Path, dict[str, Any], dict[str, np.ndarray]] | None:
    """(path, state, replay) of the newest readable checkpoint in `directory`, None when there is
    none. An unreadable newest one is passed over for the one before, with a warning naming
    it; an error when none can be read.

    A checkpoint is taken by its state's own episode counter, which must be the episode its
    folder's name says: one renamed or copied under another name (`ep-000000000999` holding
    episode 24) is passed over like a damaged one, so that a name never sends a run back to an
    older state. `replay=False` and `into`: as `load`'s."""
    found = list_checkpoints(directory)
    errors = []
    for path in reversed(found):
        try:
            state, arrays = load(path, map_location, replay, into)
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
        raise CheckpointError(
            f"no checkpoint in {directory} can be read ({len(errors)} tried; the newest: "
            f"{errors[0]}): restore them, or start the run over"
        )
    return None
