"""A wrong call of the analysis API (the wrong kind of table, a table filtered to nothing, a
name where a list is meant, one condition compared with itself) is an `AnalysisError` that names
the mistake, not a pandas KeyError from deep inside, and never a silently wrong number."""

from __future__ import annotations

import pandas as pd
import pytest

from curious import analysis
from curious.analysis import AnalysisError
from tests.test_analysis_synthetic import (
    write_distractor_study,
    write_perturbation_study,
    write_study,
)


@pytest.fixture(scope="module")
def main(tmp_path_factory) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A made-up main comparison: its runs table and its test rollouts."""
    root = tmp_path_factory.mktemp("main")
    write_study(root, seeds=(0, 1), n_episodes=200, tests_per_epoch=20)
    return analysis.load_runs(root), analysis.load_tests(root)


@pytest.fixture(scope="module")
def distractors(tmp_path_factory) -> pd.DataFrame:
    """Made-up distractor runs' test rollouts, 0 and 4 distracting modules, 2 seeds a side."""
    root = tmp_path_factory.mktemp("distractors")
    write_distractor_study(root, counts=(0, 4), seeds=(0, 1), n_episodes=200, tests_per_epoch=20)
    return analysis.load_tests(root)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda runs, tests: analysis.final_competence(tests), "test rollouts \\(load_tests\\)"),
        (lambda runs, tests: analysis.bin_runs(tests), "pass a table from .*load_runs"),
        (lambda runs, tests: analysis.competence_crossings(tests), "no competence/<module>"),
        (lambda runs, tests: analysis.mastery_drops(tests), "no competence/<module>"),
        (lambda runs, tests: analysis.fig2b(tests), "no competence/<module>"),
        (lambda runs, tests: analysis.across_seeds(tests), "through epoch_success first"),
        (lambda runs, tests: analysis.welch_per_bin(runs, "curious", "mg-te"), "through bin_runs"),
        (lambda runs, tests: analysis.final_success(tests), "lacks episodes, value"),
        (lambda runs, tests: analysis.learning_order(runs), "takes a competence_crossings table"),
        (
            lambda runs, tests: analysis.compare_degradation(runs, "curious", "m-uvfa"),
            "pass final_competence",
        ),
    ],
)
def test_the_wrong_kind_of_table_is_named(main, call, message):
    """A tests table where a runs table is meant (and the reverse): before, a pandas KeyError
    (`'competence/reach'`, `['value']`), or for `learning_order`, 14 s a run of nonsense."""
    with pytest.raises(AnalysisError, match=message):
        call(*main)


@pytest.mark.parametrize(
    "call",
    [
        lambda runs, tests: analysis.binned_success(tests[tests["condition"] == "m-uvfa"]),
        lambda runs, tests: analysis.final_competence(runs[runs["variant"] == "nope"]),
        lambda runs, tests: analysis.bin_runs(runs.iloc[:0]),
        lambda runs, tests: analysis.perturbed_module(runs.iloc[:0]),
    ],
)
def test_a_table_filtered_to_nothing_says_so(main, call):
    """Before: `cannot convert float NaN to integer` or an IndexError."""
    with pytest.raises(AnalysisError, match="has no rows \\(filtered to nothing"):
        call(*main)


def test_across_seeds_does_not_average_variants_as_seeds(distractors):
    """Runs of 0 and 4 distracting modules under one condition and seed were averaged as if
    they were four seeds; grouped by variant they are two a side."""
    points = analysis.final_test_success(distractors)
    clash = r"condition curious, seed 0 has 2 runs \(their variant: distractors0, distractors4"
    with pytest.raises(AnalysisError, match=clash):
        analysis.across_seeds(points)
    means = analysis.across_seeds(points, by=("condition", "variant"))
    assert set(means["n"]) == {2}


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda points: analysis.across_seeds(points, by="condition"), "not a str"),
        (lambda points: analysis.across_seeds(points, by=["colour"]), "no column 'colour'"),
        (lambda points: analysis.welch_per_bin(points, "curious", "curious"), "'curious' twice"),
    ],
)
def test_arguments_of_the_statistics_are_checked(main, call, message):
    points = analysis.binned_success(main[1])
    with pytest.raises(AnalysisError, match=message):
        call(points)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"conditions": "curious"}, r"conditions takes a sequence of names, e.g. \['curious'\]"),
        ({"compare": "curious"}, "compare takes two conditions"),
        ({"compare": ("curious", "curious")}, "'curious' twice"),
    ],
)
def test_fig2a_reads_its_conditions_as_names_not_letters(main, tmp_path, kwargs, message):
    """Before: "no runs of condition(s) c, u, r, i, o, u, s" and "compares 'c' with 'u'"."""
    with pytest.raises(AnalysisError, match=message):
        analysis.fig2a(main[1], out_dir=tmp_path, **kwargs)


