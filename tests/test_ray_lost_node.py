"""A Ray node lost in the middle of a run: the run is submitted again and resumes from its last
checkpoint on the node that is alive, the other run goes on, and every table comes out as an
undisturbed reproduction's.

The cluster is two `ray start` nodes on this machine with one CPU each (`tests/ray_nodes.py`:
every address the loopback, each node in a session of its own), so that each of the two runs
of `sensor_failure` trains on a node of its own; the test kills the second node's processes by
that session once both runs have a checkpoint. The reproductions run in a driver process of
their own, the test process never joining the cluster.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from ray_nodes import (
    LOOPBACK_ENV,
    free_port,
    kill_node,
    start_node,
    stop_node,
    wait_listening,
)

from curious.reproduction.experiments import get_budget
from curious.runs.folder import RunFolder
from pipelines.training import run_folder

pytest.importorskip("ray")

pytestmark = pytest.mark.slow

TOTAL = 96
OVERRIDES = {"total_episodes": TOTAL, "checkpoint_every_cycles": 1, "torch_threads": 1}
"""Runs long enough to be caught in the middle (24 cycles of 4 episodes), a checkpoint every
cycle: a lost node costs at most 4 episodes trained twice."""
INTERVAL = 4
"""Episodes between two checkpoints with `OVERRIDES`."""

DRIVER = textwrap.dedent(
    """
    import json, sys
    from pipelines.executors import LocalPool, RayPool
    from pipelines.reproduce import reproduce

    address, out, runs, overrides = sys.argv[1], sys.argv[2], sys.argv[3], json.loads(sys.argv[4])
    said = []
    pool = (lambda: RayPool(address)) if address != "local" else (lambda: LocalPool(2))
    result = reproduce(
        "smoke", ["sensor_failure"], out=out, runs_dir=runs, make_pool=pool,
        overrides=overrides, record=False, progress=False, say=said.append,
    )
    runners = [r.runner for r in result.trained]
    print(json.dumps({"said": said, "retried": result.retried, "runners": runners}))
    """
)


def reproduce_in(address: str, out: Path, runs: Path, env: dict[str, str]) -> subprocess.Popen:
    """The driver process of a `smoke` reproduction of `sensor_failure` with `OVERRIDES`, on the
    cluster at `address` (or on 2 local worker processes: `local`)."""
    tests = Path(__file__).resolve().parent
    env = {**env, "PYTHONPATH": os.pathsep.join([str(tests.parent), env.get("PYTHONPATH", "")])}
    return subprocess.Popen(
        [sys.executable, "-c", DRIVER, address, str(out), str(runs), json.dumps(OVERRIDES)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


def finish(driver: subprocess.Popen, timeout: float) -> dict:
    out, err = driver.communicate(timeout=timeout)
    assert driver.returncode == 0, err[-3000:]
    return json.loads(out.strip().splitlines()[-1])


def checkpoints(runs: Path) -> dict[str, int]:
    """Run label -> the episodes of its newest checkpoint (0: none yet)."""
    specs = get_budget("smoke").experiments["sensor_failure"].runs()
    return {s.label: RunFolder(run_folder(s, runs)).newest_checkpoint() or 0 for s in specs}


def without_clock(path: Path):
    table = pq.read_table(path)
    return table.drop_columns([c for c in table.column_names if c == "wall_time"])


def test_a_run_whose_node_dies_resumes_on_the_node_alive_as_if_undisturbed(tmp_path):
    env = {**os.environ, **LOOPBACK_ENV, "MUJOCO_GL": "disable"}
    port = free_port()
    temp = Path(tempfile.mkdtemp(prefix="ray-", dir="/tmp"))  # a socket's path: 107 bytes at most
    head = start_node(temp / "head", 1, port, head=True)
    nodes, drivers = [head], []
    try:
        # The undisturbed reproduction trains on this machine's processes meanwhile.
        drivers.append(reproduce_in("local", tmp_path / "ref-out", tmp_path / "ref-runs", env))
        wait_listening(head, port, temp / "head.log")
        second = start_node(temp / "second", 1, port, head=False)
        nodes.append(second)
        runs = tmp_path / "shared" / "runs"
        driver = reproduce_in(f"127.0.0.1:{port}", tmp_path / "out", runs, env)
        drivers.append(driver)
        deadline = time.monotonic() + 600
        while not all(0 < e < TOTAL for e in checkpoints(runs).values()):
            assert driver.poll() is None, driver.communicate()[1][-3000:]
            assert time.monotonic() < deadline, "the runs did not both reach a checkpoint"
            time.sleep(0.1)
        before = checkpoints(runs)
        kill_node(second)
        got = finish(driver, 600)
        finish(drivers[0], 600)
    finally:
        for process in drivers:
            if process.poll() is None:
                process.kill()
                process.communicate()
        for node in reversed(nodes):
            stop_node(node)
        shutil.rmtree(temp, ignore_errors=True)

    # One run was submitted again, from a checkpoint at least as late as the one seen before
    # the kill: at most the episodes since it (fewer than INTERVAL) were trained twice.
    ((label, notes),) = got["retried"].items()
    (note,) = notes
    assert "died (NodeDiedError)" in note or "died (WorkerCrashedError)" in note, note
    resumed = int(note.rsplit("episode ", 1)[1].replace(",", ""))
    assert before[label] <= resumed < TOTAL, (before, note)
    assert f"  {label}: resumed, {TOTAL} episodes" in "\n".join(got["said"]), got["said"]
    assert any(line.startswith(f"  {label}: once: ") for line in got["said"]), got["said"]
    assert len({runner.split(" pid ")[0] for runner in got["runners"]}) == 1  # both on the head

    specs = get_budget("smoke").experiments["sensor_failure"].runs()
    for spec in specs:
        for table in ("metrics.parquet", "tests.parquet", "learner.parquet"):
            mine = without_clock(run_folder(spec, runs) / table)
            want = without_clock(run_folder(spec, tmp_path / "ref-runs") / table)
            assert mine.num_rows == want.num_rows and mine.equals(want), (spec.label, table)
