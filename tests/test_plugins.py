"""Plugins (`curious.plugins`, docs/extending.md): the page's three recipes, built as a plugin in
a temporary folder (a module and a `.dist-info` on `PYTHONPATH`, nothing installed), run through
the commands; a plugin that is missing or broken is one line; the registries take additions and
refuse bad ones."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from curious import plugins
from curious.agent.conditions import CONDITION_CLASSES, Condition, register_condition
from curious.reproduction import experiments, figures

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "extending.md"
DIST = "curious-lift"


def recipes() -> str:
    """The plugin module docs/extending.md gives: its Python blocks, in order."""
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(encoding="utf-8"), re.DOTALL)
    assert len(blocks) == 3, "docs/extending.md gives one Python block per recipe"
    return "\n\n".join(blocks)


def write_plugin(folder: Path, source: str, module: str = "curious_lift") -> Path:
    """A plugin as `importlib.metadata` finds it: `module` and its `.dist-info` in `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{module}.py").write_text(source, encoding="utf-8")
    info = folder / f"{module}-0.1.dist-info"
    info.mkdir()
    name = module.replace("_", "-")
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[curious.plugins]\nlift = {module}\n")
    return folder


@pytest.fixture(scope="module")
def plugin(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_plugin(tmp_path_factory.mktemp("plugin"), recipes())


def curious(*args: str, path: Path | None, cwd: Path) -> subprocess.CompletedProcess:
    """`curious ARGS` in a fresh process with `path` (a plugin's folder) on PYTHONPATH."""
    env = dict(os.environ)
    entries = [str(path)] if path is not None else []
    env["PYTHONPATH"] = os.pathsep.join([*entries, *filter(None, [env.get("PYTHONPATH")])])
    env.pop("CURIOUS_PLUGIN_ERRORS_SHOWN", None)
    command = [sys.executable, "-c", "import sys; from curious.cli import main; sys.exit(main())"]
    return subprocess.run(
        [*command, *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=300
    )


def ok(result: subprocess.CompletedProcess) -> str:
    assert result.returncode == 0, result.stderr[-3000:]
    return result.stdout


# ---------------------------------------------------------------------------- the three recipes


def test_a_plugin_variant_and_module_train_resume_and_evaluate(plugin, tmp_path):
    run = tmp_path / "run"
    help_text = ok(curious("train", "--help", path=plugin, cwd=tmp_path))
    assert "lift" in help_text and "unmastered" in help_text
    train = ("train", "--variant", "lift", "--preset", "smoke", "--out", str(run), "--no-progress")
    ok(curious(*train, "--set", "total_episodes=12", path=plugin, cwd=tmp_path))
    described = json.loads((run / "config.json").read_text())
    assert described["modules"] == ["reach", "push_cube1", "lift_cube1"]
    assert described["plugins"] == {
        "variant": {"plugin": DIST, "version": "0.1", "module": "curious_lift"}
    }
    ok(curious("train", "--out", str(run), "--resume", "--set", "total_episodes=24",
               "--no-progress", path=plugin, cwd=tmp_path))  # fmt: skip
    resumed = json.loads((run / "config.json").read_text())
    assert resumed["plugins"] == described["plugins"]
    assert resumed["resumed"][-1]["plugins"] == described["plugins"]
    out = ok(curious("evaluate", str(run), "--episodes", "3", path=plugin, cwd=tmp_path))
    assert "lift_cube1" in out

    # without the plugin: one line naming it, no traceback
    for command in (("evaluate", str(run)), ("train", "--out", str(run), "--resume")):
        missing = curious(*command, path=None, cwd=tmp_path)
        assert missing.returncode == 2
        assert missing.stderr.strip().splitlines() == [
            f"curious {command[0]}: error: {run} was trained with the variant 'lift' of the "
            f"plugin {DIST} 0.1, which is not installed (pip install {DIST})"
        ]


def test_a_plugin_condition_trains_and_is_recorded(plugin, tmp_path):
    run = tmp_path / "run"
    ok(curious("train", "--condition", "unmastered", "--preset", "smoke", "--out", str(run),
               "--no-progress", path=plugin, cwd=tmp_path))  # fmt: skip
    described = json.loads((run / "config.json").read_text())
    assert described["condition"] == "unmastered"
    assert described["plugins"] == {
        "condition": {"plugin": DIST, "version": "0.1", "module": "curious_lift"}
    }
    ok(curious("evaluate", str(run), "--episodes", "2", path=plugin, cwd=tmp_path))
    missing = curious("evaluate", str(run), path=None, cwd=tmp_path)
    assert missing.returncode == 2 and "condition 'unmastered' of the plugin" in missing.stderr
    assert len(missing.stderr.strip().splitlines()) == 1


def test_a_plugin_experiment_and_figure_are_reproduced_and_reported(plugin, tmp_path):
    out = tmp_path / "out"
    budgets = ok(curious("reproduce", "--help", path=plugin, cwd=tmp_path))
    assert "lift" in budgets
    ok(curious("reproduce", "--budget", "smoke", "--experiments", "lift", "--out", str(out),
               "--no-progress", "--no-shipped", path=plugin, cwd=tmp_path))  # fmt: skip
    assert (out / "figures" / "practice.png").stat().st_size > 1000
    assert (out / "runs" / "lift" / "unmastered" / "seed-0" / "config.json").is_file()
    report = (out / "report.md").read_text()
    assert "## Lifting: practising the unmastered modules against CURIOUS" in report
    assert "](figures/practice.png)" in report
    assert "Share of the training episodes that practised each module, per condition." in report
    # a budget that does not train it says so
    quick = curious("reproduce", "--budget", "quick", "--experiments", "lift", "--out",
                    str(tmp_path / "quick"), path=plugin, cwd=tmp_path)  # fmt: skip
    assert quick.returncode == 2
    assert "it is trained at budgets `smoke`, `laptop` only" in quick.stderr


def test_a_plugin_that_fails_to_import_is_one_line_and_curious_goes_on(tmp_path):
    broken = write_plugin(tmp_path / "plugin", "import a_module_that_is_not_there\n")
    result = curious("--version", path=broken, cwd=tmp_path)
    assert result.returncode == 0
    assert result.stderr.strip().splitlines() == [
        "curious: warning: plugin 'lift' (curious-lift 0.1) did not load (ModuleNotFoundError: "
        "No module named 'a_module_that_is_not_there'); its variants, conditions and figures "
        "are missing"
    ]


def test_loading_the_plugins_imports_nothing_heavy(plugin):
    code = (
        "import sys, curious; "
        "print(sorted(m for m in ('torch', 'mujoco', 'dm_control', 'matplotlib', 'pandas', "
        "'dagster') if m in sys.modules))"
    )
    path = os.pathsep.join(filter(None, [str(plugin), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "PYTHONPATH": path}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


# ------------------------------------------------------------------------------ the registries


@pytest.fixture
def registries():
    """The registries as they were, restored after the test (registering is for a process)."""
    saved = (
        dict(CONDITION_CLASSES),
        dict(figures.FIGURES),
        dict(experiments.BUDGETS),
        list(experiments.REGISTERED_EXPERIMENTS),
        dict(experiments.PAPER_EPISODES),
    )
    yield
    conditions, figures_before, budgets, names, episodes = saved
    for registry, before in (
        (CONDITION_CLASSES, conditions),
        (figures.FIGURES, figures_before),
        (experiments.BUDGETS, budgets),
        (experiments.PAPER_EPISODES, episodes),
    ):
        registry.clear()
        registry.update(before)
    experiments.REGISTERED_EXPERIMENTS[:] = names


def test_register_condition_takes_a_named_subclass_once(registries):
    class Mine(Condition):
        name = "mine"

    assert register_condition(Mine) is Mine and CONDITION_CLASSES["mine"] is Mine
    assert register_condition(Mine) is Mine  # again: the same class, nothing changes

    class Other(Condition):
        name = "mine"

    with pytest.raises(ValueError, match="a condition named 'mine' is already registered"):
        register_condition(Other)

    class Unnamed(Condition):
        pass

    with pytest.raises(ValueError, match="Unnamed needs a `name` of its own"):
        register_condition(Unnamed)

    class Partitioned(Condition):
        name = "a@b"

    with pytest.raises(ValueError, match="one word without @"):
        register_condition(Partitioned)
    with pytest.raises(TypeError, match="subclass of Condition"):
        register_condition(dict)


def test_register_figure_and_experiment_extend_the_budgets(registries):
    smoke = experiments.get_budget("smoke")
    main = smoke.experiments["main"]
    twin = replace(main, name="twin")
    experiments.register_experiment({"smoke": twin})
    assert experiments.experiment_names()[-1] == "twin"
    assert experiments.get_budget("smoke").experiments["twin"] is twin
    assert "trained at budget `smoke` only" in experiments.get_budget("quick").omitted["twin"]
    with pytest.raises(experiments.ExperimentError, match="already registered"):
        experiments.register_experiment({"smoke": twin})
    with pytest.raises(experiments.ExperimentError, match="unknown budget"):
        experiments.register_experiment({"fast": replace(main, name="x")})

    def draw(inputs):
        raise AssertionError("not drawn here")

    figures.register_figure("twin_curve", ("twin", "main"), "A curve.", in_report=False)(draw)
    spec = figures.get_figure("twin_curve")
    assert spec.stem("main") == "twin_curve_main" and spec.caption(tested=False) == "A curve."
    assert spec in figures.figures_of("main") and spec not in figures.figures_of("main", True)
    figures.check_figures(experiments.experiment_names())
    with pytest.raises(ValueError, match="already registered"):
        figures.register_figure("twin_curve", ("main",), "Another.")(draw)
    figures.register_figure("typo", ("mian",), "A curve.")(draw)
    with pytest.raises(ValueError, match="figure 'typo' is drawn for unknown experiment"):
        figures.check_figures(experiments.experiment_names())


def test_what_a_run_records_and_what_is_missing():
    lift = plugins.Plugin("lift", "curious_lift", DIST, "0.1")
    assert lift.record() == {"plugin": DIST, "version": "0.1", "module": "curious_lift"}
    assert plugins.sources("curious", "default") == {}  # curious's own: nothing recorded
    recorded = {"condition": lift.record()}
    assert plugins.missing(recorded, "curious", "default") is None  # registered here
    assert plugins.missing(recorded, "unmastered", "default") == (
        f"condition 'unmastered' of the plugin {DIST} 0.1, which is not installed "
        f"(pip install {DIST})"
    )
    assert plugins.missing(None, "unmastered", "default") is None  # no record: Config's error