def test_fig2a_of_rollouts_on_no_achievable_module_says_so(main, tmp_path):
    """Before: KeyError 'episodes' from the drawing."""
    tests = main[1]
    with pytest.raises(AnalysisError, match="none of these test rollouts is on an achievable"):
        analysis.fig2a(tests[tests["module"] == "push_cube3"], out_dir=tmp_path)


def test_a_seed_given_as_text_is_named(main, tmp_path):
    """Before: "condition 'curious' has no seed 0 (seeds: 0, 1)"."""
    with pytest.raises(AnalysisError, match="seed must be an int, got '0'"):
        analysis.fig2b(main[0], seed="0", out_dir=tmp_path)


@pytest.mark.parametrize("figure", ["fig2b", "fig2c", "table1"])
def test_a_condition_that_never_self_evaluates_has_no_competence_figure(main, tmp_path, figure):
    """HER scores its holistic goal only: its competence columns are all NaN (as in
    data/laptop/main/her), and its Fig. 2b was an empty plot."""
    runs = main[0].copy()
    competence = [c for c in runs.columns if c.startswith("competence/")]
    runs.loc[runs["condition"] == "her", competence] = float("nan")
    with pytest.raises(AnalysisError, match="condition 'her' has no self-evaluated competence"):
        getattr(analysis, figure)(runs, condition="her", out_dir=tmp_path)
    getattr(analysis, figure)(runs, condition="curious", out_dir=tmp_path)


def test_learning_order_names_a_module_no_run_has(main):
    """A typo in a given order made every run's `follows_paper` NA without a word."""
    crossings = analysis.competence_crossings(main[0])
    with pytest.raises(AnalysisError, match="order names modules no run has: push_cub1"):
        analysis.learning_order(crossings, order=[["reach"], ["push_cub1"]])
    with pytest.raises(AnalysisError, match="groups of module names"):
        analysis.learning_order(crossings, order=["reach", "push_cube1"])
    assert len(analysis.learning_order(crossings)) == 6  # the paper's order, as before


def test_recovery_by_tests_refuses_onsets_of_other_runs(tmp_path):
    """Onsets keyed by other paths made every run `no_onset`, silently."""
    runs = write_perturbation_study(tmp_path, seeds=(0, 1), tests_per_epoch=20)
    tests = analysis.load_tests(runs)
    onsets = analysis.failure_onsets(analysis.load_runs(runs))["onset"]
    assert (analysis.recovery_by_tests(tests, onsets)["status"] != "no_onset").all()
    relative = {f"elsewhere/{k}": v for k, v in onsets.items()}
    with pytest.raises(AnalysisError, match="onsets name none of these test rollouts' runs"):
        analysis.recovery_by_tests(tests, relative)
    with pytest.raises(AnalysisError, match="got a list"):
        analysis.recovery_by_tests(tests, list(onsets))


def test_compare_recoveries_takes_a_recovery_table_and_checks_its_conditions(tmp_path):
    runs = write_perturbation_study(tmp_path, seeds=(0, 1, 2))
    per_run = analysis.recovery(analysis.load_runs(runs))
    result = analysis.compare_recoveries(per_run, "curious", "m-uvfa")  # a KeyError before
    assert result["n_faster"] == 3 and result["mean_faster"] < result["mean_slower"]
    with pytest.raises(AnalysisError, match="no runs of condition 'curios'"):
        analysis.compare_recoveries(per_run, "curios", "m-uvfa")  # n_faster 0, p NaN before
    with pytest.raises(AnalysisError, match="'curious' twice"):
        analysis.compare_recoveries(per_run, "curious", "curious")  # p = 0.5 before


@pytest.mark.parametrize("given", [None, 5, b"data/laptop", [None]])
def test_what_is_no_path_is_named_where_run_folders_are_meant(given):
    """Before: "'NoneType' object is not iterable", or a TypeError from pathlib."""
    with pytest.raises(AnalysisError, match=r"pass (a run folder|run folders)"):
        analysis.load_runs(given)


