"""`curious bench resume`: the memory a resumed run takes to load its checkpoint's replay.

A replay of the suite's variant holding `--episodes` episodes (random values, the real shapes;
`checkpoint_cost._replay`) is checkpointed as a run writes it (a segment every `--every`
episodes, each checkpoint building on the one before), then loaded into a
fresh replay of that capacity as a resume loads it, each way in a process of its own (so that
the pages one touched do not count for the other), in interleaved rounds:

* ours: the segments read straight into the replay's own arrays (`checkpoint.load`'s `into`);
* peer: read into arrays of their own, copied into the replay, and those arrays kept, as a
  resume kept them for the rest of its run at the commits before 0f0f896;
* bound: the bytes of the replay's filled part, what a run holds once it is loaded.

Reported, in MB over what the process held before the load: the peak while loading (the
kernel's high-water mark of resident memory), what it holds once loaded (anonymous memory, the
peer's arrays let go, it holds what ours does: 0f0f896), and the peak of the allocations the
load made (`tracemalloc`: numpy reports its arrays to it). The high-water mark counts file pages
too, which the kernel may drop under memory pressure, from counters that it keeps per CPU and
reads approximately: on a machine of many CPUs it can be some MB off, and a small replay's
comparison then rests on the two exact ones (anonymous memory counted page by page,
`benchmarks.anonymous_memory`, and the allocations' peak).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks import anonymous_memory, checkpoint_cost, in_fresh_process
from benchmarks.checkpoint_cost import _prefix, _replay
from curious.runs.folder_lock import check_writable

add_arguments = checkpoint_cost.add_arguments
"""The checkpoint benchmark's options: `--episodes`, `--every` (a segment each), `--variant`,
`--rounds` and `--dir` mean the same here."""


def _resident_bytes() -> int:
    """This process's resident memory now, as the high-water mark counts it (/proc/self/statm)."""
    with open("/proc/self/statm") as handle:
        return int(handle.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def _reset_peak() -> bool:
    """Start this process's peak resident memory afresh from now (Linux 4.0 and later); False
    where the kernel refuses (some sandboxes), the peak then counting from the process's start."""
    try:
        with open("/proc/self/clear_refs", "w") as handle:
            handle.write("5")
    except OSError:
        return False
    return True


def _peak_bytes() -> int:
    """This process's peak resident memory (VmHWM, in kB) since `_reset_peak`."""
    with open("/proc/self/status") as handle:
        line = next(line for line in handle if line.startswith("VmHWM:"))
    return int(line.split()[1]) * 1024


def load_and_count(path: str, variant: str, capacity: int, into: bool) -> dict[str, Any]:
    """In a fresh process: load the checkpoint at `path` into a replay of `capacity` episodes,
    ours (`into`) or the peer's way; bytes added at the load's peak, held once loaded (the
    replay's arrays and what the load keeps), allocated at the load's allocations' peak, and
    seconds."""
    import gc
    import tracemalloc

    from curious.agent.replay import EpisodeReplay
    from curious.envs.goal_env import SuiteEnv
    from curious.runs import checkpoint
    from curious.runs.allocator import release_free_heap, return_freed_memory

    return_freed_memory()  # glibc's threshold fixed, as `curious.runs.driver.train` has it
    spec = SuiteEnv(variant).spec
    gc.collect()
    # The heap's free pages given back before the count starts: the replay's arrays and the
    # load's may be served from memory freed before, which, resident already, no count of what
    # they add would see (CI's peer once held 13 MB less than its two copies so).
    release_free_heap()
    before = anonymous_memory()[0]
    replay = EpisodeReplay(spec, capacity)
    tracemalloc.start()
    reset = _reset_peak()
    resident = _resident_bytes()
    tic = time.perf_counter()
    _, arrays = checkpoint.load(Path(path), into=replay.arrays() if into else None)
    replay.load_state_dict(arrays)
    seconds = time.perf_counter() - tic
    allocated = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    if into:
        del arrays  # the peer keeps its arrays, as the resume did
    gc.collect()
    return {
        "peak": float(_peak_bytes() - resident),
        "held": float(anonymous_memory()[0] - before),
        "allocated": float(allocated),
        "seconds": seconds,
        "reset": reset,
    }


def write_checkpoints(folder: Path, variant: str, episodes: int, every: int) -> tuple[Path, int]:
    """Checkpoints of a replay of `episodes` random episodes of `variant` into `folder`, as a run
    writes them (a segment every `every` episodes, each checkpoint building on the one before);
    the last one's path and the replay's bytes."""
    from curious.runs import checkpoint

    full = _replay(variant, episodes)
    path = None
    for end in [*range(every, episodes, every), episodes]:
        state = {"note": "the replay alone"}
        path = checkpoint.save(folder, end, state, _prefix(full, end), base=path)
    assert path is not None
    return path, sum(v.nbytes for v in full.values() if v.ndim > 0)


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """Loads the checkpoint both ways, `--rounds` times each; returns ours/bound/peer/unit (the
    load's peak, MB) and what each holds once loaded."""
    if args.dir is not None:
        check_writable(args.dir, "--dir", folder=True)
        Path(args.dir).mkdir(parents=True, exist_ok=True)
    results: dict[str, list[dict[str, Any]]] = {"ours": [], "peer": []}
    with tempfile.TemporaryDirectory(prefix="curious-bench-resume-", dir=args.dir) as tmp:
        path, replay_bytes = write_checkpoints(Path(tmp), args.variant, args.episodes, args.every)
        for r in range(args.rounds):
            for kind in ["ours", "peer"] if r % 2 == 0 else ["peer", "ours"]:
                task = (str(path), args.variant, args.episodes, kind == "ours")
                results[kind].append(in_fresh_process(load_and_count, *task))  # fresh each
    mb = 1e6

    def least(kind: str, key: str) -> float:
        return min(row[key] for row in results[kind]) / (mb if key != "seconds" else 1)

    return {
        "ours": least("ours", "peak"),
        "bound": replay_bytes / mb,
        "peer": least("peer", "peak"),
        "unit": "MB added at the load's peak (least of the rounds)",
        "episodes": args.episodes,
        "every": args.every,
        "variant": args.variant,
        "held_ours_mb": least("ours", "held"),
        "held_peer_mb": least("peer", "held"),
        "allocated_ours_mb": least("ours", "allocated"),
        "allocated_peer_mb": least("peer", "allocated"),
        "seconds_ours": least("ours", "seconds"),
        "seconds_peer": least("peer", "seconds"),
        "peak_ours_mb_all": [round(row["peak"] / mb, 1) for row in results["ours"]],
        "peak_peer_mb_all": [round(row["peak"] / mb, 1) for row in results["peer"]],
        # False: the kernel refused to reset the peak, which then counts the process's start-up
        "peak_reset": all(row["reset"] for rows in results.values() for row in rows),
    }


if __name__ == "__main__":
    import json

    cli = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_arguments(cli)
    print(json.dumps(measure(cli.parse_args()), indent=1))
