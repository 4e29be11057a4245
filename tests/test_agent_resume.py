"""`--resume` on a folder that was tampered with, and a run that diverges: refused or stopped in
one line, never silently losing or replacing part of the run."""

from __future__ import annotations

import gc
import hashlib
import json
import shutil
import weakref
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import torch
from toy_env import make_toy_envs

from curious.agent.agent import Agent
from curious.cli import main
from curious.presets import resolve
from curious.runs import checkpoint
from curious.runs.driver import train
from curious.runs.folder_errors import RunFolderError
from curious.runs.folder_layout import list_checkpoints
from curious.runs.trainer import TrainingDiverged

SMALL = dict(total_episodes=39, n_workers=2, episodes_per_worker=2, progress=False)
"""smoke with 2 workers: 4 episodes a cycle, an epoch of 2 cycles, a checkpoint every 3."""


def run(out: Path, stop: int | None = None, resume: bool = False, **changes) -> object:
    config = resolve("smoke", "curious", 0, {**SMALL, **changes})
    return train(
        config,
        out,
        resume=resume,
        make_envs=lambda c: make_toy_envs(c.seed, c.n_workers),
        stop_after_cycles=stop,
    )


def restart(out: Path, **changes) -> object:
    config = resolve("smoke", "curious", 0, {**SMALL, **changes})
    envs = lambda c: make_toy_envs(c.seed, c.n_workers)  # noqa: E731
    return train(config, out, restart=True, make_envs=envs)


def snapshot(folder: Path, but: tuple[str, ...] = ()) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name not in but
    }


def episodes(path: Path) -> np.ndarray:
    return pq.read_table(path, columns=["episode"])["episode"].to_numpy()


# ------------------------------------------------------------------------------ config.json

DAMAGED = {
    "a list": "[1, 2, 3]",
    "no config": '{"condition": "curious"}',
    "a number for config": '{"config": 5}',
    "garbage": "{{{ not json",
    "empty": "",
}


def test_a_damaged_config_json_is_refused_naming_the_file(tmp_path, capsys):
    out = tmp_path / "r"
    run(out, total_episodes=8)
    good = json.loads((out / "config.json").read_text())
    wrong_type = {**good, "config": {**good["config"], "hidden": "big"}}
    cases = {**DAMAGED, "a setting of the wrong type": json.dumps(wrong_type)}
    for what, text in cases.items():
        (out / "config.json").write_text(text)
        before = snapshot(out)
        with pytest.raises(RunFolderError, match=r"config\.json") as error:
            run(out, resume=True, total_episodes=16)
        assert "\n" not in str(error.value), what
        assert snapshot(out) == before, what
        args = ["train", "--preset", "smoke", "--out", str(out), "--resume", "--no-record"]
        assert main(args) == 2, what
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "config.json" in err and "Traceback" not in err, what
    assert "hidden must be an int, got 'big'" in str(error.value)


# ------------------------------------------------------------------------------ checkpoints


def test_resume_without_any_checkpoint_is_refused_and_restart_starts_over(tmp_path):
    out = tmp_path / "r"
    run(out, total_episodes=24)
    shutil.rmtree(out / "checkpoints")
    before = snapshot(out)
    with pytest.raises(RunFolderError, match=r"24 episodes in metrics.parquet.*--restart"):
        run(out, resume=True, total_episodes=32)
    assert snapshot(out) == before
    trainer = restart(out, total_episodes=8)
    assert trainer.episodes == 8
    np.testing.assert_array_equal(episodes(out / "metrics.parquet"), np.arange(8))
    info = json.loads((out / "config.json").read_text())
    assert "resumed" not in info and info["config"]["total_episodes"] == 8


def test_restart_into_a_folder_not_made_yet_starts_the_run(tmp_path):
    """`--restart` in a script that may find the folder there or not: both start a run."""
    out = tmp_path / "new" / "r"
    trainer = restart(out, total_episodes=8)
    assert trainer.episodes == 8
    np.testing.assert_array_equal(episodes(out / "metrics.parquet"), np.arange(8))


def test_restart_refuses_a_folder_holding_more_than_a_run(tmp_path):
    out = tmp_path / "r"
    run(out, total_episodes=8)
    (out / "notes.txt").write_text("mine")
    before = snapshot(out)
    with pytest.raises(RunFolderError, match=r"not a run's \(notes.txt\)"):
        restart(out, total_episodes=8)
    assert snapshot(out) == before