def test_the_sensory_failure_figure_refuses_test_rollouts_of_other_runs(tmp_path):
    """Before: "no module 'push_cube3' in these runs' test rollouts", which they had."""
    runs = write_perturbation_study(tmp_path / "a", seeds=(0, 1))
    others = write_perturbation_study(tmp_path / "b", seeds=(0, 1), tests_per_epoch=20)
    with pytest.raises(AnalysisError, match="must be those of the same runs"):
        analysis.sensor_failure(
            analysis.load_runs(runs), tests=analysis.load_tests(others), out_dir=tmp_path
        )


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda tests: analysis.epoch_success(tests, bin_size=2500.5), "bin_size must be an int"),
        (lambda tests: analysis.module_test_success(tests, window=2.5), "window must be an int"),
        (lambda tests: analysis.module_success_rates(tests, epochs=2.5), "epochs must be an int"),
        (lambda tests: analysis.binned_success(tests, bin_size=True), "bin_size must be an int"),
    ],
)
def test_a_window_or_a_bin_width_is_a_whole_count(main, call, message):
    """Before: float bin labels, or pandas' "min_periods must be an integer"."""
    with pytest.raises(ValueError, match=message):
        call(main[1])


def test_nice_bin_size_of_an_endless_run_is_refused():
    """`nice_bin_size(inf)` looped for ever."""
    with pytest.raises(ValueError, match="need n_episodes >= 1"):
        analysis.nice_bin_size(float("inf"))


def test_a_table_of_one_value_per_module_is_not_read_as_seeds(main):
    """`module_success_rates` (one row per run and module) went into `welch_per_bin` and
    `across_seeds` as if each module were a seed: 2 seeds x 4 modules counted as 8."""
    rates = analysis.module_success_rates(main[1])
    with pytest.raises(AnalysisError, match=r"holds 4 for run .* \(one per module\).*4 seeds"):
        analysis.welch_per_bin(rates, "curious", "mg-te")
    with pytest.raises(AnalysisError, match=r"select one, or pass by=\(\.\.\., 'module'\)"):
        analysis.across_seeds(rates)
    per_module = analysis.across_seeds(rates, by=("condition", "module"))
    assert set(per_module["n"]) == {2}


def test_runs_of_one_setting_read_twice_count_once_or_are_refused(main, tmp_path):
    """Two folders of the same runs (a copy, or two experiments' runs at the same settings)
    were told to "select one variant", which they share."""
    write_study(tmp_path / "copy", seeds=(0, 1), n_episodes=200, tests_per_epoch=20)
    both = pd.concat([main[1], analysis.load_tests(tmp_path / "copy")], ignore_index=True)
    with pytest.raises(AnalysisError, match=r"their runs: .*read one experiment's runs"):
        analysis.across_seeds(analysis.epoch_success(both))


def test_the_area_under_success_refuses_runs_of_several_experiments(main, distractors):
    """Runs of two variants (or presets) were all read up to the shortest one's budget, and a
    run with no epoch by then was dropped without a word."""
    with pytest.raises(AnalysisError, match=r"different variants \(distractors0, distractors4"):
        analysis.area_under_success(distractors)
    mixed = pd.concat([main[1], distractors.assign(preset="other")], ignore_index=True)
    with pytest.raises(AnalysisError, match="different presets"):
        analysis.area_under_success(mixed)
    assert len(analysis.area_under_success(main[1])) == 6


def test_the_degradation_counts_each_seed_once(tmp_path):
    """The sensory failure's runs (no distractors either) were pooled with `distractors_0`'s,
    and a table concatenated twice doubled every group, each with a confident p."""
    study = write_distractor_study(tmp_path / "d", counts=(0, 4), seeds=(0, 1), n_episodes=200)
    failure = write_perturbation_study(tmp_path / "f", seeds=(0, 1))
    final = analysis.final_competence(analysis.load_runs(study))
    analysis.compare_degradation(final, "curious", "m-uvfa")
    with pytest.raises(AnalysisError, match="seed 0 has several runs with 0 distracting"):
        analysis.compare_degradation(pd.concat([final, final]), "curious", "m-uvfa")
    pooled = analysis.final_competence(analysis.load_runs([*study, *failure]))
    with pytest.raises(AnalysisError, match=r"0 distracting modules are of several variants"):
        analysis.compare_degradation(pooled, "curious", "m-uvfa")


def test_recoveries_count_each_seed_once_at_an_alpha_that_is_one(tmp_path):
    """Two experiments' recoveries pooled counted each seed twice; alpha=5 called p = 0.04
    significant; a runs table gave pandas' KeyError 'status'."""
    runs = write_perturbation_study(tmp_path, seeds=(0, 1, 2))
    per_run = analysis.recovery(analysis.load_runs(runs))
    doubled = pd.concat([per_run, per_run], ignore_index=True)
    for call in (analysis.recovery_summary, lambda t: analysis.compare_recoveries(t, *CF)):
        with pytest.raises(AnalysisError, match=r"seed 0 has 2 rows .*each seed must count once"):
            call(doubled)
    with pytest.raises(ValueError, match=r"alpha must be in \(0, 1\), got 5"):
        analysis.compare_recoveries(per_run, *CF, alpha=5)
    with pytest.raises(AnalysisError, match=r"lacks status.*pass a recovery table"):
        analysis.recovery_summary(analysis.load_runs(runs))


