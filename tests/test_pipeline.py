"""`curious reproduce` and the Dagster pipeline behind it, on the smoke budget.

One smoke reproduction (every experiment, each run 24 episodes) is built once per session
(`conftest.py`) and shared with the notebook tests.
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from pipeline_pools import InterruptingPool, OrderPool

from curious.cli import main as curious_cli
from curious.reproduction.experiments import get_budget
from curious.reproduction.figures import figures_of
from curious.runs.provenance import machine, machine_text
from curious.watching.recording.reader import summarize
from pipelines.executors import LocalPool
from pipelines.reproduce import ReproduceError, check_output_folder, reproduce
from pipelines.resources import OutputLayout
from pipelines.training import FINISHED, folder_state, run_folder

FIGURES = (
    "fig2a",
    "fig2b",
    "fig2c",
    "table1",
    "distractors",
    "sensor_failure",
    "sensor_failure_mastered",
)
SMOKE = get_budget("smoke")
N_SMOKE = len(SMOKE.runs())
"""Runs of a whole smoke reproduction."""


def hashes(folder: Path) -> dict[str, str]:
    """Content hash of every file below `folder` (training locks, naming their holder, aside)."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.name.endswith(".lock")
    }


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# ------------------------------------------------------------------------------ the smoke output


def test_smoke_reproduce_builds_every_figure_and_the_report(smoke):
    out = smoke.out
    for name in FIGURES:
        for ext in ("png", "svg"):
            assert (out / "figures" / f"{name}.{ext}").stat().st_size > 1000, (name, ext)
    report = (out / "report.md").read_text()
    for name in FIGURES:
        assert f"](figures/{name}.png)" in report
    for experiment in SMOKE.experiments.values():
        assert experiment.title in report
    assert "Welch's t-test" in report and "24 episodes" in report
    # the main comparison's numbers come from the test rollouts, as Fig. 2a's
    assert (
        "Test success over achievable modules in the last 1-episode bin (to 24 episodes" in report
    )
    assert "Welch's t-test per 1-episode bin" in report and "significant in 0 of 2 bins" in report
    assert "computation, `curious.analysis.main_comparison`" in report
    assert "test success at the last epoch" in report
    # what the report was built from, counted from its tables; the whole budget beside it
    built = f"This report was built from {N_SMOKE} runs, {N_SMOKE * 24} training episodes in all"
    assert f"{built}: main 6 runs" in report
    assert (
        f"The budget `smoke` as a whole (`curious reproduce --budget smoke`) trains {N_SMOKE} runs"
        in report
    )
    # the smoke failure starts at episode 12 on an unlearned module: no recovery is claimed
    assert "The failure starts at episode 12. It started at episode 12 in every run." in report
    assert "nothing to forget" in report and "No recovery can be measured" in report
    assert "regained" not in report
    # C4's degradation test, from the distractors' own table (one seed a setting: not tested)
    from curious import analysis

    final = analysis.final_competence(
        pq.read_table(out / "metrics" / "distractors.parquet").to_pandas()
    )
    d = analysis.compare_degradation(final, "curious", "m-uvfa")
    assert (
        f"From 0 to 7 distracting modules the mean competence fell by {d['loss_curious']:.2f} for "
        f"CURIOUS and by {d['loss_m-uvfa']:.2f} for M-UVFA: a difference of "
        f"{d['difference']:+.2f} (not tested: a group with fewer than two seeds" in report
    )
    # ... and the distractors' second measure, each setting's test success at the end
    tests = pq.read_table(out / "metrics" / "distractors.tests.parquet").to_pandas()
    tested = analysis.final_test_success(tests)
    end, width = int(tested["episodes"].iat[0]), tested.attrs["bin_size"]
    assert (
        "Test success (the noise-free test rollouts on achievable modules, pooled per run) over "
        f"episodes {end - width + 1:,}–{end:,}, mean ± std over seeds:" in report
    )
    assert "Welch's t-test per setting (test success at the end)" in report
    # the training time is read off the runs' own clocks, not a fixed sentence
    walls = [
        pq.read_table(p, columns=["wall_time"])["wall_time"].to_numpy().max()
        for p in sorted((out / "runs").rglob("metrics.parquet"))
    ]
    assert f"{len(walls)} runs, {sum(walls) / 60:,.1f} run-minutes in all" in report
    # ... and per experiment, with the machine the runs recorded
    main = [
        pq.read_table(p, columns=["wall_time"])["wall_time"].to_numpy().max()
        for p in sorted((out / "runs" / "main").rglob("metrics.parquet"))
    ]
    here = machine_text(machine())
    assert f"- `main`: {len(main)} runs, {sum(main) / 3600:,.2f} run-hours, on {here}." in report
    # C1 and C2: episodes to 0.5 / 0.9 test success per module and seed, and the order of
    # learning against the paper's, one row per run of the main comparison
    assert "Episodes to reach test success 0.5 / 0.9 on each achievable module" in report
    assert "| CURIOUS | 0 | " in report and "| HER | 1 | " in report
    # C1: each module at the runs' end, and HER's per-module view of its rollouts
    assert "Test success on each achievable module over the last 5 epochs of each run" in report
    assert "Each achievable module's own part of the goal met, over every test rollout" in report
    assert "Order of learning: the first episode at which each module's competence" in report
    # C5: the drop, the LP and p_LP before and after the failure, per run
    assert "| LP before → after | p_LP before → after | recovery (episodes) |" in report
    # two levels before the failure, named apart
    assert (
        "| competence at the onset | pre-failure mean | drop from the pre-failure mean |" in report
    )
    assert "competence then" not in report and "competence before" not in report
    # C5 on a mastered module: recovery by test success (primary) beside the competence's, and
    # the Welch test on the episodes to recover; the smoke failure comes before 5 epochs of tests
    mastered = report[report.index("## Sensory failure on a mastered module") :]
    assert "Recovery by test success, the primary measure" in mastered
    assert (
        "| test success before (rollouts) | test success trough | LP before → after | "
        "p_LP before → after | practised before → after | recovery by test success (primary) | "
        "recovery by competence (secondary) |"
    ) in mastered
    assert "| CURIOUS | 0 | 12 | – | – |" in mastered
    assert mastered.count("| no level before | – |") == 2
    assert "Recovered by test success: CURIOUS 0 of 1 runs; M-UVFA 0 of 1 runs." in mastered
    assert (
        "One-tailed Welch's t-test on the episodes to recover by test success, CURIOUS faster "
        "than M-UVFA, alpha = 0.01: not tested (0 and 0 recovered runs" in mastered
    )
    assert (
        "- CURIOUS seed 0: no level before: the failure started at episode 12, after 1 epoch(s) "
        "of tests, fewer than the 5 epochs (40 episodes) its level pools." in mastered
    )
    # the command ends by saying where the products are
    assert str(out / "report.md") in smoke.stdout and str(out / "figures") in smoke.stdout
    assert json.loads((out / "reproduce.json").read_text())["budget"] == "smoke"
    assert "# CURIOUS reproduction — budget `smoke`" in report
    assert "`curious reproduce --budget smoke`" in report


