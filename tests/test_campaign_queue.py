"""tools/campaign.py: the queue of a campaign that goes on after a machine came back empty."""

from __future__ import annotations

import contextlib
import importlib.util
import io
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def campaign():
    spec = importlib.util.spec_from_file_location("campaign", ROOT / "tools" / "campaign.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def paths(specs) -> list[str]:
    return [str(s.relative_path) for s in specs]


def test_the_queue_goes_pattern_by_pattern_then_seed_by_seed_without_shipped_runs(campaign):
    specs = campaign.queue("smoke", ("sensor_failure/*", "main/*"), {"main/mg-te/seed-0"})
    assert paths(specs) == [
        "sensor_failure/curious/seed-0",
        "sensor_failure/m-uvfa/seed-0",
        "main/curious/seed-0",
        "main/her/seed-0",
        "main/curious/seed-1",
        "main/mg-te/seed-1",
        "main/her/seed-1",
    ]


def test_a_dry_run_leaves_out_what_the_data_folder_holds_finished_and_writes_nothing(
    campaign, shipped, tmp_path
):
    out = tmp_path / "runs"
    stdout = io.StringIO()
    with contextlib.redirect_stdout(stdout):
        code = campaign.main(
            ["--budget", "smoke", "--out", str(out), "--shipped", str(shipped.data), "--dry-run"]
        )
    assert code == 0 and "; 0 runs queued" in stdout.getvalue()
    assert not out.exists()

    manifest = json.loads((shipped.data / "shipped.json").read_text())
    assert all(r["finished"] for r in manifest["runs"])  # the smoke ship holds every run finished
    with pytest.raises(SystemExit, match="no shipped data folder"):
        campaign.main(["--budget", "smoke", "--out", str(out), "--shipped", str(tmp_path)])
