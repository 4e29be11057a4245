"""`curious view RUN_DIR [RUN_DIR ...]`: open runs' Rerun recordings in the viewer.

With a display, starts the native viewer (the `rerun` binary that rerun-sdk installs) on every
run's `recording.rrd`; several runs open in one viewer, each its own recording under the same
layout, listed in the viewer's recordings panel to switch between. Every `curious view` opens a
window of its own, also when another viewer is running (which would otherwise receive the
recordings silently). Without a display it prints
how to look at them elsewhere, and `--web` serves them here to a browser (or to a native viewer
on another machine) instead: on the loopback address (127.0.0.1) unless `--bind` names another,
so that nobody else who can reach the machine reads them; another machine reaches the server
through an SSH tunnel.
"""

from __future__ import annotations

import argparse
import contextlib
import ipaddress
import os
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from curious.commands import folder_name, refuse
from curious.runs.folder import RunFolder, folders_below, name_some
from curious.runs.shipped_folder import shipped_run_note
from curious.watching.display import has_display
from curious.watching.viewer_analytics import viewer_environment

RRD_MAGIC = b"RRF"
"""How every Rerun recording file begins (`RRF2` today, with the format's version after it)."""
RRD_HEADER_BYTES = 12
"""The file header: the magic and version (4 bytes), Rerun's version (4), options (4)."""
DEFAULT_WEB_PORT = 9090
DEFAULT_GRPC_PORT = 9876
DEFAULT_BIND = "127.0.0.1"
"""Where `--web` listens unless `--bind` says otherwise: this machine alone (Rerun's own default,
0.0.0.0, would serve the recordings to anyone who can reach it)."""
MAX_PORT = 65_535
"""Ports go from 1 to this: a TCP port is a 16-bit number, and 0 asks the system for any free
one, which no browser could be told in advance."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious view`."""
    parser = sub.add_parser(
        "view",
        help="open runs' Rerun recordings in the viewer",
        description=(
            "Open the Rerun recording (recording.rrd) of one run, or of several runs to compare "
            "them. Without a display, prints how to open them elsewhere; --web serves them to a "
            f"browser instead, on {DEFAULT_BIND} (this machine only) unless --bind names another "
            "address."
        ),
    )
    parser.add_argument(
        "runs",
        nargs="+",
        metavar="RUN_DIR",
        type=folder_name,
        help="run folder holding recording.rrd (or the path of an .rrd file)",
    )
    parser.add_argument(
        "--web",
        action="store_true",
        help="serve the recordings over HTTP/gRPC from here (for a browser or a remote viewer)",
    )
    parser.add_argument(
        "--web-port",
        type=int,
        default=DEFAULT_WEB_PORT,
        help=f"web viewer port, 1 to {MAX_PORT} (with --web; default {DEFAULT_WEB_PORT})",
    )
    parser.add_argument(
        "--grpc-port",
        type=int,
        default=DEFAULT_GRPC_PORT,
        help=f"gRPC port, 1 to {MAX_PORT} (with --web; default {DEFAULT_GRPC_PORT})",
    )
    parser.add_argument(
        "--bind",
        default=DEFAULT_BIND,
        metavar="ADDRESS",
        help=f"the address --web listens on (default {DEFAULT_BIND}: this machine only, reached "
        "from another through an SSH tunnel); 0.0.0.0 serves every interface, to anyone who "
        "can reach this machine",
    )
    parser.set_defaults(func=run)


def check_recording(path: Path) -> None:
    """A `FileNotFoundError` (reported like a missing one) for a file that is not a Rerun
    recording: empty, or not beginning as every `.rrd` does; the viewer would open it and show
    nothing, or an error of its own far from the file's name."""
    with open(path, "rb") as handle:
        head = handle.read(RRD_HEADER_BYTES)
    if not head:
        raise FileNotFoundError(f"{path}: the file is empty, not a Rerun recording")
    if not head.startswith(RRD_MAGIC) or len(head) < RRD_HEADER_BYTES:
        raise FileNotFoundError(
            f"{path}: not a Rerun recording (an .rrd file begins with {RRD_MAGIC.decode()}); "
            "a run folder's recording.rrd is written by `curious train`"
        )


