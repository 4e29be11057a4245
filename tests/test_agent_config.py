"""Presets, overrides and the errors users get for bad settings."""

import dataclasses
import json

import numpy as np
import pytest

from curious.config import Config, ConfigError
from curious.overrides import format_seeds, parse_overrides, parse_seeds
from curious.presets import PRESETS, resolve
from curious.registry import condition_names


@pytest.mark.parametrize("preset", list(PRESETS))
@pytest.mark.parametrize("condition", condition_names())
def test_every_preset_and_condition_resolves(preset, condition):
    config = resolve(preset, condition, seed=3)
    assert (config.preset, config.condition, config.seed) == (preset, condition, 3)
    assert Config.from_dict(config.to_dict()) == config


def test_settings_of_the_config_are_stated_once_in_it():
    """The authors' eps_task 0.4, replay_k 4 (her_p 0.8), queue_length 300 (lp_window) and the
    evaluation schedule (eval_every, eval_modules) live in `Config` only (pinned by the tests
    below): the replay, the conditions, the competence queues, the LP rule and the recording's
    synthetic run take them from their caller, so a changed value in `Config` cannot be shadowed
    by a second default that drifted."""
    import inspect

    from curious.agent.conditions import CONDITION_CLASSES
    from curious.agent.learning_progress import CompetenceTracker, lp_probabilities
    from curious.agent.replay import EpisodeReplay
    from curious.watching.recording.cost import synthetic_episodes

    uses = [(EpisodeReplay.sample, "her_p"), (lp_probabilities, "eps")]
    uses += [(CompetenceTracker.p_lp, "eps")]
    uses += [(CompetenceTracker.__init__, name) for name in ("window", "measure")]
    uses += [
        (cls.__init__, name)
        for cls in CONDITION_CLASSES.values()
        for name in ("lp_eps", "eval_modules", "eval_every")
    ]
    uses += [(synthetic_episodes, name) for name in ("window", "eval_every", "lp_eps")]
    for function, name in uses:
        default = inspect.signature(function).parameters[name].default
        assert default is inspect.Parameter.empty, (function.__qualname__, name, default)


def test_paper_preset_is_the_authors_protocol():
    """flowersteam/curious, baselines/her/experiment/config.py (MULTI_TASK_PARAMS) and
    train.py: 19 workers x 2 episodes x 25 cycles, 100 batches of 256 per worker, 3 x 256
    networks, lr 1e-3, polyak 0.95, action_l2 1, noise 0.2 / random 0.3, replay_k 4, queue 300,
    eps_task 0.4, 10 test episodes per worker per epoch, 316 epochs."""
    c = resolve("paper")
    assert (c.n_workers, c.episodes_per_worker, c.n_cycles, c.n_updates) == (19, 2, 25, 100)
    assert (c.hidden, c.layers, c.actor_lr, c.critic_lr) == (256, 3, 1e-3, 1e-3)
    assert (c.gamma, c.polyak, c.action_l2, c.noise_eps, c.random_eps) == (0.98, 0.95, 1, 0.2, 0.3)
    assert (c.her_p, c.lp_window, c.lp_eps, c.eval_every, c.norm_clip) == (0.8, 300, 0.4, 10, 5)
    assert c.batch_size == 256 * 19 and c.episodes_per_cycle == 38
    assert c.total_episodes == 300_000
    assert (c.test_rollouts_per_worker, c.moved_threshold, c.replay_active_only) == (10, 1e-3, True)
    assert (c.norm_eps, c.algorithm) == (0.01, "ddpg")
    assert c.lp_measure == "absolute"  # queues.py: CP = |sum(q1) - sum(q2)| / (2 window)


def test_replay_ratio_of_each_preset_is_the_documented_one():
    """flowersteam/curious, baselines/her/experiment/config.py: n_batches 100 of batch_size 256
    per worker per cycle, after rollout_batch_size 2 episodes of T = 50 per worker: 256
    replayed transitions per stored one. The smaller presets replay less (config.py's preset
    comments and docs/agent.md say so)."""
    ratios = {p: resolve(p).samples_per_stored_transition() for p in ("paper", "laptop", "quick")}
    assert ratios == {"paper": 256.0, "laptop": 51.2, "quick": 25.6}


