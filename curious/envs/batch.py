"""The environment copies a run steps together: in the training process, or in worker processes.

A round of parallel episodes resets the first k copies, then steps them together T times with one
batched policy call per step (`curious.envs.rollout.run_episodes`). `EnvBatch` is what that needs:

* `LocalEnvs` steps `GoalEnv` copies one after the other in this process;
* `ProcessEnvs` gives each of `processes` worker processes a contiguous share of the copies
  (built there from picklable constructors) and steps the shares at the same time; observations
  come back through pipes. Each copy is seeded as it would be in this process and gets the same
  actions, so a run gives the same episodes whatever the number of processes (a test checks).

Observers that read the simulators (the 3-D rollout recorder) ask for the copies they watch with
`observed(indices)`: `LocalEnvs` returns the copies themselves; `ProcessEnvs` returns shadow
copies in this process whose MuJoCo state (positions, velocities, mocap bodies, time) is set from
the worker's at every reset and step, and only for the watched copies.

A worker that dies or fails is a `RuntimeError` naming the copies it held; the run can then be
resumed from its last checkpoint.
"""

from __future__ import annotations

import itertools
import multiprocessing as mp
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from typing import Any, Protocol, runtime_checkable

import numpy as np

from curious.envs.goal_env import EnvSpec, GoalEnv

EnvFn = Callable[[], GoalEnv]
"""A picklable constructor of one environment copy."""

_PHYSICS_FIELDS = ("qpos", "qvel", "act", "mocap_pos", "mocap_quat")


