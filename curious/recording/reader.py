"""Reading a run's `recording.rrd` back with Rerun's own reader (`rerun.chunk.RrdReader`).

For checking recordings (tests, the logging-cost measurement) and for a quick look from Python.
Analysis never reads recordings: `metrics.parquet` is the source of every figure. The reader API
is rerun-sdk 0.41's (`RrdReader(path).stream()` yields chunks whose `to_record_batch()` is a
pyarrow batch with one column per timeline and per component); it has changed between releases,
which is why this stays in one small module.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
from rerun.chunk import RrdReader

__all__ = ["RecordingSummary", "read_component", "read_scalars", "summarize"]


@dataclass(frozen=True)
class RecordingSummary:
    """What a recording file holds: its ids, entities, timelines and size."""

    application_id: str
    recording_ids: tuple[str, ...]
    entities: frozenset[str]  # entity paths with data, without the leading "/"
    static_entities: frozenset[str]
    timelines: frozenset[str]
    n_chunks: int
    size_bytes: int


def _strip(path: str) -> str:
    return path.lstrip("/")


def summarize(path: str | os.PathLike[str]) -> RecordingSummary:
    """Lists the recording's stores, entity paths (static and temporal) and timelines."""
    reader = RrdReader(path)
    stores = reader.recordings()
    if not stores:
        raise ValueError(f"{path} holds no recording")
    entities: set[str] = set()
    static: set[str] = set()
    timelines: set[str] = set()
    n = 0
    for chunk in reader.stream():
        n += 1
        name = _strip(chunk.entity_path)
        if name.startswith("__"):
            continue  # recording properties
        entities.add(name)
        if chunk.is_static:
            static.add(name)
        timelines.update(chunk.timeline_names)
    return RecordingSummary(
        application_id=stores[0].application_id,
        recording_ids=tuple(s.recording_id for s in stores),
        entities=frozenset(entities),
        static_entities=frozenset(static),
        timelines=frozenset(timelines),
        n_chunks=n,
        size_bytes=os.path.getsize(path),
    )


def read_component(
    path: str | os.PathLike[str], entity: str, component: str, timeline: str | None
) -> tuple[np.ndarray, list[object]]:
    """All rows of one component of one entity, ordered by `timeline` (then logging order).

    Args:
        path: the `.rrd` file.
        entity: the entity path, e.g. "competence/reach".
        component: the column name, e.g. "Scalars:scalars" or "Transform3D:translation".
        timeline: the timeline to index by, or None for the entity's static value.

    Returns:
        (times, values): times as int64 (sequence timelines) or float seconds (duration
        timelines), empty for static rows; values as Python lists, one per row.
    """
    target = "/" + _strip(entity)
    times: list[np.ndarray] = []
    values: list[object] = []
    for chunk in RrdReader(path).stream().filter(content=target):
        if chunk.entity_path != target or chunk.is_static != (timeline is None):
            continue
        batch = chunk.to_record_batch()
        if component not in batch.schema.names:
            continue
        if timeline is not None:
            if timeline not in batch.schema.names:
                continue
            column = batch.column(timeline)
            t = column.to_numpy(zero_copy_only=False)
            if np.issubdtype(t.dtype, np.timedelta64):
                t = t.astype("timedelta64[ns]").astype(np.int64) / 1e9
            times.append(np.asarray(t))
        values.extend(batch.column(component).to_pylist())
    if timeline is None:
        return np.zeros(0), values
    if not times:
        return np.zeros(0, dtype=np.int64), []
    t_all = np.concatenate(times)
    order = np.argsort(t_all, kind="stable")
    return t_all[order], [values[i] for i in order]


def read_scalars(
    path: str | os.PathLike[str], entity: str, timeline: str = "episode"
) -> tuple[np.ndarray, np.ndarray]:
    """A scalar series (e.g. "competence/reach") as (times, values) arrays, ordered by time."""
    times, rows = read_component(path, entity, "Scalars:scalars", timeline)
    values = np.array([r[0] if r else np.nan for r in rows], dtype=np.float64)
    return times, values
