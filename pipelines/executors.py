"""Where training partitions run: local worker processes, or Ray tasks across a cluster.

Both take the same jobs (`Job`: one run's `RunSpec` and the runs root) and write the same run
folders:

* `LocalPool`: a pool of `workers` processes on this machine (default: one per core), a job at a
  time in each. Processes are started with `spawn`, so a worker never inherits the parent's
  threads or open databases, and are reused from job to job (and from experiment to experiment).
* `RayPool`: one Ray task per job with `cpus_per_run` CPUs and `gpus_per_run` GPUs (a run with a
  GPU trains its networks with `device=cuda`). The runs root must be storage every node sees
  (`--runs-dir` on a shared file system). `connect_ray` first checks that the address answers,
  so a wrong address fails in seconds with a clear error instead of hanging.

`run_all` submits jobs, shows one progress bar over every run's episodes (read from the run
folders' metrics, which the runs flush at each checkpoint) and returns one result per run, in
order. A run whose Ray worker process or node was lost (`lost_worker`) is submitted again, at
most `LOST_RUN_RETRIES` times, and resumes from its last checkpoint on a node that is alive while
the other runs go on; any other failure is the run's own (a bad config, a full disk, an error
in training), is not retried, stops the others' submission and raises `PartitionFailed` naming
the run. A Ctrl-C stops every run at once, where it is (`Pool.stop`).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import json
import logging
import math
import multiprocessing
import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

from curious.reproduction.experiments import RunSpec
from curious.runs.folder import RunFolder
from curious.runs.side_by_side import die_with_parent, interrupts_ignored
from pipelines.training import (
    PartitionResult,
    RunFolderBusy,
    episodes_logged,
    run_folder,
    run_partition,
)

RAY_CONNECT_TIMEOUT_S = 30.0
LOST_RUN_RETRIES = 3
"""How many times `run_all` submits a run again after its Ray worker or node was lost: enough
for a few lost nodes in a reproduction of days, few enough that a run whose own process
crashes every time (a segfault in the physics) soon fails instead of training the same
checkpoint interval again and again."""
LOST_LOCK_WAIT_S = 180.0
"""How long a run submitted again waits for its folder's lock, held by the process on the node
that was lost: a local file system drops it with the process, NFS when the lost client's lease
ends (90 s by default)."""


class PartitionFailed(RuntimeError):
    """A training partition raised; the message names the run and the error."""


class RayUnavailable(RuntimeError):
    """--ray-address was given but no Ray cluster answers there (or Ray is not installed)."""


@dataclass(frozen=True)
class Job:
    """One run to train in a worker process or a Ray task (`pipelines.training.run_partition`)."""

    spec: RunSpec
    runs_root: str
    overrides: dict[str, Any] = field(default_factory=dict)
    record: bool = True
    attempt: int = 0
    """0 for the first submission, n for the n-th after a lost worker (`run_all`)."""


class _WorkerState:
    """A local worker's answer to Ctrl-C (see `_on_interrupt`)."""

    running = False  # a run is training in this process
    interrupted = False  # a Ctrl-C came: no run starts here any more


def _on_interrupt(signum: int, frame: object) -> None:
    """SIGINT in a local worker: the run training here stops (a `KeyboardInterrupt` in it, once:
    a second signal would cut its clean-up short) and no other run starts here; a worker waiting
    for work only takes note, instead of dying with a traceback."""
    first = not _WorkerState.interrupted
    _WorkerState.interrupted = True
    if first and _WorkerState.running:
        raise KeyboardInterrupt


def run_job(job: Job) -> PartitionResult:
    """Entry point in a worker process or a Ray task."""
    if _WorkerState.interrupted:  # a job queued before the Ctrl-C reached this worker
        raise KeyboardInterrupt
    _WorkerState.running = True
    try:
        deadline = time.monotonic() + (LOST_LOCK_WAIT_S if job.attempt else 0.0)
        while True:
            try:
                return run_partition(job.spec, job.runs_root, job.overrides, record=job.record)
            except RunFolderBusy:  # resubmitted: the lost process's lock may outlive it a while
                if time.monotonic() >= deadline:
                    raise
                time.sleep(5.0)
    finally:
        _WorkerState.running = False


