"""tools/campaign.py: the queue of a campaign that goes on after a machine came back empty."""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import io
import json
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def campaign():
    spec = importlib.util.spec_from_file_location("campaign", ROOT / "tools" / "campaign.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def hashes(folder: Path) -> dict[str, str]:
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


ignore_recordings = shutil.ignore_patterns("*.rrd")


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


def test_once_distractors_7_is_shipped_the_default_queue_goes_on_with_4_then_0(campaign):
    """The laptop campaign's queue after its 17 runs: the distractor variants C4's degradation
    needs, 4 distractors before 0, seed by seed."""
    done = set(paths(campaign.queue("laptop", campaign.DEFAULT_ONLY[:3], set())))
    assert len(done) == 17
    assert paths(campaign.queue("laptop", campaign.DEFAULT_ONLY, done)) == [
        f"distractors/{c}@distractors_{n}/seed-{seed}"
        for n in (4, 0)
        for seed in (0, 1)
        for c in ("curious", "m-uvfa")
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


def test_a_finished_run_is_shipped_beside_the_runs_held_and_committed(
    campaign, smoke, shipped, tmp_path, monkeypatch, capsys
):
    """The data folder, in a git repository, holds the smoke ship without main's her runs; the
    machine holds main's run folders only (the others were shipped before it lost them).
    Shipping adds her's runs, keeps the others, and commits."""
    for key, value in {"NAME": "campaign test", "EMAIL": "campaign@example.invalid"}.items():
        monkeypatch.setenv(f"GIT_AUTHOR_{key}", value)
        monkeypatch.setenv(f"GIT_COMMITTER_{key}", value)
    repo = tmp_path / "repo"
    data = repo / "data" / "smoke"
    shutil.copytree(shipped.data, data)
    held = json.loads((data / "shipped.json").read_text())
    held["runs"] = [r for r in held["runs"] if not r["run"].startswith("main/her/")]
    (data / "shipped.json").write_text(json.dumps(held, indent=2) + "\n")
    shutil.rmtree(data / "main" / "her")
    subprocess.run(["git", "init", "-q", str(repo)], check=True)
    subprocess.run(["git", "-C", str(repo), "add", "."], check=True)
    subprocess.run(["git", "-C", str(repo), "commit", "-qm", "held"], check=True)

    out = tmp_path / "out"
    shutil.copytree(smoke.out / "runs" / "main", out / "runs" / "main", ignore=ignore_recordings)
    shutil.copy(smoke.out / "reproduce.json", out)
    campaign.ship_and_commit(out, data, "main/her/seed-1")
    assert "kept from the earlier ship" in capsys.readouterr().out
    log = subprocess.run(
        ["git", "-C", str(repo), "log", "--format=%s"], capture_output=True, text=True
    ).stdout.splitlines()
    assert log == [
        "smoke: main/her/seed-1 shipped as soon as it finished (tools/campaign.py --ship)",
        "held",
    ]
    status = subprocess.run(["git", "-C", str(repo), "status", "--porcelain"], capture_output=True)
    assert status.stdout == b""
    assert hashes(data) == hashes(shipped.data)  # her's runs shipped, the rest as they were
