"""The run folder's format (curious.runs.folder, folder_layout, run_info, provenance): what
config.json records, how every version of it reads, and the one check of whether a config goes on
with the run in a folder."""

from __future__ import annotations

import ast
import dataclasses
import json
from pathlib import Path

import pytest
from toy_env import ToyGoalEnv

from curious.envs.goal_env import SuiteEnv
from curious.presets import resolve
from curious.reproduction.experiments import get_budget
from curious.runs.folder import RunFolder
from curious.runs.folder_errors import ConfigMismatch, RunFolderError
from curious.runs.folder_layout import (
    RUN_ENTRIES,
    SHIPPED_MANIFEST_FILE,
    checkpoint_name,
    list_checkpoints,
)
from curious.runs.provenance import machine, machine_text
from pipelines.training import PARTIAL, RunFolderMismatch, folder_state, run_folder

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True)
def _no_gl(monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "disable")  # the suite is built, never rendered


def _written(folder: Path, variant: str) -> RunFolder:
    """A run folder whose config.json training wrote, for a run of `variant`."""
    config = resolve("smoke", "curious", 0, {"variant": variant})
    run = RunFolder(folder)
    run.write_config(config, SuiteEnv(variant, seed=0).spec)
    return run


def _as_main_wrote_it(run: RunFolder) -> None:
    """config.json as curious wrote it before it recorded the perturbed modules (main at
    abb0519, the campaign's runs): the same keys but `sensor_failure_modules`."""
    data = json.loads(run.config_path.read_text())
    del data["sensor_failure_modules"]
    run.config_path.write_text(json.dumps(data, indent=2))


def test_config_json_records_the_modules_the_sensory_failure_perturbs(tmp_path):
    failure = _written(tmp_path / "failure", "sensor_failure")
    assert json.loads(failure.config_path.read_text())["sensor_failure_modules"] == ["push_cube3"]
    assert failure.read_info().sensor_failure_modules == ("push_cube3",)
    default = _written(tmp_path / "default", "default")
    assert json.loads(default.config_path.read_text())["sensor_failure_modules"] == []
    assert default.read_info().sensor_failure_modules == ()


def test_a_config_json_written_before_the_record_reads_the_variants_modules(tmp_path):
    failure = _written(tmp_path / "failure", "sensor_failure")
    default = _written(tmp_path / "default", "default")
    for run in (failure, default):
        _as_main_wrote_it(run)
    info = failure.read_info()
    assert info.recorded_failure_modules is None
    assert info.sensor_failure_modules == ("push_cube3",)  # the suite variant's definition
    assert default.read_info().sensor_failure_modules == ()
    assert info.condition == "curious" and info.variant == "sensor_failure"
    assert info.module_names == ("reach", "push_cube1", "cube1_above_cube2", "push_cube3")
    assert info.total_episodes == resolve("smoke").total_episodes


def test_run_info_carries_the_provenance_of_every_start(tmp_path):
    run = _written(tmp_path / "run", "default")
    data = json.loads(run.config_path.read_text())
    data["git"] = {"commit": "a" * 40, "dirty": False}
    data["resumed"] = [
        {"at": "x", "git": {"commit": "b" * 40, "dirty": True}, "config": {}},
        {"at": "y", "git": {"commit": "a" * 40, "dirty": False}, "config": {}},
    ]
    run.config_path.write_text(json.dumps(data))
    info = run.read_info()
    assert info.commits == ("aaaaaaa", "bbbbbbb+")
    assert info.versions["curious"] is not None and len(info.resumed) == 2