def lost_worker(exc: BaseException) -> str | None:
    """Why a run's job failed where the machine under it was lost rather than the run failing
    (its Ray node died or left the cluster, or its worker process died), in words; None for
    any other failure, the run's own.

    Ray's own task retries (`max_retries` with `retry_exceptions=False`) retry these same
    failures, but out of the driver's sight, which could then not say which run was retried or
    why: `run_all` submits the run again itself."""
    ray = sys.modules.get("ray")
    if ray is None:  # no Ray in this process: no Ray task ran
        return None
    if isinstance(exc, ray.exceptions.NodeDiedError):
        node = re.search(r"node ID: ([0-9a-f]{12})", str(exc))
        ip = re.search(r"Node IP: ([^,\s]+)", str(exc))
        where = f" {node[1]}" if node else ""
        where += f" ({ip[1]})" if ip else ""
        return f"its Ray node{where} died (NodeDiedError)"
    if isinstance(exc, ray.exceptions.WorkerCrashedError):
        return "its Ray worker process died (WorkerCrashedError)"
    return None


class Pool(Protocol):
    """What `run_all` needs from an executor."""

    description: str
    local: bool
    """Whether the jobs train on this machine (whose memory then bounds how many at a time)."""

    def submit(self, job: Job) -> Any: ...
    def wait(self, handles: Sequence[Any], timeout: float) -> tuple[list[Any], list[Any]]: ...
    def result(self, handle: Any) -> PartitionResult: ...
    def cancel(self, handles: Sequence[Any]) -> None: ...

    def stop(self) -> None:
        """Stop every run now (after a Ctrl-C), queued ones included."""

    def close(self) -> None: ...


def mps_running() -> bool:
    """Whether NVIDIA's Multi-Process Service is listening for this user's CUDA processes: its
    control pipe, which `nvidia-cuda-mps-control -d` makes in `CUDA_MPS_PIPE_DIRECTORY`
    (default /tmp/nvidia-mps)."""
    pipes = Path(os.environ.get("CUDA_MPS_PIPE_DIRECTORY") or "/tmp/nvidia-mps")
    return (pipes / "control").exists()


def gpu_sharing_hint(pool: Any, device: str | None) -> str | None:
    """A line for a reproduction whose local worker processes share one GPU without the MPS
    server (their kernels then take turns in time slices), else None: on an H200 node the
    server trained fifteen `paper` processes 1.21 x faster (docs/benchmarks.md)."""
    if device != "cuda" or not isinstance(pool, LocalPool) or pool.workers < 2 or mps_running():
        return None
    return (
        f"the {pool.workers} worker processes share the GPU in time slices: NVIDIA's MPS server "
        "(`nvidia-cuda-mps-control -d` before this command) trained fifteen `paper` processes "
        "1.2 x faster on an H200 node (docs/scaling.md)"
    )


def _local_processes(count: int) -> str:
    return f"{count} local worker process{'es' if count > 1 else ''}"


def busy_description(pool: Pool, jobs: int) -> str:
    """`pool.description` for `jobs` jobs trained at a time: a local pool of more workers than
    that starts only as many processes (`concurrent.futures` starts them as jobs come), so
    `--workers 1000` for 6 runs says 6."""
    if isinstance(pool, LocalPool) and 0 < jobs < pool.workers:
        return _local_processes(jobs)
    return pool.description


class LocalPool:
    """`workers` worker processes on this machine (started on first use, then reused)."""

    local = True

    def __init__(self, workers: int | None = None) -> None:
        self.workers = max(1, int(workers or os.cpu_count() or 1))
        self._pool: cf.ProcessPoolExecutor | None = None
        self.description = _local_processes(self.workers)

    def _executor(self) -> cf.ProcessPoolExecutor:
        if self._pool is None:
            env = {"MUJOCO_GL": os.environ.get("MUJOCO_GL", "disable"), "OMP_NUM_THREADS": "1"}
            self._pool = cf.ProcessPoolExecutor(
                max_workers=self.workers,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_set_environment,
                initargs=(env,),
            )
        return self._pool

    def submit(self, job: Job) -> cf.Future:
        with interrupts_ignored():  # the workers, started here, begin with SIGINT ignored
            return self._executor().submit(run_job, job)

    def wait(self, handles: Sequence[Any], timeout: float) -> tuple[list[Any], list[Any]]:
        done, pending = cf.wait(handles, timeout=timeout, return_when=cf.FIRST_COMPLETED)
        return [h for h in handles if h in done], [h for h in handles if h in pending]

    def result(self, handle: cf.Future) -> PartitionResult:
        return handle.result()

    def cancel(self, handles: Sequence[Any]) -> None:
        for handle in handles:
            handle.cancel()

    def stop(self) -> None:
        """Stop every run now: queued runs are dropped, and every worker gets the Ctrl-C (a
        terminal sends it to them too, `kill -INT` to this process alone does not), so that its
        run stops at once, as `curious train` does, and it starts no other (`_on_interrupt`)."""
        if self._pool is None:
            return
        processes = list((getattr(self._pool, "_processes", None) or {}).values())  # no API < 3.14
        for process in processes:
            if process.is_alive() and process.pid is not None:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(process.pid, signal.SIGINT)
        self._pool.shutdown(wait=True, cancel_futures=True)
        self._pool = None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def _set_environment(env: dict[str, str]) -> None:
    """Worker start-up: the environment, the answer to Ctrl-C (`_on_interrupt`), and death with
    the parent process (`curious.runs.side_by_side.die_with_parent`)."""
    for key, value in env.items():
        os.environ.setdefault(key, value)
    signal.signal(signal.SIGINT, _on_interrupt)
    die_with_parent()


