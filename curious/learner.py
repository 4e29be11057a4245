"""DDPG (the authors') and TD3 (an option) on E-UVFA inputs: one actor-critic and its update.

The update follows the authors' settings (DESIGN §3): Adam 1e-3 for actor and critic, targets
y = r + gamma * Q'(x', pi'(x')) clipped to [-1/(1-gamma), 0] (rewards are -1 or 0 and episodes
never terminate, so there is no done mask), actor loss -Q(x, pi(x)) + action_l2 * mean(pi(x)^2),
target networks moved by Polyak averaging once per cycle (`update_targets`).

TD3 (Fujimoto et al. 2018) changes three things: two critics and the minimum of their targets,
clipped Gaussian smoothing noise on the target action, and an actor step every
`td3_policy_delay` critic steps. The target schedule stays the cycle's.

Inputs arrive normalised (`curious.inputs.InputEncoder`); the learner only does arithmetic on
tensors of its device.
"""

from __future__ import annotations

import copy
from typing import Any

import torch
from torch import nn

from curious.config import Config
from curious.mlp_workspace import MLPWorkspace, fold_parameters
from curious.networks import Actor, Critic


def _adam(params: list[nn.Parameter], lr: float) -> torch.optim.Adam:
    """Adam with the fastest implementation this torch offers for the device."""
    try:
        return torch.optim.Adam(params, lr=lr, fused=True)
    except (RuntimeError, TypeError):  # fused not available for this device / build
        return torch.optim.Adam(params, lr=lr, foreach=True)


def _adam_step(optimizer: torch.optim.Adam) -> None:
    """`optimizer.step()` for one fused Adam over one tensor, minus the per-call bookkeeping.

    `Optimizer.step` regroups the tensors by device and dtype and runs its hooks on every call,
    about 60 us at the authors' sizes, twice per update (docs/benchmarks.md). With one
    parameter and its state in place, the fused kernel is called directly, on the optimizer's
    own state, with the same arguments `step` would pass (for torch 2.13, the pinned version;
    a test checks that both give the same bits). The first step, which creates the state,
    and an unfused optimizer take the ordinary path.
    """
    (group,) = optimizer.param_groups
    (param,) = group["params"]
    state = optimizer.state.get(param)
    if not group["fused"] or not state or group["amsgrad"] or group["maximize"]:
        optimizer.step()
        return
    state["step"].add_(1)
    beta1, beta2 = group["betas"]
    torch._fused_adam_(
        [param],
        [param.grad],
        [state["exp_avg"]],
        [state["exp_avg_sq"]],
        [],
        [state["step"]],
        amsgrad=False,
        lr=group["lr"],
        beta1=beta1,
        beta2=beta2,
        weight_decay=group["weight_decay"],
        eps=group["eps"],
        maximize=False,
        grad_scale=None,
        found_inf=None,
    )


class _Workspace:
    """Buffers of one batch size: a workspace per network (each holds its own input buffer)."""

    def __init__(self, learner: Learner, batch: int) -> None:
        self.actor = MLPWorkspace(learner.actor.net, batch)
        self.critics = [MLPWorkspace(c.net, batch) for c in learner.critics]
        self.actor_target = MLPWorkspace(learner.actor_target.net, batch, with_grads=False)
        self.critics_target = [
            MLPWorkspace(c.net, batch, with_grads=False) for c in learner.critics_target
        ]
        # d(-mean q)/dq, the actor loss's gradient at the critic's output
        self.minus_mean = torch.full((batch, 1), -1.0 / batch, device=learner.device)


