"""Rollouts of a training run in 3D: a round observer that captures evaluation episodes.

`RolloutObserver` is a `Trainer.observer` (`curious.runs.hooks.RoundObserver`). In each round of
parallel
episodes it picks the evaluation episodes that the recorder wants in 3D (`rollout_due` of the
episode's evaluation count), copies the body poses out of those environments' MuJoCo physics at
every step into a preallocated `RolloutCapture`, together with the grip site (the gripper
position every module uses) and the active module's goal in the world frame (goals set in a
cube's frame follow that cube), and hands each finished episode, with its final success, to
`RunRecorder.log_rollout` at the end of the round. Rounds without such an episode cost one
comparison per episode.

Evaluation episodes are those with `episode % eval_every == eval_every - 1`, so an episode's
evaluation count is `episode // eval_every`: it is the same in a resumed run as in one that was
never interrupted. (The `her` condition has no self-evaluations; its episodes at those places,
which explore, are captured instead, so that its runs have rollouts to look at too.)

The observer hands every call on to `inner` (another observer), so observers chain.

    observer = attach_rollout_recording(trainer, recorder)   # trainer.observer now records
    train(config, out, make_recorder=recorder_factory(resume))   # what `curious train` does
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from curious.watching.recording.scene import RolloutCapture

__all__ = ["RolloutObserver", "attach_rollout_recording", "recorder_factory"]


@dataclass
class _Slot:
    """One environment copy's capture buffers (kept across rounds, rebuilt on a new model)."""

    capture: RolloutCapture
    grip_site: int  # site id of the grip site in the capture's model
    gripper: np.ndarray  # (T + 1, 3) grip-site positions
    goal: np.ndarray  # (T + 1, 3) the active module's goal in the world frame


@dataclass
class _Active:
    """An episode being captured in the current round."""

    worker: int  # position of its environment in the round
    episode: int
    module: int
    env: Any
    slot: _Slot | None = None  # set after the reset (t = 0)
    physics: Any = None
    task: Any = None


def _suite_parts(env: Any) -> tuple[Any, Any]:
    """(physics, task) of a suite environment copy; a clear error for anything else."""
    dm_env = getattr(env, "dm_env", None)
    if dm_env is None:
        raise TypeError(
            f"{type(env).__name__} is not a suite environment: 3-D rollouts read the MuJoCo "
            "physics of curious.envs.goal_env.SuiteEnv copies"
        )
    return dm_env.physics, dm_env.task


