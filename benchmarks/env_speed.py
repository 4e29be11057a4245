"""`curious bench env`: env steps per second of our suite, its physics bound, and the peer.

All three run side by side in one process, interleaved episode by episode (so that load from
other processes on the machine hits them alike), each with a reset every 50 steps and uniform
random actions in [-1, 1]^4:

- ours: `suite.load(variant)` through the dm_env interface (`reset`, `step`), observations,
  rewards, distractor walk and all.
- bound: the same compiled MuJoCo model stepped with `mj_step(model, data, nstep=20)` per env
  step and nothing else. To step the same physics as ours, each bound episode starts from the
  state one of our episodes started from and replays the mocap and finger controls that episode
  produced (recorded in an untimed pass; writing them costs two small array copies per step).
  `bound_static` in the detail is the same model with the arm standing still.
- peer: gymnasium-robotics' FetchPickAndPlace (one block), stepped through its own `step` and
  `reset` without gymnasium's wrappers. gymnasium-robotics 1.4.2 does not run on mujoco 3.17
  as shipped (a joint-type check compares numpy ints with tuples of mujoco enums, which no longer
  matches); the shim below hands its utility module plain integers for the joint types.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import platform
import time
import warnings

import mujoco
import numpy as np

from benchmarks import AtLeast

EPISODE = 50
_STATE = mujoco.mjtState.mjSTATE_INTEGRATION


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--episodes",
        type=AtLeast(1),
        default=30,
        help="timed episodes per contestant (default 30)",
    )
    parser.add_argument("--variant", default="default", help="suite variant (default: default)")
    parser.add_argument(
        "--seed", type=AtLeast(0), default=0, help="seed of the environments and actions (0)"
    )
    parser.add_argument("--no-peer", action="store_true", help="skip gymnasium-robotics")


class _JointTypes:
    """mjtJoint values as plain ints, for gymnasium-robotics' joint-type checks."""

    mjJNT_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
    mjJNT_BALL = int(mujoco.mjtJoint.mjJNT_BALL)
    mjJNT_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)
    mjJNT_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)


class _MujocoWithIntJointTypes:
    """The mujoco module, except that `mjtJoint` members are ints."""

    mjtJoint = _JointTypes

    def __getattr__(self, name: str):
        return getattr(mujoco, name)


def make_peer():
    """gymnasium-robotics' MujocoFetchPickAndPlaceEnv, shimmed to run on mujoco 3.17."""
    sink = io.StringIO()
    with (
        contextlib.redirect_stdout(sink),
        contextlib.redirect_stderr(sink),
        warnings.catch_warnings(),
    ):
        warnings.simplefilter("ignore")
        from gymnasium_robotics.envs.fetch.pick_and_place import MujocoFetchPickAndPlaceEnv
        from gymnasium_robotics.utils import mujoco_utils

    mujoco_utils.mujoco = _MujocoWithIntJointTypes()
    return MujocoFetchPickAndPlaceEnv()


