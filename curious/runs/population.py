"""A population: several runs trained in one process, their rounds stepped together.

Each run is the single run's code (`curious.runs.driver.train`: its folder, trainer, tables,
checkpoints, resume and recording) in a thread of its own; what the runs share is a `Lockstep`
(`curious.envs.lockstep`), through which every run's environment copies step, so that the
copies of all runs in a round advance in one physics call. A run in a population computes what
it computes alone, episode for episode (a test checks): its random streams, networks and
copies are its own, and the lockstep changes only when its copies step, not how.

The runs may share their updates too (`updates`, an `UpdateLockstep` of
`curious.agent.update_lockstep`): the learners of the runs in their updates at the same time
then step as one stacked computation per shape of network (`curious.agent.stacked_update`), one
batched product per layer on a GPU. On a CPU each run's products stay its own and the run
computes what it computes alone, bit for bit (a test checks); a batched product rounds
differently, within float precision.

Torch runs the updates' arithmetic and MuJoCo the physics outside Python's lock, so the runs'
threads overlap where the work is; what is Python (the conditions, the replay's bookkeeping)
takes turns. `curious bench population` measures a population against the same runs in
processes side by side: the processes were faster on a 2-core CPU and on a 16-core node with a
GPU (docs/benchmarks.md), so `curious reproduce` trains one run per process unless asked.

Ctrl-C (or `stop.set()`) asks every run to stop at the end of its cycle, after a checkpoint:
`--resume` goes on from there. A run that fails leaves the locksteps; the others train to their
end, and the failures are raised together (`PopulationError`) once they have.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from curious.agent.conditions import make_condition
from curious.agent.update_lockstep import UpdateLockstep
from curious.config import Config, ConfigError
from curious.envs.goal_env import EnvSpec, GoalEnv
from curious.envs.lockstep import Lockstep
from curious.runs.driver import RunCopies, Seat, train
from curious.runs.folder import RunFolder
from curious.runs.hooks import Recorder
from curious.runs.memory import (
    SUITE_COPY_BYTES,
    USABLE,
    available_memory,
    check_population_memory,
    memory_parts,
)
from curious.runs.trainer import Trainer


class PopulationError(RuntimeError):
    """Some runs of a population failed (the others trained to their end): `failures` maps each
    failed run's folder to its error."""

    def __init__(self, failures: dict[Path, BaseException]) -> None:
        self.failures = failures
        lines = [f"{path}: {type(e).__name__}: {e}" for path, e in failures.items()]
        super().__init__(f"{len(failures)} run(s) of the population failed:\n" + "\n".join(lines))


GRAPHS_IN_THREADS = (
    "learner_backend=compiled on cuda captures each update in a CUDA graph, and torch's CUDA "
    "graphs fail (an AssertionError) when several threads of one process replay them "
    "(pytorch/pytorch#123177), as a population's runs would"
)
"""Why a population of several runs cannot take the compiled backend on a GPU (seen on an H200
node under torch 2.11, 2026-11-30: a population of three such runs failed in two of them)."""


def graphs_in_threads(configs: Sequence[Config]) -> bool:
    """Whether `configs`, trained as one population, would replay CUDA graphs in several threads
    (`GRAPHS_IN_THREADS`): more than one run, and one with the compiled backend on cuda."""
    compiled = (c.learner_backend == "compiled" and c.device == "cuda" for c in configs)
    return len(configs) > 1 and any(compiled)


def check_members(configs: Sequence[Config], outs: Sequence[str | Path]) -> list[Path]:
    """The run folders, resolved: a `ConfigError` for a population that cannot train together
    (no runs, folders and configs that do not pair up, a folder named twice, copies in worker
    processes, CUDA graphs in threads)."""
    if not configs:
        raise ConfigError("a population needs at least one run")
    if len(configs) != len(outs):
        raise ConfigError(f"{len(configs)} configs but {len(outs)} run folders")
    paths = [Path(out).resolve() for out in outs]
    if len(set(paths)) != len(paths):
        raise ConfigError("two runs of the population share one run folder")
    if any(c.processes > 1 for c in configs):
        raise ConfigError(
            "a population steps its runs' copies in this process: set env_processes=1"
        )
    if graphs_in_threads(configs):
        raise ConfigError(
            f"{GRAPHS_IN_THREADS}: train them one run per process, or set "
            "learner_backend=autograd (the default) or workspace"
        )
    return paths