def test_reproduce_json_records_how_many_runs_train_at_once(smoke):
    """For `curious progress`'s hours left: the worker processes of this machine's pool (one
    per core by default); shipped data trains nothing and records none."""
    manifest = json.loads((smoke.out / "reproduce.json").read_text())
    assert manifest["at_once"] == max(1, os.cpu_count() or 1), manifest


def test_every_partition_is_one_finished_run_folder(smoke):
    runs_root = smoke.out / "runs"
    specs = SMOKE.runs()
    assert len(specs) == N_SMOKE
    for spec in specs:
        folder = run_folder(spec, runs_root)
        assert folder_state(spec, runs_root) == FINISHED, spec.label
        config = json.loads((folder / "config.json").read_text())
        assert (config["condition"], config["variant"], config["seed"]) == (
            spec.condition,
            spec.variant,
            spec.seed,
        )
        episodes = pq.read_table(folder / "metrics.parquet", columns=["episode"])["episode"]
        assert episodes.to_pylist() == list(range(24))
        entities = summarize(folder / "recording.rrd").entities
        assert "scene/goal" in entities and "scene/gripper_path" in entities  # a 3-D rollout
        expected = 12 if spec.variant == "sensor_failure" else -1
        assert config["config"]["sensor_failure_episode"] == expected
        failing = pq.read_table(folder / "metrics.parquet")["sensor_failure"].to_pylist()
        assert failing == [e >= expected >= 0 for e in range(24)]
        assert pq.read_table(folder / "tests.parquet").num_rows == 3 * 2  # 3 epochs x 2 workers
    # the combined metrics tables hold every run's every episode, and its every test rollout
    for name, experiment in SMOKE.experiments.items():
        table = pq.read_table(smoke.out / "metrics" / f"{name}.parquet")
        assert table.num_rows == 24 * len(experiment.runs())
        tests = pq.read_table(smoke.out / "metrics" / f"{name}.tests.parquet")
        assert tests.num_rows == 3 * 2 * len(experiment.runs())


def test_dagster_instance_in_the_output_folder_records_every_partition(smoke):
    import dagster as dg

    from pipelines.reproduce import open_instance
    from pipelines.resources import OutputLayout

    instance = open_instance(OutputLayout.at(smoke.out))
    try:
        for name, experiment in SMOKE.experiments.items():
            done = instance.get_materialized_partitions(dg.AssetKey([name, "runs"]))
            assert done == {s.partition_key for s in experiment.runs()}
            assert instance.get_latest_materialization_event(dg.AssetKey([name, "metrics"]))
        assert instance.get_latest_materialization_event(dg.AssetKey("report"))
        # every figure's caption ends by saying the budget is a smoke test's (and its seeds)
        assert SMOKE.caption_note
        for name, experiment in SMOKE.experiments.items():
            note = SMOKE.caption_note_for(experiment)
            assert note.startswith(SMOKE.caption_note)
            for figure in (f.name for f in figures_of(name)):
                event = instance.get_latest_materialization_event(dg.AssetKey([name, figure]))
                metadata = event.asset_materialization.metadata
                assert metadata["caption"].value.endswith(note), (name, figure)
                # paths relative to the output folder (it may move); the figure itself, as a
                # markdown image of the PNG file (the UI's "[Show Markdown]" dialog draws it)
                assert metadata["png"].value == f"figures/{figure}.png"
                prefix = f"![{figure}](data:image/png;base64,"
                markdown = metadata["figure"].value
                assert markdown.startswith(prefix) and markdown.endswith(")")
                png = base64.b64decode(markdown[len(prefix) : -1], validate=True)
                assert png == (smoke.out / "figures" / f"{figure}.png").read_bytes()
    finally:
        instance.dispose()


def test_the_dagster_instance_has_telemetry_and_the_community_dialog_off(tmp_path):
    """OUT/.dagster/dagster.yaml, the DAGSTER_HOME the docs and the closing line give the Dagster
    UI: telemetry off and no "join the community" dialog; what an earlier version wrote is
    replaced, a file the user edited (telemetry turned on) is kept."""
    from pipelines import reproduce as module

    layout = OutputLayout.at(tmp_path / "out")
    config = layout.dagster_home / "dagster.yaml"
    for before in (None, *module._OLD_DAGSTER_YAMLS):
        if before is not None:
            config.write_text(before)
        instance = module.open_instance(layout)
        try:
            assert not instance.telemetry_enabled and not instance.nux_enabled, before
        finally:
            instance.dispose()
    mine = config.read_text().replace("telemetry:\n  enabled: false", "telemetry:\n  enabled: true")
    config.write_text(mine)
    instance = module.open_instance(layout)
    try:
        assert instance.telemetry_enabled and config.read_text() == mine
    finally:
        instance.dispose()


def test_the_main_job_also_builds_the_shipped_campaigns_report_and_says_what_each_shows(
    smoke, shipped, tmp_path, monkeypatch, capsys
):
    """`curious reproduce` on a budget with a shipped campaign beside it (the README's quick
    job and data/laptop; here the smoke budget and its shipped smoke runs): the claims first,
    once its input is checked and before it trains, it builds the shipped campaign's report and
    figures into <campaign>-shipped beside OUT, from the shipped runs alone, and says where they
    and the claims' results table are; then what its own budget can show, its training, and at
    the end where each output is and what each can show. --no-shipped leaves the campaign out."""
    import shutil

    from curious.commands import reproduce as command

    out = tmp_path / "runs" / "smoke"
    shutil.copytree(smoke.out, out, ignore=shutil.ignore_patterns("*.lock"))  # all finished
    monkeypatch.setattr(command, "SHIPPED_BESIDE", {"smoke": "smoke"})
    monkeypatch.setattr(command, "shipped_data_folder", lambda name: shipped.data)
    args = ["reproduce", "--budget", "smoke", "--out", str(out), "--no-progress"]
    assert curious_cli(args) == 0
    stdout = capsys.readouterr().out
    beside = tmp_path / "runs" / "smoke-shipped"
    assert (beside / "report.md").read_bytes() == (smoke.out / "report.md").read_bytes()
    assert sorted(p.name for p in (beside / "figures").iterdir()) == sorted(
        p.name for p in (smoke.out / "figures").iterdir()
    )
    assert f"0 run(s) trained, {N_SMOKE} already finished" in stdout
    assert f"{N_SMOKE} shipped run(s) read, none trained" in stdout
    order = [
        "The paper's claims first: the shipped `smoke` campaign's report",
        f"{N_SMOKE} shipped run(s) read, none trained",
        f"results table: {command.results_page()} (each claim's verdict",
        "Now the budget `smoke`, trained here",
        f"0 run(s) trained, {N_SMOKE} already finished",
    ]
    found = [stdout.find(line) for line in order]
    assert -1 not in found and found == sorted(found), stdout
    assert "at_once" not in json.loads((beside / "reproduce.json").read_text())  # trains none
    closing = stdout[stdout.index("What each output can show:") :]
    assert f"{out / 'report.md'} and {out / 'figures'}/" in closing
    assert "it cannot show the paper's claims" in closing
    assert f"{beside / 'report.md'} and {beside / 'figures'}/" in closing
    assert f"the shipped `smoke` campaign, {N_SMOKE} runs read from {shipped.data}" in closing
    assert "C1, CURIOUS learns faster than MG-TE" in closing
    assert "C5 on a module just learned" in closing
    assert "C4" in closing and "C5, the recovery of a mastered module's test success" in closing

    shutil.rmtree(beside)
    assert curious_cli([*args, "--experiments", "distractors", "--no-shipped"]) == 0  # one figure
    stdout = capsys.readouterr().out
    assert not beside.exists() and "shipped run(s) read" not in stdout
    assert "What each output can show:" in stdout and "smoke-shipped" not in stdout


