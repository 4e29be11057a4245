"""The E-UVFA input: [normalised state, masked normalised goal vector, task descriptor].

The goal vector has one 3-D slot per module. Modular conditions fill only the practised module's
slot and set the one-hot task descriptor; the holistic `her` condition fills every slot and leaves
the descriptor at zero. Each slot is normalised with statistics of that module's goals only, and
inactive slots are zero *after* normalisation, so that their first-layer weights receive no
gradient (the masking of paper §3).
"""

from __future__ import annotations

import numpy as np
import torch

from curious.envs import EnvSpec
from curious.normalizer import RunningNormalizer


class InputEncoder:
    """Owns the state and goal normalisers and builds network inputs from raw arrays."""

    def __init__(self, spec: EnvSpec, norm_eps: float = 0.01, norm_clip: float = 5.0) -> None:
        self.spec = spec
        self.state_norm = RunningNormalizer((spec.state_dim,), eps=norm_eps, clip=norm_clip)
        self.goal_norm = RunningNormalizer(
            (spec.goal_dim,), groups=spec.n_modules, eps=norm_eps, clip=norm_clip
        )
        self._hindsight = spec.hindsight_columns()
        n, g = spec.n_modules, spec.goal_dim
        self.input_dim = spec.state_dim + n * g + n

    def update_stats(
        self, states: np.ndarray, achieved: np.ndarray, goals: np.ndarray, goal_mask: np.ndarray
    ) -> None:
        """Add a batch of episodes to the statistics.

        states (E, T+1, S); achieved (E, T+1, A); goals (E, N, G) the episodes' goal slots;
        goal_mask (E, N) which slots were set. Goal statistics take every module's hindsight
        goals (the outcomes the replay will relabel with) and the episodes' own goals.
        """
        n = self.spec.n_modules
        self.state_norm.update(states.reshape(-1, self.spec.state_dim))
        hindsight = achieved[..., self._hindsight]  # (E, T+1, N, G)
        flat = hindsight.reshape(-1, self.spec.goal_dim)
        groups = np.broadcast_to(np.arange(n), hindsight.shape[:-1]).reshape(-1)
        mask = np.asarray(goal_mask, dtype=bool)
        own = goals[mask]
        own_groups = np.nonzero(mask)[1]
        self.goal_norm.update(np.concatenate([flat, own]), np.concatenate([groups, own_groups]))

    def encode(
        self, state: torch.Tensor, goals: torch.Tensor, goal_mask: torch.Tensor, task: torch.Tensor
    ) -> torch.Tensor:
        """(B, input_dim) from state (B, S), goals (B, N, G), goal_mask (B, N), task (B, N)."""
        s = self.state_norm.normalize(state)
        g = self.goal_norm.normalize(goals) * goal_mask.unsqueeze(-1)
        return torch.cat([s, g.flatten(1), task], dim=1)

    def encode_pair(
        self,
        state: torch.Tensor,
        next_state: torch.Tensor,
        goals: torch.Tensor,
        goal_mask: torch.Tensor,
        task: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """`encode` of a transition's two states with one goal part (half the work)."""
        n = state.shape[0]
        s = self.state_norm.normalize(torch.cat([state, next_state]))
        g = (self.goal_norm.normalize(goals) * goal_mask.unsqueeze(-1)).flatten(1)
        return torch.cat([s[:n], g, task], dim=1), torch.cat([s[n:], g, task], dim=1)

    def state_dict(self) -> dict:
        return {"state": self.state_norm.state_dict(), "goal": self.goal_norm.state_dict()}

    def load_state_dict(self, state: dict) -> None:
        self.state_norm.load_state_dict(state["state"])
        self.goal_norm.load_state_dict(state["goal"])
