"""Networks, normalisers, the E-UVFA input and the DDPG / TD3 update."""

import copy
import dataclasses
import logging

import numpy as np
import pytest
import torch
from fresh_process import run_fresh
from toy_env import ToyGoalEnv

from curious.agent.goals import GoalBox, GoalInput
from curious.agent.inputs import InputEncoder
from curious.agent.learner import Learner
from curious.agent.networks import Actor, Critic
from curious.agent.normalizer import RunningNormalizer
from curious.presets import resolve

torch.set_num_threads(1)


def small_config(**changes):
    return dataclasses.replace(resolve("smoke"), hidden=32, layers=2, **changes)


def batch(n=64, d=10, a=4, seed=0):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, d, generator=g)
    action = torch.rand(n, a, generator=g) * 2 - 1
    reward = -(torch.rand(n, generator=g) < 0.7).float()
    x_next = torch.randn(n, d, generator=g)
    return x, action, reward, x_next


def test_networks_shapes_and_bounds():
    actor, critic = Actor(10, 4, 256, 3), Critic(10, 4, 256, 3)
    hidden = [m for m in actor.net if isinstance(m, torch.nn.Linear)]
    assert [layer.out_features for layer in hidden] == [256, 256, 256, 4]
    x = torch.randn(5, 10) * 100
    a = actor(x)
    assert a.shape == (5, 4) and a.abs().max() <= 1
    assert critic(x, a).shape == (5,)


def test_normaliser_matches_numpy_and_clips():
    rng = np.random.default_rng(0)
    data = rng.normal(3.0, 2.0, (1000, 4))
    data[:, 3] = 7.0  # constant feature: std floored at eps
    norm = RunningNormalizer((4,), eps=0.01, clip=5.0)
    norm.update(data[:600])
    norm.update(data[600:])
    np.testing.assert_allclose(norm.mean, data.mean(0), rtol=1e-5)
    np.testing.assert_allclose(norm.std[:3], data[:, :3].std(0), rtol=1e-4)
    assert norm.std[3] == pytest.approx(0.01)
    out = norm.normalize(np.array([[3.0, 3.0, 3.0, 100.0]]))
    assert out[0, 3] == 5.0  # clipped
    torch_out = norm.normalize(torch.tensor([[3.0, 3.0, 3.0, 100.0]]))
    np.testing.assert_allclose(torch_out.numpy(), out, rtol=1e-5)


def test_inactive_goal_slots_get_no_gradient():
    spec = ToyGoalEnv.spec
    encoder = InputEncoder(spec, GoalBox.of(ToyGoalEnv()))
    rng = np.random.default_rng(0)
    encoder.update_stats(rng.normal(size=(4, 11, 7)))
    n = 32
    goals = torch.tensor(rng.normal(size=(n, 3, 3)), dtype=torch.float32)
    task = torch.zeros(n, 3)
    task[:, 1] = 1.0  # every transition practises module 1
    x = encoder.encode(torch.randn(n, 7), GoalInput(goals, task, task))
    assert x.shape == (n, encoder.input_dim)
    slot = lambda m: slice(7 + 3 * m, 7 + 3 * m + 3)  # noqa: E731
    assert torch.all(x[:, slot(0)] == 0) and torch.all(x[:, slot(2)] == 0)
    assert torch.all(x[:, slot(1)] != 0)
    learner = Learner(encoder.input_dim, 4, small_config())
    first = learner.critics[0].net[0].weight.detach().clone()
    learner.update(x, torch.zeros(n, 4), -torch.ones(n), x)
    after = learner.critics[0].net[0].weight.detach()
    assert torch.equal(after[:, slot(0)], first[:, slot(0)])
    assert torch.equal(after[:, slot(2)], first[:, slot(2)])
    assert not torch.equal(after[:, slot(1)], first[:, slot(1)])


def test_targets_are_clipped_to_the_return_range():
    learner = Learner(10, 4, small_config())
    _x, _, reward, x_next = batch()
    last = learner.critics_target[0].net[-1]
    with torch.no_grad():
        last.bias.fill_(1e3)
        assert torch.all(learner.td_target(reward, x_next) == 0)
        last.bias.fill_(-1e3)
        assert torch.allclose(learner.td_target(reward, x_next), torch.full((64,), -50.0))