def test_the_readme_job_builds_the_repositorys_shipped_laptop_campaign():
    """The quick budget's campaign beside it is data/laptop, which a clone holds."""
    from curious.commands import reproduce as command

    assert command.SHIPPED_BESIDE == {"quick": "laptop"}
    data = Path(__file__).resolve().parents[1] / "data" / "laptop"
    if not (data / "shipped.json").is_file():
        pytest.skip("no data/laptop in this checkout")
    assert command.shipped_data_folder("laptop") == data


def test_second_reproduce_retrains_nothing_and_leaves_logging_handlers_open(smoke, tmp_path):
    """Run again on a copy of the smoke output: it rewrites the figures (byte-identical), which
    other workers' tests read from the shared output meanwhile."""
    import logging

    class Handler(logging.Handler):
        closed = False

        def emit(self, record):
            pass

        def close(self):
            Handler.closed = True
            super().close()

    handler = Handler()  # a caller's handler (a notebook's, absl's) must survive the Dagster runs
    logging.getLogger("caller").addHandler(handler)
    out = tmp_path / "out"
    shutil.copytree(smoke.out, out)
    runs_before = hashes(out / "runs")
    figures_before = hashes(out / "figures")
    try:
        result = reproduce("smoke", out=out, progress=False, say=lambda _: None)
    finally:
        logging.getLogger("caller").removeHandler(handler)
    assert not Handler.closed
    assert any(ref() is handler for ref in logging._handlerList)  # closed at exit as usual
    assert result.trained == [] and len(result.skipped) == N_SMOKE
    assert hashes(out / "runs") == runs_before  # not one byte of a run changed
    assert hashes(out / "figures") == figures_before  # figures rebuild byte-identical


@pytest.mark.parametrize("experiment", ["distractors", "sensor_failure_mastered"])
def test_a_figure_drawn_without_its_test_panel_is_captioned_without_it(smoke, tmp_path, experiment):
    """Runs trained with `test_rollouts_per_worker=0` have no test rollouts: the distractors
    and the mastered sensory failure's figures draw no test success panel, and the report's
    caption does not name one."""
    import shutil

    from curious.reproduction.figures import get_figure
    from pipelines.report import write_report
    from pipelines.resources import OutputLayout, Reproduction

    name = {"distractors": "distractors", "sensor_failure_mastered": "sensor_failure_mastered"}
    out = tmp_path / "out"
    shutil.copytree(smoke.out, out, ignore=shutil.ignore_patterns("*.lock", ".dagster"))
    repro = Reproduction(SMOKE, OutputLayout.at(out), make_pool=LocalPool)
    report, _ = write_report(repro)
    spec = get_figure(name[experiment])
    assert spec.untested_text and spec.text != spec.untested_text
    assert spec.text in report.read_text()  # with test rollouts

    for path in (out / "runs" / experiment).rglob("tests.parquet"):
        path.unlink()
    repro.layout.tests(experiment).unlink()
    report, _ = write_report(repro)
    text = report.read_text()
    assert spec.text not in text
    assert spec.untested_text in text


def test_runs_without_test_rollouts_get_no_fig2a_and_the_report_says_why(smoke, tmp_path):
    import shutil

    from curious.analysis import AnalysisError
    from pipelines.assets import load_tests
    from pipelines.report import write_report
    from pipelines.report.blocks import NO_TESTS
    from pipelines.resources import OutputLayout, Reproduction

    out = tmp_path / "out"
    shutil.copytree(smoke.out, out, ignore=shutil.ignore_patterns("*.lock", ".dagster"))
    for path in (out / "runs" / "main").rglob("tests.parquet"):  # as runs trained before them
        path.unlink()
    (out / "metrics" / "main.tests.parquet").unlink()
    repro = Reproduction(SMOKE, OutputLayout.at(out), make_pool=LocalPool)
    main = SMOKE.experiments["main"]
    with pytest.raises(AnalysisError, match=r"main/curious/seed-0 has no test rollouts"):
        load_tests(repro, main)  # what the fig2a asset reads: no fallback to the competence
    report, _ = write_report(repro)
    text = report.read_text()
    assert NO_TESTS in text and "Test success over achievable modules" not in text
    assert "final competence" in text


def test_a_failure_that_never_started_shows_as_such_in_the_report(tmp_path):
    from test_analysis_synthetic import FAILURE_MODULES, failure_curves, write_run

    from curious import analysis
    from pipelines.report.blocks import ExperimentTables
    from pipelines.report.sensory_failures import sensor_failure
    from pipelines.resources import OutputLayout, Reproduction

    # A short laptop run's case: push_cube3 never reaches the 0.5 that would start the failure.
    laptop = get_budget("laptop")
    for condition in ("curious", "m-uvfa"):
        write_run(
            tmp_path / "runs" / condition,
            condition=condition,
            seed=0,
            competence=failure_curves(0, 1000, None, 10.0, learned=False),
            achievable=(True,) * len(FAILURE_MODULES),
            variant="sensor_failure",
            sensor_failure_competence=0.5,
            log_failure=True,
        )
    table = analysis.load_runs(tmp_path / "runs")
    repro = Reproduction(laptop, OutputLayout.at(tmp_path / "out"), make_pool=LocalPool)
    figures = repro.layout.figures
    _, per_run = analysis.sensor_failure(table, out_dir=figures)
    per_run.drop(columns=["run"]).to_csv(figures / "sensor_failure.csv", index=False)
    text = "\n".join(
        sensor_failure(repro, laptop.experiments["sensor_failure"], ExperimentTables(table, None))
    )
    assert "The failure starts when the perturbed module's competence reaches 0.5." in text
    assert "It never started in any of the 2 runs." in text
    assert "push_cube3 never reached competence 0.50 over a full window" in text
    assert "No recovery can be measured in these runs." in text
    assert "regained" not in text and "mean recovery" not in text


