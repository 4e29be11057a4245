"""Where a run's recording goes, and the life of the file it is written to.

One stream per run, with its own recording id, written to a working file beside the recording
(`.recording.rrd.part`), and also streamed to a live viewer where one is asked for. `checkpoint()`,
which `train()` calls before every checkpoint, flushes it and copies it over `recording.rrd`
atomically, and `close()` writes the final, compacted `recording.rrd` (the file helpers are in
`curious.watching.recording.rrd_files`). So `recording.rrd` always holds a whole recording, up to
the last checkpoint of a run killed at any moment, which a resumed run starts from
(`curious.watching.recording.resume`). A write that fails (a full disk) never replaces
`recording.rrd` (`curious.watching.recording.rrd_files.end_file`).
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rerun as rr

from curious.runs.folder_layout import RECORDING_FILE
from curious.watching.display import has_display
from curious.watching.recording.blueprint import default_blueprint
from curious.watching.recording.rrd_files import (
    RecordingWriteError,
    compact_recording,
    disconnect,
    end_file,
    flush_to_file,
    has_room_for,
    replace_with_copy,
)

__all__ = ["APPLICATION_ID", "DEFAULT_VIEWER_PORT", "WORKING_FILENAME", "WorkingFile"]

APPLICATION_ID = "curious"
WORKING_FILENAME = f".{RECORDING_FILE}.part"
"""The file a running recorder writes; `recording.rrd` is its copy at the last checkpoint."""
DEFAULT_VIEWER_PORT = 9876


class WorkingFile:
    """A recording stream writing the working file beside `path` (and to viewers, if asked).

    Args:
        path: the recording, `recording.rrd` in the run folder.
        recording_id: the stream's recording id.
        n_modules: the run's module count (the default layout's panels).
        run_name: the name the viewer shows for the recording.
        spawn, connect, viewer_port: the live viewers (`RunRecorder`'s arguments).
    """

    def __init__(
        self,
        path: Path,
        recording_id: str,
        n_modules: int,
        *,
        run_name: str,
        spawn: bool,
        connect: str | None,
        viewer_port: int,
    ) -> None:
        self.path = path
        self.working = path.with_name(WORKING_FILENAME)
        self.stream = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
        sinks: list[Any] = [rr.FileSink(str(self.working))]
        if spawn:
            if has_display():
                self.stream.spawn(port=viewer_port, connect=False)
                sinks.append(rr.GrpcSink(f"rerun+http://127.0.0.1:{viewer_port}/proxy"))
            else:
                warnings.warn(
                    "no display (DISPLAY/WAYLAND_DISPLAY unset): not spawning a viewer; the "
                    f"recording is still written to {self.path}. Open it on a machine with a "
                    f"display with `rerun {self.path}`, or start `rerun --serve-web --bind "
                    "127.0.0.1` here and pass its gRPC url with `curious train --connect` "
                    "(`connect=` in Python).",
                    RuntimeWarning,
                    stacklevel=3,
                )
        if connect:
            sinks.append(rr.GrpcSink(connect))
        self.live = len(sinks) > 1
        self.blueprint = default_blueprint(n_modules)
        self.stream.set_sinks(*sinks, default_blueprint=self.blueprint)
        self.stream.send_recording_name(run_name)
        self.closed = False
        self.write_failed = False

    def check_open(self) -> None:
        """Raises where the recording is closed already."""
        if self.closed:
            raise RuntimeError(f"recorder for {self.path} is closed")

    def flush(self) -> None:
        """Blocks until everything sent so far is in the working file."""
        try:
            flush_to_file(self.stream, self.working)
        except RecordingWriteError:
            self.write_failed = True
            raise

    def checkpoint(self) -> None:
        """Copies the flushed working file over the recording, atomically."""
        replace_with_copy(self.working, self.path)

    def close(self, pending: Callable[[], None], compact: bool) -> None:
        """Sends what is `pending`, ends the working file and makes it the recording, with its
        chunks merged when `compact` and there is room for a second copy (else as written, with
        a warning). A write that fails raises, and leaves the recording as at the checkpoint."""
        self.closed = True
        try:
            pending()
            end_file(self.stream, self.working)
        except BaseException:
            self._abandon()
            raise
        size = self.working.stat().st_size
        if compact and has_room_for(self.working, size):
            try:
                compact_recording(self.working, self.path, self.blueprint)
            except (OSError, RuntimeError) as exc:  # the recording is whole without it
                warnings.warn(
                    f"{self.path} was not compacted ({exc}); it holds the whole recording, "
                    "uncompacted",
                    RuntimeWarning,
                    stacklevel=3,
                )
            else:
                self.working.unlink()
                return
        os.replace(self.working, self.path)

    def close_after_error(self, pending: Callable[[], None]) -> None:
        """Sends what is `pending` and makes the working file the recording, uncompacted, never
        raising: where that cannot be written, or a write failed before (a full disk, a live
        viewer gone), the recording stays as at the checkpoint. A sink that failed once may or
        may not take a later flush, so the file is not trusted after it."""
        self.closed = True
        if self.write_failed:
            self._abandon()
            return
        try:
            pending()
            end_file(self.stream, self.working, timeout=60.0)
            os.replace(self.working, self.path)
        except Exception:
            self._abandon()

    def _abandon(self) -> None:
        """Disconnects the sink and removes the working file (not whole: a write failed)."""
        with contextlib.suppress(Exception):
            disconnect(self.stream)
        with contextlib.suppress(OSError):
            self.working.unlink(missing_ok=True)