def test_every_preset_forms_p_lp_from_absolute_lp_and_signed_lp_changes_the_run():
    """The paper's absolute LP in every preset (a preset changes the scale, never the
    algorithm). Signed LP changes what a run computes: `curious reproduce --set` refuses it, as
    `--resume` refuses a change of it (tests/test_agent_conditions.py)."""
    from curious.commands.reproduce import placement_overrides

    for preset in PRESETS:
        assert resolve(preset).lp_measure == "absolute"
    assert resolve("laptop", overrides={"lp_measure": "signed"}).lp_measure == "signed"
    with pytest.raises(ConfigError, match="lp_measure would change the budget's runs"):
        placement_overrides(["lp_measure=signed"])


@pytest.mark.parametrize("preset", list(PRESETS))
def test_every_preset_is_synchronous_like_the_authors(preset):
    """flowersteam/curious, baselines/her/experiment/train.py: each cycle rolls out, then trains
    on what it stored; acting never lags learning. The speed settings that would change that
    (`overlap_rollouts`) are off, and those that do not (prefetching, CPU acting copies, worker
    processes) keep their in-process defaults."""
    c = resolve(preset)
    assert not c.overlap_rollouts
    assert (c.prefetch_minibatches, c.act_on_cpu, c.env_processes) == (False, False, 1)


@pytest.mark.parametrize("preset", list(PRESETS))
def test_every_preset_keeps_the_whole_run_in_replay(preset):
    """The authors' per-task buffers (flowersteam/curious, baselines/her/experiment/config.py:
    buffer_size 1e6 transitions) evicted nothing in a 300k-episode run."""
    config = resolve(preset)
    assert config.replay_capacity >= config.total_episodes
    longer = resolve(preset, overrides={"total_episodes": 3 * config.total_episodes})
    assert longer.replay_capacity == longer.total_episodes
    assert resolve(preset, overrides={"buffer_episodes": 100}).replay_capacity == 100
    with pytest.raises(ConfigError, match="buffer_episodes"):
        resolve(preset, overrides={"buffer_episodes": -1})


def test_overrides_are_typed():
    values = parse_overrides(["hidden=64", "her_p=0.5", "progress=false", "algorithm=td3"])
    assert values == {"hidden": 64, "her_p": 0.5, "progress": False, "algorithm": "td3"}
    config = resolve("smoke", overrides=values)
    assert config.hidden == 64 and config.algorithm == "td3"


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: resolve("huge"), "unknown preset 'huge'"),
        (lambda: resolve("smoke", "curiouser"), "unknown condition 'curiouser'"),
        (lambda: parse_overrides(["hiden=3"]), "unknown config key 'hiden'"),
        (lambda: parse_overrides(["hidden=big"]), "hidden='big': expected an integer"),
        (lambda: parse_overrides(["hidden"]), "not of the form key=value"),
        (lambda: parse_overrides(["progress=maybe"]), "expected true or false"),
        (lambda: parse_overrides(["preset=paper"]), "choose the preset with --preset, not an"),
        (lambda: parse_overrides(["condition=her"]), "choose the condition with --condition"),
        (lambda: parse_overrides(["seed=3"]), r"choose the seed with --seed \(or --seeds\)"),
        (lambda: resolve("smoke", overrides={"algorithm": "sac"}), "unknown algorithm 'sac'"),
        (
            lambda: resolve("smoke", overrides={"lp_measure": "relative"}),
            "unknown lp_measure 'relative'; choose one of absolute, signed",
        ),
        (lambda: resolve("smoke", overrides={"her_p": 1.5}), "her_p must be in"),
        (lambda: resolve("smoke", overrides={"n_workers": 0}), "n_workers must be > 0"),
        (lambda: Config.from_dict({"hidden": 3, "colour": 1}), "unknown config keys: colour"),
    ],
)
def test_bad_settings_name_the_problem(call, message):
    with pytest.raises(ConfigError, match=message):
        call()


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: Config(n_workers=2.0), "n_workers must be an int, got 2.0"),
        (lambda: Config(seed="0"), "seed must be an int, got '0'"),
        (lambda: Config(overlap_rollouts="false"), "overlap_rollouts must be a bool, got 'false'"),
        (lambda: Config(hidden=True), "hidden must be an int, got True"),
        (lambda: Config(her_p="0.8"), "her_p must be a float, got '0.8'"),
        (lambda: Config(algorithm=3), "algorithm must be a str, got 3"),
        (lambda: resolve("smoke", overrides={"total_episodes": "30"}), "total_episodes must be"),
        (lambda: dataclasses.replace(resolve("smoke"), n_cycles=1.5), "n_cycles must be an int"),
        (lambda: Config.from_dict({"gamma": "0.98"}), "gamma must be a float"),
    ],
)
def test_a_setting_of_the_wrong_type_is_refused_however_the_config_is_made(build, message):
    """`Config(...)`, `resolve`'s overrides, `dataclasses.replace` and `from_dict` check the
    types alike: a float count or a string flag would otherwise fail deep in numpy or torch,
    or (``"false"`` is truthy) quietly switch a setting on."""
    with pytest.raises(ConfigError, match=message):
        build()


