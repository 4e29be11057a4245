"""`curious bench`: the learner bound's FLOP accounting, each benchmark's result, and the
options every benchmark refuses."""

import argparse
import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from freed_heap import leave_freed_heap
from torch.utils.flop_counter import FlopCounterMode

from benchmarks import AtLeast, CountList, in_fresh_process
from benchmarks.learner_speed import add_arguments, measure, update_gemms
from curious.agent.learner import Learner
from curious.commands.bench import BENCHMARKS
from curious.presets import resolve


def _benchmark_parser(name: str) -> argparse.ArgumentParser:
    """`curious bench NAME`'s own options, as the command line builds them."""
    parser = argparse.ArgumentParser(prog=f"curious bench {name}", exit_on_error=False)
    importlib.import_module(BENCHMARKS[name][0]).add_arguments(parser)
    return parser


def measured(name: str, args: list[str]) -> dict:
    """What `curious bench NAME ARGS` measures, measured in this process."""
    module = importlib.import_module(BENCHMARKS[name][0])
    return module.measure(_benchmark_parser(name).parse_args(args))


@pytest.mark.parametrize("algorithm_sizes", [(256, 77, 4, 256, 3), (32, 10, 2, 16, 2)])
def test_bound_counts_exactly_the_products_of_one_update(algorithm_sizes):
    batch, inputs, actions, hidden, layers = algorithm_sizes
    # the bound is the products of the written-out update (the workspace backend)
    config = resolve(
        "paper", overrides=dict(hidden=hidden, layers=layers, learner_backend="workspace")
    )
    learner = Learner(inputs, actions, config)
    x, x2 = torch.randn(batch, inputs), torch.randn(batch, inputs)
    a, r = torch.rand(batch, actions) * 2 - 1, -torch.ones(batch)
    learner.update(x, a, r, x2)
    with FlopCounterMode(display=False) as counter:
        learner.update(x, a, r, x2)
    # The learner folds each bias into its layer's products (a column of ones): a forward
    # product (x @ W^T) has one more inner column, a weight-gradient product (g^T @ h) one more
    # output column. The bound counts the products without them.
    with_biases = sum(
        2 * m * (k + forward) * (n + weight_grad)
        for m, k, n, weight_grad, forward in update_gemms(*algorithm_sizes)
    )
    assert counter.get_total_flops() == with_biases


def test_measure_reports_ours_bound_peer_unit():
    parser = argparse.ArgumentParser()
    parser.add_argument("--json", action="store_true")
    add_arguments(parser)
    args = parser.parse_args(["--seconds", "0.1", "--no-peer", "--no-cycle", "--batch", "64"])
    result = measure(args)
    assert list(result)[:4] == ["ours", "bound", "peer", "unit"]
    assert result["ours"] > 0 and result["bound"] > 0 and result["peer"] is None
    assert result["unit"] == "updates/s" and result["ours_with_replay"] > 0
    assert result["workspace"] > 0 and result["compiled"] > 0


def test_the_cycle_benchmark_reports_every_contender_and_its_parts():
    result = measured("cycle", ["--preset", "smoke", "--cycles", "1"])
    assert list(result)[:4] == ["ours", "bound", "peer", "unit"]
    assert result["unit"] == "episodes/s"
    for name in ("peer", "ours", "workers", "ours_workers", "ours_workspace", "ours_threads"):
        assert result[name] > 0 and result[f"{name}_cycle_ms"] > 0
        assert result[f"{name}_update_ms"] > 0 and f"{name}_rollout_env_ms" in result
    assert torch.get_num_threads() == result["threads"]  # left as it was found


def test_the_cycle_benchmark_times_more_cycles_than_the_preset_holds():
    """7 timed cycles and the warm-up outlast the smoke preset's 24 episodes (6 cycles): the
    benchmark gives its trainers the episodes it times."""
    args = ["--preset", "smoke", "--cycles", "7", "--contenders", ""]
    result = measured("cycle", args)
    assert result["peer"] > 0 and result["ours"] > 0 and "workers" not in result


def test_the_rollout_scaling_benchmark_reports_every_process_count():
    args = ["--preset", "quick", "--episodes", "1", "--max-processes", "2"]
    result = measured("rollouts", args)
    assert list(result)[:4] == ["ours", "bound", "peer", "unit"]
    assert result["processes_1"] > 0 and result["processes_2"] == result["ours"]
    assert result["bound"] == 2 * result["physics_episodes_per_s_one_core"]