def test_config_json_records_the_machine_of_every_start(tmp_path, monkeypatch):
    """For the compute an experiment took (the report's run-hours per machine): the processor
    and cores of the first start, and of each resume; none for starts that predate the record."""
    here = machine()
    assert here["cpu"] and here["cores"] >= 1 and here["gpu"] is None
    if Path("/proc/cpuinfo").exists():  # Linux: the generation behind the model name
        assert here["cpu_generation"].startswith("family ")
        assert machine_text(here).startswith(f"{here['cpu']} ({here['cpu_generation']}), ")
    run = _written(tmp_path / "run", "default")
    assert json.loads(run.config_path.read_text())["machine"] == here
    assert run.read_info().machines == (machine_text(here),)
    elsewhere = {"cpu": "Other CPU", "cores": 64, "system": "Linux", "gpu": "NVIDIA H100"}
    monkeypatch.setattr("curious.runs.folder.machine", lambda device="cpu": elsewhere)
    run.write_config(resolve("smoke", "curious", 0), SuiteEnv("default", seed=0).spec)
    data = json.loads(run.config_path.read_text())
    assert data["machine"] == here and data["resumed"][-1]["machine"] == elsewhere
    assert run.read_info().machines == (machine_text(here), "Other CPU, 64 cores, NVIDIA H100")
    # a folder whose first start predates the record: the resume's machine only
    old = _written(tmp_path / "old", "default")
    data = json.loads(old.config_path.read_text())
    del data["machine"]
    old.config_path.write_text(json.dumps(data))
    assert old.read_info().machines == ()
    old.write_config(resolve("smoke", "curious", 0), SuiteEnv("default", seed=0).spec)
    assert json.loads(old.config_path.read_text())["machine"] is None
    assert old.read_info().machines == ("Other CPU, 64 cores, NVIDIA H100",)


def test_a_bad_record_of_the_perturbed_modules_is_named(tmp_path):
    run = _written(tmp_path / "run", "sensor_failure")
    data = json.loads(run.config_path.read_text())
    data["sensor_failure_modules"] = ["push_cube9"]
    run.config_path.write_text(json.dumps(data))
    with pytest.raises(RunFolderError, match=r"config\.json: 'sensor_failure_modules' must list"):
        run.read_info()


def _pipeline_run(root: Path):
    """A smoke reproduction's first run, its config.json written as training writes it."""
    spec = get_budget("smoke").experiments["main"].runs()[0]
    run = RunFolder(run_folder(spec, root))
    run.write_config(spec.config(), ToyGoalEnv.spec)
    return spec, run


@pytest.mark.parametrize(
    ("what", "change", "accepted"),
    [
        ("nothing", {}, True),
        ("a resumable setting", {"total_episodes": 10**6}, True),
        ("a setting", {"hidden": 7}, False),
        ("an int setting written as a float", {"hidden": "as float"}, False),
        ("a setting this version lacks", {"lp_eps": None}, False),
    ],
)
def test_the_pipeline_takes_a_folder_exactly_when_a_resume_would(tmp_path, what, change, accepted):
    """One check (`RunFolder.check_resumable`) decides both: the pipeline never hands training
    a folder that `train(resume=True)` refuses, nor refuses one it would go on with."""
    spec, run = _pipeline_run(tmp_path)
    data = json.loads(run.config_path.read_text())
    for key, value in change.items():
        if value is None:
            del data["config"][key]
        else:
            data["config"][key] = float(data["config"][key]) if value == "as float" else value
    run.config_path.write_text(json.dumps(data))
    config = spec.config()
    if accepted:
        RunFolder.prepare(run.path, config, resume=True)
        assert folder_state(spec, tmp_path) == PARTIAL, what
    else:
        with pytest.raises(RunFolderError):
            RunFolder.prepare(run.path, config, resume=True)
        with pytest.raises(RunFolderMismatch):
            folder_state(spec, tmp_path)


def test_a_changed_setting_is_named_on_both_sides(tmp_path):
    spec, run = _pipeline_run(tmp_path)
    hidden = spec.config().hidden
    changed = dataclasses.replace(spec.config(), hidden=hidden + 1)
    detail = rf"different config \(hidden: {hidden} -> {hidden + 1}\)"
    with pytest.raises(ConfigMismatch, match=detail) as error:
        run.check_resumable(changed)
    assert error.value.differences == {"hidden": (hidden, hidden + 1)}
    other = get_budget("quick").experiments["main"].runs()[0]
    with pytest.raises(RunFolderMismatch, match="training preset 'smoke', not 'quick'"):
        folder_state(other, tmp_path)


def test_checkpoints_are_listed_by_their_names(tmp_path):
    run = RunFolder(tmp_path)
    assert run.newest_checkpoint() is None and run.episodes_logged() == 0
    for name in (
        checkpoint_name(40),
        checkpoint_name(1200),
        f".tmp-{checkpoint_name(2000)}",
        "ep-7",
    ):
        (run.checkpoints / name).mkdir(parents=True)
    assert [p.name for p in list_checkpoints(run.checkpoints)] == [
        "ep-000000000040",
        "ep-000000001200",
    ]
    assert run.newest_checkpoint() == 1200


