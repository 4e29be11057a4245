"""Rollouts: n environment copies stepped together in one process.

At every step the policy is called once for all copies (one batched forward pass), then each copy
steps. Episodes have a fixed length and never end early, so all copies stay in lock-step.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from curious.envs import GoalEnv


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
    envs: Sequence[GoalEnv],
    modules: np.ndarray,
    raw_goals: np.ndarray,
    act: Callable[[np.ndarray, int], np.ndarray],
    on_step: Callable[[int], None] | None = None,
) -> EpisodeData:
    """One episode in each of `envs`: env i practises `modules[i]` with goal `raw_goals[i]`.

    `act(states, t)` maps the (n, S) states at step t to (n, A) actions for all copies at once.
    `on_step(t)`, if given, is called after the resets (t = 0) and after each step (t = 1..T),
    when every copy has moved (recorders read the simulators' state there).
    """
    spec = envs[0].spec
    n, T = len(envs), spec.episode_length
    states = np.empty((n, T + 1, spec.state_dim), np.float32)
    achieved = np.empty((n, T + 1, spec.achieved_dim), np.float32)
    actions = np.empty((n, T, spec.action_dim), np.float32)
    final_success = np.zeros((n, spec.n_modules), bool)
    env_seconds = policy_seconds = 0.0
    tic = time.perf_counter()
    for i, env in enumerate(envs):
        obs = env.reset(int(modules[i]), raw_goals[i])
        states[i, 0], achieved[i, 0] = obs.state, obs.achieved
    env_seconds += time.perf_counter() - tic
    if on_step is not None:
        on_step(0)
    for t in range(T):
        tic = time.perf_counter()
        actions[:, t] = act(states[:, t], t)
        toc = time.perf_counter()
        policy_seconds += toc - tic
        for i, env in enumerate(envs):
            obs, success = env.step(actions[i, t])
            states[i, t + 1], achieved[i, t + 1] = obs.state, obs.achieved
            if t == T - 1:
                final_success[i] = success
        env_seconds += time.perf_counter() - toc
        if on_step is not None:
            on_step(t + 1)
    return EpisodeData(states, achieved, actions, final_success, policy_seconds, env_seconds)
