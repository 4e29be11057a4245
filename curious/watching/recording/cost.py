"""What recording costs: seconds of logging per episode and per rollout, and the file's size.

Logs N synthetic episodes of scalars (in batches, as the training loop does once per cycle) and
M rollouts of a MuJoCo model (by default gymnasium-robotics' Fetch pick-and-place scene, which
the suite's arm resembles) through a `RunRecorder`, timing only the recorder's calls, then
closes the recording and reports its size.

    python -m curious.watching.recording.cost --episodes 20000 --rollouts 40 --out /tmp/rec-cost

The synthetic run looks like a real one where it matters for size: one evaluation episode in
`eval_every`, competence as the mean of each module's last `lp_window` evaluations (so it changes
only on that module's evaluations), LP and p_LP derived from it as in the paper (the run's
settings, `Config`).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

import mujoco
import numpy as np

from curious.agent.learning_progress import CompetenceTracker, lp_probabilities
from curious.config import Config
from curious.watching.recording.recorder import RecorderSettings, RunRecorder
from curious.watching.recording.scene import RolloutCapture
from suite import standard_modules

__all__ = ["fetch_model", "measure_logging_cost", "synthetic_episodes"]

# The paper's seven modules, named as the suite names them.
MODULES = tuple(module.name for module in standard_modules(3))
FETCH_GRIPPER = "robot0:gripper_link"


def fetch_model() -> mujoco.MjModel:
    """gymnasium-robotics' Fetch pick-and-place scene (MJCF and meshes ship with the package)."""
    import gymnasium_robotics

    path = Path(gymnasium_robotics.__file__).parent / "envs/assets/fetch/pick_and_place.xml"
    return mujoco.MjModel.from_xml_path(str(path))


def synthetic_episodes(
    n_episodes: int, n_modules: int, seed: int, window: int, eval_every: int, lp_eps: float
) -> dict[str, np.ndarray]:
    """Per-episode arrays shaped like `metrics.parquet`'s, from made-up learning curves.

    Module i's success probability rises along a logistic curve starting at a module-dependent
    episode (the last modules never rise, like distractors); every `eval_every`-th episode is an
    evaluation; competence, absolute LP and p_LP come from the agent's own
    `curious.agent.learning_progress` (last `window` results against the `window` before, p_LP with
    `lp_eps`).
    """
    rng = np.random.default_rng(seed)
    episodes = np.arange(n_episodes, dtype=np.int64)
    modules = rng.integers(0, n_modules, n_episodes)
    onset = np.linspace(0.1, 1.2, n_modules) * n_episodes
    p = 1.0 / (1.0 + np.exp(-(episodes[:, None] - onset[None]) / (0.05 * n_episodes + 1)))
    success = rng.random(n_episodes) < p[episodes, modules]
    is_eval = episodes % eval_every == 0
    # The agent's own bookkeeping, one evaluation at a time; row i + 1 holds the values after
    # the i-th evaluation, row 0 those before any. Each episode then reads the row of the last
    # evaluation at or before it.
    evals = np.flatnonzero(is_eval)
    after = np.zeros((3, len(evals) + 1, n_modules))
    after[2, 0] = 1.0 / n_modules
    tracker = CompetenceTracker(n_modules, window, "absolute")
    for i, e in enumerate(evals, start=1):
        tracker.add(int(modules[e]), bool(success[e]))
        after[0, i] = tracker.competence()
        after[1, i] = tracker.learning_progress()
        after[2, i] = lp_probabilities(after[1, i], lp_eps)
    competence, lp, p_lp = after[:, np.searchsorted(evals, episodes, side="right")]
    return {
        "episode": episodes,
        "module": modules,
        "success": success,
        "eval": is_eval,
        "competence": competence,
        "lp": lp,
        "p_lp": p_lp,
    }


def _scripted_rollout(
    model: mujoco.MjModel, data: mujoco.MjData, capture: RolloutCapture, steps: int, rng
) -> float:
    """Moves the Fetch mocap target along a random line; returns seconds spent in `record`."""
    mujoco.mj_resetData(model, data)
    mujoco.mj_forward(model, data)
    capture.reset()
    spent = 0.0
    t = time.perf_counter()
    capture.record(data)
    spent += time.perf_counter() - t
    direction = rng.uniform(-1, 1, 3) * 0.004
    for _ in range(steps):
        if model.nmocap:
            data.mocap_pos[0] += direction
        mujoco.mj_step(model, data, nstep=20)
        t = time.perf_counter()
        capture.record(data)
        spent += time.perf_counter() - t
    return spent


