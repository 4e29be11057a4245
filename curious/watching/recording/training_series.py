"""The scalar series of a training run, from the batches the training loop hands over: each
episode's module and success, the module statistics (`module_statistics`), test success rates,
replay shares and learner statistics, and the static names, colours and styles the viewer draws
them with.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import rerun as rr

from curious.watching.recording.module_statistics import STATS, ModuleStatistics
from curious.watching.recording.recorded_modules import RecordedModules, as_1d
from curious.watching.recording.rrd_files import PreviousRecording
from curious.watching.recording.scalar_series import ScalarSeries

__all__ = ["TrainingSeries"]


class TrainingSeries:
    """Turns the training loop's batches into scalar rows (the arguments of `RunRecorder`'s
    `log_episodes`, `log_tests`, `log_replay` and `log_learner`)."""

    def __init__(
        self,
        stream: rr.RecordingStream,
        modules: RecordedModules,
        scalars: ScalarSeries,
        stats: ModuleStatistics,
    ) -> None:
        self.stream = stream
        self.modules = modules
        self.scalars = scalars
        self.stats = stats
        self._styled: set[str] = set()
        """Learner series whose static style is logged (they are named by the learner)."""

    def take_over(self, previous: PreviousRecording) -> None:
        """The learner series a resumed recording has styled already."""
        self._styled = {e for e in previous.static_entities if e.startswith(("losses/", "q/"))}

    def log_styles(self) -> None:
        """Static names, colours and styles of every per-module series."""
        log = self.stream.log
        step = "StepAfter" if self.stats.settings.stats_on_change else "Linear"
        for m, name in enumerate(self.modules.entities):
            color, label = self.modules.rgb[m], self.modules.labels[m]
            for kind in STATS:
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

    def log_episodes(
        self,
        episode: Any,
        module: Any,
        success: Any,
        is_eval: Any,
        stats: Mapping[str, Any],
        wall_time: Any,
    ) -> None:
        """A batch of finished episodes; `stats` maps each of `STATS` to its (B, n_modules)
        values."""
        episodes = as_1d("episode", episode, None, np.int64)
        n = episodes.shape[0]
        if n == 0:
            return
        wall = self.scalars.wall(wall_time, n)
        modules = self.modules.slots(module, n)
        succ = as_1d("success", success, n).astype(bool)
        evaluation = as_1d("eval", is_eval, n).astype(bool)
        values = {kind: self.modules.per_module(kind, stats[kind], n) for kind in STATS}
        for m, name in enumerate(self.modules.entities):
            mine = modules == m
            rows = np.flatnonzero(mine)
            if rows.size:
                self.scalars.add(
                    f"module/{name}", episodes[rows], wall[rows], np.full(rows.size, float(m))
                )
            for split, mask in (("eval", mine & evaluation), ("train", mine & ~evaluation)):
                rows = np.flatnonzero(mask)
                if rows.size:
                    self.scalars.add(
                        f"success/{split}/{name}",
                        episodes[rows],
                        wall[rows],
                        succ[rows].astype(np.float64),
                    )
        self.stats.log(episodes, wall, values)
        self.scalars.maybe_send()

    def log_tests(self, episode: int, module: Any, success: Any, wall_time: Any) -> None:
        """One epoch's test rollouts, as each tested module's success rate at `episode`."""
        succ = as_1d("success", success, None).astype(np.float64)
        modules = self.modules.slots(module, succ.shape[0])
        counts = np.bincount(modules, minlength=len(self.modules))
        rates = np.bincount(modules, weights=succ, minlength=len(self.modules))
        wall = self.scalars.wall(wall_time, 1)
        for m in np.flatnonzero(counts):
            self.scalars.add(
                f"test/{self.modules.entities[m]}",
                np.array([episode], np.int64),
                wall,
                np.array([rates[m] / counts[m]]),
            )
        self.scalars.maybe_send()

    def log_replay(self, episode: Any, counts: Any, wall_time: Any) -> None:
        """The replay composition, each row normalised to shares."""
        episodes = as_1d("episode", episode, None, np.int64)
        n = episodes.shape[0]
        arr = self.modules.per_module("counts", counts, n)
        if np.any(arr < 0):
            raise ValueError("replay counts must be non-negative")
        total = arr.sum(axis=1, keepdims=True)
        shares = np.divide(arr, total, out=np.zeros_like(arr), where=total > 0)
        wall = self.scalars.wall(wall_time, n)
        for m, name in enumerate(self.modules.entities):
            self.scalars.add(f"replay/{name}", episodes, wall, shares[:, m])
        self.scalars.maybe_send()

    def log_learner(
        self,
        episode: Any,
        groups: Mapping[str, Mapping[str, Any]],
        wall_time: Any,
    ) -> None:
        """Learner statistics, `groups` mapping `losses` and `q` to name -> values, under
        `<group>/<name>` (styled where first seen)."""
        episodes = as_1d("episode", episode, None, np.int64)
        n = episodes.shape[0]
        wall = self.scalars.wall(wall_time, n)
        for group, stats in groups.items():
            for name, values in stats.items():
                path = f"{group}/{name}"
                if path not in self._styled:
                    self.stream.log(path, rr.SeriesLines(names=[f"{group} {name}"]), static=True)
                    self._styled.add(path)
                self.scalars.add(path, episodes, wall, as_1d(path, values, n, np.float64))
        self.scalars.maybe_send()
