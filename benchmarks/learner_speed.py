"""`curious bench learner`: DDPG+HER updates per second, ours vs the compute bound vs SB3.

All three at the authors' sizes (minibatch 256, actor and critic 3 x 256 ReLU) and the suite's
input (49 state + 21 goal + 7 task = 77 numbers, 4 actions), on the same threads:

* ours: `curious.agent.learner.Learner.update` on a fixed minibatch (one critic and one actor step,
  Adam, no sampling) with the default backend (autograd, the readable reference); `workspace` and
  `compiled` the same update with the other backends (`Config.learner_backend`);
  `ours_with_replay` adds relabelled sampling from a filled replay and input normalisation to the
  default (the training loop's full update step);
* bound: the update's matrix products (forward, weight-gradient and input-gradient products of
  the four networks it touches) timed alone on this machine, back to back with `torch.mm` on
  the same shapes: the update's FLOPs over the fp32 matmul rate measured at those shapes. A
  second figure, `bound_peak`, uses the rate of one large (2048^2) product instead;
* peer: Stable-Baselines3's DDPG with `HerReplayBuffer` ('future', k = 4), `train()` steps at
  the same sizes (its HER sampling included, as in `ours_with_replay`).

Each contender runs in three interleaved rounds and keeps its best round, so that all of them
meet the same share of a shared machine's load. Then one training cycle (rollouts + updates) of
the `quick` and `laptop` presets on the suite, and where its time goes.
"""

from __future__ import annotations

import argparse
import itertools
import time
from typing import Any

import numpy as np
import torch

from benchmarks import AtLeast, check_device, positive_seconds
from curious.config import Config
from curious.envs.goal_env import EnvSpec, RowsByModule
from curious.presets import resolve

STATE, GOAL, TASKS, ACTIONS = 49, 21, 7, 4


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--batch", type=AtLeast(1), default=256, help="minibatch (default 256)")
    parser.add_argument("--hidden", type=AtLeast(1), default=256, help="units per layer (256)")
    parser.add_argument("--layers", type=AtLeast(1), default=3, help="hidden layers (3)")
    parser.add_argument("--threads", type=AtLeast(1), default=1, help="torch threads (1)")
    parser.add_argument(
        "--seconds",
        type=positive_seconds,
        default=1.5,
        help="seconds per contender and round, 3 interleaved rounds (1.5)",
    )
    parser.add_argument(
        "--device", default="cpu", choices=("cpu", "cuda"), help="where networks train (cpu)"
    )
    parser.add_argument("--no-peer", action="store_true", help="skip Stable-Baselines3")
    parser.add_argument("--no-cycle", action="store_true", help="skip the training cycles")


def _rate(step: Any, seconds: float, sync: Any = None) -> float:
    """Calls of `step` per second over about `seconds`."""
    n, start = 0, time.perf_counter()
    while True:
        step()
        n += 1
        if n % 5 == 0:
            if sync:
                sync()
            elapsed = time.perf_counter() - start
            if elapsed >= seconds:
                return n / elapsed


def best_rates(steps: dict[str, Any], seconds: float, rounds: int = 3, sync: Any = None) -> dict:
    """Best calls/s of each step over `rounds` interleaved rounds of `seconds / rounds` each.

    Interleaving gives every contender the same share of a shared machine's quiet and busy
    moments; the best round is the least disturbed one.
    """
    for step in steps.values():  # warm-up: allocations, caches, lazy initialisation
        for _ in range(5):
            step()
    best = dict.fromkeys(steps, 0.0)
    for _ in range(rounds):
        for name, step in steps.items():
            best[name] = max(best[name], _rate(step, seconds / rounds, sync))
    return best


def _config(args: argparse.Namespace, **changes: Any) -> Config:
    return resolve(
        "paper",
        overrides=dict(
            hidden=args.hidden,
            layers=args.layers,
            batch_per_worker=args.batch,
            n_workers=1,
            device=args.device,
            torch_threads=args.threads,
            **changes,
        ),
    )


def _sync(device: str) -> Any:
    return torch.cuda.synchronize if device == "cuda" else None


