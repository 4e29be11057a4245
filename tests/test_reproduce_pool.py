"""How `curious reproduce` hands its runs to the pool: every run's progress and result read, no
more runs at a time than it is told, and on this machine no more than fit in its memory."""

from __future__ import annotations

import pytest

from curious.reproduction.experiments import get_budget
from curious.runs import memory
from pipelines.executors import Job, LocalPool, PartitionFailed, run_all
from pipelines.resources import OutputLayout, Reproduction
from pipelines.training import PartitionResult, run_folder


class ListingPool:
    """Trains nothing: ends one job a poll after the first, each with its budget's episodes; a
    job of the run named `fails` fails as a worker's run would."""

    description = "this process (training nothing)"
    local = True

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
        spec = self.jobs[handle].spec
        if spec.label == self.fails:
            raise OSError("simulator lost")
        folder = str(run_folder(spec, self.jobs[handle].runs_root))
        return PartitionResult(spec.partition_key, folder, "new", 24, 1, True)

    def cancel(self, handles):
        pass

    def close(self):
        pass


def test_run_all_reads_and_reports_every_run(smoke):
    """Progress reads every run folder of the jobs in flight; each run is handed to `on_done`,
    and the results come one per run, in order. A run that failed raises `PartitionFailed`
    naming it."""
    runs = get_budget("smoke").experiments["main"].runs()
    root = str(smoke.out / "runs")
    jobs = [Job(run, root) for run in runs]
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


def test_a_machine_trains_at_a_time_only_the_runs_that_fit_in_its_memory(tmp_path, monkeypatch):
    """Each run checks its own memory as it starts, not that of the runs beside it: with room
    for two and a half runs, main's six smoke runs train two at a time; on Ray the nodes' own
    memory decides."""
    budget = get_budget("smoke")
    runs = budget.experiments["main"].runs()
    one = max(
        memory._run_bytes(config, memory._suite_spec(config.variant))
        for config in (spec.config() for spec in runs)
    )

    def room_for(k: float) -> None:
        monkeypatch.setattr(memory, "available_memory", lambda: int(k * one / memory.USABLE))

    root = str(tmp_path)
    repro = Reproduction(budget, OutputLayout.at(tmp_path), lambda: LocalPool(4), {})
    room_for(2.5)
    assert repro.at_once([Job(run, root) for run in runs]) == 2
    room_for(100)
    assert repro.at_once([Job(run, root) for run in runs]) == 6
    ray_like = ListingPool()
    ray_like.local = False
    on_ray = Reproduction(budget, OutputLayout.at(tmp_path), lambda: ray_like, {})
    assert on_ray.at_once([Job(run, root) for run in runs]) is None
