"""The conditions: the flat baseline's goal space and score, which modules are self-evaluated and
practised (the paper's text or the released code's rule), mg-te's epochs, task replay over the
modules that have something to replay, and CURIOUS's two uses of LP apart (lp-select, lp-replay)
with signed LP."""

import numpy as np
import pyarrow.parquet as pq
import pytest
from toy_env import ToyGoalEnv, make_toy_envs

from curious.agent.conditions import HER, MGTE, MUVFA, Curious, LPReplay, LPSelect
from curious.agent.goals import HolisticGoals
from curious.agent.learning_progress import CompetenceTracker, lp_probabilities
from curious.config import ConfigError
from curious.envs.batch import LocalEnvs
from curious.envs.goal_env import EnvSpec
from curious.envs.rollout import EpisodeData
from curious.presets import PRESETS, resolve
from curious.runs.driver import train
from curious.runs.folder_errors import RunFolderError
from curious.runs.trainer import Trainer

SPEC = ToyGoalEnv.spec

# Three modules of 3-D goals; the last one's outcome has a fourth number after its goal part, as
# the suite's `stack` watches the gripper for its guard.
GUARDED = EnvSpec(
    module_names=("a", "b", "stack"),
    achievable=(True, True, True),
    state_dim=1,
    action_dim=1,
    goal_dim=3,
    outcome_slices=(slice(0, 3), slice(3, 6), slice(6, 10)),
    episode_length=2,
    success_distance=0.05,
)


# ----------------------------------------------------------------------------- the flat baseline


def test_the_holistic_goal_is_met_only_within_one_distance_over_every_coordinate():
    """gym_flowers multi_task_fetch_arm_v0.py, `compute_reward` with `set_flat_env`: the flat
    agent's reward (and, through `_is_success`, its success) is -(d > 0.05) for d the Euclidean
    distance between the whole goal and every task's goal part of the outcome, with no stack
    guard."""
    space = HolisticGoals(GUARDED)
    achieved = np.zeros(10, np.float32)
    goals = np.zeros((3, 3), np.float32)
    assert space.success(achieved, goals) and space.reward(achieved, goals) == 0
    off = goals.copy()
    off[:, 0] = 0.04  # every module within 0.05 of its slot, together 0.069 away
    assert space.distance(achieved, off) == pytest.approx(0.04 * np.sqrt(3), rel=1e-6)
    assert not space.success(achieved, off) and space.reward(achieved, off) == -1
    one = goals.copy()
    one[1, 2] = 0.049  # one module just within: the whole goal is met
    assert space.success(achieved, one)
    guard = achieved.copy()
    guard[9] = 123.0  # what lies beyond a module's goal part (stack's gripper) plays no part
    assert space.success(guard, goals)
    # vectorised over leading axes
    batch = np.stack([achieved, achieved])
    np.testing.assert_array_equal(space.reward(batch, np.stack([goals, off])), [0.0, -1.0])


def _episodes(achieved_final: np.ndarray) -> EpisodeData:
    n = len(achieved_final)
    achieved = np.repeat(achieved_final[:, None], 2, axis=1)
    return EpisodeData(
        states=np.zeros((n, 2, SPEC.state_dim), np.float32),
        achieved=achieved.astype(np.float32),
        actions=np.zeros((n, 1, SPEC.action_dim), np.float32),
        final_success=np.zeros((n, SPEC.n_modules), bool),
    )


def test_her_scores_the_whole_goal_and_keeps_the_named_modules_slot_as_a_second_view():
    """The paper's HER "stays flat": its success is the holistic goal met, never the named
    module's slot alone (what our scorer read before)."""
    her = HER(SPEC, 0.4, "released", 10)
    env = ToyGoalEnv()
    goals = np.zeros((2, 3, 3), np.float32)
    goals[:, 2] = 0.9  # the beacon's slot: far from where the outcomes are
    data = _episodes(np.zeros((2, SPEC.achieved_dim), np.float32))
    modules = np.array([0, 2])
    np.testing.assert_array_equal(her.success(env, data, modules, goals), [False, False])
    np.testing.assert_array_equal(her.module_success(env, data, modules, goals), [True, False])
    goals[:, 2] = 0.0
    np.testing.assert_array_equal(her.success(env, data, modules, goals), [True, True])


