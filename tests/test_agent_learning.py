"""The agent learns the toy env's achievable modules, and p_LP moves away from the impossible one.

Seconds, not MuJoCo: `toy_env.ToyGoalEnv` has two achievable modules (reach, dial) and one
impossible module (beacon).
"""

import numpy as np
import torch
from toy_env import make_toy_envs

from curious.envs.batch import LocalEnvs
from curious.presets import resolve
from curious.runs.trainer import Trainer

TOY = dict(
    total_episodes=1200,
    n_workers=4,
    episodes_per_worker=2,
    n_cycles=10,
    hidden=64,
    layers=2,
    batch_per_worker=64,
    n_updates=16,
    buffer_episodes=2000,
    lp_window=15,
    eval_every=4,
    progress=False,
)


def run_toy(condition: str, seed: int = 0) -> tuple[Trainer, dict[str, np.ndarray]]:
    torch.set_num_threads(1)
    config = resolve("smoke", condition, seed, TOY)
    trainer = Trainer(config, LocalEnvs(make_toy_envs(seed, config.n_workers)))
    rows: list[dict[str, np.ndarray]] = []
    while not trainer.done:
        rows.append(trainer.cycle().rows)
    return trainer, {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}


def test_curious_learns_achievable_modules_and_leaves_the_impossible_one():
    trainer, rows = run_toy("curious")
    competence = trainer.tracker.competence()
    assert competence[0] >= 0.8 and competence[1] >= 0.8, competence  # reach, dial
    assert competence[2] == 0.0  # beacon
    # final self-evaluations succeed on the achievable modules
    last = rows["eval"] & (rows["episode"] >= 900) & (rows["module"] != "beacon")
    assert rows["success"][last].mean() >= 0.8
    # p_LP: the beacon's probability never rises above uniform and sits at its floor
    # eps / N whenever any module makes progress
    p_beacon = rows["p_lp/beacon"]
    assert p_beacon.max() <= 1 / 3 + 1e-6
    progressing = (rows["lp/reach"] + rows["lp/dial"]) > 0
    assert progressing.mean() > 0.3
    np.testing.assert_allclose(p_beacon[progressing], 0.4 / 3, rtol=1e-5)
    assert rows["lp/beacon"].max() == 0
    # so the impossible module is practised less than a third of the time
    practice = ~rows["eval"]
    assert (rows["module"][practice] == "beacon").mean() < 0.3
