"""Bad input to the command line: one line on stderr, a non-zero exit, nothing written.

`MUJOCO_GL` set to what MuJoCo cannot load (only `render` needs GL), seeds out of range, an
empty `--out`, settings that would exhaust the machine or cannot learn, and the lock files of
refused commands.
"""

from __future__ import annotations

import ctypes.util
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from curious.cli import main
from curious.config import MAX_SEED, ConfigError
from curious.presets import resolve
from curious.reproduction.experiments import ExperimentError

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "data" / "laptop"


def cli(
    args: list[str], mujoco_gl: str | None, timeout: float = 240
) -> subprocess.CompletedProcess:
    """`python -m curious.cli ARGS` in a fresh process with this `MUJOCO_GL` (None: unset)."""
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    env["OMP_NUM_THREADS"] = "1"
    if mujoco_gl is not None:
        env["MUJOCO_GL"] = mujoco_gl
    command = [sys.executable, "-m", "curious.cli", *args]
    return subprocess.run(
        command, env=env, cwd=ROOT, capture_output=True, text=True, timeout=timeout
    )


def one_line(stderr: str) -> str:
    """The single line of an error report (asserting there is one, without a traceback)."""
    assert "Traceback" not in stderr, stderr[-2000:]
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr[-2000:]
    return lines[0]


# ------------------------------------------------------------------------------ MUJOCO_GL


def test_a_mujoco_gl_that_cannot_load_breaks_no_command_but_render(tmp_path):
    out = tmp_path / "run"
    done = cli(["--help"], "nonsense")
    assert done.returncode == 0 and done.stdout.startswith("usage: curious"), done.stderr[-2000:]
    done = cli(["render", "--help"], "nonsense")  # the help needs no GL either
    assert done.returncode == 0 and "variants: default" in done.stdout, done.stderr[-2000:]
    train = ["train", "--preset", "smoke", "--out", str(out), "--no-record", "--no-progress"]
    done = cli([*train, "--set", "total_episodes=4"], "nonsense")
    assert done.returncode == 0 and "4 episodes in" in done.stdout, done.stderr[-2000:]
    frames = tmp_path / "frames"
    done = cli(["render", "--out", str(frames)], "nonsense")
    line = one_line(done.stderr)
    assert done.returncode == 2 and line.startswith("curious render: error: MUJOCO_GL=nonsense")
    assert "export MUJOCO_GL=egl" in line and not frames.exists()


@pytest.mark.parametrize("mujoco_gl", [None, ""], ids=["unset", "empty"])
def test_render_without_mujoco_gl_or_a_display_takes_a_headless_backend(
    tmp_path, monkeypatch, mujoco_gl
):
    """A server or a container: no DISPLAY, MUJOCO_GL unset or empty (`export MUJOCO_GL=`, which
    MuJoCo and dm_control read as unset). dm_control alone would try GLFW and fail; render takes
    EGL (or OSMesa) where its library is installed, and otherwise says in one line what to
    install."""
    from curious.gl import headless_default

    for name in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(name, raising=False)
    backend = headless_default()
    frames = tmp_path / "clip.gif"
    args = ["render", "--policy", "still", "--steps", "2", "--out", str(frames), "--no-progress"]
    done = cli(args, mujoco_gl)
    assert "GLFW" not in done.stderr and "DISPLAY" not in done.stderr, done.stderr[-2000:]
    if backend is None:  # neither library here
        line = one_line(done.stderr)
        assert done.returncode == 2 and "export MUJOCO_GL=egl" in line
    else:
        assert done.returncode == 0 and frames.stat().st_size > 0, done.stderr[-2000:]


def test_without_a_display_or_a_headless_library_render_refuses_before_trying_glfw(monkeypatch):
    from curious import gl

    for name in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(gl, "headless_default", lambda: None)
    gl.gl_for_command(["render", "--out", "x.gif"])
    assert "MUJOCO_GL" not in os.environ
    problem = gl.rendering_problem()
    assert problem is not None and "neither libEGL nor libOSMesa" in problem
    assert "export MUJOCO_GL=egl" in problem


def test_with_a_display_render_leaves_the_backend_to_dm_control(monkeypatch):
    from curious.gl import gl_for_command, headless_default

    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    assert headless_default() is None
    gl_for_command(["render", "--out", "x.gif"])
    assert "MUJOCO_GL" not in os.environ


