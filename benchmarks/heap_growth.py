"""`curious bench heap`: the memory a training process holds that it has already freed.

The same run (a preset cut to `--episodes` from scratch, with its recording, as `curious train`
writes it) is trained in a fresh process each way, in interleaved rounds:

* ours: as `curious train` runs it, freed memory given back (`curious.runs.allocator`: glibc's
  mmap threshold fixed, mimalloc's freed pages purged at once);
* peer: the allocators' defaults (glibc's mmap threshold rising with the blocks freed,
  `MIMALLOC_PURGE_DELAY=10`);
* bound: what glibc's heap held in use at the run's end (ours), in MB: a heap with no free
  space in it (counted as allocated, some of it perhaps never touched).

Speed is measured apart, in one process, so that both meet the same load: one trainer of the
preset (no test rollouts) runs two cycles a block with glibc's threshold fixed at 128 KiB (ours)
and at its ceiling of 32 MiB (the peer's threshold once large blocks were freed), the blocks
alternating for `--speed-rounds` rounds after two untimed cycles: `episodes_per_s_*`.

Sampled every half second, page by page (`benchmarks.anonymous_memory`, /proc/self/smaps):
the peak of the process's anonymous memory and of glibc's heap (`[heap]`), in MB, and at the
end what the heap held in use and free (`mallinfo2`, glibc 2.33 and later), and episodes per
second over each whole run (start-up included, the runs one after the other).
"""

from __future__ import annotations

import argparse
import ctypes
import os
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from benchmarks import AtLeast, anonymous_memory, in_fresh_process
from curious.runs.allocator import MIMALLOC_PURGE_DELAY
from curious.runs.folder_lock import check_writable

GLIBC_MMAP_CEILING = 32 * 2**20
"""The highest glibc's threshold rises to by itself (64-bit), the peer's in the speed measure."""
PEER_PURGE_DELAY = "10"
"""mimalloc's default purge delay (ms), which the peer keeps."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", default="laptop", help="preset of the run (laptop)")
    parser.add_argument(
        "--episodes",
        type=AtLeast(1),
        default=800,
        help="episodes per run (800: one checkpoint interval of laptop)",
    )
    parser.add_argument("--rounds", type=AtLeast(1), default=1, help="interleaved rounds (1)")
    parser.add_argument(
        "--speed-rounds",
        type=AtLeast(1),
        default=4,
        help="rounds of the speed measure, two cycles a block each way (4)",
    )
    parser.add_argument("--dir", default=None, help="where the runs are written (a temporary)")


class _MallInfo2(ctypes.Structure):
    _fields_ = [
        (name, ctypes.c_size_t)
        for name in (
            "arena",
            "ordblks",
            "smblks",
            "hblks",
            "hblkhd",
            "usmblks",
            "fsmblks",
            "uordblks",
            "fordblks",
            "keepcost",
        )
    ]


def _glibc_heap() -> tuple[float, float]:
    """Bytes glibc's main heap holds in use and free (NaN, NaN where mallinfo2 is missing)."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallinfo2.restype = _MallInfo2
    except (OSError, AttributeError):
        return float("nan"), float("nan")
    info = libc.mallinfo2()
    return float(info.uordblks), float(info.fordblks)


def _train(kind: str, folder: str, preset: str, episodes: int) -> dict[str, Any]:
    """In a fresh process: train the run, `kind` ours or peer; peaks and end state in bytes."""
    from curious.cli import main
    from curious.runs import driver

    if kind == "peer":
        driver.return_freed_memory = lambda: False  # glibc's threshold left to rise
    peaks = [0, 0]
    done = threading.Event()

    def sample() -> None:
        while not done.wait(0.5):
            total, heap = anonymous_memory()
            peaks[0], peaks[1] = max(peaks[0], total), max(peaks[1], heap)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    tic = time.perf_counter()
    args = ["train", "--out", folder, "--preset", preset, "--no-progress"]
    code = main([*args, "--set", f"total_episodes={episodes}"])
    seconds = time.perf_counter() - tic
    done.set()
    sampler.join()
    if code != 0:
        raise RuntimeError(f"curious train exited {code}")
    in_use, free = _glibc_heap()
    return {
        "peak_anonymous": float(peaks[0]),
        "peak_heap": float(peaks[1]),
        "heap_in_use": in_use,
        "heap_free": free,
        "episodes_per_s": episodes / seconds,
        "purge_delay": os.environ.get("MIMALLOC_PURGE_DELAY"),
    }


