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

A recording that cannot be read (`read_previous`) is set aside with a warning, never a reason a
run cannot resume. A recording that is missing, or that was set aside, is rebuilt from the run's
tables instead (`rebuild_from_tables`): every series `metrics.parquet`, `tests.parquet` and
`learner.parquet` hold (competence, LP and p_LP, success, module, test success; the replay
shares and the learner statistics), logged cycle by cycle as the run logged them, so that they
come out as an uninterrupted run's (the module statistics at the float32 precision of the
tables). No table holds the 3-D rollouts: they start again after the resumed episode, and so do
the replay shares and learner statistics of a run whose `learner.parquet` does not reach back to
its start (a run from before that table); a warning says where each starts.
"""

from __future__ import annotations

import itertools
import os
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
from rerun.chunk import Chunk

from curious.runs.hooks import log_learner_rows
from curious.watching.recording.rrd_files import PreviousRecording, load_previous

__all__ = [
    "IN_LEARNER_TABLE",
    "NOT_IN_TABLES",
    "PER_CYCLE",
    "last_episode_kept",
    "read_previous",
    "rebuild_from_tables",
    "take_held_values",
]

NOT_IN_TABLES = ("scene/",)
"""Entity prefixes a recording rebuilt from the run's tables lacks before the resumed episode:
the 3-D rollouts, which no table keeps."""

IN_LEARNER_TABLE = ("replay/", "losses/", "q/")
"""Entity prefixes of the series `learner.parquet` keeps (from the episode it begins at,
`curious.runs.metrics.LearnerLog.from_episode`): the replay shares, the losses, the Q values."""

PER_CYCLE = ("losses/", "q/", "replay/", "test/")
"""Entity prefixes logged once a cycle, at the episode count after it."""

_SCALARS = "Scalars:scalars"


def last_episode_kept(episodes_done: int) -> Callable[[str], int]:
    """Entity path -> the last episode of it that a run resumed at `episodes_done` keeps."""

    def last(entity: str) -> int:
        return episodes_done if entity.startswith(PER_CYCLE) else episodes_done - 1

    return last


def read_previous(
    path: Path, resume_from_episode: int | None
) -> tuple[PreviousRecording | None, str | None]:
    """The recording at `path` in memory, cut at the checkpoint of `resume_from_episode`
    episodes (None: not cut), and its id; (None, None) where there is none, or where it cannot
    be read: it is then kept as `<name>.unreadable`, with a warning."""
    if not path.exists():
        return None, None
    try:
        cut = None if resume_from_episode is None else last_episode_kept(resume_from_episode)
        return load_previous(path, cut)
    except Exception as exc:  # whatever a damaged file raises, the run goes on
        aside = path.with_name(f"{path.name}.unreadable")
        os.replace(path, aside)
        warnings.warn(
            f"{path} could not be read ({exc}); it is kept as {aside.name} and the "
            "recording starts again (`curious train --resume` rebuilds what the run's "
            "tables hold)",
            RuntimeWarning,
            stacklevel=3,
        )
        return None, None


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


def rebuild_from_tables(
    recorder: Any,
    metrics: pa.Table,
    tests: pa.Table,
    episodes_done: int,
    episodes_per_cycle: int,
    learner: pa.Table | None = None,
) -> int:
    """Log into `recorder` (a `RunRecorder` that starts a new recording) the rows of the run's
    tables up to `episodes_done`, the checkpoint's episode count, as the run logged them: the
    episodes cycle by cycle (`episodes_per_cycle` a cycle: written-where-it-changes statistics
    and their keyframes depend on it), after each its test rollouts (at an epoch's end) and its
    row of `learner` (`learner.parquet`, where there is one). Returns the episodes logged."""
    metrics = metrics.filter(pc.less(metrics["episode"], episodes_done)).sort_by("episode")
    tests = tests.filter(pc.less_equal(tests["episode"], episodes_done)).sort_by("episode")
    if learner is not None:
        learner = learner.filter(pc.less_equal(learner["episode"], episodes_done))
        learner = learner.sort_by("episode")
        learner_episode = learner["episode"].to_numpy()
    names = recorder.module_names
    stats = {
        kind: np.column_stack(
            [metrics[f"{kind}/{name}"].to_numpy().astype(np.float64) for name in names]
        )
        if metrics.num_rows
        else np.zeros((0, len(names)))
        for kind in ("competence", "lp", "p_lp")
    }
    episode = metrics["episode"].to_numpy()
    module = np.asarray(metrics["module"].to_pylist(), dtype=object)
    success = metrics["success"].to_numpy(zero_copy_only=False)
    is_eval = metrics["eval"].to_numpy(zero_copy_only=False)
    wall = metrics["wall_time"].to_numpy()
    test_episode = tests["episode"].to_numpy()
    test_module = np.asarray(tests["module"].to_pylist(), dtype=object)
    test_success = tests["success"].to_numpy(zero_copy_only=False)
    test_wall = tests["wall_time"].to_numpy()
    cycle = episode // episodes_per_cycle
    starts = np.flatnonzero(np.r_[True, cycle[1:] != cycle[:-1]]) if episode.size else []
    bounds = [*starts, episode.size]
    for a, b in itertools.pairwise(bounds):
        sl = slice(a, b)
        recorder.log_episodes(
            episode=episode[sl],
            module=module[sl],
            success=success[sl],
            eval=is_eval[sl],
            competence=stats["competence"][sl],
            lp=stats["lp"][sl],
            p_lp=stats["p_lp"][sl],
            wall_time=wall[sl],
        )
        end = int(episode[b - 1]) + 1
        lo, hi = np.searchsorted(test_episode, [end, end + 1])  # tests run after this cycle
        if hi > lo:
            recorder.log_tests(end, test_module[lo:hi], test_success[lo:hi], test_wall[lo])
        if learner is not None:  # this cycle's row, and any before it the loop has not met
            upto = int(np.searchsorted(learner_episode, end, side="right"))
            log_learner_rows(recorder, learner.slice(0, upto).to_pydict())
            learner = learner.slice(upto)
            learner_episode = learner_episode[upto:]
    if episode.size:
        recorder.continue_clock(float(wall[-1]))
    return int(episode.size)
