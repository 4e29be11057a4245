"""The fingerprint of a tree's training: what a set of smoke runs produce, hashed.

A change that should change no episode (a reorganisation, a faster path) is checked by running
this on the commit before it and after it: the two prints must be equal, line for line.

    python tools/fingerprint.py                      # this checkout
    python tools/fingerprint.py --tree ../other-tree # another checkout of the project

Each case trains one `smoke` run with `curious train` (from `--tree`'s code, one torch thread),
then hashes what it wrote: `metrics.parquet` and `tests.parquet` without their clock column
(`wall_time`), and the final checkpoint's state (networks, optimisers, normalisers, competence
queues, random streams: every tensor and array, not its timings) with its replay. The cases
cover every condition, both update backends, the sensory failure and a distractor variant.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import torch

CASES: dict[str, list[str]] = {
    "curious": ["--condition", "curious"],
    "curious-workspace": ["--condition", "curious", "--set", "learner_backend=workspace"],
    "m-uvfa": ["--condition", "m-uvfa"],
    "curious-lp": [
        "--condition", "curious", "--set", "total_episodes=96", "--set", "lp_window=2",
    ],
    "mg-te": ["--condition", "mg-te"],
    "mg-te-workspace": ["--condition", "mg-te", "--set", "learner_backend=workspace"],
    "her": ["--condition", "her"],
    "sensor-failure": [
        "--condition", "curious", "--variant", "sensor_failure",
        "--set", "sensor_failure_episode=12",
    ],
    "distractors-4": ["--condition", "m-uvfa", "--variant", "distractors_4"],
}  # fmt: skip
"""Name -> `curious train` options (besides the preset, the seed and the folder). In 24 smoke
episodes no module has two windows of self-evaluations, so no learning progress: CURIOUS plays
as M-UVFA; `curious-lp` runs long enough, with a short window, for p_LP to choose."""

LEFT_OUT = ("elapsed", "wall_time", "created", "resumed", "time", "torch_rng")
"""Keys of the checkpoint's state left out of the hash: clocks, and the state of torch's global
generator (`torch_rng`), which differs between two runs of one seed although every network,
replay and table is equal: nothing a run computes draws from it after the learners are built
(they draw from generators of their own)."""


def _hash_table(path: Path) -> str:
    if not path.exists():
        return "absent"
    table = pq.read_table(path)
    if "wall_time" in table.column_names:
        table = table.drop(["wall_time"])
    digest = hashlib.sha256()
    for name in table.column_names:
        digest.update(name.encode())
        column = table.column(name).to_numpy(zero_copy_only=False)
        digest.update(
            np.asarray(column).astype(str).tobytes()
            if column.dtype == object
            else np.ascontiguousarray(column).tobytes()
        )
    return digest.hexdigest()[:16]


def _feed(digest: hashlib._Hash, value: object, key: str = "") -> None:
    """Hash a nested state: tensors and arrays by their bytes, the rest by its repr."""
    if key in LEFT_OUT:
        return
    if isinstance(value, dict):
        for k in sorted(value, key=str):
            digest.update(str(k).encode())
            _feed(digest, value[k], str(k))
    elif isinstance(value, (list, tuple)):
        for item in value:
            _feed(digest, item)
    elif isinstance(value, torch.Tensor):
        digest.update(value.detach().cpu().contiguous().numpy().tobytes())
    elif isinstance(value, np.ndarray):
        digest.update(np.ascontiguousarray(value).tobytes())
    else:
        digest.update(repr(value).encode())


def _hash_checkpoint(run: Path) -> tuple[str, str]:
    """(state, replay) hashes of the run's newest checkpoint."""
    newest = sorted((run / "checkpoints").glob("ep-*"))[-1]
    state = torch.load(newest / "state.pt", map_location="cpu", weights_only=False)
    digest = hashlib.sha256()
    _feed(digest, {k: v for k, v in state.items() if k != "config"})
    replay = hashlib.sha256()
    for path in sorted([*newest.glob("*.npz"), *(run / "checkpoints" / "replay").glob("*.npz")]):
        with np.load(path) as arrays:
            for name in sorted(arrays.files):
                replay.update(name.encode())
                replay.update(np.ascontiguousarray(arrays[name]).tobytes())
    return digest.hexdigest()[:16], replay.hexdigest()[:16]


def fingerprint(tree: Path, case: str, folder: Path) -> dict[str, str]:
    """Train `case` from `tree`'s code into `folder`; the hashes of what it wrote."""
    env = {**os.environ, "PYTHONPATH": str(tree), "MUJOCO_GL": "disable"}
    command = [
        sys.executable, "-m", "curious.cli", "train", "--preset", "smoke", "--seed", "0",
        "--out", str(folder), "--no-progress", "--no-record", "--set", "torch_threads=1",
        *CASES[case],
    ]  # fmt: skip
    done = subprocess.run(command, cwd=tree, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{case}: curious train failed ({done.returncode}):\n{done.stderr}")
    state, replay = _hash_checkpoint(folder)
    return {
        "metrics": _hash_table(folder / "metrics.parquet"),
        "tests": _hash_table(folder / "tests.parquet"),
        "state": state,
        "replay": replay,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--tree", type=Path, default=Path(__file__).resolve().parents[1],
        help="the checkout whose code trains (default: this one)",
    )  # fmt: skip
    parser.add_argument(
        "--case", action="append", choices=list(CASES), help="only these cases (repeatable)"
    )
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.case or list(CASES):
            hashes = fingerprint(args.tree.resolve(), case, Path(tmp) / case)
            print(json.dumps({"case": case, **hashes}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
