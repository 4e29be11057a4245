"""Ray nodes on this machine for the tests, every one on the loopback address only.

A node is one `ray start --block` in a session of its own, with its own temp folder and ports:
everything it starts (raylet, agents, worker processes) is in that session, so the test ends
that node, and only it, by the session's processes (`kill_node`), never by a name.

Ray binds to the loopback only where it takes the node's address to be the loopback: it turns
127.0.0.1 into the machine's outward address unless `RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0`
(`LOOPBACK_ENV`), which a driver and a head node accept; a node that joins a head refuses that
setting, so it is started with Ray's translation of 127.0.0.1 turned off instead (`_JOIN`).
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

START_SECONDS = 180
"""A loaded 2-core machine (CI beside other jobs) has taken over a minute to start Ray."""

LOOPBACK_ENV = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_USAGE_STATS_ENABLED": "0"}
"""For a head node and a driver: Ray keeps 127.0.0.1 as the node's address."""

_JOIN = (
    "import sys; import ray._private.services as s; s.resolve_ip_for_localhost = lambda h: h; "
    "from ray.scripts.scripts import main; sys.argv[0] = 'ray'; main()"
)
"""`ray start` with 127.0.0.1 kept as the head's address, and so as the joining node's own."""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_node(temp: Path, cpus: int, head_port: int, head: bool) -> subprocess.Popen:
    """A Ray node of `cpus` CPUs in a session of its own: the head, listening at `head_port`,
    or a node joining it there. Its output goes to `temp`.log."""
    temp.mkdir(parents=True, exist_ok=True)
    ports = [
        "node-manager-port", "object-manager-port", "dashboard-agent-listen-port",
        "dashboard-agent-grpc-port", "runtime-env-agent-port", "metrics-export-port",
    ]  # fmt: skip
    command = (
        [sys.executable, "-m", "ray.scripts.scripts"] if head else [sys.executable, "-c", _JOIN]
    )
    command += ["start", "--block", f"--num-cpus={cpus}", "--num-gpus=0", f"--temp-dir={temp}"]
    command += [f"--{name}={free_port()}" for name in ports]
    command += ["--min-worker-port=0", "--max-worker-port=0", "--disable-usage-stats"]
    if head:
        command += ["--head", "--node-ip-address=127.0.0.1", f"--port={head_port}"]
        command += [f"--ray-client-server-port={free_port()}", "--include-dashboard=false"]
    else:
        command += [f"--address=127.0.0.1:{head_port}"]
    env = {**os.environ, **(LOOPBACK_ENV if head else {"RAY_USAGE_STATS_ENABLED": "0"})}
    with open(temp.with_suffix(".log"), "wb") as output:
        return subprocess.Popen(
            command, stdout=output, stderr=subprocess.STDOUT, start_new_session=True, env=env
        )


def wait_listening(node: subprocess.Popen, port: int, log: Path) -> None:
    """Until the head `node` listens at `port`; a `RuntimeError` with its output where it ends
    or takes longer than `START_SECONDS`."""
    deadline = time.monotonic() + START_SECONDS
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            exited = node.poll()
            if exited is not None or time.monotonic() > deadline:
                why = (
                    f"exited with code {exited}"
                    if exited is not None
                    else f"did not listen on port {port} within {START_SECONDS} s"
                )
                tail = log.read_text(errors="replace")[-2000:]
                raise RuntimeError(f"the test's Ray node {why}; its output:\n{tail}") from None
            time.sleep(0.2)


def session_processes(session: int) -> list[tuple[int, str]]:
    """(pid, name) of every live process of the session `session` (a node's, see the module
    docstring), read from /proc."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:  # gone meanwhile
            continue
        name = stat[stat.index("(") + 1 : stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2 :].split()
        if fields[0] != "Z" and int(fields[3]) == session:  # state, ppid, pgrp, session
            found.append((int(entry.name), name))
    return found


def kill_node(node: subprocess.Popen) -> None:
    """The node dies as a machine does: its raylet first, then every other process of its
    session, each by SIGKILL, with no chance to tell the cluster."""
    for name_first in (True, False):
        for pid, name in session_processes(node.pid):
            if name_first == (name == "raylet"):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
    with contextlib.suppress(subprocess.TimeoutExpired):
        node.wait(timeout=30)


def stop_node(node: subprocess.Popen) -> None:
    """Stop a node the test started: SIGTERM to `ray start --block`, which stops what it
    started; what is left of its session after a minute is killed."""
    if node.poll() is None:
        node.send_signal(signal.SIGTERM)
        try:
            node.wait(timeout=60)
        except subprocess.TimeoutExpired:
            node.kill()
            node.wait()
    for pid, _ in session_processes(node.pid):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