def train_population(
    configs: Sequence[Config],
    outs: Sequence[str | Path],
    resume: bool | Sequence[bool] = False,
    restart: bool = False,
    make_recorder: Callable[[Trainer, RunFolder], Recorder] | None = None,
    make_envs: Callable[[Config], Sequence[GoalEnv]] | None = None,
    physics_threads: int | None = None,
    stop: threading.Event | None = None,
    stop_after_cycles: int | None = None,
    updates: UpdateLockstep | None = None,
) -> list[Trainer]:
    """Train run `configs[i]` in folder `outs[i]`, all at once in this process (the module
    docstring); `resume`, `restart`, `make_recorder`, `make_envs` and `stop_after_cycles` as
    for every run of `curious.runs.driver.train`, `resume` one flag for every run or one per run
    (a population may go on with some runs and start others). `make_recorder` tells the runs
    apart by the folder it is handed. The suite's copies of each variant step in
    one call on `physics_threads` native threads (default: one per core;
    `curious.envs.threaded.ThreadedPhysics`), or one after the other with 0 (as with
    `make_envs`, whose copies step themselves). `updates`: the lockstep the runs' learners step
    through (`curious.agent.update_lockstep.UpdateLockstep`), which computes the steps of the
    runs in their updates at the same time, one stacked step per shape of network; None (the
    default): each run's learners step alone. Every run folder and the memory of all the runs
    together are checked before any run starts. Returns the runs' trainers, in order."""
    paths = check_members(configs, outs)
    resumes = [resume] * len(configs) if isinstance(resume, bool) else list(resume)
    if len(resumes) != len(configs):
        raise ConfigError(f"{len(configs)} configs but {len(resumes)} resume flags")
    for config, path, goes_on in zip(configs, paths, resumes, strict=True):  # before any starts
        RunFolder.prepare(path, config, goes_on, restart)
    if make_envs is None:  # the suite's copies (with make_envs, each trainer checks its own)
        _check_memory(configs)
    stop = stop if stop is not None else threading.Event()
    copies = [_copies(c) if make_envs is None else None for c in configs]
    locksteps = _locksteps(configs, copies, physics_threads)
    try:
        return _train_all(
            configs, paths, copies, locksteps, resumes, restart, make_recorder, make_envs, stop,
            stop_after_cycles, updates,
        )  # fmt: skip
    finally:
        for lockstep in locksteps.values():
            lockstep.physics.close()


def _copies(config: Config) -> RunCopies:
    """A run's training copies and its test rollouts' (None without test rollouts), seeded as
    `curious.runs.driver.train` seeds them."""
    from curious.envs.goal_env import make_suite_envs

    train = make_suite_envs(config.variant, config.seed, config.n_workers)
    if not config.test_rollouts_per_worker:
        return train, None
    return train, make_suite_envs(config.variant, config.seed, config.n_workers, stream=1)


def _locksteps(
    configs: Sequence[Config], copies: Sequence[RunCopies | None], threads: int | None
) -> dict[str, Lockstep]:
    """One lockstep per variant, over the copies of every run of it (stepped one by one where
    the copies are not the suite's, or `threads` is 0)."""
    by_variant: dict[str, list[GoalEnv]] = {}
    for config, run in zip(configs, copies, strict=True):
        envs = by_variant.setdefault(config.variant, [])
        if run is not None:
            envs += [env for part in run if part is not None for env in part]
    locksteps: dict[str, Lockstep] = {}
    try:
        for variant, envs in by_variant.items():
            if envs and threads != 0:
                from curious.envs.threaded import ThreadedPhysics

                locksteps[variant] = Lockstep(ThreadedPhysics(envs, threads))
            else:
                locksteps[variant] = Lockstep()
    except BaseException:
        for lockstep in locksteps.values():
            lockstep.physics.close()
        raise
    return locksteps


def _train_all(
    configs: Sequence[Config],
    paths: Sequence[Path],
    copies: Sequence[RunCopies | None],
    locksteps: dict[str, Lockstep],
    resumes: Sequence[bool],
    restart: bool,
    make_recorder: Callable[[Trainer, RunFolder], Recorder] | None,
    make_envs: Callable[[Config], Sequence[GoalEnv]] | None,
    stop: threading.Event,
    stop_after_cycles: int | None,
    updates: UpdateLockstep | None,
) -> list[Trainer]:
    """Each run in a thread of its own; the failures raised together once every run ended."""

    def run(i: int) -> Trainer:
        seat = Seat(locksteps[configs[i].variant], i, stop, copies[i], updates)
        return train(
            configs[i], paths[i], resume=resumes[i], restart=restart, make_envs=make_envs,
            make_recorder=make_recorder, stop_after_cycles=stop_after_cycles, seat=seat,
        )  # fmt: skip

    with ThreadPoolExecutor(len(configs), thread_name_prefix="run") as pool:
        futures = [pool.submit(run, i) for i in range(len(configs))]
        try:
            for future in futures:
                future.exception()  # wait for every run, whatever happens to the others
        except KeyboardInterrupt:
            stop.set()  # each run stops after its cycle's checkpoint
            for future in futures:
                future.exception()
            raise
    failures = {paths[i]: f.exception() for i, f in enumerate(futures) if f.exception()}
    if len(failures) == 1 and len(configs) == 1:
        raise next(iter(failures.values()))  # a population of one fails as the run does
    if failures:
        raise PopulationError(failures)  # type: ignore[arg-type]
    return [f.result() for f in futures]


def _sized_runs(configs: Sequence[Config]) -> list[tuple[Config, EnvSpec, int]]:
    """Each run's (config, spec, experts), what `curious.runs.memory` sizes a run by (one suite
    copy per variant gives its spec)."""
    from curious.envs.goal_env import SuiteEnv

    specs = {variant: SuiteEnv(variant, seed=0).spec for variant in {c.variant for c in configs}}
    runs = []
    for config in configs:
        spec = specs[config.variant]
        runs.append((config, spec, make_condition(config, spec).n_experts))
    return runs


def _check_memory(configs: Sequence[Config]) -> None:
    """The memory of all the runs together."""
    check_population_memory(_sized_runs(configs), SUITE_COPY_BYTES)


def runs_that_fit(configs: Sequence[Config]) -> int:
    """How many of `configs`, taken in order, fit in this machine's memory as one population
    (`train_population` checks the same sum before it starts); at least 1, so that a run too
    big alone meets its own error."""
    need = np.cumsum(
        [
            sum(part.nbytes for part in memory_parts(*run, SUITE_COPY_BYTES))
            for run in _sized_runs(configs)
        ]
    )
    return max(1, int(np.searchsorted(need, USABLE * available_memory(), side="right")))
