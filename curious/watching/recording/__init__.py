"""Rerun recordings of training runs: per-episode scalars, rollouts in 3D, a default layout.

The training loop makes one `RunRecorder` per run and calls its `log_*` methods with batches of
arrays; rollout code fills a `RolloutCapture` from MuJoCo data each step. `curious view` opens
the resulting `recording.rrd` files (named by the run folder's format,
`curious.runs.folder.RECORDING_FILE`); `curious.watching.recording.reader` reads them back.
"""

from curious.watching.recording.blueprint import default_blueprint
from curious.watching.recording.recorder import (
    APPLICATION_ID,
    RecorderSettings,
    RunRecorder,
    compact_recording,
)
from curious.watching.recording.scene import RolloutCapture, SceneLayout, wxyz_to_xyzw

__all__ = [
    "APPLICATION_ID",
    "RecorderSettings",
    "RolloutCapture",
    "RunRecorder",
    "SceneLayout",
    "compact_recording",
    "default_blueprint",
    "wxyz_to_xyzw",
]
