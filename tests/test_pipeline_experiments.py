"""The experiment definitions of the budgets (curious/reproduction/experiments.py)."""

from __future__ import annotations

import re
from dataclasses import replace

import pytest

from curious.reproduction.experiments import (
    BEYOND_PAPER,
    BUDGETS,
    DEFAULT_BUDGET,
    EXPERIMENTS,
    Experiment,
    ExperimentError,
    ReproduceBudget,
    budgets_with,
    experiment_names,
    get_budget,
)


@pytest.mark.parametrize("name", list(BUDGETS))
def test_every_run_of_every_budget_resolves_to_a_valid_config(name):
    budget = get_budget(name)
    assert sorted([*budget.experiments, *budget.omitted]) == sorted(experiment_names())
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
        main, distractors = budget.experiments["main"], budget.experiments["distractors"]
        assert main.conditions == ("curious", "mg-te", "her") and main.variants == ("default",)
        assert distractors.conditions == ("curious", "m-uvfa")
        assert distractors.variants == ("distractors_0", "distractors_4", "distractors_7")
    for name in budgets_with("sensor_failure"):
        sensor = get_budget(name).experiments["sensor_failure"]
        assert sensor.conditions == ("curious", "m-uvfa") and sensor.variants == ("sensor_failure",)
        assert sensor.sensor_failure_episode or sensor.sensor_failure_competence
    assert budgets_with("sensor_failure") == ["smoke", "laptop", "paper"]
    assert get_budget("paper").experiments["main"].seeds == (0, 1, 2, 3, 4)
    assert get_budget("paper").experiments["main"].total_episodes == 300_000


def test_the_sensory_failure_starts_on_a_learned_module_or_at_the_authors_epoch():
    # laptop: when push_cube3's competence reaches 0.5, whatever the budget
    sensor = get_budget("laptop").experiments["sensor_failure"]
    assert sensor.sensor_failure_competence == 0.5 and sensor.sensor_failure_episode is None
    config = sensor.runs()[0].config()
    assert (config.sensor_failure_competence, config.sensor_failure_episode) == (0.5, -1)
    # paper: the authors' epoch 250 of 316 at 950 episodes an epoch
    paper = get_budget("paper").experiments["sensor_failure"]
    assert paper.sensor_failure_episode == 237_500 and paper.sensor_failure_competence is None
    assert paper.runs()[0].config().sensor_failure_competence == -1.0
    # smoke: a fixed episode, so that the pipeline's tests see a failure start
    assert get_budget("smoke").experiments["sensor_failure"].sensor_failure_episode == 12
    assert "competence reaches 0.5" in sensor.sensor_failure_text


def test_the_study_on_a_mastered_module_follows_the_rules_fixed_before_its_runs():
    """`sensor_failure_mastered` at `laptop`: the numbers docs/results.md fixed before any of
    its runs trained (C5, "The study as it will be rerun"): CURIOUS against M-UVFA, seeds 0 to
    2, 120,000 episodes each, the failure once push_cube3's competence reaches 0.9 over a full
    window. Changing them is changing the study, not tuning it."""
    mastered = get_budget("laptop").experiments["sensor_failure_mastered"]
    assert mastered.conditions == ("curious", "m-uvfa") and mastered.compare == mastered.conditions
    assert mastered.variants == ("sensor_failure",) and mastered.seeds == (0, 1, 2)
    assert mastered.total_episodes == 120_000 and mastered.train_preset == "laptop"
    assert mastered.sensor_failure_competence == 0.9 and mastered.sensor_failure_episode is None
    config = mastered.runs()[0].config()
    assert (config.sensor_failure_competence, config.sensor_failure_episode) == (0.9, -1)
    assert [str(r.relative_path) for r in mastered.runs()] == [
        f"sensor_failure_mastered/{c}/seed-{s}" for s in (0, 1, 2) for c in ("curious", "m-uvfa")
    ]
    # the earlier study is untouched: its runs are the shipped ones
    assert get_budget("laptop").experiments["sensor_failure"].seeds == (0, 1)
    assert get_budget("laptop").experiments["sensor_failure"].total_episodes == 60_000
    # smoke: a fixed onset, as its sensor_failure's, so that the pipeline's tests see one
    smoke = get_budget("smoke").experiments["sensor_failure_mastered"]
    assert smoke.sensor_failure_episode == 12 and smoke.seeds == (0,)
    assert budgets_with("sensor_failure_mastered") == ["smoke", "laptop"]
    assert EXPERIMENTS.index("sensor_failure_mastered") == EXPERIMENTS.index("sensor_failure") + 1
    smoke_experiments = BUDGETS["smoke"].experiments.values()
    perturbed = {"sensor_failure", "sensor_failure_mastered", "signed_lp"}
    assert all(e.perturbed == (e.name in perturbed) for e in smoke_experiments)


