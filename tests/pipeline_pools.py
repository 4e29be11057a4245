"""Pools that train a reproduction's jobs in the test's own process, for the tests of
`curious reproduce` that stop it part-way."""

from __future__ import annotations

from pipelines.executors import run_job
from pipelines.training import run_partition


class InterruptingPool:
    """Trains in this process: the first job to its end, then the first run of the second for
    one cycle and a Ctrl-C, as a kill between two checkpoints would; `jobs`: what was sent."""

    description = "this process (interrupting the second job)"
    local = True

    def __init__(self) -> None:
        self.jobs: list = []

    def submit(self, job):
        self.jobs.append(job)
        if len(self.jobs) == 1:
            return run_job(job)
        run_partition(job.spec, job.runs_root, job.overrides, job.record, stop_after_cycles=1)
        raise KeyboardInterrupt  # the run is gone between two checkpoints

    def wait(self, handles, timeout):
        return list(handles), []

    def result(self, handle):
        return handle

    def cancel(self, handles):
        pass

    def stop(self):
        pass

    def close(self):
        pass


class OrderPool(InterruptingPool):
    """Records the runs of each job in the order they are sent (`sent`: each job's run
    folders below the runs root, one a job), then stops before any trains."""

    description = "this process (recording the order)"

    def __init__(self) -> None:
        self.sent: list[list[str]] = []

    def submit(self, job):
        self.sent.append([str(job.spec.relative_path)])
        return len(self.sent)

    def wait(self, handles, timeout):
        raise KeyboardInterrupt
