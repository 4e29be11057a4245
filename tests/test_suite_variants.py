"""Every registered variant loads, resets and steps with the documented specs (dm_control style:
one test over all registered variants), the registry behaves, and the `sensor_failure` variant is
the authors' perturbation study."""

from __future__ import annotations

import dm_env
import numpy as np
import pytest

import suite
import suite.environment
import suite.task
from suite import catalog, layout

EXPECTED = {
    # variant: (n_modules, n_cubes, n_reachable, state size, achievable flags)
    "default": (7, 5, 2, 49, (True,) * 4 + (False,) * 3),
    "distractors_0": (4, 2, 2, 40, (True,) * 4),
    "distractors_4": (8, 6, 2, 52, (True,) * 4 + (False,) * 4),
    "distractors_7": (11, 9, 2, 61, (True,) * 4 + (False,) * 7),
    "sensor_failure": (4, 3, 3, 55, (True,) * 4),
}


def test_the_paper_variants_are_registered():
    assert set(EXPECTED) <= set(suite.ALL_VARIANTS)
    assert suite.ALL_VARIANTS[0] == "default"


@pytest.mark.parametrize("name", suite.ALL_VARIANTS)
def test_variant_resets_and_steps_with_documented_specs(name):
    env = suite.load(name, seed=0)
    task = env.task
    assert isinstance(task, suite.task.MultiTaskFetch)
    n_mod = len(task.modules)
    n_cubes, n_reachable = task.n_cubes, task.n_reachable
    state_size = 10 + 3 * n_cubes + 12 * n_reachable  # docs/suite.md, the `state` layout
    assert task.state_layout.size == state_size
    achievable = tuple(m.achievable for m in task.modules)
    if name in EXPECTED:
        assert (n_mod, n_cubes, n_reachable, state_size, achievable) == EXPECTED[name]
    outcome_total = sum(m.outcome_dim for m in task.modules)
    shapes = {
        "state": (state_size,),
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
    assert tuple(obs_spec) == suite.task.OBSERVATION_KEYS
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
            module = task.modules[active]
            outcome = obs["achieved"][task.outcome_slices[active]]
            np.testing.assert_array_equal(
                goal[active], module.goal(task.goal_slots[active], outcome)
            )
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
    monkeypatch.setattr(catalog, "REGISTERED", dict(catalog.REGISTERED))

    @suite.register
    def two_distractors(seed=None, **kwargs):
        return suite.build(2, seed=seed, **kwargs)

    assert suite.ALL_VARIANTS[-1] == "two_distractors"
    env = suite.load("two_distractors", seed=3)
    assert env.task.module_names[-2:] == ("push_cube3", "push_cube4")

    with pytest.raises(ValueError, match="already registered"):
        suite.register("default")(two_distractors)
    # a number or a lambda's name once registered, and broke every later unknown-name error
    with pytest.raises(ValueError, match="a variant's name or its function, got 3"):
        suite.register(3)
    with pytest.raises(ValueError, match="got '<lambda>'"):
        suite.register(lambda seed=None, **kwargs: suite.build(2, seed=seed, **kwargs))
    with pytest.raises(TypeError, match="a function that builds the variant"):
        suite.register("five")(5)
    with pytest.raises(ValueError, match="unknown"):
        suite.load("defualt")

    @suite.register
    def forty_two(seed=None, **kwargs):  # was handed back by suite.load as the environment
        return 42

    with pytest.raises(TypeError, match=r"'forty_two' built a int, not a composer\.Environment"):
        suite.load("forty_two")


def test_composer_environment_and_single_call_stepping():
    from dm_control import composer

    env = suite.load("default", seed=0)
    assert isinstance(env, composer.Environment)
    assert env.single_call_stepping
    assert env.control_timestep() == pytest.approx(0.04)
    assert env.physics.timestep() == pytest.approx(0.002)


@pytest.mark.parametrize("variant", suite.ALL_VARIANTS)
def test_fast_step_matches_stock_composer_step_for_step(variant):
    """`SuiteEnvironment` runs a control step's substeps in one physics call; it must give what
    composer's own step gives: observations, rewards and the MuJoCo state, over resets."""
    from dm_control import composer

    fast = suite.load(variant, seed=7)
    stock = suite.load(variant, seed=7, stock=True)
    assert type(fast) is suite.environment.SuiteEnvironment and fast.single_call_stepping
    assert type(stock) is composer.Environment
    actions = np.random.default_rng(0).uniform(-1, 1, (2, 50, 4))
    for episode in range(2):
        for env in (fast, stock):
            env.task.set_next_episode(module=episode % 2, goal=[0.3, -0.2, 0.5])
        steps = [(fast.reset(), stock.reset())]
        steps += [(fast.step(a), stock.step(a)) for a in actions[episode]]
        for t, (a, b) in enumerate(steps):
            assert a.step_type == b.step_type and a.reward == b.reward, (episode, t)
            for key in a.observation:
                np.testing.assert_array_equal(a.observation[key], b.observation[key], key)
        for name in ("qpos", "qvel", "act", "mocap_pos", "mocap_quat"):
            np.testing.assert_array_equal(
                getattr(fast.physics.data, name), getattr(stock.physics.data, name), name
            )


def test_the_fast_step_is_used_only_with_the_dm_control_it_was_checked_against(monkeypatch):
    import suite.environment as environment

    monkeypatch.setattr(environment, "FAST_PATH_DM_CONTROL", "0.0.1")
    with pytest.warns(UserWarning, match="composer's own step"):
        env = suite.load("default", seed=0)
    assert type(env) is not suite.environment.SuiteEnvironment
    monkeypatch.undo()
    monkeypatch.setenv("SUITE_STOCK_COMPOSER", "1")
    assert type(suite.load("default", seed=0)) is not suite.environment.SuiteEnvironment


# -- the sensory failure: the authors' perturbation study ---------------------------------------
# Facts from gym_flowers multi_task_fetch_arm_v3.py (`MultiTaskFetchArm4-v3`, tasks [0, 1, 2, 3]):
# tasks reach, push cube0, cube0 above cube1, push cube2 (our cubes 1, 2, 3), three objects placed
# by `_reset_sim`, and with `self.bias` object2's observed x (`object2_pos[0] += 0.05`) shifted
# before its relative position and the achieved goal are derived from the observation.

CUBE3 = 2  # 0-based index of cube 3, the failing cube
PUSH_CUBE3 = 3  # its module's slot


def cube3_true_position(env) -> np.ndarray:
    """Where cube 3 really is: its body in the physics, not the observation."""
    return env.physics.bind(env.task.cubes[CUBE3].geom).xpos.copy()


def test_sensor_failure_variant_has_the_authors_modules():
    """gym_flowers multi_task_fetch_arm_v3.py: 4 tasks (reach, push cube0, cube0 above cube1,
    push cube2), three reachable cubes, no distractors; the bias perturbs push cube2."""
    task = suite.load("sensor_failure", seed=0).task
    assert task.module_names == ("reach", "push_cube1", "cube1_above_cube2", "push_cube3")
    assert all(m.achievable for m in task.modules)
    assert (task.n_cubes, task.n_reachable) == (3, 3)
    assert task.has_sensor_failure and not task.sensor_failure
    assert task.failing_cube == 3
    assert task.sensor_failure_modules == ("push_cube3",)
    assert task.sensor_failure_module == "push_cube3"
    for name in suite.ALL_VARIANTS:
        if name != "sensor_failure":
            other = suite.load(name, seed=0).task
            assert not other.has_sensor_failure and other.sensor_failure_module is None


def test_sensor_failure_variant_places_three_reachable_cubes_apart():
    """gym_flowers multi_task_fetch_arm_v3.py `_reset_sim`: each object at grip0_xy +
    U(-obj_range, obj_range)^2 (obj_range 0.15), redrawn until 0.1 from the gripper's xy and from
    the objects already placed."""
    env = suite.load("sensor_failure", seed=5)
    sl = env.task.state_layout
    for _ in range(40):
        state = env.reset().observation["state"]
        grip = state[sl.gripper_pos]
        cubes = state[sl.cube_pos].reshape(3, 3)
        np.testing.assert_allclose(cubes[:, 2], 0.425, atol=2e-3)  # resting on the table
        offsets = cubes[:, :2] - grip[:2]
        assert np.all(np.abs(offsets) <= layout.OBJECT_RANGE + 1e-3)
        assert np.all(np.linalg.norm(offsets, axis=1) >= layout.OBJECT_MIN_SEPARATION - 1e-3)
        pair = np.linalg.norm(cubes[:, None, :2] - cubes[None, :, :2], axis=-1) + np.eye(3)
        assert pair.min() >= layout.OBJECT_MIN_SEPARATION - 1e-6
        # Every reachable cube has its relative position, orientation and velocity.
        np.testing.assert_allclose(state[sl.cube_rel_pos].reshape(3, 3), cubes - grip, atol=1e-6)
        np.testing.assert_allclose(state[sl.cube_euler], 0.0, atol=1e-6)
        assert state[sl.cube_vel].shape == (18,)


def test_sensor_failure_shifts_cube3_in_state_and_push_cube3_outcome_only():
    """gym_flowers multi_task_fetch_arm_v3.py: with the bias, object2's x reads +0.05 in its
    position, its position relative to the gripper and the achieved goal of push cube2; the
    simulation is untouched. Ours holds it on every step, switched on at step 20, off at 35, and
    compares with a twin that never fails (same seed, same actions: the same physics)."""
    env, twin = suite.load("sensor_failure", seed=4), suite.load("sensor_failure", seed=4)
    task = env.task
    sl = task.state_layout
    state_idx = list(sl.cube_x_indices(CUBE3))
    assert state_idx == [sl.cube_pos.start + 3 * CUBE3, sl.cube_rel_pos.start + 3 * CUBE3]
    achieved_idx = task.outcome_slices[PUSH_CUBE3].start  # push_cube3's x
    module = task.modules[PUSH_CUBE3]
    actions = np.random.default_rng(2).uniform(-1, 1, size=(50, 4))
    for env_ in (env, twin):
        env_.task.set_next_episode(module="push_cube3")
    pairs = [(env.reset(), twin.reset())]
    for t, a in enumerate(actions):
        if t == 20:
            task.set_sensor_failure(True)
        if t == 35:
            task.set_sensor_failure(False)
        pairs.append((env.step(a), twin.step(a)))
        np.testing.assert_array_equal(cube3_true_position(env), cube3_true_position(twin))
    assert not task.sensor_failure
    for t, (ts, ref) in enumerate(pairs):
        obs = ts.observation
        shift = layout.SENSOR_SHIFT_X if 21 <= t <= 35 else 0.0
        expected = np.zeros_like(obs["state"])
        expected[state_idx] = shift
        np.testing.assert_allclose(obs["state"] - ref.observation["state"], expected, atol=1e-6)
        expected = np.zeros_like(obs["achieved"])
        expected[achieved_idx] = shift
        np.testing.assert_allclose(
            obs["achieved"] - ref.observation["achieved"], expected, atol=1e-6
        )
        for key in ("goal", "task"):
            np.testing.assert_array_equal(obs[key], ref.observation[key])
        others = np.arange(4) != PUSH_CUBE3
        np.testing.assert_array_equal(obs["success"][others], ref.observation["success"][others])
        # Success and reward follow the perceived outcome, as the replay recomputes them.
        achieved = obs["achieved"][task.outcome_slices[PUSH_CUBE3]]
        recomputed = module.reward(achieved, task.goal_slots[PUSH_CUBE3])
        assert obs["success"][PUSH_CUBE3] - 1.0 == recomputed
        if t:
            assert ts.reward == recomputed


def _push_cube3_goal_near_cube3(env, seed: int, dx: float) -> np.ndarray:
    """g putting push_cube3's goal slot `dx` in x from cube 3's true start in the episode that
    `seed` starts (found by a probe episode from the same seed: goals draw nothing extra)."""
    env.random_state.seed(seed)
    env.task.set_next_episode(module="push_cube3", goal=np.zeros(3))
    env.reset()
    x, y, _ = cube3_true_position(env) - np.r_[layout.GRIP0[:2], 0.0]
    return np.array([(x + dx) / layout.OBJECT_RANGE, y / layout.OBJECT_RANGE, 0.0])


@pytest.mark.parametrize(
    ("dx", "without", "with_failure"),
    [
        (-0.01, True, False),  # at the true position (1 cm short of it, away from the threshold)
        (0.04, True, True),  # 0.05 further in x: where the failing sensor sees the cube
        (0.07, False, True),  # beyond the true position's reach, at the perceived one
    ],
)
def test_push_cube3_success_and_reward_follow_the_perceived_cube(dx, without, with_failure):
    """gym_flowers multi_task_fetch_arm_v3.py: the reward of push cube2 compares the goal with
    the achieved goal read from the biased observation, so its perceived success changes."""
    env = suite.load("sensor_failure", seed=0)
    task = env.task
    seed = next(  # an episode whose cube 3 leaves room for the goals in [-1, 1]
        s for s in range(100) if np.all(np.abs(_push_cube3_goal_near_cube3(env, s, 0.07)) <= 1)
    )
    g = _push_cube3_goal_near_cube3(env, seed, dx)
    module = task.modules[PUSH_CUBE3]
    for on, expected in ((False, without), (True, with_failure), (False, without)):
        task.set_sensor_failure(on)
        env.random_state.seed(seed)
        task.set_next_episode(module="push_cube3", goal=g)
        start = env.reset()
        truth = cube3_true_position(env)
        ts = env.step(np.zeros(4))  # the arm hovers: cube 3 stays where it is
        np.testing.assert_allclose(cube3_true_position(env), truth, atol=1e-6)
        slot = task.goal_slots[PUSH_CUBE3]
        assert slot[0] == pytest.approx(truth[0] + dx, abs=1e-6)
        for obs in (start.observation, ts.observation):
            achieved = obs["achieved"][task.outcome_slices[PUSH_CUBE3]]
            shift = layout.SENSOR_SHIFT_X if on else 0.0
            assert achieved[0] == pytest.approx(truth[0] + shift, abs=1e-6)
            assert obs["success"][PUSH_CUBE3] == float(expected)
        assert ts.reward == (0.0 if expected else -1.0)
        assert ts.reward == module.reward(achieved, slot)


def test_sensor_failure_is_refused_where_the_variant_has_none():
    env = suite.load("default", seed=0)
    assert not env.task.has_sensor_failure
    with pytest.raises(ValueError, match="no sensory failure"):
        env.task.set_sensor_failure(True)


def test_reachable_cubes_and_failing_cube_are_checked():
    modules = suite.standard_modules(0)
    with pytest.raises(ValueError, match="n_reachable must be between 1 and 3"):
        suite.task.MultiTaskFetch(modules, n_cubes=4, n_reachable=4)
    with pytest.raises(ValueError, match="n_cubes must be between 3 and 10"):
        suite.task.MultiTaskFetch(modules, n_cubes=11, n_reachable=3)
    with pytest.raises(ValueError, match="failing_cube must be a cube from 1 to 2"):
        suite.task.MultiTaskFetch(modules, n_cubes=2, failing_cube=3)
    # Cube 2 is read by two modules: both are perturbed, and no single one can be named.
    task = suite.task.MultiTaskFetch(modules, n_cubes=2, failing_cube=2)
    assert task.sensor_failure_modules == ("cube1_above_cube2", "stack")
    with pytest.raises(ValueError, match="several modules"):
        _ = task.sensor_failure_module


@pytest.mark.parametrize("seed", ["0", -1, 1.5, True, 2**32])
def test_a_seed_that_numpy_cannot_take_is_named_before_the_task_is_built(seed):
    """Before: numpy's "Cannot cast scalar" or "Seed must be between 0 and 2**32 - 1"."""
    with pytest.raises(ValueError, match=f"seed must be None or an integer .* got {seed!r}"):
        suite.load("default", seed=seed)


@pytest.mark.parametrize("n_distractors", ["3", 2.5])
def test_a_number_of_distractors_that_is_no_integer_is_named(n_distractors):
    with pytest.raises(ValueError, match="n_distractors must be an integer"):
        suite.build(n_distractors)