def test_the_studies_beyond_the_paper_follow_the_rules_fixed_before_their_runs():
    """`lp_uses` and `signed_lp` at `laptop`: the numbers docs/results.md fixed before any of
    their runs trained ("Beyond the paper"): each a single change to a shipped protocol, so that
    the shipped runs are what it is read against."""
    laptop = get_budget("laptop")
    uses, signed = laptop.experiments["lp_uses"], laptop.experiments["signed_lp"]
    assert uses.conditions == ("lp-select", "lp-replay") and uses.variants == ("distractors_7",)
    assert uses.seeds == (0, 1, 2) and uses.total_episodes == 50_000
    distractors = laptop.experiments["distractors"]
    # the same runs as the distractors' CURIOUS runs of distractors_7 but for the condition
    theirs = next(r for r in distractors.runs() if r.condition_key == "curious@distractors_7")
    ours = next(r for r in uses.runs() if r.condition == "lp-select" and r.seed == theirs.seed)
    assert replace(ours.config(), condition="curious") == theirs.config()
    assert signed.conditions == ("curious",) and signed.seeds == (0, 1, 2)
    assert signed.overrides == (("lp_measure", "signed"),)
    mastered = laptop.experiments["sensor_failure_mastered"]
    absolute = next(r for r in mastered.runs() if r.condition == "curious" and r.seed == 0)
    assert replace(signed.runs()[0].config(), lp_measure="absolute") == absolute.config()
    # after the paper's experiments, in every budget that trains them; the others say why
    assert EXPERIMENTS[-2:] == ("lp_uses", "signed_lp")
    assert budgets_with("lp_uses") == budgets_with("signed_lp") == ["smoke", "laptop"]
    assert "beyond the paper" in get_budget("paper").omitted["lp_uses"]


@pytest.mark.parametrize(
    "budget, words",
    [
        ("quick", "1,000 episodes a run are far too short for"),
        ("paper", "the failure starts at the authors' epoch 250 (episode 237,500), long after"),
    ],
)
def test_the_budgets_without_the_study_on_a_mastered_module_say_why(budget, words):
    reason = get_budget(budget).omitted["sensor_failure_mastered"]
    assert words in reason
    with pytest.raises(ExperimentError, match="has no sensor_failure_mastered experiment"):
        get_budget(budget).select(["sensor_failure_mastered"])


def test_condition_axis_carries_the_variant_only_where_an_experiment_has_several():
    smoke = get_budget("smoke")
    assert smoke.experiments["main"].condition_keys == ("curious", "mg-te", "her")
    assert "m-uvfa@distractors_4" in smoke.experiments["distractors"].condition_keys
    spec = smoke.experiments["distractors"].run("curious@distractors_7|0")
    assert (spec.condition, spec.variant, spec.seed) == ("curious", "distractors_7", 0)
    assert str(spec.relative_path) == "distractors/curious@distractors_7/seed-0"
    with pytest.raises(ExperimentError, match=re.escape("no partition 'curious|9'")):
        smoke.experiments["main"].run("curious|9")


def test_an_experiment_cut_to_some_variants_names_the_same_run_folders():
    """What a shipped data folder holding one variant's runs stands for (`ShippedData.stands_for`):
    the runs of that variant, at the whole experiment's paths and partition keys."""
    whole = get_budget("laptop").experiments["distractors"]
    cut = whole.with_variants(["distractors_7"])
    assert cut.variants == ("distractors_7",)
    assert cut.left_out_variants == ("distractors_0", "distractors_4")
    assert [r.relative_path for r in cut.runs()] == [
        r.relative_path for r in whole.runs() if r.variant == "distractors_7"
    ]
    assert cut.condition_keys == ("curious@distractors_7", "m-uvfa@distractors_7")
    assert whole.with_variants(["distractors_4", "distractors_0"]).variants == (
        "distractors_0",
        "distractors_4",
    )
    with pytest.raises(ExperimentError, match="no variant"):
        whole.with_variants(["distractors_9"])
    with pytest.raises(ExperimentError, match="at least one variant"):
        whole.with_variants([])


def test_seeds_beyond_the_budgets_are_its_runs_but_for_the_seed_and_named():
    """What a campaign that adds seeds trains and a shipped data folder holding them stands for:
    the budget's runs with another seed, after the budget's own, named in `extra_seeds`."""
    main = get_budget("laptop").experiments["main"]
    more = main.with_seeds([3, 1, 4, 3])
    assert more.seeds == (0, 1, 2, 3, 4) and more.extra_seeds == (3, 4)
    assert more.budget_seeds == main.seeds and main.with_seeds([2]) is main
    runs = more.runs()
    assert [str(r.relative_path) for r in runs[9:12]] == [
        f"main/{c}/seed-3" for c in ("curious", "mg-te", "her")
    ]
    assert runs[:9] == main.runs()
    assert [replace(r, seed=r.seed - 3) for r in runs[9:]] == main.runs()[:6]
    assert more.with_seeds([5]).extra_seeds == (3, 4, 5)
    cut = get_budget("laptop").experiments["distractors"].with_variants(["distractors_7"])
    assert cut.with_seeds([2]).runs()[-1].partition_key == "m-uvfa@distractors_7|2"
    with pytest.raises(ExperimentError, match="not among its seeds"):
        replace(main, extra_seeds=(7,))


