"""tools/campaign.py: the queue of a campaign that goes on on a machine without its run folders."""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import importlib.util
import io
import json
import os
import shutil
import subprocess
import sys
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


LAPTOP_17 = (
    [f"main/{c}/seed-{s}" for s in (0, 1, 2) for c in ("curious", "mg-te", "her")]
    + [f"sensor_failure/{c}/seed-{s}" for s in (0, 1) for c in ("curious", "m-uvfa")]
    + [f"distractors/{c}@distractors_7/seed-{s}" for s in (0, 1) for c in ("curious", "m-uvfa")]
)


def test_issue_51s_queue_goes_on_after_the_budgets_with_distractors_2_then_main_seeds_3_and_4(
    campaign,
):
    """The laptop campaign's default queue once distractors_4 seed 0 is shipped: the budget's
    runs left (distractors_4 seed 1, then distractors_0, in flight when the seeds were added, so
    a restart resumes them first), then the distractors' seed 2 of every variant, then main's
    seeds 3 and 4 seed by seed."""
    done = {*LAPTOP_17, *(f"distractors/{c}@distractors_4/seed-0" for c in ("curious", "m-uvfa"))}
    assert set(paths(campaign.queue("laptop", campaign.DEFAULT_ONLY[:3], set()))) <= done
    seeds = campaign.DEFAULT_SEEDS["laptop"]
    assert seeds == {"distractors": (0, 1, 2), "main": (0, 1, 2, 3, 4)}
    distractor = "distractors/{}@distractors_{}/seed-{}"
    assert paths(campaign.queue("laptop", campaign.DEFAULT_ONLY, done, seeds)) == [
        *(distractor.format(c, 4, 1) for c in ("curious", "m-uvfa")),
        *(distractor.format(c, 0, s) for s in (0, 1) for c in ("curious", "m-uvfa")),
        *(distractor.format(c, n, 2) for n in (7, 4, 0) for c in ("curious", "m-uvfa")),
        *(f"main/{c}/seed-{s}" for s in (3, 4) for c in ("curious", "mg-te", "her")),
    ]
    # the seeds added are queued in the order `--seeds` names their experiments
    main_first = {"main": seeds["main"], "distractors": seeds["distractors"]}
    assert paths(campaign.queue("laptop", campaign.DEFAULT_ONLY, done, main_first))[6:] == [
        *(f"main/{c}/seed-{s}" for s in (3, 4) for c in ("curious", "mg-te", "her")),
        *(distractor.format(c, n, 2) for n in (7, 4, 0) for c in ("curious", "m-uvfa")),
    ]
    # without the seeds, the budget's queue as before
    assert (
        paths(campaign.queue("laptop", campaign.DEFAULT_ONLY, done))
        == paths(campaign.queue("laptop", campaign.DEFAULT_ONLY, done, seeds))[:6]
    )


def test_a_run_beyond_the_budgets_seeds_is_the_budgets_run_but_for_the_seed(campaign):
    budget = {str(s.relative_path): s for s in campaign.get_budget("laptop").runs()}
    extra = campaign.queue("laptop", ("*",), set(budget), campaign.DEFAULT_SEEDS["laptop"])
    assert len(extra) == 2 * 3 + 3 * 2
    for spec in extra:
        assert spec.seed not in campaign.get_budget("laptop").experiments[spec.experiment].seeds
        twin = budget[str(spec.relative_path).replace(f"seed-{spec.seed}", "seed-0")]
        assert dataclasses.replace(spec, seed=0) == twin
        assert spec.config().seed == spec.seed


BOTH = "37 runs queued (beyond the budget's: distractors seed 2; main seeds 3, 4)"


@pytest.mark.parametrize(
    "args, queued",
    [
        (["--seeds", "main=0-4"], "31 runs queued (beyond the budget's: main seeds 3, 4)"),
        (["--seeds", "distractors=0-2", "--seeds", "main=3,4"], BOTH),
        (
            ["--seeds", "main=3,4", "--seeds", "distractors=0-2"],
            "37 runs queued (beyond the budget's: main seeds 3, 4; distractors seed 2)",
        ),
        (["--seeds", "none"], "25 runs queued"),
        ([], BOTH),
        # the line names the seeds beyond the budget's that the queue holds, not the whole plan
        (["--only", "sensor_failure_mastered/*"], "6 runs queued"),
        (["--only", "main/curious/*"], "5 runs queued (beyond the budget's: main seeds 3, 4)"),
    ],
)
def test_seeds_options_add_to_the_budgets_and_the_default_is_issue_51s(
    campaign, args, queued, tmp_path, capsys
):
    out = tmp_path / "out"
    assert campaign.main(["--out", str(out), "--dry-run", *args]) == 0
    assert capsys.readouterr().out.splitlines()[0].endswith(f"; {queued}")
    assert not out.exists()


@pytest.mark.parametrize(
    "value, why",
    [
        ("main", "write EXPERIMENT=SEEDS"),
        ("main=a-b", "write them as 0-4 or 0,2,5"),
        ("elsewhere=3", "budget laptop trains no elsewhere"),
    ],
)
def test_a_bad_seeds_option_is_refused(campaign, value, why, tmp_path, capsys):
    with pytest.raises(SystemExit):
        campaign.main(["--out", str(tmp_path / "out"), "--dry-run", "--seeds", value])
    assert why in capsys.readouterr().err