@pytest.mark.skipif(
    ctypes.util.find_library("OSMesa") is not None, reason="libOSMesa is installed here"
)
def test_mujoco_gl_osmesa_without_its_library_is_refused_by_render_alone(tmp_path):
    """The README suggests osmesa; without libOSMesa, PyOpenGL fails at MuJoCo's import."""
    done = cli(["train", "--help"], "osmesa")
    assert done.returncode == 0, done.stderr[-2000:]
    done = cli(["render", "--out", str(tmp_path / "frames")], "osmesa")
    line = one_line(done.stderr)
    assert done.returncode == 2 and "MUJOCO_GL=osmesa cannot be used here" in line
    assert "libosmesa6" in line


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs Linux's /proc")
def test_ctrl_c_while_the_command_line_starts_is_one_line(tmp_path):
    """The parser imports torch and MuJoCo (seconds): a Ctrl-C then, as later, is one line."""
    env = {**os.environ, "MUJOCO_GL": "disable", "OMP_NUM_THREADS": "1"}
    command = [sys.executable, "-m", "curious.cli", "train", "--preset", "smoke"]
    proc = subprocess.Popen(
        [*command, "--out", str(tmp_path / "run"), "--no-record", "--no-progress"],
        env=env,
        cwd=ROOT,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    # Wait until torch is being loaded, i.e. the command line is importing (a fixed sleep lands
    # before Python has started on a loaded machine, where SIGINT still kills by default).
    maps = Path(f"/proc/{proc.pid}/maps")
    deadline = time.monotonic() + 120
    while "libtorch" not in maps.read_text() and time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()[1][-2000:]
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and one_line(err) == "curious train: interrupted"


# ------------------------------------------------------------------------------ small ones


def test_a_seed_out_of_range_is_refused_naming_the_option(tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    for seed in ("-1", str(2**70), str(MAX_SEED + 1)):
        assert main(["train", "--preset", "smoke", "--seed", seed, "--out", str(out)]) == 2
        line = one_line(capsys.readouterr().err)
        assert "seed (--seed) must be from 0 to 4,294,967,295" in line and seed in line
    monkeypatch.setenv("MUJOCO_GL", "egl")  # render's own checks, past the backend's
    assert main(["render", "--seed", "-1", "--out", str(tmp_path / "frames")]) == 2
    assert "--seed must be from 0 to" in one_line(capsys.readouterr().err)
    assert sorted(tmp_path.iterdir()) == []
    assert resolve("smoke", seed=MAX_SEED).seed == MAX_SEED  # the range's top is a seed


@pytest.mark.parametrize(
    ("args", "error"),
    [
        (["train", "--preset", "smoke", "--seed", "-1", "--out", "OUT"], ConfigError),
        (["reproduce", "--budget", "nosuch", "--out", "OUT"], ExperimentError),
        (["progress", "OUT"], ValueError),
    ],
    ids=["train", "reproduce", "progress"],
)
def test_curious_debug_shows_the_traceback_of_every_commands_refusal(
    args, error, tmp_path, capsys, monkeypatch
):
    """The one-line refusal by default; with CURIOUS_DEBUG=1 the exception itself, traceback and
    all, from every command (docs/usage.md, "When something goes wrong")."""
    args = [str(tmp_path / "out") if a == "OUT" else a for a in args]
    assert main(args) == 2
    assert one_line(capsys.readouterr().err).startswith(f"curious {args[0]}: error: ")
    monkeypatch.setenv("CURIOUS_DEBUG", "1")
    with pytest.raises(error):
        main(args)
    assert sorted(tmp_path.iterdir()) == []


def test_an_empty_out_is_refused_instead_of_meaning_here(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--preset", "smoke", "--out", ""]) == 2
    assert "--out is empty" in one_line(capsys.readouterr().err)
    assert main(["reproduce", "--budget", "smoke", "--out", ""]) == 2
    assert "--out is empty" in one_line(capsys.readouterr().err)
    monkeypatch.setenv("MUJOCO_GL", "egl")  # render's own checks, past the backend's
    assert main(["render", "--out", ""]) == 2
    assert "--out is empty" in one_line(capsys.readouterr().err)
    assert sorted(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["reproduce", "--budget", ""], "unknown budget ''; choose one of smoke, quick"),
        (["reproduce", "--budget", "", "--from-data", str(DATA)], "unknown budget ''; choose"),
        (["train", "--preset", ""], "unknown preset ''; choose one of smoke, quick"),
        (["train", "--condition", ""], "unknown condition ''; choose one of curious"),
        (["reproduce", "--ray-address", ""], "--ray-address is empty: name a cluster"),
    ],
    ids=["reproduce", "reproduce-from-data", "train-preset", "train-condition", "ray-address"],
)
def test_an_empty_name_is_refused_instead_of_meaning_the_default(args, message, tmp_path, capsys):
    """An empty name (`--budget "$BUDGET"` with the variable unset) names nothing: refused, not
    taken for the default, which would train something nobody asked for."""
    out = tmp_path / "out"
    assert main([*args, "--out", str(out)]) == 2
    assert message in one_line(capsys.readouterr().err)
    assert not out.exists()


def test_evaluate_refuses_an_empty_variant_instead_of_taking_the_runs(tmp_path, capsys):
    run = tmp_path / "run"
    train = ["train", "--preset", "smoke", "--set", "total_episodes=8", "--no-record"]
    assert main([*train, "--no-progress", "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(run), "--variant", "", "--episodes", "2", "--no-progress"]) == 2
    assert "unknown suite variant ''; variants: default" in one_line(capsys.readouterr().err)


def test_refused_commands_leave_no_lock_file_and_no_folder(tmp_path, capsys):
    """The lock beside --out is taken before the folder's checks; a refusal must not leave it,
    nor the parent folders made to hold it."""
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "notes.txt").write_text("mine")
    refused = [
        ["--out", str(tmp_path / "full")],  # not empty
        ["--out", str(tmp_path / "a" / "b" / "run"), "--resume"],  # nothing to resume
        ["--out", str(tmp_path / "c" / "run"), "--set", "batch_per_worker=1000000000"],  # no memory
        ["--out", str(tmp_path / "full"), "--resume", "--restart"],
    ]
    for args in refused:
        assert main(["train", "--preset", "smoke", "--no-record", *args]) == 2
        one_line(capsys.readouterr().err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full"]
    assert [p.name for p in (tmp_path / "full").iterdir()] == ["notes.txt"]


# ------------------------------------------------------------------------------ settings


@pytest.mark.parametrize(
    ("setting", "named"),
    [
        ("batch_per_worker=1000000000", "lower batch_per_worker"),
        ("n_workers=100000", "lower n_workers"),
        ("hidden=10000000", "lower hidden or layers"),
        ("lp_window=10000000000", "lower lp_window"),
        ("total_episodes=10000000000", "lower buffer_episodes"),
    ],
)
def test_a_run_that_would_exhaust_the_memory_is_refused_before_writing(
    setting, named, tmp_path, capsys
):
    out = tmp_path / "run"
    args = ["train", "--preset", "smoke", "--out", str(out), "--no-record", "--set", setting]
    assert main(args) == 2
    line = one_line(capsys.readouterr().err)
    assert "this run needs at least" in line and named in line
    assert sorted(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("noise_eps=1e300", "noise_eps must be in [0, 1]"),
        ("td3_noise_clip=7", "td3_noise_clip must be in [0, 1]"),
        ("actor_lr=1e30", "actor_lr must be in (0, 1]"),
        ("critic_lr=2", "critic_lr must be in (0, 1]"),
        ("eval_every=100000000000000000000", "eval_every must be at most 10,000,000,000"),
        ("total_episodes=100000000000000000000", "total_episodes must be at most 10,000,000,000"),
        ("n_updates=100000000000000000000", "n_updates must be at most 100,000"),
        ("td3_policy_delay=1000000", "td3_policy_delay must be at most 100,000"),
        ("torch_threads=100000000000000000000", "torch_threads must be at most 1,024"),
        ("norm_eps=1e300", "norm_eps must be in [1e-08, 1000]"),
        ("norm_eps=1e-300", "norm_eps must be in [1e-08, 1000]"),
        ("norm_eps=nan", "norm_eps must be a finite number"),
    ],
)
def test_settings_outside_their_documented_range_are_refused(setting, message, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", "--preset", "smoke", "--out", str(out), "--set", setting]) == 2
    assert message in one_line(capsys.readouterr().err)
    assert not out.exists()
    key, value = setting.split("=")
    with pytest.raises(ConfigError, match=key):
        resolve("smoke", overrides={key: float(value)})


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--seeds", "0-1", "--set", "seed=3"], "choose the seed with --seed (or --seeds), not"),
        (["--condition", "curious", "--set", "condition=her"], "choose the condition with"),
    ],
    ids=["seed", "condition"],
)
def test_a_setting_that_names_the_run_is_refused_as_an_override(options, message, tmp_path, capsys):
    """`--set seed=3` would give every run of `--seeds 0-1` seed 3, in folders named seed-0
    and seed-1; `--set condition=her` would win over `--condition curious`."""
    out = tmp_path / "runs"
    assert main(["train", "--preset", "smoke", "--out", str(out), *options]) == 2
    assert message in one_line(capsys.readouterr().err)
    assert not out.exists()


def test_the_divergence_error_names_the_settings_set_apart_from_the_authors():
    """A learning rate too high is the usual cause, but not the only one."""
    from curious.runs.trainer import diverged

    plain = str(diverged(resolve("smoke"), 16, "the critic's loss is not finite"))
    assert plain.endswith("(the authors': 1e-3)") and "set apart" not in plain
    assert "(actor_lr=0.001, critic_lr=0.001)" in plain
    config = resolve("smoke", overrides={"norm_eps": 1e-8, "gamma": 0.5})
    message = str(diverged(config, 16, "the critic's loss is not finite"))
    assert "set apart from the authors': norm_eps=1e-08, gamma=0.5)" in message
    assert message.endswith("or these settings back to the authors'")


# ------------------------------------------------------------------------------ outputs


@pytest.fixture
def read_only(tmp_path):
    """A folder nothing can be written in, for root too: immutable (`chattr +i`) where this
    runs as root, whom permissions do not stop, else without write permission."""
    folder = tmp_path / "ro"
    folder.mkdir()
    if os.geteuid() == 0:
        done = subprocess.run(["chattr", "+i", str(folder)], capture_output=True)
        if done.returncode != 0:
            pytest.skip("chattr +i is not available here")
    else:
        folder.chmod(0o555)
    try:
        (folder / "probe").touch()
    except OSError:
        pass
    else:
        pytest.skip("no folder here can be made read-only")
    yield folder
    if os.geteuid() == 0:
        subprocess.run(["chattr", "-i", str(folder)], check=True)
    else:
        folder.chmod(0o755)


@pytest.mark.parametrize(
    "args",
    [
        ["evaluate", "{tmp}/run", "--record", "{ro}/e.rrd"],
        ["render", "--policy", "still", "--steps", "2", "--out", "{ro}/x.gif"],
        ["render", "--policy", "still", "--steps", "2", "--out", "{ro}/frames"],
        ["ship", "{tmp}/runs", "--out", "{ro}/s"],
        ["reproduce", "--budget", "smoke", "--out", "{ro}/r"],
        ["reproduce", "--budget", "smoke", "--runs-dir", "{ro}/runs", "--out", "{tmp}/r"],
        ["train", "--preset", "smoke", "--no-record", "--out", "{ro}/run"],
        ["train", "--preset", "smoke", "--no-record", "--seeds", "0-1", "--out", "{ro}/pop"],
    ],
    ids=[
        "evaluate-record",
        "render-gif",
        "render-png",
        "ship",
        "reproduce",
        "reproduce-runs-dir",
        "train",
        "train-seeds",
    ],
)
def test_a_read_only_output_is_refused_naming_the_option(
    args, read_only, tmp_path, capsys, monkeypatch
):
    monkeypatch.setenv("MUJOCO_GL", "egl")  # render's own checks, past the backend's
    (tmp_path / "runs").mkdir()
    option = next(args[i - 1] for i, a in enumerate(args) if a.startswith("{ro}"))
    args = [a.format(tmp=tmp_path, ro=read_only) for a in args]
    assert main(args) == 2
    line = one_line(capsys.readouterr().err)
    assert f"{option} {read_only}/" in line and "cannot be written" in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ro", "runs"]


# ------------------------------------------------------------------------------ numbers

GIF = ["--policy", "still", "--steps", "2", "--out", "{tmp}/x.gif"]
REPRODUCE = ["reproduce", "--budget", "smoke", "--out", "{tmp}/r", "--no-progress"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["evaluate", "{tmp}/run", "--episodes", "1000000000000000"], "--episodes must be from 1"),
        (["evaluate", "{tmp}/run", "--episodes", "0"], "--episodes must be from 1 to 100,000"),
        (["evaluate", "{tmp}/run", "--seed", "18446744073709551616"], "--seed must be from 0 to"),
        (["evaluate", "{tmp}/run", "--seed", "-1"], "--seed must be from 0 to 4,294,967,295"),
        (["render", "--episodes", "1000000000000000", *GIF], "--episodes must be from 1 to"),
        (["render", "--fps", "inf", *GIF], "--fps must be a finite number, got inf"),
        (["render", "--fps", "nan", *GIF], "--fps must be a finite number, got nan"),
        (["render", "--fps", "1000", *GIF], "--fps 1000: videos play at 0.01 to 100 frames"),
        (["render", "--speed", "1e300", *GIF], "--speed 1e+300 makes 2.5e+301 frames per second"),
        (["render", "--speed", "1e-300", *GIF], "--speed 1e-300 makes"),
        (["render", "--hold", "1e9", *GIF], "--hold must be at most 10 seconds, got 1e+09"),
        (["render", "--width", "100000", "--height", "100000", *GIF], "--width must be from 16"),
        (["render", "--height", "100000", *GIF], "--height must be from 16 to 4,096 pixels"),
        (["render", "--steps", "100000000000000000000", "--out", "{tmp}/x.gif"], "--steps must"),
        (["train", "--rollout-every", "100000000000000000000", "--out", "{tmp}/r"], "from 0 to"),
        (["view", "--web", "--web-port", "-1", "{tmp}"], "--web-port must be from 1 to 65535"),
        (["view", "--web", "--web-port", "99999", "{tmp}"], "--web-port must be from 1 to 65535"),
        (["view", "--web", "--grpc-port", "65536", "{tmp}"], "--grpc-port must be from 1 to"),
        (["view", "--web", "--web-port", "9877", "--grpc-port", "9877", "{tmp}"], "both 9877"),
        ([*REPRODUCE, "--cpus-per-run", "nan"], "--cpus-per-run must be a number > 0, got nan"),
        ([*REPRODUCE, "--gpus-per-run", "nan"], "--gpus-per-run must be a number >= 0, got nan"),
        ([*REPRODUCE, "--gpus-per-run", "inf"], "--gpus-per-run must be a number >= 0, got inf"),
        # an OverflowError from the worker pool once, after reproduce.json was written
        ([*REPRODUCE, "--workers", "100000000000000000000"], "--workers must be from 1 to 4,096"),
        ([*REPRODUCE, "--workers", "4294967296"], "--workers must be from 1 to 4,096"),
        ([*REPRODUCE, "--workers", "0"], "--workers must be from 1 to 4,096"),
        (["view", "--web", "--bind", "every", "{tmp}"], "--bind must be an IP address"),
    ],
)
def test_numbers_past_what_a_command_can_hold_are_refused_naming_the_option(
    args, message, tmp_path, capsys, monkeypatch
):
    monkeypatch.setenv("MUJOCO_GL", "egl")  # render's own checks, past the backend's
    args = [a.format(tmp=tmp_path) for a in args]
    assert main(args) == 2
    assert message in one_line(capsys.readouterr().err)
    assert sorted(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("options", "message", "not_given"),
    [
        (["--every", "100000000000000000000"], "--every 100000000000000000000 makes", "--speed"),
        (["--every", "3000", "--speed", "0.5"], "--every 3000 with --speed 0.5 makes", "--fps"),
        (["--fps", "-1"], "--fps must be positive, got -1", "--speed"),
        (["--speed", "0"], "--speed must be positive, got 0", "--fps"),
    ],
)
def test_a_render_refusal_names_the_option_given_and_none_that_was_not(
    options, message, not_given, tmp_path, capsys, monkeypatch
):
    """`--every 1e20` made too few frames per second, and the refusal named `--speed`, which
    was not given: a refusal names the options at fault."""
    monkeypatch.setenv("MUJOCO_GL", "egl")
    assert main(["render", *options, *(a.format(tmp=tmp_path) for a in GIF)]) == 2
    line = one_line(capsys.readouterr().err)
    assert message in line and not_given not in line, line
    assert sorted(tmp_path.iterdir()) == []


