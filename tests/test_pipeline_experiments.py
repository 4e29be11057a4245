"""The experiment definitions of the budgets (curious/experiments.py)."""

from __future__ import annotations

import re

import pytest

from curious.experiments import (
    BUDGETS,
    DEFAULT_BUDGET,
    EXPERIMENTS,
    Experiment,
    ExperimentError,
    get_budget,
)


@pytest.mark.parametrize("name", list(BUDGETS))
def test_every_run_of_every_budget_resolves_to_a_valid_config(name):
    budget = get_budget(name)
    assert tuple(budget.experiments) == EXPERIMENTS
    runs = budget.runs()
    assert len({r.relative_path for r in runs}) == len(runs)  # one folder per run
    for experiment in budget.experiments.values():
        keys = [r.partition_key for r in experiment.runs()]
        assert len(set(keys)) == len(keys)  # one partition per run
        assert len(keys) == len(experiment.condition_keys) * len(experiment.seed_keys)
    for run in runs:
        config = run.config()
        assert (config.condition, config.seed, config.variant) == (
            run.condition,
            run.seed,
            run.variant,
        )
        assert config.total_episodes == run.total_episodes and config.preset == run.train_preset
        if run.sensor_failure_episode is not None:
            assert 0 < run.sensor_failure_episode < run.total_episodes
            assert run.variant == "sensor_failure"
        if run.sensor_failure_competence is not None:
            assert config.sensor_failure_competence == run.sensor_failure_competence
            assert run.variant == "sensor_failure" and config.sensor_failure_episode == -1


def test_budgets_compare_what_the_paper_compares():
    for budget in BUDGETS.values():
        main, distractors, sensor = (budget.experiments[n] for n in EXPERIMENTS)
        assert main.conditions == ("curious", "mg-te", "her") and main.variants == ("default",)
        assert distractors.conditions == ("curious", "m-uvfa")
        assert distractors.variants == ("distractors_0", "distractors_4", "distractors_7")
        assert sensor.conditions == ("curious", "m-uvfa") and sensor.variants == ("sensor_failure",)
        assert sensor.sensor_failure_episode or sensor.sensor_failure_competence
    assert get_budget("paper").experiments["main"].seeds == (0, 1, 2, 3, 4)
    assert get_budget("paper").experiments["main"].total_episodes == 300_000


def test_the_sensory_failure_starts_on_a_learned_module_or_at_the_authors_epoch():
    # quick and laptop: when push_cube3's competence reaches 0.5, whatever the budget
    for name in ("quick", "laptop"):
        sensor = get_budget(name).experiments["sensor_failure"]
        assert sensor.sensor_failure_competence == 0.5 and sensor.sensor_failure_episode is None
        config = sensor.runs()[0].config()
        assert (config.sensor_failure_competence, config.sensor_failure_episode) == (0.5, -1)
    # paper: the authors' epoch 250 of 316 at 950 episodes an epoch
    paper = get_budget("paper").experiments["sensor_failure"]
    assert paper.sensor_failure_episode == 237_500 and paper.sensor_failure_competence is None
    assert paper.runs()[0].config().sensor_failure_competence == -1.0
    # smoke: a fixed episode, so that the pipeline's tests see a failure start
    assert get_budget("smoke").experiments["sensor_failure"].sensor_failure_episode == 12
    assert (
        "competence reaches 0.5"
        in get_budget("quick").experiments["sensor_failure"].sensor_failure_text
    )


def test_condition_axis_carries_the_variant_only_where_an_experiment_has_several():
    smoke = get_budget("smoke")
    assert smoke.experiments["main"].condition_keys == ("curious", "mg-te", "her")
    assert "m-uvfa@distractors_4" in smoke.experiments["distractors"].condition_keys
    spec = smoke.experiments["distractors"].run("curious@distractors_7|0")
    assert (spec.condition, spec.variant, spec.seed) == ("curious", "distractors_7", 0)
    assert str(spec.relative_path) == "distractors/curious@distractors_7/seed-0"
    with pytest.raises(ExperimentError, match=re.escape("no partition 'curious|9'")):
        smoke.experiments["main"].run("curious|9")


def test_the_quick_budget_is_the_default_and_small():
    quick = get_budget(DEFAULT_BUDGET)
    assert quick.name == "quick" and quick.default_out == "runs/quick"
    assert sum(len(e.runs()) * e.total_episodes for e in quick.experiments.values()) <= 16_000


def test_unknown_names_and_bad_definitions_are_clear_errors():
    with pytest.raises(ExperimentError, match=r"unknown budget 'fast'.*smoke, quick"):
        get_budget("fast")
    with pytest.raises(ExperimentError, match=r"unknown experiment.*'forgetting'"):
        get_budget("smoke").select(["main", "forgetting"])
    assert [e.name for e in get_budget("smoke").select(["sensor_failure", "main"])] == [
        "main",
        "sensor_failure",
    ]
    base = dict(name="main", title="t", variants=("default",), seeds=(0,), train_preset="smoke")
    with pytest.raises(ExperimentError, match="unknown or no conditions"):
        Experiment(conditions=("curious", "random"), total_episodes=10, **base)
    with pytest.raises(ExperimentError, match="must lie inside the run"):
        Experiment(conditions=("curious",), total_episodes=10, sensor_failure_episode=10, **base)
    with pytest.raises(ExperimentError, match="not both"):
        Experiment(
            conditions=("curious",),
            total_episodes=10,
            sensor_failure_episode=5,
            sensor_failure_competence=0.5,
            **base,
        )
    with pytest.raises(ExperimentError, match=r"is not in \(0, 1\]"):
        Experiment(
            conditions=("curious",), total_episodes=10, sensor_failure_competence=1.5, **base
        )
    with pytest.raises(ExperimentError, match="compares"):
        Experiment(conditions=("curious",), total_episodes=10, compare=("curious", "her"), **base)
