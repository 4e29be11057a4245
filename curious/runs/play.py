"""A round of play: the one protocol that training episodes, test rollouts and evaluations share.

The caller chooses the modules and the raw goals in [-1, 1]^3 of n episodes (each from its own
random stream and rule); `play_round` then does the rest, the same way for all three: the
condition places the goal slots and picks the acting experts, the policy acts on the goals where
they are at every step, the first n environment copies step together, and the condition judges
each episode's final success. A round observer (the 3-D rollout capture, a video's frame
grabber) is called around it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from curious.agent.agent import Agent
from curious.agent.conditions import Condition
from curious.agent.goals import GoalInput
from curious.envs.batch import EnvBatch
from curious.envs.goal_env import GoalEnv
from curious.envs.rollout import run_episodes
from curious.runs.hooks import RolloutInfo, RoundObserver

Act = Callable[[np.ndarray, np.ndarray, int], np.ndarray]
"""`act(states, achieved, t)` -> actions of all copies at step t, as `run_episodes` calls it."""
PolicyFor = Callable[[GoalInput[np.ndarray], np.ndarray], Act]
"""`policy_for(goal, experts)`: the `Act` of a round with this goal input and these experts."""


def goal_policy(
    env: GoalEnv,
    agent: Agent,
    goal: GoalInput[np.ndarray],
    experts: np.ndarray,
    explore: np.ndarray,
    rng: np.random.Generator,
) -> Act:
    """`act(states, achieved, t)` of a round of episodes with this goal input, experts and
    noise: the agent sees each slot's goal where it is at step t (`GoalInput.placed`)."""

    def act(states: np.ndarray, achieved: np.ndarray, t: int) -> np.ndarray:
        return agent.act(states, goal.placed(env, achieved), experts, explore, rng)

    return act


@dataclass
class Round:
    """A round played: what observers see (`info`), and the experts that acted."""

    info: RolloutInfo
    experts: np.ndarray  # (n,) the expert that acted in each episode


def play_round(
    envs: EnvBatch,
    condition: Condition,
    modules: np.ndarray,
    raw_goals: np.ndarray,
    rng: np.random.Generator,
    epoch: int,
    policy_for: PolicyFor,
    episodes: np.ndarray,
    evaluation: np.ndarray,
    failing: np.ndarray,
    observer: RoundObserver | None = None,
) -> Round:
    """Play one episode in each of the first n = len(modules) copies of `envs`.

    `modules` (n,) and `raw_goals` (n, 3) are the caller's; `rng` draws what the condition adds
    to the goals (the flat baseline's holistic goal); `epoch` picks MG-TE's experts;
    `policy_for(goal, experts)` gives the round's `act`. `episodes` (their numbers),
    `evaluation` and `failing` (run with the sensory failure, which the caller switched) describe
    the round to the observer and in the `RolloutInfo` it returns."""
    env = envs.reference
    goal = condition.goals(env, modules, raw_goals, rng)
    experts = condition.acting_experts(modules, epoch)
    act = policy_for(goal, experts)
    n = len(modules)
    if observer is not None:
        views = envs.observed(observer.watched(episodes, evaluation))
        observer.begin_round(episodes, modules, goal.slots, evaluation, views[:n])
    step_hook = observer.after_step if observer is not None else None
    data = run_episodes(envs, modules, raw_goals, act, step_hook)
    success = condition.success(env, data, modules, goal.slots)
    info = RolloutInfo(episodes, modules, raw_goals, goal.slots, evaluation, success, data, failing)
    if observer is not None:
        observer.end_round(info)
    return Round(info, experts)