@runtime_checkable
class EnvBatch(Protocol):
    """n environment copies stepped together (see the module docstring); `isinstance` tells
    one from a list of copies."""

    spec: EnvSpec
    reference: GoalEnv
    """A copy in this process for what does not step: goal slots, rewards, the spec."""

    def __len__(self) -> int: ...

    def reset(self, modules: np.ndarray, goals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Start an episode in the first len(modules) copies: (states, achieved)."""
        ...

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Step the first len(actions) copies: (states, achieved, per-module success)."""
        ...

    def set_sensor_failure(self, on: np.ndarray) -> None:
        """Switch the sensory failure of the first len(on) copies."""
        ...

    def observed(self, indices: Sequence[int]) -> list[Any]:
        """Copies an observer may read (synced from now on for `indices`; others None)."""
        ...

    def get_rng_states(self) -> list[Any]: ...

    def set_rng_states(self, states: Sequence[Any]) -> None: ...

    def close(self) -> None: ...


class LocalEnvs:
    """Copies stepped one after the other in this process."""

    def __init__(self, envs: Sequence[GoalEnv]) -> None:
        self.envs = list(envs)
        self.reference = self.envs[0]
        self.spec = self.reference.spec
        if any(env.spec != self.spec for env in self.envs):
            raise ValueError("all environment copies must share one EnvSpec")

    def __len__(self) -> int:
        return len(self.envs)

    def reset(self, modules: np.ndarray, goals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        obs = [env.reset(int(m), g) for env, m, g in zip(self.envs, modules, goals, strict=False)]
        return np.stack([o.state for o in obs]), np.stack([o.achieved for o in obs])

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        out = [env.step(a) for env, a in zip(self.envs, actions, strict=False)]
        states = np.stack([o.state for o, _ in out])
        return states, np.stack([o.achieved for o, _ in out]), np.stack([s for _, s in out])

    def set_sensor_failure(self, on: np.ndarray) -> None:
        for env, flag in zip(self.envs, on, strict=False):
            env.set_sensor_failure(bool(flag))

    def observed(self, indices: Sequence[int]) -> list[Any]:
        return list(self.envs)

    def get_rng_states(self) -> list[Any]:
        return [env.get_rng_state() for env in self.envs]

    def set_rng_states(self, states: Sequence[Any]) -> None:
        for env, state in zip(self.envs, states, strict=True):
            env.set_rng_state(state)

    def close(self) -> None:
        """Nothing to release."""


# ----------------------------------------------------------------------------------------------
def _physics_state(env: Any) -> tuple[np.ndarray, ...]:
    data = env.dm_env.physics.data
    return (np.array(data.time), *(np.array(getattr(data, f)) for f in _PHYSICS_FIELDS))


def _worker(conn: Connection, env_fns: list[EnvFn]) -> None:
    """A worker process: builds its copies, then answers commands until told to close."""
    try:
        envs = [fn() for fn in env_fns]
        conn.send(("ok", None))
    except BaseException:  # everything goes back to the trainer, named
        conn.send(("error", traceback.format_exc()))
        return
    while True:
        try:
            command, args = conn.recv()
        except (EOFError, KeyboardInterrupt):
            return
        try:
            if command == "close":
                conn.send(("ok", None))
                return
            if command == "reset":
                modules, goals, watched = args
                obs = [
                    envs[i].reset(int(m), g)
                    for i, (m, g) in enumerate(zip(modules, goals, strict=True))
                ]
                result: Any = (
                    np.stack([o.state for o in obs]),
                    np.stack([o.achieved for o in obs]),
                    [_physics_state(envs[i]) for i in watched],
                )
            elif command == "step":
                actions, watched = args
                out = [envs[i].step(a) for i, a in enumerate(actions)]
                result = (
                    np.stack([o.state for o, _ in out]),
                    np.stack([o.achieved for o, _ in out]),
                    np.stack([s for _, s in out]),
                    [_physics_state(envs[i]) for i in watched],
                )
            elif command == "failure":
                for env, flag in zip(envs, args, strict=False):
                    env.set_sensor_failure(bool(flag))
                result = None
            elif command == "get_rng":
                result = [env.get_rng_state() for env in envs]
            elif command == "set_rng":
                for env, state in zip(envs, args, strict=True):
                    env.set_rng_state(state)
                result = None
            else:
                raise ValueError(f"unknown command {command!r}")
            conn.send(("ok", result))
        except BaseException:  # the trainer raises it, naming the copies
            conn.send(("error", traceback.format_exc()))


class ProcessEnvs:
    """Copies stepped in worker processes (see the module docstring)."""

    def __init__(self, env_fns: Sequence[EnvFn], processes: int) -> None:
        if not 1 <= processes <= len(env_fns):
            raise ValueError(f"processes must be in 1..{len(env_fns)}, got {processes}")
        self.env_fns = list(env_fns)
        self.reference = self.env_fns[0]()  # spec, and the copy shadows are made like
        self.spec = self.reference.spec
        bounds = np.linspace(0, len(env_fns), processes + 1).round().astype(int)
        self.shares = [range(int(a), int(b)) for a, b in itertools.pairwise(bounds)]
        context = mp.get_context("spawn")  # no torch or MuJoCo state inherited by a fork
        self._conns: list[Connection] = []
        self._procs: list[Any] = []
        for share in self.shares:
            parent, child = context.Pipe()
            proc = context.Process(
                target=_worker, args=(child, [self.env_fns[i] for i in share]), daemon=True
            )
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)
        self._shadows: dict[int, Any] = {}
        self._watched: list[int] = []
        self._closed = False
        self._gather(range(len(self.shares)))  # every copy built, or a clear error

    def __len__(self) -> int:
        return len(self.env_fns)

    # -- talking to the workers ----------------------------------------------------------------
    def _send(self, w: int, command: str, args: Any = None) -> None:
        try:
            self._conns[w].send((command, args))
        except (BrokenPipeError, OSError):
            self._fail(w, "is gone")

    def _receive(self, w: int) -> Any:
        try:
            status, payload = self._conns[w].recv()
        except (EOFError, OSError):
            self._procs[w].join(timeout=1)
            self._fail(w, f"died (exit code {self._procs[w].exitcode})")
        if status == "error":
            self._fail(w, f"failed:\n{payload}")
        return payload

    def _gather(self, workers: Sequence[int]) -> list[Any]:
        return [self._receive(w) for w in workers]

    def _fail(self, w: int, what: str) -> None:
        share = self.shares[w]
        self.close()
        raise RuntimeError(
            f"environment worker {w} (copies {share.start}..{share.stop - 1}) {what}; the run "
            "can be resumed from its last checkpoint with --resume"
        )

    def _split(self, n: int) -> list[tuple[int, range]]:
        """(worker, the copies among the first n it holds) for every worker with some."""
        out = []
        for w, share in enumerate(self.shares):
            part = range(share.start, min(share.stop, n))
            if len(part):
                out.append((w, part))
        return out

    def _local(self, part: range) -> list[int]:
        return [i - part.start for i in self._watched if i in part]

    def _sync(self, part: range, states: list[tuple[np.ndarray, ...]]) -> None:
        for i, state in zip([i for i in self._watched if i in part], states, strict=True):
            physics = self._shadows[i].dm_env.physics
            data = physics.data
            data.time = float(state[0])
            for name, value in zip(_PHYSICS_FIELDS, state[1:], strict=True):
                getattr(data, name)[...] = value
            physics.forward()

    # -- EnvBatch --------------------------------------------------------------------------------
    def reset(self, modules: np.ndarray, goals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        parts = self._split(len(modules))
        for w, part in parts:
            share = slice(part.start, part.stop)
            self._send(w, "reset", (modules[share], goals[share], self._local(part)))
        for i in self._watched:  # the shadows get the same task and goal
            if i < len(modules):
                self._shadows[i].reset(int(modules[i]), goals[i])
        states, achieved = [], []
        for (_, part), (s, a, phys) in zip(parts, self._gather([w for w, _ in parts]), strict=True):
            states.append(s)
            achieved.append(a)
            self._sync(part, phys)
        return np.concatenate(states), np.concatenate(achieved)

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        parts = self._split(len(actions))
        for w, part in parts:
            self._send(w, "step", (actions[part.start : part.stop], self._local(part)))
        states, achieved, success = [], [], []
        for (_, part), (s, a, ok, phys) in zip(
            parts, self._gather([w for w, _ in parts]), strict=True
        ):
            states.append(s)
            achieved.append(a)
            success.append(ok)
            self._sync(part, phys)
        return np.concatenate(states), np.concatenate(achieved), np.concatenate(success)

    def set_sensor_failure(self, on: np.ndarray) -> None:
        parts = self._split(len(on))
        for w, part in parts:
            self._send(w, "failure", np.asarray(on[part.start : part.stop]))
        self._gather([w for w, _ in parts])

    def observed(self, indices: Sequence[int]) -> list[Any]:
        self._watched = sorted(int(i) for i in indices)
        for i in self._watched:
            if i not in self._shadows:
                self._shadows[i] = self.env_fns[i]()
        return [self._shadows.get(i) if i in self._watched else None for i in range(len(self))]

    def get_rng_states(self) -> list[Any]:
        for w in range(len(self.shares)):
            self._send(w, "get_rng")
        return [state for states in self._gather(range(len(self.shares))) for state in states]

    def set_rng_states(self, states: Sequence[Any]) -> None:
        if len(states) != len(self):
            raise ValueError(f"{len(states)} random states for {len(self)} copies")
        for w, share in enumerate(self.shares):
            self._send(w, "set_rng", list(states[share.start : share.stop]))
        self._gather(range(len(self.shares)))

    def close(self) -> None:
        """Stop the workers (also when one failed)."""
        if self._closed:
            return
        self._closed = True
        for conn, proc in zip(self._conns, self._procs, strict=True):
            try:
                conn.send(("close", None))
            except (BrokenPipeError, OSError):
                pass
            proc.join(timeout=5)
            if proc.is_alive():
                proc.kill()
                proc.join()
            conn.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # interpreter shutdown
            pass
