"""Several learners' updates computed as one stacked step (`curious.agent.stacked_update`)."""

import dataclasses
import warnings

import pytest
import torch

from curious.agent.learner import Learner
from curious.agent.stacked_update import adam_steps, stack_key, stacked_step
from curious.agent.update_backends import adam
from curious.config import resolve

torch.set_num_threads(1)
CUDA = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
D, A = 10, 4
UPDATES = 50
"""Updates compared in each test (the targets follow every 5th)."""


def config(**changes):
    base = dict(hidden=64, layers=2, batch_per_worker=64, td3_policy_delay=2)
    return dataclasses.replace(resolve("smoke"), **{**base, **changes})


def minibatch(seed, n=128, device="cpu"):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, D, generator=g)
    action = torch.rand(n, A, generator=g) * 2 - 1
    reward = -(torch.rand(n, generator=g) < 0.7).float()
    return tuple(t.to(device) for t in (x, action, reward, torch.randn(n, D, generator=g)))


def stacked_update(learners, minibatches, batched_products=None):
    """What `Learner.update` does around its backend's step, for learners stepped together."""
    step_actor = []
    for learner in learners:
        learner.n_updates += 1
        step_actor.append(
            not learner.td3 or learner.n_updates % learner.config.td3_policy_delay == 0
        )
    return stacked_step(learners, minibatches, step_actor, batched_products)


def adam_state(learner):
    for opt in (learner.actor_opt, learner.critic_opt):
        (param,) = opt.param_groups[0]["params"]
        yield from (opt.state[param][k] for k in ("exp_avg", "exp_avg_sq", "step"))


def train_both(algorithm, compare, batched_products=None, device="cpu"):
    """Three learners updated one by one and three copies updated as one stack, on the same
    minibatches, their networks on `device`; `compare(want, got)` on every loss, then on every
    network, Adam moment and step count. The third learner took one update more first (alone),
    so that TD3's delay steps its actor at other updates than the others'."""
    cfg = config(algorithm=algorithm, device=device)
    alone = [Learner(D, A, cfg, seed=s) for s in range(3)]
    stacked = [Learner(D, A, cfg, seed=s) for s in range(3)]
    for learner in (alone[2], stacked[2]):
        learner.update(*minibatch(99, device=device))
    for step in range(UPDATES):
        minibatches = [minibatch(10 * step + r, device=device) for r in range(3)]
        wants = [learner.update(*mb) for learner, mb in zip(alone, minibatches, strict=True)]
        gots = stacked_update(stacked, minibatches, batched_products)
        for want, got in zip(wants, gots, strict=True):
            critic_loss, actor_loss, q_target = got
            compare(want["critic_loss"], critic_loss)
            compare(want["q_target_mean"], q_target)
            if actor_loss is not None:
                compare(want["actor_loss"], actor_loss)
        if step % 5 == 4:
            for learner in (*alone, *stacked):
                learner.update_targets()
    for one, other in zip(alone, stacked, strict=True):
        assert one.n_updates == other.n_updates
        assert torch.equal(one.generator.get_state(), other.generator.get_state())
        backends = one.backend, other.backend
        for want, got in zip(*(b.online + b.targets for b in backends), strict=True):
            compare(want, got)
        for want, got in zip(adam_state(one), adam_state(other), strict=True):
            compare(want, got)


@pytest.mark.parametrize("algorithm", ["ddpg", "td3"])
def test_stacked_steps_are_each_learners_steps_alone(algorithm):
    """On a CPU each run's products are its own (`addmm`, as `nn.Linear` calls them): over 50
    updates the stacked learners' losses, weights, targets, Adam moments and step counts, and
    TD3's generators, are those of each learner updated alone, bit for bit."""
    train_both(algorithm, lambda want, got: torch.testing.assert_close(got, want, rtol=0, atol=0))


@pytest.mark.parametrize("algorithm", ["ddpg", "td3"])
def test_batched_products_follow_the_learners_alone(algorithm):
    """With one batched product per layer for all runs (`torch.baddbmm`, the default off the
    CPU), the kernels may sum in another order. Measured over these 50 updates: 2.3e-7 of
    relative difference in the losses at most, 2.4e-7 in any weight, target or Adam moment;
    held to 1e-5 relative and 1e-4 absolute. The differences grow with the networks and the
    updates (at the `laptop` sizes, 3 x 256 and batch 512: 5e-5 in a weight after one update,
    4e-3 after 50, where Adam turns near-zero gradients' rounding into steps of the full
    learning rate), so the comparison stays at these sizes."""

    def close(want, got):
        torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-4)

    train_both(algorithm, close, batched_products=True)