def test_the_bounds_of_render_are_its_help_and_its_edges_are_taken(tmp_path, capsys, monkeypatch):
    """The range a refusal names is the range that passes: its edges are accepted."""
    from curious.cli import build_parser
    from curious.commands import render

    monkeypatch.setenv("MUJOCO_GL", "egl")
    parser = build_parser()
    edges = ["--width", "4096", "--height", "16", "--fps", "100", "--hold", "10", "--episodes"]
    args = parser.parse_args(["render", *edges, "100000", "--out", str(tmp_path / "x.gif")])
    assert render._check(args) == "gif"
    args = parser.parse_args(["render", "--fps", "0.01", "--out", str(tmp_path / "x.webp")])
    assert render._check(args) == "webp"
    assert sorted(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------ folders

SEEDS = ["train", "--preset", "smoke", "--seeds", "0-1", "--no-record", "--no-progress"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["progress", "{file}"], "{file} is a file, not a folder: name a run folder"),
        (["progress", "{tmp}", "{file}"], "{file} is a file, not a folder"),
        (["reproduce", "--from-data", "{file}", "--out", "{tmp}/r"], "--from-data {file} is a"),
        ([*SEEDS, "--out", "{file}"], "--out {file}: {file} is a file, not a folder"),
        (["bench", "checkpoint", "--dir", "{file}"], "--dir {file}: {file} is a file, not a"),
        (["ship", "{file}"], "{file} is a file, not a folder of run folders"),
        (["ship", "{tmp}/nowhere"], "{tmp}/nowhere does not exist"),
        (["evaluate", "{file}"], "{file} is a file, not a run folder"),
        (["evaluate", "{tmp}/nowhere"], "{tmp}/nowhere does not exist: name a run folder"),
        (["render", "--run", "{file}", "--out", "{tmp}/x.gif"], "{file} is a file, not a run"),
    ],
    ids=[
        "progress",
        "progress-second",
        "reproduce",
        "train-seeds",
        "bench-checkpoint",
        "ship",
        "ship-missing",
        "evaluate",
        "evaluate-missing",
        "render",
    ],
)
def test_a_file_where_a_folder_is_read_is_one_line(args, message, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "egl")  # render's own checks, past the backend's
    file = tmp_path / "notes.txt"
    file.write_text("mine")
    args = [a.format(tmp=tmp_path, file=file) for a in args]
    assert main(args) == 2
    assert message.format(file=file, tmp=tmp_path) in one_line(capsys.readouterr().err)
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]


