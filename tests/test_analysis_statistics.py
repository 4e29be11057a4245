"""Statistics (curious.analysis.statistics) on hand-made numbers, checked against numpy/scipy."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from test_analysis_synthetic import (
    DEFAULT_ACHIEVABLE,
    DEFAULT_MODULES,
    FAILURE_MODULES,
    failure_curves,
    write_run,
)

from curious import analysis
from curious.analysis import (
    LEARNED_COMPETENCE,
    AnalysisError,
    achievable_competence,
    across_seeds,
    bin_runs,
    epoch_success,
    failure_onsets,
    final_competence,
    final_success,
    load_runs,
    load_tests,
    nice_bin_size,
    perturbed_module,
    recovery,
    recovery_summary,
    welch_per_bin,
)

ACHIEVABLE = DEFAULT_MODULES[:4]
DISTRACTORS = DEFAULT_MODULES[4:]


def _run(root, condition, seed, achievable_curve, distractor_value=0.9, **kw):
    """A run whose four achievable modules all follow ``achievable_curve`` (one value per episode)
    and whose distractors sit at ``distractor_value`` (high, so leaking them in would show)."""
    curve = np.asarray(achievable_curve, dtype=np.float64)
    curves = {m: curve for m in ACHIEVABLE}
    curves.update({m: np.full(len(curve), distractor_value) for m in DISTRACTORS})
    return write_run(
        root / f"{condition}-{kw.get('variant', 'default')}-{seed}",
        condition=condition,
        seed=seed,
        competence=curves,
        achievable=DEFAULT_ACHIEVABLE,
        **kw,
    )


LEVELS = (0.25, 0.5, 0.75, 1.0, 1.0, 1.0, 1.0)


def test_success_averages_the_achievable_modules_only(tmp_path):
    curves = {m: np.full(4, v) for m, v in zip(DEFAULT_MODULES, LEVELS, strict=True)}
    write_run(
        tmp_path / "r",
        condition="curious",
        seed=0,
        competence=curves,
        achievable=DEFAULT_ACHIEVABLE,
    )
    df = load_runs(tmp_path)
    np.testing.assert_allclose(achievable_competence(df), 0.625)


@pytest.mark.parametrize(
    ("n", "target", "expected"),
    [(1, 50, 1), (99, 50, 1), (100, 50, 2), (1200, 50, 20), (300_000, 50, 5000), (5000, 10, 500)],
)
def test_nice_bin_size(n, target, expected):
    assert nice_bin_size(n, target) == expected


def test_bins_take_the_value_at_the_end_of_each_complete_bin(tmp_path):
    values = np.arange(10) / 16.0  # exact in float32
    _run(tmp_path, "curious", 0, values)
    binned = bin_runs(load_runs(tmp_path), bin_size=3)
    # Bins [0,3), [3,6), [6,9): values after episodes 2, 5, 8; episode 9 starts an unfinished bin.
    assert binned["episodes"].tolist() == [3, 6, 9]
    np.testing.assert_array_equal(binned["value"], values[[2, 5, 8]])
    assert binned.attrs["bin_size"] == 3


def test_bins_use_the_last_logged_episode_when_rows_are_missing(tmp_path):
    episodes = np.array([0, 1, 2, 4, 7, 8])  # 3, 5, 6 missing (a killed run, say)
    values = np.array([1, 2, 3, 4, 5, 6]) / 8.0
    _run(tmp_path, "curious", 0, values, episodes=episodes)
    binned = bin_runs(load_runs(tmp_path), bin_size=3)
    # Bin ends 2, 5, 8 -> last rows at episodes 2, 4, 8.
    np.testing.assert_array_equal(binned["value"], [3 / 8, 4 / 8, 6 / 8])


def _two_conditions(root, better_values, worse_values, n=8):
    """Runs whose per-seed level is the given number at every episode, per condition."""
    for seed, v in enumerate(better_values):
        _run(root, "curious", seed, np.full(n, v))
    for seed, v in enumerate(worse_values):
        _run(root, "mg-te", seed, np.full(n, v))
    return load_runs(root)


def test_mean_std_and_welch_match_numpy_and_scipy_on_the_same_numbers(tmp_path):
    rng = np.random.default_rng(3)
    n, bin_size = 12, 4
    better = np.round(rng.uniform(0.4, 0.9, size=(5, n)) * 64) / 64  # float32-exact
    worse = np.round(rng.uniform(0.1, 0.6, size=(4, n)) * 64) / 64
    for seed, curve in enumerate(better):
        _run(tmp_path, "curious", seed, curve)
    for seed, curve in enumerate(worse):
        _run(tmp_path, "mg-te", seed, curve)
    binned = bin_runs(load_runs(tmp_path), bin_size=bin_size)
    ends = [3, 7, 11]
    summary = across_seeds(binned).set_index(["condition", "episodes"])
    for k, end in enumerate(ends):
        row = summary.loc[("curious", (k + 1) * bin_size)]
        assert row["n"] == 5
        assert row["mean"] == pytest.approx(better[:, end].mean())
        assert row["std"] == pytest.approx(better[:, end].std(ddof=1))
    test = welch_per_bin(binned, "curious", "mg-te")
    assert test["episodes"].tolist() == [4, 8, 12]
    for k, end in enumerate(ends):
        expected = stats.ttest_ind(
            better[:, end], worse[:, end], equal_var=False, alternative="greater"
        )
        assert test["t"].iat[k] == pytest.approx(expected.statistic)
        assert test["p"].iat[k] == pytest.approx(expected.pvalue)
        assert test["significant"].iat[k] == (expected.pvalue < 0.01)
        assert (test["n_better"].iat[k], test["n_worse"].iat[k]) == (5, 4)


def test_a_better_condition_gets_its_dots_and_an_equal_one_none(tmp_path):
    better = bin_runs(
        _two_conditions(tmp_path / "a", [0.8, 0.82, 0.85, 0.87], [0.2, 0.25, 0.3, 0.28]),
        bin_size=2,
    )
    result = welch_per_bin(better, "curious", "mg-te")
    assert len(result) == 4 and result["significant"].all()
    assert (result["p"] < 0.01).all()
    # The other way round (one-tailed): never significant.
    assert not welch_per_bin(better, "mg-te", "curious")["significant"].any()
    same = [0.5, 0.55, 0.6, 0.52]
    equal = bin_runs(_two_conditions(tmp_path / "b", same, same), bin_size=2)
    result = welch_per_bin(equal, "curious", "mg-te")
    assert len(result) == 4 and not result["significant"].any()
    np.testing.assert_allclose(result["p"], 0.5)


def test_a_small_difference_is_not_significant_at_one_percent(tmp_path):
    # Means differ by one std: p is between 0.01 and 0.5, so no dot at alpha = 0.01 ...
    df = _two_conditions(tmp_path, [0.5, 0.6, 0.7], [0.4, 0.5, 0.6])
    result = welch_per_bin(bin_runs(df, bin_size=4), "curious", "mg-te")
    assert ((result["p"] > 0.01) & (result["p"] < 0.5)).all()
    assert not result["significant"].any()
    # ... but there is one at a looser level.
    assert welch_per_bin(bin_runs(df, bin_size=4), "curious", "mg-te", alpha=0.2)[
        "significant"
    ].all()


def test_one_seed_gives_no_test_and_no_std(tmp_path):
    df = _two_conditions(tmp_path, [0.9], [0.1, 0.2])
    binned = bin_runs(df, bin_size=4)
    result = welch_per_bin(binned, "curious", "mg-te")
    assert result["p"].isna().all() and not result["significant"].any()
    assert across_seeds(binned).query("condition == 'curious'")["std"].isna().all()


def test_comparing_runs_with_different_achievable_modules_is_refused(tmp_path):
    _run(tmp_path, "curious", 0, np.full(8, 0.5))
    curves = {m: np.full(8, 0.5) for m in DEFAULT_MODULES}
    write_run(
        tmp_path / "other",
        condition="mg-te",
        seed=0,
        competence=curves,
        achievable=(True, True, False, False, False, False, False),
        variant="other",
    )
    binned = bin_runs(load_runs(tmp_path), bin_size=4)
    with pytest.raises(AnalysisError, match="different achievable modules"):
        welch_per_bin(binned, "curious", "mg-te")


def test_two_runs_of_one_seed_are_refused(tmp_path):
    _run(tmp_path, "curious", 0, np.full(8, 0.5))
    _run(tmp_path, "curious", 0, np.full(8, 0.6), variant="again")
    _run(tmp_path, "mg-te", 0, np.full(8, 0.5))
    _run(tmp_path, "mg-te", 1, np.full(8, 0.5))
    binned = bin_runs(load_runs(tmp_path), bin_size=4)
    with pytest.raises(AnalysisError, match="'curious' seed 0 has 2 runs"):
        welch_per_bin(binned, "curious", "mg-te")
    with pytest.raises(AnalysisError, match="no runs of condition 'her'"):
        welch_per_bin(binned, "her", "mg-te")


def test_final_competence_is_read_at_the_common_budget(tmp_path):
    _run(tmp_path, "curious", 0, np.arange(10) / 16.0)
    _run(tmp_path, "curious", 1, np.arange(6) / 16.0)
    final = final_competence(load_runs(tmp_path)).set_index("seed")
    assert (final["episodes"] == 6).all()
    assert final.loc[0, "value"] == 5 / 16 and final.loc[1, "value"] == 5 / 16
    with pytest.raises(AnalysisError, match="before 8"):
        final_competence(load_runs(tmp_path), at_episode=8)


def _perturbed(root, condition, seed, curve, p=4):
    curves = {m: np.full(len(curve), 0.75) for m in DEFAULT_MODULES}
    curves["push_cube1"] = np.asarray(curve, dtype=np.float64)
    return write_run(
        root / f"{condition}{seed}",
        condition=condition,
        seed=seed,
        competence=curves,
        achievable=DEFAULT_ACHIEVABLE,
        sensor_failure_episode=p,
    )


def test_recovery_counts_episodes_from_the_perturbation_to_regained_competence(tmp_path):
    # Pre-perturbation level 0.75 (episodes 0-3), threshold 0.675. Episode 4 dips on the way
    # down to 0.625, episode 5 reads 0.6875 by noise, trough 0.25 at episode 7, back at 0.6875 at
    # episode 10: recovered after 10 - 4 + 1 = 7 episodes (the noisy reading at 5 does not count).
    curve = [0.75, 0.75, 0.75, 0.75, 0.625, 0.6875, 0.5, 0.25, 0.375, 0.5, 0.6875, 0.75]
    _perturbed(tmp_path, "curious", 0, curve)
    # Never falls below 0.675: recovery 0. Never comes back: NaN.
    _perturbed(tmp_path, "curious", 1, [0.75] * 4 + [0.6875] * 8)
    _perturbed(tmp_path, "curious", 2, [0.75] * 4 + [0.25] * 8)
    rec = recovery(load_runs(tmp_path), "push_cube1", fraction=0.9, pre_window=4)
    rec = rec.set_index("seed")
    assert rec.loc[0, "pre_competence"] == 0.75
    assert rec.loc[0, "threshold"] == pytest.approx(0.675)
    assert rec.loc[0, "trough_episode"] == 7 and rec.loc[0, "min_competence"] == 0.25
    assert rec.loc[0, "recovery_episodes"] == 7
    assert rec.loc[1, "recovery_episodes"] == 0 and not rec.loc[1, "dropped"]
    assert np.isnan(rec.loc[2, "recovery_episodes"]) and not rec.loc[2, "recovered"]
    summary = recovery_summary(rec.reset_index()).set_index("condition")
    assert summary.loc["curious", "n_runs"] == 3 and summary.loc["curious", "n_recovered"] == 2
    assert summary.loc["curious", "mean_recovery_episodes"] == pytest.approx(3.5)


def test_recovery_needs_a_sensory_failure_or_a_given_episode(tmp_path):
    _run(tmp_path, "curious", 0, np.full(8, 0.5))
    df = load_runs(tmp_path)
    with pytest.raises(AnalysisError, match="has no sensory failure"):
        recovery(df, "reach")
    with pytest.raises(AnalysisError, match="pass module="):
        recovery(df, perturbation_episode=3)  # the default variant perturbs nothing
    at_start = recovery(df, "reach", perturbation_episode=0)
    assert at_start["status"].iat[0] == "not_learned"
    assert "started with the run's first episode" in at_start["note"].iat[0]
    with pytest.raises(KeyError, match="no module 'fly'"):
        recovery(df, "fly", perturbation_episode=3)
    # competence 0.5 at the onset is learned (LEARNED_COMPETENCE) and never falls: 0 episodes
    assert LEARNED_COMPETENCE == 0.5
    assert recovery(df, "reach", perturbation_episode=3)["recovery_episodes"].iat[0] == 0


# ------------------------------------------------------------------------- the sensory failure


def _failure_run(root, condition, seed, curves, **kw):
    """A run of the sensor_failure variant (its modules all achievable), failure columns in kw."""
    return write_run(
        root / f"{condition}{seed}",
        condition=condition,
        seed=seed,
        competence=curves,
        achievable=(True,) * len(FAILURE_MODULES),
        variant="sensor_failure",
        **kw,
    )


def test_the_perturbed_module_is_the_one_the_run_folder_records(tmp_path, monkeypatch):
    """Read from config.json, not from a table of variants in the analysis: a config.json that
    records another module is followed, and one written before the module was recorded gets
    the variant's, as the suite defines it (push_cube3)."""
    monkeypatch.setenv("MUJOCO_GL", "disable")  # no rendering here, and no display to find
    curves = failure_curves(0, 60, None, 10.0)
    _failure_run(tmp_path / "old", "curious", 0, curves)  # no sensor_failure_modules
    assert perturbed_module(load_runs(tmp_path / "old")) == "push_cube3"
    _failure_run(tmp_path / "new", "curious", 0, curves, sensor_failure_modules=["reach"])
    table = load_runs(tmp_path / "new")
    assert set(table["perturbed_modules"]) == {"reach"}
    assert perturbed_module(table) == "reach"
    assert recovery(table, perturbation_episode=30)["module"].iat[0] == "reach"
    with pytest.raises(AnalysisError, match="perturb push_cube3 / reach, not one module"):
        perturbed_module(load_runs(tmp_path))


