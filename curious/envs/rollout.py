"""Rollouts: n environment copies stepped together (`curious.envs.batch`).

At every step the policy is called once for all copies (one batched forward pass), then the
copies step (one after the other, or in worker processes at the same time). Episodes have a
fixed length and never end early, so all copies stay in lock-step.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from curious.envs.batch import EnvBatch


@dataclass
class EpisodeData:
    """n episodes of T steps, as arrays."""

    states: np.ndarray  # (n, T+1, S)
    achieved: np.ndarray  # (n, T+1, sum of outcome dims)
    actions: np.ndarray  # (n, T, A)
    final_success: np.ndarray  # (n, N) per-module success reported by the env at the last step
    policy_seconds: float = 0.0
    env_seconds: float = 0.0


def run_episodes(
    envs: EnvBatch,
    modules: np.ndarray,
    raw_goals: np.ndarray,
    act: Callable[[np.ndarray, np.ndarray, int], np.ndarray],
    on_step: Callable[[int], None] | None = None,
) -> EpisodeData:
    """One episode in each of the first n = len(modules) copies of `envs`: copy i practises
    `modules[i]` with goal `raw_goals[i]`.

    `act(states, achieved, t)` maps the (n, S) states and (n, sum of outcome dims) outcomes at
    step t to (n, A) actions for all copies at once (the outcomes place goals that follow an
    object, `GoalEnv.goal`).
    `on_step(t)`, if given, is called after the resets (t = 0) and after each step (t = 1..T),
    when every copy has moved (recorders read the simulators' state there).
    """
    spec = envs.spec
    n, T = len(modules), spec.episode_length
    states = np.empty((n, T + 1, spec.state_dim), np.float32)
    achieved = np.empty((n, T + 1, spec.achieved_dim), np.float32)
    actions = np.empty((n, T, spec.action_dim), np.float32)
    env_seconds = policy_seconds = 0.0
    tic = time.perf_counter()
    states[:, 0], achieved[:, 0] = envs.reset(modules, raw_goals)
    env_seconds += time.perf_counter() - tic
    if on_step is not None:
        on_step(0)
    success = np.zeros((n, spec.n_modules), bool)
    for t in range(T):
        tic = time.perf_counter()
        actions[:, t] = act(states[:, t], achieved[:, t], t)
        toc = time.perf_counter()
        policy_seconds += toc - tic
        states[:, t + 1], achieved[:, t + 1], success = envs.step(actions[:, t])
        env_seconds += time.perf_counter() - toc
        if on_step is not None:
            on_step(t + 1)
    final_success = np.asarray(success, bool)
    return EpisodeData(states, achieved, actions, final_success, policy_seconds, env_seconds)