def test_every_figure_caption_says_how_many_seeds_it_reads_where_the_paper_budget_has_more():
    """The budget's caption note, and where the figure's experiment reads fewer seeds than the
    `paper` budget trains, how many: seeds beyond the budget's can bring it level, so the count is
    the experiment's, not the budget's."""
    laptop, paper = get_budget("laptop"), get_budget("paper")
    main = laptop.experiments["main"]
    own = "Budget laptop (reduced): 100,000 episodes per run, a third of the paper's 300,000."
    assert laptop.caption_note_for(main) == f"{own} 3 seeds where the `paper` budget trains 5."
    assert laptop.caption_note_for(main.with_seeds([3, 4])) == own
    assert laptop.caption_note_for(main.with_seeds_only([0])).endswith(
        " 1 seed where the `paper` budget trains 5."
    )
    # no `paper` experiment to compare with, or the paper budget itself: the note alone
    mastered = laptop.experiments["sensor_failure_mastered"]
    assert laptop.caption_note_for(mastered) == (
        "Budget laptop (reduced): 120,000 episodes per run, two fifths of the paper's 300,000."
    )
    assert all(paper.caption_note_for(e) == "" for e in paper.experiments.values())
    quick = get_budget("quick")
    assert quick.caption_note_for(quick.experiments["main"]).startswith(quick.caption_note)


@pytest.mark.parametrize(
    "experiment, words",
    [
        ("main", "100,000 episodes per run, a third of the paper's 300,000."),
        ("distractors", "50,000 episodes per run; the paper gives no episode count for this"),
        ("sensor_failure", "60,000 episodes per run, a fifth of the paper's 300,000."),
        ("long", "300,000 episodes per run, as many as the paper's runs, with the `laptop`"),
    ],
)
def test_each_laptop_caption_states_its_own_experiments_episodes_against_the_papers(
    experiment, words
):
    """The `laptop` experiments run 50,000 to 300,000 episodes: no one sentence fits them all."""
    laptop = get_budget("laptop")
    assert words in laptop.caption_note_for(laptop.experiments[experiment])


def test_an_experiment_cut_to_some_seeds_names_the_same_run_folders_and_the_seeds_left_out():
    """What a shipped data folder holding seed 0 of every run stands for: those runs, at the
    same paths, the budget's other seeds named in `left_out_seeds`, the extra ones dropped."""
    whole = get_budget("laptop").experiments["sensor_failure_mastered"]
    cut = whole.with_seeds_only([0])
    assert cut.seeds == (0,) and cut.left_out_seeds == (1, 2) and cut.budget_seeds == (0,)
    assert cut.runs() == [r for r in whole.runs() if r.seed == 0]
    more = get_budget("laptop").experiments["main"].with_seeds([3, 4]).with_seeds_only([2, 0, 3])
    assert more.seeds == (0, 2, 3) and more.extra_seeds == (3,) and more.left_out_seeds == (1,)
    with pytest.raises(ExperimentError, match="no seed"):
        whole.with_seeds_only([7])
    with pytest.raises(ExperimentError, match="at least one seed"):
        whole.with_seeds_only([])
    with pytest.raises(ExperimentError, match="both kept and left out"):
        replace(cut, left_out_seeds=(0,))


def test_the_quick_budget_is_the_default_and_small():
    quick = get_budget(DEFAULT_BUDGET)
    assert quick.name == "quick" and quick.default_out == "runs/quick"
    assert tuple(quick.experiments) == ("main", "distractors") and len(quick.runs()) == 12
    assert sum(len(e.runs()) * e.total_episodes for e in quick.experiments.values()) == 12_000


def test_the_quick_budget_leaves_the_sensory_failure_out_and_says_why():
    """In a quick reproduction the failure never started (push_cube3 not learned by 1,000
    episodes): the budget omits the experiment, and asking for it is a one-line error."""
    quick = get_budget("quick")
    reason = quick.omitted["sensor_failure"]
    assert "in none of the 4 runs" in reason
    assert "`curious reproduce --budget laptop --experiments sensor_failure`" in reason
    assert quick.why_absent("sensor_failure") == (
        f"Budget `quick` leaves out the `sensor_failure` experiment: {reason}."
    )
    with pytest.raises(ExperimentError) as error:
        quick.select(["main", "sensor_failure"])
    message = str(error.value)
    assert message == (
        "budget 'quick' has no sensor_failure experiment (budgets with it: smoke, laptop, "
        f"paper): {reason}"
    )
    assert "\n" not in message
    # a budget that trains the experiment: its absence from an output folder is a missing run
    assert get_budget("laptop").why_absent("sensor_failure") == (
        "The `sensor_failure` experiment has not been reproduced yet: run "
        "`curious reproduce --budget laptop --experiments sensor_failure`."
    )