def _recordings_below(folder: Path, name: str) -> str:
    """Where `folder` is a folder of runs (a reproduction's output, a `--seeds` folder), a
    sentence naming the runs below it that have a recording; empty where none has."""
    if RunFolder(folder).has_config:
        return ""
    found = folders_below(folder, name)
    if not found:
        return ""
    named = name_some(found)
    return f" It holds runs that have one: {named}; name them (several open side by side)."


def recording_paths(runs: list[str]) -> list[Path]:
    """The `.rrd` file of each run; a clear error for a folder without one, or for a file that
    is not a recording."""
    paths: list[Path] = []
    for run in runs:
        path = Path(run)
        if path.is_dir():
            rrd = RunFolder(path).recording_path
            if not rrd.is_file():
                below = _recordings_below(path, rrd.name)
                shipped = shipped_run_note(path)
                raise FileNotFoundError(
                    f"{path}: no {rrd.name} in this folder."
                    + (
                        below
                        or shipped
                        or " A run folder gets one when `curious train` runs with recording "
                        "on; check the path, or that the run has started."
                    )
                )
            paths.append(rrd)
        elif path.is_file() and path.suffix == ".rrd":
            paths.append(path)
        elif path.exists():
            raise FileNotFoundError(f"{path}: not a run folder or an .rrd file")
        else:
            what = "recording" if path.suffix == ".rrd" else "run folder"
            raise FileNotFoundError(f"{path}: no such {what}")
    for path in paths:
        check_recording(path)
    return paths


def viewer_command() -> list[str]:
    """The Rerun viewer's command: the `rerun` script on PATH, else `python -m rerun`."""
    exe = shutil.which("rerun")
    return [exe] if exe else [sys.executable, "-m", "rerun"]


def web_viewer_url(host: str, web_port: int, grpc_port: int) -> str:
    """The address that opens the served recordings in a browser.

    The page alone opens the viewer's welcome screen; the `url` query names the gRPC proxy to
    load from, with its `+` escaped (a bare `+` in a query reads as a space).
    """
    return f"http://{host}:{web_port}/?url=rerun%2Bhttp://{host}:{grpc_port}/proxy"


IPAddress = ipaddress.IPv4Address | ipaddress.IPv6Address


def check_bind(address: str) -> IPAddress:
    """The IP address `--bind` names; a `ValueError` naming the option for one that is not an
    IP address, or that no server on this machine can listen on (another machine's)."""
    try:
        ip = ipaddress.ip_address(address)
    except ValueError:
        raise ValueError(
            f"--bind must be an IP address of this machine ({DEFAULT_BIND}, the default, serves "
            f"it alone; 0.0.0.0 every interface), got {address!r}"
        ) from None
    family = socket.AF_INET6 if ip.version == 6 else socket.AF_INET
    try:
        with socket.socket(family, socket.SOCK_STREAM) as sock:
            sock.bind((str(ip), 0))
    except OSError as exc:
        raise ValueError(
            f"--bind {address}: no server can listen there ({exc.strerror or exc}); name one of "
            "this machine's addresses, or 0.0.0.0 for every interface"
        ) from None
    return ip


def _url_host(ip: IPAddress) -> str:
    """`ip` as the host of a URL (an IPv6 address in brackets)."""
    return f"[{ip}]" if ip.version == 6 else str(ip)


def _scope(ip: IPAddress) -> str:
    """Who can reach a server bound to `ip`, as a clause after its address."""
    if ip.is_loopback:
        return ", this machine only"
    if ip.is_unspecified:
        return ", every interface: anyone who can reach this machine can read them"
    return ""


def _local_host(ip: IPAddress) -> str:
    """The host a browser on this machine names to reach a server bound to `ip`."""
    return "localhost" if ip.is_unspecified or str(ip) == DEFAULT_BIND else _url_host(ip)


def port_in_use(port: int, ip: IPAddress | None = None) -> bool:
    """True when something on this machine already listens on `port` at `ip` (a running
    viewer); for every interface (0.0.0.0, ::), at the loopback address of that family."""
    ip = ipaddress.ip_address(DEFAULT_BIND) if ip is None else ip
    if ip.is_unspecified:
        ip = ipaddress.ip_address("::1" if ip.version == 6 else DEFAULT_BIND)
    family = socket.AF_INET6 if ip.version == 6 else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as sock:
        sock.settimeout(0.5)
        return sock.connect_ex((str(ip), port)) == 0


