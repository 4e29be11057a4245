"""Several learners' DDPG / TD3 steps computed as one: their networks stacked over a run axis.

A population (`curious.runs.population`) trains runs whose learners have networks of one shape
each; their updates are the same computation on other numbers. `stacked_step` takes k such
learners and a minibatch for each, and runs the step `curious.agent.learner.Learner.update`
would run for each, for all k at once: each network's k flat tensors (`flatten_parameters`)
are gathered into one (k, P) tensor, every Linear layer becomes a weight (k, out, in) and a bias
(k, out) viewed in it, autograd takes the gradients of the k losses' sum into a (k, P) gradient
tensor (run r's gradient is that of its own loss: the runs share no weight), and one Adam call
steps the k learners' own flat parameters with their own optimiser states (`adam_steps`).

What each run computes is the learner's own statement (`td_target`, `critic_loss`,
`actor_loss`, the order of DDPG's and TD3's steps), written with a leading run axis; TD3's target
noise comes from each learner's generator, as alone. Off the CPU each layer is one batched
product for all runs (`torch.baddbmm`), whose kernels may sum in another order than a run's
alone: float rounding (a test holds it to a tolerance). On a CPU a batched product is no faster
than k products (they are compute-bound), so there each run's products are its own, the `addmm`
that `nn.Linear` calls on the same shapes and strides: each run then gets, bit for bit, what its
learner's reference backend (`autograd`) computes alone (tests/test_stacked_update.py), which
checks the stacked computation to the bit. A learner whose backend is `workspace` or `compiled`
gets the reference's arithmetic, which its own backend matches to float rounding.

The layers are products on views of the gathered tensor rather than `torch.func.vmap` over
`functional_call`: the same batched kernels, without building parameter dictionaries every step
or the transforms' dispatch around every operation, and the gradients land where Adam reads
them. The parameters are gathered copies rather than the learners' storage: which learners step
together changes from call to call (runs enter and leave their updates, MG-TE's trained expert
changes every epoch), and a learner whose weights were views of a shared stack would write every
run's weights into its checkpoint (`torch.save` keeps a view's whole storage). A gather is one
copy per network per step, a few hundred kilobytes per run at the authors' sizes.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Callable, Hashable, Iterator, Sequence
from typing import TYPE_CHECKING

import torch
from torch import nn
from torch.optim.adam import adam

from curious.agent.update_backends import StepLosses

if TYPE_CHECKING:
    from curious.agent.learner import Learner

Place = tuple[int, tuple[int, ...], tuple[int, ...]]
"""Where a parameter lies in its network's flat tensor: offset, shape, strides."""
LayerPlaces = tuple[tuple[Place, Place], ...]
"""(weight, bias) places of an MLP's Linear layers, in order."""
Minibatch = tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]
"""(x, action, reward, x_next) of one learner's step."""


def _place(param: torch.Tensor, flat: torch.Tensor) -> Place:
    """`param`'s place in `flat`, of which it must be a view."""
    same = param.untyped_storage().data_ptr() == flat.untyped_storage().data_ptr()
    if not same or param.dtype != flat.dtype:
        raise ValueError("a parameter that is not a view of its network's flat tensor")
    offset = param.storage_offset() - flat.storage_offset()
    return offset, tuple(param.shape), tuple(param.stride())


def _mlp_places(mlp: nn.Sequential, flat: torch.Tensor) -> LayerPlaces:
    """The places of an MLP's (Linear, ReLU, ..., Linear) layers in its flat tensor."""
    linears = [m for m in mlp if isinstance(m, nn.Linear)]
    if len(mlp) != 2 * len(linears) - 1 or any(lin.bias is None for lin in linears):
        raise ValueError("a stacked network must be Linear, ReLU, ..., Linear, with biases")
    return tuple((_place(lin.weight, flat), _place(lin.bias, flat)) for lin in linears)


def _places(learner: Learner) -> tuple[tuple[LayerPlaces, ...], ...]:
    """Per network (actor, critics, their targets): the places of each MLP's layers."""
    actor_flat, critics_flat = learner.backend.online
    actor_target_flat, critics_target_flat = learner.backend.targets
    return (
        (_mlp_places(learner.actor.net, actor_flat),),
        tuple(_mlp_places(c.net, critics_flat) for c in learner.critics),
        (_mlp_places(learner.actor_target.net, actor_target_flat),),
        tuple(_mlp_places(c.net, critics_target_flat) for c in learner.critics_target),
    )