def test_a_numpy_scalar_is_taken_as_its_python_value():
    """A seed or a count from numpy (a table, an ``np.arange`` of seeds) is a valid setting, and
    the config stays what config.json can hold."""
    config = resolve("smoke", seed=np.int64(3), overrides={"n_workers": np.int32(2)})
    config = dataclasses.replace(config, her_p=np.float32(0.5), progress=np.bool_(False))
    assert (config.seed, config.n_workers, config.her_p, config.progress) == (3, 2, 0.5, False)
    assert all(type(v) in (int, float, bool, str) for v in dataclasses.asdict(config).values())
    json.dumps(config.to_dict())
    with pytest.raises(ConfigError, match=r"n_workers must be an int, got 2\.0"):
        Config(n_workers=np.float64(2.0))


def test_an_int_given_for_a_float_setting_is_that_float():
    assert Config(actor_lr=1).actor_lr == 1.0 and isinstance(Config(actor_lr=1).actor_lr, float)
    assert isinstance(Config.from_dict({"noise_eps": 0}).noise_eps, float)
    assert isinstance(resolve("smoke", overrides={"her_p": 1}).her_p, float)


@pytest.mark.parametrize(
    "setting",
    [
        "noise_eps=nan",
        "action_l2=-1",
        "norm_eps=0",
        "norm_clip=inf",
        "critic_lr=-0.001",
        "actor_lr=nan",
        "moved_threshold=-1e-3",
        "td3_noise_clip=-0.5",
        "gamma=nan",
    ],
)
def test_settings_out_of_range_are_refused_naming_the_setting(setting):
    key = setting.split("=")[0]
    with pytest.raises(ConfigError, match=key):
        resolve("smoke", overrides=parse_overrides([setting]))


@pytest.mark.parametrize(
    ("seeds", "written"),
    [((0,), "0"), ((0, 1, 2, 3, 4), "0-4"), ((0, 2, 5), "0,2,5"), ((3, 0, 1, 7, 8), "0-1,3,7-8")],
)
def test_seeds_are_written_as_seeds_takes_them(seeds, written):
    """The hint that resumes a `--seeds` folder names its seeds the way `--seeds` reads them."""
    assert format_seeds(seeds) == written
    assert sorted(parse_seeds(written)) == sorted(seeds)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["n_workers=4"], r"got a list: parse_overrides turns"),
        ("n_workers=4", r"got a str: parse_overrides turns"),
        ({"preset": "paper"}, "preset is resolve's own argument"),
        ({"condition": "her"}, "condition is resolve's own argument"),
        ({"seed": 5}, "seed is resolve's own argument"),
    ],
)
def test_resolve_takes_settings_as_a_mapping_and_never_its_own_arguments(overrides, message):
    """The command line's strings passed straight in failed with "'list' object has no
    attribute 'items'"; `{"preset": "paper"}` labelled a run of smoke numbers `paper`."""
    with pytest.raises(ConfigError, match=message):
        resolve("smoke", overrides=overrides)
    assert resolve("smoke", overrides=parse_overrides(["n_workers=4"])).n_workers == 4


def test_overrides_are_a_list_and_their_values_are_read_without_spaces():
    """`parse_overrides("n_workers=4")` said "override 'n' is not of the form key=value";
    `variant= default` kept its space, an unknown variant far later."""
    with pytest.raises(ConfigError, match=r"a list of 'key=value' strings, got one: \['n_w"):
        parse_overrides("n_workers=4")
    assert parse_overrides(["variant= default", " n_workers = 4 "]) == {
        "variant": "default",
        "n_workers": 4,
    }


@pytest.mark.parametrize("data", [None, [("seed", 0)], "seed=0"])
def test_a_config_is_read_from_a_mapping_only(data):
    """`Config.from_dict(None)` was "'NoneType' object is not iterable"."""
    with pytest.raises(ConfigError, match="a config is a mapping of settings"):
        Config.from_dict(data)
