"""The recording file on disk: reading one back to resume it, copying it, ending it, compacting it.

`RunRecorder` writes through Rerun's file sink; these helpers work on whole `.rrd` files: a resumed
run reads the recording of its last checkpoint into memory, cut at the checkpoint's episode
(`load_previous`); the working file is copied over `recording.rrd` atomically at every checkpoint
(`replace_with_copy`); a file sink is ended so that the file is whole even when the disk fills
(`end_file`); and a finished recording is rewritten with its chunks merged (`compact_recording`).

Rerun writes a footer (a manifest of the file's chunks) when a file sink is disconnected, and
reports no failure to write it: on a full disk the footer is cut short and the whole file becomes
unreadable, although every chunk before it was written. `end_file` checks the footer and, where
it is broken, cuts the file back to what the last successful flush wrote. A file without a
footer (the copy made at a checkpoint of a recording still being written) is read in full by
Rerun's reader; the reader's warning that it is in a "legacy format" is silenced here.
"""

from __future__ import annotations

import errno
import os
import shutil
import threading
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import rerun as rr
import rerun.blueprint as rrb
from rerun.chunk import Chunk, OptimizationProfile, RrdReader

from curious.watching.recording.blueprint import default_blueprint

__all__ = [
    "PreviousRecording",
    "RecordingWriteError",
    "compact_recording",
    "end_file",
    "flush_to_file",
    "has_footer",
    "load_previous",
    "open_rrd",
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


FLUSH_POLL_SECONDS = 2.0
"""How often a flush looks for a writer that died on a full disk: Rerun's flush sometimes fails
at once then, and sometimes waits out its whole timeout."""


def flush_to_file(
    stream: rr.RecordingStream, path: Path, timeout: float = FLUSH_TIMEOUT_SECONDS
) -> None:
    """`stream.flush()`, with a failure of its file sink writing `path` raised as a
    `RecordingWriteError` naming the file (and a full disk, when it is one).

    The wait is cut into steps of `FLUSH_POLL_SECONDS`: a step that times out with `path` no
    longer growing on a full disk ends the wait there, not after `timeout`."""
    deadline = time.monotonic() + timeout
    while True:
        remaining = deadline - time.monotonic()
        step = min(FLUSH_POLL_SECONDS, remaining)
        size, started = _size(path), time.monotonic()
        try:
            stream.flush(timeout_sec=max(step, 1e-3))
            return
        except RuntimeError as exc:
            timed_out = time.monotonic() - started >= 0.9 * step
            stalled = _size(path) == size and not _has_room(path)
            if not timed_out or step >= remaining or stalled:
                raise _write_error(path, exc) from exc


def _size(path: Path) -> int:
    """The file's size, -1 where there is none."""
    try:
        return path.stat().st_size
    except OSError:
        return -1


def open_rrd(path: str | os.PathLike[str]) -> RrdReader:
    """`RrdReader(path)` without the warning Rerun gives for a file without a footer (a
    checkpoint's copy of a recording still being written is one, and is read in full)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r".*no footer")
        return RrdReader(path)


def has_footer(path: str | os.PathLike[str]) -> bool:
    """Whether the file ends with a whole footer (what Rerun writes when a sink is disconnected)."""
    try:
        open_rrd(path).store()
    except Exception:  # no footer, a footer cut short, or no file: Rerun raises RuntimeError
        return False
    return True


DISCONNECT_TIMEOUT_SECONDS = 10.0
"""Longest wait for a stream to let go of its sinks: Rerun's `disconnect` can wait forever on a
file writer that died (a full disk), as its flush can."""


def disconnect(stream: rr.RecordingStream, timeout: float = DISCONNECT_TIMEOUT_SECONDS) -> bool:
    """`stream.disconnect()`, given up after `timeout` seconds (in a daemon thread, so that a
    writer that died cannot hold the run); whether it returned.

    Given up, it also takes Rerun's shutdown off the interpreter's exit (`unregister_shutdown`):
    that shutdown waits for every sink, the dead writer's too, and the process would never end.
    """
    done = threading.Event()

    def run() -> None:
        stream.disconnect()
        done.set()

    threading.Thread(target=run, name="rerun-disconnect", daemon=True).start()
    if done.wait(timeout):
        return True
    rr.unregister_shutdown()
    return False


def end_file(
    stream: rr.RecordingStream, path: Path, timeout: float = FLUSH_TIMEOUT_SECONDS
) -> None:
    """Flushes `stream` into `path` and disconnects it, leaving a whole file.

    A failed flush raises `RecordingWriteError` (the file is then not whole). A footer that could
    not be written in full (Rerun only logs that) is cut off: the file is then what the flush
    wrote, every chunk whole, without a footer, rather than a file Rerun cannot read at all.
    """
    flush_to_file(stream, path, timeout)
    flushed = path.stat().st_size
    disconnect(stream)
    if path.stat().st_size != flushed and not has_footer(path):
        os.truncate(path, flushed)


def has_room_for(path: Path, size: int) -> bool:
    """Whether the disk holding `path` has `size` bytes free, and a margin."""
    return shutil.disk_usage(path.parent).free >= size + _NEARLY_FULL


def _has_room(path: Path) -> bool:
    """`has_room_for(path, 0)`, True where the disk cannot be asked."""
    try:
        return has_room_for(path, 0)
    except OSError:
        return True


def _write_error(path: Path, cause: BaseException) -> RecordingWriteError:
    if "gRPC" in str(cause):  # Rerun's flush waits on every sink: a live viewer that went away
        return RecordingWriteError(
            f"the live viewer this recording streams to stopped answering ({cause}); "
            f"{path.parent} keeps the recording as at the run's last checkpoint: `curious train "
            "--resume` goes on from there, with the viewer running again or without "
            "--connect/--spawn-viewer"
        )
    if not _has_room(path):
        return RecordingWriteError(
            errno.ENOSPC,
            f"No space left on device: the recording could not be written ({cause})",
            str(path),
        )
    return RecordingWriteError(f"the recording could not be written to {path}: {cause}")


@dataclass
class PreviousRecording:
    """The chunks of a recording being resumed, cut at its checkpoint, and what they end with.

    chunks: the chunks kept, in the file's order.
    next_frame: the next free rollout frame (the rollout_frame timeline is dense).
    static_entities: entity paths with static data (styles, the scene's geometry).
    last_wall: the latest wall_time kept, in seconds (0.0 when none).
    """

    chunks: list[Chunk]
    next_frame: int
    static_entities: frozenset[str] = frozenset()
    last_wall: float = 0.0
    max_episode: dict[str, int] = field(default_factory=dict)
    """The last episode each temporal entity holds a row at (entity path without the "/")."""


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
    reader = open_rrd(path)
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
        end_file(stream, tmp)
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)


def load_previous(
    path: Path, last_episode: Callable[[str], int] | None
) -> tuple[PreviousRecording, str]:
    """The recording at `path` in memory, and its id. With `last_episode`, each entity's rows
    after `last_episode(entity path)` (on the episode timeline) are dropped."""
    reader = open_rrd(path)
    stores = reader.recordings()
    if not stores:
        raise ValueError(f"{path} holds no recording to resume")
    kept: list[Chunk] = []
    static: set[str] = set()
    max_episode: dict[str, int] = {}
    next_frame = 1
    last_wall = 0.0
    for chunk in reader.stream().to_chunks():
        entity = chunk.entity_path.lstrip("/")
        if chunk.is_static:
            static.add(entity)
            kept.append(chunk)
            continue
        batch = chunk.to_record_batch()
        if last_episode is not None and "episode" in batch.schema.names:
            limit = pa.scalar(last_episode(entity), pa.int64())
            keep = pc.less_equal(batch.column("episode"), limit)
            if not pc.all(keep).as_py():
                batch = batch.filter(keep)
                if batch.num_rows == 0:
                    continue
                kept.extend(Chunk.from_record_batch(batch))
            else:
                kept.append(chunk)
        else:
            kept.append(chunk)
        names = batch.schema.names
        if "episode" in names:
            top = int(pc.max(batch.column("episode")).as_py())
            max_episode[entity] = max(max_episode.get(entity, top), top)
        if "rollout_frame" in names:
            next_frame = max(next_frame, int(pc.max(batch.column("rollout_frame")).as_py()) + 1)
        if "wall_time" in names:
            wall = pc.max(batch.column("wall_time").cast(pa.int64())).as_py()
            last_wall = max(last_wall, wall / 1e9)
    previous = PreviousRecording(kept, next_frame, frozenset(static), last_wall, max_episode)
    return previous, stores[0].recording_id
