"""DDPG (the authors') and TD3 (an option) on E-UVFA inputs: one actor-critic and its update.

The update, with the authors' settings (docs/agent.md), on a minibatch (x, a, r, x'):

* TD target: y = r + gamma * Q'(x', pi'(x')), clipped to [-1/(1-gamma), 0] (rewards are -1 or 0
  and episodes never terminate, so there is no done mask) (`td_target`);
* critic loss: mean (Q(x, a) - y)^2 (`critic_loss`);
* actor loss: -mean Q(x, pi(x)) + action_l2 * mean pi(x)^2, through the critic held fixed
  (`actor_loss`);
* Adam 1e-3 for actor and critic; DDPG takes both gradients from the current networks, then
  steps both, as the authors' baselines code did;
* targets: theta' <- polyak * theta' + (1 - polyak) * theta, once per cycle (`update_targets`).

TD3 (Fujimoto et al. 2018) changes three things: two critics and the minimum of their targets,
clipped Gaussian smoothing noise on the target action, and an actor step every
`td3_policy_delay` critic steps, through the stepped critics. The target schedule stays the
cycle's.

`Learner.update` is the one place that says which steps an update takes (`ddpg_step`, or TD3's
`critic_step` and `actor_step`); they run on the backend `Config.learner_backend` picks
(`curious.agent.update_backends`: the reference with autograd, the same functions compiled, or
the same update written out into preallocated buffers), which also keeps each network's
parameters in one flat tensor. docs/benchmarks.md has the speed of each.

Inputs arrive normalised (`curious.agent.inputs.InputEncoder`); the learner only does arithmetic on
tensors of its device.
"""

from __future__ import annotations

import copy
from typing import Any

import torch
from torch import nn
from torch.func import functional_call

from curious.agent.networks import Actor, Critic
from curious.agent.update_backends import UpdateBackend
from curious.config import Config


