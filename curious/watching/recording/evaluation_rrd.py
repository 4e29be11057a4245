"""The Rerun recording of `curious evaluate --record`: an evaluation's episodes in 3-D.

`EvaluationRecording` records, for each module evaluated, its first `per_module` episodes as 3-D
rollouts, with the training recording's own machinery (`RunRecorder.log_rollout` through a
`RolloutObserver`, so bodies, goal, goal region and gripper path look as in `recording.rrd`),
and every episode's success, laid out by the training recording's blueprint:

| path | content |
|---|---|
| `scene/...` | the recorded episodes in 3-D, one after another on `rollout_frame` |
| `success/eval/<module>` | 0/1 success of each of the module's episodes (`curious evaluate`'s) |
| `competence/<module>` | the module's success rate over its episodes so far (last: the table's) |
| `module/<module>` | the module of each episode, drawn at its slot index |

The `episode` timeline counts the evaluation's episodes (0, 1, ...: module after module, as
`curious evaluate` plays them), not training episodes; the recording's name says which run and
checkpoint it evaluates. A rollout's label reads "T4 stack cube 1 on 2, episode 7: failure".

The file is written beside its target under a temporary name and renamed when whole; a run's
training recording (`recording.rrd` next to a `config.json`) is never a target.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from curious.runs.folder_layout import CONFIG_FILE, EVALUATION_RECORDING_FILE, RECORDING_FILE
from curious.runs.folder_lock import check_writable
from curious.watching.palette import module_entity
from curious.watching.recording.recorder import RecorderSettings, RunRecorder
from curious.watching.recording.rollout_capture import RolloutObserver

__all__ = ["DEFAULT_FILE", "EvaluationRecording", "check_target"]

DEFAULT_FILE = EVALUATION_RECORDING_FILE


def check_target(path: str | os.PathLike[str], run: str | os.PathLike[str]) -> Path:
    """The recording's path, refused in one line where it would be no recording, would
    replace a run's training recording, or cannot be written (`check_writable`)."""
    target = Path(path)
    if target.suffix.lower() != ".rrd":
        raise ValueError(f"--record writes a Rerun .rrd file, got {str(path)!r}")
    if target.is_dir():
        raise ValueError(f"--record {path} is a folder; name an .rrd file")
    resolved = target.resolve()
    run_recording = (Path(run) / RECORDING_FILE).resolve()
    training = resolved.name == RECORDING_FILE and (resolved.parent / CONFIG_FILE).exists()
    if resolved == run_recording or training:
        raise ValueError(
            f"--record {path} is a run's training recording; name another file "
            f"(default: ./{DEFAULT_FILE})"
        )
    check_writable(target, "--record")
    return target


class _FirstEpisodes:
    """What `RolloutObserver` asks of a recorder: which episodes to capture (each module's
    first `per_module`), and where to log them."""

    def __init__(self, recorder: RunRecorder, episodes: int, per_module: int) -> None:
        self.recorder = recorder
        self.episodes = episodes
        self.per_module = per_module

    def rollout_due(self, index: int) -> bool:
        return index % self.episodes < self.per_module

    def log_rollout(self, *args: Any, **kwargs: Any) -> None:
        self.recorder.log_rollout(*args, **kwargs)


class EvaluationRecording:
    """Records an evaluation of `episodes` episodes per module into the `.rrd` file `path`.

    Pass `observer` to `EvaluationSession.evaluate`, then `finish(result)` with its result
    (or `abandon()` when it failed): the file appears only when whole.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        module_names: Sequence[str],
        episodes: int,
        per_module: int,
        episode_length: int,
        name: str,
    ) -> None:
        if per_module < 0:
            raise ValueError(f"--record-episodes must be >= 0, got {per_module}")
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.module_names = tuple(module_names)
        self._folder = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", dir=self.path.parent))
        settings = RecorderSettings(rollout_every=1, rollout_stride=1)
        self.recorder = RunRecorder(
            self._folder, self.module_names, settings=settings, run_name=name
        )
        self.observer = RolloutObserver(
            _FirstEpisodes(self.recorder, episodes, per_module), 1, episode_length
        )

    def _log_scores(self, result: Any) -> None:
        """Each episode's success, the running success rate and the module, per module."""
        stream = self.recorder.stream
        for k, row in enumerate(result.modules):
            entity = module_entity(row.module)
            success = np.asarray(row.per_episode["success"], np.float64)
            n = success.size
            index = [rr.TimeColumn("episode", sequence=k * row.episodes + np.arange(n))]
            rate = np.cumsum(success) / np.arange(1, n + 1)
            slot = float(self.module_names.index(row.module))
            for path, values in (
                (f"success/eval/{entity}", success),
                (f"competence/{entity}", rate),
                (f"module/{entity}", np.full(n, slot)),
            ):
                stream.send_columns(path, indexes=index, columns=rr.Scalars.columns(scalars=values))

    def finish(self, result: Any) -> Path:
        """Logs the scores of `result` (an `Evaluation`), writes the file, returns its path."""
        try:
            self._log_scores(result)
            self.recorder.close()
            os.replace(self._folder / RECORDING_FILE, self.path)
        except BaseException:
            self.abandon()
            raise
        shutil.rmtree(self._folder, ignore_errors=True)
        return self.path

    def abandon(self) -> None:
        """Drops the recording (the evaluation failed or was interrupted)."""
        self.recorder.close_after_error()
        shutil.rmtree(self._folder, ignore_errors=True)