def test_the_checkpoint_benchmark_keeps_the_replay_once_where_the_peer_keeps_it_twice():
    args = ["--episodes", "300", "--every", "100", "--rounds", "1"]
    result = measured("checkpoint", args)
    assert list(result)[:4] == ["ours", "bound", "peer", "unit"]
    assert result["ours"] > 0 and result["peer"] > 0 and result["bound"] > 0
    replay_mb = result["replay_kb_per_episode"] * 300 / 1e3
    assert replay_mb < result["disk_two_checkpoints_ours_mb"] < 1.1 * replay_mb
    both = replay_mb * (300 + 200) / 300  # the replay at both checkpoints, 300 and 200 episodes
    assert both < result["disk_two_checkpoints_peer_mb"] < 1.1 * both


def test_the_resume_benchmark_loads_the_replay_once_where_the_peer_holds_it_twice():
    args = ["--episodes", "2000", "--every", "400", "--rounds", "1"]
    result = measured("resume", args)
    assert list(result)[:4] == ["ours", "bound", "peer", "unit"]
    replay = result["bound"]  # 33 MB of the default variant's replay
    assert replay < result["held_ours_mb"] < 1.5 * replay  # the replay once, and little beside
    assert result["held_peer_mb"] > result["held_ours_mb"] + 0.8 * replay  # a second copy
    assert result["allocated_ours_mb"] < 0.5 * replay  # a segment at a time, read into the replay
    assert result["allocated_peer_mb"] > replay  # arrays of its own for the whole replay
    # The peaks (the kernel's high-water mark) are not asserted: it counts file pages, which the
    # kernel may drop, from per-CPU counters read approximately; CI's kernel once counted the
    # peer 13 MB short of its two copies, as much as this small replay's difference.
    assert result["ours"] > 0 and result["peer"] > 0


def _load_after_freeing_heap(path: str, capacity: int, into: bool) -> float:
    """MB the resume benchmark counts held by a load, in a process that first left 40 MB free
    in its heap, resident, with glibc's threshold risen as freeing large blocks raises it."""
    from benchmarks.resume_memory import load_and_count

    above = leave_freed_heap(40)
    held = load_and_count(path, "default", capacity, into)["held"] / 1e6
    del above
    return held


def test_the_resume_benchmark_counts_what_a_load_adds_where_the_heap_held_memory_freed(
    tmp_path,
):
    # Without the heap given back first, the load's arrays came from memory already resident:
    # ours counted under the replay, the peer under its two copies (as on CI).
    from benchmarks.resume_memory import write_checkpoints

    path, replay_bytes = write_checkpoints(tmp_path, "default", 2000, 400)
    replay = replay_bytes / 1e6
    ours, peer = (
        in_fresh_process(_load_after_freeing_heap, str(path), 2000, into) for into in (True, False)
    )
    assert replay < ours < 1.5 * replay
    assert peer > ours + 0.8 * replay


def test_the_heap_benchmark_trains_both_ways_each_with_its_allocators_settings(tmp_path):
    args = ["--preset", "smoke", "--episodes", "8", "--speed-rounds", "1", "--dir", str(tmp_path)]
    result = measured("heap", args)
    assert list(result)[:4] == ["ours", "bound", "peer", "unit"]
    assert (result["purge_delay_ours"], result["purge_delay_peer"]) == ("0", "10")
    assert 0 < result["bound"] and 0 < result["ours"] < result["peak_anonymous_ours_mb"]
    assert 0 < result["peer"] < result["peak_anonymous_peer_mb"]
    assert result["episodes_per_s_ours"] > 0 and result["episodes_per_s_peer"] > 0
    assert list(tmp_path.iterdir()) == []  # the runs are removed


def test_the_relabel_benchmark_times_both_routes_on_the_same_minibatches():
    args = ["--batch", "64", "--episodes", "40", "--seconds", "0.05", "--rounds", "1"]
    result = measured("relabel", args)
    assert list(result)[:4] == ["ours", "bound", "peer", "unit"]
    assert result["unit"] == "minibatches/s" and result["batch"] == 64
    assert result["ours"] > 0 and result["peer"] > 0 and result["bound"] > 0
    assert 0 < result["rewards_met"] < 1  # some relabelled goals met, some not


def _count_options() -> list[tuple[str, str, int]]:
    """(benchmark, option, minimum) for every count option of every benchmark."""
    found = []
    for name in BENCHMARKS:
        for action in _benchmark_parser(name)._actions:
            if isinstance(action.type, (AtLeast, CountList)):
                found.append((name, action.option_strings[0], action.type.minimum))
    return found


@pytest.mark.parametrize("name", sorted(BENCHMARKS))
def test_every_whole_number_option_of_a_benchmark_has_a_floor(name):
    """A count given as a bare `int` took 0 or -3 into the benchmark, which then failed deep
    inside (a ZeroDivisionError, numpy's "negative dimensions")."""
    bare = [a.option_strings[0] for a in _benchmark_parser(name)._actions if a.type is int]
    assert bare == []