def test_a_budget_without_the_sensory_failure_says_why_in_its_report(smoke, tmp_path):
    """The quick budget's report over main and distractors tables (here the smoke runs'): one
    sentence on why the sensory failure is left out, and no claim that it is still to come."""
    import shutil

    from pipelines.report import write_report
    from pipelines.resources import OutputLayout, Reproduction

    quick = get_budget("quick")
    out = tmp_path / "out"
    empty = Reproduction(quick, OutputLayout.at(out), make_pool=LocalPool)
    text = write_report(empty)[0].read_text()
    assert quick.why_absent("sensor_failure") in text and "No experiment has finished yet" in text
    for folder in ("metrics", "figures"):
        shutil.copytree(
            smoke.out / folder, out / folder, ignore=shutil.ignore_patterns("sensor_failure*")
        )
    report, included = write_report(Reproduction(quick, OutputLayout.at(out), make_pool=LocalPool))
    text = report.read_text()
    assert included == ["main", "distractors"]
    reasons = [quick.why_absent(name) for name in ("sensor_failure", "sensor_failure_mastered")]
    assert all(text.count(reason) == 1 for reason in reasons)
    assert "sensor_failure" not in text.replace(reasons[0], "").replace(reasons[1], "")
    assert "Budget `quick` leaves out the `sensor_failure` experiment: the failure starts" in text
    assert "not reproduced yet" not in text and "Not in this report" not in text
    assert "Sensory failure" not in text and "figures/sensor_failure" not in text
    assert all(e.title in text for e in quick.experiments.values())


def test_a_measured_recovery_is_reported_with_its_numbers(tmp_path):
    from test_analysis_synthetic import write_perturbation_study

    from curious import analysis
    from pipelines.report.blocks import ExperimentTables
    from pipelines.report.sensory_failures import sensor_failure
    from pipelines.resources import OutputLayout, Reproduction

    write_perturbation_study(tmp_path / "runs", perturbation=300, n_episodes=900, seeds=(0, 1))
    table = analysis.load_runs(tmp_path / "runs")
    paper = get_budget("paper")
    repro = Reproduction(paper, OutputLayout.at(tmp_path / "out"), make_pool=LocalPool)
    _, per_run = analysis.sensor_failure(table, out_dir=repro.layout.figures)
    per_run.drop(columns=["run"]).to_csv(repro.layout.figures / "sensor_failure.csv", index=False)
    lines = sensor_failure(
        repro, paper.experiments["sensor_failure"], ExperimentTables(table, None)
    )
    assert "The failure starts at episode 237,500. It started at episode 300 in every run." in (
        "\n".join(lines)
    )
    summary = analysis.recovery_summary(per_run).set_index("condition")
    mean = summary.loc["curious", "mean_recovery_episodes"]
    row = next(line for line in lines if line.startswith("| CURIOUS | 2/2 |"))
    assert f"| {mean:,.0f} |" in row


def test_the_report_names_each_commit_its_experiments_were_trained_from(tmp_path):
    """A campaign can train a later experiment from its own commit: the report's software line
    then says which experiment came from which, where one commit is one line."""
    import json

    import pandas as pd

    from curious.envs.goal_env import SuiteEnv
    from curious.presets import resolve
    from curious.runs.folder import RunFolder
    from pipelines.report.overview import software

    tables = {}
    for name, commit in (("main", "a" * 40), ("sensor_failure_mastered", "b" * 40)):
        run = RunFolder(tmp_path / name)
        run.write_config(resolve("smoke", "curious", 0), SuiteEnv("default", seed=0).spec)
        data = json.loads(run.config_path.read_text())
        data["git"] = {"commit": commit, "dirty": False}
        run.config_path.write_text(json.dumps(data))
        tables[name] = pd.DataFrame({"run": [str(run.path)]})
    both = software(tables)[0]
    assert both.startswith("Software, per experiment (the first run of each): main: ")
    assert "; git aaaaaaaaaa; sensor_failure_mastered: " in both
    assert both.endswith("; git bbbbbbbbbb.")
    one = software({"main": tables["main"]})[0]
    assert one.startswith("Software: python ") and one.endswith("; git aaaaaaaaaa.")


def test_spontaneous_drops_are_reported_per_run_with_their_response(tmp_path):
    """The forgetting section of the main comparison: a row per run (HER: no self-evaluations)
    and a row per drop, its numbers those of `analysis.mastery_drops`."""
    import numpy as np
    from test_analysis_drops import _reach, _unmastered, _wiggle
    from test_analysis_synthetic import write_run

    from curious import analysis
    from pipelines.report.spontaneous_forgetting import spontaneous_forgetting

    curves = {"reach": _reach(), "push_cube1": _unmastered(), "cube1_above_cube2": _wiggle()}
    write_run(
        tmp_path / "curious", condition="curious", seed=0, competence=curves, achievable=[True] * 3
    )
    flat = {m: np.full(len(c), 0.02) for m, c in curves.items()}
    write_run(tmp_path / "her", condition="her", seed=0, competence=flat, achievable=[True] * 3)
    table = analysis.load_runs(tmp_path)
    for column in [c for c in table.columns if c.startswith("competence/")]:
        table.loc[table["condition"] == "her", column] = np.nan  # HER never self-evaluates
    lines = spontaneous_forgetting(get_budget("laptop").experiments["main"], table)
    text = "\n".join(lines)
    assert lines[0] == "### Spontaneous forgetting"
    assert "for 25 consecutive self-evaluations (a window: 50)" in text
    drops = analysis.mastery_drops(table)
    read = analysis.mastery(table).set_index(["condition", "module"])
    curious = next(line for line in lines if line.startswith("| CURIOUS | 0 |"))
    reach = read.loc[("curious", "reach")]
    assert f"| {int(reach.mastered_episode):,} ({reach.deepest_fall:.2f}) |" in curious
    assert curious.endswith("| 2 |") and "| – |" in curious  # push_cube1 never mastered
    her = next(line for line in lines if line.startswith("| HER | 0 |"))
    assert her.endswith("| no self-evaluations |")
    rows = [line for line in lines if line.startswith("| CURIOUS | 0 | T1 reach |")]
    assert len(rows) == len(drops) == 2
    first = drops.iloc[0]
    assert f"| {int(first.drop_episode):,} |" in rows[0]
    assert f"| {first.peak:.2f} → {first.trough:.2f} at {int(first.trough_episode):,} |" in rows[0]
    assert f"| {first.recovery_episodes:,.0f} |" in rows[0]
    assert rows[1].endswith("| not by the run's end |")
    assert "No drop of a mastered module" not in text


