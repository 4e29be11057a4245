"""The recording file on disk: reading one back to resume it, copying it, compacting it.

`RunRecorder` writes through Rerun's file sink; these helpers work on whole `.rrd` files: a resumed
run reads the recording of its last checkpoint into memory, cut at the checkpoint's episode
(`load_previous`); the working file is copied over `recording.rrd` atomically at every checkpoint
(`replace_with_copy`); and a finished recording is rewritten with its chunks merged
(`compact_recording`).
"""

from __future__ import annotations

import errno
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import rerun as rr
import rerun.blueprint as rrb
from rerun.chunk import Chunk, OptimizationProfile, RrdReader

from curious.recording.blueprint import default_blueprint

__all__ = [
    "PreviousRecording",
    "RecordingWriteError",
    "compact_recording",
    "flush_to_file",
    "load_previous",
    "replace_with_copy",
]

_NEARLY_FULL = 64 * 2**20
"""Free bytes under which a failed write is put down to a full disk."""


class RecordingWriteError(OSError):
    """A recording file could not be written (Rerun's file writer stopped), with the reason in
    the user's terms: Rerun itself says only "File-writer thread shut down prematurely"."""


FLUSH_TIMEOUT_SECONDS = 300.0
"""Longest wait for a file sink to take what was logged: Rerun's flush can wait forever on a file
writer that died (a full disk), and a healthy one takes seconds even for a whole run."""


def flush_to_file(
    stream: rr.RecordingStream, path: Path, timeout: float = FLUSH_TIMEOUT_SECONDS
) -> None:
    """`stream.flush()`, with a failure of its file sink writing `path` raised as a
    `RecordingWriteError` naming the file (and a full disk, when it is one)."""
    try:
        stream.flush(timeout_sec=timeout)
    except RuntimeError as exc:
        raise _write_error(path, exc) from exc


def has_room_for(path: Path, size: int) -> bool:
    """Whether the disk holding `path` has `size` bytes free, and a margin."""
    return shutil.disk_usage(path.parent).free >= size + _NEARLY_FULL


def _write_error(path: Path, cause: BaseException) -> RecordingWriteError:
    try:
        full = not has_room_for(path, 0)
    except OSError:
        full = False
    if full:
        return RecordingWriteError(
            errno.ENOSPC,
            f"No space left on device: the recording could not be written ({cause})",
            str(path),
        )
    return RecordingWriteError(f"the recording could not be written to {path}: {cause}")


@dataclass
class PreviousRecording:
    """The chunks of a recording being resumed, and the next free rollout frame."""

    chunks: list[Chunk]
    next_frame: int


def replace_with_copy(source: Path, target: Path) -> None:
    """`target` becomes a copy of `source`, atomically (a temporary file, fsync, rename)."""
    tmp = target.with_name(f".{target.name}.tmp")
    try:
        shutil.copyfile(source, tmp)
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except OSError as exc:  # named after the file being made, not the working copy it reads
        raise RecordingWriteError(
            exc.errno, f"{exc.strerror or exc}: the recording could not be copied", str(target)
        ) from exc
    finally:
        tmp.unlink(missing_ok=True)  # a half-written copy (disk full) is not left behind


def compact_recording(
    path: str | os.PathLike[str],
    out: str | os.PathLike[str] | None = None,
    blueprint: rrb.Blueprint | None = None,
) -> None:
    """Rewrites a recording with its chunks merged (same ids and data; smaller), in place or
    into `out`, with `blueprint` as its default layout (`default_blueprint()` if None).

    Each `send_columns` call is one chunk in the file, with ~1.2 kB of overhead; merging them
    (Rerun's `OptimizationProfile.LIVE`, chunks of up to 4096 rows) shrinks a run's recording
    several times over and makes it faster to open. Written to a temporary file, then renamed.
    """
    path = Path(path)
    target = Path(out) if out is not None else path
    reader = RrdReader(path)
    stores = reader.recordings()
    if not stores:
        raise ValueError(f"{path} holds no recording")
    store = reader.stream().collect(optimize=OptimizationProfile.LIVE)
    tmp = target.with_name(f".{target.name}.tmp")
    stream = rr.RecordingStream(
        stores[0].application_id, recording_id=stores[0].recording_id, send_properties=False
    )
    layout = blueprint if blueprint is not None else default_blueprint()
    try:
        stream.set_sinks(rr.FileSink(str(tmp)), default_blueprint=layout)
        stream.send_chunks(store)
        flush_to_file(stream, tmp)
        stream.disconnect()
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)


def load_previous(path: Path, after_episode: int | None) -> tuple[PreviousRecording, str]:
    """The recording at `path` in memory (chunks cut after `after_episode`), and its id."""
    reader = RrdReader(path)
    stores = reader.recordings()
    if not stores:
        raise ValueError(f"{path} holds no recording to resume")
    kept: list[Chunk] = []
    next_frame = 1
    for chunk in reader.stream().to_chunks():
        batch = chunk.to_record_batch()
        if after_episode is not None and "episode" in batch.schema.names:
            keep = pc.less_equal(batch.column("episode"), pa.scalar(after_episode, pa.int64()))
            if not pc.all(keep).as_py():
                batch = batch.filter(keep)
                if batch.num_rows == 0:
                    continue
                kept.extend(Chunk.from_record_batch(batch))
            else:
                kept.append(chunk)
        else:
            kept.append(chunk)
        if "rollout_frame" in batch.schema.names:
            last = pc.max(batch.column("rollout_frame")).as_py()
            next_frame = max(next_frame, int(last) + 1)
    return PreviousRecording(kept, next_frame), stores[0].recording_id
