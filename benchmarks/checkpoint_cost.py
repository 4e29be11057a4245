"""`curious bench checkpoint`: what a checkpoint's replay costs, in seconds and in disk.

A replay of the suite's variant holding `--episodes` episodes (random values, the real shapes) is
checkpointed the way a run does it at that point: the checkpoint before it holds all but the
last `--every` episodes (one checkpoint interval), and the timed checkpoint adds those. Timed,
in interleaved rounds (the order alternates), each into a fresh folder and fsynced as
`curious.runs.checkpoint` writes it:

* ours: milliseconds of a checkpoint that writes only the episodes since the one before (segments);
* peer: milliseconds of one that rewrites the whole replay (`replay.npz`, what a replay that has
  evicted episodes gets, and what every checkpoint wrote at the commits before 447379f);
* bound: milliseconds to write and fsync the new episodes' bytes alone, as one raw file.

The disk that the two checkpoints a run keeps take is reported for both.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks import AtLeast
from curious.runs.folder_lock import check_writable


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--episodes", type=AtLeast(1), default=20_000, help="episodes in the replay (20,000)"
    )
    parser.add_argument(
        "--every",
        type=AtLeast(1),
        default=800,
        help="episodes since the checkpoint before (800: a `laptop` run's interval)",
    )
    parser.add_argument("--variant", default="default", help="the suite's variant (default)")
    parser.add_argument("--rounds", type=AtLeast(1), default=3, help="interleaved rounds (3)")
    parser.add_argument(
        "--dir",
        default=None,
        help="folder to write in, made if missing (default: a temporary one under TMPDIR)",
    )


def _replay(variant: str, episodes: int) -> dict[str, Any]:
    """A replay `state_dict` of `episodes` random episodes with the variant's shapes."""
    from curious.agent.replay import EpisodeReplay
    from curious.envs.goal_env import SuiteEnv

    spec = SuiteEnv(variant).spec
    replay = EpisodeReplay(spec, episodes)
    rng = np.random.default_rng(0)
    T, n = spec.episode_length, spec.n_modules
    for start in range(0, episodes, 1_000):
        e = min(1_000, episodes - start)
        replay.store(
            rng.standard_normal((e, T + 1, spec.state_dim), np.float32),
            rng.standard_normal((e, T + 1, spec.achieved_dim), np.float32),
            rng.uniform(-1, 1, (e, T, spec.action_dim)).astype(np.float32),
            rng.integers(n, size=e),
            rng.standard_normal((e, n, spec.goal_dim), np.float32),
        )
    return replay.state_dict()


def _prefix(replay: dict[str, Any], size: int) -> dict[str, Any]:
    out = {k: v[:size] for k, v in replay.items() if np.ndim(v) > 0}
    return {**out, "size": np.int64(size), "ptr": np.int64(size), "evicted": np.bool_(False)}


def _disk(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def _raw_write(path: Path, arrays: dict[str, Any]) -> float:
    tic = time.perf_counter()
    with open(path, "wb") as handle:
        for value in arrays.values():
            np.ascontiguousarray(value).tofile(handle)
        handle.flush()
        os.fsync(handle.fileno())
    return time.perf_counter() - tic


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """Times the three writes; returns ours/bound/peer/unit and the disk each kind keeps."""
    from curious.runs import checkpoint

    if args.dir is not None:
        check_writable(args.dir, "--dir", folder=True)
        Path(args.dir).mkdir(parents=True, exist_ok=True)
    if args.every > args.episodes:
        raise ValueError(f"--every ({args.every}) cannot exceed --episodes ({args.episodes})")
    full = _replay(args.variant, args.episodes)
    before = _prefix(full, args.episodes - args.every)
    after = _prefix(full, args.episodes)
    whole = {**after, "evicted": np.bool_(True)}  # written whole, as a replay that evicted
    new = {k: v[args.episodes - args.every :] for k, v in after.items() if np.ndim(v) > 0}
    state = {"note": "the replay alone is timed"}
    times: dict[str, list[float]] = {"ours": [], "peer": [], "bound": []}
    disk: dict[str, int] = {}
    with tempfile.TemporaryDirectory(prefix="curious-bench-checkpoint-", dir=args.dir) as tmp:
        root = Path(tmp)
        for r in range(args.rounds):
            order = ["ours", "peer", "bound"]
            if r % 2:
                order.reverse()
            for kind in order:
                folder = root / f"round{r}-{kind}"
                if kind == "bound":
                    folder.mkdir()
                    times[kind].append(_raw_write(folder / "new.bin", new))
                    continue
                replay_before = before if kind == "ours" else {**before, "evicted": np.True_}
                base = checkpoint.save(folder, 1, state, replay_before)
                tic = time.perf_counter()
                checkpoint.save(folder, 2, state, after if kind == "ours" else whole, base=base)
                times[kind].append(time.perf_counter() - tic)
                disk[kind] = _disk(folder)
            for kind in order:
                shutil.rmtree(root / f"round{r}-{kind}", ignore_errors=True)
    per_episode = sum(v.nbytes for v in new.values()) / args.every
    return {
        "ours": 1e3 * min(times["ours"]),
        "bound": 1e3 * min(times["bound"]),
        "peer": 1e3 * min(times["peer"]),
        "unit": "ms per checkpoint (fastest round)",
        "episodes": args.episodes,
        "every": args.every,
        "variant": args.variant,
        "replay_kb_per_episode": per_episode / 1e3,
        "ours_median_ms": 1e3 * statistics.median(times["ours"]),
        "peer_median_ms": 1e3 * statistics.median(times["peer"]),
        "disk_two_checkpoints_ours_mb": disk["ours"] / 1e6,
        "disk_two_checkpoints_peer_mb": disk["peer"] / 1e6,
        "seconds_ours_all": [round(t, 3) for t in times["ours"]],
        "seconds_peer_all": [round(t, 3) for t in times["peer"]],
        "seconds_bound_all": [round(t, 3) for t in times["bound"]],
    }


if __name__ == "__main__":
    import json

    cli = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_arguments(cli)
    print(json.dumps(measure(cli.parse_args()), indent=1))
