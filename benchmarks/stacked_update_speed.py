"""`curious bench stacked`: R learners' updates as one stacked step (ours) against the same
learners updated one after the other (peer).

Each of `--runs` learners (the `laptop` networks by default: 3 x 256, the suite's 77 inputs and
4 actions, DDPG) updates on a minibatch of its own, `--batch` transitions. Peer: each learner's
`Learner.update` in turn, in one thread, with its `--backend`. Ours: each learner's
`Learner.update` in a thread of its own, all joined to one `UpdateLockstep`
(`curious.agent.update_lockstep`), as a population's runs are: every call stacks the R steps
(`curious.agent.stacked_update.stacked_step`), lockstep hand-offs included. `ours_batched` is
ours with one batched product per layer for all runs (the GPU's arithmetic; on a CPU ours runs
each run's products on their own). Rates are learner updates per second, all runs together;
each contender runs `--updates` updates per learner in each of 3 interleaved rounds, and keeps
its best round. `bound`: the updates/s of the update's matrix products alone, back to back
(`benchmarks.learner_speed.bound_steps`), best of 3 seconds, which on a compute-bound device is
the same for one learner as for R.
"""

from __future__ import annotations

import argparse
import functools
import threading
import time
from collections.abc import Callable
from typing import Any

import torch

from benchmarks import AtLeast, CountList, check_device

STATE, GOAL, TASKS, ACTIONS = 49, 21, 7, 4


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--runs",
        type=CountList(1),
        default=[2, 4],
        help="learners stepped together, a list (default 2,4)",
    )
    parser.add_argument("--batch", type=AtLeast(1), default=512, help="minibatch (default 512)")
    parser.add_argument("--hidden", type=AtLeast(1), default=256, help="units per layer (256)")
    parser.add_argument("--layers", type=AtLeast(1), default=3, help="hidden layers (3)")
    parser.add_argument("--threads", type=AtLeast(1), default=1, help="torch threads (1)")
    parser.add_argument(
        "--algorithm", default="ddpg", choices=("ddpg", "td3"), help="the learners' update (ddpg)"
    )
    parser.add_argument(
        "--backend", default="autograd", help="the learners' own backend (default autograd)"
    )
    parser.add_argument(
        "--updates", type=AtLeast(1), default=20, help="updates per learner and round (default 20)"
    )
    parser.add_argument(
        "--device", default="cpu", choices=("cpu", "cuda"), help="where networks train (cpu)"
    )


def _learners(args: argparse.Namespace, runs: int) -> tuple[list[Any], list[tuple]]:
    """`runs` learners (seeds 0, 1, ...) and a minibatch for each."""
    from curious.agent.learner import Learner
    from curious.config import resolve

    config = resolve(
        "laptop",
        overrides=dict(
            hidden=args.hidden, layers=args.layers, algorithm=args.algorithm,
            learner_backend=args.backend, device=args.device, torch_threads=args.threads,
        ),
    )  # fmt: skip
    inputs, dev = STATE + GOAL + TASKS, torch.device(args.device)
    learners = [Learner(inputs, ACTIONS, config, seed=s) for s in range(runs)]
    batches = []
    for s in range(runs):
        g = torch.Generator().manual_seed(s)
        batches.append(
            (
                torch.randn(args.batch, inputs, generator=g).to(dev),
                (torch.rand(args.batch, ACTIONS, generator=g) * 2 - 1).to(dev),
                -(torch.rand(args.batch, generator=g) < 0.8).float().to(dev),
                torch.randn(args.batch, inputs, generator=g).to(dev),
            )
        )
    return learners, batches


def _in_thread(work: Callable[[], float]) -> float:
    """`work()` in a thread of its own, as a population's runs are (`_torch_threads`)."""
    out: list[float] = []
    thread = threading.Thread(target=lambda: out.append(_torch_threads(work)()))
    thread.start()
    thread.join()
    return out[0]


