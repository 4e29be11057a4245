"""The DDPG / TD3 update with explicit forward and backward passes into preallocated buffers.

`Config.learner_backend = "workspace"`: the fastest update on a CPU, and an option beside the
autograd reference (`curious.agent.learner.Learner.update`), which a test compares it with. The
`Learner` picks this backend and hands `WorkspaceUpdate` its networks, optimisers and settings;
this module knows nothing of the `Learner` (the dependency runs one way).

The DDPG update is a dozen small matrix products per network; on a CPU, autograd's bookkeeping
and the fresh tensors it allocates for every activation and gradient cost a good part of what
the products themselves cost. `WorkspaceUpdate` therefore writes the two passes out: every
product goes into a buffer allocated once per batch size, ReLU runs in place, its backward is
one fused `threshold_backward` into a buffer, and weight gradients land directly in each
parameter's `.grad`, where the optimiser reads them. The arithmetic is that of autograd (the
tests compare the updates); the networks stay ordinary `nn.Module`s.

Biases ride inside the products. `fold_parameters` stores each Linear layer as one
(out, in + 1) block [W | b], so that the weight and the bias are views of it, and every
activation buffer carries a last column of ones. A layer's forward is then one product
[h, 1] @ [W | b]^T, and its weight and bias gradients one product g^T @ [h, 1], instead of a
product plus a broadcast copy of the bias, and a product plus a column sum (docs/benchmarks.md).

An MLP here is what `curious.agent.networks.mlp` builds: Linear, ReLU, ..., Linear.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from curious.agent.networks import Actor, Critic
from curious.config import Config

_relu_backward = torch.ops.aten.threshold_backward.grad_input


def fold_parameters(module: nn.Module, grads: bool) -> torch.Tensor:
    """Moves all of `module`'s Linear layers into one flat tensor, and returns it.

    Each layer becomes a contiguous (out, in + 1) block [W | b] of the tensor; its weight and
    bias stay the module's parameters (state dicts, `forward` and the tests see no difference)
    but become views of the block. With `grads`, the returned tensor is a Parameter and the
    layers' gradients become views of the same blocks of its `.grad`. One tensor per network
    lets Adam and the Polyak update run once per network; the blocks let `MLPWorkspace` fold
    the biases into its products.
    """
    linears = [m for m in module.modules() if isinstance(m, nn.Linear)]
    n_params = len(list(module.parameters()))
    if any(lin.bias is None for lin in linears) or n_params != 2 * len(linears):
        raise ValueError("fold_parameters expects parameters only in Linear layers with biases")
    shapes = [(lin.out_features, lin.in_features + 1) for lin in linears]
    weight = linears[0].weight
    flat = torch.empty(sum(o * i for o, i in shapes), device=weight.device, dtype=weight.dtype)
    if grads:
        flat = nn.Parameter(flat)
        flat.grad = torch.zeros_like(flat)
    offset = 0
    for lin, (n_out, n_in) in zip(linears, shapes, strict=True):
        block = flat.data[offset : offset + n_out * n_in].view(n_out, n_in)
        block[:, :-1].copy_(lin.weight.detach())
        block[:, -1].copy_(lin.bias.detach())
        lin.weight.data, lin.bias.data = block[:, :-1], block[:, -1]
        if grads:
            grad = flat.grad[offset : offset + n_out * n_in].view(n_out, n_in)
            lin.weight.grad, lin.bias.grad = grad[:, :-1], grad[:, -1]
        offset += n_out * n_in
    return flat


def _block(weight: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
    """The (out, in + 1) block [W | b] that `fold_parameters` made `weight` and `bias` views of."""
    n_out, n_in = weight.shape
    folded = (
        weight.stride() == (n_in + 1, 1)
        and bias.stride() == (n_in + 1,)
        and bias.data_ptr() == weight.data_ptr() + n_in * weight.element_size()
    )
    if not folded:
        raise ValueError("MLPWorkspace needs the layers laid out by fold_parameters")
    return weight.detach().as_strided((n_out, n_in + 1), (n_in + 1, 1))


def _with_ones(batch: int, width: int, like: torch.Tensor) -> torch.Tensor:
    """A (batch, width + 1) buffer whose last column is ones (the biases' input)."""
    buffer = torch.empty(batch, width + 1, device=like.device, dtype=like.dtype)
    buffer[:, -1] = 1.0
    return buffer


class MLPWorkspace:
    """Buffers and passes for one `nn.Sequential` MLP at one batch size.

    `input` is a (batch, in) view of the first layer's buffer: callers may write the input
    there in place (the learner assembles the critic's [x, a] in it) and call `forward(input)`.
    """

    def __init__(self, net: nn.Sequential, batch: int, with_grads: bool = True) -> None:
        self.linears = [m for m in net if isinstance(m, nn.Linear)]
        expected = 2 * len(self.linears) - 1
        if len(net) != expected or not all(isinstance(m, nn.ReLU) for m in list(net)[1::2]):
            raise ValueError("MLPWorkspace expects Linear, ReLU, ..., Linear")
        self.blocks = [_block(lin.weight, lin.bias) for lin in self.linears]
        self.grad_blocks = (
            [_block(lin.weight.grad, lin.bias.grad) for lin in self.linears] if with_grads else []
        )
        like = self.blocks[0]
        first, *hidden = self.linears
        self._input = _with_ones(batch, first.in_features, like)
        self.input = self._input[:, :-1]
        self._hidden = [_with_ones(batch, lin.in_features, like) for lin in hidden]
        self._output = like.new_empty(batch, self.linears[-1].out_features)
        self.input_grads = [like.new_empty(batch, lin.in_features) for lin in self.linears]
        self._column_grads: dict[tuple[int, int], torch.Tensor] = {}
        self._ready = False

    def _below(self, i: int) -> torch.Tensor:
        """Layer i's input with its column of ones."""
        return self._hidden[i - 1] if i > 0 else self._input

    @torch.no_grad()
    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """The MLP's output for x (batch, in); keeps the activations for `backward`."""
        if x.data_ptr() != self.input.data_ptr():
            self.input.copy_(x)
        last = len(self.linears) - 1
        for i, block in enumerate(self.blocks):
            if i < last:
                # ReLU over the whole buffer: max(1, 0) leaves the column of ones as it is
                torch.mm(self._below(i), block.t(), out=self._hidden[i][:, :-1])
                self._hidden[i].clamp_min_(0.0)
            else:
                torch.mm(self._below(i), block.t(), out=self._output)
        self._ready = True
        return self._output

    @torch.no_grad()
    def backward(
        self,
        grad_output: torch.Tensor,
        weight_grads: bool = True,
        input_grad: bool = False,
        input_columns: slice | None = None,
    ) -> torch.Tensor | None:
        """Back-propagate dL/d(output) through the last `forward`.

        With `weight_grads`, each parameter's `.grad` is overwritten with dL/dparameter. With
        `input_grad`, returns dL/d(input), or only its `input_columns` (the critic's action
        part), as a buffer valid until the next call.
        """
        if not self._ready:
            raise RuntimeError("backward() before forward()")
        g = grad_output
        for i in range(len(self.linears) - 1, -1, -1):
            block, below = self.blocks[i], self._below(i)
            if weight_grads:
                torch.mm(g.t(), below, out=self.grad_blocks[i])
            if i == 0:
                if not input_grad:
                    return None
                if input_columns is not None:
                    start, stop, _ = input_columns.indices(block.shape[1] - 1)
                    key = (start, stop)
                    if key not in self._column_grads:
                        self._column_grads[key] = g.new_empty(g.shape[0], stop - start)
                    return torch.mm(g, block[:, start:stop], out=self._column_grads[key])
            grad_in = self.input_grads[i]
            torch.mm(g, block[:, :-1], out=grad_in)
            if i > 0:
                _relu_backward(grad_in, below[:, :-1], 0.0, grad_input=grad_in)
            g = grad_in
        return g


DIRECT_ADAM_TORCH = "2.13.0"
"""The torch release whose private fused-Adam kernel `_adam_step` calls directly."""


def _adam_step(optimizer: torch.optim.Adam) -> None:
    """`optimizer.step()` for one fused Adam over one tensor, minus the per-call bookkeeping.

    `Optimizer.step` regroups the tensors by device and dtype and runs its hooks on every call,
    about 60 us at the authors' sizes, twice per update (docs/benchmarks.md). With one
    parameter and its state in place, the fused kernel is called directly, on the optimizer's
    own state, with the same arguments `step` would pass. The kernel is private: it is called
    only on the torch release it was checked against (`DIRECT_ADAM_TORCH`; a test checks that
    both give the same bits there). Other releases, the first step (which creates the state)
    and an unfused optimizer take the ordinary path.
    """
    (group,) = optimizer.param_groups
    (param,) = group["params"]
    state = optimizer.state.get(param)
    direct = torch.__version__.split("+")[0] == DIRECT_ADAM_TORCH
    if not direct or not group["fused"] or not state or group["amsgrad"] or group["maximize"]:
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


class _Buffers:
    """Buffers of one batch size: a workspace per network (each holds its own input buffer)."""

    def __init__(
        self,
        actor: Actor,
        critics: Sequence[Critic],
        actor_target: Actor,
        critics_target: Sequence[Critic],
        batch: int,
    ) -> None:
        self.actor = MLPWorkspace(actor.net, batch)
        self.critics = [MLPWorkspace(c.net, batch) for c in critics]
        self.actor_target = MLPWorkspace(actor_target.net, batch, with_grads=False)
        self.critics_target = [MLPWorkspace(c.net, batch, with_grads=False) for c in critics_target]
        # d(-mean q)/dq, the actor loss's gradient at the critic's output
        device = self.actor.blocks[0].device
        self.minus_mean = torch.full((batch, 1), -1.0 / batch, device=device)


class WorkspaceUpdate:
    """The DDPG / TD3 update of `curious.agent.learner` (its losses, gradients and order of steps),
    written out through `MLPWorkspace` buffers (one set per batch size).

    It is given the networks it reads and steps, their optimisers, the settings of the update
    and the generator of TD3's target noise; besides its buffers it keeps no state. The networks'
    parameters must be laid out by `fold_parameters`. Which steps run is the caller's: `update`
    steps the actor only when told to (TD3's delay), and keeps no count.
    """

    def __init__(
        self,
        *,
        actor: Actor,
        critics: Sequence[Critic],
        actor_target: Actor,
        critics_target: Sequence[Critic],
        actor_opt: torch.optim.Adam,
        critic_opt: torch.optim.Adam,
        config: Config,
        generator: torch.Generator,
    ) -> None:
        self.actor, self.critics = actor, list(critics)
        self.actor_target, self.critics_target = actor_target, list(critics_target)
        self.actor_opt, self.critic_opt = actor_opt, critic_opt
        self.config = config
        self.generator = generator
        self.td3 = config.algorithm == "td3"
        self.clip_return = 1.0 / (1.0 - config.gamma)
        self.input_dim = actor.net[0].in_features
        self.device = actor.net[0].weight.device
        self._by_batch: dict[int, _Buffers] = {}

    def _buffers(self, batch: int) -> _Buffers:
        if batch not in self._by_batch:
            nets = (self.actor, self.critics, self.actor_target, self.critics_target)
            self._by_batch[batch] = _Buffers(*nets, batch)
        return self._by_batch[batch]

    @torch.no_grad()
    def td_target(self, reward: torch.Tensor, x_next: torch.Tensor) -> torch.Tensor:
        """r + gamma * Q'(x', pi'(x')), clipped to [-1/(1-gamma), 0]; TD3 smooths the target
        action and takes the smaller of its two target critics."""
        cfg = self.config
        ws = self._buffers(x_next.shape[0])
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
        self,
        x: torch.Tensor,
        action: torch.Tensor,
        reward: torch.Tensor,
        x_next: torch.Tensor,
        step_actor: bool,
    ) -> tuple[torch.Tensor, torch.Tensor | None, torch.Tensor]:
        """One step on a minibatch: (critic loss, actor loss or None where the actor was not
        stepped, mean TD target), detached.

        DDPG (the critics stepped after the actor's gradient) and TD3 (the critics stepped
        first) as the reference, `curious.agent.learner.Learner.update`.
        """
        cfg = self.config
        batch, d = x.shape[0], self.input_dim
        ws = self._buffers(batch)
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

        actor_loss = None
        if step_actor:
            pi = ws.actor.forward(x).tanh_()
            inputs[:, d:].copy_(pi)
            q_pi = ws.critics[0].forward(inputs)
            pi_sq = pi.square()
            actor_loss = cfg.action_l2 * pi_sq.mean() - q_pi.mean()
            grad_pi = ws.critics[0].backward(
                ws.minus_mean, weight_grads=False, input_grad=True, input_columns=slice(d, None)
            )
            grad_pi.add_(pi, alpha=2.0 * cfg.action_l2 / pi.numel())
            grad_pi.mul_(pi_sq.neg_().add_(1.0))  # through tanh: d tanh(z)/dz = 1 - tanh^2
            ws.actor.backward(grad_pi)
            _adam_step(self.actor_opt)
        if not self.td3:
            _adam_step(self.critic_opt)
        return critic_loss, actor_loss, target.mean()