def _probe(host: str, port: int, timeout: float) -> None:
    """Raise `RayUnavailable` unless a TCP connection to host:port opens within `timeout`."""
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return
    except OSError as exc:
        raise RayUnavailable(
            f"no Ray cluster answers at {host}:{port} ({exc.strerror or exc}); start one with "
            f"`ray start --head --port={port}` there, or leave out --ray-address to train locally"
        ) from None


def resolve_ray_address(address: str) -> str:
    """`host:port` of the cluster's GCS; `auto` reads RAY_ADDRESS or the local cluster's file."""
    if address == "auto":
        found = os.environ.get("RAY_ADDRESS")
        if not found:
            current = Path(os.environ.get("RAY_TMPDIR", "/tmp"), "ray", "ray_current_cluster")
            if current.is_file():
                found = current.read_text().strip()
        if not found:
            raise RayUnavailable(
                "--ray-address auto found no running Ray cluster on this machine (RAY_ADDRESS is "
                "unset and no `ray start` is running); start one with `ray start --head`"
            )
        address = found
    address = address.removeprefix("ray://") if address.startswith("ray://") else address
    host, sep, port = address.rpartition(":")
    if not sep or not host or not port.isdigit():
        raise RayUnavailable(f"--ray-address {address!r} is not of the form HOST:PORT (or auto)")
    return f"{host}:{port}"


_CLUSTER_CHECK = """
import json, sys
import ray
ray.init(address=sys.argv[1], logging_level="ERROR", log_to_driver=False)
nodes = [n["Resources"] for n in ray.nodes() if n["Alive"]]
print(json.dumps(nodes))
ray.shutdown()
"""


def _use_token_if_available() -> None:
    """Turn Ray's token authentication on where a token is at hand and nothing says otherwise.

    Ray 2.60 clusters started with `ray start` require a token once one exists on the machine
    (~/.ray/auth_token), but a driver given an explicit address only sends it with
    RAY_AUTH_MODE=token (a token sent to a cluster without authentication is ignored). Ray's own
    helper for `address="auto"` sets the mode and refreshes Ray's cached configuration, which an
    environment variable alone cannot do once Ray is imported.
    """
    if "RAY_AUTH_MODE" in os.environ:
        return
    try:
        from ray._private.authentication import authentication_token_setup as auth
    except ImportError:  # a Ray without token authentication: nothing to do
        return
    logger = logging.getLogger(auth.__name__)
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        auth.maybe_enable_token_auth_if_token_available(warn_if_disabled=False)
    finally:
        logger.setLevel(level)


