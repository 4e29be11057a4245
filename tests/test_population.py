"""A population: several runs trained in one process, their copies stepped in lockstep."""

from __future__ import annotations

import json
import pickle
import shutil
import threading
import time

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
import torch
from pipeline_pools import InterruptingPool, OrderPool
from test_agent_runs import assert_same_state

from curious.agent.update_lockstep import UpdateLockstep, stack_alike
from curious.cli import main
from curious.config import ConfigError, resolve
from curious.envs.goal_env import make_suite_envs
from curious.envs.lockstep import Lockstep, OneByOne
from curious.envs.threaded import ThreadedPhysics
from curious.reproduction.experiments import get_budget
from curious.runs import checkpoint
from curious.runs.driver import train
from curious.runs.folder_lock import folder_lock
from curious.runs.population import PopulationError, train_population
from curious.watching.recording import RecorderSettings
from pipelines.executors import Job, LocalPool, PartitionFailed, run_all
from pipelines.reproduce import reproduce
from pipelines.resources import OutputLayout, Reproduction
from pipelines.training import (
    FINISHED,
    PartitionResult,
    RunsFailed,
    folder_state,
    run_folder,
    run_group,
    run_partition,
)

SMALL = dict(total_episodes=24, progress=False)
MEMBERS = [("curious", 0), ("mg-te", 1), ("her", 2)]


def _table(path):
    return pq.read_table(path).drop(["wall_time"]).to_pandas()


def _assert_same_table(a, b):
    pd.testing.assert_frame_equal(_table(a), _table(b))  # NaN (her's competence) equals NaN


def _state(folder):
    _, state, replay = checkpoint.load_latest(folder / "checkpoints")
    return state, replay


def _assert_same(a, b, where=""):
    """Equal nested states: tensors and arrays bit for bit, timings and torch's global generator
    left out."""
    assert_same_state(a, b, where, uncompared=("elapsed", "torch_rng"))


@pytest.fixture(scope="module")
def alone(tmp_path_factory):
    """The members, each trained alone: what a population must write."""
    root = tmp_path_factory.mktemp("alone")
    outs = [root / f"{c}-{s}" for c, s in MEMBERS]
    for (condition, seed), out in zip(MEMBERS, outs, strict=True):
        train(resolve("smoke", condition, seed, SMALL), out)
    return outs


def _assert_same_runs(alone, together):
    for a, b in zip(alone, together, strict=True):
        for name in ("metrics.parquet", "tests.parquet"):
            _assert_same_table(a / name, b / name)
        _assert_same(_state(a), _state(b), b.name)


@pytest.mark.parametrize("physics_threads", [2, 0], ids=["threaded", "one-by-one"])
def test_a_run_trained_in_a_population_is_the_run_trained_alone(
    alone, tmp_path, monkeypatch, physics_threads
):
    """Three runs (three conditions, three seeds) trained together in one process write the
    same episodes, test rollouts, networks, optimisers, queues and replay as each alone,
    whether their copies step in MuJoCo's threads or one by one: the lockstep changes when
    their copies step, not how."""
    configs = [resolve("smoke", c, s, SMALL) for c, s in MEMBERS]
    together = [tmp_path / f"{c}-{s}" for c, s in MEMBERS]
    groups_per_call = []
    physics = ThreadedPhysics if physics_threads else OneByOne
    step = physics.step

    def counting(self, groups):
        groups_per_call.append(len(groups))
        return step(self, groups)

    monkeypatch.setattr(physics, "step", counting)
    trainers = train_population(configs, together, physics_threads=physics_threads)
    assert [t.episodes for t in trainers] == [24, 24, 24]
    assert max(groups_per_call) > 1  # some calls stepped several runs' copies
    _assert_same_runs(alone, together)


