"""How the learner's update runs: flat parameters, Adam, and the backend that runs its steps.

`curious.agent.learner.Learner` states the update (TD target, losses, the steps DDPG and TD3
take); this module makes it fast without changing what it computes. Every network's parameters
live in one flat tensor (so Adam and the Polyak update run once per network), Adam is the
fastest implementation the device offers, and `Config.learner_backend` picks who runs the steps:

* `autograd`: the learner's own step functions, with autograd (the reference);
* `compiled`: the same functions through `torch.compile` (on CUDA in `reduce-overhead` mode: each
  step one CUDA graph with a capturable Adam; DDPG's step with its backward traced into the
  graph, `compile_step`);
* `workspace`: `curious.agent.mlp_workspace.WorkspaceUpdate`, the same update with both passes
  written out into preallocated buffers, the fastest on a CPU.

docs/benchmarks.md has the speed of each; tests/test_agent_learner.py holds them to the
reference, step for step.
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from typing import Any, Protocol

import torch
from torch import nn

from curious.agent.mlp_workspace import WorkspaceUpdate, fold_parameters
from curious.config import Config

StepLosses = tuple[torch.Tensor, torch.Tensor | None, torch.Tensor]
"""What one backend's step returns, detached: the critic loss, the actor loss (None where the
actor was not stepped) and the mean TD target."""


def flatten_parameters(module: nn.Module, grads: bool) -> torch.Tensor:
    """Moves all of `module`'s parameters into one flat tensor and returns it; each parameter
    stays the module's, as a contiguous view of it. With `grads`, the tensor is a Parameter whose
    one flat `.grad` holds the parameters' gradients as views. One tensor per network lets Adam
    and the Polyak update run once per network."""
    params = list(module.parameters())
    flat = torch.cat([p.detach().reshape(-1) for p in params])
    if grads:
        flat = nn.Parameter(flat)
        flat.grad = torch.zeros_like(flat)
    offset = 0
    for p in params:
        n = p.numel()
        p.data = flat.data[offset : offset + n].view_as(p)
        if grads:
            p.grad = flat.grad[offset : offset + n].view_as(p)
        offset += n
    return flat


def adam(params: list[nn.Parameter], lr: float, capturable: bool = False) -> torch.optim.Adam:
    """Adam with the fastest implementation this torch offers for the device; `capturable`
    keeps its step count on the device, so that a CUDA graph can replay the step."""
    if capturable:
        return torch.optim.Adam(params, lr=lr, foreach=True, capturable=True)
    try:
        return torch.optim.Adam(params, lr=lr, fused=True)
    except (RuntimeError, TypeError):  # fused not available for this device / build
        return torch.optim.Adam(params, lr=lr, foreach=True)


DYNAMO_PROFILER_NOTICE = ("torch._dynamo.variables.ctx_manager", "Profiler record function ")
"""(logger, the message's start) of what dynamo logs when a compiled step meets Adam's profiler
range, which stays out of the graph: a notice at the first step that says nothing a user of
curious can act on."""


class _DropsNotice(logging.Filter):
    def __init__(self, start: str) -> None:
        super().__init__()
        self.start = start

    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith(self.start)


@functools.cache
def quiet_dynamo_profiler_notice() -> None:
    """Drops `DYNAMO_PROFILER_NOTICE`, once per process; a torch whose logger or wording differs
    prints it, and nothing else changes."""
    logger, start = DYNAMO_PROFILER_NOTICE
    logging.getLogger(logger).addFilter(_DropsNotice(start))


def compile_step(
    step: Callable[..., Any], mode: str | None, trace_backward: bool
) -> Callable[..., Any]:
    """`torch.compile(step, mode=mode)`; with `trace_backward`, the step's `backward()` is traced
    into the graph of its losses where this torch can (dynamo's `trace_autograd_ops`, set while
    the step runs: dynamo reads its settings when it compiles, and recompiles where they
    differ). DDPG's step then runs as the losses-and-gradients graph and Adam's, instead of the
    losses' graph, the autograd engine's kernels one by one, and Adam's (docs/benchmarks.md: 0.87
    against 1.30 ms an update on an H100). TD3's steps keep the break: traced, torch 2.11 on CUDA
    skipped the critic step's CUDA graph (its gradients are mutated inputs) and failed in the
    actor step. A torch without the setting compiles the step with the break."""
    quiet_dynamo_profiler_notice()
    compiled = torch.compile(step, mode=mode)
    if not trace_backward or not hasattr(torch._dynamo.config, "trace_autograd_ops"):
        return compiled
    traced = torch._dynamo.config.patch(trace_autograd_ops=True)

    @functools.wraps(step)
    def run(*args: Any) -> Any:
        with traced:
            return compiled(*args)

    return run


class UpdateSteps(Protocol):
    """What a backend runs: the networks of a learner and the steps of its update
    (`curious.agent.learner.Learner` is one). A protocol, so that this module, which the learner
    imports, does not import it back."""

    td3: bool
    device: torch.device
    actor: nn.Module
    critics: nn.ModuleList
    actor_target: nn.Module
    critics_target: nn.ModuleList

    def target_noise(self, batch_size: int) -> torch.Tensor: ...

    def ddpg_step(
        self, x: torch.Tensor, action: torch.Tensor, reward: torch.Tensor, x_next: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]: ...

    def critic_step(
        self,
        x: torch.Tensor,
        action: torch.Tensor,
        reward: torch.Tensor,
        x_next: torch.Tensor,
        noise: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor]: ...

    def actor_step(self, x: torch.Tensor) -> torch.Tensor: ...


class UpdateBackend:
    """The flat parameters, the optimisers, the generator and the step runner of one learner.

    Built once the learner's networks and their targets exist: it moves their parameters into
    one flat tensor per network (the workspace lays out each layer as a `[W | b]` block), makes
    the two Adams and TD3's generator (seeded `seed + 1`), and wires the backend
    `config.learner_backend` names."""

    def __init__(self, learner: UpdateSteps, config: Config, seed: int) -> None:
        self.td3 = learner.td3
        flatten = fold_parameters if config.learner_backend == "workspace" else flatten_parameters
        nets = (learner.actor, learner.critics)
        self.online = [flatten(net, grads=True) for net in nets]
        targets = (learner.actor_target, learner.critics_target)
        self.targets = [flatten(net, grads=False) for net in targets]
        compiled = config.learner_backend == "compiled"
        self.graphs = compiled and learner.device.type == "cuda"  # each step one CUDA graph
        self.actor_opt = adam([self.online[0]], config.actor_lr, capturable=self.graphs)
        self.critic_opt = adam([self.online[1]], config.critic_lr, capturable=self.graphs)
        self.generator = torch.Generator(device=learner.device)
        self.generator.manual_seed(seed + 1)
        self.target_noise = learner.target_noise
        # the backend's step: (x, a, r, x', step_actor) -> StepLosses
        self.step: Callable[..., StepLosses] = self._autograd_step
        if config.learner_backend == "workspace":
            self.step = WorkspaceUpdate(
                actor=learner.actor,
                critics=learner.critics,
                actor_target=learner.actor_target,
                critics_target=learner.critics_target,
                actor_opt=self.actor_opt,
                critic_opt=self.critic_opt,
                config=config,
                generator=self.generator,
            ).update
        steps = (learner.ddpg_step, learner.critic_step, learner.actor_step)
        if compiled:  # losses, backward and Adam in one compiled function each
            mode = "reduce-overhead" if self.graphs else None
            steps = (
                compile_step(learner.ddpg_step, mode, trace_backward=True),
                compile_step(learner.critic_step, mode, trace_backward=False),
                compile_step(learner.actor_step, mode, trace_backward=False),
            )
        self._steps = steps

    def _autograd_step(
        self,
        x: torch.Tensor,
        action: torch.Tensor,
        reward: torch.Tensor,
        x_next: torch.Tensor,
        step_actor: bool,
    ) -> StepLosses:
        """The reference backend (and the compiled one): DDPG's step, or TD3's critic step and,
        when `step_actor`, its actor step through the stepped critics."""
        ddpg_step, critic_step, actor_step = self._steps
        actor_flat, critics_flat = self.online
        if self.graphs:  # a new replay of the captured graphs begins
            torch.compiler.cudagraph_mark_step_begin()
        # Gradients are zeroed here, outside the steps: a compiled step that wrote into a tensor
        # it was handed would not be captured as a CUDA graph ("mutated inputs").
        if not self.td3:
            actor_flat.grad.zero_()
            critics_flat.grad.zero_()
            critic_loss, actor_loss, q_target = self._kept(ddpg_step(x, action, reward, x_next))
            return critic_loss, actor_loss, q_target
        critics_flat.grad.zero_()
        noise = self.target_noise(len(x))
        critic_loss, q_target = self._kept(critic_step(x, action, reward, x_next, noise))
        actor_loss = None
        if step_actor:
            actor_flat.grad.zero_()
            actor_loss = self._kept((actor_step(x),))[0]
        return critic_loss, actor_loss, q_target

    def _kept(self, outputs: tuple[torch.Tensor, ...]) -> tuple[torch.Tensor, ...]:
        """A step's outputs, copied out of the CUDA graph's buffers (its next replay
        overwrites them); as they are otherwise."""
        return tuple(t.clone() for t in outputs) if self.graphs else outputs
