"""A run whose Ray node or worker process was lost is submitted again, a bounded number of times,
from its last checkpoint; a run that fails for its own reason is not (`pipelines.executors`).
The pools here train nothing; tests/test_ray_lost_node.py kills a real node."""

from __future__ import annotations

import threading

import pytest

from curious.reproduction.experiments import get_budget
from curious.runs.folder_layout import checkpoint_name
from curious.runs.folder_lock import folder_lock
from pipelines import executors
from pipelines.executors import Job, PartitionFailed, lost_worker, run_all, run_job
from pipelines.resources import OutputLayout, Reproduction
from pipelines.training import PartitionResult, RunFolderBusy, run_folder

ray = pytest.importorskip("ray")

NODE_DIED = ray.exceptions.NodeDiedError(
    "Task failed because the node it was running on is dead or unavailable. Node IP: "
    "127.0.0.1, node ID: 55d739affebf0123456789abcdef. This can happen if the node was "
    "preempted, had a hardware failure, or its raylet crashed unexpectedly."
)


class LosingPool:
    """Trains nothing: the n-th submission of a job fails with `failures[label][n]` while there
    is one, then ends with the run's budget of episodes; `jobs`: what was submitted."""

    description = "this process (losing workers)"
    local = False

    def __init__(self, failures: dict[str, list[Exception]]) -> None:
        self.failures = failures
        self.jobs: list[Job] = []

    def submit(self, job: Job) -> int:
        self.jobs.append(job)
        return len(self.jobs) - 1

    def wait(self, handles, timeout):
        return list(handles[:1]), list(handles[1:])

    def result(self, handle: int) -> PartitionResult:
        job = self.jobs[handle]
        failures = self.failures.get(job.spec.label, [])
        if job.attempt < len(failures):
            raise failures[job.attempt]
        folder = str(run_folder(job.spec, job.runs_root))
        return PartitionResult(job.spec.partition_key, folder, "new", 24, 1, True)

    def cancel(self, handles):
        pass

    def close(self):
        pass


def jobs(root) -> list[Job]:
    return [Job(spec, str(root)) for spec in get_budget("smoke").experiments["main"].runs()]


def test_the_losses_of_a_ray_worker_are_told_from_a_runs_own_failures():
    assert lost_worker(NODE_DIED) == "its Ray node 55d739affebf (127.0.0.1) died (NodeDiedError)"
    crashed = lost_worker(ray.exceptions.WorkerCrashedError())
    assert crashed == "its Ray worker process died (WorkerCrashedError)"
    full = ray.exceptions.RayTaskError("run_job", "traceback", OSError(28, "No space left"))
    for own in (full, OSError(28, "No space left on device"), ValueError("bad config")):
        assert lost_worker(own) is None


def test_a_run_whose_node_died_is_submitted_again_from_its_checkpoint(tmp_path):
    """The lost run goes again, first in line, from its newest checkpoint; every result comes,
    in order, and `on_retry` says why and from where."""
    todo = jobs(tmp_path)
    lost = todo[2].spec
    (run_folder(lost, tmp_path) / "checkpoints" / checkpoint_name(12)).mkdir(parents=True)
    pool = LosingPool({lost.label: [NODE_DIED]})
    said = []
    results = run_all(pool, todo, on_retry=lambda job, note: said.append((job.spec.label, note)))
    assert [r.partition_key for r in results] == [job.spec.partition_key for job in todo]
    assert [(job.spec.label, job.attempt) for job in pool.jobs].count((lost.label, 1)) == 1
    assert said == [
        (
            lost.label,
            "its Ray node 55d739affebf (127.0.0.1) died (NodeDiedError); submitted again "
            "(1 of 3), from its checkpoint at episode 12",
        )
    ]


def test_a_run_lost_every_time_fails_after_the_retries_and_its_own_failure_at_once(tmp_path):
    todo = jobs(tmp_path)
    label = todo[0].spec.label
    pool = LosingPool({label: [ray.exceptions.WorkerCrashedError()] * 5})
    with pytest.raises(PartitionFailed, match=rf"^{label} failed: its Ray worker process died "):
        run_all(pool, todo, retries=2)
    assert [job.attempt for job in pool.jobs if job.spec.label == label] == [0, 1, 2]
    pool = LosingPool({label: [OSError(28, "No space left on device")] * 5})
    with pytest.raises(PartitionFailed, match=rf"^{label} failed: OSError: .*No space left"):
        run_all(pool, todo)
    assert [job.attempt for job in pool.jobs if job.spec.label == label] == [0]


def test_the_reproduction_ends_with_a_line_per_run_retried(tmp_path):
    said: list[str] = []
    budget = get_budget("smoke")
    repro = Reproduction(budget, OutputLayout.at(tmp_path), lambda: LosingPool({}), {})
    repro.say = said.append
    repro.say_retried()
    assert said == []
    repro.retried = {"main: her seed 0": ["a", "b"], "main: curious seed 1": ["c"]}
    repro.say_retried()
    assert said == [
        "2 run(s) submitted again after their worker was lost:",
        "  main: her seed 0: 2 times: a | b",
        "  main: curious seed 1: once: c",
    ]


def test_a_run_submitted_again_waits_for_the_lost_process_lock(tmp_path, monkeypatch):
    """The first submission of a run whose folder is locked fails at once; one submitted again
    waits (`LOST_LOCK_WAIT_S`) and fails only if the lock outlives the wait."""
    monkeypatch.setattr(executors, "LOST_LOCK_WAIT_S", 0.3)
    monkeypatch.setattr(executors.time, "sleep", lambda s: threading.Event().wait(0.05))
    job = jobs(tmp_path)[0]
    tries = []
    real = executors.run_partition

    def counting(*args, **kwargs):
        tries.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(executors, "run_partition", counting)
    with folder_lock(run_folder(job.spec, tmp_path)):
        with pytest.raises(RunFolderBusy):
            run_job(job)
        assert len(tries) == 1
        with pytest.raises(RunFolderBusy):
            run_job(Job(job.spec, job.runs_root, attempt=1))
        assert len(tries) > 2