def test_a_population_with_stacked_updates_is_each_run_alone(alone, tmp_path):
    """With their updates stacked (an `UpdateLockstep`), the runs still write what each writes
    alone: on a CPU each run's products stay its own."""
    configs = [resolve("smoke", c, s, SMALL) for c, s in MEMBERS]
    stacked = [tmp_path / f"{c}-{s}" for c, s in MEMBERS]
    stacks = []

    def slow_stacking(handed):  # slow calls, so that the other runs join the next one
        stacks.append(len(handed))
        time.sleep(0.02)
        return stack_alike(handed)

    train_population(configs, stacked, updates=UpdateLockstep(slow_stacking))
    assert max(stacks) > 1  # some calls stepped several runs' learners
    _assert_same_runs(alone, stacked)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_on_cuda_a_population_is_each_run_alone_and_stacked_updates_finish_every_run(tmp_path):
    """With the networks on a GPU: runs trained together, each learner stepping alone, write
    what each writes alone on that GPU, bit for bit (the same kernels on the same shapes); with
    their updates stacked (batched products, float rounding apart) every run trains to its end
    and writes as many episodes and test rollouts as alone."""
    cuda = dict(SMALL, device="cuda")
    configs = [resolve("smoke", c, s, cuda) for c, s in MEMBERS]
    alone = [tmp_path / "alone" / f"{c}-{s}" for c, s in MEMBERS]
    for config, out in zip(configs, alone, strict=True):
        train(config, out)
    together = [tmp_path / "together" / f"{c}-{s}" for c, s in MEMBERS]
    train_population(configs, together)
    _assert_same_runs(alone, together)
    stacked = [tmp_path / "stacked" / f"{c}-{s}" for c, s in MEMBERS]
    trainers = train_population(configs, stacked, updates=UpdateLockstep())
    assert [t.episodes for t in trainers] == [24, 24, 24]
    for a, b in zip(alone, stacked, strict=True):
        for name in ("metrics.parquet", "tests.parquet"):
            assert len(_table(b / name)) == len(_table(a / name))


def test_a_population_resumes_from_its_runs_checkpoints(tmp_path):
    """Stopped after two cycles and resumed, a population (one run with the sensory failure
    from episode 8) ends where it ends uninterrupted."""
    failing = {**SMALL, "variant": "sensor_failure", "sensor_failure_episode": 8}
    configs = [resolve("smoke", "mg-te", 1, SMALL), resolve("smoke", "curious", 0, failing)]
    straight = [tmp_path / "straight" / str(i) for i in range(2)]
    resumed = [tmp_path / "resumed" / str(i) for i in range(2)]
    train_population(configs, straight)
    first = train_population(configs, resumed, stop_after_cycles=2)
    assert all(0 < t.episodes < 24 for t in first)
    train_population(configs, resumed, resume=True)
    assert _table(resumed[1] / "metrics.parquet")["sensor_failure"].any()
    for a, b in zip(straight, resumed, strict=True):
        _assert_same_table(a / "metrics.parquet", b / "metrics.parquet")
        _assert_same(_state(a), _state(b))


def test_a_stop_request_ends_every_run_at_a_checkpoint(tmp_path):
    """`stop` set while the runs train: each ends after its cycle, with a checkpoint there."""
    configs = [resolve("smoke", "curious", s, SMALL) for s in (0, 1)]
    stop = threading.Event()
    stop.set()  # asked before the first cycle ends: every run stops after one cycle
    trainers = train_population(configs, [tmp_path / "a", tmp_path / "b"], stop=stop)
    for trainer, out in zip(trainers, ("a", "b"), strict=True):
        assert trainer.episodes == configs[0].episodes_per_cycle
        found = checkpoint.load_latest(tmp_path / out / "checkpoints")
        assert found is not None and found[1]["episodes"] == trainer.episodes


@pytest.mark.parametrize("stacked_updates", [False, True])
def test_a_failing_run_does_not_stop_the_others(tmp_path, stacked_updates):
    """A run whose copies fail leaves the locksteps; the other trains to its end, and the
    failure is raised with its folder once it has."""
    configs = [resolve("smoke", "curious", s, SMALL) for s in (0, 1)]
    bad = tmp_path / "bad"

    def make_envs(config):
        envs = make_suite_envs(config.variant, config.seed, config.n_workers)
        if config.seed == 1:
            envs[0].step = lambda action: (_ for _ in ()).throw(OSError("simulator lost"))
        return envs

    with pytest.raises(PopulationError, match="simulator lost") as caught:
        updates = UpdateLockstep() if stacked_updates else None
        train_population(configs, [tmp_path / "good", bad], make_envs=make_envs, updates=updates)
    assert list(caught.value.failures) == [bad.resolve()]
    assert len(_table(tmp_path / "good" / "metrics.parquet")) == 24


