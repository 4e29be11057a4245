"""`curious bench rollouts`: rollout episodes/s with the copies in 1, 2, ... worker processes,
against the physics bound of as many cores.

Rollouts alone (no policy, no learner): `n_workers` copies of the preset's size reset on random
modules and goals, then stepped together for one episode with random actions, as the training
loop steps them. `peer` is the default (`env_processes=1`), every copy stepped in the training
process (`LocalEnvs`); `ours` is the copies spread over one worker process per core (`ProcessEnvs`,
`--set env_processes=0`); the detail has every process count from 1 to the cores. `bound` is
the physics alone, one core stepping the suite's compiled model for one episode's 50 control
steps, times the cores used; `<p>_over_bound` says how much of it p processes reach.
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import numpy as np

from benchmarks import AtLeast


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", default="paper", help="training preset (default paper)")
    parser.add_argument(
        "--episodes", type=AtLeast(1), default=3, help="timed rounds each (default 3)"
    )
    parser.add_argument(
        "--max-processes",
        type=AtLeast(0),
        default=0,
        help="largest process count, at most the preset's n_workers (default 0: the cores)",
    )


def _rounds_per_second(envs: Any, rounds: int, episode_length: int, seed: int) -> float:
    """Rounds of len(envs) parallel episodes per second, after one untimed round."""
    rng = np.random.default_rng(seed)
    n, spec = len(envs), envs.spec

    def one_round() -> None:
        envs.reset(rng.integers(0, spec.n_modules, n), rng.uniform(-1.0, 1.0, (n, 3)))
        for _ in range(episode_length):
            envs.step(rng.uniform(-1.0, 1.0, (n, spec.action_dim)))

    one_round()
    tic = time.perf_counter()
    for _ in range(rounds):
        one_round()
    return rounds / (time.perf_counter() - tic)


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """ours, bound, peer (episodes/s) and the rate of every process count."""
    from benchmarks.cycle_speed import physics_episodes_per_second
    from curious.envs.batch import LocalEnvs, ProcessEnvs
    from curious.envs.goal_env import suite_env_fns
    from curious.presets import resolve

    config = resolve(args.preset, overrides=dict(progress=False))
    cores = os.cpu_count() or 1
    top = min(args.max_processes or cores, config.n_workers)
    fns = suite_env_fns(config.variant, config.seed, config.n_workers)
    local = LocalEnvs([fn() for fn in fns])
    length = local.spec.episode_length
    try:
        peer = _rounds_per_second(local, args.episodes, length, 0) * config.n_workers
    finally:
        local.close()
    rates: dict[int, float] = {}
    for processes in range(1, top + 1):
        envs = ProcessEnvs(fns, processes)
        try:
            rates[processes] = _rounds_per_second(envs, args.episodes, length, 0) * config.n_workers
        finally:
            envs.close()
    one_core = physics_episodes_per_second(config.variant)
    out: dict[str, Any] = {
        "ours": rates[top],
        "bound": one_core * top,
        "peer": peer,
        "unit": "episodes/s",
        "ours_over_peer": rates[top] / peer,
        "cores": cores,
        "copies": config.n_workers,
        "physics_episodes_per_s_one_core": one_core,
    }
    for processes, rate in rates.items():
        out[f"processes_{processes}"] = rate
        out[f"processes_{processes}_over_bound"] = rate / (one_core * processes)
    return out
