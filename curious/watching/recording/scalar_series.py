"""Scalar series sent in large chunks, and the run's clock that times their rows.

Rows are buffered per entity and sent with `send_columns` every `flush_rows` rows or
`flush_seconds` (`live_flush_seconds` while a viewer watches), and whenever the recording is
flushed: each send is one chunk per entity in the file, and a chunk costs ~1.2 kB whatever its
length. The rows are indexed on two timelines: `episode` (the global episode index, a sequence)
and `wall_time` (seconds since the run started, a duration).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import rerun as rr

from curious.watching.recording.recorded_modules import as_1d
from curious.watching.recording.settings import RecorderSettings

__all__ = ["ScalarSeries"]


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


class ScalarSeries:
    """Buffers scalar rows of any entity and sends them to `stream` in large chunks.

    Args:
        stream: the recording they go to.
        settings: the buffer's limits (`flush_rows`, `flush_seconds`, `live_flush_seconds`).
        live: whether a viewer watches (the shorter interval then applies).
        start: the wall time of the run at this moment, in seconds (where a resumed recording
            ends), from which the clock goes on.
    """

    def __init__(
        self,
        stream: rr.RecordingStream,
        settings: RecorderSettings,
        live: bool,
        start: float = 0.0,
    ) -> None:
        self.stream = stream
        self.settings = settings
        self.live = live
        now = time.perf_counter()
        self._t0 = now - start
        self._last_send = now
        self._buffer = _ScalarBuffer()

    def continue_clock(self, seconds: float) -> None:
        """The clock reads `seconds` now and goes on from there."""
        self._t0 = time.perf_counter() - seconds

    def wall(self, wall_time: Any, n: int) -> np.ndarray:
        """(n,) wall times: `wall_time` checked, or the clock now for every row."""
        if wall_time is None:
            return np.full(n, time.perf_counter() - self._t0)
        return as_1d("wall_time", wall_time, n, np.float64)

    def add(self, path: str, episodes: np.ndarray, wall: np.ndarray, values: Any) -> None:
        """Queues scalar rows of one entity; `maybe_send` sends them in large chunks."""
        self._buffer.add(path, episodes, wall, np.asarray(values, dtype=np.float64))

    def maybe_send(self) -> None:
        """Sends the buffer when it holds `flush_rows` rows or waited its interval."""
        interval = self.settings.live_flush_seconds if self.live else self.settings.flush_seconds
        now = time.perf_counter()
        if self._buffer.rows >= self.settings.flush_rows or now - self._last_send >= interval:
            self.send()

    def send(self) -> None:
        """Sends every buffered row, one chunk per entity."""
        for path, episodes, wall, values in self._buffer.drain():
            self.stream.send_columns(
                path,
                indexes=[
                    rr.TimeColumn("episode", sequence=episodes),
                    rr.TimeColumn("wall_time", duration=wall),
                ],
                columns=rr.Scalars.columns(scalars=values),
            )
        self._last_send = time.perf_counter()
