"""When modules are learned (curious.analysis.milestones) and the LP / p_LP shift after the
sensory failure (curious.analysis.perturbation), on hand-made numbers."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from test_analysis_synthetic import DEFAULT_ACHIEVABLE, DEFAULT_MODULES, write_run

from curious.analysis import (
    PAPER_ORDER,
    competence_crossings,
    episodes_to_test_success,
    learning_order,
    load_runs,
    load_tests,
    module_success_rates,
    module_test_success,
    recovery,
)

ACHIEVABLE = DEFAULT_MODULES[:4]


def _run(root, seed, competence, *, n=40, lp_window=3, condition="curious", **kw):
    """A run whose every episode is a self-evaluation of achievable module ``episode % 4``, so
    that module k has its ``j``-th evaluation at episode ``4 (j - 1) + k``."""
    curves = {m: np.zeros(n) for m in DEFAULT_MODULES}
    curves.update({m: np.asarray(c, dtype=np.float64) for m, c in competence.items()})
    folder = write_run(
        root / f"{condition}{seed}",
        condition=condition,
        seed=seed,
        competence=curves,
        achievable=DEFAULT_ACHIEVABLE,
        lp_window=lp_window,
        **kw,
    )
    metrics = pd.read_parquet(folder / "metrics.parquet")
    metrics["module"] = pd.array([ACHIEVABLE[i % 4] for i in range(n)], dtype="string")
    metrics["eval"] = True
    metrics.to_parquet(folder / "metrics.parquet", index=False)
    return folder


def _step(n, at, value, before=0.0):
    out = np.full(n, before)
    out[at:] = value
    return out


def test_a_module_crosses_only_once_a_full_window_of_evaluations_backs_its_competence(tmp_path):
    n = 40
    _run(
        tmp_path,
        0,
        {
            "reach": np.ones(n),  # one lucky first evaluation: 1.0 from episode 0
            "push_cube1": _step(n, 20, 0.6),
            "cube1_above_cube2": np.full(n, 0.49),  # just under: never
            "stack": _step(n, 30, 0.5),  # exactly the level: crosses
        },
    )
    crossings = competence_crossings(load_runs(tmp_path), level=0.5).set_index("module")
    # reach's 3rd evaluation (lp_window 3) is at episode 8; push_cube1's at 9, crossing at 20
    assert crossings.loc["reach", "episode"] == 8
    assert crossings.loc["push_cube1", "episode"] == 20
    assert pd.isna(crossings.loc["cube1_above_cube2", "episode"])
    assert crossings.loc["stack", "episode"] == 30
    assert crossings["rank"].tolist()[:2] == [1, 2] and crossings.loc["stack", "rank"] == 3
    order = learning_order(crossings.reset_index())
    assert order["order"].tolist() == ["reach → push_cube1 → stack"]
    assert order["not_reached"].tolist() == ["cube1_above_cube2"]
    assert order["follows_paper"].tolist() == [True]


def test_the_paper_order_is_checked_group_by_group(tmp_path):
    n = 40
    # seed 0: push_cube1 before reach; seed 1: stack and cube1_above_cube2 tie, after push;
    # seed 2: nothing learned; seed 3: stack learned while push_cube1 never was
    _run(tmp_path, 0, {"reach": _step(n, 24, 1.0), "push_cube1": _step(n, 12, 1.0)})
    both = _step(n, 32, 1.0)
    _run(
        tmp_path,
        1,
        {
            "reach": _step(n, 12, 1.0),
            "push_cube1": _step(n, 20, 1.0),
            "cube1_above_cube2": both,
            "stack": both,
        },
    )
    _run(tmp_path, 2, {})
    _run(tmp_path, 3, {"reach": _step(n, 12, 1.0), "stack": _step(n, 20, 1.0)})
    order = learning_order(competence_crossings(load_runs(tmp_path))).set_index("seed")
    assert order.loc[0, "order"] == "push_cube1 → reach" and not order.loc[0, "follows_paper"]
    assert order.loc[1, "order"] == "reach → push_cube1 → cube1_above_cube2=stack"
    assert order.loc[1, "follows_paper"]
    assert order.loc[2, "order"] == "" and pd.isna(order.loc[2, "follows_paper"])
    assert not order.loc[3, "follows_paper"]
    assert PAPER_ORDER[0] == ("reach",) and PAPER_ORDER[1] == ("push_cube1",)


def _tests(root, seed, rows, condition="curious", own=None):
    """A run with hand-made test rollouts: rows of (epoch, module, success); epoch k ran after
    10 (k + 1) training episodes. `own`: each row's `module_success` (default: its success)."""
    folder = _run(root, seed, {}, n=200, condition=condition)
    frame = pd.DataFrame(rows, columns=["epoch", "module", "success"])
    frame = frame.astype({"epoch": np.int64, "success": bool})
    frame.insert(1, "episode", (frame["epoch"] + 1) * 10)
    frame.insert(2, "worker", np.arange(len(frame), dtype=np.int32))
    for g in ("g0", "g1", "g2"):
        frame[g] = np.float32(0.0)
    frame["module_success"] = frame["success"] if own is None else np.asarray(own, bool)
    frame["wall_time"] = frame["episode"] * 0.1
    frame.to_parquet(folder / "tests.parquet", index=False)
    return folder


