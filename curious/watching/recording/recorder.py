"""`RunRecorder`: the Rerun recording of one training run (`recording.rrd` in the run folder).

One recorder per run, with its own `recording_id` (a fresh UUID unless given), so that runs in
parallel processes never merge into one recording (Rerun's default id is shared by every process
of a job). The training loop hands over arrays for a batch of episodes at a time; scalars are
buffered per entity and sent with `send_columns` in large chunks (every `flush_rows` rows or
`flush_seconds`, and on `flush()`/`close()`), indexed on two timelines: `episode` (the global
episode index, a sequence) and `wall_time` (seconds since the run started, a duration).

Entity paths (fixed, so that recordings of different runs line up; `<module>` is the module's
name led by its task number in the paper where it has one, `T1-reach`, `T2-push_cube1`, ...,
`curious.analysis.palette.module_entity`, so that the viewer's legends read T1..T7):

| path | content |
|---|---|
| `competence/<module>` | competence after each episode (line, written where it changes*) |
| `lp/<module>` | absolute learning progress (line, written where it changes*) |
| `p_lp/<module>` | module selection probability (line, written where it changes*) |
| `success/eval/<module>`, `success/train/<module>` | 0/1 final success of each episode (points) |
| `module/<module>` | the module of each episode, drawn at its slot index (points) |
| `replay/<module>` | share of replayed transitions with that module (relabelled or their own) |
| `losses/<name>`, `q/<name>` | learner statistics |
| `scene/...` | rollouts in 3D: bodies, goal, gripper path (see `curious.watching.recording.scene`)
|

*and again every `stats_keyframe_every` (500) episodes while it holds, so that a live view draws
a held value up to the present.

Durability: the recorder writes to a working file beside the recording
(`.recording.rrd.part`); `checkpoint()`, which `train()` calls before every checkpoint, flushes
it and copies it over `recording.rrd` atomically, and `close()` writes the final, compacted
`recording.rrd` (the file helpers are in `curious.watching.recording.rrd_files`). So `recording.rrd`
always holds a whole recording, up to the last checkpoint of a run killed at any moment, and a
resumed run starts from it, cut at the checkpoint (`curious.watching.recording.resume`): after
any kills and resumes the recording holds the points of an uninterrupted run, no more, no fewer.
A write that fails (a full disk) never replaces `recording.rrd`
(`curious.watching.recording.rrd_files.end_file`). A recording that cannot be read is set aside
with a warning, never a reason a run cannot resume;
`curious.watching.recording.rollout_capture.recorder_factory` then rebuilds, as where the
recording is missing, what the run's tables hold
(`curious.watching.recording.resume.rebuild_from_tables`).

Module colours and labels come from `curious.analysis.palette`, shared with the figures.
A rollout's frames go on a third timeline, `rollout_frame` (dense: the recorded rollouts follow
one another without gaps, so playing that timeline shows them in order), and also on `episode`
at the rollout's episode, where the 3D view then shows how each recorded episode ended.
"""

from __future__ import annotations

import contextlib
import os
import time
import uuid
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from curious.analysis.palette import module_entity, module_label, module_rgb
from curious.runs.folder import RECORDING_FILE
from curious.watching.display import has_display
from curious.watching.recording.blueprint import default_blueprint
from curious.watching.recording.resume import last_episode_kept, take_held_values
from curious.watching.recording.rrd_files import (
    PreviousRecording,
    compact_recording,
    disconnect,
    end_file,
    flush_to_file,
    has_room_for,
    load_previous,
    replace_with_copy,
)
from curious.watching.recording.scene import (
    RolloutCapture,
    SceneLayout,
    log_scene_geometry,
    send_rollout,
)
from curious.watching.recording.settings import RecorderSettings

__all__ = [
    "APPLICATION_ID",
    "RecorderSettings",
    "RunRecorder",
    "compact_recording",
]

APPLICATION_ID = "curious"
WORKING_FILENAME = f".{RECORDING_FILE}.part"
"""The file a running recorder writes; `recording.rrd` is its copy at the last checkpoint."""
DEFAULT_VIEWER_PORT = 9876

