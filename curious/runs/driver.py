"""A training run in a run folder: `train()` runs a `curious.runs.trainer.Trainer` cycle after
cycle.

It prepares the folder (`curious.runs.folder`), builds the environment copies (the training
ones and the test rollouts' own), appends each cycle's rows to `metrics.parquet`,
`tests.parquet` and `learner.parquet`, writes a checkpoint every `checkpoint_every_cycles`
cycles (with no rounds in flight) and at the end, resumes from the newest one (`resume=True`,
after `resume_checks`), shows a progress bar and hands every cycle to an optional recorder
(`curious.runs.hooks.Recorder`). `curious train` and the reproduction pipeline call it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pyarrow.compute as pc

from curious.agent.conditions import Condition
from curious.config import Config, ConfigError
from curious.envs.batch import EnvBatch, LocalEnvs, ProcessEnvs
from curious.envs.goal_env import GoalEnv, suite_env_fns
from curious.runs import checkpoint
from curious.runs.allocator import return_freed_memory
from curious.runs.folder import RunFolder
from curious.runs.folder_errors import RunFolderError
from curious.runs.folder_lock import folder_lock
from curious.runs.hooks import Recorder, log_learner_rows
from curious.runs.memory import SUITE_COPY_BYTES, checked_condition
from curious.runs.metrics import LearnerLog, MetricsLog, TableLog, TestsLog
from curious.runs.trainer import CycleResult, Trainer


def train(
    config: Config,
    out: str | Path,
    resume: bool = False,
    make_envs: Callable[[Config], Sequence[GoalEnv]] | None = None,
    make_recorder: Callable[[Trainer, RunFolder], Recorder] | None = None,
    stop_after_cycles: int | None = None,
    restart: bool = False,
    stop: Callable[[], bool] | None = None,
    position: int | None = None,
) -> Trainer:
    """Train `config` in the run folder `out` (created, continued with `resume=True`, or started
    over with `restart=True`, which removes the run the folder held once every check passed).

    `make_envs(config)` builds the `n_workers` environment copies (default: the suite variant
    `config.variant`); it is called a second time for the test rollouts' copies (the default
    seeds those from a stream of their own). `make_recorder(trainer, folder)`, called once the
    folder is ready (and a resumed trainer is at its checkpoint's episode), returns the recorder
    the loop logs to.
    `stop_after_cycles` ends this call early (after a checkpoint), which is how tests interrupt
    a run. Errors about the folder, the checkpoint or what the run needs (memory) are raised
    before anything in the folder is written (`resume_checks` says what a resume refuses);
    while it trains, the folder is locked against a second process (`RunFolderBusy`).
    `stop()`, asked after every cycle, ends the run at the end of that cycle, after a
    checkpoint (how `curious train --seeds` stops its runs on Ctrl-C); `position` is the line of
    its progress bar among several runs' bars.
    """
    return_freed_memory()  # a long run's heap would otherwise grow with memory it freed
    with folder_lock(out):
        folder = RunFolder.prepare(out, config, resume, restart)
        envs, test_envs, condition = _environments(config, make_envs)
        trainer = Trainer(config, envs, test_envs, condition)
        with contextlib.closing(trainer):  # the environment workers stop
            return _run(
                trainer, folder, resume, restart, make_recorder, stop_after_cycles, stop, position
            )


def _environments(
    config: Config, make_envs: Callable[[Config], Sequence[GoalEnv]] | None
) -> tuple[EnvBatch, EnvBatch | None, Condition]:
    """The training copies and the test rollouts' copies of a run (see `train`), and the run's
    condition from `checked_condition`: with the suite's copies, on one copy's spec before the
    others are built or their workers started, so that the memory check counts them."""
    tests_wanted = config.test_rollouts_per_worker > 0
    if config.processes > 1 and make_envs is not None:
        raise ConfigError(
            "env_processes > 1 builds the suite's environments in worker processes; a custom "
            "make_envs runs in this process (env_processes=1)"
        )
    if make_envs is not None:
        envs = LocalEnvs(make_envs(config))
        tests = LocalEnvs(make_envs(config)) if tests_wanted else None
        return envs, tests, checked_condition(config, envs.spec)

    train_fns = suite_env_fns(config.variant, config.seed, config.n_workers)
    test_fns = suite_env_fns(config.variant, config.seed, config.n_workers, stream=1)
    # One copy first: its spec sizes the run, checked before the others are built.
    first = (test_fns if tests_wanted else train_fns)[0]()
    condition = checked_condition(config, first.spec, SUITE_COPY_BYTES)
    if config.processes > 1:
        # The test copies step in worker processes too: stepped in this process, a `paper`
        # epoch's 190 test rollouts took about 8 s, a third of its 950 training episodes'
        # 24 s (16 cores and an H100, 2026-11-26; docs/scaling.md).
        train = ProcessEnvs(train_fns, config.processes)
        if not tests_wanted:
            return train, None, condition
        try:
            return train, ProcessEnvs(test_fns, config.processes), condition
        except BaseException:
            train.close()
            raise
    if tests_wanted:
        tests = LocalEnvs([first, *(fn() for fn in test_fns[1:])])  # stepped once an epoch
        return LocalEnvs([fn() for fn in train_fns]), tests, condition
    return LocalEnvs([first, *(fn() for fn in train_fns[1:])]), None, condition


def resume_checks(
    trainer: Trainer,
    folder: RunFolder,
    metrics: TableLog,
    tests: TableLog,
    from_checkpoint: bool,
) -> None:
    """Refuse (`RunFolderError`) a resume that would lose or leave out part of the run.

    Without a checkpoint, a run starts over from episode 0: right for a run stopped before its
    first checkpoint was written (its rows, at most one checkpoint interval, are redone as rows
    after any checkpoint are), but a folder holding more rows than that had checkpoints, which
    were removed, and starting over would replace the whole run. With one, the tables must hold
    every row the checkpoint's own counters say the run wrote (a deleted or older
    metrics.parquet or tests.parquet would leave a gap)."""
    config, episodes = trainer.config, trainer.episodes
    if not from_checkpoint:
        interval = config.checkpoint_every_cycles * config.episodes_per_cycle
        if metrics.n_rows > interval:
            kept = [f"{metrics.n_rows:,} episodes in {metrics.path.name}"]
            kept += [f"{tests.n_rows:,} test rollouts in {tests.path.name}"] if tests.n_rows else []
            kept += [folder.recording_path.name] if folder.recording_path.exists() else []
            raise RunFolderError(
                f"cannot resume {folder.path}: no checkpoint is left in {folder.checkpoints}, so "
                f"the run would start over from episode 0 and replace {', '.join(kept)}; "
                "restore the checkpoints, or pass --restart instead of --resume to start the "
                "run over"
            )
        return
    if metrics.n_rows < episodes:
        raise RunFolderError(
            f"{folder.metrics_path} holds {metrics.n_rows:,} rows but the checkpoint is at "
            f"episode {episodes:,}: the run's rows are missing, so going on would leave a gap; "
            "restore metrics.parquet, or start the run over with --restart"
        )
    # Test rollouts ran after every finished epoch, n_workers x test_rollouts_per_worker each.
    epochs = trainer.cycles // config.n_cycles
    expected = epochs * config.n_workers * config.test_rollouts_per_worker
    table = tests.table()
    have = int(pc.sum(pc.less_equal(table["episode"], episodes)).as_py() or 0)
    if have < expected:
        raise RunFolderError(
            f"{folder.tests_path} holds {have:,} test rollouts up to episode {episodes:,}, but the "
            f"run had run {expected:,} by its checkpoint ({epochs:,} epochs): they are missing, "
            "so going on would leave the run without them; restore tests.parquet, or start the "
            "run over with --restart"
        )


def _load_latest(trainer: Trainer, folder: RunFolder) -> Path | None:
    """Load the run's newest readable checkpoint into `trainer`; its path, None without one.

    The checkpoint's replay is read into the trainer's own replay arrays (where it was written
    as segments: every replay that never evicted an episode), and what was read is let go on
    return: a second copy, held while loading or for the rest of the run, would be as large as
    the replay at the checkpoint (a 300,000-episode run's is 4.64 GiB, 6.02 GiB on
    `distractors_7`: docs/agent.md)."""
    latest = checkpoint.load_latest(
        folder.checkpoints, trainer.agent.device, into=trainer.replay.load_room()
    )
    if latest is None:
        return None
    path, state, replay = latest
    trainer.load_state_dict(state, replay)  # raises on another config, before any write
    trainer.last_checkpoint = path
    return path


def _run(
    trainer: Trainer,
    folder: RunFolder,
    resume: bool,
    restart: bool,
    make_recorder: Callable[[Trainer, RunFolder], Recorder] | None,
    stop_after_cycles: int | None,
    stop: Callable[[], bool] | None = None,
    position: int | None = None,
) -> Trainer:
    from tqdm.auto import tqdm  # it picks notebook or console bars, and warns, when imported

    config = trainer.config
    latest = _load_latest(trainer, folder) if resume else None
    tables: list[TableLog] = []
    if resume:  # read before anything is written: a bad table is an error with nothing changed
        tables = [MetricsLog(folder.metrics_path, trainer.spec.module_names)]
        tables.append(TestsLog(folder.tests_path))
        resume_checks(trainer, folder, *tables, from_checkpoint=latest is not None)

    if restart:
        folder.clear()
    folder.write_config(config, trainer.spec)
    checkpoint.remove_partial(folder.checkpoints)
    checkpoint.prune(folder.checkpoints, spare=latest)
    if not tables:
        tables = [MetricsLog(folder.metrics_path, trainer.spec.module_names)]
        tables.append(TestsLog(folder.tests_path))
    metrics, tests = tables
    learner = LearnerLog(folder.learner_path, trainer.spec.module_names, trainer.episodes)
    for table in (*tables, learner):
        if table.n_rows:
            rows_before = table.n_rows
            table.truncate(trainer.episodes)  # rows logged after the checkpoint are redone
            if table.n_rows != rows_before:
                table.flush()

    recorder = make_recorder(trainer, folder) if make_recorder is not None else None
    bar = tqdm(
        total=config.total_episodes,
        initial=trainer.episodes,
        unit="ep",
        disable=not config.progress,
        dynamic_ncols=True,
        desc=f"{config.condition} seed {config.seed}",
        position=position,
    )
    cycles_here = 0
    try:
        while not trainer.done:
            every = config.checkpoint_every_cycles
            stopping = stop is not None and stop()
            drain = (
                (trainer.cycles + 1) % every == 0
                or stopping
                or (stop_after_cycles is not None and cycles_here + 1 >= stop_after_cycles)
            )
            result = trainer.cycle(drain=drain)
            cycles_here += 1
            metrics.append(result.rows)
            if result.tests is not None:
                tests.append(result.tests)
            row = learner.append_cycle(
                trainer.episodes, result.replay_counts, result.losses, trainer.wall_time()
            )
            if recorder is not None and len(result.module_index):
                _log_cycle(recorder, result, row)
            bar.update(len(result.rows.get("episode", ())))
            bar.set_postfix(_progress_text(trainer), refresh=False)
            stop_now = stopping or (
                stop_after_cycles is not None and cycles_here >= stop_after_cycles
            )
            if trainer.done or stop_now or trainer.cycles % config.checkpoint_every_cycles == 0:
                trainer.ensure_finite()  # a diverged run writes none of this checkpoint
                metrics.flush()
                if config.test_rollouts_per_worker:
                    tests.flush()
                learner.flush()
                if recorder is not None:
                    recorder.checkpoint()
                trainer.save_checkpoint(folder.checkpoints)
            if stop_now:
                break
    except BaseException:
        if recorder is not None:
            recorder.close_after_error()  # never hides the error that stopped training
        raise
    finally:
        bar.close()
    if recorder is not None:
        recorder.close()
    return trainer


def _log_cycle(recorder: Recorder, result: CycleResult, learner: dict | None) -> None:
    """Hand one cycle to a recorder (the calls: `curious.runs.hooks`); `learner`: the cycle's
    row of `learner.parquet` (None: no updates)."""
    rows = result.rows
    recorder.log_episodes(
        episode=rows["episode"],
        module=result.module_index,
        success=rows["success"],
        eval=rows["eval"],
        competence=result.competence,
        lp=result.lp,
        p_lp=result.p_lp,
        wall_time=rows["wall_time"],
    )
    if result.tests is not None:
        tests = result.tests
        recorder.log_tests(
            int(tests["episode"][0]), tests["module"], tests["success"], tests["wall_time"][0]
        )
    if learner is not None:
        log_learner_rows(recorder, learner)


def _progress_text(trainer: Trainer) -> dict[str, str]:
    """The progress bar's text: mean competence over the achievable modules and p_LP."""
    spec = trainer.spec
    if not trainer.condition.self_evaluates:
        return {}  # no competence to show (her)
    competence = trainer.tracker.competence()
    achievable = np.array(spec.achievable, bool)
    success = competence[achievable].mean() if achievable.any() else float("nan")
    p = trainer.condition.practice_probs(trainer.tracker, trainer.epoch)
    short = [name.replace("cube", "c").replace("_", "") for name in spec.module_names]
    p_text = " ".join(f"{name}:{v:.2f}" for name, v in zip(short, p, strict=True))
    return {"success": f"{success:.2f}", "p_LP": p_text}
