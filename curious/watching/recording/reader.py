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

from curious.watching.recording.rrd_files import open_rrd

__all__ = ["RecordingSummary", "read_component", "read_points", "read_scalars", "summarize"]


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
    reader = open_rrd(path)
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
    for chunk in open_rrd(path).stream().filter(content=target):
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


Point = tuple[int | None, int | None, str]
"""One row of a component: (episode, rollout_frame, the value's repr); None off a timeline."""


def read_points(
    path: str | os.PathLike[str],
) -> tuple[dict[tuple[str, str], list[Point]], dict[tuple[str, str], str]]:
    """Everything a recording holds, entity by entity and component by component, without
    its timing: for checking that two recordings of the same run hold the same points.

    Returns (temporal, static): temporal maps (entity, component) to its rows, sorted, on the
    `episode` and `rollout_frame` timelines (`wall_time` is left out: it differs between two
    runs of the same seed); static maps (entity, component) to the repr of its value (the last
    one logged, the one a viewer shows). Values are compared by repr, so NaN equals NaN.
    """
    temporal: dict[tuple[str, str], list[Point]] = {}
    static: dict[tuple[str, str], str] = {}
    for chunk in open_rrd(path).stream():
        entity = _strip(chunk.entity_path)
        if entity.startswith("__"):
            continue  # recording properties
        batch = chunk.to_record_batch()
        names = batch.schema.names
        n = batch.num_rows
        episode = batch.column("episode").to_pylist() if "episode" in names else [None] * n
        frame = (
            batch.column("rollout_frame").to_pylist() if "rollout_frame" in names else [None] * n
        )
        for component in (c for c in names if ":" in c and not c.startswith("rerun.")):
            values = [repr(v) for v in batch.column(component).to_pylist()]
            if chunk.is_static:
                static[(entity, component)] = values[-1]
            else:
                rows = temporal.setdefault((entity, component), [])
                rows.extend(zip(episode, frame, values, strict=True))
    for rows in temporal.values():
        rows.sort(key=lambda r: (r[0] is None, r[0] or 0, r[1] is None, r[1] or 0, r[2]))
    return temporal, static