def test_a_read_only_file_to_update_is_refused_before_the_tables(tmp_path, capsys):
    """`curious progress --update FILE` rewrites FILE in place: read-only, it is refused in one
    line before any run is read (the file immutable where this runs as root)."""
    doc = tmp_path / "results.md"
    doc.write_text("<!-- progress:begin -->\n<!-- progress:end -->\n")
    if os.geteuid() == 0:
        if subprocess.run(["chattr", "+i", str(doc)], capture_output=True).returncode:
            pytest.skip("chattr +i is not available here")
    else:
        doc.chmod(0o444)
    try:
        assert main(["progress", str(tmp_path / "nothing"), "--update", str(doc)]) == 2
        assert f"--update {doc} cannot be written" in one_line(capsys.readouterr().err)
    finally:
        if os.geteuid() == 0:
            subprocess.run(["chattr", "-i", str(doc)], check=True)


@pytest.mark.parametrize(
    ("target", "message"),
    [("", "--update is empty: name the Markdown file"), ("{tmp}", "is a folder: name the")],
    ids=["empty", "folder"],
)
def test_an_update_that_names_no_file_is_refused_saying_so(target, message, tmp_path, capsys):
    """`--update ''` is not the current folder, and a folder is not a file to create."""
    target = target.format(tmp=tmp_path)
    assert main(["progress", str(tmp_path / "nothing"), "--update", target]) == 2
    assert message in one_line(capsys.readouterr().err)


