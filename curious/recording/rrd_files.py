"""The recording file on disk: reading one back to resume it, copying it, compacting it.

`RunRecorder` writes through Rerun's file sink; these helpers work on whole `.rrd` files: a resumed
run reads the recording of its last checkpoint into memory, cut at the checkpoint's episode
(`load_previous`); the working file is copied over `recording.rrd` atomically at every checkpoint
(`replace_with_copy`); and a finished recording is rewritten with its chunks merged
(`compact_recording`).
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc
import rerun as rr
from rerun.chunk import Chunk, OptimizationProfile, RrdReader

from curious.recording.blueprint import default_blueprint

__all__ = ["PreviousRecording", "compact_recording", "load_previous", "replace_with_copy"]


@dataclass
class PreviousRecording:
    """The chunks of a recording being resumed, and the next free rollout frame."""

    chunks: list[Chunk]
    next_frame: int


def replace_with_copy(source: Path, target: Path) -> None:
    """`target` becomes a copy of `source`, atomically (a temporary file, fsync, rename)."""
    tmp = target.with_name(f".{target.name}.tmp")
    shutil.copyfile(source, tmp)
    with open(tmp, "rb") as handle:
        os.fsync(handle.fileno())
    os.replace(tmp, target)


def compact_recording(
    path: str | os.PathLike[str], out: str | os.PathLike[str] | None = None
) -> None:
    """Rewrites a recording with its chunks merged (same ids, data and blueprint; smaller), in
    place or into `out`.

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
    stream.set_sinks(rr.FileSink(str(tmp)), default_blueprint=default_blueprint())
    stream.send_chunks(store)
    stream.flush()
    stream.disconnect()
    os.replace(tmp, target)


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