def stack_key(learner: Learner) -> Hashable:
    """What learners must share to step together: the networks' layout (shapes and places in
    their flat tensors), device and dtype, the algorithm and the settings its step reads."""
    cfg = learner.config
    flat = learner.backend.online[0]
    td3 = (cfg.td3_target_noise, cfg.td3_noise_clip) if learner.td3 else None
    sizes = tuple(f.numel() for f in (*learner.backend.online, *learner.backend.targets))
    return (_places(learner), sizes, flat.device, flat.dtype, td3, cfg.gamma, cfg.action_l2)


class _Stacked:
    """One network of k learners gathered into a (k, P) tensor, each Linear layer of each of its
    MLPs a weight (k, out, in) and a bias (k, out) viewed in it, or, with `per_run`, k weights
    (out, in) and k biases (out,), each run's own. With `grads`, the views are leaves whose
    gradients accumulate into a (k, P) tensor of the same layout (`grad`)."""

    def __init__(
        self,
        flats: Sequence[torch.Tensor],
        mlps: tuple[LayerPlaces, ...],
        grads: bool,
        per_run: bool,
    ) -> None:
        self.flat = torch.stack([f.detach() for f in flats])
        self.grad = torch.zeros_like(self.flat) if grads else None
        self.per_run = per_run
        self.mlps = [[(self._view(w), self._view(b)) for w, b in m] for m in mlps]

    def _view(self, place: Place) -> torch.Tensor | list[torch.Tensor]:
        offset, shape, stride = place
        k, size = self.flat.shape

        def leaf(at: Callable[[torch.Tensor], torch.Tensor]) -> torch.Tensor:
            if self.grad is None:
                return at(self.flat)
            view = at(self.flat).detach().requires_grad_()
            view.grad = at(self.grad)
            return view

        if self.per_run:
            return [
                leaf(lambda t, r=r: t.as_strided(shape, stride, r * size + offset))
                for r in range(k)
            ]
        return leaf(lambda t: t.as_strided((k, *shape), (size, *stride), offset))

    def forward(self, mlp: int, h: torch.Tensor, fixed: bool = False) -> torch.Tensor:
        """MLP `mlp` (Linear, ReLU, ..., Linear) on h (k, B, in): per run, what `nn.Linear`
        and `nn.ReLU` compute. `fixed`: through the weights held fixed (no gradient to them)."""
        layers = self.mlps[mlp]
        for i, (w, b) in enumerate(layers):
            h = _linear(h, w, b, fixed)
            if i < len(layers) - 1:
                h = torch.relu(h)
        return h

    def actor(self, x: torch.Tensor) -> torch.Tensor:
        """pi(x) (k, B, A), as `curious.agent.networks.Actor`."""
        return torch.tanh(self.forward(0, x))

    def critic(
        self, i: int, x: torch.Tensor, action: torch.Tensor, fixed: bool = False
    ) -> torch.Tensor:
        """Q_i(x, a) (k, B), as `curious.agent.networks.Critic`."""
        return self.forward(i, torch.cat([x, action], dim=-1), fixed).squeeze(-1)


def _linear(
    h: torch.Tensor,
    w: torch.Tensor | list[torch.Tensor],
    b: torch.Tensor | list[torch.Tensor],
    fixed: bool,
) -> torch.Tensor:
    """h W^T + b for each run: one batched product, or one `addmm` per run (what
    `nn.Linear` calls, on the same shapes and strides: the same kernels, and through autograd's
    `addmm` backward the same gradient kernels, as the run alone)."""
    if isinstance(w, list) and isinstance(b, list):
        if fixed:
            w, b = [t.detach() for t in w], [t.detach() for t in b]
        runs = zip(h.unbind(0), w, b, strict=True)
        return torch.stack([torch.addmm(bias, x, weight.t()) for x, weight, bias in runs])
    assert isinstance(w, torch.Tensor) and isinstance(b, torch.Tensor)
    if fixed:
        w, b = w.detach(), b.detach()
    return torch.baddbmm(b.unsqueeze(1), h, w.transpose(1, 2))