_STATS = ("competence", "lp", "p_lp")
_NO_EPISODE = np.iinfo(np.int64).min


class _ScalarBuffer:
    """Scalar rows waiting to be sent, per entity path, in the order they were logged."""

    def __init__(self) -> None:
        self.parts: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
        self.rows = 0

    def add(self, path: str, episodes: np.ndarray, wall: np.ndarray, values: np.ndarray) -> None:
        """Queues copies (the caller may reuse its arrays before they are sent)."""
        self.parts.setdefault(path, []).append(
            (episodes.astype(np.int64), wall.astype(np.float64), values.astype(np.float64))
        )
        self.rows += episodes.shape[0]

    def drain(self) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
        """Everything buffered, one concatenated (path, episodes, wall, values) per entity."""
        out = [
            (
                path,
                np.concatenate([p[0] for p in parts]),
                np.concatenate([p[1] for p in parts]),
                np.concatenate([p[2] for p in parts]),
            )
            for path, parts in self.parts.items()
        ]
        self.parts = {}
        self.rows = 0
        return out


def _same_layout(a: SceneLayout, b: SceneLayout) -> bool:
    """True when two layouts draw the same geoms under the same paths."""
    return a.geom_paths == b.geom_paths and np.array_equal(a.drawn_geoms, b.drawn_geoms)


def _as_1d(name: str, values: Any, n: int | None = None, dtype: Any = None) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(values, dtype=dtype))
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a scalar or a 1-D array, got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        if arr.shape[0] == 1:
            return np.repeat(arr, n)
        raise ValueError(f"{name} has {arr.shape[0]} rows, expected {n} (one per episode)")
    return arr


