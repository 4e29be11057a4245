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
    import shutil

    root = tmp_path_factory.mktemp("extra_seed")
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
    os.environ.setdefault("MUJOCO_GL", "disable")
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        assert campaign.main(args) == 0
    return ExtraSeed(out, data, stdout.getvalue())