class _Runs:
    """The learners that step together, and how their products run."""

    def __init__(
        self,
        learners: Sequence[Learner],
        per_run: bool,
        places: tuple[tuple[LayerPlaces, ...], ...] | None = None,
    ) -> None:
        self.learners = list(learners)
        self.first = learners[0]
        self.per_run = per_run
        self.places = places if places is not None else _places(self.first)  # alike: one layout

    def subset(self, rows: Sequence[int]) -> _Runs:
        return _Runs([self.learners[r] for r in rows], self.per_run, self.places)

    def gather(self, online: bool, i: int, grads: bool) -> _Stacked:
        """Network i (0 the actor, 1 the critics), online or target, of every learner."""
        flats = [(lr.backend.online if online else lr.backend.targets)[i] for lr in self.learners]
        mlps = self.places[i + (0 if online else 2)]
        return _Stacked(flats, mlps, grads, self.per_run)


def adam_steps(optimizers: Sequence[torch.optim.Adam], grads: Sequence[torch.Tensor]) -> None:
    """One Adam step of each optimizer (one parameter each) with the gradient given for it, in
    one call of torch's Adam function for all optimizers of like settings: what each
    `optimizer.step()` would do with that gradient in its parameter's `.grad`. An optimizer
    without state yet (its first step) takes its own `step()`, which creates the state."""
    groups: dict[tuple, list[tuple[torch.optim.Adam, torch.Tensor]]] = {}
    for optimizer, grad in zip(optimizers, grads, strict=True):
        (group,) = optimizer.param_groups
        (param,) = group["params"]
        if not optimizer.state.get(param) or group["amsgrad"]:
            param.grad.copy_(grad)
            optimizer.step()
            continue
        settings = tuple(sorted((k, v) for k, v in group.items() if k != "params"))
        groups.setdefault(settings, []).append((optimizer, grad))
    for members in groups.values():
        group = members[0][0].param_groups[0]
        params = [opt.param_groups[0]["params"][0] for opt, _ in members]
        states = [opt.state[p] for (opt, _), p in zip(members, params, strict=True)]
        beta1, beta2 = group["betas"]
        adam(
            params,
            [grad for _, grad in members],
            [s["exp_avg"] for s in states],
            [s["exp_avg_sq"] for s in states],
            [],
            [s["step"] for s in states],
            amsgrad=False,
            beta1=beta1,
            beta2=beta2,
            lr=group["lr"],
            weight_decay=group["weight_decay"],
            eps=group["eps"],
            maximize=group["maximize"],
            foreach=group["foreach"],
            capturable=group["capturable"],
            differentiable=group["differentiable"],
            fused=group["fused"],
            decoupled_weight_decay=group.get("decoupled_weight_decay", False),
        )


@contextlib.contextmanager
def _relaxed_grad_layout() -> Iterator[None]:
    """Autograd's gradient layout contract relaxed (`torch.autograd.enforce_grad_layout_policy`,
    torch >= 2.13); with an earlier torch, the same gradients with the contract's warning
    silenced."""
    relax = getattr(torch.autograd, "enforce_grad_layout_policy", None)
    if relax is not None:
        with relax(False):
            yield
        return
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*gradient layout contract")
        yield


def _backward(losses: torch.Tensor) -> None:
    """The gradients of the k losses' sum, accumulated in place into the stacks' gradient
    tensors. Their views are not dense (a run's row is P apart from the next), which autograd's
    layout contract would warn about: it is the layout the gradients are wanted in."""
    with _relaxed_grad_layout():
        losses.sum().backward()


@torch.no_grad()
def _td_target(runs: _Runs, reward: torch.Tensor, x_next: torch.Tensor) -> torch.Tensor:
    """`Learner.td_target` of each learner (k, B), TD3's noise from each one's generator."""
    first, cfg = runs.first, runs.first.config
    actor_target = runs.gather(online=False, i=0, grads=False)
    critics_target = runs.gather(online=False, i=1, grads=False)
    next_action = actor_target.actor(x_next)
    if first.td3:
        noise = torch.stack([lr.target_noise(x_next.shape[1]) for lr in runs.learners])
        noise = (noise * cfg.td3_target_noise).clamp(-cfg.td3_noise_clip, cfg.td3_noise_clip)
        next_action = (next_action + noise).clamp(-1.0, 1.0)
    q_next = critics_target.critic(0, x_next, next_action)
    if first.td3:
        q_next = torch.minimum(q_next, critics_target.critic(1, x_next, next_action))
    return (reward + cfg.gamma * q_next).clamp(-first.clip_return, 0.0)