def test_two_chance_level_curves_make_no_recovery_claim(tmp_path):
    # push_cube3 at chance (0.1) before and after a failure switched on at episode 300: nothing
    # was learned, so nothing can be forgotten or recovered. (Before, this printed "90 %
    # regained after N episodes" for both conditions.)
    for condition in ("curious", "m-uvfa"):
        for seed in (0, 1):
            curves = failure_curves(seed, 600, 300, 50.0, learned=False)
            _failure_run(
                tmp_path,
                condition,
                seed,
                curves,
                sensor_failure_episode=300,
                failure_onset=300,
                log_failure=True,
            )
    df = load_runs(tmp_path)
    per_run = recovery(df)
    assert (per_run["status"] == "not_learned").all()
    assert per_run["recovery_episodes"].isna().all() and not per_run["recovered"].any()
    assert per_run["note"].str.contains("nothing to forget").all()
    assert per_run["note"].str.contains(r"competence 0\.10 < 0\.50 at episode 300").all()
    summary = recovery_summary(per_run).set_index("condition")
    assert (summary["n_started"] == 2).all() and (summary["n_measured"] == 0).all()
    assert summary["mean_recovery_episodes"].isna().all()
    fig, _ = analysis.sensor_failure(df)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == [
        "CURIOUS: not learned before the failure, nothing to forget (2 of 2 seeds)",
        "M-UVFA: not learned before the failure, nothing to forget (2 of 2 seeds)",
    ]
    assert not any("regained" in label for label in labels)