@pytest.mark.parametrize(
    ("outs", "message"),
    [(["a", "a"], "share one run folder"), (["a"], "2 configs but 1 run folders")],
)
def test_a_population_that_cannot_train_together_is_refused(tmp_path, outs, message):
    configs = [resolve("smoke", "curious", s, SMALL) for s in (0, 1)]
    with pytest.raises(ConfigError, match=message):
        train_population(configs, [tmp_path / o for o in outs])


def test_a_population_of_compiled_cuda_learners_is_refused_before_anything_is_written(tmp_path):
    """torch's CUDA graphs assert when several threads replay them (pytorch/pytorch#123177): a
    population of three `compiled` runs on cuda failed in two of them on an H200 node. Refused
    with the reason before a folder is made; one such run, or compiled runs on a CPU, train."""
    from curious.runs.population import check_members

    on_gpu = {**SMALL, "learner_backend": "compiled", "device": "cuda"}
    configs = [resolve("smoke", "curious", s, on_gpu) for s in (0, 1)]
    with pytest.raises(ConfigError, match=r"pytorch/pytorch#123177.*one run per process"):
        train_population(configs, [tmp_path / "a", tmp_path / "b"])
    assert list(tmp_path.iterdir()) == []
    assert check_members(configs[:1], [tmp_path / "a"])  # alone, a run is not in threads
    on_cpu = [resolve("smoke", "curious", s, {**on_gpu, "device": "cpu"}) for s in (0, 1)]
    assert check_members(on_cpu, [tmp_path / "a", tmp_path / "b"])


def test_a_lane_refuses_steps_outside_a_round_and_bad_actions():
    lane = Lockstep().lane(make_suite_envs("default", 0, 2))
    with pytest.raises(RuntimeError, match="reset it first"):
        lane.step(np.zeros((2, lane.spec.action_dim)))
    lane.reset(np.zeros(2, int), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="need"):
        lane.step(np.zeros((3, lane.spec.action_dim)))


def test_train_seeds_trains_a_population_into_seed_folders(tmp_path, capsys):
    """`curious train --seeds 0-1`: one run folder per seed under --out, a line per run; a bad
    seed list is one line and exit status 2, nothing written. `--stack-updates` trains the same
    runs, and needs `--seeds`."""
    out = tmp_path / "curious"
    short = ["--set", "total_episodes=8"]  # two cycles: what matters here is where they go
    argv = ["train", "--preset", "smoke", "--out", str(out), "--no-record", "--no-progress"]
    assert main([*argv, *short, "--seeds", "0-1"]) == 0
    printed = capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["seed-0", "seed-1"]
    assert f"8 episodes in {out / 'seed-1'}" in printed
    assert main([*argv, "--seeds", "2-x"]) == 2
    assert "write them as 0-4 or 0,2,5" in capsys.readouterr().err
    assert main([*argv, "--seeds", "0,3-1"]) == 2
    assert "seeds '0,3-1': a range runs upwards (1-3)" in capsys.readouterr().err
    assert main([*argv, "--seeds", "4294967295-4294967296"]) == 2  # named as --seeds
    assert "seeds '4294967295-4294967296': each must be from 0 to 4,294,967,295" in (
        capsys.readouterr().err
    )
    assert main([*argv, "--seeds", "0-1"]) == 2  # the folders hold runs: nothing trains
    assert "is not empty" in capsys.readouterr().err
    stacked = ["train", "--preset", "smoke", "--no-record", "--no-progress", "--stack-updates"]
    assert main([*stacked, "--out", str(tmp_path / "one"), "--seed", "0"]) == 2
    assert "name --seeds" in capsys.readouterr().err
    assert main([*stacked, *short, "--out", str(tmp_path / "stacked"), "--seeds", "0-1"]) == 0
    metrics = "seed-1/metrics.parquet"
    _assert_same_table(out / metrics, tmp_path / "stacked" / metrics)
    single = out / "seed-0"  # a run folder: a population is not nested in it
    before = sorted(p.name for p in single.iterdir())
    assert main([*argv[:3], "--out", str(single), *argv[5:], "--seeds", "0-1"]) == 2
    assert "holds a run (config.json)" in capsys.readouterr().err
    assert sorted(p.name for p in single.iterdir()) == before