def test_her_draws_a_goal_for_every_module_with_no_task_and_no_task_replay():
    her = HER(SPEC, 0.4, "released", 10)
    rng = np.random.default_rng(0)
    modules = np.array([0, 1, 2, 0])
    raw = rng.uniform(-1, 1, (4, 3))
    goal = her.goals(ToyGoalEnv(), modules, raw, rng)
    goals = goal.slots
    assert np.all(goal.mask == 1) and np.all(goal.task == 0)
    env = ToyGoalEnv()
    for i, m in enumerate(modules):  # the named module keeps its drawn goal
        np.testing.assert_array_equal(goals[i, m], env.goal_slot(int(m), raw[i]))
    assert np.all(np.abs(goals[:, 0]) > 0)  # every slot carries a goal
    assert her.goal_space is not None and her.replay_probs(None, 0, np.ones(3, bool)) is None
    assert not her.self_evaluates and her.lead_draw(rng) is None


class _Capture:
    """A round observer that keeps every round's `RolloutInfo`."""

    def __init__(self) -> None:
        self.infos = []

    def watched(self, episodes, evaluation):
        return []

    def begin_round(self, *args):
        pass

    def after_step(self, t):
        pass

    def end_round(self, info):
        self.infos.append(info)


def test_a_her_run_scores_every_episode_and_test_by_the_holistic_goal(tmp_path):
    """flowersteam/curious rollout.py: the flat workers never exploit (only `curious` and
    `task_experts` draw `self.exploit`), so every training episode explores; the evaluator's
    success is the env's flat `is_success`."""
    config = resolve("smoke", "her", 0, {"total_episodes": 40, "progress": False})
    envs = LocalEnvs(make_toy_envs(0, config.n_workers))
    trainer = Trainer(config, envs, LocalEnvs(make_toy_envs(1, 2)))
    capture = _Capture()
    trainer.observer = capture
    space = HolisticGoals(SPEC)
    try:
        for _ in range(4):
            trainer.cycle()
    finally:
        trainer.close()
    named = []
    for info in capture.infos:
        assert not info.evaluation.any()
        final = info.data.achieved[:, -1]
        np.testing.assert_array_equal(info.success, space.success(final, info.goals))
        env = ToyGoalEnv()
        named += [
            env.reward(int(m), final[i], info.goals[i, m]) == 0 for i, m in enumerate(info.modules)
        ]
    assert any(named)  # the named module's slot is met now and then; the whole goal is not

    out = tmp_path / "her"
    train(config, out, make_envs=lambda c: make_toy_envs(c.seed, c.n_workers))
    tests = pq.read_table(out / "tests.parquet").to_pandas()
    assert tests["module_success"].any()
    assert not (tests["success"] & ~tests["module_success"]).any()
    assert tests["success"].mean() < tests["module_success"].mean()


# ----------------------------------------------------------- self-evaluated and practised modules


def _tracker_with_progress() -> CompetenceTracker:
    """Four modules; module 1 is learning (LP 0.5), the others show none."""
    tracker = CompetenceTracker(4, window=4, measure="absolute")
    for success in (0, 0, 0, 0, 1, 1, 1, 1):
        tracker.add(1, bool(success))
    for m in (0, 2, 3):
        for _ in range(8):
            tracker.add(m, False)
    return tracker


FOUR = EnvSpec(
    module_names=("m0", "m1", "m2", "m3"),
    achievable=(True,) * 4,
    state_dim=1,
    action_dim=1,
    goal_dim=3,
    outcome_slices=tuple(slice(3 * k, 3 * k + 3) for k in range(4)),
    episode_length=2,
)


