"""`curious view`: opens recordings, explains itself without a display, names a bad folder."""

from __future__ import annotations

from pathlib import Path
from urllib.parse import parse_qs, urlparse

import pytest

from curious.cli import main
from curious.commands import view
from curious.runs.folder_layout import RECORDING_FILE

RRD_HEADER = b"RRF2\x00\x29\x00\x00\x01\x02\x00\x00"
"""The first 12 bytes of a recording that rerun-sdk 0.41 wrote: magic, version, options."""


def _run_folder(root: Path, name: str) -> Path:
    folder = root / name
    folder.mkdir()
    (folder / RECORDING_FILE).write_bytes(RRD_HEADER)
    return folder


@pytest.fixture
def no_display(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(view.sys, "platform", "linux")


def test_the_view_command_opens_the_file_the_recorder_writes(tmp_path: Path) -> None:
    from curious.runs.folder import RunFolder
    from curious.watching.recording.recorder import RunRecorder

    RunRecorder(tmp_path / "run", ("reach",)).close()
    assert view.recording_paths([str(tmp_path / "run")]) == [
        RunFolder(tmp_path / "run").recording_path
    ]


def test_folder_without_recording_is_an_error_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good = _run_folder(tmp_path, "run_a")
    empty = tmp_path / "run_b"
    empty.mkdir()
    assert main(["view", str(good), str(empty)]) == 2
    err = capsys.readouterr().err
    assert str(empty) in err and "no recording.rrd" in err
    assert main(["view", str(tmp_path / "missing")]) == 2
    assert "no such run folder" in capsys.readouterr().err
    assert main(["view", str(tmp_path / "missing.rrd")]) == 2
    assert "missing.rrd: no such recording" in capsys.readouterr().err


def test_a_folder_of_runs_names_the_runs_below_it_that_have_a_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "main").mkdir()
    runs = [_run_folder(tmp_path / "main", f"seed-{i}") for i in range(5)]
    assert main(["view", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"It holds runs that have one: {runs[0]}, {runs[1]}, {runs[2]} and 2 more" in err


def test_a_file_that_is_not_a_recording_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(view, "run_viewer", _no_viewer)
    empty, garbage = tmp_path / "empty.rrd", tmp_path / "garbage.rrd"
    empty.write_bytes(b"")
    garbage.write_bytes(b"PK\x03\x04 not a recording at all")
    for path, message in ((empty, "the file is empty"), (garbage, "not a Rerun recording")):
        assert main(["view", str(path)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and str(path) in err and message in err
    run = _run_folder(tmp_path, "run")
    (run / RECORDING_FILE).write_text("hello")
    assert main(["view", str(run)]) == 2
    assert "not a Rerun recording" in capsys.readouterr().err


def test_without_display_prints_how_to_open_elsewhere(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], no_display: None, monkeypatch
) -> None:
    monkeypatch.setattr(view, "run_viewer", _no_viewer)
    a, b = _run_folder(tmp_path, "run_a"), _run_folder(tmp_path, "run_b")
    assert main(["view", str(a), str(b)]) == 0
    out = capsys.readouterr().out
    assert "No display" in out
    files = f"{(a / RECORDING_FILE).resolve()} {(b / RECORDING_FILE).resolve()}"
    assert f"rerun {files}" in out
    assert f"curious view --web {a} {b}" in out


def test_with_display_opens_every_recording_in_one_viewer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("DISPLAY", ":0")
    calls: list[list[str]] = []
    monkeypatch.setattr(view, "run_viewer", lambda cmd: calls.append(cmd) or 0)
    a, b = _run_folder(tmp_path, "run_a"), _run_folder(tmp_path, "run_b")
    rrd = b / RECORDING_FILE
    assert main(["view", str(a), str(rrd)]) == 0
    (command,) = calls
    assert command[-2:] == [str(a / RECORDING_FILE), str(rrd)]
    assert "rerun" in " ".join(command[:-2])
    # a window of its own even when another viewer listens (it would get the files silently)
    assert "--new" in command


def test_web_refuses_a_port_already_taken(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import socket

    monkeypatch.setattr(view, "run_viewer", _no_viewer)
    a = _run_folder(tmp_path, "run_a")
    with socket.socket() as taken, socket.socket() as free:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        free.bind(("127.0.0.1", 0))  # bound, not listening: nobody serves there
        busy, idle = taken.getsockname()[1], free.getsockname()[1]
        for args, flag in (
            (["--web-port", str(busy), "--grpc-port", str(idle)], "--web-port"),
            (["--web-port", str(idle), "--grpc-port", str(busy)], "--grpc-port"),
        ):
            assert main(["view", "--web", *args, str(a)]) == 2
            err = capsys.readouterr().err
            assert f"port {busy} is already in use" in err and flag in err


def test_web_serves_the_recordings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, no_display: None
) -> None:
    calls: list[list[str]] = []
    monkeypatch.setattr(view, "run_viewer", lambda cmd: calls.append(cmd) or 0)
    a = _run_folder(tmp_path, "run_a")
    assert main(["view", "--web", "--web-port", "9191", "--grpc-port", "9292", str(a)]) == 0
    (command,) = calls
    assert "--serve-web" in command and "9191" in command and "9292" in command
    assert command[-1] == str(a / RECORDING_FILE)


def test_the_printed_browser_address_names_the_grpc_proxy_in_its_url(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch, no_display: None
) -> None:
    """The page alone shows the viewer's welcome screen: the address must name the gRPC proxy
    in its `url` query, with the `+` escaped (a bare one reads as a space)."""
    monkeypatch.setattr(view, "run_viewer", lambda cmd: 0)
    a = _run_folder(tmp_path, "run_a")
    for args, web, grpc in (
        (["--web", "--web-port", "9191", "--grpc-port", "9292"], 9191, 9292),
        ([], 9090, 9876),  # printed without a display, for the default ports
    ):
        assert main(["view", *args, str(a)]) == 0
        out = capsys.readouterr().out
        addresses = [w for w in out.split() if w.startswith(f"http://localhost:{web}")]
        assert addresses
        for address in addresses:
            query = parse_qs(urlparse(address).query)
            assert query == {"url": [f"rerun+http://localhost:{grpc}/proxy"]}


def _no_viewer(cmd: list[str]) -> int:
    raise AssertionError(f"no viewer may start without a display: {cmd}")


def test_stopping_curious_view_stops_the_viewer_it_started(tmp_path: Path) -> None:
    """`curious view --web` leaves no rerun server behind when it is stopped (SIGTERM here)."""
    import os
    import signal
    import threading
    import time

    pidfile = tmp_path / "viewer.pid"

    def stop_soon() -> None:
        deadline = time.time() + 10
        while not pidfile.exists() or not pidfile.read_text().strip():
            if time.time() > deadline:
                return
            time.sleep(0.02)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=stop_soon, daemon=True).start()
    with pytest.raises(SystemExit) as stopped:
        view.run_viewer(["sh", "-c", f"echo $$ > {pidfile}; exec sleep 60"])
    assert stopped.value.code == 128 + signal.SIGTERM
    with pytest.raises(ProcessLookupError):
        os.kill(int(pidfile.read_text()), 0)  # the viewer is gone, reaped


def test_stopping_curious_view_stops_the_viewers_children_too(tmp_path: Path) -> None:
    """The `rerun` command is a script that runs the viewer binary as its child: stopped with
    SIGTERM, `curious view` stops that child too (it would keep serving, holding the ports)."""
    import os
    import signal
    import threading
    import time

    pidfile = tmp_path / "server.pid"

    def stop_soon() -> None:
        deadline = time.time() + 10
        while not pidfile.exists() or not pidfile.read_text().strip():
            if time.time() > deadline:
                return
            time.sleep(0.02)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=stop_soon, daemon=True).start()
    with pytest.raises(SystemExit) as stopped:  # a wrapper whose child serves, as `rerun` does
        view.run_viewer(["sh", "-c", f"sleep 60 & echo $! > {pidfile}; wait"])
    assert stopped.value.code == 128 + signal.SIGTERM
    server = int(pidfile.read_text())

    def state() -> str | None:
        """The child's state letter (Z: stopped, waiting to be reaped), None once it is gone."""
        try:
            return Path(f"/proc/{server}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError, IndexError):
            return None

    deadline = time.time() + 5
    while time.time() < deadline:
        if state() in (None, "Z", "X"):  # an orphan's reaping is up to the system's init
            break
        time.sleep(0.05)
    else:
        seen = state()
        os.kill(server, signal.SIGKILL)
        raise AssertionError(f"the viewer's child outlived `curious view` (state {seen})")


def _group_members(group: int) -> dict[int, str]:
    """pid -> state letter of every process of the group, from /proc."""
    members = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[2]) == group:
            members[int(stat.parent.name)] = fields[0]
    return members


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc (Linux)")
def test_a_viewer_group_left_with_a_zombie_alone_counts_as_stopped() -> None:
    """Where the first process of a container reaps nobody, an orphaned child of the viewer
    stays a zombie in the viewer's group: the group answers signals, but nothing in it runs,
    and `curious view` must not wait its grace period for it."""
    import contextlib
    import ctypes
    import os
    import signal
    import subprocess
    import sys
    import time

    # zombies are kept for their parent to reap (a SIGCHLD ignored, as some libraries set it,
    # would have the kernel reap them at once)
    previous = signal.signal(signal.SIGCHLD, signal.SIG_DFL)
    libc = ctypes.CDLL(None, use_errno=True)
    pr_set_child_subreaper = 36  # orphans come to this process, which reaps none of them here
    zombies: list[int] = []
    live = None
    try:
        if libc.prctl(pr_set_child_subreaper, 1, 0, 0, 0) != 0:
            pytest.skip("prctl(PR_SET_CHILD_SUBREAPER) refused")
        live = subprocess.Popen(["sleep", "60"], start_new_session=True)
        assert view.group_running(live.pid)
        live.kill()
        live.wait()
        assert not view.group_running(live.pid)  # the group is gone

        # a viewer that forks a child, which ends at once, and ends without reaping it: the
        # child is left a zombie in the viewer's group
        script = "import os, time\nif os.fork() == 0:\n    os._exit(0)\ntime.sleep(0.2)"
        viewer = subprocess.Popen([sys.executable, "-c", script], start_new_session=True)
        viewer.wait()
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            members = _group_members(viewer.pid)
            if members and set(members.values()) == {"Z"}:
                break
            time.sleep(0.02)
        zombies = list(members)
        assert zombies and set(members.values()) == {"Z"}, members
        os.killpg(viewer.pid, 0)  # the group still answers a signal (what was read before)
        assert not view.group_running(viewer.pid)
    finally:
        libc.prctl(pr_set_child_subreaper, 0, 0, 0, 0)
        signal.signal(signal.SIGCHLD, previous)
        if live is not None and live.poll() is None:
            live.kill()
            live.wait()
        for pid in zombies:
            with contextlib.suppress(ChildProcessError):
                os.waitpid(pid, 0)


def test_the_printed_addresses_name_this_machine_or_localhost_never_a_placeholder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch, no_display: None
) -> None:
    import socket

    monkeypatch.setattr(view, "run_viewer", lambda cmd: 0)
    a = _run_folder(tmp_path, "run_a")
    host = socket.gethostname()
    for args in (["--web", "--bind", "0.0.0.0"], []):
        assert main(["view", *args, str(a)]) == 0
        out = capsys.readouterr().out
        assert "<" not in out and "this-host" not in out
        assert f"http://{host}:9090/?url=rerun%2Bhttp://{host}:9876/proxy" in out
        assert "http://localhost:9090/?url=rerun%2Bhttp://localhost:9876/proxy" in out


