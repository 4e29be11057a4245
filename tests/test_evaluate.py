"""`curious evaluate`: success per module of a trained run's newest checkpoint.

Runs on real smoke runs (`curious train --preset smoke`), with a few episodes per module: what a
user relies on is the table's shape, its intervals, its determinism, the scores matching the
environment's own for the goals drawn, MG-TE playing module m with expert m, HER scored on its
holistic goal, and one-line errors for folders it cannot evaluate.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import torch

from curious.cli import main as curious_cli
from curious.watching.evaluation import evaluate, evaluation_table, wilson_interval


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Smoke runs of curious, mg-te and her (seed 0)."""
    root = tmp_path_factory.mktemp("evaluate_runs")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MUJOCO_GL", "disable")
        for condition in ("curious", "mg-te", "her"):
            args = ["train", "--condition", condition, "--seed", "0", "--preset", "smoke"]
            args += ["--out", str(root / condition), "--no-progress"]
            assert curious_cli(args) == 0
    return root


def test_wilson_interval_known_values():
    # 8 of 10: the textbook Wilson 95 % interval is [0.490, 0.943].
    low, high = wilson_interval(8, 10)
    assert low == pytest.approx(0.4902, abs=1e-3) and high == pytest.approx(0.9433, abs=1e-3)
    assert wilson_interval(0, 5)[0] == 0.0 and wilson_interval(5, 5)[1] == 1.0


def test_json_has_a_row_per_chosen_module(runs, capsys):
    args = ["evaluate", str(runs / "curious"), "--episodes", "2", "--json", "--no-progress"]
    assert curious_cli([*args, "--modules", "reach", "stack", "reach"]) == 0  # each once
    out = json.loads(capsys.readouterr().out)
    assert out["condition"] == "curious" and out["episode"] == 24
    assert [row["module"] for row in out["modules"]] == ["reach", "stack"]
    for row in out["modules"]:
        assert row["episodes"] == 2
        assert row["low"] <= row["success"] <= row["high"]
        assert row["distance"] >= 0 and row["holistic_distance"] is None


def test_every_module_by_default_and_table(runs):
    result = evaluate(runs / "curious", episodes=1, copies=4)
    names = [r.module for r in result.modules]
    assert names == [
        "reach", "push_cube1", "cube1_above_cube2", "stack", "push_cube3", "push_cube4",
        "push_cube5",
    ]  # fmt: skip
    table = evaluation_table(result)
    assert all(name in table for name in names) and "95% interval" in table


def test_same_seed_same_numbers(runs):
    one = evaluate(runs / "curious", episodes=3, modules=["push_cube1"], copies=2, seed=5)
    two = evaluate(runs / "curious", episodes=3, modules=["push_cube1"], copies=2, seed=5)
    other = evaluate(runs / "curious", episodes=3, modules=["push_cube1"], copies=2, seed=6)
    a, b = one.modules[0].per_episode, two.modules[0].per_episode
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])
    assert not np.array_equal(a["goal"], other.modules[0].per_episode["goal"])
    # Copies stepped in two worker processes give the same episodes.
    spread = evaluate(
        runs / "curious", episodes=3, modules=["push_cube1"], copies=2, seed=5, processes=2
    )
    for key in a:
        np.testing.assert_array_equal(a[key], spread.modules[0].per_episode[key])


def test_still_arm_reach_scored_by_the_env(runs):
    """A policy that does nothing: reach's success is the env's own verdict for each goal
    drawn, and it is whether the final distance is within the env's success distance."""
    seen = []

    def still(goal, experts):
        seen.append(goal.slots)
        return lambda states, achieved, t: np.zeros((len(states), 4), np.float32)

    result = evaluate(runs / "curious", episodes=6, modules=["reach"], copies=3, policy=still)
    row = result.modules[0]
    per = row.per_episode
    assert len(seen) == 2 and row.episodes == 6  # two batches of three copies
    np.testing.assert_array_equal(per["success"], per["distance"] <= 0.05)
    assert row.success == per["success"].mean()
    # The arm stays where it starts: the final distance is the goal's distance from the start
    # position, which differs between goals.
    assert np.unique(np.round(per["distance"], 6)).size == 6


def test_mgte_plays_module_m_with_expert_m(runs):
    experts_seen = {}

    def record(goal, experts):
        module = int(np.flatnonzero(goal.task[0])[0])
        experts_seen.setdefault(module, []).extend(experts.tolist())
        return lambda states, achieved, t: np.zeros((len(states), 4), np.float32)

    modules = ["reach", "stack", "push_cube5"]
    result = evaluate(runs / "mg-te", episodes=2, modules=modules, copies=2, policy=record)
    assert {k: set(v) for k, v in experts_seen.items()} == {0: {0}, 3: {3}, 6: {6}}
    for row, m in zip(result.modules, (0, 3, 6), strict=True):
        np.testing.assert_array_equal(row.per_episode["expert"], [m, m])


