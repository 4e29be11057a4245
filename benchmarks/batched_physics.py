"""`curious bench threads`: episodes/s of many suite copies stepped together in MuJoCo's threads,
against the bare physics of `mujoco.rollout` and the suite stepping copy by copy.

All contestants run the same episodes (the same copies, seeds, modules, goals and actions)
round by round, interleaved, so that load from other processes hits them alike:

- ours: `ThreadedEnvs` (`curious.envs.threaded`), the physics of all copies in one call per
  step on `--threads` native threads, the task logic vectorised over the copies.
- bound: the bare physics through `mujoco.rollout.Rollout(nthread=--threads)`: one call per
  control step advancing every copy by its substeps from the last call's states, with the
  controls (finger commands, mocap targets) our episodes produced, recorded in an untimed pass,
  on the models ours runs (one shared model where the copies' are the same). No task logic,
  no observation.
- peer: `LocalEnvs` (`curious.envs.batch`), the suite stepping each copy in turn, as the
  training loop does today in one process.

`batch_physics` in the detail is the physics of ours alone (`suite.lockstep_physics`: the same
recorded controls through `mujoco.batch`, which also computes the positions and velocities the
observation reads): ours over it is what the task logic costs, it over the bound what the
batch's extra work costs. Rates come from the median round of each; the `cpu_` rates divide by
the CPU time of all this process's threads instead of the wall time, a steadier measure of what a
step costs where other processes share the cores.
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Any

import numpy as np


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--copies", type=int, default=38, help="environment copies (default 38: 2 runs x 19)"
    )
    parser.add_argument("--threads", type=int, default=2, help="native threads (default 2)")
    parser.add_argument("--rounds", type=int, default=3, help="timed rounds each (default 3)")
    parser.add_argument("--variant", default="default", help="suite variant (default: default)")
    parser.add_argument("--seed", type=int, default=0)


def _full_physics() -> int:
    import mujoco  # here: `curious bench threads --help` imports no MuJoCo

    return int(mujoco.mjtState.mjSTATE_FULLPHYSICS)


class _Recording:
    """What the bound replays of one round: the copies' states after the reset and the controls
    of every step."""

    def __init__(
        self, initial: np.ndarray, mocap0: np.ndarray, ctrl: np.ndarray, mocap: np.ndarray
    ) -> None:
        self.initial = initial  # (n, nstate) mjSTATE_FULLPHYSICS
        self.mocap0 = mocap0  # (n, nmocap, 3) after the reset
        self.ctrl = ctrl  # (T, n, nu)
        self.mocap = mocap  # (T, n, nmocap, 3)


class _Clock:
    """Wall and CPU seconds (of all this process's threads) from its start to `stop`."""

    def __init__(self) -> None:
        self.wall, self.cpu = time.perf_counter(), time.process_time()

    def stop(self) -> tuple[float, float]:
        return time.perf_counter() - self.wall, time.process_time() - self.cpu


def _round(
    envs: Any, modules: np.ndarray, goals: np.ndarray, actions: np.ndarray
) -> tuple[float, float]:
    clock = _Clock()
    envs.reset(modules, goals)
    for a in actions:
        envs.step(a)
    return clock.stop()


def _record(ours: Any, modules: np.ndarray, goals: np.ndarray, actions: np.ndarray) -> _Recording:
    """An untimed round of ours, keeping the start states and the controls it stepped with."""
    import mujoco

    physics = ours.lockstep.physics
    ours.reset(modules, goals)
    n = len(modules)
    full = _full_physics()
    initial = np.empty((n, mujoco.mj_stateSize(physics.models[0], full)))
    for i in range(n):
        dm = ours.envs[i].dm_env.physics
        mujoco.mj_getState(dm.model.ptr, dm.data.ptr, initial[i], full)
    mocap0 = physics.mocap_pos[:n].copy()
    ctrl, mocap = [], []
    for a in actions:
        ours.step(a)
        ctrl.append(physics.ctrl[:n].copy())
        mocap.append(physics.mocap_pos[:n].copy())
    return _Recording(initial, mocap0, np.stack(ctrl), np.stack(mocap))


class _Bound:
    """The bare physics of the copies through one `mujoco.rollout.Rollout` thread pool."""

    def __init__(self, models: list[Any], threads: int, substeps: int) -> None:
        import mujoco
        from mujoco import rollout

        self.models = models
        self.substeps = substeps
        self.spec = int(mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_MOCAP_POS)
        self.pool = rollout.Rollout(nthread=threads)
        self.datas = [mujoco.MjData(models[0]) for _ in range(threads)]
        self.nstate = mujoco.mj_stateSize(models[0], _full_physics())

    def controls(self, rec: _Recording) -> np.ndarray:
        """(T, n, substeps, ncontrol): the per-substep controls of ours' legacy stepping."""
        steps, n, nu = rec.ctrl.shape
        out = np.empty((steps, n, self.substeps, nu + rec.mocap[0, 0].size))
        out[..., :nu] = rec.ctrl[:, :, None]
        mocap = rec.mocap.reshape(steps, n, 1, -1)
        out[:, :, 1:, nu:] = mocap
        out[0, :, 0, nu:] = rec.mocap0.reshape(n, -1)
        out[1:, :, 0, nu:] = mocap[:-1, :, 0]
        return out

    def episode(self, rec: _Recording, controls: np.ndarray) -> tuple[float, float]:
        n = len(rec.initial)
        models = self.models[:n]
        state = np.empty((n, self.substeps, self.nstate))
        sensordata = np.empty((n, self.substeps, 0))
        initial = rec.initial.copy()
        clock = _Clock()
        for control in controls:
            self.pool.rollout(
                models,
                self.datas,
                initial,
                control,
                control_spec=self.spec,
                skip_checks=True,
                nstep=self.substeps,
                state=state,
                sensordata=sensordata,
                chunk_size=None,
            )
            initial[:] = state[:, -1]
        return clock.stop()

    def close(self) -> None:
        self.pool.close()


def _batch_physics_episode(ours: Any, rec: _Recording) -> tuple[float, float]:
    """The same controls through ours' physics alone, from the recorded round's reset."""
    lockstep = ours.lockstep
    physics = lockstep.physics
    n = len(rec.initial)
    # Back to the reset: each copy's own MjData still holds it (ours syncs none).
    lockstep.load(range(n))
    clock = _Clock()
    for ctrl, mocap in zip(rec.ctrl, rec.mocap, strict=True):
        physics.advance(ctrl, mocap)
    return clock.stop()


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """ours, bound, peer (episodes/s) on the same rounds, and the batch's physics alone."""
    import mujoco

    from curious.envs.batch import LocalEnvs
    from curious.envs.goal_env import make_suite_envs
    from curious.envs.threaded import ThreadedEnvs

    copies, threads, rounds = int(args.copies), int(args.threads), int(args.rounds)
    if copies < 1 or threads < 1 or rounds < 1:
        raise ValueError("--copies, --threads and --rounds must be at least 1")
    started = time.perf_counter()
    load = os.getloadavg()[0]
    peer = LocalEnvs(make_suite_envs(args.variant, args.seed, copies))
    ours = ThreadedEnvs(make_suite_envs(args.variant, args.seed, copies), threads=threads)
    physics = ours.lockstep.physics
    shared = physics.shared_model
    models = physics.models if shared is None else [shared] * copies  # as ours runs them
    bound = _Bound(models, threads, physics.substeps)
    spec = ours.spec
    rng = np.random.default_rng(args.seed)
    names = ("ours", "bound", "peer", "batch_physics")
    wall: dict[str, list[float]] = {name: [] for name in names}
    cpu: dict[str, list[float]] = {name: [] for name in names}
    try:
        for r in range(rounds + 1):  # the first one warms up, untimed
            modules = rng.integers(0, spec.n_modules, copies)
            goals = rng.uniform(-1.0, 1.0, (copies, spec.goal_dim))
            actions = rng.uniform(-1.0, 1.0, (spec.episode_length, copies, spec.action_dim))
            states = ours.get_rng_states()
            rec = _record(ours, modules, goals, actions)
            ours.set_rng_states(states)
            controls = bound.controls(rec)
            result = {
                "peer": _round(peer, modules, goals, actions),
                "ours": _round(ours, modules, goals, actions),
                "bound": bound.episode(rec, controls),
                "batch_physics": _batch_physics_episode(ours, rec),
            }
            if r:
                for name, (wall_s, cpu_s) in result.items():
                    wall[name].append(wall_s)
                    cpu[name].append(cpu_s)
    finally:
        ours.close()
        bound.close()
    rate = {name: copies / float(np.median(t)) for name, t in wall.items()}
    cpu_rate = {name: copies / float(np.median(t)) for name, t in cpu.items()}
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
        # Episodes per CPU second (all threads): what a step costs, whatever share of the cores
        # other processes leave; on a loaded machine a steadier comparison than the rates.
        "cpu_ours": cpu_rate["ours"],
        "cpu_bound": cpu_rate["bound"],
        "cpu_peer": cpu_rate["peer"],
        "cpu_batch_physics": cpu_rate["batch_physics"],
        "cpu_ours_over_bound": cpu_rate["ours"] / cpu_rate["bound"],
        "cpu_ours_over_batch_physics": cpu_rate["ours"] / cpu_rate["batch_physics"],
        "copies": copies,
        "threads": threads,
        "shared_model": physics.shared_model is not None,
        "steps_per_episode": spec.episode_length,
        "substeps": physics.substeps,
        "variant": args.variant,
        "rounds": rounds,
        "cpus": os.cpu_count(),
        "load_average_1min_at_start": load,
        "mujoco": mujoco.__version__,
        "wall_s": time.perf_counter() - started,
    }
