"""C5's primary measure: the recovery of the perturbed module's test success after the sensory
failure (`analysis.recovery_by_tests`), and the Welch test on the episodes to recover
(`analysis.compare_recoveries`), and the readings beside them (`analysis.success_after_onset`,
`analysis.returns_below`), on small hand-made tests tables."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from curious import analysis

MODULES = "reach,push_cube1,cube1_above_cube2,push_cube3"
PER_EPOCH = 10
"""Test rollouts of push_cube3 an epoch (a laptop epoch tests it about 10 times)."""


def rollouts(
    run: str,
    successes: Sequence[int],
    condition: str = "curious",
    seed: int = 0,
    epoch_episodes: int = 200,
) -> pd.DataFrame:
    """One run's test rollouts: after every `epoch_episodes` training episodes, `PER_EPOCH` on
    push_cube3 of which `successes[k]` succeed at epoch k, and one on reach (a success), which
    the measure must leave out."""
    rows = []
    for epoch, won in enumerate(successes):
        episode = (epoch + 1) * epoch_episodes
        rows += [(epoch, episode, "push_cube3", i < won) for i in range(PER_EPOCH)]
        rows.append((epoch, episode, "reach", True))
    table = pd.DataFrame(rows, columns=["epoch", "episode", "module", "success"])
    identity = {
        "run": run,
        "condition": condition,
        "seed": seed,
        "variant": "sensor_failure",
        "preset": "laptop",
        "modules": MODULES,
        "achievable_modules": MODULES,
        "n_distractors": 0,
        "perturbation_episode": pd.NA,
        "failure_competence": 0.9,
        "perturbed_modules": "push_cube3",
        "lp_window": 100,
    }
    return pd.concat([pd.DataFrame(identity, index=table.index), table], axis=1)


# (successes per epoch, onset, epoch length) -> what the measure finds
CASES = {
    # Mastered (10/10) until the onset at 2,100 (inside epoch 10, tested at 2,200); test
    # success at 0 for 5 epochs, then back: the first window of 5 epochs all tested after the
    # onset that reaches 0.9 x 1.0 ends at epoch 19 (4,000 episodes), 1,900 after the onset.
    "recovered": ([10] * 10 + [0] * 5 + [10] * 10, 2_100, 200),
    # Level 0.8 before, threshold 0.72 (0.7200000000000001 in floating point): back at exactly
    # 36/50 over epochs 15-19, which counts.
    "recovered at the threshold exactly": (
        [8] * 10 + [0] * 5 + [4] + [8] * 4 + [0] * 3,
        2_100,
        200,
    ),
    # A mild drop: a window reaching back before the onset would read 0.92 at once; the first
    # window wholly after it (epochs 10-14) reads 46/50, so recovered at 3,000, 900 after.
    "a window across the onset does not count": ([10] * 10 + [6] + [10] * 6, 2_100, 200),
    # Down at 3/10 and never back: not recovered, with the episodes it had left.
    "not recovered": ([10] * 10 + [3] * 12, 2_100, 200),
    # The module never reached 0.9: no onset.
    "no onset": ([4] * 12, None, 200),
    # The onset after 3 epochs of tests (100 episodes each): no level before.
    "onset too close to the start": ([10] * 3 + [0] * 10, 350, 100),
}


@pytest.mark.parametrize(
    "case, status, recovered, episodes, note",
    [
        (
            "recovered",
            "measured",
            4_000,
            1_900,
            "test success back at 90% of its level before (1.00) 1,900 episodes after the onset",
        ),
        ("recovered at the threshold exactly", "measured", 4_000, 1_900, "level before (0.80)"),
        ("a window across the onset does not count", "measured", 3_000, 900, "900 episodes"),
        (
            "not recovered",
            "measured",
            None,
            None,
            "test success not back at 90% of its level before (1.00) by the run's end, 2,300 "
            "episodes after the onset",
        ),
        (
            "no onset",
            "no_onset",
            None,
            None,
            "no onset: push_cube3's competence never reached 0.9 within the 2,400 episodes tested",
        ),
        (
            "onset too close to the start",
            "no_level",
            None,
            None,
            "no level before: the failure started at episode 350, after 3 epoch(s) of tests, "
            "fewer than the 5 epochs (500 episodes) its level pools",
        ),
    ],
)
def test_the_recovery_of_test_success_follows_the_fixed_rules(
    case, status, recovered, episodes, note
):
    successes, onset, epoch_episodes = CASES[case]
    tests = rollouts("run-a", successes, epoch_episodes=epoch_episodes)
    row = analysis.recovery_by_tests(tests, {"run-a": onset}).iloc[0]
    assert row["module"] == "push_cube3"  # the one the run folder says its failure perturbs
    assert row["status"] == status and note in row["note"]
    assert row["epoch_episodes"] == epoch_episodes and row["window"] == 5
    assert bool(row["recovered"]) == (recovered is not None)
    if recovered is None:
        assert pd.isna(row["recovered_episode"]) and np.isnan(row["recovery_episodes"])
    else:
        assert row["recovered_episode"] == recovered and row["recovery_episodes"] == episodes
    if status != "measured":
        assert np.isnan(row["level_before"]) and np.isnan(row["threshold"])
        assert pd.isna(row["trough_episode"])


def test_the_level_before_pools_the_five_epochs_before_the_onset_and_the_trough_after():
    """The level: epochs 4-8 (tested at 1,000-1,800), not epoch 9, tested at the onset's own
    episode count (2,000): whether its tests ran with the failure depends on how the rounds were
    collected, so it counts on neither side."""
    successes = [10] * 4 + [9, 9, 8, 8, 6] + [0] + [2] * 5 + [5] * 6
    row = analysis.recovery_by_tests(rollouts("r", successes), {"r": 2_000}).iloc[0]
    assert row["level_before"] == pytest.approx(40 / 50) and row["n_before"] == 50
    assert row["threshold"] == pytest.approx(0.72)
    # windows wholly after the onset: from epoch 10 (2,200) on; the lowest is 10/50 at 3,000
    assert row["trough"] == pytest.approx(0.2) and row["trough_episode"] == 3_000
    assert not row["recovered"] and row["episodes_left"] == 4_200 - 2_000


def test_several_runs_are_measured_at_once_and_onsets_read_from_the_metrics_format():
    """The onsets as `failure_onsets(runs)["onset"]` gives them: a nullable-int Series indexed
    by run."""
    tests = pd.concat(
        [
            rollouts("a", [10] * 10 + [0] * 5 + [10] * 10, "curious", 0),
            rollouts("b", [10] * 10 + [3] * 12, "m-uvfa", 0),
            rollouts("c", [4] * 12, "m-uvfa", 1),
        ],
        ignore_index=True,
    )
    tests["run"] = tests["run"].astype("category")
    onsets = pd.Series([2_100, 2_100, pd.NA], index=["a", "b", "c"], dtype="Int64")
    per_run = analysis.recovery_by_tests(tests, onsets)
    assert per_run["run"].astype(str).tolist() == ["a", "b", "c"]
    assert per_run["status"].tolist() == ["measured", "measured", "no_onset"]
    assert per_run["recovered"].tolist() == [True, False, False]
    assert list(per_run.columns) == list(analysis.RECOVERY_BY_TESTS_COLUMNS)


def test_bad_arguments_are_refused():
    tests = rollouts("r", [10] * 6)
    with pytest.raises(ValueError, match="fraction"):
        analysis.recovery_by_tests(tests, {"r": 700}, fraction=0)
    with pytest.raises(ValueError, match="window"):
        analysis.recovery_by_tests(tests, {"r": 700}, window=0)
    with pytest.raises(KeyError, match="stack"):
        analysis.recovery_by_tests(tests, {"r": 700}, module="stack")
    with pytest.raises(analysis.AnalysisError, match="load_tests"):
        analysis.recovery_by_tests(tests.drop(columns=["epoch"]), {"r": 700})


def _per_run(episodes: dict[str, Sequence[float | None]]) -> pd.DataFrame:
    """A `recovery_by_tests`-like table: per condition, one run a value (None: not recovered)."""
    rows = [
        {
            "run": f"{condition}-{seed}",
            "condition": condition,
            "seed": seed,
            "variant": "sensor_failure",
            "preset": "laptop",
            "achievable_modules": MODULES,
            "n_distractors": 0,
            "status": "measured",
            "recovered": value is not None,
            "recovery_episodes": np.nan if value is None else float(value),
            "note": "not back" if value is None else "back",
        }
        for condition, values in episodes.items()
        for seed, value in enumerate(values)
    ]
    return pd.DataFrame(rows)


def test_curious_faster_is_a_one_tailed_welch_test_on_the_recovered_runs():
    curious, uvfa = [1_000.0, 1_400.0, 1_200.0], [5_000.0, 6_200.0, 5_600.0]
    test = analysis.compare_recoveries(
        _per_run({"curious": curious, "m-uvfa": [*uvfa, None]}), "curious", "m-uvfa"
    )
    expected = stats.ttest_ind(uvfa, curious, equal_var=False, alternative="greater")
    assert test["p"] == pytest.approx(expected.pvalue) and test["t"] == pytest.approx(
        expected.statistic
    )
    assert test["significant"] and test["alpha"] == 0.01
    assert (test["n_faster"], test["n_slower"]) == (3, 3)
    assert test["mean_faster"] == pytest.approx(1_200) and test["mean_slower"] == 5_600
    # the run that never recovered is listed, not given a number
    assert test["unrecovered"]["run"].tolist() == ["m-uvfa-3"]


@pytest.mark.parametrize(
    "episodes",
    [
        {"curious": [1_000.0, 1_200.0], "m-uvfa": [5_000.0, None]},  # one recovered M-UVFA run
        {"curious": [None, None], "m-uvfa": [5_000.0, 6_000.0]},  # no recovered CURIOUS run
    ],
)
def test_fewer_than_two_recovered_runs_a_side_give_no_test(episodes):
    test = analysis.compare_recoveries(_per_run(episodes), "curious", "m-uvfa")
    assert np.isnan(test["p"]) and not test["significant"]
    assert len(test["unrecovered"]) == sum(v is None for vs in episodes.values() for v in vs)


def test_the_course_after_the_onset_reads_the_first_window_wholly_after_it_at_or_past_each_point():
    """`success_after_onset`: epochs every 200 episodes, the onset at 2,100, so the first window
    of 5 epochs wholly after it ends at 3,000; +500 reads there, +1,000 at 3,200, +2,000 at 4,200,
    +3,000 past the run's last tests (NaN); a run without an onset has no row."""
    tests = pd.concat(
        [
            rollouts("a", [10] * 10 + [0] * 5 + [10] * 10),
            rollouts("b", [4] * 12, "m-uvfa"),
        ],
        ignore_index=True,
    )
    offsets = [500, 1_000, 2_000, 3_000]
    after = analysis.success_after_onset(tests, {"a": 2_100, "b": pd.NA}, offsets)
    assert after["run"].astype(str).unique().tolist() == ["a"]
    assert after["offset"].tolist() == offsets
    assert after["episodes"].iloc[:3].tolist() == [3_000, 3_200, 4_200]
    assert after["value"].iloc[:3].tolist() == pytest.approx([0.0, 10 / 50, 1.0])
    assert np.isnan(after["value"].iat[3]) and after["n_tests"].tolist() == [50, 50, 50, 0]
    assert after[["condition", "seed", "onset"]].iloc[0].tolist() == ["curious", 0, 2_100]