# ------------------------------------------------------------------------------ interruption


def test_runs_are_trained_seed_by_seed_so_a_stopped_campaign_compares_conditions(tmp_path):
    pool = OrderPool()
    with pytest.raises(KeyboardInterrupt):
        reproduce(
            "smoke", ["main"], out=tmp_path / "out", make_pool=lambda: pool, say=lambda _: None
        )
    assert pool.sent == [
        [f"main/{condition}/seed-{seed}"]
        for seed in (0, 1)
        for condition in ("curious", "mg-te", "her")
    ]


def test_interrupted_partition_resumes_and_finished_ones_are_kept(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        reproduce(
            "smoke",
            ["sensor_failure"],
            out=out,
            make_pool=InterruptingPool,
            progress=False,
            say=lambda _: None,
        )
    runs_root = out / "runs"
    finished, killed = get_budget("smoke").experiments["sensor_failure"].runs()
    assert folder_state(finished, runs_root) == FINISHED
    assert folder_state(killed, runs_root) == "partial"
    kept = hashes(run_folder(finished, runs_root))
    # as an earlier version wrote it, naming the budget `preset`: the folder still resumes
    (out / "reproduce.json").write_text(json.dumps({"version": 1, "preset": "smoke"}))

    result = reproduce(
        "smoke",
        ["sensor_failure"],
        out=out,
        make_pool=lambda: LocalPool(1),
        progress=False,
        say=lambda _: None,
    )
    by_key = {r.partition_key: r for r in result.results}
    assert not by_key[finished.partition_key].trained
    assert by_key[killed.partition_key].state_before == "partial"
    assert by_key[killed.partition_key].trained
    assert hashes(run_folder(finished, runs_root)) == kept
    folder = run_folder(killed, runs_root)
    config = json.loads((folder / "config.json").read_text())
    assert len(config["resumed"]) == 1  # went on from its checkpoint, not from scratch
    assert config["config"]["sensor_failure_episode"] == 12
    episodes = pq.read_table(folder / "metrics.parquet", columns=["episode"])["episode"]
    assert episodes.to_pylist() == list(range(24))
    assert (out / "figures" / "sensor_failure.png").is_file()
    # rewritten in today's form: the budget by its name, and how many runs train at once
    manifest = json.loads((out / "reproduce.json").read_text())
    assert manifest == {"version": 1, "budget": "smoke", "at_once": 1}


def group_ends(pgid: int, within: float) -> bool:
    """Whether every process of the group `pgid` is gone within `within` seconds (an exited
    child of a dead parent lingers until the system's init collects it)."""
    deadline = time.time() + within
    while time.time() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.2)
    return False