def test_a_population_records_each_run_as_alone(tmp_path):
    """Recorded in a population (their copies stepped in MuJoCo's threads, the 3-D rollouts
    read from the copies' own simulators), two runs of different variants write recordings
    that hold the same points as each run recorded alone."""
    from curious.watching.recording.reader import read_points  # rerun: only where recorded
    from curious.watching.recording.rollout_capture import recorder_factory

    configs = [
        resolve("smoke", "m-uvfa", 3, SMALL),
        resolve("smoke", "curious", 0, {**SMALL, "variant": "distractors_4"}),
    ]
    record = recorder_factory(False, RecorderSettings(rollout_every=1))
    alone = [tmp_path / "alone" / str(i) for i in range(2)]
    for config, out in zip(configs, alone, strict=True):
        train(config, out, make_recorder=record)
    together = [tmp_path / "together" / str(i) for i in range(2)]
    train_population(configs, together, make_recorder=record, physics_threads=2)
    for a, b in zip(alone, together, strict=True):
        points_a, static_a = read_points(a / "recording.rrd")
        points_b, static_b = read_points(b / "recording.rrd")
        assert any(entity.startswith("scene/") for entity, _ in points_a)  # 3-D rollouts
        assert points_a == points_b and static_a == static_b


# ------------------------------------------------------------------ populations in `reproduce`