def test_a_failure_that_never_started_is_said_so_not_measured(tmp_path):
    # Started by competence: push_cube3 never reaches 0.5, so no episode ran with the failure.
    curves = failure_curves(0, 400, None, 10.0, learned=False)
    _failure_run(tmp_path, "curious", 0, curves, sensor_failure_competence=0.5, log_failure=True)
    df = load_runs(tmp_path)
    onsets = failure_onsets(df)
    assert onsets["source"].tolist() == ["metrics"] and onsets["onset"].isna().all()
    per_run = recovery(df)
    assert per_run["status"].tolist() == ["never_started"]
    assert per_run["note"].iat[0] == (
        "the failure never started: push_cube3 never reached competence 0.50 over a full window "
        "of its evaluations within 400 episodes (highest 0.10, early values over fewer "
        "evaluations included)"
    )
    assert per_run["recovery_episodes"].isna().all()
    fig, _ = analysis.sensor_failure(df)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["CURIOUS: the failure never started (1 of 1 seeds)"]
    caption = fig.get_supxlabel().replace("\n", " ")
    assert "The failure never started in any run, so no recovery can be measured" in caption
    assert "reached at most 0.10" in caption


def test_the_onset_is_the_first_failing_episode_of_the_metrics(tmp_path):
    # Started by competence at episode 230 (the config has no episode), a fixed episode logged
    # in the column, and an older run without the column whose config gives the episode.
    learned = failure_curves(0, 500, 230, 40.0)
    _failure_run(
        tmp_path,
        "curious",
        0,
        learned,
        sensor_failure_competence=0.5,
        failure_onset=230,
        log_failure=True,
    )
    _failure_run(
        tmp_path,
        "curious",
        1,
        learned,
        sensor_failure_episode=230,
        failure_onset=230,
        log_failure=True,
    )
    _failure_run(tmp_path, "curious", 2, learned, sensor_failure_episode=230)
    _failure_run(tmp_path, "curious", 3, learned, sensor_failure_episode=700)  # beyond the end
    df = load_runs(tmp_path)
    onsets = failure_onsets(df).reset_index(drop=True)
    assert onsets["onset"].tolist() == [230, 230, 230, pd.NA]
    assert onsets["source"].tolist() == ["metrics", "metrics", "config", "config"]
    per_run = recovery(df).set_index("seed")
    assert (per_run.loc[[0, 1, 2], "status"] == "measured").all()
    assert per_run.loc[0, "learned_threshold"] == 0.5  # the run's own threshold
    assert per_run.loc[0, "recovery_episodes"] == per_run.loc[2, "recovery_episodes"] > 0
    assert per_run.loc[3, "status"] == "never_started"
    assert per_run.loc[3, "note"].endswith("the run ended after 500 episodes, before episode 700")