def test_web_serves_on_the_loopback_address_unless_bind_names_another(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch, no_display: None
) -> None:
    """Rerun's own default is every interface (0.0.0.0): `--web` tells it 127.0.0.1, so that
    nobody else who can reach the machine reads the recordings, and says how to reach it from
    another machine (an SSH tunnel of both ports), naming no address that would not answer."""
    import socket

    calls: list[list[str]] = []
    monkeypatch.setattr(view, "run_viewer", lambda cmd: calls.append(cmd) or 0)
    a = _run_folder(tmp_path, "run_a")
    host = socket.gethostname()
    assert main(["view", "--web", str(a)]) == 0
    assert main(["view", "--web", "--bind", "0.0.0.0", str(a)]) == 0
    local, everywhere = calls
    assert local[local.index("--bind") + 1] == "127.0.0.1"
    assert everywhere[everywhere.index("--bind") + 1] == "0.0.0.0"
    out = capsys.readouterr().out.split("Ctrl-C")[0]  # the first server's lines
    assert "on 127.0.0.1, this machine only" in out
    assert f"ssh -L 9090:127.0.0.1:9090 -L 9876:127.0.0.1:9876 {host}" in out
    assert f"rerun+http://{host}:9876" not in out  # a native viewer could not connect there


@pytest.mark.parametrize(
    ("bind", "message"),
    [
        ("my-laptop", "--bind must be an IP address of this machine"),
        ("192.0.2.1", "--bind 192.0.2.1: no server can listen there"),  # TEST-NET-1: nobody's
    ],
)
def test_web_refuses_an_address_it_cannot_listen_on_naming_bind(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch, bind: str, message: str
) -> None:
    monkeypatch.setattr(view, "run_viewer", _no_viewer)
    a = _run_folder(tmp_path, "run_a")
    assert main(["view", "--web", "--bind", bind, str(a)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


def _listening(port: int) -> list[str]:
    """The local addresses of the TCP sockets listening on `port`, from Linux's /proc/net tables
    (an address there is 32-bit words of hex, each in the machine's little-endian order)."""
    import ipaddress

    found = []
    for table in (Path("/proc/net/tcp"), Path("/proc/net/tcp6")):
        lines = table.read_text().splitlines()[1:] if table.exists() else []
        for fields in (line.split() for line in lines):
            address, hex_port = fields[1].split(":")
            if fields[3] == "0A" and int(hex_port, 16) == port:  # 0A: LISTEN
                words = [bytes.fromhex(address[i : i + 8])[::-1] for i in range(0, len(address), 8)]
                found.append(str(ipaddress.ip_address(b"".join(words))))
    return found


@pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="reads Linux's /proc/net/tcp")
def test_the_served_viewer_listens_on_the_loopback_address_alone(
    tmp_path: Path, monkeypatch, no_display: None
) -> None:
    """The real `rerun --serve-web` that `curious view --web` starts: its page and its gRPC
    server listen on 127.0.0.1, on no other address."""
    import socket
    import subprocess
    import time

    from curious.watching.recording.recorder import RunRecorder

    RunRecorder(tmp_path / "run", ("reach",)).close()
    ports = []
    for _ in range(2):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            ports.append(probe.getsockname()[1])
    seen: dict[int, list[str]] = {}

    def serve(command: list[str]) -> int:
        proc = subprocess.Popen(command, start_new_session=True, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)  # fmt: skip
        try:
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and proc.poll() is None:
                seen.update({port: _listening(port) for port in ports})
                if all(seen.values()):
                    break
                time.sleep(0.1)
        finally:
            view._stop_group(proc)
        return 0

    monkeypatch.setattr(view, "run_viewer", serve)
    web, grpc = (str(port) for port in ports)
    run = str(tmp_path / "run")
    assert main(["view", "--web", "--web-port", web, "--grpc-port", grpc, run]) == 0
    assert seen == {ports[0]: ["127.0.0.1"], ports[1]: ["127.0.0.1"]}


def test_a_shipped_run_says_shipped_runs_carry_no_recording_and_no_checkpoint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`curious view` and `curious evaluate` on a run folder of shipped data (data/<budget>,
    `curious ship`): one line saying what shipped runs carry, and what reads them."""
    data = Path(__file__).resolve().parents[1] / "data" / "laptop"
    if not (data / "main" / "curious" / "seed-0").is_dir():
        pytest.skip("no shipped runs in data/laptop")
    run = data / "main" / "curious" / "seed-0"
    assert main(["view", str(run)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no recording.rrd" in err
    assert "shipped runs carry config.json and their tables only" in err
    assert "no recording.rrd and no checkpoints" in err and "--from-data" in err
    assert f"It lies in the shipped data folder {data.resolve()} (written by" in err
    assert main(["view", str(data)]) == 2  # the data folder itself: the same sentence
    assert f"It lies in the shipped data folder {data.resolve()} (written by" in (
        capsys.readouterr().err
    )
    assert main(["evaluate", str(run), "--episodes", "1", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "holds no checkpoint" in err and "no recording.rrd and no checkpoints" in err
    trained = _run_folder(tmp_path, "run")  # a training's run folder: no such sentence
    (trained / RECORDING_FILE).unlink()
    assert main(["view", str(trained)]) == 2
    assert "shipped runs carry" not in capsys.readouterr().err


def test_a_sigterm_as_the_viewer_starts_is_already_taken(monkeypatch) -> None:
    """The handlers that stop the viewer with `curious view` are in place before the viewer
    starts: a SIGTERM right after its start (a service manager stopping both at once) used to
    end `curious view` by the signal's default action, leaving the viewer serving alone."""
    import signal
    import subprocess

    seen = []
    real = subprocess.Popen

    def popen(*args, **kwargs):
        seen.append(signal.getsignal(signal.SIGTERM))
        return real(*args, **kwargs)

    monkeypatch.setattr(view.subprocess, "Popen", popen)
    before = signal.getsignal(signal.SIGTERM)
    assert view.run_viewer(["true"]) == 0
    assert seen and callable(seen[0]) and seen[0] not in (signal.SIG_DFL, signal.SIG_IGN, before)
    assert signal.getsignal(signal.SIGTERM) == before  # put back


@pytest.mark.parametrize("signum", ["SIGTERM", "SIGINT"])
def test_a_signal_while_the_viewer_starts_stops_the_viewer_too(monkeypatch, signum) -> None:
    """A signal that comes while `Popen` returns (the viewer forked, `proc` not yet set) stops
    the viewer with `curious view`: raised there, it used to leave the viewer serving."""
    import os
    import signal
    import subprocess

    started = []
    real = subprocess.Popen

    def popen(*args, **kwargs):
        child = real(*args, **kwargs)
        started.append(child)
        os.kill(os.getpid(), getattr(signal, signum))  # its handler runs before the return
        return child

    monkeypatch.setattr(view.subprocess, "Popen", popen)
    if signum == "SIGTERM":
        with pytest.raises(SystemExit) as stopped:
            view.run_viewer(["sleep", "60"])
        assert stopped.value.code == 128 + signal.SIGTERM
    else:
        assert view.run_viewer(["sleep", "60"]) == 130  # Ctrl-C, as `curious view` ends on it
    (child,) = started
    try:
        assert child.poll() is not None, "the viewer outlived `curious view`"
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()


def test_the_viewer_runs_with_rerun_analytics_off_unless_the_user_opts_in(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The viewer `curious view` starts reads a Rerun configuration of its own, analytics off
    (the real `rerun` reads it so), removed when the viewer ends; CURIOUS_RERUN_ANALYTICS=1
    leaves the viewer to the user's own configuration."""
    import json
    import shutil

    from curious.watching.viewer_analytics import OPT_IN

    monkeypatch.delenv(OPT_IN, raising=False)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "users"))
    seen = tmp_path / "seen"
    config_file = '"$XDG_CONFIG_HOME/rerun/analytics.json"'
    show = f'echo "$XDG_CONFIG_HOME" > {seen}; cat {config_file} >> {seen}'
    assert view.run_viewer(["sh", "-c", show]) == 0
    folder, *config = seen.read_text().splitlines()
    assert json.loads("\n".join(config))["analytics_enabled"] is False
    assert folder != str(tmp_path / "users") and not Path(folder).exists()
    if shutil.which("rerun"):
        out = tmp_path / "rerun.txt"
        assert view.run_viewer(["sh", "-c", f"rerun analytics config > {out} 2>&1"]) == 0
        assert '"analytics_enabled": false' in out.read_text() and "Welcome" not in out.read_text()

    monkeypatch.setenv(OPT_IN, "1")
    assert view.run_viewer(["sh", "-c", f'echo "$XDG_CONFIG_HOME" > {seen}']) == 0
    assert seen.read_text().strip() == str(tmp_path / "users")