@pytest.mark.parametrize(
    ("args", "argument"),
    [
        (["progress", ""], "ROOT"),
        (["evaluate", ""], "RUN"),
        (["ship", ""], "ROOT"),
        (["view", ""], "RUN_DIR"),
        (["render", "--run", ""], "--run"),
    ],
    ids=["progress", "evaluate", "ship", "view", "render"],
)
def test_an_empty_folder_argument_is_refused_instead_of_meaning_here(
    args, argument, tmp_path, capsys, monkeypatch
):
    """A folder named by an unset shell variable is refused by the parser, not read as the
    current folder (whose runs the command would then report, ship or open)."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MUJOCO_GL", "egl")  # render's own checks, past the backend's
    with pytest.raises(SystemExit) as exit_:
        main(args)
    assert exit_.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last == f"curious {args[0]}: error: argument {argument}: is empty: name a folder"
    assert sorted(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------------ damaged files


@pytest.mark.parametrize(
    ("command", "manifest", "message"),
    [
        (
            "ship",
            {"budget": "smoke", "runs_dir": 5},
            "is damaged: runs_dir must be a folder path, got 5",
        ),
        (
            "progress",
            {"budget": "smoke", "runs_dir": 5},
            "is damaged: runs_dir must be a folder path",
        ),
        ("ship", {"budget": "bogus"}, "is damaged: unknown budget 'bogus'; choose one of smoke"),
        ("ship", "{", "is unreadable (Expecting property name"),
    ],
    ids=["ship-runs-dir", "progress-runs-dir", "ship-budget", "ship-not-json"],
)
def test_a_damaged_reproduce_json_is_named_in_one_line(
    command, manifest, message, tmp_path, capsys
):
    """A reproduce.json edited by hand or cut short: the refusal names the file and what is
    wrong in it, and ships nothing."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "reproduce.json").write_text(
        manifest if isinstance(manifest, str) else json.dumps(manifest)
    )
    args = [command, str(out), *(["--out", str(tmp_path / "data")] if command == "ship" else [])]
    assert main(args) == 2
    assert f"reproduce.json {message}" in one_line(capsys.readouterr().err)
    assert sorted(tmp_path.iterdir()) == [out]