def test_learned_means_the_runs_own_threshold_else_one_half(tmp_path):
    # push_cube3 at 0.4 then 0.7 before the failure at episode 10, 0.2 after.
    curves = {m: np.full(20, 0.25) for m in FAILURE_MODULES}
    curves["push_cube3"] = np.array([0.4] * 9 + [0.7] + [0.2] * 10)
    own_threshold = {"sensor_failure_competence": 0.7, "failure_onset": 10, "log_failure": True}
    _failure_run(tmp_path / "own", "curious", 0, curves, **own_threshold)
    _failure_run(tmp_path / "half", "curious", 1, curves, sensor_failure_episode=10)
    own = recovery(load_runs(tmp_path / "own"))
    # 0.7 is stored as float32 (0.69999999): still "reached 0.7", as the trainer saw it
    assert own["status"].iat[0] == "measured" and own["learned_threshold"].iat[0] == 0.7
    assert own["dropped"].iat[0] and not own["recovered"].iat[0]
    assert "not regained within the 10 episodes after the failure" in own["note"].iat[0]
    half = load_runs(tmp_path / "half")
    assert recovery(half)["status"].iat[0] == "measured"  # 0.7 >= 0.5
    strict = recovery(half, learned=0.8)
    assert strict["status"].iat[0] == "not_learned"
    assert strict["onset_competence"].iat[0] == pytest.approx(0.7)


