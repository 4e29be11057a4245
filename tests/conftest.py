"""Fixtures shared by the test files: one `curious reproduce --budget smoke` output and the same
output shipped (`curious ship`) into a data folder, each built once per test session."""

from __future__ import annotations

import contextlib
import io
import os
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from curious.cli import main as curious_cli


@dataclass(frozen=True)
class SmokeOutput:
    out: Path
    seconds: float
    stdout: str
    stderr: str


@dataclass(frozen=True)
class ShippedSmoke:
    source: SmokeOutput
    data: Path
    seconds: float
    stdout: str


def _run(args: list[str]) -> tuple[float, str, str]:
    """`curious ARGS` in this process: its seconds, stdout and stderr; it must succeed."""
    stdout, stderr = io.StringIO(), io.StringIO()
    tic = time.perf_counter()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = curious_cli(args)
    seconds = time.perf_counter() - tic
    assert code == 0, stderr.getvalue()[-3000:]
    return seconds, stdout.getvalue(), stderr.getvalue()


@pytest.fixture(scope="session")
def smoke(tmp_path_factory) -> SmokeOutput:
    """The smoke budget reproduced (every experiment) into a session temp folder."""
    out = tmp_path_factory.mktemp("smoke_reproduce") / "out"
    os.environ.setdefault("MUJOCO_GL", "disable")
    seconds, stdout, stderr = _run(["reproduce", "--budget", "smoke", "--out", str(out)])
    return SmokeOutput(out, seconds, stdout, stderr)


@pytest.fixture(scope="session")
def shipped(smoke, tmp_path_factory) -> ShippedSmoke:
    """The smoke output shipped with `curious ship OUT --out DATA` into a session temp folder."""
    data = tmp_path_factory.mktemp("smoke_shipped") / "smoke"
    seconds, stdout, _ = _run(["ship", str(smoke.out), "--out", str(data)])
    return ShippedSmoke(smoke, data, seconds, stdout)
