"""Training partitions as Ray tasks, on a real one-machine cluster that the test starts.

The cluster is `ray start --head --block` on loopback with a free port and its own temp folder;
the test stops it by terminating that process, which shuts down what it started.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import pyarrow.parquet as pq
import pytest
from ray_nodes import free_port, wait_listening

from curious.reproduction.experiments import get_budget
from pipelines.executors import RayPool, RayUnavailable, check_cluster, resolve_ray_address
from pipelines.reproduce import reproduce
from pipelines.training import FINISHED, folder_state, run_folder

pytest.importorskip("ray")


@pytest.fixture(scope="module")
def ray_cluster(tmp_path_factory):
    """HOST:PORT of a fresh one-machine Ray cluster with 2 CPUs."""
    port = free_port()
    temp = tmp_path_factory.mktemp("ray")
    command = [
        sys.executable,
        "-m",
        "ray.scripts.scripts",
        "start",
        "--head",
        "--block",
        f"--port={port}",
        "--node-ip-address=127.0.0.1",
        f"--ray-client-server-port={free_port()}",
        "--num-cpus=2",
        "--num-gpus=0",
        "--include-dashboard=false",
        "--disable-usage-stats",
        f"--temp-dir={temp}",
    ]
    log = temp / "ray-start.log"
    with open(log, "wb") as output:
        process = subprocess.Popen(
            command, stdout=output, stderr=subprocess.STDOUT, start_new_session=True
        )
    try:
        wait_listening(process, port, log)
        yield f"127.0.0.1:{port}"
    finally:
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def test_two_partitions_train_as_ray_tasks(ray_cluster, tmp_path):
    os.environ.setdefault("MUJOCO_GL", "disable")
    out = tmp_path / "out"
    experiment = get_budget("smoke").experiments["sensor_failure"]
    assert len(experiment.runs()) == 2
    result = reproduce(
        "smoke",
        ["sensor_failure"],
        out=out,
        runs_dir=tmp_path / "shared" / "runs",
        make_pool=lambda: RayPool(ray_cluster),
        progress=False,
        say=lambda _: None,
    )
    assert len(result.trained) == 2
    for r in result.trained:
        assert r.runner.startswith("ray node"), r.runner
    runs_root = tmp_path / "shared" / "runs"
    for spec in experiment.runs():
        assert folder_state(spec, runs_root) == FINISHED
        metrics = pq.read_table(run_folder(spec, runs_root) / "metrics.parquet")
        assert metrics.num_rows == spec.total_episodes
    assert json.loads((out / "reproduce.json").read_text())["runs_dir"] == str(runs_root)
    assert (out / "figures" / "sensor_failure.png").is_file() and (out / "report.md").is_file()
    assert not (out / "runs").exists()  # the run folders live on the shared path only


def test_ray_pool_refuses_runs_no_node_can_hold(ray_cluster):
    with pytest.raises(RayUnavailable, match="no node of the Ray cluster"):
        RayPool(ray_cluster, cpus_per_run=1, gpus_per_run=1)


def test_a_runs_task_asks_for_whole_cpus_above_one(ray_cluster):
    """Ray takes a share of a CPU, or whole CPUs: 0.75 is asked as it is, 1.5 as 2. Each pool is
    closed: a process still connected when the cluster stops is ended by Ray."""
    import ray

    for cpus, asked in ((0.75, (0.75, 0.0)), (1.5, (2.0, 0.0))):
        pool = RayPool(ray_cluster, cpus_per_run=cpus)
        try:
            assert pool.resources() == asked
        finally:
            pool.close()
    assert not ray.is_initialized()


def test_a_port_that_answers_but_is_not_ray_times_out_clearly():
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    accepted: list[socket.socket] = []
    thread = threading.Thread(
        target=lambda: accepted.extend(server.accept() for _ in range(8)), daemon=True
    )
    thread.start()
    address = f"127.0.0.1:{server.getsockname()[1]}"
    tic = time.perf_counter()
    try:
        with pytest.raises(RayUnavailable, match="no Ray cluster answered"):
            check_cluster(address, timeout=4)
    finally:
        server.close()
    assert time.perf_counter() - tic < 15


def test_auto_without_a_local_cluster_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    monkeypatch.setenv("RAY_TMPDIR", str(tmp_path))
    with pytest.raises(RayUnavailable, match="found no running Ray cluster"):
        resolve_ray_address("auto")