def measure_logging_cost(
    out_dir: str | Path,
    *,
    n_episodes: int = 20_000,
    batch: int = 38,
    n_rollouts: int = 40,
    episode_length: int = 50,
    settings: RecorderSettings | None = None,
    model: mujoco.MjModel | None = None,
    gripper_body: str | None = FETCH_GRIPPER,
    seed: int = 0,
) -> dict[str, float]:
    """Times a recorder on N synthetic episodes and M rollouts; returns seconds and bytes.

    Keys: `scalar_us_per_episode` (log_episodes + one log_replay and one log_learner per batch),
    `capture_us_per_step` (RolloutCapture.record), `rollout_ms` (log_rollout, scene geometry
    excluded), `scene_ms` (the one-off static geometry), `close_s` (flush + compaction),
    `cpu_s_all_threads` (CPU seconds of all the recording work, Rerun's threads included),
    `file_bytes`, and the inputs.
    """
    settings = settings or RecorderSettings()
    data_arrays = synthetic_episodes(
        n_episodes, len(MODULES), seed, Config.lp_window, Config.eval_every, Config.lp_eps
    )
    rng = np.random.default_rng(seed)
    model = model if model is not None else fetch_model()
    mj_data = mujoco.MjData(model)
    capture = RolloutCapture(model, episode_length + 1, gripper_body=gripper_body)

    out_dir = Path(out_dir)
    cpu0 = time.process_time()
    sim_s = 0.0
    recorder = RunRecorder(out_dir, MODULES, settings=settings, run_name="logging-cost")
    scalar_s = 0.0
    for start in range(0, n_episodes, batch):
        sl = slice(start, min(start + batch, n_episodes))
        ep = data_arrays["episode"][sl]
        t = time.perf_counter()
        recorder.log_episodes(
            ep,
            data_arrays["module"][sl],
            data_arrays["success"][sl],
            data_arrays["eval"][sl],
            data_arrays["competence"][sl],
            data_arrays["lp"][sl],
            data_arrays["p_lp"][sl],
            wall_time=ep * 0.25,
        )
        recorder.log_replay(ep[-1], data_arrays["p_lp"][sl][-1] * 256, wall_time=ep[-1] * 0.25)
        recorder.log_learner(
            ep[-1],
            losses={"critic": 0.1, "actor": 1.0},
            q={"mean": -5.0, "min": -20.0, "max": 0.0},
            wall_time=ep[-1] * 0.25,
        )
        scalar_s += time.perf_counter() - t

    t = time.perf_counter()
    recorder.log_scene(capture)
    scene_s = time.perf_counter() - t
    capture_s = 0.0
    rollout_s = 0.0
    eval_episodes = np.flatnonzero(data_arrays["eval"])
    for k in range(n_rollouts):
        t = time.perf_counter()
        capture_s += _scripted_rollout(model, mj_data, capture, episode_length, rng)
        sim_s += time.perf_counter() - t
        if len(eval_episodes):
            episode = int(eval_episodes[(k * len(eval_episodes)) // n_rollouts])
        else:
            episode = k * 10 * settings.rollout_every
        goal = mj_data.xpos[capture.gripper_id] if capture.gripper_id is not None else np.zeros(3)
        t = time.perf_counter()
        recorder.log_rollout(episode, k % len(MODULES), capture, goal=goal, success=bool(k % 2))
        rollout_s += time.perf_counter() - t

    t = time.perf_counter()
    recorder.close()
    close_s = time.perf_counter() - t
    # CPU of every thread (Rerun encodes and writes on its own threads), less the simulation,
    # which runs on this thread; an upper bound on what recording takes from training.
    cpu_s = time.process_time() - cpu0 - (sim_s - capture_s)
    return {
        "n_episodes": float(n_episodes),
        "batch": float(batch),
        "n_rollouts": float(n_rollouts),
        "scalar_us_per_episode": scalar_s / max(n_episodes, 1) * 1e6,
        "capture_us_per_step": capture_s / max(n_rollouts * (episode_length + 1), 1) * 1e6,
        "rollout_ms": rollout_s / max(n_rollouts, 1) * 1e3,
        "scene_ms": scene_s * 1e3,
        "close_s": close_s,
        "cpu_s_all_threads": cpu_s,
        "file_bytes": float(recorder.path.stat().st_size),
    }


def main(argv: list[str] | None = None) -> int:
    """Command-line entry: prints the measurement as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20_000)
    parser.add_argument("--batch", type=int, default=38, help="episodes per log_episodes call")
    parser.add_argument("--rollouts", type=int, default=40)
    parser.add_argument("--stride", type=int, default=1, help="rollout_stride setting")
    parser.add_argument("--every-episode", action="store_true", help="stats_on_change=False")
    parser.add_argument("--out", type=str, default=None, help="folder for the recording")
    args = parser.parse_args(argv)
    settings = RecorderSettings(rollout_stride=args.stride, stats_on_change=not args.every_episode)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.out) if args.out else Path(tmp)
        result = measure_logging_cost(
            out,
            n_episodes=args.episodes,
            batch=args.batch,
            n_rollouts=args.rollouts,
            settings=settings,
        )
    print(json.dumps({**result, "settings": asdict(settings)}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