# ----------------------------------------------------------------------------------------------
def update_gemms(batch: int, inputs: int, actions: int, hidden: int, layers: int) -> list[tuple]:
    """(m, k, n, transpose_a, transpose_b) of every matrix product in one DDPG update.

    Target: actor' and critic' forward. Critic step: forward, weight gradients, input gradients
    below the first layer. Actor step: actor and critic forward, the critic's input gradients
    (its first layer only for the action columns), actor weight gradients and input gradients
    below its first layer.
    """

    def net(n_in: int, n_out: int) -> list[tuple[int, int]]:
        return [(n_in, hidden)] + [(hidden, hidden)] * (layers - 1) + [(hidden, n_out)]

    actor, critic = net(inputs, actions), net(inputs + actions, 1)
    fwd = lambda L: [(batch, i, o, False, True) for i, o in L]  # noqa: E731  x @ W^T
    wgrad = lambda L: [(o, batch, i, True, False) for i, o in L]  # noqa: E731  g^T @ h
    igrad = lambda L: [(batch, o, i, False, False) for i, o in L[1:]]  # noqa: E731  g @ W
    return (
        fwd(actor) + fwd(critic)
        + fwd(critic) + wgrad(critic) + igrad(critic)
        + fwd(actor) + fwd(critic) + igrad(critic) + [(batch, hidden, actions, False, False)]
        + wgrad(actor) + igrad(actor)
    )  # fmt: skip


def bound_steps(args: argparse.Namespace) -> tuple[dict[str, Any], int]:
    """Steps that run one update's matrix products alone, and a large product; the FLOPs."""
    gemms = update_gemms(args.batch, STATE + GOAL + TASKS, ACTIONS, args.hidden, args.layers)
    flops = sum(2 * m * k * n for m, k, n, _, _ in gemms)
    dev = torch.device(args.device)
    operands = []
    for m, k, n, ta, tb in gemms:
        a = torch.randn(k, m, device=dev).t() if ta else torch.randn(m, k, device=dev)
        b = torch.randn(n, k, device=dev).t() if tb else torch.randn(k, n, device=dev)
        operands.append((a, b, torch.empty(m, n, device=dev)))

    def all_products() -> None:
        for a, b, c in operands:
            torch.mm(a, b, out=c)

    big = torch.randn(2048, 2048, device=dev)
    out = torch.empty_like(big)
    return {"bound": all_products, "big": lambda: torch.mm(big, big, out=out)}, flops


# ----------------------------------------------------------------------------------------------
class _SyntheticGoals(RowsByModule):
    """Goal slots and rewards with the suite's shapes: all the replay needs to relabel."""

    spec = EnvSpec(
        module_names=tuple(f"m{i}" for i in range(TASKS)),
        achievable=(True,) * TASKS,
        state_dim=STATE,
        action_dim=ACTIONS,
        goal_dim=3,
        # The default variant's outcome sizes: reach, push, cube above cube (cube 1 and cube 2's
        # xy), stack (cube 1, the gripper, cube 2's xy), three distractor pushes.
        outcome_slices=tuple(
            slice(a, b) for a, b in itertools.pairwise((0, 3, 6, 11, 19, 22, 25, 28))
        ),
        episode_length=50,
    )

    def goal_slot(self, module: int, g: np.ndarray) -> np.ndarray:
        return np.asarray(g, np.float32) * 0.15

    def goal(self, module: int, slot: np.ndarray, achieved: np.ndarray) -> np.ndarray:
        batch = np.broadcast_shapes(np.shape(slot)[:-1], np.shape(achieved)[:-1])
        return np.array(np.broadcast_to(slot, (*batch, 3)), np.float32)

    def reward(self, module: int, achieved: np.ndarray, goal: np.ndarray) -> np.ndarray:
        out = np.asarray(achieved)[..., self.spec.outcome_slices[module]][..., :3]
        far = np.linalg.norm(out - goal, axis=-1) > 0.05
        return np.where(far, -1.0, 0.0).astype(np.float32)


