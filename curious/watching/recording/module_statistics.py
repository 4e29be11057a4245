"""Each module's competence, LP and p_LP as series (`competence/<module>`, `lp/<module>`,
`p_lp/<module>`), written where they change.

A module's statistics change only on its own evaluation episodes, so with
`RecorderSettings.stats_on_change` a row is written only where its value changes (drawn as
steps), again every `stats_keyframe_every` episodes while it holds, so that a live view draws a
held value up to the present, and once more at the run's latest episode when the recording
closes (`finish`). Without it every episode's row is written.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from curious.watching.recording.recorded_modules import RecordedModules
from curious.watching.recording.resume import take_held_values
from curious.watching.recording.rrd_files import PreviousRecording
from curious.watching.recording.scalar_series import ScalarSeries
from curious.watching.recording.settings import RecorderSettings

__all__ = ["STATS", "ModuleStatistics"]

STATS = ("competence", "lp", "p_lp")
"""The statistics of a module, each the first part of its series' entity path."""

_NO_EPISODE = np.iinfo(np.int64).min


class ModuleStatistics:
    """Writes the statistics of every module into `scalars`, remembering what each series
    holds: its last value, the episode it was last written at, and where the run stands."""

    def __init__(
        self, modules: RecordedModules, settings: RecorderSettings, scalars: ScalarSeries
    ) -> None:
        self.modules = modules
        self.settings = settings
        self.scalars = scalars
        n = len(modules)
        self._last = {k: np.full(n, np.nan) for k in STATS}
        self._logged_until = {k: np.full(n, _NO_EPISODE, dtype=np.int64) for k in STATS}
        self.latest_episode = _NO_EPISODE
        """The latest episode logged, where `finish` carries the held values to."""
        self.last_wall = 0.0
        """Its wall time."""

    def take_over(self, previous: PreviousRecording) -> None:
        """Goes on from a resumed recording: where it ends, and each series' held value."""
        self.last_wall = previous.last_wall
        episodes = [e for path, e in previous.max_episode.items() if path.startswith("module/")]
        if episodes:
            self.latest_episode = max(episodes)
        if not self.settings.stats_on_change:
            return
        entities = self.modules.entities
        paths = [f"{kind}/{name}" for kind in STATS for name in entities]
        held = take_held_values(previous, paths, self.settings.stats_keyframe_every)
        for kind in STATS:
            for m, name in enumerate(entities):
                if f"{kind}/{name}" in held:
                    episode, value = held[f"{kind}/{name}"]
                    self._logged_until[kind][m] = episode
                    self._last[kind][m] = value

    def log(self, episodes: np.ndarray, wall: np.ndarray, stats: Mapping[str, np.ndarray]) -> None:
        """A batch of episodes' statistics (`STATS` -> (B, n_modules) values)."""
        for kind, values in stats.items():
            self._log_kind(kind, episodes, wall, values)
        self.latest_episode = max(self.latest_episode, int(episodes.max()))
        self.last_wall = float(wall[-1])

    def _log_kind(
        self, kind: str, episodes: np.ndarray, wall: np.ndarray, values: np.ndarray
    ) -> None:
        """One statistic for a batch: every row, or only the rows where it changed (and
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
        for m, name in enumerate(self.modules.entities):
            rows = np.flatnonzero(keep[:, m])
            if rows.size:
                self.scalars.add(f"{kind}/{name}", episodes[rows], wall[rows], values[rows, m])
                self._logged_until[kind][m] = episodes[rows[-1]]
        self._last[kind] = values[-1].copy()

    def finish(self) -> None:
        """Carries each held value to the latest episode (written where they change only)."""
        if not self.settings.stats_on_change or self.latest_episode == _NO_EPISODE:
            return
        ep = np.array([self.latest_episode], dtype=np.int64)
        wall = np.array([self.last_wall])
        for kind in STATS:
            for m, name in enumerate(self.modules.entities):
                if self._logged_until[kind][m] < self.latest_episode:
                    self.scalars.add(f"{kind}/{name}", ep, wall, self._last[kind][m : m + 1])