@pytest.mark.parametrize("command", ["evaluate", "render", "ship"])
def test_a_file_where_the_checkpoints_folder_should_be_is_one_line(
    command, smoke, tmp_path, capsys, monkeypatch
):
    """A run whose checkpoints/ is a file (a copy gone wrong): every command that looks for
    its checkpoints refuses it naming the file, not with an OS error's traceback."""
    monkeypatch.setenv("MUJOCO_GL", "egl")  # render's own checks, past the backend's
    run = tmp_path / "run"
    source = smoke.out / "runs" / "main" / "curious" / "seed-0"
    shutil.copytree(source, run, ignore=shutil.ignore_patterns("checkpoints", "*.rrd"))
    (run / "checkpoints").write_text("not a folder")
    args = {
        "evaluate": ["evaluate", str(run)],
        "render": ["render", "--run", str(run), "--out", str(tmp_path / "x.gif")],
        "ship": ["ship", str(run), "--out", str(tmp_path / "data")],
    }[command]
    assert main(args) == 2
    message = one_line(capsys.readouterr().err)
    assert "checkpoints is a file, not a folder of checkpoints: move it away" in message
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["relabel", "--seconds", "0"], "argument --seconds: must be a positive number of seconds"),
        (["learner", "--seconds", "nan"], "argument --seconds: must be a positive number of"),
        (["learner", "--seconds", "-1"], "argument --seconds: must be a positive number of"),
    ],
)
def test_a_benchmark_timed_for_no_time_is_refused_by_the_parser(args, message, capsys):
    """0 seconds would divide by zero, NaN would never end the timing loop."""
    with pytest.raises(SystemExit) as exit_:
        main(["bench", *args])
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.parametrize(
    ("args", "prog", "unknown", "option_listed"),
    [
        (
            ["train", "--out", "{tmp}/r", "--episodes", "5"],
            "train",
            "--episodes 5",
            "--rollout-every",
        ),
        (["progress", "--pace", "{tmp}"], "progress", "--pace", "--at-once"),
        (["reproduce", "--budget", "smoke", "extra"], "reproduce", "extra", "--from-data"),
        (["bench", "env", "--steps", "5"], "bench env", "--steps 5", "--episodes"),
        (
            ["bench", "learner", "--json", "--updates", "0"],
            "bench learner",
            "--updates 0",
            "--seconds",
        ),
    ],
    ids=["train", "progress", "reproduce-word", "bench-env", "bench-learner"],
)
def test_an_unknown_option_is_refused_by_the_command_it_was_given_to(
    args, prog, unknown, option_listed, tmp_path, capsys
):
    """A mistyped option is named with the usage of the (sub-)command it was typed for, which
    lists the options meant, not with the top-level usage; nothing is written."""
    with pytest.raises(SystemExit) as exit_:
        main([a.format(tmp=tmp_path) for a in args])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert (
        err.strip().splitlines()[-1] == f"curious {prog}: error: unrecognized arguments: {unknown}"
    )
    assert err.startswith(f"usage: curious {prog} ") and option_listed in err
    assert sorted(tmp_path.iterdir()) == []


