"""`curious bench recording`: what the Rerun recording costs a training run, in time and bytes.

The same short training run on the suite (a preset cut to `--episodes`, one torch thread) is
timed with and without its recording, in interleaved rounds (the order alternates from round to
round, after an untimed warm-up of each), so that both meet the same share of a shared
machine's load. A run with recording is what `curious train` does: the `RunRecorder` gets every
cycle's scalars, the rollout observer captures every K-th evaluation episode in 3D, and the file
is compacted when it closes.

* ours: the overhead in percent, from the fastest run of each kind;
* bound: 0 (a run that records nothing);
* peer: seconds of the fastest run without recording.

The file size is reported as is and per 1,000 episodes; the latter leaves out the fixed part
(the scene's meshes and the layout, logged once per run), measured on its own.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks import AtLeast
from curious.presets import resolve
from curious.runs.folder import RunFolder


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from curious.watching.recording.settings import RecorderSettings

    parser.add_argument("--preset", default="quick", help="preset of the timed run (quick)")
    parser.add_argument("--episodes", type=AtLeast(1), default=200, help="episodes per run (200)")
    parser.add_argument("--rounds", type=AtLeast(1), default=3, help="interleaved rounds (3)")
    parser.add_argument(
        "--rollout-every",
        type=AtLeast(0),
        default=None,
        metavar="K",
        help="3-D rollout every K evaluation episodes, 0 for none (default: the recorder's, "
        f"{RecorderSettings.rollout_every})",
    )
    parser.add_argument("--threads", type=AtLeast(1), default=1, help="torch threads (1)")


def _settings(args: argparse.Namespace) -> Any:
    from curious.watching.recording.settings import RecorderSettings

    if args.rollout_every is None:
        return RecorderSettings()
    return RecorderSettings(rollout_every=args.rollout_every)


def _timed_run(config: Any, out: Path, record: bool, settings: Any) -> float:
    """Seconds of one `train()` call (environments built inside, as in `curious train`)."""
    from curious.runs.driver import train
    from curious.watching.recording.recorder import RunRecorder
    from curious.watching.recording.rollout_capture import attach_rollout_recording

    def make_recorder(trainer: Any, folder: Any) -> RunRecorder:
        recorder = RunRecorder(folder.path, trainer.spec.module_names, settings=settings)
        if settings.rollout_every > 0:
            attach_rollout_recording(trainer, recorder)
        return recorder

    tic = time.perf_counter()
    train(config, out, make_recorder=make_recorder if record else None)
    return time.perf_counter() - tic


def _fixed_bytes(variant: str, settings: Any, folder: Path) -> int:
    """Size of a recording that holds only the scene's geometry and the layout."""
    from curious.envs.goal_env import SuiteEnv
    from curious.watching.recording.recorder import RunRecorder
    from curious.watching.recording.scene import RolloutCapture

    env = SuiteEnv(variant)
    capture = RolloutCapture(env.dm_env.physics.model.ptr, 1)
    with RunRecorder(folder, env.spec.module_names, settings=settings) as recorder:
        recorder.log_scene(capture)
    return recorder.path.stat().st_size


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """Times the run with and without recording; returns ours/bound/peer/unit and detail."""
    os.environ.setdefault("MUJOCO_GL", "disable")
    config = resolve(
        args.preset,
        "curious",
        0,
        {"total_episodes": args.episodes, "progress": False, "torch_threads": args.threads},
    )
    settings = _settings(args)
    times: dict[bool, list[float]] = {False: [], True: []}
    sizes: list[int] = []
    with tempfile.TemporaryDirectory(prefix="curious-bench-recording-") as tmp:
        root = Path(tmp)
        # Untimed warm-up of both kinds (imports, first MuJoCo compile, Rerun's threads).
        first_round = config.n_workers * config.episodes_per_worker
        warm = dataclasses.replace(config, total_episodes=first_round)
        for record in (False, True):
            _timed_run(warm, root / f"warm-{record}", record, settings)
        for r in range(args.rounds):
            order = (False, True) if r % 2 == 0 else (True, False)
            for record in order:
                out = root / f"round{r}-{'rec' if record else 'plain'}"
                times[record].append(_timed_run(config, out, record, settings))
                if record:
                    sizes.append(RunFolder(out).recording_path.stat().st_size)
        fixed = _fixed_bytes(config.variant, settings, root / "scene-only")
    plain, recorded = min(times[False]), min(times[True])
    paired = [100.0 * (w / o - 1.0) for o, w in zip(times[False], times[True], strict=True)]
    size = statistics.median(sizes)
    return {
        "ours": 100.0 * (recorded / plain - 1.0),
        "bound": 0.0,
        "peer": plain,
        "unit": "% overhead of recording (peer: seconds without)",
        "seconds_with_recording": recorded,
        "overhead_pct_median_of_pairs": statistics.median(paired),
        "episodes": args.episodes,
        "preset": args.preset,
        "rollout_every": settings.rollout_every,
        "eval_every": config.eval_every,
        "rrd_mb": size / 1e6,
        "rrd_fixed_mb": fixed / 1e6,
        "rrd_mb_per_1000_episodes": (size - fixed) / 1e6 * 1000.0 / args.episodes,
        "seconds_plain_all": [round(t, 2) for t in times[False]],
        "seconds_recorded_all": [round(t, 2) for t in times[True]],
    }


if __name__ == "__main__":
    import json

    cli = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_arguments(cli)
    print(json.dumps(measure(cli.parse_args()), indent=1))