def test_the_failure_competence_is_read_from_the_nested_config(tmp_path):
    curves = failure_curves(0, 40, None, 10.0)
    _failure_run(tmp_path, "curious", 0, curves, sensor_failure_competence=0.5)
    _failure_run(tmp_path, "curious", 1, curves, sensor_failure_episode=20)
    runs = analysis.runs_table(load_runs(tmp_path)).set_index("seed")
    assert runs.loc[0, "failure_competence"] == 0.5 and pd.isna(runs.loc[0, "perturbation_episode"])
    assert pd.isna(runs.loc[1, "failure_competence"]) and runs.loc[1, "perturbation_episode"] == 20


# ------------------------------------------------------------------------- test rollouts


def _tests_table(root, rows):
    """A run with hand-made test rollouts: rows of (epoch, episode, module, success)."""
    folder = _run(root, "curious", 0, np.full(100, 0.5))
    frame = pd.DataFrame(rows, columns=["epoch", "episode", "module", "success"])
    frame = frame.assign(worker=np.arange(len(frame), dtype=np.int32), g0=0.0, g1=0.0, g2=0.0)
    frame = frame.astype({"epoch": np.int64, "episode": np.int64, "success": bool})
    frame["module_success"] = frame["success"]
    frame["wall_time"] = frame["episode"] * 0.1
    for g in ("g0", "g1", "g2"):
        frame[g] = frame[g].astype(np.float32)
    frame.to_parquet(folder / "tests.parquet", index=False)
    return load_tests(root)