@pytest.mark.parametrize(("name", "option", "minimum"), _count_options())
def test_a_count_below_its_floor_is_refused_naming_the_option(name, option, minimum):
    parser = _benchmark_parser(name)
    with pytest.raises(argparse.ArgumentError, match=f"must be at least {minimum}"):
        parser.parse_args([option, str(minimum - 1)])
    assert parser.parse_args([option, str(minimum)]) is not None


def test_the_seeds_benchmark_needs_two_cycles_and_says_why(capsys):
    """One cycle leaves no rate to read (the rate is read after each run's first cycle)."""
    from curious.cli import main

    with pytest.raises(SystemExit) as refused:  # argparse's own refusal: status 2
        main(["bench", "seeds", "--cycles", "1"])
    assert refused.value.code == 2
    err = capsys.readouterr().err
    assert "--cycles: must be at least 2 (the rate is read after each run's first cycle)" in err


def test_the_seeds_benchmark_gives_every_run_its_settings_and_refuses_bad_ones(capsys):
    """`--set` reaches every run's `curious train` (and the episodes a cycle, which settings
    may change); an unknown key is one line before any run starts. Ours is one `curious train
    --seeds` with every run at once, the peer a `curious train --seed` process per run."""
    from benchmarks import seeds_speed
    from curious.cli import main

    parser = argparse.ArgumentParser()
    seeds_speed.add_arguments(parser)
    args = parser.parse_args(["--preset", "smoke", "--cycles", "3", "--set", "n_workers=3"])
    command = seeds_speed._train_command(args, Path("out"), "0", "--seed")
    assert command[-2:] == ["--set", "n_workers=3"]
    assert "total_episodes=18" in command  # 3 cycles of 3 workers x 2 episodes
    (ours,) = seeds_speed._contender_commands(args, "ours", Path("o"), 5)
    assert ours[ours.index("--seeds") + 1] == "0-4" and ours[-2:] == ["--workers", "5"]
    peer = seeds_speed._contender_commands(args, "peer", Path("p"), 5)
    assert [c[c.index("--out") + 1] for c in peer] == [f"p/seed-{i}" for i in range(5)]
    with pytest.raises(SystemExit) as exit_:
        sys.exit(main(["bench", "seeds", "--set", "nonsense=1"]))
    assert exit_.value.code == 2
    assert "curious bench: error: unknown config key 'nonsense'" in capsys.readouterr().err


