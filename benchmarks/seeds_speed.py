"""`curious bench seeds`: `--runs` runs trained side by side by one `curious train --seeds`
(ours: each seed in a process of its own, all at once) against as many `curious train --seed i`
processes started at once (peer), for the same episodes.

Both are what a user types, and both train each run in a process of its own: the benchmark
measures what `--seeds` costs or gains over processes started by hand, and, with `--peer-only`,
what runs side by side on a machine train together (on a GPU node: with and without NVIDIA's
MPS server, and each learner backend over many cycles, `tools/gpu_checks.sh`). Every run
trains `--cycles` cycles of the preset from scratch (no recording, no test rollouts, one torch
thread per run), into a temporary folder. The rate is read from the runs' own tables: each
run's episodes after its first cycle over the seconds they took (metrics.parquet's
`wall_time`), summed over the runs, so that imports and the first cycle's allocations count for
neither; `*_late` is the same rate over the second half of the cycles alone, which tells a
warm-up that outlasts the first cycle (a compiled learner's, say) from a steady rate, and
`*_cycle_s` each cycle's seconds from the second on (the median over the runs), which shows
where it ends; `*_command_s` is the wall time of the whole command, start-up included.

`bound` is the physics alone: one core stepping the suite's model for an episode's control
steps, times the machine's cores (`benchmarks.cycle_speed.physics_episodes_per_second`).
`--repeats` alternates the two that many times and reports the median of each; `--set` gives
every run a training setting (the learner's backend, say).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from benchmarks import AtLeast, check_device

if TYPE_CHECKING:
    from curious.config import Config


CONTENDERS = ("peer", "ours")
"""Processes started by hand, and one `curious train --seeds`."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", default="laptop", help="training preset (default laptop)")
    parser.add_argument(
        "--runs", type=AtLeast(1), default=None, help="runs each (default: one per core)"
    )
    parser.add_argument(
        "--condition", default="curious", help="the runs' condition (default curious)"
    )
    parser.add_argument(
        "--cycles",
        type=AtLeast(2, "the rate is read after each run's first cycle"),
        default=6,
        help="cycles per run (default 6)",
    )
    parser.add_argument(
        "--repeats", type=AtLeast(1), default=1, help="alternations of the two (default 1)"
    )
    parser.add_argument(
        "--device", default="cpu", choices=("cpu", "cuda"), help="where networks train"
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        dest="settings",
        help="a training setting for every run of every contender (`curious train --set`)",
    )
    parser.add_argument(
        "--peer-only",
        action="store_true",
        help="train the peer's processes alone (ours' keys are then null)",
    )


def _config(args: argparse.Namespace) -> Config:
    """The runs' config (seed 0): the preset, the condition and `--set`, checked before any run
    starts."""
    from curious.config import ConfigError
    from curious.overrides import parse_overrides
    from curious.presets import resolve

    overrides = parse_overrides(args.settings)
    taken = sorted(set(overrides) & set(BENCH_SETTINGS))
    if taken:
        raise ConfigError(f"--set {taken[0]}: {BENCH_SETTINGS[taken[0]]}")
    return resolve(args.preset, args.condition, 0, overrides)


BENCH_SETTINGS = {
    "total_episodes": "the benchmark sets it from --cycles",
    "torch_threads": "the benchmark gives every run one torch thread",
    "test_rollouts_per_worker": "the benchmark's runs take no test rollouts",
}
"""The settings every contender's runs get from the benchmark itself (`_train_command`)."""


def _train_command(args: argparse.Namespace, out: Path, seeds: str, flag: str) -> list[str]:
    episodes = args.cycles * _config(args).episodes_per_cycle
    return [
        sys.executable, "-m", "curious.cli", "train", "--preset", args.preset,
        "--condition", args.condition, flag, seeds, "--out", str(out), "--no-record",
        "--no-progress", "--set", f"total_episodes={episodes}", "--set", "torch_threads=1",
        "--set", "test_rollouts_per_worker=0", "--device", args.device,
        *(part for setting in args.settings for part in ("--set", setting)),
    ]  # fmt: skip


def _run_clock(folder: Path) -> tuple[np.ndarray, int]:
    """A run's `wall_time` per episode (metrics.parquet) and its episodes a cycle (config.json)."""
    import json

    import pyarrow.parquet as pq

    from curious.runs.folder_layout import CONFIG_FILE, METRICS_FILE

    wall = pq.read_table(folder / METRICS_FILE, columns=["wall_time"])["wall_time"]
    config = json.loads((folder / CONFIG_FILE).read_text())["config"]
    per_cycle = int(config["n_workers"]) * int(config["episodes_per_worker"])
    return np.asarray(wall.to_numpy(), dtype=float), per_cycle


def _steady_rate(folders: list[Path], after_cycles: int = 1) -> float:
    """Episodes/s of the runs together after each one's first `after_cycles` cycles, from their
    tables."""
    total = 0.0
    for folder in folders:
        wall, per_cycle = _run_clock(folder)
        skipped = after_cycles * per_cycle
        # the last episode of the cycles skipped, to the run's last
        total += (len(wall) - skipped) / (wall[-1] - wall[skipped - 1])
    return float(total)


