"""Run folders: metrics.parquet contract, checkpoints, resume, bad input, SIGKILL, the CLI."""

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
import torch
from toy_env import make_toy_envs

from curious.agent.conditions import CONDITION_CLASSES
from curious.agent.goals import GoalInput
from curious.agent.learning_progress import CompetenceTracker
from curious.cli import main
from curious.config import ConfigError
from curious.presets import resolve
from curious.registry import condition_names
from curious.runs import checkpoint
from curious.runs.checkpoint import CheckpointError
from curious.runs.driver import train
from curious.runs.folder_errors import RunFolderError
from curious.runs.folder_layout import checkpoint_name, list_checkpoints

TESTS = Path(__file__).resolve().parent
SMALL = dict(total_episodes=39, n_workers=2, episodes_per_worker=2, progress=False)


def toy_envs(config):
    return make_toy_envs(config.seed, config.n_workers)


def run(out, condition="curious", seed=0, resume=False, **changes):
    config = resolve("smoke", condition, seed, {**SMALL, **changes})
    return train(config, out, resume=resume, make_envs=toy_envs)


def run_stop(out, stop, resume=False, **changes):
    config = resolve("smoke", "curious", 0, {**SMALL, **changes})
    return train(config, out, resume=resume, make_envs=toy_envs, stop_after_cycles=stop)


UNCOMPARED = ("elapsed",)
"""Checkpoint keys that two equal runs may still differ in: `elapsed` is wall-clock time.
Everything else, torch's global generator (`torch_rng`) included, a resumed run restores."""


def assert_same_state(
    a: Any, b: Any, where: str = "", uncompared: tuple[str, ...] = UNCOMPARED
) -> None:
    """Equal nested checkpoint states (dicts, lists, tuples, tensors and arrays bit for bit),
    but for the keys in `uncompared`."""
    assert type(a) is type(b), f"{where}: {type(a).__name__} != {type(b).__name__}"
    if isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for key in (k for k in a if k not in uncompared):
            assert_same_state(a[key], b[key], f"{where}/{key}", uncompared)
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same_state(x, y, f"{where}/{i}", uncompared)
    elif isinstance(a, torch.Tensor):
        assert a.dtype == b.dtype and torch.equal(a, b), where
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype, where
        np.testing.assert_array_equal(a, b, err_msg=where)
    else:
        assert a == b, where