def _torch_threads(work: Callable[..., Any]) -> Callable[..., Any]:
    """`work`, taking torch's thread count in the thread that calls it: OpenMP's count is a
    thread's own, and a thread that has not set it runs its first products (a thread running
    products only, all of them) with every core, as a run's thread does not
    (`Trainer` sets it)."""
    threads = torch.get_num_threads()

    def run(*args: Any) -> Any:
        torch.set_num_threads(threads)
        return work(*args)

    return run


def _rate(step: Callable[[], None], sync: Any, seconds: float = 1.0) -> float:
    """Calls of `step` per second, over about `seconds`."""
    for _ in range(3):
        step()
    tic, n = time.perf_counter(), 0
    while time.perf_counter() - tic < seconds:
        step()
        n += 1
    sync()
    return n / (time.perf_counter() - tic)


def _one_by_one(learners: list[Any], batches: list[tuple], updates: int, sync: Any) -> float:
    """Learner updates/s, each learner's update in turn, in one thread."""

    def work() -> float:
        tic = time.perf_counter()
        for _ in range(updates):
            for learner, batch in zip(learners, batches, strict=True):
                learner.update(*batch)
        sync()
        return len(learners) * updates / (time.perf_counter() - tic)

    return _in_thread(work)


def _together(
    learners: list[Any], batches: list[tuple], updates: int, sync: Any, run_steps: Callable
) -> float:
    """Learner updates/s, each learner in a thread of its own through one `UpdateLockstep`
    (one update phase of `updates` steps each)."""
    from curious.agent.update_lockstep import UpdateLockstep

    lanes = UpdateLockstep(run_steps).join(learners, updates)
    start = threading.Barrier(len(learners) + 1)

    def work(learner: Any, batch: tuple) -> None:
        start.wait()
        for _ in range(updates):
            learner.update(*batch)

    threads = [
        threading.Thread(target=_torch_threads(work), args=pair)
        for pair in zip(learners, batches, strict=True)
    ]
    for thread in threads:
        thread.start()
    start.wait()
    tic = time.perf_counter()
    for thread in threads:
        thread.join()
    sync()
    elapsed = time.perf_counter() - tic
    lanes.close()
    return len(learners) * updates / elapsed


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """Per number of runs: ours, ours_batched and peer (learner updates/s); bound."""
    from benchmarks.learner_speed import bound_steps
    from curious.agent.update_lockstep import stack_alike

    check_device(args.device)
    torch.set_num_threads(args.threads)
    sync = torch.cuda.synchronize if args.device == "cuda" else lambda: None
    contenders: dict[str, Callable[..., float]] = {
        "peer": _one_by_one,
        "ours": functools.partial(_together, run_steps=stack_alike),
        "ours_batched": functools.partial(
            _together, run_steps=functools.partial(stack_alike, batched_products=True)
        ),
    }
    out: dict[str, Any] = {"unit": "learner updates/s"}
    for runs in args.runs:
        learners, batches = _learners(args, runs)
        for run in contenders.values():  # warm-up: allocations, caches, the optimisers' state
            run(learners, batches, 2, sync)
        best = dict.fromkeys(contenders, 0.0)
        for _ in range(3):
            for name, run in contenders.items():
                best[name] = max(best[name], run(learners, batches, args.updates, sync))
        for name, rate in best.items():
            out[f"{name}_{runs}"] = rate
        out[f"ours_over_peer_{runs}"] = best["ours"] / best["peer"]
    last = max(args.runs)
    out["ours"], out["peer"] = out[f"ours_{last}"], out[f"peer_{last}"]
    products = functools.partial(_rate, bound_steps(args)[0]["bound"], sync)
    out["bound"] = max(_in_thread(products) for _ in range(3))
    out["shape"] = (
        f"{args.algorithm}, {args.layers} x {args.hidden}, batch {args.batch}, "
        f"{args.threads} torch thread(s), backend {args.backend}, {args.device}; "
        f"{args.updates} updates per learner and round, best of 3 rounds"
    )
    return out