class RolloutObserver:
    """A `Trainer` round observer that records due evaluation episodes in 3D.

    Args:
        recorder: the run's recorder; needs `rollout_due(eval_index)` and `log_rollout(...)`
            (`curious.watching.recording.recorder.RunRecorder`).
        eval_every: the run's `Config.eval_every` (every eval_every-th episode is an evaluation).
        episode_length: steps per episode (the capture holds episode_length + 1 rows).
        inner: another observer that gets every call after this one, or None.
    """

    def __init__(
        self, recorder: Any, eval_every: int, episode_length: int, inner: Any = None
    ) -> None:
        if eval_every < 1:
            raise ValueError(f"eval_every must be >= 1, got {eval_every}")
        if episode_length < 1:
            raise ValueError(f"episode_length must be >= 1, got {episode_length}")
        self.recorder = recorder
        self.eval_every = int(eval_every)
        self.rows = int(episode_length) + 1
        self.inner = inner
        self._slots: dict[int, _Slot] = {}
        self._active: list[_Active] = []
        self.logged = 0  # rollouts handed to the recorder so far

    def _slot(self, worker: int, physics: Any, task: Any) -> _Slot:
        model = physics.model.ptr
        slot = self._slots.get(worker)
        if slot is None or slot.capture.model is not model:
            site = int(physics.bind(task.robot.grip_site).element_id)
            slot = _Slot(
                capture=RolloutCapture(model, self.rows),
                grip_site=site,
                gripper=np.zeros((self.rows, 3)),
                goal=np.zeros((self.rows, 3)),
            )
            self._slots[worker] = slot
        return slot

    def _due(self, episodes: np.ndarray, evaluation: np.ndarray) -> list[int]:
        """Positions in the round of the evaluation episodes due for a 3-D capture. The
        episodes are those of the evaluation schedule, which are the self-evaluations, except
        in `her`, which has none: its exploring episodes in their places are captured."""
        episodes = np.asarray(episodes)
        scheduled = episodes % self.eval_every == self.eval_every - 1
        return [
            int(i)
            for i in np.flatnonzero(scheduled)
            if self.recorder.rollout_due(int(episodes[i]) // self.eval_every)
        ]

    def watched(self, episodes: np.ndarray, evaluation: np.ndarray) -> list[int]:
        """The copies whose simulators this round's captures read (and the inner observer's)."""
        mine = self._due(episodes, evaluation)
        if self.inner is not None:
            mine = sorted(set(mine) | set(self.inner.watched(episodes, evaluation)))
        return mine

    def begin_round(
        self,
        episodes: np.ndarray,
        modules: np.ndarray,
        goals: np.ndarray,
        evaluation: np.ndarray,
        envs: Sequence[Any],
    ) -> None:
        """Chooses the round's episodes to capture (evaluations whose count is due)."""
        self._active = []
        for i in self._due(episodes, evaluation):
            _suite_parts(envs[i])  # fails here, before the round runs, for other envs
            self._active.append(_Active(i, int(episodes[i]), int(modules[i]), envs[i]))
        if self.inner is not None:
            self.inner.begin_round(episodes, modules, goals, evaluation, envs)

    def after_step(self, t: int) -> None:
        """Copies the captured episodes' poses, grip site and goal of step t (0 = after reset)."""
        for a in self._active:
            if t == 0:
                # Read after the reset: a composer env may build a new physics when it resets.
                a.physics, a.task = _suite_parts(a.env)
                a.slot = self._slot(a.worker, a.physics, a.task)
                a.slot.capture.reset()
            data = a.physics.data
            a.slot.capture.record(data)
            a.slot.gripper[t] = data.site_xpos[a.slot.grip_site]
            a.slot.goal[t] = a.task.goal_positions()[a.module]
        if self.inner is not None:
            self.inner.after_step(t)

    def end_round(self, info: Any) -> None:
        """Logs every captured episode with its final success."""
        for a in self._active:
            if a.slot is None or a.slot.capture.n_steps == 0:
                continue  # the round ended before its first step
            n = a.slot.capture.n_steps
            self.recorder.log_rollout(
                a.episode,
                a.module,
                a.slot.capture,
                goal=a.slot.goal[:n],
                gripper=a.slot.gripper[:n],
                success=bool(info.success[a.worker]),
            )
            self.logged += 1
        self._active = []
        if self.inner is not None:
            self.inner.end_round(info)


def attach_rollout_recording(trainer: Any, recorder: Any) -> RolloutObserver:
    """Installs a `RolloutObserver` on `trainer`, chaining the observer it already has."""
    observer = RolloutObserver(
        recorder,
        trainer.config.eval_every,
        trainer.spec.episode_length,
        inner=trainer.observer,
    )
    trainer.observer = observer
    return observer


def recorder_factory(
    resume: bool,
    settings: Any = None,
    spawn: bool = False,
    run_name: str | None = None,
    connect: str | None = None,
) -> Callable[[Any, Any], Any]:
    """The `make_recorder` hook of `curious.runs.driver.train`: a run's `RunRecorder`, with the
    observer that records evaluation episodes in 3D installed when `settings.rollout_every > 0`;
    `spawn` and `connect` also stream it live (`RunRecorder`'s).

    `curious train` and the reproduction pipeline both record their runs through it.
    """
    from curious.watching.recording.recorder import RecorderSettings, RunRecorder

    settings = settings if settings is not None else RecorderSettings()

    def make(trainer: Any, folder: Any) -> RunRecorder:
        # A run killed before its first checkpoint starts over, its recording too.
        resumed = resume and trainer.episodes > 0
        recorder = RunRecorder(
            folder.path,
            trainer.spec.module_names,
            settings=settings,
            run_name=run_name,
            spawn=spawn,
            connect=connect,
            resume=resumed,
            resume_from_episode=trainer.episodes if resumed else None,
        )
        if recorder.started_over:
            _rebuild(recorder, trainer, folder)
        if settings.rollout_every > 0:
            attach_rollout_recording(trainer, recorder)
        return recorder

    return make


def _rebuild(recorder: Any, trainer: Any, folder: Any) -> None:
    """A resumed run's recording that was missing or unreadable, rebuilt from its tables
    (`curious.watching.recording.resume.rebuild_from_tables`), with a warning naming each series
    the tables do not hold from the run's start, and the episode of its first point."""
    import pyarrow.parquet as pq

    from curious.runs.metrics import metrics_schema, tests_schema
    from curious.watching.recording.resume import rebuild_from_tables

    def read(path: Any, schema: Any) -> Any:
        return pq.read_table(path) if path.exists() else schema.empty_table()

    metrics = read(folder.metrics_path, metrics_schema(trainer.spec.module_names))
    tests = read(folder.tests_path, tests_schema())
    episodes = trainer.episodes
    learner, learner_from = _learner_table(folder.learner_path, episodes)
    logged = rebuild_from_tables(
        recorder, metrics, tests, episodes, trainer.config.episodes_per_cycle, learner
    )
    restarts = restart_episodes(
        trainer.config, recorder.settings.rollout_every, episodes, learner_from
    )
    lacking = "; ".join(
        f"{what} ({', '.join(f'{p}...' for p in prefixes)}) "
        + (f"at episode {first:,}" if first is not None else "not again: the run has ended")
        for what, prefixes, first in restarts
    )
    names = [folder.metrics_path.name, folder.tests_path.name]
    names += [folder.learner_path.name] if learner is not None else []
    warnings.warn(
        f"{recorder.path} had no readable recording to resume: its series of episodes 0 to "
        f"{episodes - 1:,} were rebuilt from {', '.join(names[:-1])} and {names[-1]} "
        f"({logged:,} episodes)"
        + (f"; what those tables do not hold from the run's start begins later: {lacking}"
           if lacking else ""),
        RuntimeWarning,
        stacklevel=3,
    )  # fmt: skip


def _learner_table(path: Any, episodes: int) -> tuple[Any, int | None]:
    """`learner.parquet` at `path` (None where there is none or it cannot be read), and where
    its series begin in a recording rebuilt at `episodes` (`restart_episodes`' `learner_from`):
    None where the table reaches back to the run's start, else its first row up to `episodes`,
    or -1 where it has none."""
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    from curious.runs.metrics import learner_begins

    try:
        table = pq.read_table(path) if path.exists() else None
    except (OSError, ValueError):  # the run sets it aside as it starts (`LearnerLog`)
        table = None
    if table is None:
        return None, -1
    if learner_begins(table.schema) == 0:
        return table, None
    kept = table.filter(pc.less_equal(table["episode"], episodes))
    return table, (int(pc.min(kept["episode"]).as_py()) if kept.num_rows else -1)


def restart_episodes(
    config: Any, rollout_every: int, episodes: int, learner_from: int | None = -1
) -> list[tuple[str, tuple[str, ...], int | None]]:
    """The series that a recording rebuilt from the tables at `episodes` lacks from the run's
    start, each as (what, its entity prefixes, the episode of its first point, None where the
    run has no episode left to record it at): the 3-D rollouts (no table holds them) at the
    first evaluation episode due for one from `episodes` on (every `rollout_every`-th
    evaluation); the replay shares and learner statistics unless `learner.parquet` holds them
    from the run's start (`learner_from` None), at `learner_from` where its rows begin later,
    else (-1: no rows) at the end of the first cycle resumed (they are logged once a cycle, at
    the count after it). A series the run never records (no updates, `rollout_every` 0) is
    left out."""
    from curious.watching.recording.resume import IN_LEARNER_TABLE

    total, every = config.total_episodes, config.eval_every
    restarts: list[tuple[str, tuple[str, ...], int | None]] = []
    if config.n_updates > 0 and learner_from is not None:
        cycle_end = min(episodes + config.episodes_per_cycle, total)
        resumed = cycle_end if episodes < total else None
        first = learner_from if learner_from >= 0 else resumed
        restarts.append(("the replay shares and learner statistics", IN_LEARNER_TABLE, first))
    if rollout_every > 0:
        evaluation = -(-(episodes // every) // rollout_every) * rollout_every  # the first due
        rollout = evaluation * every + every - 1
        restarts.append(("the 3-D rollouts", ("scene/",), rollout if rollout < total else None))
    return restarts