def test_polyak_update_of_targets_once_per_call():
    learner = Learner(10, 4, small_config())
    x, a, r, x2 = batch()
    for _ in range(3):
        learner.update(x, a, r, x2)
    before_t = [p.detach().clone() for p in learner.actor_target.parameters()]
    online = [p.detach().clone() for p in learner.actor.parameters()]
    assert any(not torch.equal(t, o) for t, o in zip(before_t, online, strict=True))
    learner.update_targets()
    for t0, o, t1 in zip(before_t, online, learner.actor_target.parameters(), strict=True):
        torch.testing.assert_close(t1, 0.95 * t0 + 0.05 * o)


def test_critic_learns_a_constant_return():
    learner = Learner(10, 4, small_config())
    x, a, _, x2 = batch(n=128)
    reward = -torch.ones(128)
    losses = []
    for i in range(300):
        losses.append(float(learner.update(x, a, reward, x2)["critic_loss"]))
        if i % 10 == 9:
            learner.update_targets()
    assert np.mean(losses[-20:]) < 0.2 * np.mean(losses[:20])


def test_action_penalty_pulls_actions_to_zero_when_q_is_flat():
    learner = Learner(10, 4, small_config(actor_lr=1e-2))
    with torch.no_grad():  # a critic that ignores the action: only the L2 term moves the actor
        for p in learner.critics.parameters():
            p.zero_()
        learner.actor.net[-1].bias.fill_(1.0)
    x, a, _r, x2 = batch()
    start = learner.act(x).abs().mean()
    for _ in range(50):
        learner.update(x, a, torch.zeros(64), x2)
    assert learner.act(x).abs().mean() < 0.3 * start


def test_td3_has_twin_critics_and_delays_the_actor():
    learner = Learner(10, 4, small_config(algorithm="td3", td3_policy_delay=2))
    assert len(learner.critics) == 2
    x, a, r, x2 = batch()
    actor0 = [p.detach().clone() for p in learner.actor.parameters()]
    learner.update(x, a, r, x2)
    assert all(torch.equal(p, q) for p, q in zip(actor0, learner.actor.parameters(), strict=True))
    learner.update(x, a, r, x2)
    assert not all(
        torch.equal(p, q) for p, q in zip(actor0, learner.actor.parameters(), strict=True)
    )


def test_td3_target_is_the_smaller_target_critic_on_the_clipped_smoothed_action():
    """TD3's target (Fujimoto et al. 2018): r + gamma * min(Q1', Q2') on the target action
    smoothed by noise scaled by `td3_target_noise`, clipped to +-`td3_noise_clip`, the action
    then clamped to [-1, 1]. Non-default settings, so that no hard-coded constant passes; the
    critics differ row by row, so that neither critic alone (nor the larger) passes."""
    config = small_config(algorithm="td3", gamma=0.9, td3_target_noise=0.1, td3_noise_clip=0.3)
    learner = Learner(10, 4, config, seed=2)
    _x, _a, reward, x_next = batch(seed=4)
    with torch.no_grad():  # returns well inside [-1/(1-gamma), 0]: the return's clip is idle
        for critic in learner.critics_target:
            critic.net[-1].bias.fill_(-3.0)
        learner.critics_target[1].net[-1].bias.add_(0.05)
        learner.actor_target.net[-1].bias.copy_(torch.tensor([4.0, -4.0, 0.0, 0.0]))
        learner.actor_target.net[-1].weight[2:].mul_(0.2)  # actions 2 and 3 near 0
        pi = learner.actor_target(x_next)
    # raw standard normal draws: scaled by 0.1, +-5 is clipped to +-0.3, 1.0 becomes 0.1
    noise = torch.tensor([50.0, -50.0, 50.0, 1.0]).expand(len(x_next), 4)
    assert torch.all(pi[:, 0] + 0.3 > 1) and torch.all(pi[:, 1] - 0.3 < -1)  # clamped
    assert torch.all(pi[:, 2].abs() < 0.5)  # only the noise's clip bounds it
    smoothed = torch.stack([pi.new_ones(64), -pi.new_ones(64), pi[:, 2] + 0.3, pi[:, 3] + 0.1], 1)
    seen = []
    for critic in learner.critics_target:
        critic.register_forward_hook(lambda _m, args, _out: seen.append(args[1].clone()))
    target = learner.td_target(reward, x_next, noise)
    assert len(seen) == 2
    for action in seen:  # both target critics judge the one smoothed action
        torch.testing.assert_close(action, smoothed)

    with torch.no_grad():
        q1, q2 = (critic(x_next, smoothed) for critic in learner.critics_target)
    assert torch.any(q1 < q2) and torch.any(q2 < q1)  # each critic is the smaller on some rows
    want = reward + 0.9 * torch.minimum(q1, q2)
    assert torch.all(want > -10) and torch.all(want < 0)
    torch.testing.assert_close(target, want)