@pytest.mark.parametrize("which", ["learner", "seeds"])
def test_a_benchmark_on_cuda_without_a_gpu_is_one_line(which, capsys):
    import torch

    if torch.cuda.is_available():
        pytest.skip("this machine has a CUDA device")
    assert main(["bench", which, "--device", "cuda"]) == 2
    assert "--device cuda, but torch sees no CUDA device" in one_line(capsys.readouterr().err)


def test_a_warning_of_curious_is_one_line_like_its_errors(tmp_path):
    """A damaged newest checkpoint passed over on --resume is said in one line naming the
    command, not as a UserWarning with its source line."""
    out = tmp_path / "run"
    train = ["train", "--preset", "smoke", "--out", str(out), "--no-record", "--no-progress"]
    train += ["--set", "checkpoint_every_cycles=1"]
    assert cli([*train, "--set", "total_episodes=8"], "disable").returncode == 0
    newest = max((out / "checkpoints").glob("ep-*"))
    (newest / "state.pt").write_bytes(b"not a checkpoint")
    done = cli([*train, "--set", "total_episodes=12", "--resume"], "disable")
    assert done.returncode == 0, done.stderr[-2000:]
    warned = [line for line in done.stderr.splitlines() if "warning" in line.lower()]
    assert len(warned) == 1 and warned[0].startswith("curious train: warning: "), done.stderr
    assert f"resuming from the one before, {newest.name}" not in warned[0]
    assert "resuming from the one before, ep-" in warned[0]


def test_a_replay_smaller_than_a_round_is_refused_before_anything_is_written(tmp_path, capsys):
    """`buffer_episodes` below the episodes a round stores at once (n_workers) failed after
    config.json was written, in the replay's words, and then every retry met a folder in use."""
    out = tmp_path / "run"
    settings = ["--set", "n_workers=4", "--set", "buffer_episodes=3"]
    assert main(["train", "--preset", "smoke", "--no-record", "--out", str(out), *settings]) == 2
    assert "buffer_episodes must be 0 (the whole run) or at least 4, the episodes a round" in (
        one_line(capsys.readouterr().err)
    )
    assert not out.exists()


def test_a_resume_that_would_shorten_the_run_says_so(tmp_path, capsys):
    """`--resume --set total_episodes=N` below the episodes trained read "checkpoint replay holds
    24 episodes, capacity is 12": a run can be lengthened, not shortened."""
    run = tmp_path / "run"
    train = ["train", "--preset", "smoke", "--no-record", "--no-progress", "--out", str(run)]
    assert main([*train, "--set", "total_episodes=8"]) == 0
    capsys.readouterr()
    before = sorted(p.name for p in run.iterdir())
    assert main([*train, "--resume", "--set", "total_episodes=4"]) == 2
    err = one_line(capsys.readouterr().err)
    assert "with total_episodes=4: the run has trained 8 episodes" in err
    assert "lengthened, not shortened" in err
    assert sorted(p.name for p in run.iterdir()) == before


@pytest.mark.parametrize(
    ("option", "override"),
    [
        (["--variant", "distractors_0"], "variant=distractors_4"),
        (["--device", "cpu"], "device=cuda"),
    ],
    ids=["variant", "device"],
)
def test_an_option_and_an_override_that_disagree_are_refused(option, override, tmp_path, capsys):
    """`--variant distractors_0 --set variant=distractors_4` trained distractors_0 without a
    word (the option silently won), as `--device cpu --set device=cuda` trained on the CPU."""
    out = tmp_path / "run"
    args = ["train", "--preset", "smoke", "--no-record", "--out", str(out), *option]
    assert main([*args, "--set", override]) == 2
    assert "disagree: give one" in one_line(capsys.readouterr().err)
    assert not out.exists()