def test_her_scored_on_its_holistic_goal(runs, capsys):
    result = evaluate(runs / "her", episodes=2, modules=["reach"], copies=2)
    row = result.modules[0]
    assert row.holistic_distance is not None and row.holistic_distance > row.distance
    per = row.per_episode
    # Meeting the holistic goal (every slot within 5 cm in all) means meeting the module's.
    assert np.all(per["success"] <= per["module_success"])
    assert "module_success" in evaluation_table(result)
    assert "holistic distance" in evaluation_table(result)


def _one_line_error(capsys, args):
    assert curious_cli(["evaluate", *args, "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("curious evaluate: error:") and "\n" not in err
    return err


def test_errors_are_one_line(runs, tmp_path, capsys):
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(runs / "curious" / "config.json", bare / "config.json")
    assert "no checkpoint" in _one_line_error(capsys, [str(bare)])

    old = tmp_path / "old"
    shutil.copytree(runs / "curious", old)
    for state_path in (old / "checkpoints").glob("*/state.pt"):
        state = torch.load(state_path, weights_only=False)
        state["format"] = 1
        torch.save(state, state_path)
    assert "format" in _one_line_error(capsys, [str(old)])

    err = _one_line_error(capsys, [str(runs / "curious"), "--variant", "distractors_0"])
    assert "modules" in err
    assert "unknown module" in _one_line_error(capsys, [str(runs / "curious"), "--modules", "x"])
    assert "no config.json" in _one_line_error(capsys, [str(tmp_path)])
    lone = [str(runs / "curious"), "--record-episodes", "3"]
    assert "--record-episodes is for --record" in _one_line_error(capsys, lone)


def _files(folder):
    return {p.relative_to(folder): p.stat().st_mtime_ns for p in folder.rglob("*")}


def test_record_writes_the_episodes_in_3d_beside_not_into_the_run(runs, tmp_path, monkeypatch):
    from curious.commands.evaluate import DEFAULT_FILE
    from curious.watching.recording import evaluation_rrd as recording
    from curious.watching.recording.reader import read_component, read_scalars, summarize

    assert DEFAULT_FILE == recording.DEFAULT_FILE == "evaluation.rrd"
    run = runs / "curious"
    before = _files(run)
    monkeypatch.chdir(tmp_path)
    args = ["evaluate", str(run), "--episodes", "3", "--modules", "reach", "stack"]
    assert curious_cli([*args, "--record", "--record-episodes", "2", "--no-progress"]) == 0
    path = tmp_path / "evaluation.rrd"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["evaluation.rrd"]  # no temporaries
    assert _files(run) == before  # the run folder is left as it was

    summary = summarize(path)
    assert {"scene/goal", "scene/goal_region", "scene/gripper_path"} <= summary.entities
    assert any(e.startswith("scene/bodies/") for e in summary.static_entities)  # the geometry
    assert {"episode", "rollout_frame"} <= summary.timelines
    # Two episodes of each module in 3-D, 51 frames each, labelled with their module.
    _, labels = read_component(path, "scene/goal", "Points3D:labels", "rollout_frame")
    assert len(labels) == 4
    assert [lab[0].split(",")[0] for lab in labels] == ["T1 reach"] * 2 + [
        "T4 stack cube 1 on 2"
    ] * 2
    frames, _ = read_component(path, "scene/goal", "Points3D:positions", "rollout_frame")
    assert len(frames) == 4 * 51
    # Every episode's success is the evaluation's (same seed, same episodes): reach's are
    # episodes 0-2, stack's 3-5.
    result = evaluate(run, episodes=3, modules=["reach", "stack"])
    for row, entity, first in zip(result.modules, ("T1-reach", "T4-stack"), (0, 3), strict=True):
        times, values = read_scalars(path, f"success/eval/{entity}")
        np.testing.assert_array_equal(times, first + np.arange(3))
        np.testing.assert_array_equal(values, row.per_episode["success"])
        _, rate = read_scalars(path, f"competence/{entity}")
        assert rate[-1] == pytest.approx(row.success)


def test_record_never_replaces_a_runs_recording(runs, tmp_path, capsys):
    run = runs / "curious"
    before = (run / "recording.rrd").read_bytes()
    err = _one_line_error(
        capsys, [str(run), "--episodes", "1", "--record", str(run / "recording.rrd")]
    )
    assert "training recording" in err
    assert (run / "recording.rrd").read_bytes() == before
    assert ".rrd" in _one_line_error(capsys, [str(run), "--record", str(tmp_path / "x.txt")])
    assert not list(tmp_path.iterdir())
