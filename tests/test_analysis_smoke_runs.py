"""The analysis library on real run folders: `curious train --preset smoke` runs on the suite.

The smoke preset trains for a few dozen episodes, so the curves are flat; what this checks is
that folders written by the trainer load, and that every figure builds from them.
"""

from __future__ import annotations

import pytest

from curious import analysis
from curious.cli import main as curious_cli

CONDITIONS = ("curious", "mg-te")
SEEDS = (0, 1)


@pytest.fixture(scope="module")
def smoke_runs(tmp_path_factory):
    """A root of smoke runs: every condition in CONDITIONS with every seed in SEEDS."""
    root = tmp_path_factory.mktemp("smoke_runs")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MUJOCO_GL", "disable")  # no rendering here, and no display to find
        for condition in CONDITIONS:
            for seed in SEEDS:
                out = root / f"{condition}-{seed}"
                args = ["train", "--condition", condition, "--seed", str(seed)]
                args += ["--preset", "smoke", "--out", str(out), "--no-progress"]
                assert curious_cli(args) == 0
    return root


def test_trainer_run_folders_load(smoke_runs):
    df = analysis.load_runs(smoke_runs)
    runs = analysis.runs_table(df)
    assert sorted(zip(runs["condition"], runs["seed"], strict=True)) == [
        (c, s) for c in sorted(CONDITIONS) for s in SEEDS
    ]
    assert set(runs["preset"]) == {"smoke"} and set(runs["variant"]) == {"default"}
    assert (runs["first_episode"] == 0).all()
    assert (runs["n_episodes"] == runs["last_episode"] + 1).all()  # every episode logged once
    assert set(runs["achievable_modules"]) == {"reach,push_cube1,cube1_above_cube2,stack"}
    values = analysis.achievable_competence(df)
    assert values.notna().all() and values.between(0, 1).all()


def test_trainer_test_rollouts_load_one_point_per_epoch(smoke_runs):
    tests = analysis.load_tests(smoke_runs)
    assert set(tests["run"]) == set(analysis.load_runs(smoke_runs)["run"])
    points = analysis.epoch_success(tests)
    # smoke: 2 workers x 2 episodes x 2 cycles = 8 episodes an epoch, 24 episodes, 1 test a worker
    assert sorted(points["episodes"].unique()) == [8, 16, 24]
    assert (tests.groupby(["run", "epoch"], observed=True).size() == 2).all()
    valid = points["value"].dropna()
    assert valid.between(0, 1).all()


def test_every_figure_builds_from_smoke_runs(smoke_runs, tmp_path):
    df = analysis.load_runs(smoke_runs)
    n = int(df["episode"].max()) + 1
    analysis.fig2a(analysis.load_tests(smoke_runs), out_dir=tmp_path)
    analysis.fig2b(df, out_dir=tmp_path)
    analysis.fig2c(df, out_dir=tmp_path)
    analysis.table1(df, out_dir=tmp_path)
    _, per_run = analysis.sensor_failure(
        df, module="push_cube1", perturbation_episode=n // 2, out_dir=tmp_path
    )
    assert len(per_run) == len(CONDITIONS) * len(SEEDS)
    assert set(per_run["onset_source"]) == {"given"}
    analysis.distractors(df, out_dir=tmp_path)
    names = ("fig2a", "fig2b", "fig2c", "table1", "sensor_failure", "distractors")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        f"{name}.{ext}" for name in names for ext in ("png", "svg")
    )