def our_steps(args: argparse.Namespace) -> tuple[dict[str, Any], float]:
    """Our update alone, and the training loop's step (sample + encode + update); the time
    of one relabelled sample in ms."""
    from curious.agent.agent import Agent
    from curious.agent.goals import GoalBox
    from curious.agent.learner import Learner
    from curious.agent.replay import EpisodeReplay

    config = _config(args)
    dev = torch.device(args.device)
    learner = Learner(STATE + GOAL + TASKS, ACTIONS, config)
    backends = {
        name: Learner(STATE + GOAL + TASKS, ACTIONS, _config(args, learner_backend=name))
        for name in ("workspace", "compiled")
    }
    g = torch.Generator().manual_seed(0)
    x = torch.randn(args.batch, STATE + GOAL + TASKS, generator=g).to(dev)
    a = (torch.rand(args.batch, ACTIONS, generator=g) * 2 - 1).to(dev)
    r = -(torch.rand(args.batch, generator=g) < 0.8).float().to(dev)
    x2 = torch.randn(args.batch, STATE + GOAL + TASKS, generator=g).to(dev)

    env = _SyntheticGoals()
    spec = env.spec
    rng = np.random.default_rng(0)
    n_ep, T = 400, spec.episode_length
    replay = EpisodeReplay(spec, capacity=n_ep)
    walk = rng.normal(0, 0.01, (n_ep, T + 1, spec.achieved_dim)).cumsum(1)
    replay.store(
        rng.normal(size=(n_ep, T + 1, STATE)).astype(np.float32),
        walk.astype(np.float32),
        rng.uniform(-1, 1, (n_ep, T, ACTIONS)).astype(np.float32),
        rng.integers(TASKS, size=n_ep),
        rng.uniform(-0.15, 0.15, (n_ep, TASKS, 3)).astype(np.float32),
    )
    agent = Agent(spec, config, GoalBox.of(env))
    agent.encoder.update_stats(replay.states[:50])
    probs = np.full(TASKS, 1 / TASKS)

    def full_step() -> None:
        agent.update(0, replay.sample(args.batch, rng, env, probs, config.her_p))

    tic = time.perf_counter()
    for _ in range(50):
        replay.sample(args.batch, rng, env, probs, config.her_p)
    sample_ms = (time.perf_counter() - tic) / 50 * 1e3
    steps = {"ours": lambda: learner.update(x, a, r, x2), "ours_with_replay": full_step}
    for name, other in backends.items():
        steps[name] = lambda other=other: other.update(x, a, r, x2)
    return steps, sample_ms


# ----------------------------------------------------------------------------------------------
def peer_step(args: argparse.Namespace) -> tuple[Any, str]:
    """One Stable-Baselines3 DDPG + HER `train()` step at the same sizes (None if missing)."""
    try:
        import gymnasium as gym
        from stable_baselines3 import DDPG, HerReplayBuffer
        from stable_baselines3.common.logger import configure
        from stable_baselines3.common.vec_env import DummyVecEnv
    except ImportError as exc:
        return None, f"stable-baselines3 not installed ({exc.name})"

    # SB3 feeds [observation, achieved_goal, desired_goal]; 35 + 21 + 21 = our 77 inputs.
    obs_dim = STATE + GOAL + TASKS - 2 * GOAL

    class Stub(gym.Env):
        observation_space = gym.spaces.Dict(
            {
                "observation": gym.spaces.Box(-10, 10, (obs_dim,), np.float32),
                "achieved_goal": gym.spaces.Box(-10, 10, (GOAL,), np.float32),
                "desired_goal": gym.spaces.Box(-10, 10, (GOAL,), np.float32),
            }
        )
        action_space = gym.spaces.Box(-1, 1, (ACTIONS,), np.float32)

        def reset(self, seed: int | None = None, options: Any = None) -> tuple[dict, dict]:
            return self.observation_space.sample(), {}

        def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
            return self.observation_space.sample(), -1.0, False, False, {}

        def compute_reward(self, achieved: np.ndarray, desired: np.ndarray, info: Any) -> Any:
            return -(np.linalg.norm(achieved - desired, axis=-1) > 0.05).astype(np.float32)

    env = DummyVecEnv([Stub])
    model = DDPG(
        "MultiInputPolicy",
        env,
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs=dict(n_sampled_goal=4, goal_selection_strategy="future"),
        batch_size=args.batch,
        policy_kwargs=dict(net_arch=[args.hidden] * args.layers),
        device=args.device,
        seed=0,
        verbose=0,
    )
    model.set_logger(configure(None, []))
    space = Stub.observation_space
    buffer = model.replay_buffer
    rng = np.random.default_rng(0)
    for _episode in range(40):
        for t in range(50):
            obs = {k: s.sample()[None] for k, s in space.spaces.items()}
            nxt = {k: s.sample()[None] for k, s in space.spaces.items()}
            done = np.array([t == 49])
            infos = [{"TimeLimit.truncated": bool(t == 49)}]
            action = rng.uniform(-1, 1, (1, ACTIONS)).astype(np.float32)
            buffer.add(obs, nxt, action, np.array([-1.0]), done, infos)
    import stable_baselines3

    def step() -> None:
        model.train(gradient_steps=1, batch_size=args.batch)

    return step, f"stable-baselines3 {stable_baselines3.__version__}"