def _critic_loss(
    critics: _Stacked, x: torch.Tensor, action: torch.Tensor, target: torch.Tensor
) -> torch.Tensor:
    """`Learner.critic_loss` of each learner (k,)."""
    n = len(critics.mlps)
    return sum((critics.critic(i, x, action) - target).square().mean(1) for i in range(n))


def _actor_loss(actor: _Stacked, critics: _Stacked, x: torch.Tensor, l2: float) -> torch.Tensor:
    """`Learner.actor_loss` of each learner (k,), through the critics held fixed."""
    pi = actor.actor(x)
    q_pi = critics.critic(0, x, pi, fixed=True)
    return -q_pi.mean(1) + l2 * pi.square().mean((1, 2))


def stacked_step(
    learners: Sequence[Learner],
    minibatches: Sequence[Minibatch],
    step_actor: Sequence[bool],
    batched_products: bool | None = None,
) -> list[StepLosses]:
    """For each learner, the step its backend takes in `Learner.update` on its minibatch
    (DDPG's, or TD3's critic step and, where `step_actor`, its actor step), all at once; each
    learner's (critic loss, actor loss or None, mean TD target), detached. The learners must
    share a `stack_key` and their minibatches one size.

    `batched_products`: each layer's products as one batched product for all runs (the default
    off the CPU), or one per run (the default on the CPU, where a batched product is no faster
    and the per-run products give each run its bits alone)."""
    first = learners[0]
    if batched_products is None:
        batched_products = first.backend.online[0].device.type != "cpu"
    runs = _Runs(learners, per_run=not batched_products)
    x, action, reward, x_next = (torch.stack(t) for t in zip(*minibatches, strict=True))
    target = _td_target(runs, reward, x_next)
    critics = runs.gather(online=True, i=1, grads=True)
    critic_loss = _critic_loss(critics, x, action, target)
    l2 = first.config.action_l2
    if not first.td3:  # both losses from the current networks, then both steps
        actor = runs.gather(online=True, i=0, grads=True)
        actor_loss = _actor_loss(actor, critics, x, l2)
        _backward(critic_loss + actor_loss)
        adam_steps([lr.critic_opt for lr in learners], _rows(critics))
        adam_steps([lr.actor_opt for lr in learners], _rows(actor))
        return _losses(critic_loss, actor_loss, target, [True] * len(learners))
    _backward(critic_loss)  # TD3: the critics first, the actor through the stepped ones
    adam_steps([lr.critic_opt for lr in learners], _rows(critics))
    rows = [r for r, step in enumerate(step_actor) if step]
    actor_loss = None
    if rows:
        stepping = runs.subset(rows)
        actor = stepping.gather(online=True, i=0, grads=True)
        stepped = stepping.gather(online=True, i=1, grads=False)
        actor_loss = _actor_loss(actor, stepped, x[rows] if len(rows) < len(x) else x, l2)
        _backward(actor_loss)
        adam_steps([lr.actor_opt for lr in stepping.learners], _rows(actor))
    return _losses(critic_loss, actor_loss, target, step_actor)


def _rows(stacked: _Stacked) -> list[torch.Tensor]:
    """Each run's gradient (P,) of a stacked network."""
    assert stacked.grad is not None
    return list(stacked.grad.unbind(0))


def _losses(
    critic_loss: torch.Tensor,
    actor_loss: torch.Tensor | None,
    target: torch.Tensor,
    step_actor: Sequence[bool],
) -> list[StepLosses]:
    """Each learner's detached losses; `actor_loss` holds rows of the actors stepped only."""
    critic_loss, q_target = critic_loss.detach(), target.mean(1)
    actor_rows = iter(actor_loss.detach() if actor_loss is not None else ())
    return [
        (critic_loss[r], next(actor_rows) if step else None, q_target[r])
        for r, step in enumerate(step_actor)
    ]