@pytest.mark.parametrize(
    "args, why",
    [
        (["--only", "mian/*"], "--only mian/* matches no run of budget laptop"),
        (["--workers", "0"], "--workers must be at least 1, got 0"),
        (["--shipped", "{tmp}/nowhere"], "no shipped data folder there (no shipped.json)"),
        (["--set", "nope=1"], "unknown config key 'nope'"),
        (["--set", "hidden=64"], "hidden would change the budget's runs"),
        (["--budget", "huge"], "unknown budget 'huge'"),
    ],
)
def test_a_bad_campaign_option_is_one_line_before_anything_is_written(
    campaign, args, why, tmp_path, capsys
):
    """Each refusal is argparse's: one line naming the option, status 2, no traceback; a glob
    that matches no run would otherwise queue nothing without a word."""
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as refused:
        campaign.main(["--out", str(out), *(a.format(tmp=tmp_path) for a in args)])
    assert refused.value.code == 2
    err = capsys.readouterr().err
    assert why in err and "Traceback" not in err
    assert not out.exists()


def test_a_seed_beyond_the_budgets_is_trained_shipped_and_its_plan_recorded(extra_seed, tmp_path):
    """`--seeds main=2` on the smoke budget, whose main has seeds 0 and 1 shipped: main's seed 2
    is trained, shipped beside the runs held, and recorded in reproduce.json, whose plan
    `curious progress` lists before the runs start."""
    from curious.reproduction.campaign_progress import progress_table
    from curious.reproduction.experiments import get_budget
    from curious.runs.shipped_folder import ShippedFolder

    seed_2 = [f"main/{c}/seed-2" for c in ("curious", "mg-te", "her")]
    assert "3 runs queued (beyond the budget's: main seed 2)" in extra_seed.stdout
    assert extra_seed.stdout.count("kept from the earlier ship") == 3
    manifest = json.loads((extra_seed.out / "reproduce.json").read_text())
    assert manifest["budget"] == "smoke" and manifest["extra_seeds"] == {"main": [2]}
    shipped = ShippedFolder(extra_seed.data).read_manifest()
    assert len(shipped.runs) == len(get_budget("smoke").runs()) + 3
    assert all(shipped.get(run).finished for run in seed_2)

    rows = progress_table([extra_seed.out, extra_seed.data])
    n = len(get_budget("smoke").runs()) + 3
    assert len(rows) == n and all(r.shipped and r.done == 1 for r in rows)
    assert [(r.name, r.checkpoint) for r in rows if r.seed == 2] == [
        (run, 24) for run in sorted(seed_2)
    ]
    planned = tmp_path / "planned"
    planned.mkdir()
    shutil.copy(extra_seed.out / "reproduce.json", planned)
    rows = progress_table(planned)
    assert len(rows) == n and not any(r.episodes for r in rows)
    assert sorted(r.name for r in rows if r.seed == 2) == sorted(seed_2)


def test_a_dry_run_leaves_out_what_the_data_folder_holds_finished_and_writes_nothing(
    campaign, shipped, tmp_path, capsys
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
    with pytest.raises(SystemExit):
        campaign.main(["--budget", "smoke", "--out", str(out), "--shipped", str(tmp_path)])
    assert "no shipped data folder" in capsys.readouterr().err


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


def test_a_start_with_the_budgets_seeds_only_keeps_the_plan_recorded(
    campaign, extra_seed, tmp_path, capsys
):
    """`tools/campaign.sh` starts `--seeds none` (the budget's runs) before the seeds beyond
    them: that start must not erase the plan an earlier one wrote into reproduce.json, which
    `curious progress` reads."""
    out = tmp_path / "out"
    shutil.copytree(extra_seed.out, out, ignore=shutil.ignore_patterns("*.rrd", "checkpoints"))
    args = ["--budget", "smoke", "--out", str(out), "--shipped", str(extra_seed.data)]
    assert campaign.main([*args, "--only", "main/*", "--seeds", "none"]) == 0
    assert "0 runs queued" in capsys.readouterr().out
    manifest = json.loads((out / "reproduce.json").read_text())
    assert manifest["extra_seeds"] == {"main": [2]}


def test_without_the_worktree_on_the_path_the_queue_says_how_to_start_it(tmp_path):
    """campaign.py leaves out editable installs on purpose (one commit's code per run), so a
    plain `python tools/campaign.py` finds no curious: one line saying how to run it, status 2."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    done = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "campaign.py"), "--help"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert "PYTHONPATH" in done.stderr and "tools/campaign.sh" in done.stderr
    assert "Traceback" not in done.stderr


def test_plan_only_records_each_steps_seeds_and_trains_nothing(campaign, tmp_path, capsys):
    """A campaign of two steps records its whole plan before either trains: each `--plan-only`
    adds its seeds beyond the budget's to reproduce.json, keeps those recorded before, writes no
    run folder, and `curious progress` lists every planned run as not started."""
    from curious.reproduction.campaign_progress import progress_table
    from curious.reproduction.experiments import get_budget

    out = tmp_path / "out"
    smoke = ["--budget", "smoke", "--out", str(out), "--plan-only"]
    assert campaign.main([*smoke, "--seeds", "main=0-2", "--only", "main/*"]) == 0
    assert campaign.main([*smoke, "--seeds", "distractors=0,3", "--only", "distractors/*"]) == 0
    manifest = json.loads((out / "reproduce.json").read_text())
    assert manifest["extra_seeds"] == {"main": [2], "distractors": [3]}
    assert not (out / "runs").exists() or not any((out / "runs").rglob("config.json"))
    rows = progress_table(out)
    budget = get_budget("smoke")
    assert len(rows) == len(budget.runs()) + 3 + len(budget.experiments["distractors"].runs())
    assert not any(r.episodes for r in rows)
    with pytest.raises(SystemExit):
        campaign.main([*smoke, "--dry-run"])
    assert "--plan-only writes the plan, --dry-run writes nothing" in capsys.readouterr().err