def test_test_success_per_module_pools_the_last_epochs(tmp_path):
    rows = [
        (0, "reach", False),
        (0, "push_cube3", True),  # a distractor: not a module of this table
        (1, "reach", True),
        (2, "stack", True),  # epoch 2 has no reach test: the window still counts it
        (3, "reach", True),
        (3, "reach", True),
        (4, "push_cube1", False),
    ]
    _tests(tmp_path, 0, rows)
    success = module_test_success(load_tests(tmp_path), window=3)
    assert sorted(set(success["module"])) == sorted(ACHIEVABLE)
    reach = success[success["module"] == "reach"].set_index("epoch")
    assert reach.index.tolist() == [2, 3, 4]  # from the window's 3rd epoch on
    assert reach["episodes"].tolist() == [30, 40, 50]
    assert reach["n_tests"].tolist() == [2, 3, 2]
    np.testing.assert_allclose(reach["value"], [1 / 2, 1.0, 1.0])
    above = success[success["module"] == "cube1_above_cube2"]
    assert (above["n_tests"] == 0).all() and above["value"].isna().all()
    with pytest.raises(ValueError, match="window"):
        module_test_success(load_tests(tmp_path), window=0)


def test_module_success_rates_at_the_end_and_over_the_whole_run(tmp_path):
    """Where each module stands at a run's end pools its last tested epochs (the `curious
    progress` reading); over the whole run, every epoch; `module_success` is read apart from
    the score, as HER's per-module view of a holistic goal never met."""
    rows = [
        (0, "reach", False),
        (1, "reach", True),
        (2, "push_cube3", True),  # a distractor: not a module of this table
        (3, "reach", True),
        (3, "stack", False),
        (4, "reach", False),
        (4, "push_cube1", True),
    ]
    _tests(tmp_path, 0, rows, condition="her", own=[True, True, True, True, False, True, True])
    tests = load_tests(tmp_path)
    end = module_success_rates(tests, epochs=2).set_index("module")
    assert end.index.tolist() == list(ACHIEVABLE)  # slot order, untested modules included
    assert (end["episodes"] == 50).all()
    assert end["n_tests"].to_dict() == {
        "reach": 2,
        "push_cube1": 1,
        "cube1_above_cube2": 0,
        "stack": 1,
    }
    assert end.loc["reach", "value"] == 0.5 and np.isnan(end.loc["cube1_above_cube2", "value"])
    whole = module_success_rates(tests, epochs=None).set_index("module")
    assert whole.loc["reach", "n_tests"] == 4 and whole.loc["reach", "value"] == 0.5
    own = module_success_rates(tests, epochs=None, score="module_success").set_index("module")
    assert own.loc["reach", "value"] == 1.0 and own.loc["stack", "value"] == 0.0
    # more epochs asked than the run has: all of them
    assert module_success_rates(tests, epochs=50)["n_tests"].sum() == 6
    with pytest.raises(ValueError, match="epochs"):
        module_success_rates(tests, epochs=0)
    with pytest.raises(ValueError, match="score must be one of success, module_success"):
        module_success_rates(tests, score="holistic")


def test_episodes_to_a_level_of_test_success_per_module_and_seed(tmp_path):
    # reach: 1 of 2 over epochs 0-1, then 2 of 2, then 2 of 2 with 0.9 reached at epoch 2.
    rows = [(0, "reach", False), (1, "reach", True), (2, "reach", True), (2, "stack", False)]
    rows += [(e, "push_cube1", e >= 3) for e in range(6)]
    _tests(tmp_path, 0, rows)
    table = episodes_to_test_success(load_tests(tmp_path), levels=(0.5, 0.9), window=2)
    got = table.set_index(["module", "level"])["episodes"]
    assert got[("reach", 0.5)] == 20 and got[("reach", 0.9)] == 30
    # push_cube1 pooled over 2 epochs: 0/2, 0/2, 1/2 at epoch 3 (40 episodes), 2/2 at epoch 4
    assert got[("push_cube1", 0.5)] == 40 and got[("push_cube1", 0.9)] == 50
    assert pd.isna(got[("stack", 0.5)]) and pd.isna(got[("cube1_above_cube2", 0.9)])
    assert (table["last_episodes"] == 60).all()
    assert table["module"].tolist()[::2] == list(ACHIEVABLE)  # slot order, then level
    # a run with fewer epochs than the window has a row per module and level, reaching nothing
    short = episodes_to_test_success(load_tests(tmp_path), window=7)
    assert len(short) == 8 and short["episodes"].isna().all()
    with pytest.raises(ValueError, match="levels"):
        episodes_to_test_success(load_tests(tmp_path), levels=(1.5,))


def test_the_failure_shifts_lp_and_p_lp_before_against_after(tmp_path):
    n, p = 40, 20
    folder = _run(
        tmp_path,
        0,
        {"push_cube1": np.r_[np.full(p, 0.8), np.full(n - p, 0.2)]},
        sensor_failure_episode=p,
    )
    metrics = pd.read_parquet(folder / "metrics.parquet")
    after = metrics["episode"] >= p
    metrics["lp/push_cube1"] = np.where(after, 0.3, 0.0).astype(np.float32)
    metrics["p_lp/push_cube1"] = np.where(after, 0.5, 0.125).astype(np.float32)
    metrics.to_parquet(folder / "metrics.parquet", index=False)
    row = recovery(load_runs(tmp_path), "push_cube1", pre_window=5).iloc[0]
    assert row["status"] == "measured"
    assert row["competence_drop"] == pytest.approx(0.6)
    assert row["lp_before"] == 0.0 and row["lp_after"] == pytest.approx(0.3)
    assert row["p_lp_before"] == 0.125 and row["p_lp_after"] == 0.5
    never = recovery(load_runs(tmp_path), "push_cube1", perturbation_episode=n + 5).iloc[0]
    assert never["status"] == "never_started"
    assert np.isnan([never["lp_before"], never["p_lp_after"], never["competence_drop"]]).all()