def busy_ports_error(web_port: int, grpc_port: int, ip: IPAddress | None = None) -> str | None:
    """Why `--web` cannot serve on these ports, or None when both are free."""
    for port, flag in ((web_port, "--web-port"), (grpc_port, "--grpc-port")):
        if port_in_use(port, ip):
            return (
                f"port {port} is already in use (another `curious view --web` or Rerun server?); "
                f"stop it, or choose a free port with {flag}"
            )
    return None


def access_lines(ip: IPAddress, web_port: int, grpc_port: int) -> list[str]:
    """How to open recordings served on `ip`: from this machine, and from another one (through
    an SSH tunnel where `ip` is a loopback address, which no other machine reaches)."""
    host = socket.gethostname()
    here = _local_host(ip)
    lines = [f"in a browser on this machine: {web_viewer_url(here, web_port, grpc_port)}"]
    if ip.is_loopback:
        target = _url_host(ip)
        lines += [
            f"from another machine, through an SSH tunnel: ssh -L {web_port}:{target}:{web_port} "
            f"-L {grpc_port}:{target}:{grpc_port} {host}, then on that machine",
            f"  {web_viewer_url('localhost', web_port, grpc_port)}",
            f"  or a native viewer: rerun --connect rerun+http://localhost:{grpc_port}/proxy",
            "(--bind 0.0.0.0 serves every interface instead, to anyone who can reach "
            f"{host}: {web_viewer_url(host, web_port, grpc_port)})",
        ]
    else:
        remote = host if ip.is_unspecified else _url_host(ip)
        named = f" (by this machine's name, {host})" if ip.is_unspecified else ""
        lines += [
            f"from another machine{named}: {web_viewer_url(remote, web_port, grpc_port)}",
            f"  or a native viewer: rerun --connect rerun+http://{remote}:{grpc_port}/proxy",
        ]
    return lines


def elsewhere_instructions(
    runs: list[str], paths: list[Path], web_port: int, grpc_port: int, ip: IPAddress
) -> str:
    """How to open the recordings from a machine without a display."""
    files = " ".join(shlex.quote(str(p.resolve())) for p in paths)
    runs_text = " ".join(shlex.quote(r) for r in runs)
    bind = "" if str(ip) == DEFAULT_BIND else f"--bind {ip} "
    return "\n".join(
        [
            "No display here (DISPLAY and WAYLAND_DISPLAY are unset), so no viewer window can "
            "open. To look at the recording(s):",
            "",
            "  1. On a machine with a display (pip install rerun-sdk==0.41.0), copy the files",
            "     and open them:",
            f"       rerun {files}",
            "",
            f"  2. Or serve them from here (on {ip}{_scope(ip)}):",
            f"       curious view --web {bind}{runs_text}",
            "     then open them",
            *(f"       {line}" for line in access_lines(ip, web_port, grpc_port)),
        ]
    )


