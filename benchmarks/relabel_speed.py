"""`curious bench relabel`: relabelled minibatches per second from the suite's replay.

A replay of `--episodes` episodes with the suite variant's shapes (random states, outcomes that
drift so that some relabelled goals are met) is sampled the way `Trainer._update` samples it:
`EpisodeReplay.sample` with uniform module probabilities and the authors' `her_p` of 0.8, which
draws the transitions, relabels their goals (HER's future outcomes or the episode's own goal,
placed where the outcomes put it) and recomputes their rewards. Timed, in interleaved rounds:

* ours: goals placed and rewards recomputed row by row in one pass over the minibatch
  (`GoalEnv.row_goals`, `GoalEnv.row_rewards`: the suite's `ModuleEvaluator.row_goals` and
  `row_success`);
* peer: the same minibatch relabelled one module at a time (`RowsByModule`: each module's own
  `goal` and `reward` on its rows), the same numbers;
* bound: the minibatch's gathers alone (states, next states, actions and outcomes of the drawn
  transitions), what any relabelling reads.

Both routes draw the same transitions from the same seed, and the benchmark checks that they
give the same goals and rewards.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from benchmarks import AtLeast, positive_seconds


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--batch", type=AtLeast(1), default=512, help="minibatch (512: `laptop`; `paper`: 4864)"
    )
    parser.add_argument(
        "--episodes", type=AtLeast(1), default=2_000, help="episodes stored (2,000)"
    )
    parser.add_argument("--variant", default="default", help="the suite's variant (default)")
    parser.add_argument(
        "--seconds",
        type=positive_seconds,
        default=1.0,
        help="seconds per contender and round (1.0)",
    )
    parser.add_argument("--rounds", type=AtLeast(1), default=3, help="interleaved rounds (3)")


def _per_module(env: Any) -> Any:
    """The suite env relabelling one module at a time (the peer): its own `goal` and `reward`
    behind `RowsByModule`'s row-wise methods."""
    from curious.envs.goal_env import RowsByModule

    class PerModule(RowsByModule):
        spec = env.spec
        goal, reward = staticmethod(env.goal), staticmethod(env.reward)

    return PerModule()


def _filled_replay(env: Any, episodes: int) -> Any:
    from curious.agent.replay import EpisodeReplay

    spec = env.spec
    replay = EpisodeReplay(spec, episodes)
    rng = np.random.default_rng(0)
    T, n, width = spec.episode_length, spec.n_modules, spec.achieved_dim
    start = np.tile(env.reset(0, np.zeros(3)).achieved, (episodes, 1, 1))
    drift = rng.normal(0.0, 0.01, (episodes, T + 1, width)).cumsum(axis=1)
    slots = np.stack([env.goal_slot(k, rng.uniform(-1, 1, (episodes, 3))) for k in range(n)], 1)
    replay.store(
        rng.standard_normal((episodes, T + 1, spec.state_dim), np.float32),
        (start + drift).astype(np.float32),
        rng.uniform(-1, 1, (episodes, T, spec.action_dim)).astype(np.float32),
        rng.integers(n, size=episodes),
        slots.astype(np.float32),
    )
    return replay


def _rate(step: Any, seconds: float) -> float:
    """Calls per second of `step` over about `seconds` (after one untimed call)."""
    step()
    calls, tic = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - tic) < seconds:
        step()
        calls += 1
    return calls / elapsed


def measure(args: argparse.Namespace) -> dict[str, Any]:
    from curious.envs.goal_env import SuiteEnv

    env = SuiteEnv(args.variant, seed=0)
    replay = _filled_replay(env, args.episodes)
    probs = np.full(env.spec.n_modules, 1 / env.spec.n_modules)
    peer_env = _per_module(env)

    ours_batch = replay.sample(args.batch, np.random.default_rng(1), env, probs, 0.8)
    peer_batch = replay.sample(args.batch, np.random.default_rng(1), peer_env, probs, 0.8)
    if not (
        np.array_equal(ours_batch.reward, peer_batch.reward)
        and np.array_equal(ours_batch.goal.slots, peer_batch.goal.slots)
    ):
        raise AssertionError("the two relabelling routes disagree")

    rng = np.random.default_rng(2)
    T = env.spec.episode_length

    def gathers() -> None:
        episode = rng.integers(args.episodes, size=args.batch)
        step = rng.integers(T, size=args.batch)
        _ = replay.states[episode, step], replay.states[episode, step + 1]
        _ = replay.actions[episode, step], replay.achieved[episode, step + 1]

    contenders = {
        "ours": lambda: replay.sample(args.batch, rng, env, probs, 0.8),
        "peer": lambda: replay.sample(args.batch, rng, peer_env, probs, 0.8),
        "bound": gathers,
    }
    rates: dict[str, list[float]] = {name: [] for name in contenders}
    for r in range(args.rounds):
        names = list(contenders) if r % 2 == 0 else list(reversed(contenders))
        for name in names:
            rates[name].append(_rate(contenders[name], args.seconds))
    best = {name: max(values) for name, values in rates.items()}
    return {
        "ours": best["ours"],
        "bound": best["bound"],
        "peer": best["peer"],
        "unit": "minibatches/s",
        "batch": args.batch,
        "variant": args.variant,
        "rewards_met": float((ours_batch.reward == 0).mean()),
        "ours_ms": 1e3 / best["ours"],
        "peer_ms": 1e3 / best["peer"],
        "ours_over_peer": best["ours"] / best["peer"],
    }
