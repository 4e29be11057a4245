"""`RunRecorder`: the Rerun recording of one training run (`recording.rrd` in the run folder).

One recorder per run, with its own `recording_id` (a fresh UUID unless given), so that runs in
parallel processes never merge into one recording (Rerun's default id is shared by every process
of a job). The training loop hands over arrays for a batch of episodes at a time. The recorder
composes the parts that do the work:

| part | module |
|---|---|
| the stream, its sinks, the working file's flushes, checkpoints and close | `working_file` |
| a resumed recording read back, cut at the checkpoint | `resume` |
| the modules' names, labels and colours; the arguments checked | `recorded_modules` |
| scalar rows buffered and sent in large chunks; the run's clock | `scalar_series` |
| episodes, tests, replay shares, learner statistics | `training_series` |
| competence, LP and p_LP, written where they change | `module_statistics` |
| rollouts and their scene in 3D | `rollout_log` |

Entity paths (fixed, so that recordings of different runs line up; `<module>` is the module's
name led by its task number in the paper where it has one, `T1-reach`, `T2-push_cube1`, ...,
`curious.watching.palette.module_entity`, so that the viewer's legends read T1..T7):

| path | content |
|---|---|
| `competence/<module>` | competence after each episode (line, written where it changes*) |
| `lp/<module>` | absolute learning progress (line, written where it changes*) |
| `p_lp/<module>` | module selection probability (line, written where it changes*) |
| `success/eval/<module>`, `success/train/<module>` | 0/1 final success of each episode (points) |
| `module/<module>` | the module of each episode, drawn at its slot index (points) |
| `test/<module>` | success rate of an epoch's test rollouts of that module |
| `replay/<module>` | share of replayed transitions with that module (relabelled or their own) |
| `losses/<name>`, `q/<name>` | learner statistics |
| `scene/...` | rollouts in 3D: bodies, goal, gripper path (`curious.watching.recording.scene`) |

*and again every `stats_keyframe_every` (500) episodes while it holds, so that a live view draws
a held value up to the present.

After any kills and resumes the recording holds the points of an uninterrupted run, no more, no
fewer. A recording that cannot be read is set aside with a warning, never a reason a run cannot
resume; `curious.watching.recording.rollout_capture.recorder_factory` then rebuilds, as where the
recording is missing, what the run's tables hold
(`curious.watching.recording.resume.rebuild_from_tables`).
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from curious.runs.folder_layout import RECORDING_FILE
from curious.watching.recording.module_statistics import ModuleStatistics
from curious.watching.recording.recorded_modules import RecordedModules
from curious.watching.recording.resume import read_previous
from curious.watching.recording.rollout_log import RolloutLog
from curious.watching.recording.rrd_files import compact_recording
from curious.watching.recording.scalar_series import ScalarSeries
from curious.watching.recording.scene import RolloutCapture
from curious.watching.recording.settings import RecorderSettings
from curious.watching.recording.training_series import TrainingSeries
from curious.watching.recording.working_file import (
    APPLICATION_ID,
    DEFAULT_VIEWER_PORT,
    WorkingFile,
)

__all__ = [
    "APPLICATION_ID",
    "RecorderSettings",
    "RunRecorder",
    "compact_recording",
]


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
        modules = RecordedModules(module_names)
        self.module_names: tuple[str, ...] = modules.names
        self.settings = settings or RecorderSettings()
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.path = self.run_dir / RECORDING_FILE
        previous, old_id = read_previous(self.path, resume_from_episode) if resume else (None, None)
        self.started_over = resume and previous is None
        """A resume that found no readable recording to continue: a new one was started."""
        self.recording_id = str(recording_id or old_id or uuid.uuid4())
        self._file = WorkingFile(
            self.path,
            self.recording_id,
            len(modules),
            run_name=run_name or self.run_dir.resolve().name,
            spawn=spawn,
            connect=connect,
            viewer_port=viewer_port,
        )
        self.working = self._file.working
        self.stream = self._file.stream
        self.live = self._file.live
        self.blueprint = self._file.blueprint
        start = previous.last_wall if previous is not None else 0.0
        self._scalars = ScalarSeries(self.stream, self.settings, self.live, start)
        self._stats = ModuleStatistics(modules, self.settings, self._scalars)
        self._series = TrainingSeries(self.stream, modules, self._scalars, self._stats)
        self._rollouts = RolloutLog(self.stream, modules, self.settings)
        if previous is not None:
            self._stats.take_over(previous)
            self._series.take_over(previous)
            self._rollouts.take_over(previous)
            self.stream.send_chunks(previous.chunks)  # less what `take_over` dropped
        self._series.log_styles()

    def continue_clock(self, seconds: float) -> None:
        """Wall times logged without one go on from `seconds` (where a rebuilt recording ends),
        as a resumed recording's go on from where it ends."""
        self._scalars.continue_clock(seconds)
        self._stats.last_wall = seconds

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
        self._file.check_open()
        stats = {"competence": competence, "lp": lp, "p_lp": p_lp}
        self._series.log_episodes(episode, module, success, eval, stats, wall_time)

    def log_tests(self, episode: int, module: Any, success: Any, wall_time: Any = None) -> None:
        """Logs one epoch's test rollouts as each tested module's success rate, under
        `test/<module>` at the training episode count `episode`.

        Args:
            episode: training episodes done when the tests ran.
            module: (K,) module of each test rollout, slot indices or names.
            success: (K,) bool, its final success.
            wall_time: seconds since the run started (default: now).
        """
        self._file.check_open()
        self._series.log_tests(episode, module, success, wall_time)

    def log_replay(self, episode: Any, counts: Any, wall_time: Any = None) -> None:
        """Logs the replay composition: how many replayed transitions had each module (counts
        or shares; each row is normalised to shares).

        Args:
            episode: int or (B,) episode index at which each row was measured.
            counts: (n_modules,) or (B, n_modules) non-negative counts or shares.
            wall_time: seconds since the run started (default: now).
        """
        self._file.check_open()
        self._series.log_replay(episode, counts, wall_time)

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
        self._file.check_open()
        self._series.log_learner(episode, {"losses": losses or {}, "q": q or {}}, wall_time)

    # ------------------------------------------------------------------ rollouts

    def rollout_due(self, eval_index: int) -> bool:
        """True when the evaluation episode with this 0-based count is to be recorded in 3D
        (every `settings.rollout_every`-th, starting with the first)."""
        return self.settings.rollout_due(eval_index)

    def log_scene(self, capture: RolloutCapture) -> None:
        """Logs the static geometry of the capture's model (done by the first `log_rollout`)."""
        self._file.check_open()
        self._rollouts.log_scene(capture)

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
        self._file.check_open()
        self._rollouts.log_rollout(capture, episode, module, success, goal, gripper)

    # ------------------------------------------------------------------ end

    def flush(self) -> None:
        """Sends the buffered scalars and blocks until everything logged so far is written."""
        self._file.check_open()
        self._scalars.send()
        self._file.flush()

    def checkpoint(self) -> None:
        """Makes `recording.rrd` hold everything logged so far (before a training checkpoint):
        flushes the working file and copies it over the recording atomically."""
        self.flush()
        self._file.checkpoint()

    def close(self) -> None:
        """Extends each module's series to the last episode, writes everything, closes the file,
        then (with `compact_on_close`) rewrites it with its chunks merged.

        A write that fails (a full disk) raises `RecordingWriteError` and leaves `recording.rrd`
        as at the last checkpoint; compacting, which needs room for a second copy, falls back to
        the recording as written, with a warning.
        """
        if self._file.closed:
            return
        self._stats.finish()
        self._file.close(self._scalars.send, self.settings.compact_on_close)

    def close_after_error(self) -> None:
        """Ends the recording when an error stopped training, never raising over that error.

        What was logged is flushed and becomes `recording.rrd`, uncompacted (a rename needs no
        room on a full disk; the next resume compacts it). If even that cannot be written, or
        the error was a write of the recording itself (a full disk, a live viewer gone), the
        recording stays as at the last checkpoint, where a resume starts anyway: a file that was
        not written in full never replaces it.
        """
        if self._file.closed:
            return
        self._file.close_after_error(self._scalars.send)

    def __enter__(self) -> RunRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