def test_adam_steps_are_each_optimizers_step():
    """One call for optimizers of like settings (a first step creates the state through
    `step()`; another learning rate makes a group of its own) gives each optimizer's `step()`."""
    torch.manual_seed(0)
    lrs = (1e-3, 1e-3, 5e-4)
    ours = [torch.nn.Parameter(torch.randn(100)) for _ in lrs]
    theirs = [torch.nn.Parameter(p.detach().clone()) for p in ours]
    for p in (*ours, *theirs):
        p.grad = torch.zeros_like(p)
    our_opts = [adam([p], lr) for p, lr in zip(ours, lrs, strict=True)]
    their_opts = [adam([p], lr) for p, lr in zip(theirs, lrs, strict=True)]
    for _ in range(4):
        grads = [torch.randn(100) for _ in lrs]
        adam_steps(our_opts, grads)
        for p, opt, grad in zip(theirs, their_opts, grads, strict=True):
            p.grad.copy_(grad)
            opt.step()
    for p, q, mine, reference in zip(ours, theirs, our_opts, their_opts, strict=True):
        assert torch.equal(p, q)
        assert torch.equal(mine.state[p]["exp_avg_sq"], reference.state[q]["exp_avg_sq"])
        assert float(mine.state[p]["step"]) == float(reference.state[q]["step"]) == 4.0


def test_only_learners_of_one_shape_and_update_stack():
    """Learners stack when their networks' layout and what their step reads agree: another
    input size, algorithm, layout of the flat parameters (`workspace` folds each layer into one
    [W | b] block) or discount makes another key."""
    key = stack_key(Learner(D, A, config(), seed=0))
    assert stack_key(Learner(D, A, config(), seed=1)) == key
    assert stack_key(Learner(D, A, config(action_l2=1.0), seed=1)) == key
    for other in (
        Learner(D + 1, A, config(), seed=0),
        Learner(D, A, config(algorithm="td3"), seed=0),
        Learner(D, A, config(learner_backend="workspace"), seed=0),
        Learner(D, A, config(gamma=0.9), seed=0),
        Learner(D, A, config(hidden=32), seed=0),
    ):
        assert stack_key(other) != key


def test_workspace_learners_stack_with_the_reference_arithmetic():
    """Learners whose backend is the written-out `workspace` stack too (their parameters laid
    out in blocks): the stacked step takes the reference's arithmetic, which their own backend
    matches to float rounding."""
    cfg = config(learner_backend="workspace")
    alone = [Learner(D, A, cfg, seed=s) for s in range(2)]
    stacked = [Learner(D, A, cfg, seed=s) for s in range(2)]
    for step in range(5):
        minibatches = [minibatch(10 * step + r) for r in range(2)]
        wants = [lr.update(*mb) for lr, mb in zip(alone, minibatches, strict=True)]
        gots = stacked_update(stacked, minibatches)
        for want, (critic_loss, _, _) in zip(wants, gots, strict=True):
            torch.testing.assert_close(critic_loss, want["critic_loss"], rtol=1e-4, atol=1e-5)
    for one, other in zip(alone, stacked, strict=True):
        for p, q in zip(one.actor.parameters(), other.actor.parameters(), strict=True):
            torch.testing.assert_close(q, p, rtol=1e-4, atol=1e-4)


@CUDA
@pytest.mark.parametrize("algorithm", ["ddpg", "td3"])
def test_on_cuda_the_stacked_steps_follow_the_learners_alone(algorithm):
    """On a GPU, where a population's stacked updates run by default, one batched product per
    layer for all runs follows each learner updated alone on the same device to float rounding,
    held to the CPU's tolerance (`test_batched_products_follow_the_learners_alone`)."""

    def close(want, got):
        torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-4)

    train_both(algorithm, close, device="cuda")


def test_with_a_torch_before_the_layout_policy_the_steps_follow_and_are_quiet(monkeypatch):
    """torch < 2.13 has no `torch.autograd.enforce_grad_layout_policy` (the GPU nodes' images
    carry 2.11): the batched products' gradients, views of the stacks (not dense), still follow
    each learner alone, without autograd's layout warning."""
    monkeypatch.delattr(torch.autograd, "enforce_grad_layout_policy", raising=False)

    def close(want, got):
        torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-4)

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        train_both("td3", close, batched_products=True)
