"""Every registered variant loads, resets and steps with the documented specs (dm_control style:
one test over all registered variants), and the registry behaves."""

from __future__ import annotations

import dm_env
import numpy as np
import pytest

import suite
from suite import variants

EXPECTED = {
    # variant: (n_modules, n_cubes, achievable flags)
    "default": (7, 5, (True,) * 4 + (False,) * 3),
    "distractors_0": (4, 2, (True,) * 4),
    "distractors_4": (8, 6, (True,) * 4 + (False,) * 4),
    "distractors_7": (11, 9, (True,) * 4 + (False,) * 7),
    "sensor_failure": (7, 5, (True,) * 4 + (False,) * 3),
}


def test_the_paper_variants_are_registered():
    assert set(EXPECTED) <= set(suite.ALL_VARIANTS)
    assert suite.ALL_VARIANTS[0] == "default"


@pytest.mark.parametrize("name", suite.ALL_VARIANTS)
def test_variant_resets_and_steps_with_documented_specs(name):
    env = suite.load(name, seed=0)
    task = env.task
    assert isinstance(task, suite.MultiTaskFetch)
    n_mod = len(task.modules)
    n_cubes = task.n_cubes
    if name in EXPECTED:
        assert (n_mod, n_cubes, tuple(m.achievable for m in task.modules)) == EXPECTED[name]
    outcome_total = sum(m.outcome_dim for m in task.modules)
    shapes = {
        "state": (34 + 3 * n_cubes,),
        "achieved": (outcome_total,),
        "goal": (3 * n_mod,),
        "task": (n_mod,),
        "success": (n_mod,),
    }

    action_spec = env.action_spec()
    assert action_spec.shape == (4,)
    np.testing.assert_array_equal(action_spec.minimum, -1.0)
    np.testing.assert_array_equal(action_spec.maximum, 1.0)
    obs_spec = env.observation_spec()
    assert tuple(obs_spec) == suite.OBSERVATION_KEYS
    for key, shape in shapes.items():
        assert obs_spec[key].shape == shape, key
        assert obs_spec[key].dtype == np.float32, key

    rng = np.random.default_rng(0)
    for _ in range(2):  # two episodes: the second starts from an automatic reset
        ts = env.reset()
        assert ts.step_type == dm_env.StepType.FIRST
        active = task.active_module
        steps = 0
        while True:
            ts = env.step(rng.uniform(-1.0, 1.0, size=4))
            steps += 1
            obs = ts.observation
            assert set(obs) == set(shapes)
            for key, shape in shapes.items():
                assert obs[key].shape == shape and obs[key].dtype == np.float32, key
            assert ts.reward in (-1.0, 0.0)
            assert ts.reward == obs["success"][active] - 1.0
            assert ts.discount == 1.0
            assert np.all(np.isin(obs["success"], (0.0, 1.0)))
            np.testing.assert_array_equal(obs["task"], np.eye(n_mod, dtype=np.float32)[active])
            goal = obs["goal"].reshape(n_mod, 3)
            np.testing.assert_array_equal(np.delete(goal, active, axis=0), 0.0)
            np.testing.assert_array_equal(goal[active], task.goal_slots[active])
            assert np.all(np.isfinite(obs["state"]))
            if ts.last():
                break
            assert ts.step_type == dm_env.StepType.MID
        assert steps == 50


def test_unknown_variant_names_the_known_ones():
    with pytest.raises(ValueError, match="unknown variant 'nope'") as info:
        suite.load("nope")
    for name in suite.ALL_VARIANTS:
        assert name in str(info.value)


def test_register_adds_a_variant_and_refuses_a_taken_name(monkeypatch):
    monkeypatch.setattr(variants, "_REGISTRY", dict(variants._REGISTRY))

    @suite.register
    def two_distractors(seed=None, **kwargs):
        return suite.build(2, seed=seed, **kwargs)

    assert suite.ALL_VARIANTS[-1] == "two_distractors"
    env = suite.load("two_distractors", seed=3)
    assert env.task.module_names[-2:] == ("push_cube3", "push_cube4")

    with pytest.raises(ValueError, match="already registered"):
        suite.register("default")(two_distractors)


def test_composer_environment_and_single_call_stepping():
    from dm_control import composer

    env = suite.load("default", seed=0)
    assert isinstance(env, composer.Environment)
    assert env.single_call_stepping
    assert env.control_timestep() == pytest.approx(0.04)
    assert env.physics.timestep() == pytest.approx(0.002)