class _Ours:
    def __init__(self, variant: str, seed: int) -> None:
        import suite

        self.env = suite.load(variant, seed=seed)
        self.env.reset()
        physics = self.env.physics
        self.model, self.data = physics.model.ptr, physics.data.ptr

    def episode(self, actions: np.ndarray) -> float:
        env = self.env
        start = time.perf_counter()
        env.reset()
        for a in actions:
            env.step(a)
        return time.perf_counter() - start

    def record(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Run an episode untimed; return its start state and per-step mocap/finger controls."""
        env, d = self.env, self.data
        env.reset()
        state = np.empty(mujoco.mj_stateSize(self.model, _STATE))
        mujoco.mj_getState(self.model, d, state, _STATE)
        mocap = np.empty((len(actions), *d.mocap_pos.shape))
        ctrl = np.empty((len(actions), *d.ctrl.shape))
        for i, a in enumerate(actions):
            env.step(a)
            # The step wrote this step's controls before stepping; they are still in place.
            mocap[i] = d.mocap_pos
            ctrl[i] = d.ctrl
        return state, mocap, ctrl


def _bound_episode(model, data, state, mocap, ctrl, substeps: int) -> float:
    mujoco.mj_setState(model, data, state, _STATE)
    mujoco.mj_forward(model, data)
    mocap_pos, data_ctrl = data.mocap_pos, data.ctrl
    start = time.perf_counter()
    for i in range(len(mocap)):
        mocap_pos[:] = mocap[i]
        data_ctrl[:] = ctrl[i]
        mujoco.mj_step(model, data, substeps)
    return time.perf_counter() - start


def _bound_static_episode(model, data, state, steps: int, substeps: int) -> float:
    mujoco.mj_setState(model, data, state, _STATE)
    mujoco.mj_forward(model, data)
    start = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data, substeps)
    return time.perf_counter() - start


def _peer_episode(peer, actions: np.ndarray) -> float:
    start = time.perf_counter()
    peer.reset()
    for a in actions:
        peer.step(a)
    return time.perf_counter() - start


def measure(args: argparse.Namespace) -> dict:
    """Interleave ours, the bound and the peer episode by episode; report steps per second.

    Each round records one of our episodes (untimed), replays it timed through our env (same
    start, same actions, hence the same trajectory), then steps the bound through exactly that
    physics, then runs the peer on the same actions. Rates come from the median episode time of
    each contestant, which shrugs off bursts of load from other processes; means are in the
    detail.
    """
    from suite import layout

    episodes = int(getattr(args, "episodes", 30))
    variant = getattr(args, "variant", "default")
    seed = int(getattr(args, "seed", 0))
    with_peer = not getattr(args, "no_peer", False)
    if episodes < 1:
        raise ValueError(f"--episodes must be at least 1, got {episodes}")

    wall = time.perf_counter()
    ours = _Ours(variant, seed)
    peer = make_peer() if with_peer else None
    if peer is not None:
        peer.reset(seed=seed)
    rng = np.random.default_rng(seed)
    substeps = layout.SUBSTEPS
    times: dict[str, list[float]] = {"ours": [], "bound": [], "bound_static": [], "peer": []}

    # One untimed round to warm caches and code paths.
    warm = rng.uniform(-1.0, 1.0, size=(EPISODE, 4))
    ours.episode(warm)
    if peer is not None:
        _peer_episode(peer, warm.astype(np.float32))

    for _ in range(episodes):
        actions = rng.uniform(-1.0, 1.0, size=(EPISODE, 4))
        rng_state = ours.env.random_state.get_state()
        state, mocap, ctrl = ours.record(actions)
        ours.env.random_state.set_state(rng_state)
        times["ours"].append(ours.episode(actions))
        times["bound"].append(_bound_episode(ours.model, ours.data, state, mocap, ctrl, substeps))
        times["bound_static"].append(
            _bound_static_episode(ours.model, ours.data, state, EPISODE, substeps)
        )
        if peer is not None:
            times["peer"].append(_peer_episode(peer, actions.astype(np.float32)))

    nan = float("nan")
    median = {k: EPISODE / float(np.median(v)) if v else nan for k, v in times.items()}
    mean = {k: EPISODE / float(np.mean(v)) if v else nan for k, v in times.items()}
    return {
        "ours": median["ours"],
        "bound": median["bound"],
        "peer": median["peer"],
        "unit": "env steps/s",
        "ours_pct_of_bound": 100.0 * median["ours"] / median["bound"],
        "ours_pct_of_peer": 100.0 * median["ours"] / median["peer"],
        "bound_static": median["bound_static"],
        "mean_ours": mean["ours"],
        "mean_bound": mean["bound"],
        "mean_peer": mean["peer"],
        "variant": variant,
        "episodes": episodes,
        "steps_per_episode": EPISODE,
        "substeps": substeps,
        "peer_name": "gymnasium-robotics MujocoFetchPickAndPlaceEnv (1 block), unwrapped",
        "mujoco": mujoco.__version__,
        "cpus": os.cpu_count(),
        "machine": platform.machine(),
        "wall_s": time.perf_counter() - wall,
    }