def test_a_run_stopped_before_its_first_checkpoint_still_resumes_from_zero(tmp_path):
    """Its rows (one checkpoint interval at most) are redone, as rows after any checkpoint."""
    out = tmp_path / "r"
    run(out, stop=3, total_episodes=24)
    shutil.rmtree(out / "checkpoints")  # as if the first checkpoint's write had failed
    trainer = run(out, resume=True, total_episodes=24)
    assert trainer.episodes == 24
    np.testing.assert_array_equal(episodes(out / "metrics.parquet"), np.arange(24))


def test_a_checkpoint_under_another_name_never_sends_the_run_back(tmp_path):
    """A copy of the 12-episode checkpoint named as episode 999 was taken as the newest for
    ever: every later resume went back to episode 12. The state's own counter decides."""
    out = tmp_path / "r"
    run(out, stop=3, total_episodes=60)
    (old,) = list_checkpoints(out / "checkpoints")
    assert old.name == "ep-000000000012"
    shutil.copytree(old, old.with_name("ep-000000000999"))
    with pytest.warns(UserWarning, match=r"holds the state of episode 12, not of episode 999"):
        trainer = run(out, stop=3, resume=True, total_episodes=60)
    assert trainer.episodes == 24
    with pytest.warns(UserWarning, match="resuming from the one before"):
        trainer = run(out, stop=1, resume=True, total_episodes=60)
    assert trainer.episodes == 28  # from 24, not from the copy's 12
    np.testing.assert_array_equal(episodes(out / "metrics.parquet"), np.arange(28))


def test_a_deleted_tests_parquet_is_refused_instead_of_leaving_a_run_without_half_its_tests(
    tmp_path,
):
    out = tmp_path / "r"
    run(out, stop=6, total_episodes=48)  # 3 epochs, each with 2 test rollouts
    assert len(pq.read_table(out / "tests.parquet")) == 6
    for damage in ("delete", "older"):
        if damage == "delete":
            saved = (out / "tests.parquet").read_bytes()
            (out / "tests.parquet").unlink()
        else:  # an older copy: the first epoch's tests only
            table = pq.read_table(out / "tests.parquet")
            pq.write_table(table.slice(0, 2), out / "tests.parquet")
        before = snapshot(out)
        with pytest.raises(RunFolderError, match=r"tests.parquet holds \d test rollouts.* 6 "):
            run(out, resume=True, total_episodes=48)
        assert snapshot(out) == before
        (out / "tests.parquet").write_bytes(saved)
    trainer = run(out, resume=True, total_episodes=48)
    assert trainer.episodes == 48
    assert len(pq.read_table(out / "tests.parquet")) == 12


def test_a_resumed_run_trains_without_a_second_copy_of_its_replay(tmp_path, monkeypatch):
    """The checkpoint's replay arrays, once copied into the trainer's replay, are let go: held
    for the rest of the run, they doubled the replay's memory (docs/benchmarks.md)."""
    out = tmp_path / "r"
    run(out, stop=3, total_episodes=24)
    loaded: list[weakref.ref] = []
    load_latest = checkpoint.load_latest

    def load_and_watch(*args, **kwargs):
        latest = load_latest(*args, **kwargs)
        loaded.extend(weakref.ref(array) for array in latest[2].values())
        return latest

    monkeypatch.setattr(checkpoint, "load_latest", load_and_watch)
    alive_while_training: list[int] = []

    def count_alive() -> bool:
        gc.collect()
        alive_while_training.append(sum(ref() is not None for ref in loaded))
        return False

    config = resolve("smoke", "curious", 0, {**SMALL, "total_episodes": 24})
    trainer = train(
        config, out, resume=True, make_envs=lambda c: make_toy_envs(c.seed, 2), stop=count_alive
    )
    assert trainer.episodes == 24
    assert len(loaded) >= 6  # states, achieved, actions, modules, goals, moved, counters
    assert alive_while_training and set(alive_while_training) == {0}


# ------------------------------------------------------------------------------ divergence