def test_test_success_pools_the_epochs_rollouts_on_achievable_modules(tmp_path):
    rows = [
        (0, 20, "reach", True),
        (0, 20, "reach", True),
        (0, 20, "push_cube1", False),
        (0, 20, "push_cube3", True),  # a distractor: left out
        (1, 40, "stack", True),
        (1, 40, "push_cube4", True),
        (2, 60, "push_cube5", False),  # only distractors tested: no value
        (3, 80, "cube1_above_cube2", False),
        (3, 80, "reach", True),
    ]
    tests = _tests_table(tmp_path, rows)
    points = epoch_success(tests)
    assert points["episodes"].tolist() == [20, 40, 60, 80]
    assert points["n_tests"].tolist() == [3, 1, 0, 2]
    np.testing.assert_allclose(points["value"], [2 / 3, 1.0, np.nan, 0.5])
    # pooled over rollouts, not a mean of per-module rates (which would give (1 + 0) / 2)
    assert points["value"].iat[0] != 0.5
    binned = epoch_success(tests, bin_size=40)
    assert binned["episodes"].tolist() == [40, 80]
    np.testing.assert_allclose(binned["value"], [3 / 4, 1 / 2])
    assert binned["epoch"].tolist() == [1, 3]
    # across seeds and the Welch tests take the points as they take competence bins
    assert across_seeds(points)["n"].tolist() == [1, 1, 1]  # the NaN point is left out
    final = final_success(points)
    assert final["episodes"].tolist() == [80] and final["value"].tolist() == [0.5]