def snapshot(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.mark.parametrize("condition", condition_names())  # a plugin's among them
def test_run_folder_holds_config_metrics_and_checkpoint(tmp_path, condition):
    trainer = run(tmp_path / "run", condition)
    folder = tmp_path / "run"
    info = json.loads((folder / "config.json").read_text())
    assert (info["condition"], info["seed"], info["preset"]) == (condition, 0, "smoke")
    assert info["modules"] == ["reach", "dial", "beacon"]
    assert info["achievable"] == [True, True, False]
    assert info["config"]["total_episodes"] == 39
    assert set(info["versions"]) >= {"torch", "numpy", "mujoco", "dm-control", "python"}
    assert "commit" in info["git"]

    table = pq.read_table(folder / "metrics.parquet")
    names = ["reach", "dial", "beacon"]
    expected = ["episode", "worker", "module", "g0", "g1", "g2", "success", "eval"]
    expected += ["sensor_failure"]
    expected += [f"{p}/{n}" for p in ("competence", "lp", "p_lp") for n in names] + ["wall_time"]
    assert table.schema.names == expected
    types = {f.name: str(f.type) for f in table.schema}
    assert types["episode"] == "int64" and types["worker"] == "int32"
    assert types["module"] == "string" and types["g0"] == "float"
    assert types["success"] == "bool" and types["eval"] == "bool"
    assert types["p_lp/dial"] == "float" and types["wall_time"] == "double"
    df = table.to_pandas()
    # episodes counted exactly (39 is not a multiple of the 4 episodes per cycle)
    assert trainer.episodes == 39
    np.testing.assert_array_equal(df["episode"], np.arange(39))
    if not CONDITION_CLASSES[condition].self_evaluates:  # HER: no competence
        assert not df["eval"].any()
        assert df[[f"competence/{n}" for n in names]].isna().all().all()
    else:
        assert df["eval"].sum() == 39 // 5 and np.all(df["episode"][df["eval"]] % 5 == 4)
    assert set(df["module"]) <= set(names)
    p = df[[f"p_lp/{n}" for n in names]].to_numpy()
    np.testing.assert_allclose(p.sum(1), 1, rtol=1e-5)
    assert np.all(np.diff(df["wall_time"]) >= 0)
    assert len(list_checkpoints(folder / "checkpoints")) == 2  # the newest and the one before


CUDA = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")


@pytest.mark.parametrize("device", ["cpu", pytest.param("cuda", marks=CUDA)])
@pytest.mark.parametrize("overlap", [False, True])
def test_resume_gives_the_same_run_as_no_interruption(tmp_path, overlap, device):
    """A run stopped and resumed from its checkpoint is the run never stopped: the same final
    checkpoint (every part of it but its wall-clock time), episodes and test rollouts."""
    common = dict(
        total_episodes=48, checkpoint_every_cycles=3, overlap_rollouts=overlap, device=device
    )
    whole = run_stop(tmp_path / "whole", stop=None, **common)
    assert whole.episodes == 48
    # A kill resumes from a checkpoint: overlapped, checkpoints collect the rounds in flight,
    # so the split is taken at a checkpoint cycle (6), where the whole run drained them too.
    first = run_stop(tmp_path / "split", stop=6 if overlap else 5, **common)
    assert first.episodes == (32 if overlap else 20)
    rest = run_stop(tmp_path / "split", stop=None, resume=True, **common)
    assert rest.episodes == 48
    # the final checkpoints, whole: every expert, optimiser, normaliser, queue, RNG and replay
    final = [checkpoint.load_latest(tmp_path / f / "checkpoints") for f in ("whole", "split")]
    assert [path.name for path, _, _ in final] == [checkpoint_name(48)] * 2
    assert_same_state(final[0][1:], final[1][1:])
    df_a = pq.read_table(tmp_path / "whole" / "metrics.parquet").to_pandas()
    df_b = pq.read_table(tmp_path / "split" / "metrics.parquet").to_pandas()
    cols = [c for c in df_a.columns if c != "wall_time"]
    assert df_a[cols].equals(df_b[cols])
    tests_a = pq.read_table(tmp_path / "whole" / "tests.parquet").to_pandas()
    tests_b = pq.read_table(tmp_path / "split" / "tests.parquet").to_pandas()
    cols = [c for c in tests_a.columns if c != "wall_time"]
    assert len(tests_a) and tests_a[cols].equals(tests_b[cols])
    resumed = json.loads((tmp_path / "split" / "config.json").read_text())["resumed"]
    assert len(resumed) == 1


def test_test_rollouts_follow_every_epoch_and_change_nothing_of_training(tmp_path):
    """The authors' evaluator: after every epoch, noise-free test rollouts on uniformly drawn
    modules (flowersteam/curious, baselines/her/experiment/train.py and config.py:
    n_test_rollouts 5 x rollout_batch_size 2 = 10 per worker)."""
    assert resolve("paper").test_rollouts_per_worker == 10
    tested = run(tmp_path / "tested", test_rollouts_per_worker=3)
    untested = run(tmp_path / "untested", test_rollouts_per_worker=0)
    tests = pq.read_table(tmp_path / "tested" / "tests.parquet").to_pandas()
    assert not (tmp_path / "untested" / "tests.parquet").exists()
    # smoke: an epoch is 2 cycles of 4 episodes; 39 episodes end inside the 5th epoch
    per_epoch = 3 * 2
    assert list(tests["epoch"].unique()) == [0, 1, 2, 3, 4]
    assert (tests.groupby("epoch").size() == per_epoch).all()
    np.testing.assert_array_equal(tests["episode"].unique(), [8, 16, 24, 32, 39])
    assert set(tests["module"]) == {"reach", "dial", "beacon"}  # drawn uniformly
    assert tests["success"].dtype == bool
    a = pq.read_table(tmp_path / "tested" / "metrics.parquet").to_pandas()
    b = pq.read_table(tmp_path / "untested" / "metrics.parquet").to_pandas()
    cols = [c for c in a.columns if c != "wall_time"]
    assert a[cols].equals(b[cols])
    for x, y in zip(
        tested.agent.experts[0].actor.parameters(),
        untested.agent.experts[0].actor.parameters(),
        strict=True,
    ):
        assert torch.equal(x, y)


def test_resume_may_extend_a_finished_run(tmp_path):
    run_stop(tmp_path / "r", stop=None, total_episodes=12)
    trainer = run_stop(tmp_path / "r", stop=None, resume=True, total_episodes=20)
    assert trainer.episodes == 20
    df = pq.read_table(tmp_path / "r" / "metrics.parquet").to_pandas()
    np.testing.assert_array_equal(df["episode"], np.arange(20))


def test_non_empty_folder_without_resume_is_refused_untouched(tmp_path):
    run(tmp_path / "r")
    before = snapshot(tmp_path / "r")
    with pytest.raises(RunFolderError, match="not empty; pass --resume"):
        run(tmp_path / "r")
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(RunFolderError, match="not empty"):
        run(other)
    assert snapshot(tmp_path / "r") == before
    assert [p.name for p in other.iterdir()] == ["notes.txt"]


def test_resume_with_another_config_is_refused_untouched(tmp_path):
    run(tmp_path / "r")
    before = snapshot(tmp_path / "r")
    with pytest.raises(RunFolderError, match=r"different config \(hidden: 32 -> 64"):
        run(tmp_path / "r", resume=True, hidden=64)
    assert snapshot(tmp_path / "r") == before


def test_checkpoint_from_another_config_is_refused_untouched(tmp_path):
    run(tmp_path / "seed1", seed=1)
    run_stop(tmp_path / "seed0", stop=2)
    shutil.rmtree(tmp_path / "seed0" / "checkpoints")
    shutil.copytree(tmp_path / "seed1" / "checkpoints", tmp_path / "seed0" / "checkpoints")
    before = snapshot(tmp_path / "seed0")
    with pytest.raises(CheckpointError, match=r"another config .*seed"):
        run(tmp_path / "seed0", resume=True)
    assert snapshot(tmp_path / "seed0") == before


def test_a_trainer_refusing_another_runs_checkpoint_keeps_its_replay(tmp_path):
    """A checkpoint's replay is read into the replay's own arrays only while it is empty: a
    trainer with episodes that loads another run's checkpoint, refused after the read, still
    holds its own."""
    from curious.envs.batch import LocalEnvs
    from curious.runs.trainer import Trainer

    def trainer(seed: int) -> Trainer:
        config = resolve("smoke", "curious", seed, SMALL)
        return Trainer(config, LocalEnvs(toy_envs(config)))

    other, own = trainer(0), trainer(1)
    try:
        for t in (other, own):
            t.cycle()
        path = other.save_checkpoint(tmp_path / "other")
        kept = {key: array[: own.replay.size].copy() for key, array in own.replay.arrays().items()}
        with pytest.raises(CheckpointError, match=r"another config .*seed"):
            own.load_checkpoint(path)
        for key, array in own.replay.arrays().items():
            np.testing.assert_array_equal(array[: own.replay.size], kept[key], err_msg=key)
    finally:
        other.close()
        own.close()


def test_nothing_to_resume(tmp_path):
    with pytest.raises(RunFolderError, match="nothing to resume"):
        run(tmp_path / "absent", resume=True)


KILL_SCRIPT = textwrap.dedent(
    """
    import sys
    sys.path.insert(0, {tests!r})
    from toy_env import make_toy_envs
    from curious.presets import resolve
    from curious.runs.driver import train
    config = resolve("smoke", "curious", 0, dict(
        total_episodes=10**7, n_workers=2, checkpoint_every_cycles=1, progress=False,
        buffer_episodes=64))
    train(config, {out!r}, make_envs=lambda c: make_toy_envs(c.seed, c.n_workers))
    """
)


def kill_after_a_checkpoint(script: str, out: Path, episodes: int = 40, wait: float = 90) -> int:
    """Run a training script, SIGKILL it once it has a checkpoint at `episodes` or more, and
    return the episodes of the last checkpoint it left."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.Popen([sys.executable, "-c", script], env=env)
    try:
        deadline = time.time() + wait
        while time.time() < deadline:
            ckpts = list_checkpoints(out / "checkpoints")
            if ckpts and int(ckpts[-1].name[3:]) >= episodes:
                break
            assert proc.poll() is None, "training process ended early"
            time.sleep(0.05)
        else:
            pytest.fail(f"no checkpoint after {wait} s")
        time.sleep(0.1)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    return int(list_checkpoints(out / "checkpoints")[-1].name[3:])


def test_sigkill_leaves_readable_metrics_and_a_resumable_run(tmp_path):
    out = tmp_path / "killed"
    kill_after_a_checkpoint(KILL_SCRIPT.format(tests=str(TESTS), out=str(out)), out)
    df = pq.read_table(out / "metrics.parquet").to_pandas()  # readable after SIGKILL
    np.testing.assert_array_equal(df["episode"], np.arange(len(df)))
    saved = int(list_checkpoints(out / "checkpoints")[-1].name[3:])
    assert len(df) >= saved - 4  # at most one checkpoint interval (one cycle) lost
    trainer = run_stop(
        out,
        stop=None,
        resume=True,
        total_episodes=saved + 8,
        checkpoint_every_cycles=1,
        buffer_episodes=64,
        n_workers=2,
    )
    assert trainer.episodes == saved + 8
    df = pq.read_table(out / "metrics.parquet").to_pandas()
    np.testing.assert_array_equal(df["episode"], np.arange(saved + 8))


def test_cli_tells_its_version_and_helps_with_real_names_and_defaults(capsys):
    import suite

    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out.startswith("curious 0.")
    for command in (["train", "--help"], ["render", "--help"]):
        with pytest.raises(SystemExit):
            main(command)
        text = capsys.readouterr().out
        assert "variants: " + ", ".join(suite.ALL_VARIANTS) in text
        assert "{variants}" not in text and "{modules}" not in text  # placeholders filled
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    assert "(default 50)" in " ".join(capsys.readouterr().out.split())  # --rollout-every


def test_every_command_and_benchmark_prints_its_help(capsys):
    from curious.cli import COMMAND_MODULES
    from curious.commands.bench import BENCHMARKS

    commands = [[module.rsplit(".", 1)[1]] for module in COMMAND_MODULES]  # train, view, ...
    commands += [["bench", name] for name in BENCHMARKS]
    for command in [[], *commands]:
        with pytest.raises(SystemExit) as exit_:
            main([*command, "--help"])
        assert exit_.value.code == 0, command
        assert capsys.readouterr().out.startswith("usage: curious"), command


def test_the_sub_commands_import_nothing_from_the_command_line_that_loads_them():
    """One-way dependency: `curious.cli` (the `curious` console script) loads the sub-command
    modules; none of them imports `curious.cli` back (what they share is `curious.commands`)."""
    import ast
    import importlib
    import inspect

    from curious.cli import COMMAND_MODULES

    for name in ("curious.commands", *COMMAND_MODULES):
        tree = ast.parse(inspect.getsource(importlib.import_module(name)))
        imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        assert "curious.cli" not in imported, name


@pytest.mark.parametrize(
    "command",
    [
        [],
        ["train"],
        ["bench"],
        ["progress"],
        ["ship"],
        ["reproduce"],
        ["render"],
        ["evaluate"],
        ["view"],
    ],
)
def test_help_imports_nothing_heavy(command):
    """`curious --help` builds every sub-command's parser; it and the sub-commands' own help
    import none of the libraries that take seconds to load (a benchmark's module, with torch
    and MuJoCo, is imported only for `curious bench NAME`)."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from curious.cli import main\n"
        "try:\n"
        f"    main({[*command, '--help']!r})\n"
        "except SystemExit:\n"
        "    pass\n"
        "heavy = ('torch', 'mujoco', 'dm_control', 'pandas', 'dagster', 'rerun', 'matplotlib')\n"
        "print([m for m in heavy if m in sys.modules], file=sys.stderr)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stderr.strip().splitlines()[-1] == "[]", (command, done.stderr)


def test_without_a_display_the_commands_that_do_not_render_say_nothing_of_gl():
    """dm_control tries GLFW when MUJOCO_GL is unset and warns that DISPLAY is missing."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY")}
    env.pop("WAYLAND_DISPLAY", None)
    command = [sys.executable, "-m", "curious.cli", "train", "--help"]
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "variants: default" in done.stdout
    assert "GLFW" not in done.stderr and "DISPLAY" not in done.stderr, done.stderr


def test_cli_reports_bad_input_in_one_line(tmp_path, capsys):
    out = str(tmp_path / "r")
    cases = [
        (["--condition", "curiouser"], "unknown condition 'curiouser'"),
        (["--preset", "weekend"], "unknown preset 'weekend'"),
        (["--set", "hiden=3"], "unknown config key 'hiden'"),
        (["--set", "n_workers=two"], "n_workers='two': expected an integer"),
    ]
    for extra, message in cases:
        assert main(["train", "--out", out, "--no-record", *extra]) == 2
        err = capsys.readouterr().err
        assert message in err and err.startswith("curious train: error:")
    assert not (tmp_path / "r").exists()
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "x").write_text("keep")
    assert main(["train", "--out", out, "--preset", "smoke", "--no-record"]) == 2
    assert "not empty; pass --resume" in capsys.readouterr().err
    assert (tmp_path / "r" / "x").read_text() == "keep"
    assert main(["train", "--out", str(tmp_path / "none"), "--resume", "--no-record"]) == 2
    assert "nothing to resume" in capsys.readouterr().err


def test_td3_option_trains(tmp_path):
    trainer = run(tmp_path / "td3", algorithm="td3", total_episodes=12)
    assert trainer.episodes == 12 and len(trainer.agent.experts[0].critics) == 2


class CountingObserver:
    def __init__(self):
        self.rounds, self.steps, self.ended = [], [], []

    def watched(self, episodes, evaluation):
        return []

    def begin_round(self, episodes, modules, goals, evaluation, envs):
        self.rounds.append((episodes.copy(), len(envs)))
        self.steps.append([])

    def after_step(self, t):
        self.steps[-1].append(t)

    def end_round(self, info):
        self.ended.append(info.episodes.copy())
        assert info.data.states.shape[1] == 11  # toy episodes: 10 steps


class ListRecorder:
    def __init__(self):
        self.calls = []

    def log_episodes(self, **columns):
        self.calls.append(("episodes", columns))

    def log_replay(self, episode, counts, wall_time):
        self.calls.append(("replay", episode, counts))

    def log_learner(self, episode, losses, q, wall_time):
        self.calls.append(("learner", episode, losses, q))

    def log_tests(self, episode, module, success, wall_time):
        self.calls.append(("tests", episode, module, success))

    def checkpoint(self):
        self.calls.append(("checkpoint",))

    def close(self):
        self.calls.append(("close",))

    def close_after_error(self):
        self.calls.append(("close_after_error",))


def test_observer_and_recorder_hooks_are_called_in_order(tmp_path):
    observer, recorder = CountingObserver(), ListRecorder()

    def make_recorder(trainer, folder):
        trainer.observer = observer
        return recorder

    config = resolve("smoke", "curious", 0, {**SMALL, "total_episodes": 10})
    train(config, tmp_path / "r", make_envs=toy_envs, make_recorder=make_recorder)
    # rounds of 2 parallel episodes, the last one cut to what is left
    assert [len(e) for e, _ in observer.rounds] == [2, 2, 2, 2, 2]
    assert all(steps == list(range(11)) for steps in observer.steps)
    np.testing.assert_array_equal(np.concatenate(observer.ended), np.arange(10))
    kinds = [c[0] for c in recorder.calls]
    # 3 cycles; the second ends the first epoch and the third the run: each brings its tests
    cycle, tested = ["episodes", "replay", "learner"], ["episodes", "tests", "replay", "learner"]
    assert kinds == cycle + tested * 2 + ["checkpoint", "close"]  # one checkpoint, at the end
    episodes = recorder.calls[0][1]
    assert episodes["competence"].shape == (4, 3) and list(episodes["episode"]) == [0, 1, 2, 3]
    assert recorder.calls[1][2].sum() == 4 * 2 * 32  # n_updates x batch substitutions


def test_a_run_written_before_a_setting_existed_is_refused_clearly(tmp_path):
    run(tmp_path / "r")
    path = tmp_path / "r" / "config.json"
    info = json.loads(path.read_text())
    del info["config"]["test_rollouts_per_worker"]  # as a version without that setting wrote it
    path.write_text(json.dumps(info))
    before = snapshot(tmp_path / "r")
    with pytest.raises(RunFolderError, match="lacks test_rollouts_per_worker"):
        run(tmp_path / "r", resume=True, total_episodes=60)
    assert snapshot(tmp_path / "r") == before


def sensor_failure_trainer(**changes):
    from curious.envs.batch import LocalEnvs
    from curious.envs.goal_env import make_suite_envs
    from curious.runs.trainer import Trainer

    config = resolve("smoke", "curious", 0, {"variant": "sensor_failure", **changes})
    envs = LocalEnvs(make_suite_envs(config.variant, 0, config.n_workers))
    tests = LocalEnvs(make_suite_envs(config.variant, 0, config.n_workers, stream=1))
    return Trainer(config, envs, tests)


def test_sensory_failure_starts_when_the_perturbed_module_is_learned(tmp_path):
    trainer = sensor_failure_trainer(sensor_failure_competence=0.75)
    module = trainer.spec.module_index("push_cube3")
    assert trainer.failure.module == module
    rows = trainer.cycle().rows
    assert trainer.failure.start is None and not rows["sensor_failure"].any()
    trainer.tracker = CompetenceTracker(
        trainer.spec.n_modules, trainer.config.lp_window, trainer.config.lp_measure
    )
    for _ in range(trainer.config.lp_window - 1):  # competence 1.0 over less than a window
        trainer.tracker.add(module, True)
    trainer.failure.start_if_due(trainer.episodes, trainer.tracker)
    assert trainer.failure.start is None
    trainer.tracker.add(module, True)  # a full window at competence >= 0.75
    started_at = trainer.episodes
    result = trainer.cycle()
    assert trainer.failure.start == started_at
    assert result.rows["sensor_failure"].all()
    assert all(env._task.sensor_failure for env in trainer.envs.envs)
    assert all(env._task.sensor_failure for env in trainer.test_envs.envs)  # tests, after an epoch
    # the onset survives a checkpoint
    path = trainer.save_checkpoint(tmp_path / "checkpoints")
    again = sensor_failure_trainer(sensor_failure_competence=0.75)
    again.load_checkpoint(path)
    assert again.failure.start == started_at


def test_sensory_failure_settings_are_checked(tmp_path):
    with pytest.raises(ConfigError, match="not both"):
        resolve("smoke", overrides={"sensor_failure_episode": 5, "sensor_failure_competence": 0.5})
    with pytest.raises(ConfigError, match="sensor_failure_competence"):
        resolve("smoke", overrides={"sensor_failure_competence": 1.5})
    with pytest.raises(ConfigError, match="set_sensor_failure"):
        run(tmp_path / "toy", sensor_failure_competence=0.5)  # the toy env has no failure
    assert not (tmp_path / "toy").exists()
    with pytest.raises(ConfigError, match="sensory failure"):
        sensor_failure_trainer(variant="default", sensor_failure_competence=0.5)


def test_a_second_process_cannot_train_in_a_folder_being_trained(tmp_path):
    from curious.runs.folder_errors import RunFolderBusy

    out = tmp_path / "run"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\n"
            "from curious.runs.folder_lock import folder_lock\n"
            f"with folder_lock({str(out)!r}):\n"
            "    print('held', flush=True)\n"
            "    time.sleep(60)\n",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(RunFolderBusy, match=r"is being trained by .* pid"):
            run(out)
        assert not out.exists()
    finally:
        holder.kill()
        holder.wait()
    run(out)  # the lock died with its process


def test_a_run_folder_under_a_file_is_a_one_line_error(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    out = str(tmp_path / "file" / "run")
    assert main(["train", "--preset", "smoke", "--out", out, "--no-record"]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err


def test_resume_refuses_a_run_whose_metrics_are_gone(tmp_path):
    run(tmp_path / "r")
    (tmp_path / "r" / "metrics.parquet").unlink()
    with pytest.raises(RunFolderError, match="rows are missing"):
        run(tmp_path / "r", resume=True, total_episodes=60)


@pytest.mark.parametrize(
    ("table", "damage", "reason"),
    [
        ("metrics.parquet", b"not a table", "Parquet magic bytes not found in footer"),
        ("tests.parquet", b"", "Parquet file size is 0 bytes"),
    ],
    ids=["garbage", "empty"],
)
def test_resume_refuses_a_damaged_table_naming_it_and_writes_nothing(
    table, damage, reason, tmp_path
):
    """A table a run cannot be read back from (a crash of another tool, a copy cut short) is
    named with the way out, as a missing one is, and not in pyarrow's words alone."""
    run(tmp_path / "r")
    (tmp_path / "r" / table).write_bytes(damage)
    before = {p: p.read_bytes() for p in (tmp_path / "r").rglob("*") if p.is_file()}
    with pytest.raises(RunFolderError) as caught:
        run(tmp_path / "r", resume=True, total_episodes=60)
    message = str(caught.value)
    assert message.startswith(f"{tmp_path / 'r' / table} is damaged, not a table the run can")
    assert f"({reason}" in message and message.endswith("or start the run over with --restart")
    assert message.count(str(tmp_path)) == 1
    after = {p: p.read_bytes() for p in (tmp_path / "r").rglob("*") if p.is_file()}
    assert after == before


def test_a_damaged_newest_checkpoint_falls_back_to_the_one_before(tmp_path):
    run_stop(tmp_path / "r", stop=4, total_episodes=60, checkpoint_every_cycles=2)
    found = list_checkpoints(tmp_path / "r" / "checkpoints")
    assert len(found) == 2  # the newest and the one before are kept
    own = json.loads((found[-1] / "replay.json").read_text())["segments"][-1][0]
    (found[-1].parent / "replay" / own).write_bytes(b"PK\x03\x04 truncated")  # its own episodes
    (tmp_path / "r" / "checkpoints" / "ep-000000000016.bak").mkdir()  # a stray folder
    with pytest.warns(UserWarning, match="resuming from the one before"):
        trainer = run_stop(
            tmp_path / "r", stop=None, resume=True, total_episodes=60, checkpoint_every_cycles=2
        )
    assert trainer.episodes == 60
    episodes = pq.read_table(tmp_path / "r" / "metrics.parquet")["episode"].to_numpy()
    np.testing.assert_array_equal(episodes, np.arange(60))


def test_a_checkpoint_that_cannot_be_written_is_a_clear_error(tmp_path, monkeypatch):
    import errno

    from curious.runs import checkpoint

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(checkpoint.np, "savez", full)
    with pytest.raises(CheckpointError, match=r"No space left on device: cannot write .*\.npz"):
        run(tmp_path / "r")
    assert not [p for p in (tmp_path / "r" / "checkpoints").iterdir() if p.name.startswith(".")]


RECORDED_KILL_SCRIPT = textwrap.dedent(
    """
    import sys
    sys.path.insert(0, {tests!r})
    from toy_env import make_toy_envs
    from curious.presets import resolve
    from curious.watching.recording.settings import RecorderSettings
    from curious.watching.recording.rollout_capture import recorder_factory
    from curious.runs.driver import train
    config = resolve("smoke", "curious", 0, dict(
        total_episodes=10**7, n_workers=2, checkpoint_every_cycles=1, progress=False,
        buffer_episodes=64))
    make = recorder_factory(False, RecorderSettings(rollout_every=0))
    train(config, {out!r}, make_envs=lambda c: make_toy_envs(c.seed, c.n_workers),
          make_recorder=make)
    """
)


def recorded_episodes(path: Path) -> np.ndarray:
    """Every episode the recording holds a module point for (one per episode)."""
    from curious.watching.recording.reader import read_scalars

    names = ("T1-reach", "dial", "beacon")  # entity parts: the paper's T1 leads (the legend)
    found = [read_scalars(path, f"module/{name}")[0] for name in names]
    return np.sort(np.concatenate([np.asarray(e) for e in found]))


def test_sigkill_leaves_a_whole_recording_that_a_resume_continues_without_a_gap(tmp_path):
    from curious.watching.recording.rollout_capture import recorder_factory
    from curious.watching.recording.settings import RecorderSettings

    out = tmp_path / "killed"
    saved = kill_after_a_checkpoint(
        RECORDED_KILL_SCRIPT.format(tests=str(TESTS), out=str(out)), out
    )
    held = recorded_episodes(out / "recording.rrd")  # a whole file after the kill
    assert held.max() >= saved - 1 - 4  # at most one checkpoint interval behind
    np.testing.assert_array_equal(held, np.arange(len(held)))
    config = resolve(
        "smoke",
        "curious",
        0,
        {**SMALL, "total_episodes": saved + 8, "checkpoint_every_cycles": 1, "buffer_episodes": 64},
    )
    make = recorder_factory(True, RecorderSettings(rollout_every=0))
    train(config, out, resume=True, make_envs=toy_envs, make_recorder=make)
    np.testing.assert_array_equal(recorded_episodes(out / "recording.rrd"), np.arange(saved + 8))
    assert not (out / ".recording.rrd.part").exists()


def test_a_damaged_recording_does_not_stop_a_resume(tmp_path):
    from curious.watching.recording.rollout_capture import recorder_factory
    from curious.watching.recording.settings import RecorderSettings

    settings = RecorderSettings(rollout_every=0)
    config = resolve("smoke", "curious", 0, {**SMALL, "total_episodes": 16})
    train(
        config, tmp_path / "r", make_envs=toy_envs, make_recorder=recorder_factory(False, settings)
    )
    (tmp_path / "r" / "recording.rrd").write_bytes(b"RRF2 cut")
    longer = resolve("smoke", "curious", 0, {**SMALL, "total_episodes": 24})
    with (
        pytest.warns(RuntimeWarning, match="could not be read"),
        pytest.warns(RuntimeWarning, match="had no readable recording to resume"),
    ):
        train(
            longer,
            tmp_path / "r",
            resume=True,
            make_envs=toy_envs,
            make_recorder=recorder_factory(True, settings),
        )
    assert (tmp_path / "r" / "recording.rrd.unreadable").exists()
    np.testing.assert_array_equal(
        recorded_episodes(tmp_path / "r" / "recording.rrd"), np.arange(24)
    )


def test_overlapped_rollouts_act_with_the_policy_from_before_the_updates(tmp_path, monkeypatch):
    """With overlap_rollouts, the next cycle's episodes are collected during this cycle's
    updates by a copy of the policy taken before them: acting lags learning by one cycle."""
    from curious.agent.agent import Agent
    from curious.envs.batch import LocalEnvs
    from curious.runs.trainer import Trainer

    copies = []
    original = Agent.acting_copy

    def recorded(self, device=None):
        copies.append(original(self, device))
        return copies[-1]

    monkeypatch.setattr(Agent, "acting_copy", recorded)
    config = resolve("smoke", "curious", 0, {**SMALL, "overlap_rollouts": True})
    trainer = Trainer(config, LocalEnvs(toy_envs(config)))
    try:
        before = [p.detach().clone() for p in trainer.agent.experts[0].actor.parameters()]
        trainer.cycle()  # collects its own rounds, then the next cycle's beside the updates
        assert len(copies) == 1 and trainer._ahead.in_flight
        frozen = list(copies[0].experts[0].actor.parameters())
        live = list(trainer.agent.experts[0].actor.parameters())
        assert all(torch.equal(f, b) for f, b in zip(frozen, before, strict=True))
        assert any(not torch.equal(f, p) for f, p in zip(frozen, live, strict=True))
        result = trainer.cycle(drain=True)  # the rounds in flight, then the next ones, stored
        assert not trainer._ahead.in_flight and len(result.rows["episode"]) == 8
        np.testing.assert_array_equal(result.rows["episode"], np.arange(4, 12))
    finally:
        trainer.close()


def test_a_full_disk_under_the_recording_is_a_clear_error_and_the_run_resumes(
    tmp_path, monkeypatch
):
    """Disk full while the recording is made durable at a checkpoint: the error says so and
    names the file (Rerun alone says "File-writer thread shut down prematurely"), no
    temporary file is left, and a resume once there is room gives the whole recording."""
    import errno
    import shutil

    from curious.watching.recording import rrd_files
    from curious.watching.recording.rollout_capture import recorder_factory
    from curious.watching.recording.settings import RecorderSettings

    settings = RecorderSettings(rollout_every=0)
    config = resolve(
        "smoke", "curious", 0, {**SMALL, "total_episodes": 32, "checkpoint_every_cycles": 1}
    )
    copies = []

    def full_at_the_third(source, target):
        copies.append(target)
        if len(copies) == 3:
            raise OSError(errno.ENOSPC, "No space left on device", str(source))
        return shutil.copyfile(source, target)

    monkeypatch.setattr(rrd_files.shutil, "copyfile", full_at_the_third)
    out = tmp_path / "r"
    with pytest.raises(OSError, match="No space left on device") as error:
        train(config, out, make_envs=toy_envs, make_recorder=recorder_factory(False, settings))
    assert error.value.errno == errno.ENOSPC and error.value.filename == str(out / "recording.rrd")
    assert not list(out.glob(".recording.rrd.*"))  # neither the working file nor a half copy
    monkeypatch.undo()
    train(
        config, out, resume=True, make_envs=toy_envs, make_recorder=recorder_factory(True, settings)
    )
    np.testing.assert_array_equal(recorded_episodes(out / "recording.rrd"), np.arange(32))


def test_a_sink_that_dies_on_a_full_disk_is_named_as_one(tmp_path, monkeypatch):
    import errno
    from collections import namedtuple

    from curious.watching.recording import rrd_files

    class DeadSink:
        def flush(self, timeout_sec):
            raise RuntimeError("File-writer thread shut down prematurely")

    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(rrd_files.shutil, "disk_usage", lambda path: usage(10**9, 10**9, 4096))
    with pytest.raises(OSError) as full:
        rrd_files.flush_to_file(DeadSink(), tmp_path / "x.rrd")
    assert full.value.errno == errno.ENOSPC and "File-writer" in str(full.value)
    monkeypatch.setattr(rrd_files.shutil, "disk_usage", lambda path: usage(10**12, 0, 10**12))
    with pytest.raises(OSError, match=r"could not be written to .*x\.rrd: File-writer") as other:
        rrd_files.flush_to_file(DeadSink(), tmp_path / "x.rrd")
    assert other.value.errno is None


@pytest.mark.parametrize("overlap", [False, True])
def test_prefetched_minibatches_give_the_same_run(tmp_path, overlap):
    """`prefetch_minibatches` draws the next minibatch beside the update: same draws, same
    order, so the same networks and the same metrics, with or without overlapped rollouts."""
    runs = [
        run(tmp_path / f"p{prefetch}", overlap_rollouts=overlap, prefetch_minibatches=prefetch)
        for prefetch in (False, True)
    ]
    states = [trainer.agent.state_dict()["experts"] for trainer in runs]
    for a, b in zip(*states, strict=True):
        for key in ("actor", "critics"):
            for name, tensor in a[key].items():
                assert torch.equal(tensor, b[key][name]), (key, name)
    tables = [pq.read_table(tmp_path / f"p{p}" / "metrics.parquet") for p in (False, True)]
    assert tables[0].drop(["wall_time"]).equals(tables[1].drop(["wall_time"]))


def test_an_acting_copy_on_another_device_acts_as_the_agent(tmp_path):
    """`act_on_cpu` hands the rollouts a CPU copy of the actors: it picks the same actions
    (here from a CPU agent; on CUDA, float rounding aside) and stays put while the agent
    learns. A run with the setting on a CPU is the same run (the setting is for CUDA)."""
    from curious.envs.batch import LocalEnvs
    from curious.runs.trainer import Trainer

    config = resolve("smoke", "curious", 0, SMALL)
    trainer = Trainer(config, LocalEnvs(toy_envs(config)))
    try:
        trainer.cycle()
        agent = trainer.agent
        twin = agent.acting_copy("cpu")
        assert twin.device == torch.device("cpu") and twin.encoder is agent.encoder
        rng = np.random.default_rng(0)
        n, spec = 3, trainer.spec
        states = rng.normal(size=(n, spec.state_dim)).astype(np.float32)
        goals = rng.uniform(-1, 1, (n, spec.n_modules, spec.goal_dim)).astype(np.float32)
        mask, task = np.ones((n, spec.n_modules)), np.eye(spec.n_modules)[[0, 1, 0]]
        experts, calm = np.zeros(n, np.int64), np.zeros(n, bool)
        args = (states, GoalInput(goals, mask, task), experts, calm, rng)
        np.testing.assert_array_equal(agent.act(*args), twin.act(*args))
    finally:
        trainer.close()
    plain = run(tmp_path / "plain")
    on_cpu = run(tmp_path / "cpu", act_on_cpu=True)
    for p, q in zip(
        plain.agent.experts[0].actor.parameters(),
        on_cpu.agent.experts[0].actor.parameters(),
        strict=True,
    ):
        assert torch.equal(p, q)


def test_a_trainer_given_a_list_of_copies_says_to_wrap_it_in_local_envs():
    """`Trainer` takes its copies as an `EnvBatch`, the test rollouts' too."""
    from curious.envs.batch import LocalEnvs
    from curious.runs.trainer import Trainer

    config = resolve("smoke", "curious", 0, SMALL)
    wrap = "got list: wrap a list of copies in curious.envs.batch.LocalEnvs"
    with pytest.raises(TypeError, match=wrap):
        Trainer(config, toy_envs(config))
    with pytest.raises(TypeError, match=wrap):
        Trainer(config, LocalEnvs(toy_envs(config)), toy_envs(config))
