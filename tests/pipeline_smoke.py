"""One `curious reproduce --budget smoke` output, built once per test session and shared, and
the same output shipped (`curious ship`) into a data folder.

Test modules wrap `smoke_output` in a session-scoped fixture; the cache here makes sure the
reproduction runs once however many modules ask for it (imported fixtures are registered per
module, each with its own session cache).
"""

from __future__ import annotations

import contextlib
import io
import os
import time
from dataclasses import dataclass
from pathlib import Path

from curious.cli import main as curious_cli

_CACHE: dict[str, SmokeOutput] = {}
_SHIPPED: dict[str, ShippedSmoke] = {}


@dataclass(frozen=True)
class SmokeOutput:
    out: Path
    seconds: float
    stdout: str
    stderr: str


def smoke_output(tmp_path_factory) -> SmokeOutput:
    """The smoke budget reproduced (every experiment) into a session temp folder."""
    if "smoke" not in _CACHE:
        out = tmp_path_factory.mktemp("smoke_reproduce") / "out"
        os.environ.setdefault("MUJOCO_GL", "disable")
        stdout, stderr = io.StringIO(), io.StringIO()
        tic = time.perf_counter()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            code = curious_cli(["reproduce", "--budget", "smoke", "--out", str(out)])
        seconds = time.perf_counter() - tic
        assert code == 0, stderr.getvalue()[-3000:]
        _CACHE["smoke"] = SmokeOutput(out, seconds, stdout.getvalue(), stderr.getvalue())
    return _CACHE["smoke"]


@dataclass(frozen=True)
class ShippedSmoke:
    source: SmokeOutput
    data: Path
    seconds: float
    stdout: str


def shipped_smoke(tmp_path_factory) -> ShippedSmoke:
    """The smoke output shipped with `curious ship OUT --out DATA` into a session temp folder."""
    if "smoke" not in _SHIPPED:
        source = smoke_output(tmp_path_factory)
        data = tmp_path_factory.mktemp("smoke_shipped") / "smoke"
        stdout, stderr = io.StringIO(), io.StringIO()
        tic = time.perf_counter()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            code = curious_cli(["ship", str(source.out), "--out", str(data)])
        seconds = time.perf_counter() - tic
        assert code == 0, stderr.getvalue()[-3000:]
        _SHIPPED["smoke"] = ShippedSmoke(source, data, seconds, stdout.getvalue())
    return _SHIPPED["smoke"]