def _two_tests_an_epoch(folder, last: int, both_from: int) -> None:
    """`tests.parquet` of `last` epochs of 10 episodes, a test on reach and one on stack each:
    the reach test succeeds, the stack test from epoch `both_from` on."""
    epochs = np.repeat(np.arange(last), 2)
    success = np.tile([True, False], last) | (epochs >= both_from)
    pd.DataFrame(
        {
            "epoch": epochs.astype(np.int64),
            "episode": ((epochs + 1) * 10).astype(np.int64),
            "worker": np.tile([0, 1], last).astype(np.int32),
            "module": ["reach", "stack"] * last,
            "g0": np.zeros(2 * last, np.float32),
            "g1": np.zeros(2 * last, np.float32),
            "g2": np.zeros(2 * last, np.float32),
            "success": success,
            "module_success": success,
            "wall_time": np.zeros(2 * last),
        }
    ).to_parquet(folder / "tests.parquet", index=False)


def test_final_test_success_is_read_at_the_common_budget(tmp_path):
    """Seed 1 runs two epochs longer, and its stack test succeeds only from its fifth epoch:
    read at the budget both runs reached (30 episodes) it is at 0.5, at its own end at 1.0."""
    for seed, last, both_from in ((0, 3, 2), (1, 5, 4)):
        folder = _run(tmp_path, "curious", seed, np.full(100, 0.5))
        _two_tests_an_epoch(folder, last, both_from=both_from)
    final = final_success(epoch_success(load_tests(tmp_path))).set_index("seed")
    assert (final["episodes"] == 30).all()
    assert final["value"].tolist() == [1.0, 0.5]


def test_the_distractors_test_success_is_the_last_comparison_bin_of_the_common_budget(tmp_path):
    """`final_test_success`: each run's test rollouts pooled over the last of the main
    comparison's bins that every run completed (a longer run read there too)."""
    for seed, last in ((0, 4), (1, 6)):
        folder = _run(tmp_path, "curious", seed, np.full(100, 0.5))
        _two_tests_an_epoch(folder, last, both_from=3 + seed)
    tests = load_tests(tmp_path)
    final = analysis.final_test_success(tests, bin_size=20).set_index("seed")
    assert final.attrs["bin_size"] == 20
    assert (final["episodes"] == 40).all() and (final["n_tests"] == 4).all()
    np.testing.assert_allclose(final["value"], [(1 + 0 + 1 + 1) / 4, (1 + 0 + 1 + 0) / 4])
    default = analysis.final_test_success(tests)  # 20 bins of 60 episodes, rounded down to 2
    assert default.attrs["bin_size"] == 2
    assert (default["episodes"] == 40).all()  # the last such bin every run completed


def test_area_under_success_averages_every_epoch_of_the_common_budget(tmp_path):
    """Each run's epochs up to the budget every run reached weigh the same (an epoch with no
    test on an achievable module is left out), whatever the bins; the result is what the Welch
    test takes, one point a run."""
    for seed, last in ((0, 4), (1, 6)):
        folder = _run(tmp_path, "curious", seed, np.full(100, 0.5))
        # one of two tests succeeds an epoch, both from epoch 2 on (seed 1 one epoch later)
        _two_tests_an_epoch(folder, last, both_from=2 + seed)
    area = analysis.area_under_success(load_tests(tmp_path)).set_index("seed")
    assert (area["episodes"] == 40).all() and (area["n_epochs"] == 4).all()  # 4 epochs each
    np.testing.assert_allclose(area["value"], [(0.5 + 0.5 + 1 + 1) / 4, (0.5 * 3 + 1) / 4])
    test = welch_per_bin(
        area.reset_index().assign(condition=["curious", "mg-te"]), "curious", "mg-te"
    )
    assert test["n_better"].tolist() == [1] and np.isnan(test["p"]).all()  # one seed a side