def _draw_cycles(condition, tracker, n_cycles, rng, workers=19, rounds=2, eval_every=10):
    """Modules of `n_cycles` cycles of `rounds` x `workers` episodes, as the trainer draws them:
    (modules, evaluation, lead of each episode)."""
    modules, evaluation, leads, start = [], [], [], 0
    for _ in range(n_cycles):
        lead = condition.lead_draw(rng)
        for _ in range(rounds):
            episodes = start + np.arange(workers)
            is_eval = episodes % eval_every == eval_every - 1
            modules.append(condition.modules(is_eval, tracker, 0, rng, lead))
            evaluation.append(is_eval)
            leads.append(np.full(workers, bool(lead)))
            start += workers
    return np.concatenate(modules), np.concatenate(evaluation), np.concatenate(leads)


def test_released_rule_draws_every_module_of_a_cycle_from_one_distribution():
    """flowersteam/curious rollout.py (`generate_rollouts`, `reset_rollout`): rank 0 draws every
    worker's task from its own `self.p`, which is uniform only while rank 0 itself exploits
    (probability 0.1 per call), and a worker that exploits keeps the task it was given. So
    evaluations and practice both follow 0.9 p_LP + 0.1 uniform, and a cycle (one call: 19
    workers x 2 episodes) is uniform as a whole or not at all."""
    tracker = _tracker_with_progress()
    released = Curious(FOUR, 0.4, "released", 10)
    p = tracker.p_lp(0.4)
    assert p[1] == pytest.approx(0.1 + 0.6)
    rng = np.random.default_rng(1)
    modules, evaluation, lead = _draw_cycles(released, tracker, 4000, rng)
    assert lead[::38].mean() == pytest.approx(0.1, abs=0.015)
    expected = 0.9 * p + 0.1 / 4
    for mask in (evaluation, ~evaluation):
        share = np.bincount(modules[mask], minlength=4) / mask.sum()
        np.testing.assert_allclose(share, expected, atol=0.015)
    in_lead = np.bincount(modules[lead], minlength=4) / lead.sum()
    np.testing.assert_allclose(in_lead, 0.25, atol=0.015)

    uniform = Curious(FOUR, 0.4, "uniform", 10)
    assert uniform.lead_draw(rng) is None
    modules, evaluation, _ = _draw_cycles(uniform, tracker, 2000, rng)
    share = np.bincount(modules[evaluation], minlength=4) / evaluation.sum()
    np.testing.assert_allclose(share, 0.25, atol=0.02)
    share = np.bincount(modules[~evaluation], minlength=4) / (~evaluation).sum()
    np.testing.assert_allclose(share, p, atol=0.01)


def _scripted_run(rule: str, seed: int) -> tuple[np.ndarray, int]:
    """Self-evaluations of a scripted competence history under `rule`, 4 workers x 2 rounds a
    cycle, one evaluation in 10: m0 is learned between episodes 4,000 and 8,000 (its LP draws
    the focus), m3 is mastered until episode 6,000 and fails from then on, m1 and m2 never
    succeed. Returns the evaluations per module between 4,000 and 6,000, and how many episodes
    after the forgetting m3's LP first reached 0.5."""
    window, eval_every, workers, rounds = 20, 10, 4, 2
    ramp, forget_at = (4000, 8000), 6000
    condition = Curious(FOUR, 0.4, rule, eval_every)
    tracker = CompetenceTracker(4, window, "absolute")
    rng = np.random.default_rng(seed)
    outcome_rng = np.random.default_rng(1000 + seed)
    start, noticed = 0, None
    counts = np.zeros(4, np.int64)
    while noticed is None:
        lead = condition.lead_draw(rng)
        for _ in range(rounds):
            episodes = start + np.arange(workers)
            is_eval = episodes % eval_every == eval_every - 1
            modules = condition.modules(is_eval, tracker, 0, rng, lead)
            for e, m in zip(episodes[is_eval], modules[is_eval], strict=True):
                learned = np.clip((e - ramp[0]) / (ramp[1] - ramp[0]), 0.0, 1.0)
                p_success = (learned, 0.0, 0.0, float(e < forget_at))[m]
                tracker.add(int(m), bool(outcome_rng.random() < p_success))
                counts[m] += ramp[0] <= e < forget_at
            if start >= forget_at and tracker.learning_progress()[3] >= 0.5:
                noticed = start - forget_at
            start += workers
    return counts, noticed