def test_only_the_run_folder_module_spells_the_file_names():
    """Every reader and writer of a run folder takes the names from `curious.runs.folder_layout`."""
    spelled = []
    for top in ("curious", "pipelines", "notebooks", "benchmarks"):
        for path in sorted((ROOT / top).rglob("*.py")):
            if path == ROOT / "curious" / "runs" / "folder_layout.py":
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Constant) and node.value in RUN_ENTRIES:
                    spelled.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.value}")
    assert spelled == []


def test_a_new_run_inside_another_runs_folder_is_refused(tmp_path):
    """The search for runs stops at a run folder, so a run inside one would be lost to `curious
    progress`, `curious ship` and the analysis; a project's own config.json is no run."""
    config = resolve("smoke", "curious", 0)
    outer = _written(tmp_path / "outer", "default")
    for restart in (False, True):
        with pytest.raises(RunFolderError, match=r"lies inside the run folder .*outer"):
            RunFolder.prepare(outer.path / "a" / "inner", config, resume=False, restart=restart)
    (tmp_path / "project").mkdir()
    (tmp_path / "project" / "config.json").write_text('{"name": "my project"}')
    RunFolder.prepare(tmp_path / "project" / "runs" / "r", config, resume=False)
    inner = _written(outer.path / "inner", "default")  # made before the check: it still resumes
    RunFolder.prepare(inner.path, config, resume=True)


@pytest.mark.parametrize(
    ("where", "resume", "restart"),
    [
        ("main/curious/seed-0", True, False),  # `train --resume` on a shipped run
        ("main/curious/seed-0", False, True),  # `--restart` would replace its tables
        ("main/curious/seed-9", False, False),  # a new run among the shipped ones
    ],
)
def test_no_run_trains_in_a_shipped_data_folder(tmp_path, where, resume, restart):
    """A shipped data folder holds finished runs' tables for the analysis, committed with the
    repository: a resume has no checkpoint there, and `--restart` or a new run would overwrite or
    mix with what the report reads. Refused before anything is written, naming the folder."""
    data = tmp_path / "data"
    _written(data / "main" / "curious" / "seed-0", "default")
    (data / SHIPPED_MANIFEST_FILE).write_text('{"format": 2, "budget": null, "runs": []}')
    before = sorted(p.relative_to(data) for p in data.rglob("*"))
    config = resolve("smoke", "curious", 0)
    with pytest.raises(RunFolderError, match=f"lies in the shipped data folder {data}"):
        RunFolder.prepare(data / where, config, resume=resume, restart=restart)
    assert sorted(p.relative_to(data) for p in data.rglob("*")) == before
    RunFolder.prepare(tmp_path / "elsewhere", config, resume=False)


def test_a_folder_of_runs_given_as_a_run_names_the_runs_it_holds(tmp_path):
    """`curious evaluate`, `render --run` and `train --resume` given a reproduction's output or
    a `--seeds` folder instead of a run: the error names runs to choose from, not just the
    missing config.json; a folder holding none says only what is missing."""
    seeds = [_written(tmp_path / "runs" / f"seed-{i}", "default").path for i in range(4)]
    (tmp_path / "runs" / "seed-0" / "checkpoints" / "x").mkdir(parents=True)
    (tmp_path / "runs" / "seed-0" / "checkpoints" / "x" / "config.json").write_text("{}")
    named = f"it holds runs: {seeds[0]}, {seeds[1]}, {seeds[2]} and 1 more; name one"
    folder = RunFolder(tmp_path / "runs")
    with pytest.raises(RunFolderError, match="is not a run folder") as info:
        folder.read_info()
    assert str(info.value).endswith(f"no config.json; {named}")
    config = resolve("smoke", "curious", 0)
    with pytest.raises(RunFolderError, match="nothing to resume") as resumed:
        folder.check_resumable(config)
    assert str(resumed.value).endswith(
        f"does not exist; {named}, or resume them all with `--seeds 0-3`"
    )
    (tmp_path / "runs" / "seed-2" / "config.json").unlink()  # a gap: the seeds as written
    with pytest.raises(RunFolderError, match=r"them all with `--seeds 0-1,3`$"):
        folder.check_resumable(config)
    _written(tmp_path / "runs" / "main" / "her" / "seed-0", "default")  # not a --seeds folder
    with pytest.raises(RunFolderError, match=r"and 1 more; name one$"):
        folder.check_resumable(config)
    (tmp_path / "empty").mkdir()
    with pytest.raises(RunFolderError) as bare:
        RunFolder(tmp_path / "empty").read_info()
    assert str(bare.value).endswith("it has no config.json")
    with pytest.raises(RunFolderError, match="nowhere does not exist: name a run folder"):
        RunFolder(tmp_path / "nowhere").read_info()
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(RunFolderError, match=r"notes\.txt is a file, not a run folder$"):
        RunFolder(tmp_path / "notes.txt").read_info()