def check_cluster(address: str, timeout: float = RAY_CONNECT_TIMEOUT_S) -> list[dict[str, float]]:
    """The resources of every live node of the Ray cluster at `address` (HOST:PORT).

    Asked from a child process that is killed after `timeout` seconds: `ray.init` on an address
    where something other than Ray listens waits for minutes.
    """
    host, _, port = address.rpartition(":")
    _probe(host, int(port), min(timeout, 5.0))
    try:
        done = subprocess.run(
            [sys.executable, "-c", _CLUSTER_CHECK, address],
            capture_output=True,
            text=True,
            timeout=timeout,
            env=os.environ.copy(),
        )
    except subprocess.TimeoutExpired:
        raise RayUnavailable(
            f"no Ray cluster answered at {address} within {timeout:.0f} s (something listens "
            "on that port, but it is not a Ray head node, or it is overloaded)"
        ) from None
    if done.returncode != 0:
        text = done.stderr.strip().splitlines()
        last = text[-1] if text else f"exit status {done.returncode}"
        if "auth" in done.stderr.lower() and "token" in done.stderr.lower():
            last = (
                "the cluster requires token authentication: set RAY_AUTH_TOKEN (or put the "
                "cluster's token in ~/.ray/auth_token) and RAY_AUTH_MODE=token"
            )
        raise RayUnavailable(f"cannot join the Ray cluster at {address}: {last}")
    try:
        return json.loads(done.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        raise RayUnavailable(
            f"the Ray cluster at {address} did not list its nodes: {done.stdout[-300:]!r}"
        ) from None


def connect_ray(
    address: str, timeout: float = RAY_CONNECT_TIMEOUT_S
) -> tuple[str, bool, list[dict[str, float]]]:
    """Connect this process to the Ray cluster at `address` (checked first, see `check_cluster`).

    Returns (HOST:PORT, whether this call connected: False when Ray was already initialised in
    this process, the nodes' resources).
    """
    try:
        import ray
    except ModuleNotFoundError:
        hint = 'in the clone, pip install -e ".[ray]"'
        raise RayUnavailable(f"--ray-address needs Ray: {hint}") from None
    resolved = resolve_ray_address(address)
    _use_token_if_available()
    nodes = check_cluster(resolved, timeout)
    if ray.is_initialized():
        return resolved, False, nodes
    env = {"MUJOCO_GL": os.environ.get("MUJOCO_GL", "disable"), "OMP_NUM_THREADS": "1"}
    try:
        ray.init(
            address=resolved,
            runtime_env={"env_vars": env},
            log_to_driver=False,
            logging_level="ERROR",
        )
    except (ConnectionError, RuntimeError, TimeoutError) as exc:
        raise RayUnavailable(f"cannot join the Ray cluster at {resolved}: {exc}") from None
    return resolved, True, nodes


class RayPool:
    """One Ray task per job on the cluster this process is connected to, with `cpus_per_run`
    CPUs and `gpus_per_run` GPUs."""

    local = False

    def __init__(self, address: str, cpus_per_run: float = 1.0, gpus_per_run: float = 0.0) -> None:
        import ray

        self.cpus_per_run = float(cpus_per_run)
        self.gpus_per_run = float(gpus_per_run)
        self.address, self._connected, nodes = connect_ray(address)
        cpus, gpus = self.resources()
        if not any(n.get("CPU", 0.0) >= cpus and n.get("GPU", 0.0) >= gpus for n in nodes):
            self.close()
            have = "; ".join(f"{n.get('CPU', 0):g} CPU, {n.get('GPU', 0):g} GPU" for n in nodes)
            raise RayUnavailable(
                f"no node of the Ray cluster at {self.address} has {self.cpus_per_run:g} CPU and "
                f"{self.gpus_per_run:g} GPU for one run (nodes: {have or 'none'}): lower "
                "--cpus-per-run / --gpus-per-run"
            )
        # Ray retries nothing: `run_all` submits a run whose node was lost again (`lost_worker`).
        self._remote = ray.remote(num_cpus=cpus, num_gpus=gpus, max_retries=0)(run_job)
        gpu = f", {self.gpus_per_run:g} GPU" if self.gpus_per_run else ""
        self.description = f"Ray tasks at {self.address} ({self.cpus_per_run:g} CPU{gpu} per run)"

    def resources(self) -> tuple[float, float]:
        """The CPUs and GPUs a run's task asks for: `cpus_per_run` and `gpus_per_run`, rounded
        up to a whole number above 1 (where Ray takes only whole numbers)."""

        def whole_above_one(amount: float) -> float:
            return amount if amount <= 1 else float(math.ceil(amount - 1e-9))

        return whole_above_one(self.cpus_per_run), whole_above_one(self.gpus_per_run)

    def submit(self, job: Job) -> Any:
        if self.gpus_per_run > 0:
            job = replace(job, overrides={**job.overrides, "device": "cuda"})
        return self._remote.remote(job)

    def wait(self, handles: Sequence[Any], timeout: float) -> tuple[list[Any], list[Any]]:
        import ray

        if not handles:
            return [], []
        done, pending = ray.wait(list(handles), num_returns=1, timeout=timeout)
        return done, pending

    def result(self, handle: Any) -> PartitionResult:
        import ray

        return ray.get(handle)

    def cancel(self, handles: Sequence[Any]) -> None:
        import ray

        for handle in handles:
            ray.cancel(handle, force=True)

    def stop(self) -> None:
        """Nothing more to do: `cancel` already ended the tasks (`force=True`)."""

    def close(self) -> None:
        """Disconnect (if this pool connected); the cluster keeps running, it is not ours."""
        import ray

        if self._connected and ray.is_initialized():
            ray.shutdown()
        self._connected = False


def run_all(
    pool: Pool,
    jobs: Sequence[Job],
    on_progress: Callable[[int, int], None] | None = None,
    on_done: Callable[[Job, PartitionResult], None] | None = None,
    poll_seconds: float = 1.0,
    at_once: int | None = None,
    on_retry: Callable[[Job, str], None] | None = None,
    retries: int = LOST_RUN_RETRIES,
) -> list[PartitionResult]:
    """Train every job on `pool`; one result per job, in the order of `jobs`.

    `on_progress(episodes_done, episodes_total)` is called about every `poll_seconds` with the
    episodes found in every run's folder; `on_done(job, result)` after each job has ended.
    `at_once`: at most that many jobs handed to the pool at a time, the next as one ends (None:
    all at once, the pool queueing them). A job whose worker was lost (`lost_worker`) is
    submitted again, first in line, up to `retries` times, its folder's state deciding where it
    goes on (`pipelines.training.run_partition`: from its last checkpoint);
    `on_retry(job, note)` says each time why and from which episode.
    """
    current = list(jobs)  # a job submitted again takes its place
    results: dict[int, PartitionResult] = {}
    handles: dict[Any, int] = {}
    waiting = list(enumerate(current))
    total = sum(job.spec.total_episodes for job in jobs)
    pending: list[Any] = []
    folders = [run_folder(job.spec, job.runs_root) for job in jobs]
    limit = len(jobs) if at_once is None else max(1, at_once)
    try:
        while waiting or pending:
            while waiting and len(pending) < limit:
                i, job = waiting.pop(0)
                handle = pool.submit(job)
                handles[handle] = i
                pending.append(handle)
            done, pending = pool.wait(pending, poll_seconds)
            for handle in done:
                i = handles.pop(handle)
                try:
                    results[i] = pool.result(handle)
                except Exception as exc:
                    current[i] = _again(current[i], exc, folders[i], retries, on_retry)
                    waiting.insert(0, (i, current[i]))
                    continue
                if on_done is not None:
                    on_done(current[i], results[i])
            if on_progress is not None:
                seen = sum(
                    results[i].episodes if i in results else episodes_logged(folders[i])
                    for i in range(len(jobs))
                )
                on_progress(min(seen, total), total)
    except BaseException as exc:
        pool.cancel(pending)
        if not isinstance(exc, Exception):  # a Ctrl-C (Dagster's interrupt is one too)
            pool.stop()
        raise
    return [results[i] for i in range(len(jobs))]


def _again(
    job: Job,
    exc: Exception,
    folder: Path,
    retries: int,
    on_retry: Callable[[Job, str], None] | None,
) -> Job:
    """The job to submit again after `exc` ended it, its worker having been lost; else
    `PartitionFailed` naming the run (its own failure, or a lost worker once too often)."""
    why = lost_worker(exc)
    failed = f"{job.spec.label} failed: {type(exc).__name__}: {exc}"
    if why is None:
        raise PartitionFailed(failed) from exc
    if job.attempt >= retries:
        raise PartitionFailed(
            f"{job.spec.label} failed: {why}, after it was submitted again {retries} "
            f"time{'s' if retries != 1 else ''}"
        ) from exc

    start = RunFolder(folder).newest_checkpoint()
    where = f"its checkpoint at episode {start:,}" if start else "episode 0 (no checkpoint yet)"
    if on_retry is not None:
        on_retry(job, f"{why}; submitted again ({job.attempt + 1} of {retries}), from {where}")
    return replace(job, attempt=job.attempt + 1)


def make_pool(
    ray_address: str | None,
    workers: int | None = None,
    cpus_per_run: float = 1.0,
    gpus_per_run: float = 0.0,
) -> Pool:
    """`RayPool` when an address is given, else `LocalPool`."""
    if ray_address:
        return RayPool(ray_address, cpus_per_run, gpus_per_run)
    return LocalPool(workers)