# ----------------------------------------------------------------------------------------------
def measure_cycles(args: argparse.Namespace) -> dict[str, Any]:
    """Wall-clock of one training cycle of the quick and laptop presets on the suite."""
    try:
        from curious.envs.goal_env import make_suite_envs
    except ImportError as exc:  # pragma: no cover - the suite is part of the package
        return {"cycle_note": f"suite not importable: {exc}"}
    from curious.envs.batch import LocalEnvs
    from curious.runs.trainer import Trainer

    out: dict[str, Any] = {}
    for preset in ("quick", "laptop"):
        config = resolve(
            preset, overrides=dict(device=args.device, torch_threads=args.threads, progress=False)
        )
        envs = LocalEnvs(make_suite_envs(config.variant, 0, config.n_workers))
        trainer = Trainer(config, envs)
        trainer.cycle()  # warm-up: first allocations, normaliser, replay
        tic = time.perf_counter()
        result = trainer.cycle()
        total = time.perf_counter() - tic
        parts = {
            k.split("/", 1)[1]: v for k, v in result.losses.items() if k.startswith("seconds/")
        }
        prefix = f"cycle_{preset}"
        out[f"{prefix}_ms"] = total * 1e3
        out[f"{prefix}_shape"] = (
            f"{config.episodes_per_cycle} episodes x {trainer.spec.episode_length} steps, "
            f"{config.n_updates} updates x batch {config.batch_size}"
        )
        for name, seconds in parts.items():
            out[f"{prefix}_{name}_ms"] = seconds * 1e3
        out[f"{prefix}_other_ms"] = (total - sum(parts.values())) * 1e3
    return out


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """Everything above, in one dict (keys ours, bound, peer, unit first)."""
    if args.threads:
        torch.set_num_threads(args.threads)
    check_device(args.device)
    started = time.perf_counter()
    steps, sample_ms = our_steps(args)
    bound, flops = bound_steps(args)
    steps.update(bound)
    peer, peer_version = (None, "skipped") if args.no_peer else peer_step(args)
    if peer is not None:
        steps["peer"] = peer
    rates = best_rates(steps, 3 * args.seconds, rounds=3, sync=_sync(args.device))
    big_flops = 2 * 2048**3
    result: dict[str, Any] = {
        "ours": rates["ours"],
        "bound": rates["bound"],
        "peer": rates.get("peer"),
        "unit": "updates/s",
        "ours_over_bound": rates["ours"] / rates["bound"],
        "ours_with_replay": rates["ours_with_replay"],
        "ours_with_replay_over_peer": (
            rates["ours_with_replay"] / rates["peer"] if "peer" in rates else None
        ),
        "ours_over_peer": rates["ours"] / rates["peer"] if "peer" in rates else None,
        "workspace": rates["workspace"],
        "compiled": rates["compiled"],
        "workspace_over_compiled": rates["workspace"] / rates["compiled"],
        "workspace_over_ours": rates["workspace"] / rates["ours"],
        "bound_peak": rates["big"] * big_flops / flops,
        "replay_sample_ms": sample_ms,
        "flops_per_update": float(flops),
        "matmul_gflops_at_update_shapes": rates["bound"] * flops / 1e9,
        "matmul_gflops_2048": rates["big"] * big_flops / 1e9,
        "sizes": f"batch {args.batch}, {args.layers} x {args.hidden}, {args.threads} thread(s), "
        f"{args.device}",
        "peer_version": peer_version,
    }
    if not args.no_cycle:
        result.update(measure_cycles(args))
    result["bench_seconds"] = time.perf_counter() - started
    return result
