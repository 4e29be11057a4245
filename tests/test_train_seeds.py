"""`curious train --seeds`: each seed trains in a process of its own, side by side, into
`--out/seed-N`, each the run `curious train --seed N` trains; a Ctrl-C stops every run at its next
checkpoint, and `--resume` goes on with all of them."""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest
import side_by_side_jobs as jobs
import torch
from test_agent_runs import assert_same_state

from curious.cli import main
from curious.presets import resolve
from curious.runs import checkpoint
from curious.runs.driver import train
from curious.runs.side_by_side import Failed, run_side_by_side

SMOKE = ["train", "--preset", "smoke", "--no-record", "--no-progress"]


def _table(path: Path) -> pd.DataFrame:
    return pq.read_table(path).drop(["wall_time"]).to_pandas()


def _assert_same_tables(a: Path, b: Path) -> None:
    for name in ("metrics.parquet", "tests.parquet"):
        pd.testing.assert_frame_equal(_table(a / name), _table(b / name))


def _state(folder: Path) -> tuple:
    _, state, replay = checkpoint.load_latest(folder / "checkpoints")
    return state, replay


def test_each_seed_is_the_run_of_its_seed_alone_in_a_folder_of_its_own(tmp_path, capsys):
    """`--seeds 0-1`: a run folder per seed under --out and a line per run, seed 1's tables and
    checkpoint those of `--seed 1` (torch's global generator aside: nothing a run computes
    draws from it)."""
    out, alone = tmp_path / "seeds", tmp_path / "alone"
    short = ["--set", "total_episodes=8"]  # two cycles
    assert main([*SMOKE, *short, "--seeds", "0-1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["seed-0", "seed-1"]
    assert f"8 episodes in {out / 'seed-0'}" in printed
    assert f"8 episodes in {out / 'seed-1'}" in printed
    assert main([*SMOKE, *short, "--seed", "1", "--out", str(alone)]) == 0
    _assert_same_tables(alone, out / "seed-1")
    assert_same_state(_state(alone), _state(out / "seed-1"), uncompared=("elapsed", "torch_rng"))


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--seeds", "2-x"], "write them as 0-4 or 0,2,5"),
        (["--seeds", "0,3-1"], "seeds '0,3-1': a range runs upwards (1-3)"),
        (["--seeds", "4294967295-4294967296"], "each must be from 0 to 4,294,967,295"),
        (["--seed", "0", "--workers", "2"], "--workers trains several seeds side by side"),
        (["--seeds", "0-1", "--workers", "0"], "--workers must be >= 1, got 0"),
    ],
)
def test_a_bad_seed_list_or_worker_count_is_one_line_and_writes_nothing(
    options, message, tmp_path, capsys
):
    assert main([*SMOKE, "--out", str(tmp_path / "out"), *options]) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_seeds_whose_folders_hold_runs_or_lie_in_one_are_refused_before_any_trains(
    tmp_path, capsys
):
    """A seed folder that holds a run without --resume, and --out that is itself a run folder,
    are refused in one line before any seed trains (the other seed's folder stays empty)."""
    out = tmp_path / "seeds"
    run = out / "seed-1"
    assert main([*SMOKE, "--set", "total_episodes=4", "--seed", "1", "--out", str(run)]) == 0
    before = sorted(p.name for p in run.iterdir())
    assert main([*SMOKE, "--seeds", "0-1", "--out", str(out)]) == 2
    assert "seed-1 is not empty" in capsys.readouterr().err
    assert not (out / "seed-0").exists()
    assert main([*SMOKE, "--seeds", "0-1", "--out", str(run)]) == 2
    assert "holds a run (config.json)" in capsys.readouterr().err
    assert sorted(p.name for p in run.iterdir()) == before


def test_ctrl_c_stops_every_seed_at_a_checkpoint_and_resume_goes_on(tmp_path):
    """A terminal's Ctrl-C (SIGINT to the command and its processes): the two seeds training
    stop at the end of their cycle with a checkpoint there, though their settings write none
    before the run's end, and the third never begins; `--resume` goes on with the first two and
    starts the third with their settings, each ending as its seed's run trained alone."""
    out = tmp_path / "seeds"
    settings = ["--set", "total_episodes=40", "--set", "checkpoint_every_cycles=1000"]
    command = [sys.executable, "-m", "curious.cli", *SMOKE, *settings, "--seeds", "0-2",
               "--workers", "2", "--out", str(out)]  # fmt: skip
    env = {**os.environ, "MUJOCO_GL": "disable"}
    proc = subprocess.Popen(
        command, env=env, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    begun = [out / f"seed-{seed}" / "config.json" for seed in (0, 1)]
    deadline = time.monotonic() + 120
    while not all(p.exists() for p in begun) and proc.poll() is None:
        assert time.monotonic() < deadline, "the seeds did not begin"
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGINT)  # what a terminal does on Ctrl-C
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "curious train: stopped; every run ended at a checkpoint: go on with --resume" in err
    for seed in (0, 1):
        folder = out / f"seed-{seed}"
        episodes = _state(folder)[0]["episodes"]
        assert 0 < episodes < 40 and len(_table(folder / "metrics.parquet")) == episodes
    assert not (out / "seed-2").exists()
    resume = ["train", "--seeds", "0-2", "--out", str(out), "--resume", "--no-progress"]
    assert main([*resume, "--no-record"]) == 0
    for seed in (0, 2):  # one resumed, one started by the resume
        alone = tmp_path / f"alone-{seed}"
        assert main([*SMOKE, *settings, "--seed", str(seed), "--out", str(alone)]) == 0
        _assert_same_tables(alone, out / f"seed-{seed}")


def test_a_stop_request_ends_a_run_after_its_cycle_with_a_checkpoint(tmp_path):
    """`stop()` true from the start: the run ends after one cycle, with a checkpoint there."""
    config = resolve("smoke", "curious", 0, dict(progress=False))
    trainer = train(config, tmp_path / "run", stop=lambda: True)
    assert trainer.episodes == config.episodes_per_cycle
    assert _state(tmp_path / "run")[0]["episodes"] == trainer.episodes


def test_jobs_run_side_by_side_in_processes_and_a_failure_comes_back_in_its_place(tmp_path):
    """Two workers run two jobs at the same time, each in a process of its own; one worker runs
    them one after the other in one process; a job that raises leaves the others, its error
    in its place."""
    meet = functools.partial(jobs.meet, str(tmp_path), 1)
    together = run_side_by_side([meet, meet], workers=2)
    assert len(set(together)) == 2 and os.getpid() not in together
    failing = functools.partial(jobs.fail, "simulator lost")
    one = run_side_by_side([jobs.pid, failing, jobs.pid], workers=1)
    assert one[1] == Failed("OSError: simulator lost")
    assert one[0] == one[2] != os.getpid()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_on_cuda_each_seed_trains_in_its_process_as_alone(tmp_path):
    """On a GPU the seeds' processes share it, and seed 1 of `--seeds 0-1` is `--seed 1` on
    that GPU, bit for bit (the same kernels on the same shapes)."""
    cuda = ["--device", "cuda", "--set", "total_episodes=8"]
    out, alone = tmp_path / "seeds", tmp_path / "alone"
    assert main([*SMOKE, *cuda, "--seeds", "0-1", "--out", str(out)]) == 0
    assert main([*SMOKE, *cuda, "--seed", "1", "--out", str(alone)]) == 0
    assert len(_table(out / "seed-0" / "metrics.parquet")) == 8
    _assert_same_tables(alone, out / "seed-1")
