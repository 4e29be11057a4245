"""Rerun recordings of training runs: per-episode scalars, rollouts in 3D, a default layout.

The training loop makes one `RunRecorder` per run and calls its `log_*` methods with batches of
arrays; rollout code fills a `RolloutCapture` from MuJoCo data each step. `curious view` opens
the resulting `recording.rrd` files (named by the run folder's format,
`curious.runs.folder_layout.RECORDING_FILE`); `curious.watching.recording.reader` reads them back.
Each name is imported from its module (`recorder.RunRecorder`, `settings.RecorderSettings`,
`scene.RolloutCapture`, ...): `settings`, which the command line's help reads, loads neither
Rerun nor MuJoCo.
"""

import os

from curious.runs.allocator import MIMALLOC_PURGE_DELAY

RERUN_LOG_FILTER = (
    "warn,re_log_encoding::rrd::file_sink=off,re_log_encoding::rrd::encoder=off,"
    "re_sdk::recording_stream=off"
)
"""Rerun's own log lines kept (its `RUST_LOG` filter, read once, when rerun is imported; a
`RUST_LOG` set by the user wins): warnings and errors, except those of its file writer and of
the recording stream about its sinks, which say in Rerun's terms what `curious` reports itself
in one line, naming the file (a full disk:
`curious.watching.recording.rrd_files.RecordingWriteError`)."""
os.environ.setdefault("RUST_LOG", RERUN_LOG_FILTER)
os.environ.setdefault("MIMALLOC_PURGE_DELAY", MIMALLOC_PURGE_DELAY)  # read when rerun loads