class Learner:
    """One actor-critic pair with its targets, optimisers and update rule."""

    def __init__(self, input_dim: int, action_dim: int, config: Config, seed: int = 0) -> None:
        self.config = config
        self.device = torch.device(config.device)
        self.action_dim = action_dim
        self.td3 = config.algorithm == "td3"
        h, n_layers = config.hidden, config.layers
        n_critics = 2 if self.td3 else 1
        cpu_rng_state = torch.get_rng_state()  # deterministic initial weights from `seed`
        torch.manual_seed(seed)
        actor = Actor(input_dim, action_dim, h, n_layers)
        critics = nn.ModuleList(
            Critic(input_dim, action_dim, h, n_layers) for _ in range(n_critics)
        )
        torch.set_rng_state(cpu_rng_state)
        self.actor = actor.to(self.device)
        self.critics = critics.to(self.device)
        self.actor_target = copy.deepcopy(self.actor).requires_grad_(False)
        self.critics_target = copy.deepcopy(self.critics).requires_grad_(False)
        self.clip_return = 1.0 / (1.0 - config.gamma)
        self.n_updates = 0
        self.input_dim = input_dim
        self._last_actor_loss = torch.zeros((), device=self.device)
        # flat parameters, Adam, the generator and the backend that runs the steps below
        self.backend = UpdateBackend(self, config, seed)
        self.actor_opt, self.critic_opt = self.backend.actor_opt, self.backend.critic_opt
        self.generator = self.backend.generator

    # -------------------------------------------------------------------------------------------
    @torch.no_grad()
    def act(self, x: torch.Tensor) -> torch.Tensor:
        """Deterministic actions pi(x), shape (B, action_dim)."""
        return self.actor(x)

    def target_noise(self, batch_size: int) -> torch.Tensor:
        """TD3's standard normal draws for smoothing a minibatch's target actions, from the
        learner's generator (drawn outside the compiled steps, which cannot trace a generator)."""
        shape = (batch_size, self.action_dim)
        return torch.randn(shape, generator=self.generator, device=self.device)

    @torch.no_grad()
    def td_target(
        self, reward: torch.Tensor, x_next: torch.Tensor, noise: torch.Tensor | None = None
    ) -> torch.Tensor:
        """r + gamma * Q'(x', pi'(x')), clipped to [-1/(1-gamma), 0]; TD3 smooths the target
        action with `noise` (`target_noise` when not given) and takes the smaller of its two
        target critics."""
        cfg = self.config
        next_action = self.actor_target(x_next)
        if self.td3:
            noise = self.target_noise(len(x_next)) if noise is None else noise
            noise = (noise * cfg.td3_target_noise).clamp(-cfg.td3_noise_clip, cfg.td3_noise_clip)
            next_action = (next_action + noise).clamp(-1.0, 1.0)
        q_next = self.critics_target[0](x_next, next_action)
        if self.td3:
            q_next = torch.minimum(q_next, self.critics_target[1](x_next, next_action))
        return (reward + cfg.gamma * q_next).clamp(-self.clip_return, 0.0)

    def critic_loss(
        self, x: torch.Tensor, action: torch.Tensor, target: torch.Tensor
    ) -> torch.Tensor:
        """Sum over the critics of mean (Q(x, a) - y)^2."""
        return sum((critic(x, action) - target).square().mean() for critic in self.critics)

    def actor_loss(self, x: torch.Tensor) -> torch.Tensor:
        """-mean Q1(x, pi(x)) + action_l2 * mean(pi(x)^2), through the critic's weights held
        fixed: its gradient reaches the actor only."""
        pi = self.actor(x)
        critic = self.critics[0]
        fixed = {name: w.detach() for name, w in critic.named_parameters()}
        q_pi = functional_call(critic, fixed, (x, pi))
        return -q_pi.mean() + self.config.action_l2 * pi.square().mean()

    def update(
        self, x: torch.Tensor, action: torch.Tensor, reward: torch.Tensor, x_next: torch.Tensor
    ) -> dict[str, torch.Tensor]:
        """One gradient step on a minibatch; returns detached losses (no device sync).

        DDPG steps the critic and the actor every time; TD3 steps the critics every time and the
        actor every `td3_policy_delay`-th time. The actor loss reported is that of the actor's
        last step.
        """
        self.n_updates += 1
        step_actor = not self.td3 or self.n_updates % self.config.td3_policy_delay == 0
        critic_loss, actor_loss, q_target = self.backend.step(x, action, reward, x_next, step_actor)
        if actor_loss is not None:
            self._last_actor_loss = actor_loss
        return {
            "critic_loss": critic_loss,
            "actor_loss": self._last_actor_loss,
            "q_target_mean": q_target,
        }

    def ddpg_step(
        self, x: torch.Tensor, action: torch.Tensor, reward: torch.Tensor, x_next: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Both losses from the current networks, both gradients (into zeroed `.grad`s), both Adam
        steps."""
        target = self.td_target(reward, x_next)
        loss, critic_loss, actor_loss = self._ddpg_losses(x, action, target)
        loss.backward()  # each loss reaches its own network only
        self.critic_opt.step()
        self.actor_opt.step()
        return critic_loss, actor_loss, target.mean()

    def _ddpg_losses(
        self, x: torch.Tensor, action: torch.Tensor, target: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The sum of DDPG's two losses, and each detached. Only the sum keeps its autograd
        graph, so that a compiled step can trace its backward (no returned tensor needs it)."""
        critic_loss = self.critic_loss(x, action, target)
        actor_loss = self.actor_loss(x)
        return critic_loss + actor_loss, critic_loss.detach(), actor_loss.detach()

    def critic_step(
        self,
        x: torch.Tensor,
        action: torch.Tensor,
        reward: torch.Tensor,
        x_next: torch.Tensor,
        noise: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """TD3: the critics' loss, gradient and Adam step."""
        target = self.td_target(reward, x_next, noise)
        critic_loss = self.critic_loss(x, action, target)
        critic_loss.backward()
        self.critic_opt.step()
        return critic_loss.detach(), target.mean()

    def actor_step(self, x: torch.Tensor) -> torch.Tensor:
        """TD3: the actor's loss through the stepped critic, its gradient and Adam step."""
        actor_loss = self.actor_loss(x)
        actor_loss.backward()
        self.actor_opt.step()
        return actor_loss.detach()

    @torch.no_grad()
    def update_targets(self) -> None:
        """target <- polyak * target + (1 - polyak) * online."""
        for target, online in zip(self.backend.targets, self.backend.online, strict=True):
            target.lerp_(online, 1.0 - self.config.polyak)

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
