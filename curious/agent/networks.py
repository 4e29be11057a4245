"""Actor and critic networks of the E-UVFA (paper §3, Supplementary Figure 3).

Both take the E-UVFA input x = [state, masked goal vector, one-hot task descriptor] (already
normalised, see `curious.agent.inputs`); the critic also takes the action. Hidden layers are ReLU
(3 x 256 in the paper); the actor ends in tanh so that actions lie in [-1, 1]. Weights start
Xavier/Glorot-uniform and biases at zero, as the authors' `tf.layers.dense` with
`xavier_initializer` (flowersteam/curious, baselines/her/util.py).

The authors' first layer was two dense layers added together, one on [state, task] and a bias-free
one on the goal, each initialised with its own fan-in; ours is one layer on the concatenation
(the same function class; the initial weights' scale differs slightly).
"""

from __future__ import annotations

import torch
from torch import nn


def mlp(in_dim: int, out_dim: int, hidden: int, layers: int) -> nn.Sequential:
    """`layers` ReLU hidden layers of `hidden` units, then a linear output layer (Xavier-uniform
    weights, zero biases)."""
    modules: list[nn.Module] = []
    width = in_dim
    for _ in range(layers):
        modules += [nn.Linear(width, hidden), nn.ReLU()]
        width = hidden
    modules.append(nn.Linear(width, out_dim))
    for layer in modules:
        if isinstance(layer, nn.Linear):
            nn.init.xavier_uniform_(layer.weight)
            nn.init.zeros_(layer.bias)
    return nn.Sequential(*modules)


class Actor(nn.Module):
    """pi(x) in [-1, 1]^action_dim."""

    def __init__(self, input_dim: int, action_dim: int, hidden: int = 256, layers: int = 3):
        super().__init__()
        self.net = mlp(input_dim, action_dim, hidden, layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.tanh(self.net(x))


class Critic(nn.Module):
    """Q(x, a) as a (batch,) tensor."""

    def __init__(self, input_dim: int, action_dim: int, hidden: int = 256, layers: int = 3):
        super().__init__()
        self.net = mlp(input_dim + action_dim, 1, hidden, layers)

    def forward(self, x: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat([x, action], dim=-1)).squeeze(-1)
