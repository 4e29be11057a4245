"""Goals reach the networks distinguishable: the fixed goal map of every suite module, from the
first cycle of a run to its last."""

import itertools

import numpy as np
import pytest
import torch
from toy_env import ToyGoalEnv

import suite
from curious.agent.goals import GoalBox, GoalInput
from curious.config import ConfigError
from curious.envs.batch import LocalEnvs
from curious.envs.goal_env import SuiteEnv
from curious.presets import resolve
from curious.runs.driver import train
from curious.runs.trainer import Trainer
from suite import layout

GRID = np.array(list(itertools.product([-1.0, -0.5, 0.0, 0.5, 1.0], repeat=3)))


def goal_inputs(trainer: Trainer, module: int) -> np.ndarray:
    """(len(GRID), G) network inputs of module `module`'s goals drawn at GRID."""
    spec = trainer.spec
    n, g = spec.n_modules, spec.goal_dim
    goals = np.zeros((len(GRID), n, g), np.float32)
    goals[:, module] = trainer.env.goal_slot(module, GRID)
    goal = GoalInput.modular(goals, np.full(len(GRID), module)).map(torch.from_numpy)
    encoded = trainer.agent.encoder.encode_goals(goal)
    return encoded.numpy().reshape(len(GRID), n, g)[:, module]


def assert_goals_distinct_and_unclipped(trainer: Trainer) -> None:
    clip = trainer.config.norm_clip
    box = trainer.agent.encoder.goal_box
    for k, name in enumerate(trainer.spec.module_names):
        x = goal_inputs(trainer, k)
        assert np.all(np.abs(x) < clip), name
        spanned = box.half_width[k] > 0
        # the input is g itself on the coordinates the goal space spans, a constant elsewhere
        np.testing.assert_allclose(x[:, spanned], GRID[:, spanned], atol=1e-5, err_msg=name)
        assert np.all(x[:, ~spanned] == x[0, ~spanned]), name
        distinct_goals = np.unique(GRID[:, spanned], axis=0)
        assert len(np.unique(x.round(5), axis=0)) == len(distinct_goals), name


def test_every_suite_modules_goals_reach_the_networks_distinct_over_a_run(tmp_path):
    # In a run of the real suite, cubes mostly rest: statistics of hindsight outcomes had no
    # spread and mapped every cube1_above_cube2 height to the clip value.
    config = resolve("smoke", overrides={"total_episodes": 48, "progress": False})
    envs = LocalEnvs([SuiteEnv("default", seed=s) for s in range(config.n_workers)])
    trainer = Trainer(config, envs)
    assert_goals_distinct_and_unclipped(trainer)
    while not trainer.done:
        trainer.cycle()
        assert_goals_distinct_and_unclipped(trainer)
    assert trainer.agent.encoder.state_norm.count > 0  # states are still normalised


def test_goal_box_is_read_off_the_modules():
    box = GoalBox.of(SuiteEnv("default", seed=0))
    names = suite.load("default", seed=0).task.modules
    above = [m.name for m in names].index("cube1_above_cube2")
    np.testing.assert_allclose(box.half_width[above], [0, 0, 0.2], atol=1e-6)
    np.testing.assert_allclose(box.scale[above], [0.15, 0.15, 0.2], atol=1e-6)
    toy = GoalBox.of(ToyGoalEnv())
    np.testing.assert_allclose(toy.half_width, [[0.9] * 3, [0.9, 0, 0], [0.9] * 3])


def test_goals_that_follow_cube2_map_into_the_box_of_its_start_region():
    """cube1_above_cube2's and stack's goals are world positions that follow cube 2's xy (the
    authors' env): their slot is the goal with cube 2 at grip0's xy, so they are encoded in a box
    centred on cube 2's start region, grip0 +- 0.15, the same xy encoding as push_cube1's; a
    goal over a cube 2 anywhere it can start encodes within [-1, 1], and a hindsight goal (a
    world position of cube 1) encodes alike for push_cube1 and cube1_above_cube2."""
    env = SuiteEnv("default", seed=0)
    box = GoalBox.of(env)
    names = env.spec.module_names
    push, above, stack = (names.index(n) for n in ("push_cube1", "cube1_above_cube2", "stack"))
    gx, gy = layout.GRIP0[:2]
    np.testing.assert_allclose(box.centre[above], [gx, gy, 0.676], atol=1e-6)
    np.testing.assert_allclose(box.centre[stack], [gx, gy, 0.476], atol=1e-6)
    np.testing.assert_allclose(box.scale[stack], [0.15, 0.15, 0.15], atol=1e-6)
    rng = np.random.default_rng(0)
    cube2 = np.c_[layout.GRIP0[:2] + rng.uniform(-0.15, 0.15, (200, 2)), np.full(200, 0.425)]
    for k in (above, stack):
        module = env.dm_env.task.modules[k]
        gripper, cubes = np.zeros((200, 3)), np.zeros((200, 2, 3))
        cubes[:, 1] = cube2
        slots = env.goal_slot(k, rng.uniform(-1, 1, (200, 3)))
        goals = module.goal(slots, module.achieved(gripper, cubes).astype(np.float32))
        np.testing.assert_allclose(goals[:, :2], cube2[:, :2], atol=1e-6)
        scaled = (goals - box.centre[k]) / box.scale[k]
        assert np.all(np.abs(scaled) <= 1 + 1e-5), names[k]
    hindsight = np.c_[cube2[:, :2], np.full(200, 0.425)].astype(np.float32)
    as_push = (hindsight - box.centre[push]) / box.scale[push]
    as_above = (hindsight - box.centre[above]) / box.scale[above]
    np.testing.assert_allclose(as_push[:, :2], as_above[:, :2], atol=1e-5)


