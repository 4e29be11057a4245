"""`curious bench threads`: episodes/s of many suite copies stepped together in MuJoCo's threads,
against the bare physics of `mujoco.rollout` and the suite stepping copy by copy.

All contestants run the same episodes (the same copies, seeds, modules, goals and actions),
interleaved step by step, so that load from other processes hits them alike:

- ours: `ThreadedEnvs` (`curious.envs.threaded`), the physics of all copies in one call per
  step on `--threads` native threads, the task logic vectorised over the copies.
- bound: the bare physics through `mujoco.rollout.Rollout(nthread=--threads)`: one call per
  control step advancing every copy by its substeps from the last call's states, with the
  controls (finger commands, mocap targets) ours just stepped with, on the models ours runs
  (one shared model where the copies' are the same). No task logic, no observation, no reset.
- peer: `LocalEnvs` (`curious.envs.batch`), the suite stepping each copy in turn, as a run
  steps its copies in its own process (`env_processes=1`, the default).

`batch_physics` in the detail is the physics of ours alone (`suite.lockstep_physics` with the
same controls: `mujoco.batch`, which also computes the positions and velocities the observation
reads): ours over it is what the task logic and the resets cost, it over the bound what the
batch's extra work costs. An episode's time is the sum of its steps' (and for ours and the peer
its reset's); rates come from the median episode. The `cpu_` rates divide by the CPU time of all
this process's threads instead of the wall time: a steadier measure of what a step costs where
other processes share the cores.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from benchmarks import AtLeast

NAMES = ("ours", "bound", "peer", "batch_physics")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--copies",
        type=AtLeast(1),
        default=38,
        help="environment copies (default 38: 2 runs x 19)",
    )
    parser.add_argument("--threads", type=AtLeast(1), default=2, help="native threads (default 2)")
    parser.add_argument(
        "--rounds", type=AtLeast(1), default=5, help="timed episodes each (default 5)"
    )
    parser.add_argument("--variant", default="default", help="suite variant (default: default)")
    parser.add_argument(
        "--seed", type=AtLeast(0), default=0, help="seed of the environments and actions (0)"
    )


class _Clocks:
    """Wall and CPU seconds (all this process's threads) spent in each contestant's calls."""

    def __init__(self) -> None:
        self.seconds = {name: np.zeros(2) for name in NAMES}

    def time(self, name: str, call: Callable[..., Any], *args: Any) -> None:
        """Run `call(*args)` on `name`'s clocks."""
        wall, cpu = time.perf_counter(), time.process_time()
        call(*args)
        self.seconds[name] += (time.perf_counter() - wall, time.process_time() - cpu)


class _Bound:
    """The bare physics of the copies through one `mujoco.rollout.Rollout` thread pool."""

    def __init__(self, models: list[Any], threads: int, substeps: int, nu: int) -> None:
        import mujoco  # here: `curious bench threads --help` imports no MuJoCo
        from mujoco import rollout

        self.mujoco = mujoco
        self.models = models
        self.substeps, self.nu = substeps, nu
        self.spec = int(mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_MOCAP_POS)
        self.full = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
        self.pool = rollout.Rollout(nthread=threads)
        self.datas = [mujoco.MjData(models[0]) for _ in range(threads)]
        n, nstate = len(models), mujoco.mj_stateSize(models[0], self.full)
        self.initial = np.empty((n, nstate))
        self.states = np.empty((n, substeps, nstate))
        self.sensordata = np.empty((n, substeps, 0))
        self.control = np.empty((n, substeps, mujoco.mj_stateSize(models[0], self.spec)))

    def start(self, datas: list[Any]) -> None:
        """Start from the copies' states (their MjData)."""
        for i, data in enumerate(datas):
            self.mujoco.mj_getState(self.models[i], data, self.initial[i], self.full)

    def step(self, ctrl: np.ndarray, old_mocap: np.ndarray, mocap: np.ndarray) -> None:
        """One control step, with the controls of ours' (legacy order: the first substep with
        the mocap positions of the step before)."""
        n, nu, c = len(ctrl), self.nu, self.control
        c[:, :, :nu] = ctrl[:, None]
        c[:, 0, nu:] = old_mocap.reshape(n, -1)
        c[:, 1:, nu:] = mocap.reshape(n, 1, -1)
        self.pool.rollout(
            self.models,
            self.datas,
            self.initial,
            c,
            control_spec=self.spec,
            skip_checks=True,
            nstep=self.substeps,
            state=self.states,
            sensordata=self.sensordata,
            chunk_size=None,
        )
        self.initial[:] = self.states[:, -1]

    def close(self) -> None:
        self.pool.close()


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """ours, bound, peer (episodes/s) on the same episodes, and the batch's physics alone."""
    import mujoco

    from curious.envs.batch import LocalEnvs
    from curious.envs.goal_env import make_suite_envs
    from curious.envs.threaded import ThreadedEnvs
    from suite.lockstep_physics import LockstepPhysics

    copies, threads, rounds = int(args.copies), int(args.threads), int(args.rounds)
    started = time.perf_counter()
    load = os.getloadavg()[0]
    peer = LocalEnvs(make_suite_envs(args.variant, args.seed, copies))
    ours = ThreadedEnvs(make_suite_envs(args.variant, args.seed, copies), threads=threads)
    physics = ours.lockstep.physics
    shared = physics.shared_model
    models = physics.models if shared is None else [shared] * copies  # as ours runs them
    alone = LockstepPhysics(physics.models, physics.substeps, threads)
    bound = _Bound(models, threads, physics.substeps, physics.ctrl.shape[1])
    datas = [env.dm_env.physics.data.ptr for env in ours.envs]
    spec = ours.spec
    rng = np.random.default_rng(args.seed)
    episodes: dict[str, list[np.ndarray]] = {name: [] for name in NAMES}
    try:
        for r in range(rounds + 1):  # the first one warms up, untimed
            modules = rng.integers(0, spec.n_modules, copies)
            goals = rng.uniform(-1.0, 1.0, (copies, spec.goal_dim))
            clocks = _Clocks()
            clocks.time("peer", peer.reset, modules, goals)
            clocks.time("ours", ours.reset, modules, goals)
            for i, data in enumerate(datas):  # the physics alone start where ours does
                alone.load(i, data)
            alone.refresh(range(copies))
            bound.start(datas)
            for _ in range(spec.episode_length):
                actions = rng.uniform(-1.0, 1.0, (copies, spec.action_dim))
                old_mocap = physics.mocap_pos.copy()
                clocks.time("ours", ours.step, actions)
                ctrl, mocap = physics.ctrl.copy(), physics.mocap_pos.copy()
                clocks.time("batch_physics", alone.advance, ctrl, mocap)
                clocks.time("bound", bound.step, ctrl, old_mocap, mocap)
                clocks.time("peer", peer.step, actions)
            if r:
                for name, seconds in clocks.seconds.items():
                    episodes[name].append(seconds)
    finally:
        ours.close()
        alone.close()
        bound.close()
    median = {name: np.median(np.stack(t), axis=0) for name, t in episodes.items()}
    rate = {name: copies / float(m[0]) for name, m in median.items()}
    cpu_rate = {name: copies / float(m[1]) for name, m in median.items()}
    return {
        "ours": rate["ours"],
        "bound": rate["bound"],
        "peer": rate["peer"],
        "unit": "episodes/s",
        "ours_over_bound": rate["ours"] / rate["bound"],
        "ours_over_peer": rate["ours"] / rate["peer"],
        "batch_physics": rate["batch_physics"],
        "ours_over_batch_physics": rate["ours"] / rate["batch_physics"],
        "batch_physics_over_bound": rate["batch_physics"] / rate["bound"],
        "cpu_ours": cpu_rate["ours"],
        "cpu_bound": cpu_rate["bound"],
        "cpu_peer": cpu_rate["peer"],
        "cpu_batch_physics": cpu_rate["batch_physics"],
        "cpu_ours_over_bound": cpu_rate["ours"] / cpu_rate["bound"],
        "cpu_ours_over_batch_physics": cpu_rate["ours"] / cpu_rate["batch_physics"],
        "copies": copies,
        "threads": threads,
        "shared_model": shared is not None,
        "steps_per_episode": spec.episode_length,
        "substeps": physics.substeps,
        "variant": args.variant,
        "rounds": rounds,
        "cpus": os.cpu_count(),
        "load_average_1min_at_start": load,
        "mujoco": mujoco.__version__,
        "wall_s": time.perf_counter() - started,
    }