def test_the_returns_below_count_the_epochs_under_the_threshold_after_the_crossing():
    """`returns_below`: run a crosses back to 1.0 at 4,000 (threshold 0.9), then one failed epoch
    keeps the next five windows at 0.8, the last tested at 5,000 (2,900 after the onset), before
    a sixth at 1.0; run b crosses and stays; run c never recovers and is not listed."""
    tests = pd.concat(
        [
            rollouts("a", [10] * 10 + [0] * 5 + [10] * 5 + [0] + [10] * 5),
            rollouts("b", [10] * 10 + [0] * 5 + [10] * 10, seed=1),
            rollouts("c", [10] * 10 + [3] * 12, "m-uvfa"),
        ],
        ignore_index=True,
    )
    onsets = {"a": 2_100, "b": 2_100, "c": 2_100}
    by_tests = analysis.recovery_by_tests(tests, onsets)
    back = analysis.returns_below(tests, by_tests).set_index("run")
    assert back.index.astype(str).tolist() == ["a", "b"]
    assert back.loc["a", ["n_after", "n_below", "last_below"]].tolist() == [6, 5, 2_900]
    assert back.loc["b", ["n_after", "n_below"]].tolist() == [5, 0]
    assert pd.isna(back.loc["b", "last_below"]) and back["threshold"].tolist() == [0.9, 0.9]


def test_the_readings_after_the_onset_refuse_what_they_cannot_read():
    tests = rollouts("r", [10] * 10 + [0] * 5 + [10] * 10)
    for offsets in ([], [0, 1_000], [-200]):
        with pytest.raises(analysis.AnalysisError, match="offsets"):
            analysis.success_after_onset(tests, {"r": 2_100}, offsets)
    with pytest.raises(analysis.AnalysisError, match="recovery_by_tests"):
        analysis.returns_below(tests, pd.DataFrame({"run": ["r"]}))