CF = ("curious", "m-uvfa")


def test_a_bin_no_run_completed_is_named_not_returned_empty(main):
    """An empty table went on as "the runs have no test rollouts yet"."""
    runs, tests = main
    for call in (
        lambda: analysis.epoch_success(tests, 10**9),
        lambda: analysis.final_test_success(tests, 10**9),
        lambda: analysis.bin_runs(runs, bin_size=10**9),
    ):
        with pytest.raises(AnalysisError, match="bin_size 1,000,000,000 is longer than every run"):
            call()


def test_values_given_as_a_series_are_read_by_label_and_as_numbers(main):
    """A Series of a table in another row order was read by position (values wrong by up to
    0.94, silently); a column of names failed in pyarrow."""
    runs = main[0]
    reach = runs["competence/reach"]
    shuffled = runs.sample(frac=1, random_state=0)
    pd.testing.assert_frame_equal(
        analysis.bin_runs(shuffled, values=reach, bin_size=50),
        analysis.bin_runs(runs, values=reach, bin_size=50),
    )
    with pytest.raises(ValueError, match="index is not the table's rows"):
        analysis.bin_runs(runs, values=reach.set_axis(reach.index + 10**6), bin_size=50)
    with pytest.raises(AnalysisError, match="'module' holds no numbers"):
        analysis.bin_runs(runs, values="module", bin_size=50)


@pytest.mark.parametrize("levels", ["0.5", True, None])
def test_one_level_is_a_number_and_anything_else_is_named(main, levels):
    """`levels=0.5` was "'float' object is not iterable"; a string was read digit by digit."""
    tests = main[1]
    one = analysis.episodes_to_test_success(tests, levels=0.5)
    assert set(one["level"]) == {0.5}
    with pytest.raises(ValueError, match="levels takes numbers in"):
        analysis.episodes_to_test_success(tests, levels=levels)


@pytest.mark.parametrize("order", [(), [["reach"], ["reach", "stack"]]])
def test_an_order_names_each_module_once(main, order):
    """`order=()` marked every run as following it; a module twice was taken."""
    crossings = analysis.competence_crossings(main[0])
    with pytest.raises(AnalysisError, match="order takes each module once"):
        analysis.learning_order(crossings, order=order)


def test_a_figure_named_with_its_extension_is_written_once_so(tmp_path):
    """`save_figure(fig, out, "fig.png")` wrote fig.png.png and fig.png.svg."""
    import matplotlib.pyplot as plt

    fig = plt.figure()
    paths = analysis.save_figure(fig, tmp_path, "fig.png")
    plt.close(fig)
    assert sorted(p.name for p in paths.values()) == ["fig.png", "fig.svg"]


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda r, t: analysis.final_competence(r, at_episode="50"), "at_episode must be an"),
        (lambda r, t: analysis.final_competence(r, at_episode=50.5), "at_episode must be an"),
        (lambda r, t: analysis.final_competence(r, at_episode=True), "at_episode must be an"),
        (lambda r, t: analysis.final_competence(r, at_episode=-5), "at_episode must be an"),
        (
            lambda r, t: analysis.welch_per_bin(analysis.epoch_success(t), *CM, alpha="0.01"),
            r"alpha must be in \(0, 1\), got '0.01'",
        ),
        (
            lambda r, t: analysis.welch_per_bin(analysis.epoch_success(t), ["curious"], "mg-te"),
            "two conditions by name",
        ),
        (lambda r, t: analysis.nice_bin_size("100"), "need n_episodes >= 1"),
    ],
)
def test_an_argument_of_the_wrong_type_is_named(main, call, message):
    """Before: a TypeError from a comparison, "unhashable type: 'list'", a numpy ufunc error,
    or a float or bool episode taken as one."""
    with pytest.raises((ValueError, AnalysisError), match=message):
        call(*main)


@pytest.mark.parametrize("episode", [-5, "1000", 2.5])
def test_an_imposed_perturbation_episode_is_an_episode(tmp_path, episode):
    """`recovery(..., perturbation_episode='1000')` was parsed; -5 and 2.5 were taken."""
    runs = analysis.load_runs(write_perturbation_study(tmp_path, seeds=(0,)))
    with pytest.raises(ValueError, match="perturbation_episode must be an episode"):
        analysis.recovery(runs, perturbation_episode=episode)


CM = ("curious", "mg-te")