def _cycle_seconds(folders: list[Path]) -> list[float]:
    """Each cycle's seconds from the second on, the median over the runs, from their tables
    (the first cycle's start is not in them)."""
    per_run = []
    for folder in folders:
        wall, per_cycle = _run_clock(folder)
        per_run.append(np.diff(wall[per_cycle - 1 :: per_cycle]))
    cycles = min(len(d) for d in per_run)
    return np.median(np.stack([d[:cycles] for d in per_run]), axis=0).round(3).tolist()


def _late_cycles(cycles: int) -> int:
    """The cycles `*_late` skips: the first half (at least the first cycle)."""
    return max(1, cycles // 2)


def _contender_commands(
    args: argparse.Namespace, name: str, out: Path, runs: int
) -> list[list[str]]:
    """The commands of `name` (peer or ours), started at once; the runs' folders are
    out/seed-i."""
    if name == "peer":
        return [_train_command(args, out / f"seed-{i}", str(i), "--seed") for i in range(runs)]
    return [[*_train_command(args, out, f"0-{runs - 1}", "--seeds"), "--workers", str(runs)]]


def _run(commands: list[list[str]]) -> float:
    """Start every command at once; the seconds until the last ends (an error if one fails)."""
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "disable")}
    tic = time.perf_counter()
    procs = [subprocess.Popen(c, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for c in commands]  # fmt: skip
    for proc in procs:
        _, err = proc.communicate()
        if proc.returncode:
            raise RuntimeError(f"{' '.join(proc.args)} failed:\n{err.decode()[-2000:]}")
    return time.perf_counter() - tic


def _report(
    name: str,
    rates: dict[str, list[float]],
    late: dict[str, list[float]],
    seconds: dict[str, list[float]],
) -> None:
    """Each contender's result on stderr as it comes (a time limit may end the benchmark)."""
    print(
        f"{name}: {rates[name][-1]:.2f} episodes/s ({late[name][-1]:.2f} over the second half "
        f"of the cycles), the command {seconds[name][-1]:.1f} s",
        file=sys.stderr,
        flush=True,
    )


def _measure_contender(
    commands: list[list[str]], folders: list[Path], after_cycles: int
) -> tuple[float, float, float, list[float]]:
    """One contender's run: (episodes/s after the first cycle, episodes/s after
    `after_cycles`, the seconds of its commands, each cycle's seconds from the second on)."""
    seconds = _run(commands)
    rates = _steady_rate(folders), _steady_rate(folders, after_cycles)
    return *rates, seconds, _cycle_seconds(folders)


def measure(args: argparse.Namespace) -> dict[str, Any]:
    """ours, bound, peer (episodes/s) and the commands' wall times."""
    from benchmarks.cycle_speed import physics_episodes_per_second

    config = _config(args)
    cores = os.cpu_count() or 1
    check_device(args.device)
    runs = args.runs or cores
    names = ("peer",) if args.peer_only else ("peer", "ours")
    rates: dict[str, list[float]] = {name: [] for name in CONTENDERS}
    late: dict[str, list[float]] = {name: [] for name in CONTENDERS}
    seconds: dict[str, list[float]] = {name: [] for name in CONTENDERS}
    cycle_s: dict[str, list[float] | None] = {name: None for name in CONTENDERS}
    with tempfile.TemporaryDirectory(prefix="bench-seeds-") as tmp:
        for repeat in range(args.repeats):
            for name in names:
                out = Path(tmp) / f"{name}-{repeat}"
                commands = _contender_commands(args, name, out, runs)
                folders = [out / f"seed-{i}" for i in range(runs)]
                rate, late_rate, took, cycle_s[name] = _measure_contender(
                    commands, folders, _late_cycles(args.cycles)
                )
                rates[name].append(rate)
                late[name].append(late_rate)
                seconds[name].append(took)
                _report(name, rates, late, seconds)

    def median(values: list[float]) -> float | None:
        return statistics.median(values) if values else None

    out: dict[str, Any] = {
        "ours": median(rates["ours"]),
        "bound": physics_episodes_per_second(config.variant) * cores,
        "peer": statistics.median(rates["peer"]),
        "unit": "episodes/s",
    }
    out["ours_over_peer"] = out["ours"] / out["peer"] if rates["ours"] else None
    for name in CONTENDERS:
        out[f"{name}_late"] = median(late[name])
        out[f"{name}_command_s"] = median(seconds[name])
        out[f"{name}_cycle_s"] = cycle_s[name]  # the last alternation's
    out["late_after_cycles"] = _late_cycles(args.cycles)
    out["cores"] = cores
    out["shape"] = (
        f"{runs} {args.condition} runs of preset {args.preset}, {args.cycles} cycles of "
        f"{config.episodes_per_cycle} episodes and {config.n_updates} updates of "
        f"{config.batch_size} each, networks on {args.device}"
        + "".join(f", {setting}" for setting in args.settings)
        + f"; {args.repeats} alternation(s), medians"
    )
    return out
