"""What a training run calls outside itself: a recorder after every cycle, an observer around
every round of parallel episodes. Both are optional; `curious.watching.recording` implements them.

A `Recorder` (e.g. `curious.watching.recording.recorder.RunRecorder`) is called by
`curious.runs.driver.train` after every cycle, with B the cycle's episodes and N the modules:

    recorder.log_episodes(episode=(B,), module=(B,) slot indices, success=(B,), eval=(B,),
                          competence=(B, N), lp=(B, N), p_lp=(B, N), wall_time=(B,))
    recorder.log_tests(episode, module=(K,), success=(K,), wall_time)   # an epoch's K tests
    recorder.log_replay(episode, counts, wall_time)   # (N,) modules of the replayed transitions
    recorder.log_learner(episode, losses={"critic", "actor"}, q={"target_mean"}, wall_time)
    recorder.checkpoint()                    # before every checkpoint: make it durable
    recorder.close()                         # once, when training stops
    recorder.close_after_error()             # instead, when an error stops it

The replay counts and learner statistics come from the cycle's row of `learner.parquet`
(`log_learner_rows`), which a recording rebuilt from the run's tables hands over the same way.

A `RoundObserver` set as `Trainer.observer` (e.g. one that captures MuJoCo body poses for 3-D
rollouts) is called by the `Trainer` around every round of parallel training episodes:

    observer.watched(episodes, evaluation)   # the copies whose simulators it will read
    observer.begin_round(episodes, modules, goals, evaluation, envs)   # before the resets
    observer.after_step(t)                   # t = 0 after the resets, then 1..T after each step
    observer.end_round(info)                 # RolloutInfo: states, outcomes, actions, success
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from curious.envs.goal_env import GoalEnv
from curious.envs.rollout import EpisodeData
from curious.runs.metrics import LEARNER_STATS


class Recorder(Protocol):
    """What `curious.runs.driver.train` logs to after every cycle (see the module docstring);
    `curious.watching.recording.recorder.RunRecorder` is one."""

    def log_episodes(
        self,
        episode: np.ndarray,
        module: np.ndarray,
        success: np.ndarray,
        eval: np.ndarray,
        competence: np.ndarray,
        lp: np.ndarray,
        p_lp: np.ndarray,
        wall_time: np.ndarray,
    ) -> None: ...

    def log_tests(
        self, episode: int, module: np.ndarray, success: np.ndarray, wall_time: float
    ) -> None: ...

    def log_replay(self, episode: int, counts: np.ndarray, wall_time: float) -> None: ...

    def log_learner(
        self, episode: int, losses: dict[str, float], q: dict[str, float], wall_time: float
    ) -> None: ...

    def checkpoint(self) -> None:
        """Make what was logged so far durable (called before every training checkpoint)."""

    def close(self) -> None: ...

    def close_after_error(self) -> None:
        """Close when an error stopped training, never raising over that error."""


def log_learner_rows(recorder: Recorder, rows: Mapping[str, np.ndarray]) -> None:
    """Hand rows of `learner.parquet` (`curious.runs.metrics.LearnerLog`, as columns) to a
    recorder, each at its episode: the replay counts where any transition was replayed, the
    learner statistics where the cycle had updates."""
    replay = [np.asarray(values) for name, values in rows.items() if name.startswith("replay/")]
    counts = np.column_stack(replay) if replay else np.zeros((len(rows["episode"]), 0), np.int64)
    for i, episode in enumerate(np.asarray(rows["episode"]).tolist()):
        wall = float(rows["wall_time"][i])
        if counts[i].sum() > 0:
            recorder.log_replay(episode, counts[i], wall)
        groups: dict[str, dict[str, float]] = {"losses": {}, "q": {}}
        for column, (group, name) in LEARNER_STATS.items():
            value = float(rows[column][i])
            if not math.isnan(value):
                groups[group][name] = value
        if groups["losses"] or groups["q"]:
            recorder.log_learner(episode, groups["losses"], groups["q"], wall)


class RoundObserver(Protocol):
    """Called around every round of parallel episodes (see the module docstring)."""

    def watched(self, episodes: np.ndarray, evaluation: np.ndarray) -> Sequence[int]:
        """The copies (positions in the round) whose simulators it will read this round."""
        ...

    def begin_round(
        self,
        episodes: np.ndarray,
        modules: np.ndarray,
        goals: np.ndarray,
        evaluation: np.ndarray,
        envs: Sequence[GoalEnv],
    ) -> None: ...

    def after_step(self, t: int) -> None: ...

    def end_round(self, info: RolloutInfo) -> None: ...


@dataclass
class RolloutInfo:
    """One round of parallel episodes, for recorders that show rollouts."""

    episodes: np.ndarray  # (n,) global episode indices
    modules: np.ndarray  # (n,) module index practised or evaluated
    raw_goals: np.ndarray  # (n, 3) goals in [-1, 1]^3
    goals: np.ndarray  # (n, N, G) goal slots given to the policy
    evaluation: np.ndarray  # (n,) bool
    success: np.ndarray  # (n,) bool, final success of the module
    data: EpisodeData  # states, achieved outcomes, actions
    sensor_failure: np.ndarray  # (n,) bool, episodes run with the sensory failure