def test_reproduce_refuses_a_runs_folder_no_search_would_find_before_writing(tmp_path, capsys):
    """`--runs-dir` (or `--out`) in a run folder failed inside every worker and left a
    reproduce.json that made each later try fail the same way; `--runs-dir` naming another
    reproduction's output (its `runs/` left off) trained every run anew beside its runs."""
    run = tmp_path / "run"
    assert main(["train", "--preset", "smoke", "--no-record", "--no-progress",
                 "--set", "total_episodes=4", "--out", str(run)]) == 0  # fmt: skip
    other = tmp_path / "other"
    other.mkdir()
    (other / "reproduce.json").write_text('{"budget": "smoke"}')
    capsys.readouterr()
    cases = [
        (["--out", str(tmp_path / "r1"), "--runs-dir", str(run)], "--runs-dir", "lies in the run"),
        (["--out", str(run / "r2")], "--out", "lies in the run folder"),
        (["--out", str(tmp_path / "r3"), "--runs-dir", str(other)], "--runs-dir", "output"),
    ]
    for args, option, words in cases:
        assert main(["reproduce", "--budget", "smoke", "--no-progress", *args]) == 2
        line = one_line(capsys.readouterr().err)
        assert line.startswith(f"curious reproduce: error: {option} ") and words in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other", "run"]
    assert sorted(p.name for p in run.iterdir()) == sorted(
        ["checkpoints", "config.json", "learner.parquet", "metrics.parquet", "tests.parquet"]
    )


def test_evaluate_refuses_a_config_json_edited_away_from_its_checkpoint(tmp_path, capsys):
    """`condition` edited to her in config.json: evaluate scored the curious agent as HER without
    a word (and `hidden` edited gave torch's six-line size mismatch); `--resume` refuses both."""
    import json

    run = tmp_path / "run"
    train = ["train", "--preset", "smoke", "--no-record", "--no-progress", "--out", str(run)]
    assert main([*train, "--set", "total_episodes=8"]) == 0
    stored = json.loads((run / "config.json").read_text())
    stored["config"]["condition"] = "her"
    (run / "config.json").write_text(json.dumps(stored))
    capsys.readouterr()
    assert main(["evaluate", str(run), "--episodes", "1", "--no-progress"]) == 2
    line = one_line(capsys.readouterr().err)
    assert "is from another config than" in line and "(differs in condition)" in line


@pytest.mark.parametrize(
    ("settings", "why"),
    [
        ([], "neither sensor_failure_episode nor sensor_failure_competence is set"),
        (["--set", "sensor_failure_episode=8"], "sensor_failure_episode 8 is at or past"),
    ],
    ids=["unset", "past-the-end"],
)
def test_a_sensor_failure_run_whose_sensor_never_fails_says_so(settings, why, tmp_path, capsys):
    """The variant without its onset, or with one past the run's end, trained without a word,
    its tables then read as a failure that had no effect."""
    out = str(tmp_path / "run")
    args = ["train", "--preset", "smoke", "--variant", "sensor_failure", "--no-record",
            "--no-progress", "--set", "total_episodes=4", "--out", out]  # fmt: skip
    assert main([*args, *settings]) == 0
    err = capsys.readouterr().err
    assert f"curious train: warning: variant sensor_failure, but {why}" in err
    assert "the sensor never fails in this run" in err


def test_an_out_that_is_a_dangling_link_is_named_so(tmp_path, capsys):
    """A scratch link whose target is not mounted read "File exists: R"."""
    link = tmp_path / "scratch"
    link.symlink_to(tmp_path / "not-mounted")
    assert main(["train", "--preset", "smoke", "--no-record", "--out", str(link)]) == 2
    line = one_line(capsys.readouterr().err)
    assert f"is a link to {tmp_path / 'not-mounted'}, which does not exist" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scratch"]


def test_a_run_whose_checkpoints_are_all_unreadable_says_so_once(tmp_path, capsys):
    """Every checkpoint cut short read as each one's torch error in turn, one long line with
    torch's advice twice and no way out."""
    run = tmp_path / "run"
    train = ["train", "--preset", "smoke", "--no-record", "--no-progress", "--out", str(run)]
    assert main([*train, "--set", "total_episodes=8", "--set", "checkpoint_every_cycles=1"]) == 0
    states = sorted(run.glob("checkpoints/ep-*/state.pt"))
    assert len(states) >= 2
    for state in states:
        state.write_bytes(state.read_bytes()[:100])
    capsys.readouterr()
    assert main([*train, "--resume", "--set", "total_episodes=12"]) == 2
    line = one_line(capsys.readouterr().err)
    assert f"no checkpoint in {run / 'checkpoints'} can be read ({len(states)} tried" in line
    assert "restore them, or start the run over" in line
    assert line.count("cannot read checkpoint") == 1
