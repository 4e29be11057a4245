"""Fixtures shared by the test files: one `curious reproduce --budget smoke` output and the same
output shipped (`curious ship`) into a data folder, each built once per test session, however
many pytest-xdist workers the session runs on."""

from __future__ import annotations

import contextlib
import io
import os
import pickle
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import pytest
from filelock import FileLock

# As every command but `render` runs on a machine without a display (`curious.gl`): no test
# imports dm_control with MUJOCO_GL unset, where it would try GLFW and warn; the tests of that
# behaviour and of rendering set their own environment.
os.environ.setdefault("MUJOCO_GL", "disable")

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


Built = TypeVar("Built")


def _once_per_session(tmp_path_factory, name: str, build: Callable[[Path], Built]) -> Built:
    """`build(folder)` in a new temp folder, once per test session. Under pytest-xdist the
    first worker that needs it builds it in the session's shared temp folder while holding a
    file lock; the other workers wait for it and read what it returned."""
    if os.environ.get("PYTEST_XDIST_WORKER") is None:  # one process: nothing to share
        return build(tmp_path_factory.mktemp(name))
    folder = tmp_path_factory.getbasetemp().parent / name  # the workers' common parent
    built = folder / "built.pickle"
    with FileLock(f"{folder}.lock"):
        if built.is_file():
            return pickle.loads(built.read_bytes())
        shutil.rmtree(folder, ignore_errors=True)  # what a worker that failed to build it left
        folder.mkdir()
        value = build(folder)
        built.write_bytes(pickle.dumps(value))
        return value


@pytest.fixture(scope="session")
def smoke(tmp_path_factory) -> SmokeOutput:
    """The smoke budget reproduced (every experiment) into a session temp folder."""

    def build(folder: Path) -> SmokeOutput:
        out = folder / "out"
        seconds, stdout, stderr = _run(["reproduce", "--budget", "smoke", "--out", str(out)])
        return SmokeOutput(out, seconds, stdout, stderr)

    return _once_per_session(tmp_path_factory, "smoke_reproduce", build)


@pytest.fixture(scope="session")
def shipped(smoke, tmp_path_factory) -> ShippedSmoke:
    """The smoke output shipped with `curious ship OUT --out DATA` into a session temp folder."""

    def build(folder: Path) -> ShippedSmoke:
        data = folder / "smoke"
        seconds, stdout, _ = _run(["ship", str(smoke.out), "--out", str(data)])
        return ShippedSmoke(smoke, data, seconds, stdout)

    return _once_per_session(tmp_path_factory, "smoke_shipped", build)


@dataclass(frozen=True)
class ExtraSeed:
    out: Path
    """The campaign's output folder: main's runs of seed 2 only."""
    data: Path
    """The smoke ship with main's seed 2 shipped beside it (not in a git repository)."""
    stdout: str


@pytest.fixture(scope="session")
def extra_seed(shipped, tmp_path_factory) -> ExtraSeed:
    """Main's seed 2, beyond the smoke budget's 0 and 1, trained by `tools/campaign.py --seeds
    main=2` into a new output folder and shipped (`--ship`) into a copy of the smoke ship."""
    import importlib.util

    def build(root: Path) -> ExtraSeed:
        data = root / "data" / "smoke"
        shutil.copytree(shipped.data, data)
        spec = importlib.util.spec_from_file_location(
            "campaign", Path(__file__).resolve().parents[1] / "tools" / "campaign.py"
        )
        campaign = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(campaign)
        out = root / "out"
        args = ["--budget", "smoke", "--out", str(out), "--shipped", str(data), "--ship"]
        args += ["--only", "main/*", "--seeds", "main=2", "--set", "torch_threads=1"]
        stdout = io.StringIO()
        with contextlib.redirect_stdout(stdout):
            assert campaign.main(args) == 0
        return ExtraSeed(out, data, stdout.getvalue())

    return _once_per_session(tmp_path_factory, "extra_seed", build)