def test_a_table_of_another_run_is_refused_naming_its_columns(tmp_path):
    """A run goes on only from its own tables: a shipped one (most columns dropped) or one of
    other modules is refused in a line naming what differs, not with both column lists."""
    import pyarrow.parquet as pq

    from curious.runs import metrics

    path = tmp_path / "metrics.parquet"
    schema = metrics.metrics_schema(["reach", "stack"])
    shipped = [n for n in schema.names if n not in ("worker", "g0", "g1", "g2", "success")]
    pq.write_table(schema.empty_table().select(shipped), path)
    with pytest.raises(ValueError, match=r"it lacks worker, g0, g1, g2, success \(a table of"):
        metrics.MetricsLog(path, ["reach", "stack"])
    pq.write_table(metrics.metrics_schema(["reach", "push"]).empty_table(), path)
    with pytest.raises(ValueError) as caught:
        metrics.MetricsLog(path, ["reach", "stack"])
    message = str(caught.value)
    assert "it lacks competence/stack, lp/stack, p_lp/stack; it has competence/push, " in message
    assert len(message) < 400


def test_a_metrics_file_that_cannot_be_written_is_named_and_left_as_it_was(tmp_path, monkeypatch):
    """pyarrow's error on a full disk names neither the file nor the cause alone ("Error
    writing bytes to file. Detail: [errno 28] ..."): the log's is an OSError with the errno,
    its reason and the file, and the last good file stays, with no temporary file beside it."""
    import errno

    import numpy as np
    import pyarrow as pa

    from curious.runs import metrics

    log = metrics.MetricsLog(tmp_path / "metrics.parquet", ["reach"])
    rows = {
        field.name: np.array(["reach"])
        if pa.types.is_string(field.type)
        else np.zeros(1, dtype=field.type.to_pandas_dtype())
        for field in log.schema
    }
    log.append(rows)
    log.flush()
    good = (tmp_path / "metrics.parquet").read_bytes()

    def full_disk(table, where, **kwargs):
        Path(where).write_bytes(b"PAR1 cut")
        raise OSError(errno.ENOSPC, "Error writing bytes to file. Detail: [errno 28] No space")

    monkeypatch.setattr(metrics.pq, "write_table", full_disk)
    log.append(rows)
    with pytest.raises(OSError) as caught:
        log.flush()
    assert caught.value.errno == errno.ENOSPC
    assert caught.value.strerror == "No space left on device"
    assert caught.value.filename == str(tmp_path / "metrics.parquet")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["metrics.parquet"]
    assert (tmp_path / "metrics.parquet").read_bytes() == good


@pytest.mark.parametrize(
    ("fields", "generation"),
    [
        (
            {"cpu family": "25", "model": "17", "flags": "fpu avx avx2 avx512f"},
            "family 25 model 17, AVX512",
        ),
        (
            {"cpu family": "25", "model": "1", "flags": "fpu avx avx2 fma"},
            "family 25 model 1, AVX2",
        ),
        ({"cpu family": "6", "model": "85", "flags": "fpu sse2"}, "family 6 model 85"),
        ({"model name": "AMD EPYC", "flags": "avx2"}, None),
    ],
)
def test_the_cpu_generation_tells_apart_what_one_model_name_hides(fields, generation):
    """Two boots of a virtual `AMD EPYC` can be different generations, and a run's pace differs
    with them: family, model and the widest vector instructions say which."""
    from curious.runs.provenance import _cpu_generation

    assert _cpu_generation(fields) == generation
