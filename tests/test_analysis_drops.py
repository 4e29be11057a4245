"""Spontaneous drops of mastered modules (`curious.analysis.drops`) on made-up competence curves:
each part of the rule pinned (mastery and its hold, the drop's depth, its descent, trough and
recovery, a second drop after a recovery) and the response measured (LP, p_LP, practice)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from test_analysis_synthetic import write_run

from curious.analysis import (
    DROP_COLUMNS,
    LOWEST_COLUMNS,
    MASTERY_COLUMNS,
    load_runs,
    lowest_competence,
    mastery,
    mastery_drops,
)
from curious.analysis.drops import DESCENT_BAND, DROP_DEPTH, MASTERED_COMPETENCE

N = 30_000
TOP = 0.97
MODULES = ("reach", "push_cube1", "cube1_above_cube2")


def _ramp(curve: np.ndarray, start: int, end: int, to: float) -> None:
    """Over episodes ``start`` to ``end - 1`` the curve goes linearly from its value at ``start``
    to ``to``, and stays there after."""
    curve[start:end] = np.linspace(curve[start], to, end - start)
    curve[end:] = to


def _reach() -> np.ndarray:
    """Learned by ~3,000 episodes at 0.97; falls to 0.5 over 12,000-14,000, recovers over
    15,000-17,000; falls again to 0.6 over 24,000-25,000 and stays there to the end."""
    t = np.arange(N, dtype=np.float64)
    curve = TOP / (1 + np.exp(-(t - 1_500) / 200))
    curve[3_000:] = TOP
    _ramp(curve, 12_000, 14_000, 0.5)
    _ramp(curve, 15_000, 17_000, TOP)
    _ramp(curve, 24_000, 25_000, 0.6)
    return curve


def _unmastered() -> np.ndarray:
    """At 0.8, above 0.9 for only 300 episodes (about ten of its self-evaluations: too short to
    count as mastered), then down to 0.5 for a while: a fall, but of a module never mastered."""
    curve = np.full(N, 0.8)
    curve[5_000:5_300] = 0.95
    curve[20_000:22_000] = 0.5
    return curve


def _wiggle() -> np.ndarray:
    """Mastered, then wiggling 0.16 from top to bottom: less than a drop."""
    t = np.arange(N, dtype=np.float64)
    return np.clip(0.9 + 0.08 * np.sin(2 * np.pi * t / 3_000), 0, 1)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("drops")
    curves = {"reach": _reach(), "push_cube1": _unmastered(), "cube1_above_cube2": _wiggle()}
    write_run(root / "run", condition="curious", seed=0, competence=curves, achievable=[True] * 3)
    return load_runs(root)


@pytest.fixture(scope="module")
def drops(runs):
    return mastery_drops(runs)


def _first(mask: np.ndarray, after: int) -> int:
    return after + int(np.flatnonzero(mask[after:])[0])


def test_a_drop_of_a_mastered_module_is_found_where_the_rule_puts_it(runs, drops):
    assert list(drops.columns) == list(DROP_COLUMNS)
    assert drops["module"].tolist() == ["reach", "reach"]  # nothing in the other two modules
    stored = runs["competence/reach"].to_numpy(np.float64)  # as float32 on disk
    first = drops.iloc[0]
    assert 2_000 < first["mastered_episode"] < 4_000
    assert first["peak"] == pytest.approx(TOP, abs=1e-6)
    slack = 1e-6
    drop = _first(stored <= TOP - DROP_DEPTH + slack, 12_000)
    assert first["drop_episode"] == drop
    start = _first(stored < TOP - DESCENT_BAND - slack, 12_000)
    assert first["start_episode"] == start
    assert first["trough_episode"] == 13_999 and first["trough"] == pytest.approx(0.5)
    assert first["depth"] == pytest.approx(TOP - 0.5, abs=1e-6)
    recovered = _first(stored >= MASTERED_COMPETENCE - slack, 15_000)
    assert first["recovered"] and first["recovery_episode"] == recovered
    assert first["recovery_episodes"] == recovered - drop
    assert first["span_episodes"] == recovered - start


def test_after_a_recovery_the_module_is_read_again_and_a_drop_not_recovered_is_marked(drops):
    first, second = drops.iloc[0], drops.iloc[1]
    # mastered once more after its hold of evaluations at 0.9, after the recovery
    assert first["recovery_episode"] < second["mastered_episode"] < 20_000
    assert 24_000 < second["start_episode"] < second["drop_episode"] < 25_000
    assert second["trough_episode"] == 24_999 and second["trough"] == pytest.approx(0.6)
    assert not second["recovered"]
    assert pd.isna(second["recovery_episode"]) and np.isnan(second["recovery_episodes"])
    assert second["span_episodes"] == N - second["start_episode"]


def test_lp_p_lp_and_practice_rise_over_the_drop(drops):
    # The synthetic agent picks modules by p_LP computed from the curves: reach's LP is 0 while it
    # is mastered and flat (the wiggling module takes most of p_LP then), up on the drop's slopes.
    first = drops.iloc[0]
    # the span before takes in the start of the fall still within the band of the peak
    assert first["lp_before"] < 0.002
    assert first["lp_after"] > 5 * first["lp_before"]
    assert first["lp_trough"] > 5 * first["lp_before"]
    assert first["p_lp_after"] > first["p_lp_before"] + 0.2
    assert first["practice_after"] > first["practice_before"] + 0.2
    # practice follows p_LP: shares close to the mean probabilities
    assert first["practice_before"] == pytest.approx(first["p_lp_before"], abs=0.03)
    assert first["practice_after"] == pytest.approx(first["p_lp_after"], abs=0.03)


def test_mastery_lists_every_module_with_its_drops_and_runs_without_competence(runs):
    table = mastery(runs).set_index("module")
    assert list(mastery(runs).columns) == list(MASTERY_COLUMNS)
    assert table["evaluated"].all()
    assert table.loc["reach", ["n_drops", "n_recovered"]].tolist() == [2, 1]
    # read as mastered from each mastery to its drop; its deepest fall is the first drop's
    (first, second) = mastery_drops(runs).itertuples()
    stretches = first.drop_episode - first.mastered_episode
    stretches += second.drop_episode - second.mastered_episode
    assert table.loc["reach", "mastered_episodes"] == stretches
    assert table.loc["reach", "deepest_fall"] == pytest.approx(first.peak - 0.77, abs=0.01)
    # push_cube1 fell by 0.3, but was never mastered: its 300 episodes at 0.95 are too few
    # self-evaluations to count
    assert pd.isna(table.loc["push_cube1", "mastered_episode"])
    assert table.loc["push_cube1", "n_drops"] == 0
    assert table.loc["push_cube1", "mastered_episodes"] == 0
    assert np.isnan(table.loc["push_cube1", "deepest_fall"])
    # cube1_above_cube2 is mastered, and its wiggle of 0.16 is no drop
    assert not pd.isna(table.loc["cube1_above_cube2", "mastered_episode"])
    assert table.loc["cube1_above_cube2", "n_drops"] == 0
    assert table.loc["cube1_above_cube2", "deepest_fall"] == pytest.approx(0.16, abs=0.005)
    # a run without self-evaluations (HER's competence is NaN): nothing mastered, nothing found
    blind = runs.copy()
    for module in MODULES:
        blind[f"competence/{module}"] = np.nan
    none = mastery(blind)
    assert not none["evaluated"].any() and none["mastered_episode"].isna().all()
    assert mastery_drops(blind).empty


def test_binomial_noise_of_a_stable_mastered_module_is_no_drop(tmp_path):
    # The competence of a module succeeding 92 % of the time, read as the laptop runs read it:
    # the mean of its last 100 self-evaluations (one every 10 episodes here).
    rng = np.random.default_rng(3)
    outcomes = rng.random(N // 10) < 0.92
    means = pd.Series(outcomes, dtype=float).rolling(100, min_periods=1).mean().to_numpy()
    curves = {"reach": np.repeat(means, 10), "push_cube1": np.full(N, 0.3)}
    write_run(
        tmp_path / "run",
        condition="curious",
        seed=1,
        competence=curves,
        achievable=[True, True],
        lp_window=100,
    )
    table = mastery(load_runs(tmp_path)).set_index("module")
    assert not pd.isna(table.loc["reach", "mastered_episode"])
    assert table.loc["reach", "n_drops"] == 0


def test_the_rule_s_constants_are_checked(runs):
    with pytest.raises(ValueError, match="band"):
        mastery_drops(runs, depth=0.1, band=0.1)
    with pytest.raises(ValueError, match="mastered"):
        mastery_drops(runs, mastered=1.5)
    # a shallower drop counts where a deeper one is asked: the wiggle becomes drops
    shallow = mastery_drops(runs, depth=0.15, band=0.05)
    assert "cube1_above_cube2" in set(shallow["module"])


def test_lowest_competence_reads_mastered_modules_over_a_stretch(runs):
    stored = {m: runs[f"competence/{m}"].to_numpy(np.float64) for m in MODULES}
    # from 20,000: reach (mastered by ~3,000) falls to 0.6 by 25,000 and stays there; the
    # wiggle's lowest is its first trough past 20,000; push cube 1, never mastered, has no row
    after = lowest_competence(runs, 20_000)
    assert list(after.columns) == list(LOWEST_COLUMNS)
    assert after["module"].tolist() == ["reach", "cube1_above_cube2"]
    read = after.set_index("module")
    assert read.at["reach", "low"] == pytest.approx(0.6)
    assert read.at["reach", "low_episode"] == 24_999  # the first episode at it
    wiggle = stored["cube1_above_cube2"][20_000:]
    assert read.at["cube1_above_cube2", "low"] == pytest.approx(wiggle.min())
    assert read.at["cube1_above_cube2", "low_episode"] == 20_000 + int(np.argmin(wiggle))
    table = mastery(runs).set_index("module")
    first = table.loc[["reach", "cube1_above_cube2"], "mastered_episode"].astype(int).tolist()
    assert read["mastered_episode"].tolist() == first
    # a stretch with a stop: reach at its top between its two falls
    between = lowest_competence(runs, 18_000, 23_000).set_index("module")
    assert between.at["reach", "low"] == pytest.approx(TOP)
    assert between.at["reach", "low_episode"] == 18_000
    # a module mastered inside the stretch is not read, nor a run that never gets there
    assert lowest_competence(runs, 2_000).empty
    assert lowest_competence(runs, N + 1).empty
    with pytest.raises(ValueError, match="start < stop"):
        lowest_competence(runs, 5_000, 5_000)