class RunRecorder:
    """Writes one run's Rerun recording; optionally streams it to a live viewer too.

    Args:
        run_dir: the run folder; the recording is `run_dir/recording.rrd`.
        module_names: the modules in slot order (the env's `module_names`).
        settings: what to keep (`RecorderSettings`).
        recording_id: the recording's id; a fresh UUID by default. Keep it (e.g. in config.json).
        run_name: the name the viewer shows for this recording (default: the folder's name).
        spawn: also start a native viewer and stream to it live (`curious train --spawn-viewer`).
            Where there is no display it warns and only writes the file.
        connect: also stream to a viewer or server already listening at this gRPC url,
            e.g. `rerun+http://127.0.0.1:9876/proxy`.
        resume: continue an existing `recording.rrd` (same recording id, its data kept) instead
            of starting a new one.
        resume_from_episode: with `resume`, the episodes done at the checkpoint the run resumes
            from: the old recording is cut to what was logged up to that checkpoint (what came
            after it, the resumed run logs again; see `curious.watching.recording.resume`).
    """

    def __init__(
        self,
        run_dir: str | os.PathLike[str],
        module_names: Sequence[str],
        *,
        settings: RecorderSettings | None = None,
        recording_id: str | None = None,
        run_name: str | None = None,
        spawn: bool = False,
        connect: str | None = None,
        viewer_port: int = DEFAULT_VIEWER_PORT,
        resume: bool = False,
        resume_from_episode: int | None = None,
    ) -> None:
        self.module_names: tuple[str, ...] = tuple(module_names)
        if not self.module_names:
            raise ValueError("module_names is empty: a run has at least one module")
        if len(set(self.module_names)) != len(self.module_names):
            raise ValueError(f"module_names has duplicates: {self.module_names}")
        self.settings = settings or RecorderSettings()
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.path = self.run_dir / RECORDING_FILE
        self.working = self.run_dir / WORKING_FILENAME
        self._rgb = np.array([module_rgb(n) for n in self.module_names], dtype=np.uint8)
        self._labels = [module_label(n) for n in self.module_names]
        self._entities = [module_entity(n) for n in self.module_names]

        previous: PreviousRecording | None = None
        if resume and self.path.exists():
            try:
                cut = (
                    None if resume_from_episode is None else last_episode_kept(resume_from_episode)
                )
                previous, old_id = load_previous(self.path, cut)
                recording_id = recording_id or old_id
            except Exception as exc:  # whatever a damaged file raises, the run goes on
                aside = self.path.with_name(f"{self.path.name}.unreadable")
                os.replace(self.path, aside)
                warnings.warn(
                    f"{self.path} could not be read ({exc}); it is kept as {aside.name} and the "
                    "recording starts again (`curious train --resume` rebuilds what the run's "
                    "tables hold)",
                    RuntimeWarning,
                    stacklevel=2,
                )
        self.started_over = resume and previous is None
        """A resume that found no readable recording to continue: a new one was started."""
        self.recording_id = str(recording_id or uuid.uuid4())
        self.stream = rr.RecordingStream(APPLICATION_ID, recording_id=self.recording_id)

        sinks: list[Any] = [rr.FileSink(str(self.working))]
        if spawn:
            if has_display():
                self.stream.spawn(port=viewer_port, connect=False)
                sinks.append(rr.GrpcSink(f"rerun+http://127.0.0.1:{viewer_port}/proxy"))
            else:
                warnings.warn(
                    "no display (DISPLAY/WAYLAND_DISPLAY unset): not spawning a viewer; the "
                    f"recording is still written to {self.path}. Open it on a machine with a "
                    f"display with `rerun {self.path}`, or start `rerun --serve-web` here and "
                    "pass its gRPC url as `connect`.",
                    RuntimeWarning,
                    stacklevel=2,
                )
        if connect:
            sinks.append(rr.GrpcSink(connect))
        self.live = len(sinks) > 1
        self.blueprint = default_blueprint(len(self.module_names))
        self.stream.set_sinks(*sinks, default_blueprint=self.blueprint)
        self.stream.send_recording_name(run_name or self.run_dir.resolve().name)

        self._t0 = time.perf_counter()
        self._last_send = self._t0
        self._buffer = _ScalarBuffer()
        self._next_frame = 1  # frame 0 holds the scene's rest pose
        n = len(self.module_names)
        self._last = {k: np.full(n, np.nan) for k in _STATS}
        self._last_wall = 0.0
        self._logged_until = {k: np.full(n, _NO_EPISODE, dtype=np.int64) for k in _STATS}
        self._latest_episode = _NO_EPISODE
        self._styled: set[str] = set()
        self._scene: SceneLayout | None = None
        self._closed = False

        self._scene_logged: frozenset[str] = frozenset()
        """Static entities of the recording resumed (its scene geometry is not logged again)."""
        if previous is not None:
            self._take_over(previous)
            self.stream.send_chunks(previous.chunks)
        self._log_styles()

    def continue_clock(self, seconds: float) -> None:
        """Wall times logged without one go on from `seconds` (where a rebuilt recording ends),
        as a resumed recording's go on from where it ends."""
        self._t0 = time.perf_counter() - seconds
        self._last_wall = seconds

    def _take_over(self, previous: PreviousRecording) -> None:
        """Continue from a resumed recording: the next rollout frame, the clock, the series
        already styled, the scene already logged, and each statistic's held value."""
        self._next_frame = previous.next_frame
        self._t0 -= previous.last_wall  # wall times go on from where the recording ends
        self._last_wall = previous.last_wall
        self._scene_logged = previous.static_entities
        self._styled = {e for e in previous.static_entities if e.startswith(("losses/", "q/"))}
        episodes = [e for path, e in previous.max_episode.items() if path.startswith("module/")]
        if episodes:
            self._latest_episode = max(episodes)
        if not self.settings.stats_on_change:
            return
        paths = [f"{kind}/{name}" for kind in _STATS for name in self._entities]
        held = take_held_values(previous, paths, self.settings.stats_keyframe_every)
        for kind in _STATS:
            for m, name in enumerate(self._entities):
                if f"{kind}/{name}" in held:
                    episode, value = held[f"{kind}/{name}"]
                    self._logged_until[kind][m] = episode
                    self._last[kind][m] = value

    # ------------------------------------------------------------------ set-up

    def _log_styles(self) -> None:
        """Static names, colours and styles of every per-module series."""
        log = self.stream.log
        step = "StepAfter" if self.settings.stats_on_change else "Linear"
        for m, name in enumerate(self._entities):
            color, label = self._rgb[m], self._labels[m]
            for kind in _STATS:
                log(
                    f"{kind}/{name}",
                    rr.SeriesLines(colors=[color], names=[label], interpolation_mode=step),
                    static=True,
                )
            log(f"replay/{name}", rr.SeriesLines(colors=[color], names=[label]), static=True)
            for split in ("eval", "train"):
                log(
                    f"success/{split}/{name}",
                    rr.SeriesPoints(colors=[color], names=[label], marker_sizes=[3.0]),
                    static=True,
                )
            log(
                f"test/{name}",
                rr.SeriesLines(colors=[color], names=[label], interpolation_mode="Linear"),
                static=True,
            )
            log(
                f"module/{name}",
                rr.SeriesPoints(colors=[color], names=[label], marker_sizes=[2.0]),
                static=True,
            )

    # ------------------------------------------------------------------ helpers

    def _indexes(self, episodes: np.ndarray, wall: np.ndarray) -> list[rr.TimeColumn]:
        return [
            rr.TimeColumn("episode", sequence=episodes),
            rr.TimeColumn("wall_time", duration=wall),
        ]

    def _wall(self, wall_time: Any, n: int) -> np.ndarray:
        if wall_time is None:
            return np.full(n, time.perf_counter() - self._t0)
        return _as_1d("wall_time", wall_time, n, np.float64)

    def _modules(self, module: Any, n: int) -> np.ndarray:
        """(n,) slot indices of modules given by name or index: the suite's rule and its
        errors (`suite.module_index`), applied once per distinct value."""
        from suite import module_index  # a run has loaded the suite already

        values, inverse = np.unique(_as_1d("module", module, n), return_inverse=True)
        index = [module_index(self.module_names, value) for value in values.tolist()]
        return np.asarray(index, np.int64)[inverse.reshape(-1)]

    def _per_module(self, name: str, values: Any, n: int) -> np.ndarray:
        arr = np.asarray(values, dtype=np.float64)
        m = len(self.module_names)
        if arr.ndim == 1 and n == 1:
            arr = arr[None]
        if arr.shape != (n, m):
            raise ValueError(
                f"{name} must have shape ({n}, {m}) (episodes x modules), got {arr.shape}"
            )
        return arr

    def _send_scalars(
        self, path: str, episodes: np.ndarray, wall: np.ndarray, values: np.ndarray
    ) -> None:
        """Queues scalar rows of one entity; `_maybe_send` sends them in large chunks."""
        self._buffer.add(path, episodes, wall, np.asarray(values, dtype=np.float64))

    def _maybe_send(self) -> None:
        interval = self.settings.live_flush_seconds if self.live else self.settings.flush_seconds
        now = time.perf_counter()
        if self._buffer.rows >= self.settings.flush_rows or now - self._last_send >= interval:
            self._send_buffer()

    def _send_buffer(self) -> None:
        for path, episodes, wall, values in self._buffer.drain():
            self.stream.send_columns(
                path,
                indexes=self._indexes(episodes, wall),
                columns=rr.Scalars.columns(scalars=values),
            )
        self._last_send = time.perf_counter()

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"recorder for {self.path} is closed")

    # ------------------------------------------------------------------ scalars

    def log_episodes(
        self,
        episode: Any,
        module: Any,
        success: Any,
        eval: Any,
        competence: Any,
        lp: Any,
        p_lp: Any,
        wall_time: Any = None,
    ) -> None:
        """Logs a batch of B finished episodes (the rows `metrics.parquet` gets).

        Args:
            episode: (B,) int, global episode indices (increasing across calls).
            module: (B,) module of each episode, slot indices or names.
            success: (B,) bool, final success of that module.
            eval: (B,) bool, True for self-evaluation episodes.
            competence, lp, p_lp: (B, n_modules) float, each module's value after each episode.
            wall_time: (B,) seconds since the run started (default: now, for the whole batch).
        """
        self._check_open()
        episodes = _as_1d("episode", episode, None, np.int64)
        n = episodes.shape[0]
        if n == 0:
            return
        wall = self._wall(wall_time, n)
        modules = self._modules(module, n)
        succ = _as_1d("success", success, n).astype(bool)
        is_eval = _as_1d("eval", eval, n).astype(bool)
        stats = {
            "competence": self._per_module("competence", competence, n),
            "lp": self._per_module("lp", lp, n),
            "p_lp": self._per_module("p_lp", p_lp, n),
        }
        for m, name in enumerate(self._entities):
            mine = modules == m
            rows = np.flatnonzero(mine)
            if rows.size:
                self._send_scalars(
                    f"module/{name}", episodes[rows], wall[rows], np.full(rows.size, float(m))
                )
            for split, mask in (("eval", mine & is_eval), ("train", mine & ~is_eval)):
                rows = np.flatnonzero(mask)
                if rows.size:
                    self._send_scalars(
                        f"success/{split}/{name}",
                        episodes[rows],
                        wall[rows],
                        succ[rows].astype(np.float64),
                    )
        for kind, values in stats.items():
            self._log_stat(kind, episodes, wall, values)
        self._latest_episode = max(self._latest_episode, int(episodes.max()))
        self._last_wall = float(wall[-1])
        self._maybe_send()

    def _log_stat(
        self, kind: str, episodes: np.ndarray, wall: np.ndarray, values: np.ndarray
    ) -> None:
        """One module statistic for a batch: every row, or only the rows where it changed (and
        the last row of a module not written for `stats_keyframe_every` episodes)."""
        if self.settings.stats_on_change:
            prev = np.vstack([self._last[kind][None], values[:-1]])
            same = (values == prev) | (np.isnan(values) & np.isnan(prev))
            keep = ~same
            every = self.settings.stats_keyframe_every
            if every > 0:
                last_row = keep.shape[0] - 1 - np.argmax(keep[::-1], axis=0)
                written = np.where(keep.any(axis=0), episodes[last_row], self._logged_until[kind])
                keep[-1] |= (written <= episodes[-1] - every) & ~np.isnan(values[-1])
        else:
            keep = np.ones_like(values, dtype=bool)
        for m, name in enumerate(self._entities):
            rows = np.flatnonzero(keep[:, m])
            if rows.size:
                self._send_scalars(f"{kind}/{name}", episodes[rows], wall[rows], values[rows, m])
                self._logged_until[kind][m] = episodes[rows[-1]]
        self._last[kind] = values[-1].copy()

    def log_tests(self, episode: int, module: Any, success: Any, wall_time: Any = None) -> None:
        """Logs one epoch's test rollouts as each tested module's success rate, under
        `test/<module>` at the training episode count `episode`.

        Args:
            episode: training episodes done when the tests ran.
            module: (K,) module of each test rollout, slot indices or names.
            success: (K,) bool, its final success.
            wall_time: seconds since the run started (default: now).
        """
        self._check_open()
        succ = _as_1d("success", success, None).astype(np.float64)
        modules = self._modules(module, succ.shape[0])
        counts = np.bincount(modules, minlength=len(self.module_names))
        rates = np.bincount(modules, weights=succ, minlength=len(self.module_names))
        wall = self._wall(wall_time, 1)
        for m in np.flatnonzero(counts):
            self._send_scalars(
                f"test/{self._entities[m]}",
                np.array([episode], np.int64),
                wall,
                np.array([rates[m] / counts[m]]),
            )
        self._maybe_send()

    def log_replay(self, episode: Any, counts: Any, wall_time: Any = None) -> None:
        """Logs the replay composition: how many replayed transitions had each module (counts
        or shares; each row is normalised to shares).

        Args:
            episode: int or (B,) episode index at which each row was measured.
            counts: (n_modules,) or (B, n_modules) non-negative counts or shares.
            wall_time: seconds since the run started (default: now).
        """
        self._check_open()
        episodes = _as_1d("episode", episode, None, np.int64)
        n = episodes.shape[0]
        arr = self._per_module("counts", counts, n)
        if np.any(arr < 0):
            raise ValueError("replay counts must be non-negative")
        total = arr.sum(axis=1, keepdims=True)
        shares = np.divide(arr, total, out=np.zeros_like(arr), where=total > 0)
        wall = self._wall(wall_time, n)
        for m, name in enumerate(self._entities):
            self._send_scalars(f"replay/{name}", episodes, wall, shares[:, m])
        self._maybe_send()

    def log_learner(
        self,
        episode: Any,
        losses: Mapping[str, Any] | None = None,
        q: Mapping[str, Any] | None = None,
        wall_time: Any = None,
    ) -> None:
        """Logs learner statistics under `losses/<name>` and `q/<name>`.

        Args:
            episode: int or (B,) episode index of each row (e.g. the episode count at the end of
                each cycle).
            losses: name -> scalar or (B,) array, e.g. {"critic": ..., "actor": ...}.
            q: name -> scalar or (B,) array, e.g. {"mean": ..., "min": ..., "max": ...}.
            wall_time: seconds since the run started (default: now).
        """
        self._check_open()
        episodes = _as_1d("episode", episode, None, np.int64)
        n = episodes.shape[0]
        wall = self._wall(wall_time, n)
        for group, stats in (("losses", losses or {}), ("q", q or {})):
            for name, values in stats.items():
                path = f"{group}/{name}"
                if path not in self._styled:
                    self.stream.log(path, rr.SeriesLines(names=[f"{group} {name}"]), static=True)
                    self._styled.add(path)
                self._send_scalars(path, episodes, wall, _as_1d(path, values, n, np.float64))
        self._maybe_send()

    # ------------------------------------------------------------------ rollouts

    def rollout_due(self, eval_index: int) -> bool:
        """True when the evaluation episode with this 0-based count is to be recorded in 3D
        (every `settings.rollout_every`-th, starting with the first)."""
        return self.settings.rollout_due(eval_index)

    def _logged_before(self, layout: SceneLayout) -> bool:
        """Whether the recording resumed holds this layout's geometry already."""
        drawn = {layout.geom_paths[g] for g in layout.drawn_geoms}
        return bool(drawn) and drawn <= self._scene_logged

    def log_scene(self, capture: RolloutCapture) -> None:
        """Logs the static geometry of the capture's model (done by the first `log_rollout`)."""
        self._check_open()
        log_scene_geometry(self.stream, capture.model, capture.layout)
        self._scene = capture.layout

    def log_rollout(
        self,
        episode: int,
        module: int | str,
        capture: RolloutCapture,
        *,
        goal: Any,
        success: bool,
        gripper: Any = None,
    ) -> None:
        """Logs one captured episode in 3D: body poses per step, goal, gripper path, success.

        Args:
            episode: the episode's global index.
            module: its module (slot index or name); colours the goal.
            capture: the filled `RolloutCapture` (its `n_steps` rows are used).
            goal: (3,) or (n_steps, 3) goal position in the world frame (a moving target, such
                as a point above cube 2, as one row per step).
            success: the episode's final success.
            gripper: optional (n_steps, 3) gripper positions; default: the capture's gripper body.
        """
        self._check_open()
        n = capture.n_steps
        if n == 0:
            raise ValueError("the capture holds no steps: call capture.record(data) each step")
        m = int(self._modules(module, 1)[0])
        goal_rows = np.asarray(goal, dtype=np.float64)
        if goal_rows.shape == (3,):
            goal_rows = np.broadcast_to(goal_rows, (n, 3))
        if goal_rows.shape != (n, 3):
            raise ValueError(f"goal must have shape (3,) or ({n}, 3), got {goal_rows.shape}")
        if gripper is not None:
            path = np.asarray(gripper, dtype=np.float64)
            if path.shape != (n, 3):
                raise ValueError(f"gripper must have shape ({n}, 3), got {path.shape}")
        elif capture.gripper_id is not None:
            path = capture.gripper[:n]
        else:
            path = None
        if self._scene is None and self._logged_before(capture.layout):
            self._scene = capture.layout  # the recording resumed holds it
        if self._scene is None or not _same_layout(self._scene, capture.layout):
            self.log_scene(capture)

        keep = np.arange(0, n, self.settings.rollout_stride)
        if keep[-1] != n - 1:
            keep = np.append(keep, n - 1)
        f = keep.size
        frames = self._next_frame + np.arange(f, dtype=np.int64)
        self._next_frame += f
        outcome = "success" if success else "failure"
        send_rollout(
            self.stream,
            capture,
            keep,
            frames,
            int(episode),
            goal_rows[keep],
            path[keep] if path is not None else None,
            label=f"{self._labels[m]}, episode {int(episode)}: {outcome}",
            color=self._rgb[m],
            goal_radius=self.settings.goal_radius,
            path_radius=self.settings.path_radius,
        )

    # ------------------------------------------------------------------ end

    def flush(self) -> None:
        """Sends the buffered scalars and blocks until everything logged so far is written."""
        self._check_open()
        self._send_buffer()
        flush_to_file(self.stream, self.working)

    def checkpoint(self) -> None:
        """Makes `recording.rrd` hold everything logged so far (before a training checkpoint):
        flushes the working file and copies it over the recording atomically."""
        self.flush()
        replace_with_copy(self.working, self.path)

    def close(self) -> None:
        """Extends each module's series to the last episode, writes everything, closes the file,
        then (with `compact_on_close`) rewrites it with its chunks merged.

        A write that fails (a full disk) raises `RecordingWriteError` and leaves `recording.rrd`
        as at the last checkpoint; compacting, which needs room for a second copy, falls back to
        the recording as written, with a warning.
        """
        if self._closed:
            return
        if self.settings.stats_on_change and self._latest_episode != _NO_EPISODE:
            ep = np.array([self._latest_episode], dtype=np.int64)
            wall = np.array([self._last_wall])
            for kind in _STATS:
                for m, name in enumerate(self._entities):
                    if self._logged_until[kind][m] < self._latest_episode:
                        self._send_scalars(f"{kind}/{name}", ep, wall, self._last[kind][m : m + 1])
        self._closed = True
        try:
            self._send_buffer()
            end_file(self.stream, self.working)
        except BaseException:
            self._abandon_working_file()
            raise
        size = self.working.stat().st_size
        if self.settings.compact_on_close and has_room_for(self.working, size):
            try:
                compact_recording(self.working, self.path, self.blueprint)
            except (OSError, RuntimeError) as exc:  # the recording is whole without it
                warnings.warn(
                    f"{self.path} was not compacted ({exc}); it holds the whole recording, "
                    "uncompacted",
                    RuntimeWarning,
                    stacklevel=2,
                )
            else:
                self.working.unlink()
                return
        os.replace(self.working, self.path)

    def close_after_error(self) -> None:
        """Ends the recording when an error stopped training, never raising over that error.

        What was logged is flushed and becomes `recording.rrd`, uncompacted (a rename needs no
        room on a full disk; the next resume compacts it). If even that cannot be written, the
        recording stays as at the last checkpoint, where a resume starts anyway: a file that was
        not written in full never replaces it.
        """
        if self._closed:
            return
        self._closed = True
        try:
            self._send_buffer()
            end_file(self.stream, self.working, timeout=60.0)
            os.replace(self.working, self.path)
        except Exception:
            self._abandon_working_file()

    def _abandon_working_file(self) -> None:
        """Disconnects the sink and removes the working file (not whole: a write failed)."""
        with contextlib.suppress(Exception):
            disconnect(self.stream)
        with contextlib.suppress(OSError):
            self.working.unlink(missing_ok=True)

    def __enter__(self) -> RunRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