def test_a_goal_map_that_is_not_affine_is_refused():
    class Curved(ToyGoalEnv):
        def goal_slot(self, module, g):
            return np.asarray(g, np.float32) ** 3

    with pytest.raises(ValueError, match="affine"):
        GoalBox.of(Curved())


def test_a_replay_that_cannot_fit_is_refused_before_anything_is_written(tmp_path, monkeypatch):
    import curious.runs.memory

    monkeypatch.setattr(curious.runs.memory, "available_memory", lambda: 2**20)
    config = resolve("smoke", overrides={"progress": False, "total_episodes": 100_000})
    with pytest.raises(ConfigError, match="buffer_episodes"):
        train(config, tmp_path / "run", make_envs=lambda c: [ToyGoalEnv(i) for i in range(2)])
    assert not (tmp_path / "run").exists()


def test_the_policy_sees_each_episodes_goal_where_it_is_at_every_step():
    """The authors' rollout feeds the policy the env's desired goal of every step (rollout.py,
    `self.g[i] = curr_o_new['desired_goal']`), which for cube1_above_cube2 and stack follows
    cube 2: the goals our policy is given are `env.goal` of the episode's slot and the step's
    outcomes."""
    config = resolve("smoke", overrides={"total_episodes": 2, "progress": False})
    envs = LocalEnvs([SuiteEnv("default", seed=s) for s in range(config.n_workers)])
    trainer = Trainer(config, envs)
    k = trainer.spec.module_names.index("cube1_above_cube2")
    trainer.condition.practice_probs = lambda tracker, epoch: np.eye(trainer.spec.n_modules)[k]
    seen = []
    act = trainer.agent.act

    def recording_act(states, goal, *args):
        seen.append(goal.slots.copy())
        return act(states, goal, *args)

    trainer.agent.act = recording_act
    trainer.cycle()
    replay = trainer.replay
    assert replay.size == 2 and np.all(replay.modules[:2] == k)
    T = trainer.spec.episode_length
    for t in range(T):
        expected = envs.reference.goal(k, replay.goals[:2, k], replay.achieved[:2, t])
        np.testing.assert_array_equal(seen[t][:, k], expected)
        others = np.delete(seen[t], k, axis=1)
        np.testing.assert_array_equal(others, 0.0)


@pytest.mark.parametrize("condition", ["curious", "her"])
def test_the_goal_input_drawn_for_episodes_is_the_networks_goal_and_task_input(condition):
    """Paper §3, the E-UVFA input [s, g, task_d]: a condition draws one `GoalInput` per round,
    and the encoder reads exactly it: the practised module's scaled slot and its one-hot task
    descriptor, zero in every other slot (modular conditions); every slot and no descriptor
    (the flat `her`)."""
    from curious.agent.conditions import make_condition
    from curious.agent.inputs import InputEncoder

    env = ToyGoalEnv()
    spec = env.spec
    n_mod, g = spec.n_modules, spec.goal_dim
    config = resolve("smoke", condition, 0)
    rng = np.random.default_rng(4)
    modules = np.array([0, 2, 1, 2])
    raw = rng.uniform(-1.0, 1.0, (len(modules), g))
    goal = make_condition(config, spec).goals(env, modules, raw, rng)
    assert isinstance(goal, GoalInput)
    for i, m in enumerate(modules):  # the episode's own goal stands in its module's slot
        np.testing.assert_array_equal(goal.slots[i, m], env.goal_slot(int(m), raw[i]))
    encoder = InputEncoder(spec, GoalBox.of(env))
    x = encoder.encode(torch.zeros(len(modules), spec.state_dim), goal.map(torch.from_numpy))
    goal_part = x[:, spec.state_dim : spec.state_dim + n_mod * g].reshape(-1, n_mod, g).numpy()
    task_part = x[:, spec.state_dim + n_mod * g :].numpy()
    practised = np.eye(n_mod, dtype=bool)[modules]
    if condition == "her":
        assert np.all(goal.mask == 1) and np.all(task_part == 0)
        assert np.all(np.abs(goal_part).sum(-1) > 0)
    else:
        np.testing.assert_array_equal(goal.mask, practised)
        np.testing.assert_array_equal(task_part, practised)
        assert np.all(goal_part[~practised] == 0) and np.all(goal.slots[~practised] == 0)
        assert np.all(np.abs(goal_part[practised]).sum(-1) > 0)