def test_ctrl_c_stops_a_reproduction_in_one_line_and_every_worker_with_it(tmp_path):
    """Ctrl-C reaches the whole process group (Dagster, the workers): one line, exit status
    130, no process left, no lock left, and the runs keep what they had."""
    out = tmp_path / "out"
    command = [sys.executable, "-m", "curious.cli", "reproduce", "--budget", "smoke"]
    command += ["--experiments", "main", "--out", str(out), "--no-progress"]
    env = {**os.environ, "MUJOCO_GL": "disable", "OMP_NUM_THREADS": "1"}
    proc = subprocess.Popen(
        command,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # a group of its own, as a terminal's foreground job
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        deadline = time.time() + 240
        while not list(out.glob("runs/*/*/*/checkpoints/ep-*")):
            assert proc.poll() is None, proc.communicate()
            assert time.time() < deadline, "no checkpoint within 240 s"
            time.sleep(0.2)
        os.killpg(proc.pid, signal.SIGINT)
        tic = time.time()
        _, err = proc.communicate(timeout=120)
        stopped = time.time() - tic
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, err[-3000:]
    *progress, last = err.strip().splitlines()
    assert last == (
        "curious reproduce: interrupted; the runs keep what they had at their last checkpoint, "
        "and the same command goes on from there"
    ), err[-3000:]
    assert "Traceback" not in err and "dagster" not in err.lower(), err[-3000:]
    assert all(line.startswith(("curious reproduce --budget", "  main: ")) for line in progress)
    assert stopped < 60  # no worker trains a queued run to its end first
    assert group_ends(proc.pid, within=15)  # no worker goes on alone
    assert not list(tmp_path.rglob("*.lock"))
    started = [
        spec for spec in SMOKE.experiments["main"].runs() if run_folder(spec, out / "runs").exists()
    ]
    assert started and {folder_state(s, out / "runs") for s in started} <= {"partial", FINISHED}


def test_a_second_reproduction_of_a_folder_is_refused_at_once(tmp_path, capsys):
    from curious.runs.folder_lock import folder_lock

    out = tmp_path / "out"
    with folder_lock(out, activity="reproduced"):  # as the first `curious reproduce` holds it
        tic = time.perf_counter()
        code, err = run_cli(["--budget", "smoke", "--out", str(out)], capsys)
        assert time.perf_counter() - tic < 30
    assert code == 2 and err.count("\n") == 1
    assert f"{out} is being reproduced by {socket.gethostname()} pid {os.getpid()}" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no folder, no lock file


class FailingPool(InterruptingPool):
    """Every run fails as a worker's run would (another process training its folder...)."""

    description = "this process (failing every run)"

    def submit(self, job):
        return job.spec.label

    def result(self, handle):
        raise RuntimeError(f"{handle} cannot be trained here")


def test_a_failed_run_reaches_the_user_as_one_line_without_dagster_logs(tmp_path, capfd):
    from pipelines.executors import PartitionFailed

    with pytest.raises(PartitionFailed, match="cannot be trained here"):
        reproduce(
            "smoke",
            ["sensor_failure"],
            out=tmp_path / "out",
            make_pool=FailingPool,
            progress=False,
            say=lambda _: None,
        )
    captured = capfd.readouterr()
    assert "Traceback" not in captured.err and "ERROR" not in captured.err, captured.err[-3000:]
    assert "Stack Trace" not in captured.out + captured.err


# ------------------------------------------------------------------------------ bad input


def run_cli(args: list[str], capsys) -> tuple[int, str]:
    code = curious_cli(["reproduce", "--no-progress", *args])
    return code, capsys.readouterr().err


def test_unknown_budget_or_experiment_is_a_clear_error(tmp_path, capsys):
    code, err = run_cli(["--budget", "huge", "--out", str(tmp_path / "a")], capsys)
    assert code == 2 and "unknown budget 'huge'" in err and "quick" in err
    code, err = run_cli(["--budget", "smoke", "--experiments", "main,colours"], capsys)
    assert code == 2 and "unknown experiment(s) 'colours'" in err
    assert "budget 'smoke' has main, distractors" in err
    assert not (tmp_path / "a").exists()


@pytest.mark.parametrize(
    ("flags", "named", "gpu"),
    [
        (["--gpus-per-run", "1"], "--gpus-per-run size", True),
        (["--cpus-per-run", "2"], "--cpus-per-run size", False),
        (
            ["--cpus-per-run", "2", "--gpus-per-run", "0.5"],
            "--cpus-per-run and --gpus-per-run size",
            True,
        ),
    ],
)
def test_ray_resources_without_ray_are_refused_not_ignored(flags, named, gpu, tmp_path, capsys):
    """The way out named: --ray-address, and --device cuda only where a GPU was asked for."""
    code, err = run_cli(["--budget", "smoke", "--out", str(tmp_path / "a"), *flags], capsys)
    assert code == 2 and named in err and "--ray-address" in err
    assert ("--device cuda" in err) == gpu
    assert not (tmp_path / "a").exists()


def test_an_experiment_the_budget_leaves_out_is_a_one_line_error_saying_where_it_is(
    tmp_path, capsys
):
    out = tmp_path / "q"
    args = ["--budget", "quick", "--experiments", "sensor_failure", "--out", str(out)]
    code, err = run_cli(args, capsys)
    assert code == 2 and len(err.splitlines()) == 1
    assert err.startswith(
        "curious reproduce: error: budget 'quick' has no sensor_failure experiment (budgets with "
        "it: smoke, laptop, paper): the failure starts once push_cube3's competence reaches 0.5"
    )
    assert "`curious reproduce --budget laptop --experiments sensor_failure`" in err
    assert not out.exists()


def test_reproduce_set_takes_where_and_how_fast_runs_go_only(tmp_path, capsys, monkeypatch):
    """`--set` reaches every run for settings that leave what a run computes as it is; one that
    would change the budget's runs is a one-line error, and nothing is written."""
    import curious.commands.reproduce
    import pipelines.reproduce

    code, err = run_cli(
        ["--budget", "smoke", "--out", str(tmp_path / "a"), "--set", "n_updates=3"], capsys
    )
    assert code == 2 and len(err.splitlines()) == 1
    assert "n_updates would change the budget's runs" in err and "env_processes" in err
    assert not (tmp_path / "a").exists()
    seen = {}

    def fake(budget, **kwargs):
        seen.update(kwargs)
        raise pipelines.reproduce.ReproduceError("stop here")

    monkeypatch.setattr(curious.commands.reproduce, "reproduce", fake)
    args = ["--set", "env_processes=2", "--set", "prefetch_minibatches=true", "--device", "cpu"]
    code, err = run_cli(["--budget", "smoke", *args], capsys)
    assert code == 2 and "stop here" in err
    assert seen["overrides"] == {"env_processes": 2, "prefetch_minibatches": True, "device": "cpu"}


def test_reproduce_given_preset_says_it_takes_budget(tmp_path, capsys):
    """`--preset`, reproduce's option before budgets were named apart, is a one-line error."""
    with pytest.raises(SystemExit) as exit_:
        run_cli(["--preset", "smoke", "--out", str(tmp_path / "a")], capsys)
    assert exit_.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == (
        "curious reproduce: error: reproduce takes --budget smoke (smoke, quick, laptop, paper), "
        "not --preset; training presets are for `curious train --preset`"
    )
    with pytest.raises(SystemExit):
        run_cli(["--preset"], capsys)
    assert "reproduce takes --budget NAME" in capsys.readouterr().err
    assert not (tmp_path / "a").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--out", "{data}"], "--out {data} is a shipped data folder"),
        (["--out", "{data}/report"], "--out {data}/report lies in the shipped data folder {data}"),
        (
            ["--out", "{tmp}/new", "--runs-dir", "{data}/runs"],
            "--runs-dir {data}/runs lies in the shipped data folder {data}",
        ),
    ],
)
def test_a_reproduction_writes_nothing_into_a_shipped_data_folder(args, message, tmp_path, capsys):
    """A data folder `curious ship` wrote (committed with the repository) holds finished runs'
    tables only: a reproduction's output or runs inside it are refused before any run starts,
    and the folder is left as it was."""
    data = tmp_path / "data"
    data.mkdir()
    (data / "shipped.json").write_text('{"format": 2, "budget": null, "runs": []}')
    fill = {"data": str(data), "tmp": str(tmp_path)}
    code, err = run_cli(["--budget", "smoke", *(a.format(**fill) for a in args)], capsys)
    assert code == 2 and message.format(**fill) in err
    assert [p.name for p in data.iterdir()] == ["shipped.json"]
    assert not (tmp_path / "new").exists()


def test_an_output_folder_whose_manifest_says_preset_is_read_as_its_budget(tmp_path):
    """reproduce.json of an earlier version names the budget `preset`: the folder still goes on."""
    from pipelines.resources import OutputLayout

    out = tmp_path / "quick"
    out.mkdir()
    (out / "reproduce.json").write_text(json.dumps({"version": 1, "preset": "smoke"}))
    layout = OutputLayout.at(out)
    check_output_folder(layout, SMOKE)
    with pytest.raises(ReproduceError, match="holds the output of budget 'smoke', not 'quick'"):
        check_output_folder(layout, get_budget("quick"))


def test_output_of_another_budget_is_refused_untouched(smoke, tmp_path, capsys):
    before = hashes(smoke.out)
    code, err = run_cli(["--budget", "quick", "--out", str(smoke.out)], capsys)
    assert code == 2 and "holds the output of budget 'smoke'" in err
    # the same runs given as --runs-dir of a new output folder: refused run by run
    code, err = run_cli(
        [
            "--budget",
            "quick",
            "--out",
            str(tmp_path / "new"),
            "--runs-dir",
            str(smoke.out / "runs"),
        ],
        capsys,
    )
    assert code == 2 and "holds a run of training preset 'smoke', not 'quick'" in err
    assert "made by another budget" in err
    assert hashes(smoke.out) == before
    assert not (tmp_path / "new").exists()


