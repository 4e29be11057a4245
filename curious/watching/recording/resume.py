"""What a resumed `RunRecorder` takes over from the recording of the run it continues.

A run resumes from a checkpoint taken after a cycle; the recording it reads may hold more (what
was logged after that checkpoint, before a kill or an error). The resumed recorder keeps exactly
what an uninterrupted run had logged at the checkpoint, and picks up the state it logs from:

- the cut (`last_episode_kept`): a cycle's episodes are logged at their own indices, but its
  replay, learner and test statistics at the episode count after it, which is the checkpoint's
  episode count `E` for the cycle that ends at the checkpoint. So per-episode entities keep
  episodes < E, and the per-cycle entities (`PER_CYCLE`) keep episode E too;
- the held values (`take_held_values`): competence, LP and p_LP are written where they change
  (`RecorderSettings.stats_on_change`); the recorder compares each episode's value with the last
  one, so it needs the value each series holds at the checkpoint, and the episode it was last
  written at (for the keyframes). The points `close()` adds to carry a held value to the end of
  a run are not part of the run it continues (a finished run extended, or a run stopped early):
  they are dropped, and the resumed run writes its own when it ends.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
from rerun.chunk import Chunk

from curious.watching.recording.rrd_files import PreviousRecording

__all__ = ["PER_CYCLE", "last_episode_kept", "take_held_values"]

PER_CYCLE = ("losses/", "q/", "replay/", "test/")
"""Entity prefixes logged once a cycle, at the episode count after it."""

_SCALARS = "Scalars:scalars"


def last_episode_kept(episodes_done: int) -> Callable[[str], int]:
    """Entity path -> the last episode of it that a run resumed at `episodes_done` keeps."""

    def last(entity: str) -> int:
        return episodes_done if entity.startswith(PER_CYCLE) else episodes_done - 1

    return last


def _same(a: float, b: float) -> bool:
    return a == b or (np.isnan(a) and np.isnan(b))


def take_held_values(
    previous: PreviousRecording, paths: Iterable[str], keyframe_every: int
) -> dict[str, tuple[int, float]]:
    """Each series in `paths` (written where it changes): (episode, value) of its last point.

    A last point that only repeats the point before it and is no keyframe (fewer than
    `keyframe_every` episodes after it, or a NaN) was added by `close()` at the end of a run:
    it is removed from `previous.chunks` and the point before it is the held value.
    """
    wanted = set(paths)
    rows: dict[str, list[tuple[int, np.ndarray, np.ndarray]]] = {}
    for index, chunk in enumerate(previous.chunks):
        entity = chunk.entity_path.lstrip("/")
        if chunk.is_static or entity not in wanted:
            continue
        batch = chunk.to_record_batch()
        if "episode" not in batch.schema.names or _SCALARS not in batch.schema.names:
            continue
        episodes = batch.column("episode").to_numpy(zero_copy_only=False)
        values = pc.list_element(batch.column(_SCALARS), 0).to_numpy(zero_copy_only=False)
        rows.setdefault(entity, []).append((index, episodes, values.astype(np.float64)))

    held: dict[str, tuple[int, float]] = {}
    drop: dict[int, int] = {}  # chunk index -> row to drop
    for entity, parts in rows.items():
        episodes = np.concatenate([p[1] for p in parts])
        values = np.concatenate([p[2] for p in parts])
        where = np.concatenate([np.full(p[1].shape[0], p[0]) for p in parts])
        local = np.concatenate([np.arange(p[1].shape[0]) for p in parts])
        order = np.argsort(episodes, kind="stable")
        last = order[-1]
        before = order[-2] if order.size > 1 else None
        before_value = values[before] if before is not None else np.nan
        keyframe = (
            keyframe_every > 0
            and before is not None
            and not np.isnan(values[last])
            and episodes[last] - episodes[before] >= keyframe_every
        )
        if _same(values[last], before_value) and not keyframe:
            drop[int(where[last])] = int(local[last])
            if before is not None:
                held[entity] = (int(episodes[before]), float(before_value))
        else:
            held[entity] = (int(episodes[last]), float(values[last]))

    if drop:
        chunks: list[Chunk] = []
        for index, chunk in enumerate(previous.chunks):
            if index not in drop:
                chunks.append(chunk)
                continue
            batch = chunk.to_record_batch()
            keep = np.ones(batch.num_rows, bool)
            keep[drop[index]] = False
            if keep.any():
                chunks.extend(Chunk.from_record_batch(batch.filter(pa.array(keep))))
        previous.chunks = chunks
    return held