def _speed(preset: str, rounds: int) -> dict[str, float]:
    """In a fresh process: episodes/s of one trainer's cycles, with glibc's threshold fixed at
    128 KiB and at 32 MiB, in alternating blocks of two cycles."""
    import dataclasses

    from benchmarks.cycle_speed import _trainer
    from curious.presets import resolve
    from curious.runs.allocator import GLIBC_MMAP_THRESHOLD, mmap_threshold

    config = resolve(preset, overrides=dict(progress=False, test_rollouts_per_worker=0))
    cycles = 2 + 4 * rounds  # the untimed two, then two a block each way
    total = max(config.total_episodes, (cycles + 1) * config.episodes_per_cycle)
    trainer = _trainer(dataclasses.replace(config, total_episodes=total))
    thresholds = {"ours": GLIBC_MMAP_THRESHOLD, "peer": GLIBC_MMAP_CEILING}
    seconds, episodes = dict.fromkeys(thresholds, 0.0), dict.fromkeys(thresholds, 0)
    try:
        for _ in range(2):
            trainer.cycle()
        for r in range(rounds):
            for kind in ["ours", "peer"] if r % 2 == 0 else ["peer", "ours"]:
                mmap_threshold(thresholds[kind])
                for _ in range(2):
                    tic = time.perf_counter()
                    result = trainer.cycle()
                    seconds[kind] += time.perf_counter() - tic
                    episodes[kind] += len(result.rows["episode"])
    finally:
        trainer.close()
    return {kind: episodes[kind] / seconds[kind] for kind in thresholds}


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """Trains the run both ways, `--rounds` times each; returns ours/bound/peer/unit (the
    heap's peak, MB) and the rest of what each held, least of the rounds."""
    if args.dir is not None:
        check_writable(args.dir, "--dir", folder=True)
        Path(args.dir).mkdir(parents=True, exist_ok=True)
    results: dict[str, list[dict[str, Any]]] = {"ours": [], "peer": []}
    before = os.environ.get("MIMALLOC_PURGE_DELAY")
    with tempfile.TemporaryDirectory(prefix="curious-bench-heap-", dir=args.dir) as tmp:
        for r in range(args.rounds):
            for kind in ["ours", "peer"] if r % 2 == 0 else ["peer", "ours"]:
                # read by the child's allocator as Rerun loads, so set before it starts
                delay = PEER_PURGE_DELAY if kind == "peer" else MIMALLOC_PURGE_DELAY
                os.environ["MIMALLOC_PURGE_DELAY"] = delay
                try:
                    task = (kind, f"{tmp}/{kind}-{r}", args.preset, args.episodes)
                    results[kind].append(in_fresh_process(_train, *task))
                finally:
                    if before is None:
                        os.environ.pop("MIMALLOC_PURGE_DELAY", None)
                    else:
                        os.environ["MIMALLOC_PURGE_DELAY"] = before
        speed = in_fresh_process(_speed, args.preset, args.speed_rounds)
    mb = 1e6

    def least(kind: str, key: str) -> float:
        return min(row[key] for row in results[kind]) / mb

    def most(kind: str, key: str) -> float:
        return max(row[key] for row in results[kind])

    return {
        "ours": least("ours", "peak_heap"),
        "bound": least("ours", "heap_in_use"),
        "peer": least("peer", "peak_heap"),
        "unit": "MB of glibc's heap at the run's peak (least of the rounds)",
        "preset": args.preset,
        "episodes": args.episodes,
        "peak_anonymous_ours_mb": least("ours", "peak_anonymous"),
        "peak_anonymous_peer_mb": least("peer", "peak_anonymous"),
        "heap_in_use_peer_mb": least("peer", "heap_in_use"),
        "heap_free_ours_mb": least("ours", "heap_free"),
        "heap_free_peer_mb": least("peer", "heap_free"),
        "episodes_per_s_ours": speed["ours"],
        "episodes_per_s_peer": speed["peer"],
        "whole_run_episodes_per_s_ours": most("ours", "episodes_per_s"),
        "whole_run_episodes_per_s_peer": most("peer", "episodes_per_s"),
        "purge_delay_ours": results["ours"][0]["purge_delay"],
        "purge_delay_peer": results["peer"][0]["purge_delay"],
    }


if __name__ == "__main__":
    import json

    cli = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_arguments(cli)
    print(json.dumps(measure(cli.parse_args()), indent=1))