def _gpu_checks_on_cpu(out: Path, **settings: str) -> None:
    """`tools/gpu_checks.sh OUT` as a GPU node runs it, on the CPU (PRESET=smoke DEVICE=cpu, as
    its header says), with `settings` in its environment; every step it ran exited 0."""
    import os
    import subprocess

    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PRESET": "smoke", "DEVICE": "cpu", "PYTHONPATH": str(root), **settings}
    done = subprocess.run(
        ["bash", str(root / "tools" / "gpu_checks.sh"), str(out)],
        cwd=root, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert "exit 0" in done.stdout and "exit 1" not in done.stdout, done.stdout + done.stderr


def test_the_gpu_checks_seeds_step_passes_its_settings_to_the_benchmark(tmp_path):
    """`tools/gpu_checks.sh`, as a GPU node runs it but on a CPU (PRESET=smoke DEVICE=cpu, as
    its header says): the seeds step hands SEEDS_* to `curious bench seeds` and writes its JSON
    where its header says."""
    import json

    _gpu_checks_on_cpu(
        tmp_path, STEPS="seeds", SEEDS_RUNS="2", SEEDS_CYCLES="2", SEEDS_SET="n_workers=1"
    )
    result = json.loads((tmp_path / "seeds.json").read_text())
    assert result["ours"] > 0 and result["peer"] > 0 and result["ours_over_peer"] > 0
    # two cycles: the second half of the cycles is the rate after the first
    assert result["late_after_cycles"] == 1 and result["ours_late"] == result["ours"]
    assert len(result["ours_cycle_s"]) == 1 and len(result["peer_cycle_s"]) == 1
    assert result["shape"].startswith("2 curious runs of preset smoke, 2 cycles of 2 episodes")
    assert "n_workers=1" in result["shape"] and (tmp_path / "env.txt").exists()


def test_the_seeds_benchmark_reads_a_warm_up_apart_from_the_steady_rate(tmp_path):
    """The rate after the first cycle and over the second half of the cycles, summed over the
    runs, from each run's own `wall_time`: a run whose first cycles are slow (a compiled
    learner warming up) reads faster late than after its first cycle."""
    import json

    import pandas as pd

    from benchmarks import seeds_speed

    per_cycle = 2  # 1 worker x 2 episodes
    # 4 cycles: the first two take 10 s a cycle, the last two 1 s
    ends = [0.0, 10.0, 20.0, 21.0, 22.0]
    folders = []
    for seed in range(2):
        folder = tmp_path / f"seed-{seed}"
        folder.mkdir()
        (folder / "config.json").write_text(
            json.dumps({"config": {"n_workers": 1, "episodes_per_worker": per_cycle}})
        )
        wall = [ends[c] + (e + 1) * (ends[c + 1] - ends[c]) / per_cycle
                for c in range(4) for e in range(per_cycle)]  # fmt: skip
        pd.DataFrame({"wall_time": wall}).to_parquet(folder / "metrics.parquet")
        folders.append(folder)
    # after cycle 1: 6 episodes in 12 s a run; after cycle 2: 4 episodes in 2 s a run
    assert seeds_speed._steady_rate(folders) == pytest.approx(2 * 6 / 12)
    assert seeds_speed._steady_rate(folders, 2) == pytest.approx(2 * 4 / 2)
    assert [seeds_speed._late_cycles(c) for c in (2, 3, 4, 10)] == [1, 1, 2, 5]
    # cycles 2 to 4, where the warm-up ends
    assert seeds_speed._cycle_seconds(folders) == [10.0, 1.0, 1.0]


def test_the_gpu_checks_long_step_times_each_backend_over_its_cycles(tmp_path):
    """`tools/gpu_checks.sh`'s step `long` on a CPU: the processes alone over LONG_CYCLES cycles,
    once per backend of LONG_BACKENDS, each cycle's seconds in OUT/long-BACKEND.json."""
    import json

    # the compiled backend's compile is a GPU node's minutes: the eager one alone here
    _gpu_checks_on_cpu(
        tmp_path, STEPS="long", SEEDS_RUNS="2", LONG_CYCLES="4", LONG_BACKENDS="autograd"
    )
    result = json.loads((tmp_path / "long-autograd.json").read_text())
    assert len(result["peer_cycle_s"]) == 3 and result["late_after_cycles"] == 2
    assert result["ours"] is None  # the processes alone
    assert "4 cycles" in result["shape"] and "learner_backend=autograd" in result["shape"]
    assert not (tmp_path / "long-compiled.json").exists()


def test_the_seeds_benchmark_refuses_the_settings_it_sets_itself(capsys):
    """`--set total_episodes=4` made the runs shorter than the cycles the rate is read over, and
    the benchmark printed `nan episodes/s` with numpy's warning."""
    from curious.cli import main

    assert main(["bench", "seeds", "--preset", "smoke", "--runs", "1", "--cycles", "2",
                 "--peer-only", "--set", "total_episodes=4"]) == 2  # fmt: skip
    assert "--set total_episodes: the benchmark sets it from --cycles" in capsys.readouterr().err


def test_a_benchmark_too_large_for_the_memory_is_one_line(capsys):
    """numpy's MemoryError (a replay of 10^8 episodes: 931 GiB) was a traceback."""
    from curious.cli import main

    args = ["bench", "relabel", "--episodes", "100000000", "--seconds", "0.1", "--rounds", "1"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("curious bench: error: not enough memory: Unable to allocate")
    assert err.count("\n") == 1


_ENDS_AS_A_PROCESS_ENDS = """
import multiprocessing.util
import sys
import time
from pathlib import Path

from benchmarks import in_fresh_process


def mark_slowly(path):
    time.sleep(1)  # an exit as slow as a trained run's
    Path(path).touch()


def hold_a_semaphore(path):
    # finalizers run last-made first: the semaphore's (unlink, then tell the tracker), then the mark
    multiprocessing.util.Finalize(None, mark_slowly, (path,), exitpriority=0)
    hold_a_semaphore.lock = multiprocessing.get_context("spawn").Lock()
    return 7


if __name__ == "__main__":
    print(in_fresh_process(hold_a_semaphore, sys.argv[1]))
"""


def test_a_benchmarks_fresh_process_ends_as_a_process_ends_not_killed(tmp_path):
    # A pool's `with` block kills its worker while it is ending: its finalizers are cut short,
    # and the resource tracker then warns of a leaked semaphore at the benchmark's end.
    script, marker = tmp_path / "script.py", tmp_path / "ended"
    script.write_text(_ENDS_AS_A_PROCESS_ENDS)
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run(
        [sys.executable, str(script), str(marker)],
        capture_output=True, text=True, timeout=120, cwd=root,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(
            [str(root), *filter(None, [os.environ.get("PYTHONPATH")])]
        )},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "7"  # the function's result comes back
    assert marker.exists()  # its process ran its finalizers at exit
    assert "leaked" not in done.stderr
