"""The E-UVFA input: [normalised state, masked scaled goal vector, task descriptor].

`InputEncoder` builds the network input from states and a `GoalInput` (`curious.agent.goals`:
the goal part, slots, mask and task descriptor, as one value).

The goal vector has one 3-D slot per module. Modular conditions fill only the practised module's
slot and set the one-hot task descriptor; the holistic `her` condition fills every slot and leaves
the descriptor at zero. Inactive slots are zero *after* scaling, so that their first-layer weights
receive no gradient (the masking of paper §3).

States are normalised with running statistics (mean and std of every step's state, the OpenAI
Baselines rule, clip 5). Goals are not: each module's goal space is a known box (the module maps
g in [-1, 1]^3 affinely into it), and a slot is fed to the networks as its coordinates in that box,
`(slot - centre) / half_width`, a fixed map (`GoalBox`). A goal anywhere in the goal space gives
the g it was drawn from: distinct goals give distinct inputs, none clipped, from the first cycle of
a run to its last. Hindsight goals outside the box (a cube pushed far) get values beyond 1, clipped
at `norm_clip` half-widths.

Why not running statistics for goals: taken from every step's hindsight outcome (where relabelled
goals come from) they follow cubes that mostly rest on the table, whose spread is tiny; then goals
of `cube1_above_cube2` at different heights all encoded to the clip value. The authors' release
trained without any normalisation (`--normalize_obs` defaults to False in its train.py), which
keeps goals distinct too; the fixed map keeps that property and gives inputs of unit scale.
"""

from __future__ import annotations

import numpy as np
import torch

from curious.agent.goals import GoalBox, GoalInput
from curious.agent.normalizer import RunningNormalizer, device_copies
from curious.envs.goal_env import EnvSpec


class InputEncoder:
    """Owns the state normaliser and the goal map; builds network inputs from raw arrays."""

    def __init__(
        self, spec: EnvSpec, goal_box: GoalBox, norm_eps: float = 0.01, norm_clip: float = 5.0
    ) -> None:
        self.spec = spec
        self.state_norm = RunningNormalizer((spec.state_dim,), eps=norm_eps, clip=norm_clip)
        expected = (spec.n_modules, spec.goal_dim)
        if goal_box.centre.shape != expected or goal_box.half_width.shape != expected:
            raise ValueError(f"goal box of shape {goal_box.centre.shape}, spec needs {expected}")
        self.goal_box = goal_box
        self.clip = float(norm_clip)
        self._goal_centre = goal_box.centre.astype(np.float32)
        self._goal_scale = goal_box.scale
        self._torch: dict[str, tuple[torch.Tensor, ...]] = {}
        n, g = spec.n_modules, spec.goal_dim
        self.input_dim = spec.state_dim + n * g + n

    def update_stats(self, states: np.ndarray) -> None:
        """Add the states of a batch of episodes, (E, T+1, S), to the state statistics."""
        self.state_norm.update(states.reshape(-1, self.spec.state_dim))

    def encode_goals(self, goal: GoalInput[torch.Tensor]) -> torch.Tensor:
        """(B, N * G) network goal inputs: each slot's coordinates in its module's goal box,
        clipped, zero where the mask is not set."""
        slots = goal.slots
        centre, scale = device_copies(
            self._torch, slots.device, self._goal_centre, self._goal_scale
        )
        scaled = torch.clamp((slots - centre) / scale, -self.clip, self.clip)
        return (scaled * goal.mask.unsqueeze(-1)).flatten(1)

    def encode(self, state: torch.Tensor, goal: GoalInput[torch.Tensor]) -> torch.Tensor:
        """(B, input_dim) `[s_t, g, task_d]` from states (B, S) and their goal input."""
        s = self.state_norm.normalize(state)
        return torch.cat([s, self.encode_goals(goal), goal.task], dim=1)

    def encode_pair(
        self, state: torch.Tensor, next_state: torch.Tensor, goal: GoalInput[torch.Tensor]
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """`encode` of a transition's two states with one goal part (half the work)."""
        n = state.shape[0]
        s = self.state_norm.normalize(torch.cat([state, next_state]))
        g = self.encode_goals(goal)
        task = goal.task
        return torch.cat([s[:n], g, task], dim=1), torch.cat([s[n:], g, task], dim=1)

    def state_dict(self) -> dict:
        return {"state": self.state_norm.state_dict()}

    def load_state_dict(self, state: dict) -> None:
        self.state_norm.load_state_dict(state["state"])