class Learner:
    """One actor-critic pair with its targets, optimisers and update rule."""

    def __init__(self, input_dim: int, action_dim: int, config: Config, seed: int = 0) -> None:
        self.config = config
        self.device = torch.device(config.device)
        self.action_dim = action_dim
        self.td3 = config.algorithm == "td3"
        cpu_rng_state = torch.get_rng_state()
        torch.manual_seed(seed)  # deterministic initial weights, independent of callers' RNG use
        h, n_layers = config.hidden, config.layers
        self.actor = Actor(input_dim, action_dim, h, n_layers).to(self.device)
        n_critics = 2 if self.td3 else 1
        self.critics = nn.ModuleList(
            Critic(input_dim, action_dim, h, n_layers) for _ in range(n_critics)
        ).to(self.device)
        torch.set_rng_state(cpu_rng_state)
        self.actor_target = copy.deepcopy(self.actor).requires_grad_(False)
        self.critics_target = copy.deepcopy(self.critics).requires_grad_(False)
        self._online = [
            fold_parameters(self.actor, grads=True),
            fold_parameters(self.critics, grads=True),
        ]
        self._targets = [
            fold_parameters(self.actor_target, grads=False),
            fold_parameters(self.critics_target, grads=False),
        ]
        self.actor_opt = _adam([self._online[0]], config.actor_lr)
        self.critic_opt = _adam([self._online[1]], config.critic_lr)
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(seed + 1)
        self.clip_return = 1.0 / (1.0 - config.gamma)
        self.n_updates = 0
        self.input_dim = input_dim
        self._workspaces: dict[int, _Workspace] = {}
        self._last_actor_loss = torch.zeros((), device=self.device)

    # -------------------------------------------------------------------------------------------
    @torch.no_grad()
    def act(self, x: torch.Tensor) -> torch.Tensor:
        """Deterministic actions pi(x), shape (B, action_dim)."""
        return self.actor(x)

    def _workspace(self, batch: int) -> _Workspace:
        if batch not in self._workspaces:
            self._workspaces[batch] = _Workspace(self, batch)
        return self._workspaces[batch]

    @torch.no_grad()
    def td_target(self, reward: torch.Tensor, x_next: torch.Tensor) -> torch.Tensor:
        """r + gamma * Q'(x', pi'(x')), clipped to [-1/(1-gamma), 0]; TD3 smooths the target
        action and takes the smaller of its two target critics."""
        cfg = self.config
        ws = self._workspace(x_next.shape[0])
        next_action = ws.actor_target.forward(x_next).tanh_()
        if self.td3:
            noise = torch.randn(next_action.shape, generator=self.generator, device=self.device)
            noise.mul_(cfg.td3_target_noise).clamp_(-cfg.td3_noise_clip, cfg.td3_noise_clip)
            next_action.add_(noise).clamp_(-1.0, 1.0)
        inputs = ws.critics_target[0].input
        inputs[:, : self.input_dim].copy_(x_next)
        inputs[:, self.input_dim :].copy_(next_action)
        q_next = ws.critics_target[0].forward(inputs)[:, 0]
        if self.td3:
            q_next = torch.minimum(q_next, ws.critics_target[1].forward(inputs)[:, 0])
        return (reward + cfg.gamma * q_next).clamp_(-self.clip_return, 0.0)

    @torch.no_grad()
    def update(
        self, x: torch.Tensor, action: torch.Tensor, reward: torch.Tensor, x_next: torch.Tensor
    ) -> dict[str, torch.Tensor]:
        """One gradient step on a minibatch; returns detached losses (no device sync).

        Critic: minimise mean (Q(x, a) - y)^2 for each critic. Actor: minimise
        -mean Q1(x, pi(x)) + action_l2 * mean(pi(x)^2); its gradient flows through the critic's
        input, never into the critic's weights. DDPG takes both gradients from the current
        networks, then steps both (as the authors' baselines code did); TD3 steps the critics
        first and the actor, every `td3_policy_delay` steps, through the updated critic. Both
        passes are written out (`MLPWorkspace`).
        """
        cfg = self.config
        batch, d = x.shape[0], self.input_dim
        ws = self._workspace(batch)
        target = self.td_target(reward, x_next)

        inputs = ws.critics[0].input
        inputs[:, :d].copy_(x)
        inputs[:, d:].copy_(action)
        critic_loss = torch.zeros((), device=self.device)
        for critic_ws in ws.critics:
            diff = critic_ws.forward(inputs)[:, 0] - target
            critic_loss += diff.square().mean()
            critic_ws.backward(diff.mul_(2.0 / batch).unsqueeze(1))
        if self.td3:
            _adam_step(self.critic_opt)

        self.n_updates += 1
        if not self.td3 or self.n_updates % cfg.td3_policy_delay == 0:
            pi = ws.actor.forward(x).tanh_()
            inputs[:, d:].copy_(pi)
            q_pi = ws.critics[0].forward(inputs)
            pi_sq = pi.square()
            self._last_actor_loss = cfg.action_l2 * pi_sq.mean() - q_pi.mean()
            grad_pi = ws.critics[0].backward(
                ws.minus_mean, weight_grads=False, input_grad=True, input_columns=slice(d, None)
            )
            grad_pi.add_(pi, alpha=2.0 * cfg.action_l2 / pi.numel())
            grad_pi.mul_(pi_sq.neg_().add_(1.0))  # through tanh: d tanh(z)/dz = 1 - tanh^2
            ws.actor.backward(grad_pi)
            _adam_step(self.actor_opt)
        if not self.td3:
            _adam_step(self.critic_opt)
        return {
            "critic_loss": critic_loss,
            "actor_loss": self._last_actor_loss,
            "q_target_mean": target.mean(),
        }

    @torch.no_grad()
    def update_targets(self) -> None:
        """target <- polyak * target + (1 - polyak) * online."""
        torch._foreach_lerp_(self._targets, self._online, 1.0 - self.config.polyak)

    # -------------------------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        return {
            "actor": self.actor.state_dict(),
            "critics": self.critics.state_dict(),
            "actor_target": self.actor_target.state_dict(),
            "critics_target": self.critics_target.state_dict(),
            "actor_opt": self.actor_opt.state_dict(),
            "critic_opt": self.critic_opt.state_dict(),
            "generator": self.generator.get_state(),
            "n_updates": self.n_updates,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        # Copy first: torch optimisers adopt the given tensors, so loading a live learner's state
        # without a copy would make two learners share (and both update) one set of moments.
        state = copy.deepcopy(state)
        self.actor.load_state_dict(state["actor"])
        self.critics.load_state_dict(state["critics"])
        self.actor_target.load_state_dict(state["actor_target"])
        self.critics_target.load_state_dict(state["critics_target"])
        self.actor_opt.load_state_dict(state["actor_opt"])
        self.critic_opt.load_state_dict(state["critic_opt"])
        self.generator.set_state(
            state["generator"].cpu() if hasattr(state["generator"], "cpu") else state["generator"]
        )
        self.n_updates = int(state["n_updates"])