def run_viewer(command: list[str]) -> int:
    """Run the viewer until it ends, or until this process is stopped (Ctrl-C, SIGTERM, SIGHUP):
    then the viewer is stopped too, so that no server outlives `curious view`. The viewer runs
    in a process group of its own, and the whole group is stopped: the `rerun` command is a
    Python script that runs the viewer binary as its child, which stopping the script alone
    would leave serving (and holding its ports). The viewer runs with Rerun's usage analytics
    off (`curious.watching.viewer_analytics`)."""

    received: list[int] = []

    def note(signum: int, frame: object) -> None:
        received.append(signum)

    def stop(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    # While the viewer starts, a signal is only noted: raised inside `Popen`, after the fork but
    # before `proc` is set, it would leave the viewer (in its own session) serving, unknown to
    # the cleanup below. Noted from the start: a SIGTERM just after the start would otherwise
    # end this process with the signal's default action, leaving the viewer serving as well.
    signals = [signal.SIGTERM, signal.SIGHUP]
    if signal.getsignal(signal.SIGINT) not in (signal.SIG_IGN, None):  # Ctrl-C, unless ignored
        signals.append(signal.SIGINT)
    previous = {sig: signal.signal(sig, note) for sig in signals}
    proc = None
    try:
        with viewer_environment() as env:  # Rerun's analytics off (viewer_analytics)
            try:
                proc = subprocess.Popen(command, start_new_session=True, env=env)
                for sig in signals:
                    signal.signal(sig, previous[sig] if sig == signal.SIGINT else stop)
                if received:  # a signal came while the viewer started: stop both now
                    if received[0] == signal.SIGINT:
                        raise KeyboardInterrupt
                    raise SystemExit(128 + received[0])
                return proc.wait()
            finally:
                if proc is not None:
                    _stop_group(proc)
    except KeyboardInterrupt:
        return 130
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _stop_group(proc: subprocess.Popen) -> None:
    """SIGTERM to the viewer's process group, SIGKILL to what is left after 5 s; the viewer
    itself is reaped."""
    group = proc.pid
    try:
        os.killpg(group, signal.SIGTERM)
    except ProcessLookupError:
        return  # the group is gone: nothing left running
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        proc.poll()
        if not group_running(group):
            break
        time.sleep(0.05)
    else:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(group, signal.SIGKILL)
    proc.wait()


def group_running(group: int) -> bool:
    """Whether a process of the group still runs. A zombie (ended, waiting for its parent to
    reap it) counts as ended: where the container's first process reaps nobody, an orphaned
    child of the viewer stays a zombie in the group for good, and would otherwise hold
    `curious view` for the whole grace period. The states are read from /proc where there is
    one, and only while the group answers a signal."""
    try:
        os.killpg(group, 0)
    except ProcessLookupError:
        return False
    proc_root = Path("/proc")
    if not (proc_root / "self" / "stat").exists():
        return True  # no /proc: the group answers, so it counts as running
    members = [stat.parent for stat in proc_root.glob("[0-9]*/stat") if _group(stat) == group]
    return any(_runs(process) for process in members)


def _stat_fields(stat: Path) -> list[str]:
    """The fields of a /proc stat file after the command's name, which is in parentheses and
    may hold any character: state, ppid, pgrp, ...; [] where the process has just ended."""
    try:
        text = stat.read_text()
        return text[text.rindex(")") + 2 :].split()
    except (OSError, ValueError):
        return []


def _group(stat: Path) -> int | None:
    fields = _stat_fields(stat)
    return int(fields[2]) if len(fields) > 2 else None


def _runs(process: Path) -> bool:
    """Whether a process has a thread that has not ended: a process whose main thread ended
    shows as a zombie while its other threads still run."""
    states = [fields[0] for t in process.glob("task/*/stat") if (fields := _stat_fields(t))]
    return any(state not in ("Z", "X") for state in states)


def run(args: argparse.Namespace) -> int:
    """Open (or serve) the recordings; exit status 2 when a run has no recording."""
    for port, flag in ((args.web_port, "--web-port"), (args.grpc_port, "--grpc-port")):
        if not 1 <= port <= MAX_PORT:
            return refuse("view", ValueError(f"{flag} must be from 1 to {MAX_PORT}, got {port}"))
    if args.web and args.web_port == args.grpc_port:
        return refuse("view", ValueError(
            f"--web-port and --grpc-port are both {args.web_port}: the page and the recordings "
            "are served on two ports; choose two"
        ))  # fmt: skip
    try:
        ip = check_bind(args.bind)
    except ValueError as exc:
        return refuse("view", exc)
    try:
        paths = recording_paths(args.runs)
    except FileNotFoundError as exc:
        return refuse("view", exc)
    files = [str(p) for p in paths]
    if args.web:
        busy = busy_ports_error(args.web_port, args.grpc_port, ip)
        if busy:
            return refuse("view", OSError(busy))
        command = [
            *viewer_command(),
            "--serve-web",
            "--bind",
            str(ip),
            "--web-viewer-port",
            str(args.web_port),
            "--port",
            str(args.grpc_port),
            *files,
        ]
        lines = access_lines(ip, args.web_port, args.grpc_port)
        print(
            f"Serving {len(files)} recording(s) on {ip}{_scope(ip)}. Open them\n"
            + "".join(f"  {line}\n" for line in lines)
            + "Ctrl-C (or SIGTERM, SIGHUP) stops the server."
        )
        return run_viewer(command)
    if not has_display():
        print(elsewhere_instructions(args.runs, paths, args.web_port, args.grpc_port, ip))
        return 0
    # `--new`: a window of this command's own; without it, a viewer already listening on the
    # default port receives the recordings, and nothing opens here.
    return run_viewer([*viewer_command(), "--new", *files])
