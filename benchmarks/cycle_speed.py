"""`curious bench cycle`: training episodes per second of whole cycles, with rollouts overlapped
with the updates (ours) against the serial path (peer), and where a cycle's time goes.

Every contender is a `Trainer` of the same preset and seed on the suite, without test rollouts
(they run once an epoch), warmed up by one untimed cycle; then each runs its timed cycles in one
block (overlapped rollouts go on after a cycle returns, so the cycles of different contenders
cannot be interleaved). Each timed cycle scores one cycle of episodes: in steady state, the
rounds collected during the untimed warm-up stand for those still in flight at the end.

* peer: the serial path, the authors' order: rollouts, then updates, the copies stepped one
  after the other in the training process;
* ours: the next cycle's rollouts collected during this cycle's updates
  (`--set overlap_rollouts=true`, one documented flag);
* workers: the copies in worker processes, one per core (`--set env_processes=0`);
* ours_workers: both;
* ours_workspace: ours with the written-out update (`learner_backend=workspace`);
* peer_threads and ours_threads: peer and ours with one torch thread per core for the updates
  (`--set torch_threads=0`) instead of `--threads`;
* ours_gpu: every setting meant for a GPU node (`--device cuda`) at once: overlap, a worker
  process per core, prefetched minibatches, the compiled update and acting on CPU copies;
* workers_prefetch, workers_compiled, workers_act_on_cpu: the workers with one of those
  settings each, to tell what each one costs or gains on a GPU node;
* workers_prefetch_compiled: the workers with prefetched minibatches and the compiled update
  (the fastest synchronous contender measured on 16-core nodes with an H100: 51.0 episodes/s
  on node F, 2026-11-26, docs/benchmarks.md);
* ours_workers_prefetch: overlap, workers and prefetched minibatches (48.2 episodes/s on the
  first such node, 2026-11-26, with the learner of 86f245c: docs/scaling.md).

The default list leaves out the GPU node's contenders (the compiled update takes minutes to
compile on a CPU): `--device cuda --contenders ours_gpu,workers` and the like ask for them.

torch's thread count is one per process, so it is set before each contender's block.

`bound` is the physics alone: the rate at which one core steps the suite's MuJoCo model for one
episode's 50 control steps, times the machine's cores (what rollouts could reach if nothing but
physics ran).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from typing import Any

import numpy as np
import torch

from benchmarks import AtLeast


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", default="laptop", help="training preset (default laptop)")
    parser.add_argument(
        "--cycles", type=AtLeast(1), default=4, help="timed cycles each (default 4)"
    )
    parser.add_argument("--threads", type=AtLeast(1), default=1, help="torch threads (default 1)")
    parser.add_argument(
        "--device", default="cpu", choices=("cpu", "cuda"), help="where networks train"
    )
    parser.add_argument(
        "--contenders",
        default=",".join(DEFAULT_CONTENDERS),
        help=(
            "comma-separated contenders besides peer and ours, of: "
            f"{', '.join(CONTENDERS)} (default: {','.join(DEFAULT_CONTENDERS)})"
        ),
    )


CONTENDERS: dict[str, dict[str, Any]] = {
    "workers": dict(env_processes=0),
    "ours_workers": dict(overlap_rollouts=True, env_processes=0),
    "ours_workspace": dict(overlap_rollouts=True, learner_backend="workspace"),
    "peer_threads": dict(torch_threads=0),
    "ours_threads": dict(overlap_rollouts=True, torch_threads=0),
    "ours_gpu": dict(
        overlap_rollouts=True,
        env_processes=0,
        prefetch_minibatches=True,
        learner_backend="compiled",
        act_on_cpu=True,
    ),
    "workers_prefetch": dict(env_processes=0, prefetch_minibatches=True),
    "workers_compiled": dict(env_processes=0, learner_backend="compiled"),
    "workers_act_on_cpu": dict(env_processes=0, act_on_cpu=True),
    "workers_prefetch_compiled": dict(
        env_processes=0, prefetch_minibatches=True, learner_backend="compiled"
    ),
    "ours_workers_prefetch": dict(
        overlap_rollouts=True, env_processes=0, prefetch_minibatches=True
    ),
}
"""The settings of every optional contender, over the preset's (see the module docstring)."""

DEFAULT_CONTENDERS = (
    "workers",
    "ours_workers",
    "ours_workspace",
    "peer_threads",
    "ours_threads",
)
"""What `curious bench cycle` runs unless told: those that run as well on a CPU."""


