"""Resumed recordings: after any kills, errors and resumes, `recording.rrd` holds exactly the
entities and points of an uninterrupted run of the same seed (compared entity by entity, point by
point, leaving out wall-clock times); a full disk never replaces the last good recording.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import rerun as rr

from curious.runs.folder_layout import RECORDING_FILE, list_checkpoints
from curious.watching.recording.cost import synthetic_episodes
from curious.watching.recording.reader import read_points
from curious.watching.recording.recorder import RunRecorder
from curious.watching.recording.settings import RecorderSettings

MODULES = ("reach", "push_cube1", "cube1_above_cube2", "stack", "push_cube3")
SETTINGS = RecorderSettings(rollout_every=0, stats_keyframe_every=50)
CYCLE, EPOCH, TOTAL = 20, 3, 400  # episodes a cycle, cycles an epoch, episodes in all
DATA = synthetic_episodes(TOTAL, len(MODULES), seed=5, window=10, eval_every=10, lp_eps=0.4)


def assert_same_points(path: Path, reference: Path) -> None:
    """`path` holds the entities and points of `reference`, no more, no fewer."""
    (temporal, static), (want, want_static) = read_points(path), read_points(reference)
    assert sorted(temporal) == sorted(want) and static == want_static
    for key, rows in want.items():
        got = temporal[key]
        missing = sorted(set(rows) - set(got))[:3]
        extra = sorted(set(got) - set(rows))[:3]
        assert got == rows, (
            f"{key}: {len(got)} points for {len(rows)}; missing {missing}, extra {extra}"
        )


def log_cycles(recorder: RunRecorder, start: int, stop: int) -> None:
    """Logs episodes [start, stop) as the training loop does, one cycle at a time: the cycle's
    episodes, its tests at an epoch's end, then replay and learner statistics at the count."""
    for first in range(start, stop, CYCLE):
        sl, end = slice(first, first + CYCLE), first + CYCLE
        wall = DATA["episode"][sl] * 0.5
        recorder.log_episodes(
            DATA["episode"][sl],
            DATA["module"][sl],
            DATA["success"][sl],
            DATA["eval"][sl],
            DATA["competence"][sl],
            DATA["lp"][sl],
            DATA["p_lp"][sl],
            wall_time=wall,
        )
        if (end // CYCLE) % EPOCH == 0:
            recorder.log_tests(end, [0, 1, 1, 3], [True, False, True, True], wall_time=end * 0.5)
        recorder.log_replay(end, np.bincount(DATA["module"][sl], minlength=len(MODULES)), end * 0.5)
        recorder.log_learner(
            end, losses={"critic": 1.0 / end, "actor": -end / 7.0}, q={"target_mean": -end / 3.0}
        )


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("uninterrupted")
    recorder = RunRecorder(folder, MODULES, settings=SETTINGS)
    log_cycles(recorder, 0, TOTAL)
    recorder.checkpoint()
    recorder.close()
    return folder / RECORDING_FILE


@pytest.mark.parametrize(
    "stops",
    [
        [("kill", 120)],  # a checkpoint at an epoch's end: its tests are at the checkpoint too
        [("error", 100), ("kill", 240)],  # Ctrl-C (more logged after the checkpoint), a kill
        [("close", 200)],  # a finished run extended
        [("kill", TOTAL)],  # killed after the final checkpoint, before the recording was closed
    ],
)
def test_a_recording_resumed_after_any_stops_holds_what_an_uninterrupted_one_does(
    tmp_path: Path, uninterrupted: Path, stops: list[tuple[str, int]]
) -> None:
    start = 0
    for how, checkpoint in stops:
        recorder = RunRecorder(
            tmp_path, MODULES, settings=SETTINGS, resume=start > 0, resume_from_episode=start
        )
        log_cycles(recorder, start, checkpoint)
        recorder.checkpoint()
        if how == "close":
            recorder.close()
        else:
            log_cycles(recorder, checkpoint, min(checkpoint + CYCLE, TOTAL))  # not checkpointed
            if how == "error":
                recorder.close_after_error()
            else:  # killed: the process ends with recording.rrd as at the checkpoint
                recorder.stream.disconnect()
        start = checkpoint
    recorder = RunRecorder(
        tmp_path, MODULES, settings=SETTINGS, resume=True, resume_from_episode=start
    )
    log_cycles(recorder, start, TOTAL)
    recorder.close()
    assert_same_points(tmp_path / RECORDING_FILE, uninterrupted)


# ------------------------------------------------------------------------------ real runs
TESTS = Path(__file__).resolve().parent
SMOKE = ["train", "--preset", "smoke", "--set", "total_episodes=36", "--set", "torch_threads=1"]
SMOKE += ["--no-progress"]
TRAIN = [*SMOKE, "--rollout-every", "1"]  # every evaluation episode in 3-D: the scene, frames
"""Smoke runs: checkpoints every 3 cycles of 4 episodes (12, 24, 36), an epoch every 8."""

KILLED_AT_A_CHECKPOINT = textwrap.dedent(
    """
    import os, signal, sys
    from curious.runs import checkpoint
    from curious.cli import main

    save = checkpoint.save

    def save_then_die(directory, episodes, *args, **kwargs):
        path = save(directory, episodes, *args, **kwargs)
        if episodes == int(sys.argv[1]):
            os.kill(os.getpid(), signal.SIGKILL)
        return path

    checkpoint.save = save_then_die
    sys.exit(main(sys.argv[2:]))
    """
)


def train_killed_at(episodes: int, args: list[str]) -> None:
    """`curious train ARGS` in a process SIGKILLed right after its checkpoint at `episodes`."""
    env = {**os.environ, "MUJOCO_GL": "disable", "OMP_NUM_THREADS": "1"}
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS.parent), env.get("PYTHONPATH", "")])
    proc = subprocess.run(
        [sys.executable, "-c", KILLED_AT_A_CHECKPOINT, str(episodes), *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == -9, proc.stderr[-2000:]


@pytest.fixture(scope="module")
def uninterrupted_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from curious.cli import main

    out = tmp_path_factory.mktemp("run") / "full"
    assert main([*TRAIN, "--out", str(out)]) == 0
    return out / RECORDING_FILE


def test_a_run_killed_three_times_records_what_an_uninterrupted_run_does(
    tmp_path: Path, uninterrupted_run: Path, recwarn: pytest.WarningsRecorder
) -> None:
    """SIGKILL right after a checkpoint (12: mid-epoch), after the next one on `--resume` (24:
    an epoch's end, with its tests), after the final one on `--resume` (36: before the
    recording was closed), then `--resume`: the same entities and points as a run never
    stopped, the 3-D scene logged once."""
    from curious.cli import main

    out = tmp_path / "killed"
    for i, episodes in enumerate([12, 24, 36]):
        train_killed_at(episodes, [*TRAIN, "--out", str(out)] + (["--resume"] if i else []))
    assert main([*TRAIN, "--out", str(out), "--resume"]) == 0
    assert_same_points(out / RECORDING_FILE, uninterrupted_run)
    assert not [w for w in recwarn if "footer" in str(w.message)]  # no "legacy format" warning
    assert len(list_checkpoints(out / "checkpoints")) == 2


@pytest.fixture(scope="module")
def killed_at_24(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run SIGKILLed right after its checkpoint at 24 episodes (an epoch's end); each test
    damages and resumes a copy of it."""
    out = tmp_path_factory.mktemp("killed") / "killed"
    train_killed_at(24, [*TRAIN, "--out", str(out)])
    return out


def float32_points(rows: list) -> list:
    """Points with their values rounded to float32, the precision of the run's tables."""

    def rounded(value: str) -> str:
        numbers = eval(value, {"nan": float("nan"), "inf": float("inf")})  # a list of floats
        return repr([float(np.float32(x)) for x in numbers]) if isinstance(numbers, list) else value

    return [(episode, frame, rounded(value)) for episode, frame, value in rows]


@pytest.mark.parametrize("damage", ["deleted", "cut", "overwritten"])
def test_a_resume_rebuilds_a_missing_or_damaged_recording_from_the_tables(
    tmp_path: Path, uninterrupted_run: Path, killed_at_24: Path, damage: str
) -> None:
    """Killed after its checkpoint at 24 with its recording then deleted, cut short or
    overwritten, a run resumed holds every series its tables hold as an uninterrupted run does
    (the module statistics at float32), the replay shares and learner statistics among them
    (`learner.parquet`), and says what it could not rebuild, with the episode of its first
    point: the 3-D rollouts, at the first evaluation from 24 on."""
    from curious.cli import main

    out = tmp_path / "killed"
    shutil.copytree(killed_at_24, out)
    recording = out / RECORDING_FILE
    if damage == "deleted":
        recording.unlink()
    elif damage == "cut":
        recording.write_bytes(recording.read_bytes()[:200])
    else:
        recording.write_bytes(b"not a recording at all")
    unreadable = "could not be read" if damage != "deleted" else None  # a file kept aside
    rebuilt = "rebuilt from metrics.parquet, tests.parquet and learner.parquet"
    with (
        pytest.warns(RuntimeWarning, match=unreadable) if unreadable else contextlib.nullcontext(),
        pytest.warns(RuntimeWarning, match=rebuilt) as warned,
    ):
        assert main([*TRAIN, "--out", str(out), "--resume"]) == 0
    (said,) = [str(w.message) for w in warned if rebuilt in str(w.message)]
    assert "learner statistics" not in said and "replay" not in said, said
    rollouts = int(re.search(r"3-D rollouts \(.*?\) at episode ([\d,]+)", said)[1])
    assert_rebuilt(recording, uninterrupted_run, rollouts, said)


def assert_rebuilt(
    recording: Path, reference: Path, rollouts: int | None, said: str, learner_from: int = 0
) -> None:
    """`recording` holds every entity and point of `reference`, the statistics at float32, but
    the 3-D rollouts before episode `rollouts` (None: none at all) and the replay shares and
    learner statistics before `learner_from`."""
    from curious.watching.recording.resume import IN_LEARNER_TABLE

    (got, got_static), (want, want_static) = read_points(recording), read_points(reference)
    if rollouts is None:
        want = {k: rows for k, rows in want.items() if k[0].split("/")[0] != "scene"}
        want_static = {k: v for k, v in want_static.items() if k[0].split("/")[0] != "scene"}
    assert sorted(got) == sorted(want) and sorted(got_static) == sorted(want_static)
    for (entity, component), rows in want.items():
        mine = got[(entity, component)]
        if entity.startswith("scene/"):  # the rest pose, then rollouts from episode 24 on
            shown = [e for e, frame, _ in mine if frame != 0 and e is not None]
            assert shown and min(shown) == rollouts and rollouts >= 24, (entity, said)
        elif entity.startswith(IN_LEARNER_TABLE):  # float64 in the table: as they were
            assert mine == [r for r in rows if r[0] >= learner_from], entity
        else:
            assert float32_points(mine) == float32_points(rows), entity


def test_a_run_from_before_the_learner_table_rebuilds_its_series_from_where_it_begins(
    tmp_path: Path, uninterrupted_run: Path, killed_at_24: Path
) -> None:
    """A run trained before `learner.parquet` existed (here: the table deleted) begins one where
    it resumes (24: rows from the next cycle's end, 28, on); its recording, lost after the next
    checkpoint (36), is rebuilt with those series from 28, which the warning names."""
    from curious.cli import main

    out = tmp_path / "killed"
    shutil.copytree(killed_at_24, out)
    (out / "learner.parquet").unlink()
    train_killed_at(36, [*TRAIN, "--out", str(out), "--resume"])
    (out / RECORDING_FILE).unlink()
    with pytest.warns(RuntimeWarning, match="rebuilt from") as warned:
        assert main([*TRAIN, "--out", str(out), "--resume"]) == 0
    (said,) = [str(w.message) for w in warned if "rebuilt from" in str(w.message)]
    named = re.search(r"learner statistics \(.*?\) at episode ([\d,]+)", said)
    assert named and int(named[1]) == 28, said
    assert "3-D rollouts (scene/...) not again: the run has ended" in said, said
    assert_rebuilt(out / RECORDING_FILE, uninterrupted_run, None, said, learner_from=28)


# ------------------------------------------------------------------------------ a full disk
def test_a_full_disk_never_replaces_the_last_good_recording(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The disk fills while a checkpoint is written: Rerun then writes the recording's footer
    only in part, and says nothing (on a 16 MiB disk, a 1 MiB file no reader opens replaced
    `recording.rrd`). The recording stays whole, and the resume continues it without a gap."""
    from toy_env import make_toy_envs

    from curious.presets import resolve
    from curious.runs import checkpoint
    from curious.runs.driver import train
    from curious.watching.recording.rollout_capture import recorder_factory

    config = resolve(
        "smoke", "curious", 0, dict(total_episodes=48, n_workers=2, episodes_per_worker=2)
    )
    settings = RecorderSettings(rollout_every=0)

    def run(out: Path, resume: bool = False) -> None:
        train(
            config,
            out,
            resume=resume,
            make_envs=lambda c: make_toy_envs(c.seed, c.n_workers),
            make_recorder=recorder_factory(resume, settings),
        )

    saves, savez, disconnect = [], checkpoint.np.savez, rr.RecordingStream.disconnect

    def full_at_the_third(*args, **kwargs):
        saves.append(1)
        if len(saves) == 3:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return savez(*args, **kwargs)

    def footer_cut_short(stream: rr.RecordingStream) -> None:
        files = list(tmp_path.rglob("*.rrd*"))
        sizes = {f: f.stat().st_size for f in files}
        disconnect(stream)
        for f in files:  # as on a full disk: the footer's first bytes, not the rest
            grown = f.stat().st_size - sizes[f] if f.exists() else 0
            if grown > 0:
                os.truncate(f, sizes[f] + grown // 2)

    run(tmp_path / "reference")
    out = tmp_path / "full"
    monkeypatch.setattr(checkpoint.np, "savez", full_at_the_third)
    monkeypatch.setattr(rr.RecordingStream, "disconnect", footer_cut_short)
    with pytest.raises(checkpoint.CheckpointError, match="No space left on device"):
        run(out)
    monkeypatch.undo()
    run(out, resume=True)
    assert not (out / "recording.rrd.unreadable").exists()
    assert_same_points(out / RECORDING_FILE, tmp_path / "reference" / RECORDING_FILE)


class _FullDisk:
    """A file that takes `room` bytes, then fails as a full disk does."""

    def __init__(self, handle, room: int) -> None:
        self.handle, self.room = handle, room

    def write(self, data) -> int:
        if len(data) > self.room:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.room -= len(data)
        return self.handle.write(data)

    def __getattr__(self, name: str):
        return getattr(self.handle, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.handle.close()


def test_a_checkpoint_on_a_full_disk_is_one_line_saying_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """torch says only "enforce fail at inline_container.cc ... unexpected pos" when the disk
    fills under state.pt; the user reads that the disk is full, and which file, in one line."""
    import builtins

    from curious.cli import main
    from curious.runs import checkpoint

    def small_disk(path, mode="r", *args, **kwargs):
        handle = builtins.open(path, mode, *args, **kwargs)
        return _FullDisk(handle, 4096) if str(path).endswith("state.pt") else handle

    monkeypatch.setattr(checkpoint, "open", small_disk, raising=False)
    out = tmp_path / "r"
    assert main([*SMOKE, "--no-record", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err and "enforce fail" not in err
    assert err.startswith("curious train: error: No space left on device")
    assert err.split("cannot write ")[1].startswith(
        str(out / "checkpoints" / "ep-000000000012" / "state.pt")
    )
    assert not [p for p in (out / "checkpoints").iterdir()]  # no half-written checkpoint


@pytest.mark.skipif(
    os.geteuid() != 0 or not shutil.which("mount"), reason="mounts a small tmpfs (root)"
)
def test_a_checkpoint_on_a_real_full_disk_says_so(tmp_path: Path) -> None:
    """The same on a real 1 MiB disk, where torch's own message comes back."""
    import torch

    from curious.runs import checkpoint

    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)]).returncode:
        pytest.skip("cannot mount a tmpfs here")
    try:
        with pytest.raises(checkpoint.CheckpointError) as error:
            checkpoint.save(disk, 40, {"big": torch.zeros(2**19)}, {"x": np.zeros(3)})
        assert str(error.value).startswith(
            f"No space left on device: cannot write {disk / 'ep-000000000040' / 'state.pt'}"
        )
        assert not list(disk.iterdir())
    finally:
        subprocess.run(["umount", "--lazy", str(disk)], check=True)  # even with a file open


def test_a_resume_removes_the_checkpoint_a_kill_left_over(tmp_path: Path) -> None:
    """A kill between a checkpoint's rename and the removal of the oldest one leaves three
    checkpoints; the resumed run keeps the two newest (even with nothing left to train)."""
    from toy_env import make_toy_envs

    from curious.presets import resolve
    from curious.runs.driver import train

    config = resolve("smoke", "curious", 0, dict(total_episodes=24, progress=False))
    envs = lambda c: make_toy_envs(c.seed, c.n_workers)  # noqa: E731
    train(config, tmp_path, make_envs=envs)
    kept = list_checkpoints(tmp_path / "checkpoints")
    shutil.copytree(kept[0], kept[0].with_name("ep-000000000004"))  # what the kill left
    train(config, tmp_path, resume=True, make_envs=envs)
    assert list_checkpoints(tmp_path / "checkpoints") == kept