def test_a_reproduction_made_with_runs_dir_goes_on_there_without_the_flag(smoke, tmp_path, capsys):
    """Run again without --runs-dir, it goes on with its runs instead of training them anew in
    OUT/runs; another --runs-dir is refused, naming the one it was made with."""
    import shutil

    out, runs = tmp_path / "out", tmp_path / "shared"
    shutil.copytree(smoke.out / "runs" / "main", runs / "main")
    out.mkdir()
    manifest = {"version": 1, "budget": "smoke", "runs_dir": str(runs)}
    (out / "reproduce.json").write_text(json.dumps(manifest))
    code = curious_cli(["reproduce", "--no-progress", "--budget", "smoke", "--out", str(out),
                        "--experiments", "main"])  # fmt: skip
    assert code == 0
    assert "0 run(s) trained, 6 already finished" in capsys.readouterr().out
    assert not (out / "runs").exists()
    assert json.loads((out / "reproduce.json").read_text())["runs_dir"] == str(runs)
    other = tmp_path / "other"
    code, err = run_cli(
        ["--budget", "smoke", "--out", str(out), "--experiments", "main", "--runs-dir", str(other)],
        capsys,
    )
    assert code == 2 and f"whose runs are in {runs}, not {other}: pass --runs-dir {runs}" in err
    assert json.loads((out / "reproduce.json").read_text())["runs_dir"] == str(runs)
    assert not (other / "main").exists()