@pytest.mark.slow
def test_reproduce_in_populations_goes_on_where_it_stopped_and_trains_each_run_as_alone(
    smoke, tmp_path, capsys
):
    """Main's six smoke runs three to a population, stopped part-way (the first population
    finished, a run of the second partial, two not started), then gone on with `curious
    reproduce --population 2` in worker processes: the finished runs are left as they are, the
    partial run resumes in a population beside a new one, and every run folder holds what the
    same run holds trained alone, one run per process (the smoke reproduction's)."""
    out, pool = tmp_path / "out", InterruptingPool()
    with pytest.raises(KeyboardInterrupt):
        reproduce(
            "smoke", ["main"], out=out, make_pool=lambda: pool, record=False, progress=False,
            say=lambda _: None, population=3,
        )  # fmt: skip
    runs = get_budget("smoke").experiments["main"].runs()
    root = out / "runs"
    assert [len(job.specs) for job in pool.jobs] == [3, 3]
    assert [folder_state(s, root) for s in runs] == 3 * ["finished"] + ["partial", "new", "new"]
    kept = {p: p.stat().st_mtime_ns for s in runs[:3] for p in run_folder(s, root).rglob("*")}

    argv = ["reproduce", "--budget", "smoke", "--experiments", "main", "--out", str(out)]
    assert main([*argv, "--population", "2", "--no-record", "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert "main: 3 run(s) already finished, not retrained" in err
    assert "main: curious seed 1: resumed, 24 episodes" in err
    assert "main: her seed 1: 24 episodes" in err  # every run of every population is reported
    assert "main: 3 run(s) in 2 populations trained" in err
    assert {p: p.stat().st_mtime_ns for p in kept} == kept
    resumed = json.loads((run_folder(runs[3], root) / "config.json").read_text())["resumed"]
    assert len(resumed) == 1  # went on from its checkpoint
    alone = [run_folder(s, smoke.out / "runs") for s in runs]
    _assert_same_runs(alone, [run_folder(s, root) for s in runs])


class ListingPool:
    """Trains nothing: ends one job a poll after the first, each run with its budget's episodes;
    a job naming `fails` fails as a worker's population with that run failed would."""

    description = "this process (training nothing)"
    largest_group = None

    def __init__(self, fails: str | None = None) -> None:
        self.jobs: list = []
        self.fails = fails
        self.polls = 0

    def submit(self, job):
        self.jobs.append(job)
        return len(self.jobs) - 1

    def wait(self, handles, timeout):
        self.polls += 1
        if self.polls == 1:
            return [], list(handles)  # the first poll: every job in flight
        return list(handles[:1]), list(handles[1:])

    def result(self, handle):
        job = self.jobs[handle]
        if any(s.label == self.fails for s in job.specs):
            raise RunsFailed(f"{self.fails} failed: OSError: simulator lost")
        return tuple(
            PartitionResult(s.partition_key, str(run_folder(s, job.runs_root)), "new", 24, 1, True)
            for s in job.specs
        )

    def cancel(self, handles):
        pass

    def close(self):
        pass


def test_run_all_reads_and_reports_every_run_of_every_population(smoke):
    """Progress reads every run folder of every job in flight; each run is handed to `on_done`
    as a job of its own, and the results come one per run, in order. A population whose run
    failed raises `PartitionFailed` naming that run."""
    runs = get_budget("smoke").experiments["main"].runs()
    root = str(smoke.out / "runs")
    jobs = [Job(tuple(runs[:2]), root), Job(tuple(runs[2:5]), root), Job(runs[5], root)]
    seen, done = [], []
    results = run_all(
        ListingPool(), jobs, lambda n, total: seen.append((n, total)),
        lambda job, result: done.append((job.spec.label, result.partition_key)),
    )  # fmt: skip
    assert seen[0] == (6 * 24, 6 * 24)  # read from the six folders before any job ended
    assert done == [(s.label, s.partition_key) for s in runs]
    assert [r.partition_key for r in results] == [s.partition_key for s in runs]
    with pytest.raises(PartitionFailed, match=r"^main: her seed 0 failed: OSError: simulator lost"):
        run_all(ListingPool(fails="main: her seed 0"), jobs)


def test_run_all_hands_the_pool_no_more_jobs_at_a_time_than_it_is_told(tmp_path):
    """With `at_once=2`, six jobs go to the pool two at a time, the next as one ends; every
    run's result still comes, in order."""
    runs = get_budget("smoke").experiments["main"].runs()
    jobs = [Job(run, str(tmp_path)) for run in runs]
    pool = ListingPool()
    in_flight = []
    wait = pool.wait

    def counting(handles, timeout):
        in_flight.append(len(handles))
        return wait(handles, timeout)

    pool.wait = counting
    results = run_all(pool, jobs, poll_seconds=0, at_once=2)
    assert max(in_flight) == 2 and len(pool.jobs) == 6
    assert [r.partition_key for r in results] == [s.partition_key for s in runs]


def _room_for_runs(runs, monkeypatch):
    """`room_for(k)` makes this machine's available memory that of k of the largest of `runs`,
    as `curious.runs.population.runs_that_fit` reads it."""
    from curious.runs import population
    from curious.runs.memory import SUITE_COPY_BYTES, USABLE, memory_parts

    one = max(
        sum(p.nbytes for p in memory_parts(*run, SUITE_COPY_BYTES))
        for run in population._sized_runs([spec.config() for spec in runs])
    )

    def room_for(k: float) -> None:
        monkeypatch.setattr(population, "available_memory", lambda: int(k * one / USABLE))

    return room_for


def test_a_machine_trains_at_a_time_only_the_runs_that_fit_in_its_memory(tmp_path, monkeypatch):
    """Each run checks its own memory as it starts, not that of the runs beside it: with room
    for two and a half runs, main's six smoke runs train two at a time, a population of two
    alone; on Ray the nodes' own memory decides."""
    budget = get_budget("smoke")
    runs = budget.experiments["main"].runs()
    room_for = _room_for_runs(runs, monkeypatch)
    room_for(2.5)
    repro = Reproduction(budget, OutputLayout.at(tmp_path), lambda: LocalPool(4), {})
    root = str(tmp_path)
    assert repro.at_once([Job(run, root) for run in runs]) == 2
    assert repro.at_once([Job(tuple(runs[i : i + 2]), root) for i in (0, 2, 4)]) == 1
    room_for(100)
    assert repro.at_once([Job(run, root) for run in runs]) == 6
    ray_like = ListingPool()
    ray_like.largest_group = 2
    on_ray = Reproduction(budget, OutputLayout.at(tmp_path), lambda: ray_like, {})
    assert on_ray.at_once([Job(run, root) for run in runs]) is None


def test_a_population_of_a_reproduction_goes_on_with_each_run_as_its_folder_says(smoke, tmp_path):
    """One population over a finished run, a partial one and a new one: the finished run is
    left as it is, the partial one resumes and the new one starts, each recorded as alone;
    every run ends as the same run trained alone, one run per process (the smoke
    reproduction's)."""
    from curious.watching.recording.reader import read_points  # rerun: only where recorded

    finished, partial, new = get_budget("smoke").experiments["main"].runs()[:3]
    shutil.copytree(run_folder(finished, smoke.out / "runs"), run_folder(finished, tmp_path))
    run_partition(partial, tmp_path, stop_after_cycles=1)
    kept = {p: p.stat().st_mtime_ns for p in run_folder(finished, tmp_path).rglob("*")}
    results = run_group((finished, partial, new), tmp_path)
    assert [(r.state_before, r.trained, r.episodes) for r in results] == [
        ("finished", False, 24), ("partial", True, 24), ("new", True, 24),
    ]  # fmt: skip
    assert {p: p.stat().st_mtime_ns for p in kept} == kept
    specs = (finished, partial, new)
    alone = [run_folder(s, smoke.out / "runs") for s in specs]
    _assert_same_runs(alone, [run_folder(s, tmp_path) for s in specs])
    recorded = read_points(run_folder(new, tmp_path) / "recording.rrd")
    assert recorded == read_points(alone[2] / "recording.rrd")
    assert (run_folder(partial, tmp_path) / "recording.rrd").is_file()


def test_a_failing_run_of_a_population_is_named_and_the_others_train(tmp_path):
    """A run of a population that cannot train (another process trains its folder) fails with
    its name, in an error that crosses from a worker process as it is; the population's other
    run trains to its end."""
    good, busy = get_budget("smoke").experiments["sensor_failure"].runs()
    with folder_lock(run_folder(busy, tmp_path)):  # as another process training it holds it
        with pytest.raises(RunsFailed, match=rf"^{busy.label} failed: RunFolderBusy") as caught:
            run_group((good, busy), tmp_path, record=False)
    assert str(pickle.loads(pickle.dumps(caught.value))) == str(caught.value)
    assert folder_state(good, tmp_path) == FINISHED


def test_reproduce_sends_the_runs_in_populations_in_the_budgets_order(tmp_path):
    """`population=4` over main's six runs: two jobs, seed by seed, the second the rest."""
    pool = OrderPool()
    with pytest.raises(KeyboardInterrupt):
        reproduce(
            "smoke", ["main"], out=tmp_path / "out", make_pool=lambda: pool, say=lambda _: None,
            population=4,
        )  # fmt: skip
    order = [f"main/{c}/seed-{s}" for s in (0, 1) for c in ("curious", "mg-te", "her")]
    assert pool.sent == [order[:4], order[4:]]


def test_the_default_is_one_run_per_process_on_cpus_and_gpus_and_a_population_given_is_kept(
    tmp_path,
):
    """One run a process by default, where the networks train on a CPU or on a GPU (on a GPU
    node fifteen processes trained 2.2-3.2 x the episodes of one population of fifteen,
    docs/benchmarks.md), locally and on Ray; a population given is kept."""
    budget = get_budget("smoke")
    runs = budget.experiments["main"].runs()  # 6

    def size(pool, population=None, **overrides) -> int:
        layout = OutputLayout.at(tmp_path)
        repro = Reproduction(budget, layout, lambda: pool, overrides, population=population)
        return repro.population_size(runs)

    ray_like = ListingPool()
    ray_like.largest_group = 2
    assert size(LocalPool(4)) == 1
    assert size(LocalPool(1), device="cuda") == 1
    assert size(ray_like, device="cuda") == 1
    assert size(LocalPool(4), population=5) == 5
    assert size(ray_like, population=2) == 2


def test_a_population_given_holds_no_more_runs_than_fit_in_memory(tmp_path, monkeypatch):
    """With room for two and a half runs, `--population 6` on this machine trains main's six
    smoke runs in populations of two (`runs_that_fit`), not one population that the memory
    check refuses."""
    budget = get_budget("smoke")
    runs = budget.experiments["main"].runs()
    room_for = _room_for_runs(runs, monkeypatch)
    room_for(2.5)
    layout = OutputLayout.at(tmp_path)
    repro = Reproduction(budget, layout, lambda: LocalPool(1), {"device": "cuda"}, population=6)
    assert repro.population_size(runs) == 2
    room_for(0.5)
    assert repro.population_size(runs) == 1  # a run too big alone meets its own error


def test_reproduce_refuses_a_population_it_cannot_train(tmp_path, capsys):
    """A population below 1, or beside copies stepped in worker processes, is one line and
    exit status 2, nothing written; --from-data trains nothing, so it takes none."""
    out = tmp_path / "out"
    argv = ["reproduce", "--budget", "smoke", "--out", str(out), "--no-progress"]
    assert main([*argv, "--population", "0"]) == 2
    assert "--population must be >= 1, got 0" in capsys.readouterr().err
    assert main([*argv, "--population", "2", "--set", "env_processes=2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "leave out --set env_processes" in err
    assert not out.exists()
    assert main(["reproduce", "--from-data", str(out), "--population", "2"]) == 2
    assert "--from-data trains nothing, so --population" in capsys.readouterr().err