def test_released_rule_focuses_evaluations_and_so_lp_on_a_scripted_history():
    """The effect of `eval_modules` on LP, on a scripted competence history. With the released
    rule the module in focus (the one learning) is evaluated several times as often as a
    neglected one, so its LP is measured on fresher results; a neglected module is evaluated less
    than uniformly, so the first failure after it is forgotten comes later. Once a failure shows
    in its LP, though, p_LP sends the evaluations there too, and its LP rises to 0.5 sooner than
    with uniform evaluations (measured here: 267 episodes against 386, 16 seeds)."""
    runs = {
        rule: [_scripted_run(rule, seed) for seed in range(16)] for rule in ("released", "uniform")
    }
    focus = {rule: np.mean([c[0] / c[2] for c, _ in r]) for rule, r in runs.items()}
    neglected = {rule: np.mean([c[3] / c.sum() for c, _ in r]) for rule, r in runs.items()}
    noticed = {rule: np.mean([n for _, n in r]) for rule, r in runs.items()}
    assert focus["uniform"] == pytest.approx(1.0, abs=0.15)
    assert focus["released"] > 2.0
    assert neglected["uniform"] == pytest.approx(0.25, abs=0.03)
    assert neglected["released"] < 0.75 * neglected["uniform"]
    assert noticed["released"] < noticed["uniform"]


@pytest.mark.parametrize("condition", [MUVFA, LPReplay])
def test_m_uvfa_and_lp_replay_draw_uniformly_under_either_rule(condition):
    rng = np.random.default_rng(2)
    tracker = _tracker_with_progress()
    for rule in ("released", "uniform"):
        modules, _, _ = _draw_cycles(condition(FOUR, 0.4, rule, 10), tracker, 1000, rng)
        np.testing.assert_allclose(
            np.bincount(modules, minlength=4) / len(modules), 0.25, atol=0.02
        )


def test_every_preset_self_evaluates_as_the_released_code():
    """The paper's figures were made by flowersteam/curious (rollout.py): its module rule is the
    default, in every preset (a preset changes the scale of a run, never the algorithm); the
    paper's text ("evaluates itself on random tasks") is `eval_modules=uniform`."""
    for preset in PRESETS:
        assert resolve(preset).eval_modules == "released"
    assert resolve("laptop", overrides={"eval_modules": "uniform"}).eval_modules == "uniform"
    with pytest.raises(ConfigError, match="unknown eval_modules 'sometimes'"):
        resolve("smoke", overrides={"eval_modules": "sometimes"})
    with pytest.raises(ConfigError, match="her condition has none"):
        resolve("smoke", "her", overrides={"sensor_failure_competence": 0.5})


# ------------------------------------------------------------------------------------ mg-te


