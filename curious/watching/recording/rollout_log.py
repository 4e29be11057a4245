"""Rollouts in 3D on a run's recording: the scene's static geometry, logged once per layout (or
found in the recording resumed), and each captured episode's rows, on a timeline of its own.

A rollout's frames go on the `rollout_frame` timeline, which is dense: the recorded rollouts
follow one another without gaps, so playing that timeline shows them in order. They also go on
`episode` at the rollout's episode, where the 3D view then shows how each recorded episode
ended. The entities are `curious.watching.recording.scene`'s.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr

from curious.watching.recording.recorded_modules import RecordedModules
from curious.watching.recording.rrd_files import PreviousRecording
from curious.watching.recording.scene import (
    RolloutCapture,
    SceneLayout,
    log_scene_geometry,
    send_rollout,
)
from curious.watching.recording.settings import RecorderSettings

__all__ = ["RolloutLog"]


def _same_layout(a: SceneLayout, b: SceneLayout) -> bool:
    """True when two layouts draw the same geoms under the same paths."""
    return a.geom_paths == b.geom_paths and np.array_equal(a.drawn_geoms, b.drawn_geoms)


class RolloutLog:
    """Logs captured episodes and their scene to `stream` (the arguments of `RunRecorder`'s
    `log_scene` and `log_rollout`)."""

    def __init__(
        self, stream: rr.RecordingStream, modules: RecordedModules, settings: RecorderSettings
    ) -> None:
        self.stream = stream
        self.modules = modules
        self.settings = settings
        self._next_frame = 1  # frame 0 holds the scene's rest pose
        self._scene: SceneLayout | None = None
        self._scene_logged: frozenset[str] = frozenset()
        """Static entities of the recording resumed (its scene geometry is not logged again)."""

    def take_over(self, previous: PreviousRecording) -> None:
        """Goes on from a resumed recording: its next rollout frame, the scene it holds."""
        self._next_frame = previous.next_frame
        self._scene_logged = previous.static_entities

    def _logged_before(self, layout: SceneLayout) -> bool:
        """Whether the recording resumed holds this layout's geometry already."""
        drawn = {layout.geom_paths[g] for g in layout.drawn_geoms}
        return bool(drawn) and drawn <= self._scene_logged

    def log_scene(self, capture: RolloutCapture) -> None:
        """The static geometry of the capture's model."""
        log_scene_geometry(self.stream, capture.model, capture.layout)
        self._scene = capture.layout

    def log_rollout(
        self,
        capture: RolloutCapture,
        episode: int,
        module: int | str,
        success: bool,
        goal: Any,
        gripper: Any,
    ) -> None:
        """One captured episode of `module` (its scene first, where the recording lacks it):
        every `rollout_stride`-th step and the last, with its goal and gripper path (`goal`
        and `gripper`: `RunRecorder.log_rollout`'s)."""
        n = capture.n_steps
        if n == 0:
            raise ValueError("the capture holds no steps: call capture.record(data) each step")
        m = int(self.modules.slots(module, 1)[0])
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
            label=f"{self.modules.labels[m]}, episode {int(episode)}: {outcome}",
            color=self.modules.rgb[m],
            goal_radius=self.settings.goal_radius,
            path_radius=self.settings.path_radius,
        )