def test_state_dict_round_trip_gives_identical_updates():
    a = Learner(10, 4, small_config(algorithm="td3"), seed=1)
    x, act, r, x2 = batch()
    for _ in range(5):
        a.update(x, act, r, x2)
    b = Learner(10, 4, small_config(algorithm="td3"), seed=99)
    b.load_state_dict(a.state_dict())
    for _ in range(4):
        la, lb = a.update(x, act, r, x2), b.update(x, act, r, x2)
        assert torch.equal(la["critic_loss"], lb["critic_loss"])
    for p, q in zip(a.actor.parameters(), b.actor.parameters(), strict=True):
        assert torch.equal(p, q)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_cuda_update_matches_cpu_closely():
    cpu = Learner(10, 4, small_config(), seed=3)
    gpu = Learner(10, 4, small_config(device="cuda"), seed=3)
    x, a, r, x2 = batch()
    for _ in range(3):
        lc = cpu.update(x, a, r, x2)
        lg = gpu.update(x.cuda(), a.cuda(), r.cuda(), x2.cuda())
    assert float(lc["critic_loss"]) == pytest.approx(float(lg["critic_loss"]), rel=1e-3)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("algorithm", ["ddpg", "td3"])
def test_cuda_graphs_of_the_compiled_update_follow_the_reference(algorithm, caplog):
    """`compiled` on CUDA: each step captured as a CUDA graph with a capturable Adam (inductor
    says when it skips one, and why); the losses of every replay (copied out of the graph) and
    the weights follow the reference backend on the same device (TD3's target smoothing noise
    comes from the device's own generator, so a CPU reference would draw other noise)."""
    config = small_config(algorithm=algorithm, td3_policy_delay=2, device="cuda")
    reference = Learner(10, 4, config, seed=5)
    graphed = Learner(10, 4, dataclasses.replace(config, learner_backend="compiled"), seed=5)
    history = []
    with caplog.at_level(logging.WARNING):
        for step in range(6):
            x, a, r, x2 = batch(seed=step)
            x, a, r, x2 = (t.cuda() for t in (x, a, r, x2))
            history.append((reference.update(x, a, r, x2), graphed.update(x, a, r, x2)))
    skipped = [r.getMessage() for r in caplog.records if "skipping cudagraphs" in r.getMessage()]
    assert not skipped, skipped
    for want, got in history:  # earlier replays' losses were not overwritten
        for key in want:
            torch.testing.assert_close(got[key], want[key], rtol=1e-3, atol=1e-4)
    for p, q in zip(reference.actor.parameters(), graphed.actor.parameters(), strict=True):
        torch.testing.assert_close(q, p, rtol=1e-3, atol=1e-4)