def test_a_run_that_diverges_stops_in_one_line_and_keeps_its_last_checkpoint(
    tmp_path, monkeypatch, capsys
):
    """A step that leaves the networks non-finite (what a learning rate too high does) stops
    the run with an error naming the learning rates and the episode; nothing of the diverged
    state is written, and the run resumes from its last checkpoint."""
    out = tmp_path / "r"
    run(out, stop=3, total_episodes=24)  # a checkpoint at 12 episodes
    update = Agent.update

    def diverging(self, expert, batch):
        stats = update(self, expert, batch)
        with torch.no_grad():
            for p in self.experts[expert].critics.parameters():
                p.fill_(float("inf"))
        return stats

    monkeypatch.setattr(Agent, "update", diverging)
    before = snapshot(out, but=("config.json",))
    message = r"diverged at episode 16: .*not finite \(actor_lr=0.001, critic_lr=0.001\)"
    with pytest.raises(TrainingDiverged, match=message) as error:
        run(out, resume=True, total_episodes=24)
    assert "\n" not in str(error.value)
    assert snapshot(out, but=("config.json",)) == before
    monkeypatch.undo()

    def diverging_targets(self, expert):  # the losses of the cycle stay finite
        with torch.no_grad():
            for p in self.experts[expert].critics.parameters():
                p.fill_(float("nan"))

    monkeypatch.setattr(Agent, "update_targets", diverging_targets)
    with pytest.raises(TrainingDiverged, match="episode 16: the networks' weights are not"):
        run(out, stop=1, resume=True, total_episodes=24)  # a checkpoint after this cycle
    assert snapshot(out, but=("config.json",)) == before
    monkeypatch.undo()
    trainer = run(out, resume=True, total_episodes=24)
    assert trainer.episodes == 24 and trainer.finite()
    np.testing.assert_array_equal(episodes(out / "metrics.parquet"), np.arange(24))


def test_the_command_resumes_with_the_runs_own_settings(tmp_path, capsys):
    """`curious train --out X --resume` needs none of the options the run started with, and a
    total set with --set stays the run's own (the preset's would train on past it)."""
    out, quiet = tmp_path / "r", ["--no-record", "--no-progress"]
    start = ["train", "--preset", "smoke", "--condition", "mg-te", "--seed", "3", "--out", str(out)]
    assert main([*start, *quiet, "--set", "total_episodes=8"]) == 0
    resume = ["train", "--out", str(out), "--resume", *quiet]
    assert main(resume) == 0
    np.testing.assert_array_equal(episodes(out / "metrics.parquet"), np.arange(8))
    assert main([*resume, "--set", "total_episodes=16"]) == 0
    np.testing.assert_array_equal(episodes(out / "metrics.parquet"), np.arange(16))
    config = json.loads((out / "config.json").read_text())["config"]
    assert (config["preset"], config["condition"], config["seed"]) == ("smoke", "mg-te", 3)
    capsys.readouterr()
    assert main([*resume, "--seed", "4"]) == 2  # an option given must match the run's
    assert "(seed: 3 -> 4)" in capsys.readouterr().err
    assert main([*resume, "--condition", "her"]) == 2
    assert "(condition: 'mg-te' -> 'her')" in capsys.readouterr().err
    assert main([*resume, "--set", "condition=her"]) == 2  # the condition's own option only
    assert "choose the condition with --condition, not an override" in capsys.readouterr().err


def test_a_run_made_before_a_setting_existed_resumes_as_itself(tmp_path):
    """A run whose config.json and checkpoint predate `lp_measure` computed what `absolute`
    computes (`curious.config.EARLIER_BEHAVIOUR`): it resumes and its checkpoint loads, while a
    resume asking for the other measure is refused."""
    out = tmp_path / "run"
    run(out, stop=3)
    config_json = out / "config.json"
    stored = json.loads(config_json.read_text())
    stored["config"].pop("lp_measure")
    config_json.write_text(json.dumps(stored, indent=2))
    for state_file in (out / "checkpoints").glob("ep-*/state.pt"):
        state = torch.load(state_file, map_location="cpu", weights_only=False)
        state["config"].pop("lp_measure")
        torch.save(state, state_file)
    done = run(out, resume=True)
    assert episodes(out / "metrics.parquet")[-1] == SMALL["total_episodes"] - 1
    assert done is not None
    with pytest.raises(RunFolderError, match="lp_measure"):
        run(out, resume=True, total_episodes=60, lp_measure="signed")