def test_a_folder_that_is_not_a_reproduction_is_refused(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine")
    code, err = run_cli(["--budget", "smoke", "--out", str(tmp_path)], capsys)
    assert code == 2 and "not made by `curious reproduce`" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_a_damaged_manifest_or_run_config_is_a_one_line_error(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "reproduce.json").write_text("[1, 2]")
    code, err = run_cli(["--budget", "smoke", "--out", str(out)], capsys)
    assert code == 2 and err.count("\n") == 1 and "reproduce.json is unreadable" in err
    (out / "reproduce.json").write_text(json.dumps({"version": 1, "budget": "smoke"}))
    folder = run_folder(SMOKE.experiments["main"].runs()[0], out / "runs")
    folder.mkdir(parents=True)
    for text in ('{"config": 5}', "[1, 2, 3]", "", "{{"):
        (folder / "config.json").write_text(text)
        code, err = run_cli(["--budget", "smoke", "--out", str(out)], capsys)
        assert code == 2 and err.count("\n") == 1, err
        assert f"{folder / 'config.json'} is damaged" in err and "Traceback" not in err
    assert sorted(p.name for p in out.iterdir()) == ["reproduce.json", "runs"]


def test_a_run_being_trained_elsewhere_is_not_touched(smoke, capsys):
    from pipelines.training import training_lock

    spec = SMOKE.experiments["main"].runs()[0]
    before = hashes(smoke.out)
    with training_lock(spec, smoke.out / "runs"):  # as a worker of another reproduction would
        code, err = run_cli(["--budget", "smoke", "--out", str(smoke.out)], capsys)
    assert code == 2 and f"is being trained by {socket.gethostname()} pid {os.getpid()}" in err
    assert hashes(smoke.out) == before


def test_ray_address_that_does_not_answer_fails_fast(tmp_path, capsys):
    tic = time.perf_counter()
    port = free_port()
    code, err = run_cli(
        ["--budget", "smoke", "--out", str(tmp_path / "o"), "--ray-address", f"127.0.0.1:{port}"],
        capsys,
    )
    assert code == 2 and f"no Ray cluster answers at 127.0.0.1:{port}" in err
    assert time.perf_counter() - tic < 60  # an error, not Ray's minutes-long connect retries
    assert not (tmp_path / "o").exists()
    code, err = run_cli(["--budget", "smoke", "--ray-address", "nonsense"], capsys)
    assert code == 2 and "HOST:PORT" in err


# ------------------------------------------------------------------------------ definitions


def test_definitions_load_with_dagster_and_group_the_experiments(tmp_path, monkeypatch):
    import dagster as dg

    from pipelines.definitions import definitions_from_environment

    monkeypatch.setenv("CURIOUS_BUDGET", "smoke")
    monkeypatch.setenv("CURIOUS_OUT", str(tmp_path))
    defs = definitions_from_environment()
    graph = defs.resolve_asset_graph()
    groups = {key.to_user_string(): graph.get(key).group_name for key in graph.get_all_asset_keys()}
    assert groups["report"] == "report"
    for name in ("main", "distractors", "sensor_failure", "sensor_failure_mastered"):
        assert {k for k, g in groups.items() if g == name} >= {f"{name}/runs", f"{name}/metrics"}
    assert {k for k, g in groups.items() if g == "main"} == {
        "main/runs",
        "main/metrics",
        "main/fig2a",
        "main/fig2b",
        "main/fig2c",
        "main/table1",
    }
    distractors = graph.get(dg.AssetKey(["distractors", "runs"])).partitions_def
    assert set(distractors.get_partition_keys()) == {
        s.partition_key for s in SMOKE.experiments["distractors"].runs()
    }
    assert "curious@distractors_7|0" in distractors.get_partition_keys()
    # `dagster-webserver -m pipelines.code_location` finds the same definitions (validated, no
    # server)
    env = {**os.environ, "CURIOUS_BUDGET": "smoke", "CURIOUS_OUT": str(tmp_path)}
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "dagster",
            "definitions",
            "validate",
            "-m",
            "pipelines.code_location",
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert not any(tmp_path.iterdir())  # loading the definitions writes nothing


def test_definitions_refuse_the_old_curious_preset_variable(tmp_path, monkeypatch):
    from curious.reproduction.experiments import ExperimentError
    from pipelines.definitions import reproduction_from_environment

    monkeypatch.delenv("CURIOUS_BUDGET", raising=False)
    monkeypatch.setenv("CURIOUS_PRESET", "smoke")
    monkeypatch.setenv("CURIOUS_OUT", str(tmp_path))
    with pytest.raises(ExperimentError, match="no longer read: set CURIOUS_BUDGET=smoke instead"):
        reproduction_from_environment()
    monkeypatch.setenv("CURIOUS_BUDGET", "smoke")
    assert reproduction_from_environment().budget.name == "smoke"
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("value", ["100000000000000000000", "4294967296", "0", "-2", "four"])
def test_definitions_refuse_a_worker_count_no_pool_can_take(value, tmp_path, monkeypatch):
    """`CURIOUS_WORKERS` is bounded as `curious reproduce --workers` is: a count past the pool's
    queue ended in an OverflowError traceback when the UI first trained."""
    from pipelines.definitions import reproduction_from_environment

    monkeypatch.setenv("CURIOUS_BUDGET", "smoke")
    monkeypatch.setenv("CURIOUS_OUT", str(tmp_path))
    monkeypatch.setenv("CURIOUS_WORKERS", value)
    with pytest.raises(
        ValueError, match=f"CURIOUS_WORKERS must be .* from 1 to 4,096, got '{value}'"
    ):
        reproduction_from_environment()
    monkeypatch.setenv("CURIOUS_WORKERS", "3")
    assert reproduction_from_environment() is not None
    assert not any(tmp_path.iterdir())


def test_dagster_webserver_shows_the_asset_graph_and_the_materialisations(smoke, tmp_path):
    """What `dagster-webserver -m pipelines.code_location` serves, on a copy of the smoke output."""
    import shutil
    import urllib.request

    pytest.importorskip("dagster_webserver")
    out = tmp_path / "out"
    shutil.copytree(smoke.out, out)
    env = {
        **os.environ,
        "DAGSTER_HOME": str(out / ".dagster"),
        "CURIOUS_BUDGET": "smoke",
        "CURIOUS_OUT": str(out),
    }
    port = free_port()
    command = [
        sys.executable,
        "-m",
        "dagster_webserver",
        "-m",
        "pipelines.code_location",
        "-h",
        "127.0.0.1",
    ]
    server = subprocess.Popen(
        [*command, "-p", str(port)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    url = f"http://127.0.0.1:{port}"

    def graphql(query: str) -> dict:
        request = urllib.request.Request(
            f"{url}/graphql",
            data=json.dumps({"query": query}).encode(),
            headers={"Content-Type": "application/json"},
        )
        with urllib.request.urlopen(request, timeout=30) as answer:
            return json.loads(answer.read())["data"]

    try:
        for _ in range(240):  # it answers once the definitions are loaded
            if server.poll() is not None:
                pytest.fail(f"the webserver exited: {server.stderr.read()[-2000:]}")
            try:
                urllib.request.urlopen(f"{url}/server_info", timeout=2).close()
                break
            except OSError:
                time.sleep(0.5)
        nodes = graphql("{ assetNodes { assetKey { path } groupName } }")["assetNodes"]
        groups = {"/".join(n["assetKey"]["path"]): n["groupName"] for n in nodes}
        assert groups["main/runs"] == "main" and groups["report"] == "report"
        assert {k for k, g in groups.items() if g == "sensor_failure"} == {
            "sensor_failure/runs",
            "sensor_failure/metrics",
            "sensor_failure/sensor_failure",
        }
        assert {k for k, g in groups.items() if g == "sensor_failure_mastered"} == {
            "sensor_failure_mastered/runs",
            "sensor_failure_mastered/metrics",
            "sensor_failure_mastered/sensor_failure_mastered",
        }
        status = graphql(
            '{ assetNodeOrError(assetKey: {path: ["main", "runs"]}) { ... on AssetNode {'
            " assetPartitionStatuses { ... on MultiPartitionStatuses {"
            " ranges { primaryDimStartKey primaryDimEndKey } } } } } }"
        )["assetNodeOrError"]["assetPartitionStatuses"]["ranges"]
        assert status == [{"primaryDimStartKey": "curious", "primaryDimEndKey": "her"}]
    finally:
        server.terminate()
        server.wait(timeout=60)


def test_an_output_folder_opens_at_the_runs_folder_it_records(tmp_path):
    """Notebooks, `curious ship` and a re-run of `curious reproduce` all find a reproduction's
    runs where its reproduce.json says, and refuse a record that is not one."""
    out, runs = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    manifest = out / "reproduce.json"
    manifest.write_text(json.dumps({"version": 1, "budget": "smoke", "runs_dir": str(runs)}))
    assert OutputLayout.open(out).runs_root == runs.resolve()
    assert OutputLayout.at(out).recorded_runs_dir() == str(runs)
    manifest.write_text(json.dumps({"version": 1, "budget": "smoke"}))
    assert OutputLayout.open(out).runs_root == out.resolve() / "runs"
    assert OutputLayout.at(out).recorded_runs_dir() is None
    manifest.write_text("[1, 2]")
    with pytest.raises(ValueError, match="not a JSON object"):
        OutputLayout.open(out)
    assert OutputLayout.at(out).recorded_runs_dir() is None


def test_reproduce_json_rewritten_keeps_a_campaigns_planned_seeds(tmp_path):
    """`curious reproduce` resuming a folder that tools/campaign.py started keeps the seeds it
    plans beyond the budget's (`extra_seeds`, which `curious progress` lists); another budget's
    plan is not carried over."""
    from pipelines.reproduce import _write_manifest

    layout = OutputLayout.at(tmp_path / "out")
    layout.out.mkdir()
    plan = {"version": 1, "budget": "smoke", "extra_seeds": {"main": [2]}}
    layout.manifest.write_text(json.dumps(plan))
    _write_manifest(layout, get_budget("smoke"))
    assert json.loads(layout.manifest.read_text())["extra_seeds"] == {"main": [2]}
    _write_manifest(layout, get_budget("quick"))
    assert "extra_seeds" not in json.loads(layout.manifest.read_text())


def test_a_gpu_reproduction_on_local_workers_is_told_of_the_mps_server(tmp_path, monkeypatch):
    """Local worker processes sharing one GPU without NVIDIA's MPS server get one line saying
    so (the server lifted fifteen `paper` processes 1.21 x, docs/benchmarks.md); with the
    server's control pipe there, on a CPU, or with one worker, nothing is said."""
    from pipelines.executors import gpu_sharing_hint

    monkeypatch.setenv("CUDA_MPS_PIPE_DIRECTORY", str(tmp_path))
    hint = gpu_sharing_hint(LocalPool(4), "cuda")
    assert hint is not None and "4 worker processes" in hint
    assert "nvidia-cuda-mps-control -d" in hint
    assert gpu_sharing_hint(LocalPool(4), "cpu") is None
    assert gpu_sharing_hint(LocalPool(4), None) is None
    assert gpu_sharing_hint(LocalPool(1), "cuda") is None
    (tmp_path / "control").touch()  # what `nvidia-cuda-mps-control -d` makes
    assert gpu_sharing_hint(LocalPool(4), "cuda") is None


@pytest.mark.parametrize(
    ("workers", "jobs", "said"),
    [
        (1000, 6, "6 local worker processes"),
        (1000, 1, "1 local worker process"),
        (2, 6, "2 local worker processes"),
        (4, 0, "4 local worker processes"),
    ],
)
def test_a_reproduction_names_the_worker_processes_its_runs_keep_busy(workers, jobs, said):
    """`--workers 1000` for 6 runs starts 6 processes, and says so, not 1000; a pool on Ray (or
    any other) is named as it names itself."""
    from pipelines.executors import busy_description

    assert busy_description(LocalPool(workers), jobs) == said
    ray_like = type("RayLike", (), {"description": "Ray tasks at head:6379"})()
    assert busy_description(ray_like, 6) == "Ray tasks at head:6379"