def _trainer(config: Any) -> Any:
    from curious.envs.batch import LocalEnvs, ProcessEnvs
    from curious.envs.goal_env import suite_env_fns
    from curious.runs.trainer import Trainer

    fns = suite_env_fns(config.variant, config.seed, config.n_workers)
    if config.processes > 1:
        return Trainer(config, ProcessEnvs(fns, config.processes))
    return Trainer(config, LocalEnvs([fn() for fn in fns]))


def physics_episodes_per_second(variant: str, episodes: int = 5) -> float:
    """One core stepping the suite's compiled model, 50 control steps of 20 substeps."""
    import mujoco

    import suite

    env = suite.load(variant, seed=0)
    model, data = env.physics.model.ptr, env.physics.data.ptr
    substeps = round(env.control_timestep() / env.physics.timestep())
    tic = time.perf_counter()
    for _ in range(episodes):
        for _ in range(50):
            mujoco.mj_step(model, data, substeps)
    return episodes / (time.perf_counter() - tic)


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """ours, bound, peer (episodes/s) and each contender's per-part milliseconds per cycle."""
    from curious.presets import resolve

    base = resolve(
        args.preset,
        overrides=dict(
            progress=False,
            torch_threads=args.threads,
            test_rollouts_per_worker=0,
            device=args.device,
        ),
    )
    # a budget that outlasts the warm-up, the timed cycles and an overlapped cycle ahead
    needed = (args.cycles + 2) * base.episodes_per_cycle
    base = dataclasses.replace(base, total_episodes=max(base.total_episodes, needed))
    wanted = [name for name in args.contenders.split(",") if name]
    unknown = sorted(set(wanted) - set(CONTENDERS))
    if unknown:
        raise ValueError(f"unknown contenders {unknown}; choose from {', '.join(CONTENDERS)}")
    configs = {"peer": base, "ours": dataclasses.replace(base, overlap_rollouts=True)}
    configs |= {name: dataclasses.replace(base, **CONTENDERS[name]) for name in wanted}
    default_threads = torch.get_num_threads()  # torch's own, before a trainer sets it
    trainers = {name: _trainer(config) for name, config in configs.items()}
    try:
        for trainer in trainers.values():
            trainer.cycle()  # warm-up: workers, first allocations, replay
        seconds = dict.fromkeys(trainers, 0.0)
        episodes = dict.fromkeys(trainers, 0)
        parts: dict[str, dict[str, float]] = {name: {} for name in trainers}
        for name, trainer in trainers.items():  # a block of cycles each: overlapped
            torch.set_num_threads(configs[name].torch_threads or default_threads)
            for _ in range(args.cycles):  # rollouts go on after a cycle returns
                tic = time.perf_counter()
                result = trainer.cycle()
                seconds[name] += time.perf_counter() - tic
                episodes[name] += len(result.rows["episode"])
                for key, value in result.losses.items():
                    if key.startswith("seconds/"):
                        part = key.split("/", 1)[1]
                        parts[name][part] = parts[name].get(part, 0.0) + value
    finally:
        for trainer in trainers.values():
            trainer.close()
        torch.set_num_threads(default_threads)
    rates = {name: episodes[name] / seconds[name] for name in trainers}
    cores = os.cpu_count() or 1
    out: dict[str, Any] = {
        "ours": rates["ours"],
        "bound": physics_episodes_per_second(base.variant) * cores,
        "peer": rates["peer"],
        "unit": "episodes/s",
        "ours_over_peer": rates["ours"] / rates["peer"],
        "processes": dataclasses.replace(base, env_processes=0).processes,
        "cores": cores,
        "shape": (
            f"preset {args.preset}: {base.episodes_per_cycle} episodes and {base.n_updates} "
            f"updates of {base.batch_size} per cycle, {args.cycles} timed cycles each"
        ),
    }
    for name in wanted:
        out[name] = rates[name]
        out[f"{name}_over_peer"] = rates[name] / rates["peer"]
    out["threads"] = default_threads
    for name in trainers:
        total = seconds[name] / args.cycles
        out[f"{name}_cycle_ms"] = total * 1e3
        for part, value in parts[name].items():
            out[f"{name}_{part}_ms"] = value / args.cycles * 1e3
        out[f"{name}_other_ms"] = (total - sum(parts[name].values()) / args.cycles) * 1e3
    out["physics_episodes_per_s_one_core"] = float(np.round(out["bound"] / cores, 2))
    return out