def test_mg_te_plays_every_episode_of_an_epoch_on_its_module_with_its_expert(tmp_path):
    """flowersteam/curious rollout.py: a task-expert worker's `self.p` is one-hot on its task and
    exploiting switches it to uniform only for `curious`, so its self-evaluations are its own
    task, by its own expert (experiment/train.py trains `policy[i_policy]` on that worker's
    episodes); competence of the other modules does not move during its epoch."""
    changes = {"total_episodes": 48, "progress": False}
    config = resolve("smoke", "mg-te", 0, changes)
    out = tmp_path / "mgte"
    train(config, out, make_envs=lambda c: make_toy_envs(c.seed, c.n_workers))
    df = pq.read_table(out / "metrics.parquet").to_pandas()
    per_epoch = config.episodes_per_cycle * config.n_cycles
    active = np.array(SPEC.module_names)[(df["episode"] // per_epoch) % SPEC.n_modules]
    np.testing.assert_array_equal(df["module"], active)
    assert df["eval"].sum() == 48 // config.eval_every
    competence = df[[f"competence/{m}" for m in SPEC.module_names]].to_numpy()
    moved = np.abs(np.diff(competence, axis=0)) > 0
    rows_moved, modules_moved = np.nonzero(moved)
    np.testing.assert_array_equal(
        np.array(SPEC.module_names)[modules_moved], active[rows_moved + 1]
    )
    mgte = MGTE(SPEC, 0.4, "released", 10)
    np.testing.assert_array_equal(mgte.acting_experts(np.array([2, 0, 1]), 5), [2, 0, 1])


# ------------------------------------------------------------------------------ task replay


class _LP:
    def __init__(self, lp):
        self.lp = np.asarray(lp, np.float64)

    def learning_progress(self):
        return self.lp.copy()


def test_task_replay_leaves_out_modules_with_nothing_to_replay():
    """flowersteam/curious ddpg.py (`sample_batch`): minibatch proportions only over the task
    buffers that hold something (`ind_valid_buffers`), eps / n_valid + (1 - eps) CP / sum CP
    over them (`replay_task_cp_buffer`), or 1 / n_valid (`replay_task_random_buffer`)."""
    valid = np.array([True, True, False, True])
    lp = [0.2, 0.0, 0.6, 0.1]
    curious, muvfa, mgte = (c(FOUR, 0.4, "released", 10) for c in (Curious, MUVFA, MGTE))
    p = curious.replay_probs(_LP(lp), 0, valid)
    expected = [0.4 / 3 + 0.6 * 0.2 / 0.3, 0.4 / 3, 0.0, 0.4 / 3 + 0.6 * 0.1 / 0.3]
    np.testing.assert_allclose(p, expected)
    np.testing.assert_allclose(muvfa.replay_probs(_LP(lp), 0, valid), [1 / 3, 1 / 3, 0, 1 / 3])
    # nothing replayable yet: every module, as before any buffer filled
    nothing = np.zeros(4, bool)
    np.testing.assert_allclose(muvfa.replay_probs(_LP(lp), 0, nothing), 0.25)
    # no progress among the valid ones: uniform over them
    np.testing.assert_allclose(
        curious.replay_probs(_LP([0, 0, 0.6, 0]), 0, valid), [1 / 3, 1 / 3, 0, 1 / 3]
    )
    # mg-te replays its trained expert's module whatever is valid
    np.testing.assert_array_equal(mgte.replay_probs(_LP(lp), 6, valid), [0, 0, 1, 0])


def test_conditions_have_one_registry():
    """What validation and the command line accept (`condition_names`) is the registry's keys,
    each class under its own `name`, and listing them loads no torch (the help stays light)."""
    import subprocess
    import sys

    from curious.agent.conditions import BUILT_IN_CONDITIONS, CONDITION_CLASSES
    from curious.registry import condition_names

    assert condition_names() == tuple(CONDITION_CLASSES)  # a plugin's after the built-in ones
    assert condition_names()[:4] == ("curious", "m-uvfa", "mg-te", "her")  # the paper's first
    assert condition_names()[: len(BUILT_IN_CONDITIONS)] == BUILT_IN_CONDITIONS
    assert {"lp-select", "lp-replay"} <= set(BUILT_IN_CONDITIONS)
    assert all(cls.name == name for name, cls in CONDITION_CLASSES.items())
    code = "import sys; from curious.registry import condition_names; condition_names(); "
    code += "print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_every_condition_has_a_label_a_colour_and_a_place_of_its_own():
    """Figures, reports and recordings show each condition under its own label and colour, in a
    fixed order (a condition missing from the tables would get a colour from its name, which may
    be another's); a plugin's condition gets a colour from its name."""
    from curious.agent.conditions import BUILT_IN_CONDITIONS
    from curious.analysis.figures import CONDITION_ORDER
    from curious.watching import palette

    names = BUILT_IN_CONDITIONS
    assert set(names) <= set(palette.CONDITION_STYLES) and set(names) <= set(CONDITION_ORDER)
    assert len({palette.condition_color(c) for c in names}) == len(names)
    assert len({palette.condition_label(c) for c in names}) == len(names)
    assert palette.condition_label("lp-select") == "LP-select"


# ------------------------------------------------------- LP's two uses apart, and signed LP


def _curious_replay(lp, replayable, eps=0.4):
    """CURIOUS's task replay (flowersteam/curious ddpg.py `sample_batch`): eps / n + (1 - eps)
    LP / sum LP over the n replayable modules, uniform over them while their LP sums to 0."""
    lp, mask = np.asarray(lp, np.float64), np.asarray(replayable, bool)
    mask = mask if mask.any() else np.ones_like(mask)
    total = lp[mask].sum()
    share = eps / mask.sum() + (1 - eps) * lp / total if total > 0 else 1 / mask.sum()
    return np.where(mask, share, 0.0)


def test_lp_select_and_lp_replay_each_keep_one_use_of_lp():
    """`lp-select` practises as `curious` and replays as `m-uvfa`; `lp-replay` the reverse."""
    tracker = _tracker_with_progress()  # module 1 is learning
    valid = np.array([True, True, False, True])
    curious, muvfa, select, replay = (
        c(FOUR, 0.4, "released", 10) for c in (Curious, MUVFA, LPSelect, LPReplay)
    )
    p_lp = curious.practice_probs(tracker, 0)
    assert p_lp[1] == pytest.approx(0.7)  # LP tells the two draws apart
    np.testing.assert_allclose(select.practice_probs(tracker, 0), p_lp)
    np.testing.assert_allclose(select.replay_probs(tracker, 0, valid), [1 / 3, 1 / 3, 0, 1 / 3])
    np.testing.assert_allclose(replay.practice_probs(tracker, 0), muvfa.practice_probs(tracker, 0))
    expected = _curious_replay(tracker.learning_progress(), valid)
    np.testing.assert_allclose(replay.replay_probs(tracker, 0, valid), expected)
    np.testing.assert_allclose(curious.replay_probs(tracker, 0, valid), expected)
    assert replay.self_evaluates and select.follows_lead and replay.n_experts == 1


def test_signed_lp_reaches_practice_and_replay_of_every_condition_that_reads_lp():
    """With `lp_measure=signed` a forgotten module (competence 1 -> 0) draws no more than the
    eps share, where the paper's absolute LP draws practice and replay back to it."""
    valid = np.ones(4, bool)
    for measure, forgotten_share in (("absolute", 0.4 / 4 + 0.6 / 2), ("signed", 0.4 / 4)):
        tracker = CompetenceTracker(4, window=4, measure=measure)
        for success in (0, 0, 0, 0, 1, 1, 1, 1):
            tracker.add(1, bool(success))  # learning
        for success in (1, 1, 1, 1, 0, 0, 0, 0):
            tracker.add(3, bool(success))  # forgotten
        for condition in (Curious, LPSelect):
            p = condition(FOUR, 0.4, "released", 10).practice_probs(tracker, 0)
            assert p[3] == pytest.approx(forgotten_share), (measure, condition.name)
        for condition in (Curious, LPReplay):
            p = condition(FOUR, 0.4, "released", 10).replay_probs(tracker, 0, valid)
            assert p[3] == pytest.approx(forgotten_share), (measure, condition.name)


def _toy_envs(config):
    return make_toy_envs(config.seed, config.n_workers)


def _scripted_scores(monkeypatch: pytest.MonkeyPatch, condition: type) -> None:
    """Score episodes by a seeded coin (reach 1/2, dial 1/5, beacon never) instead of by their
    outcome: a smoke run's policy succeeds too rarely for competence and LP to move."""
    coin = np.random.default_rng(7)
    rates = np.array([0.5, 0.2, 0.0])
    monkeypatch.setattr(
        condition,
        "success",
        lambda self, env, data, modules, goals: coin.random(len(modules)) < rates[modules],
    )


class _ReplaySpy:
    """Records what the task replay was given and drew: (LP, replayable, module probabilities)
    of every cycle, and the module of every replayed transition."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, condition: type) -> None:
        self.cycles: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.drawn: list[np.ndarray] = []
        probs_of, sample = condition.replay_probs, condition.sample

        def replay_probs(cond, tracker, epoch, replayable):
            probs = probs_of(cond, tracker, epoch, replayable)
            self.cycles.append((tracker.learning_progress(), replayable.copy(), probs))
            return probs

        def spied_sample(cond, *args):
            batch = sample(cond, *args)
            self.drawn.append((len(self.cycles) - 1, batch.module.copy()))
            return batch

        monkeypatch.setattr(condition, "replay_probs", replay_probs)
        monkeypatch.setattr(condition, "sample", spied_sample)

    def shares(self, n_modules: int) -> tuple[np.ndarray, np.ndarray]:
        """The replayed modules' shares, and the shares the cycles' probabilities expect."""
        drawn = np.zeros(n_modules)
        expected = np.zeros(n_modules)
        for cycle, modules in self.drawn:
            drawn += np.bincount(modules, minlength=n_modules)
            expected += len(modules) * self.cycles[cycle][2]
        return drawn / drawn.sum(), expected / expected.sum()


@pytest.mark.parametrize("condition", [LPSelect, LPReplay])
def test_a_smoke_run_of_each_half_of_curious_trains_with_its_own_draws(
    tmp_path, monkeypatch, condition
):
    """A run of `lp-select` logs CURIOUS's p_LP as its practice probabilities (p_lp columns)
    and replays modules uniformly over the replayable ones; `lp-replay` logs uniform practice
    and replays by CURIOUS's formula. Every transition is relabelled (her_p 1), so the replayed
    modules are the drawn ones."""
    spy = _ReplaySpy(monkeypatch, condition)
    _scripted_scores(monkeypatch, condition)
    changes = {"total_episodes": 96, "lp_window": 2, "her_p": 1.0, "progress": False}
    config = resolve("smoke", condition.name, 0, changes)
    out = tmp_path / condition.name
    assert train(config, out, make_envs=_toy_envs).episodes == 96

    df = pq.read_table(out / "metrics.parquet").to_pandas()
    names = SPEC.module_names
    lp = df[[f"lp/{n}" for n in names]].to_numpy(np.float64)
    p_lp = df[[f"p_lp/{n}" for n in names]].to_numpy(np.float64)
    assert (lp.sum(1) > 0).mean() > 0.25  # LP had something to choose by
    if condition is LPSelect:
        formula = np.array([lp_probabilities(row, config.lp_eps) for row in lp])
        np.testing.assert_allclose(p_lp, formula, atol=1e-6)
        assert np.abs(p_lp - 1 / 3).max() > 0.1
    else:
        np.testing.assert_allclose(p_lp, 1 / 3, atol=1e-6)

    lp_shaped = 0
    for cycle_lp, replayable, probs in spy.cycles:
        uniform = _curious_replay(np.zeros(len(names)), replayable)
        wanted = uniform if condition is LPSelect else _curious_replay(cycle_lp, replayable)
        np.testing.assert_allclose(probs, wanted, atol=1e-12)
        lp_shaped += not np.allclose(wanted, uniform)
    assert lp_shaped > len(spy.cycles) // 4 if condition is LPReplay else lp_shaped == 0
    drawn, expected = spy.shares(len(names))
    np.testing.assert_allclose(drawn, expected, atol=0.03)


def test_a_signed_lp_run_logs_what_p_lp_is_formed_from_and_keeps_its_measure(tmp_path, monkeypatch):
    """A `lp_measure=signed` run trains and resumes; its lp columns are never negative and are
    what its p_lp columns are formed from; `--resume` with the paper's measure is refused (it
    would change the run)."""
    changes = {"total_episodes": 96, "lp_window": 2, "lp_measure": "signed", "progress": False}
    config = resolve("smoke", "curious", 0, changes)
    out = tmp_path / "signed"
    _scripted_scores(monkeypatch, Curious)
    train(config, out, make_envs=_toy_envs, stop_after_cycles=12)
    absolute = resolve("smoke", "curious", 0, {**changes, "lp_measure": "absolute"})
    with pytest.raises(RunFolderError, match=r"lp_measure: 'signed' -> 'absolute'"):
        train(absolute, out, resume=True, make_envs=_toy_envs)
    assert train(config, out, resume=True, make_envs=_toy_envs).episodes == 96
    df = pq.read_table(out / "metrics.parquet").to_pandas()
    lp = df[[f"lp/{n}" for n in SPEC.module_names]].to_numpy(np.float64)
    p_lp = df[[f"p_lp/{n}" for n in SPEC.module_names]].to_numpy(np.float64)
    assert lp.min() >= 0 and lp.max() > 0
    formula = np.array([lp_probabilities(row, config.lp_eps) for row in lp])
    np.testing.assert_allclose(p_lp, formula, atol=1e-6)