def test_a_budget_trains_every_experiment_or_says_why_not():
    smoke = get_budget("smoke")
    trained = {n: e for n, e in smoke.experiments.items() if n != "sensor_failure"}
    with pytest.raises(ExperimentError, match="'sensor_failure' must be either trained or omitted"):
        ReproduceBudget("b", "d", trained)  # left out without a reason
    with pytest.raises(ExperimentError, match="'sensor_failure' must be either trained or omitted"):
        ReproduceBudget("b", "d", trained, omitted={"sensor_failure": ""})
    with pytest.raises(ExperimentError, match="'main' must be either trained or omitted"):
        ReproduceBudget("b", "d", smoke.experiments, omitted={"main": "why"})  # both
    with pytest.raises(ExperimentError, match=r"omits unknown experiment\(s\) \['colours'\]"):
        ReproduceBudget("b", "d", smoke.experiments, omitted={"colours": "why"})
    assert ReproduceBudget("b", "d", trained, omitted={"sensor_failure": "why"}).omitted


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


@pytest.mark.parametrize("name", list(BUDGETS))
def test_every_seed_of_every_condition_comes_before_the_next_seed(name):
    for experiment in get_budget(name).experiments.values():
        runs = experiment.runs()
        per_seed = len(experiment.condition_keys)
        for i, seed in enumerate(experiment.seeds):
            chunk = runs[i * per_seed : (i + 1) * per_seed]
            assert {r.seed for r in chunk} == {seed}
            assert [r.condition_key for r in chunk] == list(experiment.condition_keys)


def test_the_long_runs_are_curious_on_the_default_variant_for_the_papers_episodes():
    """`long` at `laptop`: the numbers docs/results.md (C3, "The long runs and the dips: rules
    fixed before their runs") fixed before its runs trained: CURIOUS alone, the main
    comparison's variant and preset, seeds 0 to 4, 300,000 episodes (the paper's), each run the
    main comparison's CURIOUS run in every setting but its length; trained last. Changing them
    is changing the study."""
    laptop = get_budget("laptop")
    long, main = laptop.experiments["long"], laptop.experiments["main"]
    assert long.conditions == ("curious",) and long.variants == ("default",)
    assert long.seeds == (0, 1, 2, 3, 4) and long.total_episodes == 300_000
    assert long.train_preset == main.train_preset == "laptop" and not long.perturbed
    same = main.runs()[0].config()
    assert replace(long.runs()[0].config(), total_episodes=same.total_episodes) == same
    assert [str(r.relative_path) for r in long.runs()] == [
        f"long/curious/seed-{s}" for s in range(5)
    ]
    # the last of the paper's experiments, those beyond the paper after it
    assert EXPERIMENTS[EXPERIMENTS.index("long") + 1 :] == BEYOND_PAPER
    assert budgets_with("long") == ["smoke", "laptop"]
    assert "as many as the paper's runs" in laptop.caption_note_for(long)
    for budget, words in (("quick", "three hundred times a quick run"), ("paper", "already")):
        assert words in get_budget(budget).omitted["long"]
        with pytest.raises(ExperimentError, match="has no long experiment"):
            get_budget(budget).select(["long"])


def test_an_experiments_overrides_reach_every_run_config_and_are_checked():
    base = dict(
        name="main",
        title="t",
        conditions=("curious",),
        variants=("default",),
        seeds=(0, 1),
        train_preset="smoke",
        total_episodes=10,
    )
    signed = Experiment(overrides=(("lp_measure", "signed"),), **base)
    assert {run.config().lp_measure for run in signed.runs()} == {"signed"}
    assert {run.config().lp_measure for run in Experiment(**base).runs()} == {"absolute"}
    # A setting given on the command line (a campaign's torch_threads) still applies on top.
    assert signed.runs()[0].config({"torch_threads": 1}).lp_measure == "signed"
    with pytest.raises(ExperimentError, match=r"unknown setting\(s\) \['lp_sign'\]"):
        Experiment(overrides=(("lp_sign", "signed"),), **base)
    with pytest.raises(ExperimentError, match="the experiment's own fields set"):
        Experiment(overrides=(("total_episodes", 20),), **base)
    with pytest.raises(ExperimentError, match="overridden twice"):
        Experiment(overrides=(("lp_measure", "signed"), ("lp_measure", "absolute")), **base)