@pytest.mark.parametrize("algorithm", ["ddpg", "td3"])
def test_update_gradients_are_those_of_the_losses(algorithm):
    """The reference update: critic gradients of sum mean (Q - y)^2, actor gradients of
    -mean Q1(x, pi(x)) + mean pi^2 through the critic held fixed (DDPG: the critic before its
    step, both from the same networks as the authors' code; TD3: the stepped critic)."""
    learner = Learner(10, 4, small_config(algorithm=algorithm, td3_policy_delay=1), seed=5)
    x, a, r, x2 = batch(seed=2)
    for _ in range(3):  # move away from the initial weights and targets first
        learner.update(x2, a, r, x)
        learner.update_targets()
    ref = copy.deepcopy(learner)
    learner.update(x, a, r, x2)

    with torch.no_grad():
        next_action = ref.actor_target(x2)
        if algorithm == "td3":
            noise = torch.randn(next_action.shape, generator=ref.generator) * 0.2
            next_action = (next_action + noise.clamp(-0.5, 0.5)).clamp(-1, 1)
        q_next = torch.stack([c(x2, next_action) for c in ref.critics_target]).min(0).values
        target = (r + 0.98 * q_next).clamp(-50, 0)
    loss = sum(torch.nn.functional.mse_loss(c(x, a), target) for c in ref.critics)
    grads = torch.autograd.grad(loss, list(ref.critics.parameters()))
    for g, p in zip(grads, learner.critics.parameters(), strict=True):
        torch.testing.assert_close(p.grad, g, rtol=1e-4, atol=1e-6)
    if algorithm == "td3":
        ref.critics.load_state_dict(learner.critics.state_dict())
    pi = ref.actor(x)
    loss = -ref.critics[0](x, pi).mean() + 1.0 * pi.pow(2).mean()
    grads = torch.autograd.grad(loss, list(ref.actor.parameters()))
    for g, p in zip(grads, learner.actor.parameters(), strict=True):
        torch.testing.assert_close(p.grad, g, rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("backend", ["workspace", "compiled"])
@pytest.mark.parametrize("algorithm", ["ddpg", "td3"])
def test_every_backend_gives_the_reference_update(backend, algorithm):
    config = small_config(algorithm=algorithm, td3_policy_delay=2)
    reference = Learner(10, 4, config, seed=5)
    other = Learner(10, 4, dataclasses.replace(config, learner_backend=backend), seed=5)
    torch._dynamo.utils.counters.clear()  # the graph breaks of the compiled learner's steps
    for step in range(5):
        x, a, r, x2 = batch(seed=step)
        want, got = reference.update(x, a, r, x2), other.update(x, a, r, x2)
        for key in want:
            torch.testing.assert_close(got[key], want[key], rtol=1e-4, atol=1e-5)
        if step % 2:
            reference.update_targets()
            other.update_targets()
    for net in ("actor", "critics", "actor_target", "critics_target"):
        mine, theirs = getattr(reference, net).parameters(), getattr(other, net).parameters()
        for p, q in zip(mine, theirs, strict=True):
            torch.testing.assert_close(q, p, rtol=1e-4, atol=1e-5)
    if backend == "compiled" and hasattr(torch._dynamo.config, "trace_autograd_ops"):
        # DDPG's backward() is in the graph of its losses, and TD3's target noise is drawn
        # outside its steps: they break only where the optimiser's step breaks around itself,
        # and TD3's at backward()
        breaks = list(torch._dynamo.utils.counters["graph_break"])
        allowed = ("torch._dynamo.graph_break()", "torch.compiler.disable()")
        allowed += ("Tensor.backward()",) if algorithm == "td3" else ()
        assert all(any(a in reason for a in allowed) for reason in breaks), breaks


def test_the_compiled_learner_beside_the_suite_prints_none_of_torchs_own_notices():
    """A compiled run's log is its own. Loading the suite once turned every DeprecationWarning
    on for the process (dm_control's composer does at import; `suite.dm_composer` keeps it
    from it), and torch's inductor then printed 14 about its own modules at the first step;
    dynamo also notes that Adam's profiler range stays out of the graph. Neither says anything a
    user can act on."""
    code = (
        "import dataclasses, torch, suite\n"
        "suite.load('default', seed=0).reset()\n"
        "from curious.agent.learner import Learner\n"
        "from curious.presets import resolve\n"
        "config = dataclasses.replace(resolve('smoke'), hidden=32, layers=2,"
        " learner_backend='compiled')\n"
        "learner = Learner(10, 4, config, seed=5)\n"
        "x, a = torch.randn(64, 10), torch.rand(64, 4) * 2 - 1\n"
        "for _ in range(2):\n"
        "    learner.update(x, a, -torch.ones(64), torch.randn(64, 10))\n"
        "print('updated')\n"
    )
    done = run_fresh(code, timeout=600)
    assert done.returncode == 0 and "updated" in done.stdout, done.stderr
    assert "script_method" not in done.stderr and "Profiler record" not in done.stderr, done.stderr


@pytest.mark.parametrize("algorithm", ["ddpg", "td3"])
def test_the_workspace_backend_steps_the_networks_and_optimisers_it_is_given(algorithm):
    """`WorkspaceUpdate` needs no `Learner`: handed networks laid out by `fold_parameters`,
    their Adam optimisers and the settings, it takes the reference's steps, the actor's only when
    told to (TD3's delay is the caller's), and reports no actor loss when it did not step it."""
    from curious.agent.mlp_workspace import WorkspaceUpdate, fold_parameters
    from curious.agent.update_backends import adam as _adam

    config = small_config(algorithm=algorithm, td3_policy_delay=2)
    reference = Learner(10, 4, config, seed=5)
    nets = {}
    for name in ("actor", "critics", "actor_target", "critics_target"):
        nets[name] = copy.deepcopy(getattr(reference, name))
    actor_flat = fold_parameters(nets["actor"], grads=True)
    critic_flat = fold_parameters(nets["critics"], grads=True)
    targets = [fold_parameters(nets[n], grads=False) for n in ("actor_target", "critics_target")]
    backend = WorkspaceUpdate(
        **nets,
        actor_opt=_adam([actor_flat], config.actor_lr),
        critic_opt=_adam([critic_flat], config.critic_lr),
        config=config,
        generator=torch.Generator().manual_seed(6),  # the Learner's: seed + 1
    )
    for step in range(1, 6):
        x, a, r, x2 = batch(seed=step)
        want = reference.update(x, a, r, x2)
        step_actor = algorithm == "ddpg" or step % 2 == 0
        critic_loss, actor_loss, q_target = backend.update(x, a, r, x2, step_actor)
        torch.testing.assert_close(critic_loss, want["critic_loss"], rtol=1e-4, atol=1e-5)
        torch.testing.assert_close(q_target, want["q_target_mean"], rtol=1e-4, atol=1e-5)
        if step_actor:
            torch.testing.assert_close(actor_loss, want["actor_loss"], rtol=1e-4, atol=1e-5)
        else:
            assert actor_loss is None
        reference.update_targets()
        with torch.no_grad():
            for target, online in zip(targets, (actor_flat, critic_flat), strict=True):
                target.lerp_(online, 1.0 - config.polyak)
    for name, net in nets.items():
        mine = getattr(reference, name).parameters()
        for p, q in zip(mine, net.parameters(), strict=True):
            torch.testing.assert_close(q, p, rtol=1e-4, atol=1e-5)


def test_the_workspace_backend_does_not_depend_on_the_learner():
    """One-way dependency: `curious.agent.learner` picks and drives the written-out backend; the
    backend's module imports nothing of the learner (not even for type checking)."""
    import ast
    import inspect

    import curious.agent.mlp_workspace

    tree = ast.parse(inspect.getsource(curious.agent.mlp_workspace))
    imported = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert "curious.agent.learner" not in imported


def test_encode_pair_equals_two_encodes():
    spec = ToyGoalEnv.spec
    encoder = InputEncoder(spec, GoalBox.of(ToyGoalEnv()))
    rng = np.random.default_rng(3)
    encoder.update_stats(rng.normal(size=(4, 11, 7)))
    s, s2 = torch.randn(16, 7), torch.randn(16, 7)
    goals, mask = torch.randn(16, 3, 3), torch.ones(16, 3)
    task = torch.zeros(16, 3)
    goal = GoalInput(goals, mask, task)
    x, x2 = encoder.encode_pair(s, s2, goal)
    torch.testing.assert_close(x, encoder.encode(s, goal))
    torch.testing.assert_close(x2, encoder.encode(s2, goal))


def test_direct_adam_step_gives_the_same_bits_as_optimizer_step():
    from curious.agent.mlp_workspace import _adam_step
    from curious.agent.update_backends import adam as _adam

    torch.manual_seed(0)
    params = [torch.nn.Parameter(torch.randn(1000)) for _ in range(2)]
    params[1].data.copy_(params[0].data)
    ours, reference = _adam([params[0]], 1e-3), _adam([params[1]], 1e-3)
    for _ in range(4):
        grad = torch.randn(1000)
        params[0].grad, params[1].grad = grad.clone(), grad.clone()
        _adam_step(ours)
        reference.step()
    assert torch.equal(params[0], params[1])
    state, ref_state = ours.state[params[0]], reference.state[params[1]]
    assert torch.equal(state["exp_avg_sq"], ref_state["exp_avg_sq"])
    assert float(state["step"]) == float(ref_state["step"]) == 4.0


def test_networks_start_xavier_uniform_with_zero_biases():
    """The authors' dense layers: xavier_initializer() weights, zero biases
    (flowersteam/curious, baselines/her/util.py, nn and nn_modular_her)."""
    learner = Learner(120, 4, resolve("paper"))
    layers = [m for m in learner.critics[0].net if isinstance(m, torch.nn.Linear)]
    layers += [m for m in learner.actor.net if isinstance(m, torch.nn.Linear)]
    for layer in layers:
        fan_out, fan_in = layer.weight.shape
        bound = (6.0 / (fan_in + fan_out)) ** 0.5
        w = layer.weight.detach()
        assert w.abs().max() <= bound
        if w.numel() > 1000:  # uniform on [-bound, bound]: std bound / sqrt(3)
            assert w.std().item() == pytest.approx(bound / 3**0.5, rel=0.05)
        assert torch.all(layer.bias == 0)
