"""The agent: input encoder, one learner per expert, and the exploration rule.

Acting: one batched forward pass per expert present in the batch (all copies share one expert
except in mg-te evaluations), then, for exploring rows, Gaussian noise of std `noise_eps` (actions
clipped to [-1, 1]) and with probability `random_eps` a uniform random action instead (the
authors' rule). Learning: a relabelled minibatch from the replay becomes tensors on the learner's
device, is encoded, and drives one update of the chosen expert.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import torch

from curious.agent.goals import GoalBox, GoalInput
from curious.agent.inputs import InputEncoder
from curious.agent.learner import Learner
from curious.agent.replay import Transitions
from curious.config import Config
from curious.envs.goal_env import EnvSpec


class _FrozenActor:
    """A copy of an expert's actor, for acting only."""

    def __init__(self, actor: torch.nn.Module) -> None:
        self.actor = actor

    @torch.no_grad()
    def act(self, x: torch.Tensor) -> torch.Tensor:
        return self.actor(x)


class Agent:
    """Everything with parameters or statistics: encoder and experts."""

    def __init__(
        self, spec: EnvSpec, config: Config, goal_box: GoalBox, n_experts: int = 1
    ) -> None:
        self.spec = spec
        self.config = config
        self.device = torch.device(config.device)
        self.encoder = InputEncoder(spec, goal_box, config.norm_eps, config.norm_clip)
        self.experts = [
            Learner(self.encoder.input_dim, spec.action_dim, config, seed=config.seed * 1009 + k)
            for k in range(n_experts)
        ]

    def _tensor(self, array: np.ndarray) -> torch.Tensor:
        return torch.from_numpy(np.ascontiguousarray(array, dtype=np.float32)).to(self.device)

    def act(
        self,
        states: np.ndarray,
        goal: GoalInput[np.ndarray],
        experts: np.ndarray,
        explore: np.ndarray,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """(n, A) actions for n copies in states (n, S) with their goal input (the goals where
        they are at this step, `GoalInput.placed`); `experts` (n,) the expert acting in each
        row; `explore` (n,) bool rows get exploration noise."""
        x = self.encoder.encode(self._tensor(states), goal.map(self._tensor))
        first = int(experts[0])
        if len(self.experts) == 1 or np.all(experts == first):  # one expert acts for every row
            actions = self.experts[first].act(x).cpu().numpy()
        else:
            actions = np.empty((len(states), self.spec.action_dim), np.float32)
            for k in np.unique(experts):
                rows = np.flatnonzero(experts == k)
                out = self.experts[int(k)].act(x[torch.from_numpy(rows).to(self.device)])
                actions[rows] = out.cpu().numpy()
        n_explore = int(explore.sum())
        if n_explore:
            rows = np.flatnonzero(explore)
            cfg = self.config
            noisy = actions[rows] + cfg.noise_eps * rng.standard_normal(
                (n_explore, actions.shape[1])
            )
            noisy = np.clip(noisy, -1.0, 1.0)
            random = rng.random(n_explore) < cfg.random_eps
            noisy[random] = rng.uniform(-1.0, 1.0, (int(random.sum()), actions.shape[1]))
            actions[rows] = noisy
        return actions

    def acting_copy(self, device: str | None = None) -> Agent:
        """An agent that acts as this one does now, and keeps doing so while this one learns
        (its actors copied, to `device` if given; the input encoder shared, which only
        `update_stats` changes and which normalises on any device)."""
        twin = copy.copy(self)
        if device is not None:
            twin.device = torch.device(device)
        twin.experts = [_FrozenActor(copy.deepcopy(e.actor).to(twin.device)) for e in self.experts]
        return twin

    def update(self, expert: int, batch: Transitions) -> dict[str, torch.Tensor]:
        """One gradient step of `expert` on a relabelled minibatch."""
        t = self._tensor
        x, x_next = self.encoder.encode_pair(t(batch.state), t(batch.next_state), batch.goal.map(t))
        return self.experts[expert].update(x, t(batch.action), t(batch.reward), x_next)

    def update_targets(self, expert: int) -> None:
        self.experts[expert].update_targets()

    def state_dict(self) -> dict[str, Any]:
        return {
            "encoder": self.encoder.state_dict(),
            "experts": [e.state_dict() for e in self.experts],
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        if len(state["experts"]) != len(self.experts):
            raise ValueError(
                f"checkpoint has {len(state['experts'])} experts, this run {len(self.experts)}"
            )
        self.encoder.load_state_dict(state["encoder"])
        for expert, s in zip(self.experts, state["experts"], strict=True):
            expert.load_state_dict(s)
