"""`curious progress`: where each run of a campaign stands, read from its folder alone."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace

import pandas as pd
import pytest

from curious.analysis.loading import AnalysisError
from curious.cli import main as curious_cli
from curious.commands.progress import BEGIN, END, block_episodes, block_rows, fewer_episodes
from curious.reproduction.campaign_progress import (
    current_pace,
    experiment_progress,
    progress_markdown,
    progress_table,
    recorded_at_once,
    runs_at_once,
    summary_markdown,
)
from curious.reproduction.experiments import get_budget


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """Two finished smoke runs and one that has written its config but no episode yet."""
    root = tmp_path_factory.mktemp("campaign")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MUJOCO_GL", "disable")
        for condition in ("curious", "her"):
            out = root / "main" / f"{condition}-0"
            args = ["train", "--condition", condition, "--seed", "0", "--preset", "smoke"]
            assert curious_cli([*args, "--out", str(out), "--no-progress"]) == 0
    started = root / "main" / "mg-te-1"
    started.mkdir()
    config = json.loads((root / "main" / "curious-0" / "config.json").read_text())
    config.update(condition="mg-te", seed=1)
    (started / "config.json").write_text(json.dumps(config))
    return root


def test_rows_come_from_the_folders(campaign):
    rows = {(r.condition, r.seed): r for r in progress_table(campaign, epochs=2)}
    assert set(rows) == {("curious", 0), ("her", 0), ("mg-te", 1)}
    for key in (("curious", 0), ("her", 0)):
        row, folder = rows[key], campaign / "main" / f"{key[0]}-0"
        metrics = pd.read_parquet(folder / "metrics.parquet")
        assert row.episodes == len(metrics) == row.total_episodes == 24
        assert row.done == 1.0
        assert row.checkpoint == 24
        assert row.run_hours == pytest.approx(metrics["wall_time"].max() / 3600)
        tests = pd.read_parquet(folder / "tests.parquet")
        last = sorted(tests["epoch"].unique())[-2:]
        achievable = json.loads((folder / "config.json").read_text())
        names = [
            m for m, a in zip(achievable["modules"], achievable["achievable"], strict=True) if a
        ]
        recent = tests[tests["epoch"].isin(last) & tests["module"].isin(names)]
        assert row.test_count == len(recent) > 0
        assert row.test_success == pytest.approx(recent["success"].mean())
        assert row.test_episode == tests["episode"].max()
        assert len(row.commits) >= 1
    fresh = rows[("mg-te", 1)]
    assert (fresh.episodes, fresh.checkpoint, fresh.test_success) == (0, None, None)


def test_markdown_names_runs_below_the_root(campaign):
    text = progress_markdown(progress_table(campaign), campaign)
    assert "| main/curious-0 | curious | default | 0 | 24 | 24 | 100% |" in text
    assert (
        "| main/mg-te-1 | mg-te | default | 1 | 0 | 24 | 0% | none | 0.00 | - | none yet |" in text
    )
    assert text.count("\n") == 2 + 3
    run = campaign / "main" / "curious-0"  # a run given as the root goes by its own name
    assert "| curious-0 | curious |" in progress_markdown(progress_table(run), run)


def test_update_replaces_only_the_marked_block(campaign, tmp_path, capsys):
    doc = tmp_path / "results.md"
    doc.write_text(f"# Results\n\nbefore\n{BEGIN}\nold table\n{END}\nafter\n")
    assert curious_cli(["progress", str(campaign), "--update", str(doc)]) == 0
    text = doc.read_text()
    assert text.startswith("# Results\n\nbefore\n") and text.endswith(f"{END}\nafter\n")
    assert "old table" not in text and "main/her-0" in text
    assert "Computed by `curious progress" in text
    again = text
    assert curious_cli(["progress", str(campaign), "--update", str(doc)]) == 0
    assert doc.read_text().count(BEGIN) == 1 and len(doc.read_text()) == len(again)


def test_update_names_the_runs_that_lost_episodes_since_the_table_it_replaces(
    campaign, tmp_path, capsys
):
    """A machine that lost a run folder (or rolled it back) leaves a table with fewer episodes
    than the one before: the update says which runs, since the next table cannot."""
    doc = tmp_path / "results.md"
    doc.write_text(f"{BEGIN}\n{END}\n")
    assert curious_cli(["progress", str(campaign), "--update", str(doc)]) == 0
    assert "fewer episodes" not in capsys.readouterr().err  # no table before: nothing to compare
    before = doc.read_text()
    assert block_episodes(before) == {"main/curious-0": 24, "main/her-0": 24, "main/mg-te-1": 0}
    more = before.replace("| curious | default | 0 | 24 |", "| curious | default | 0 | 1,200 |")
    doc.write_text(more.replace("| main/her-0 |", "| main/gone-0 |"))
    assert curious_cli(["progress", str(campaign), "--update", str(doc)]) == 0
    err = capsys.readouterr().err
    assert "fewer episodes than the table this one replaced" in err
    assert "main/curious-0: 24 episodes, the table before: 1,200" in err
    assert "main/gone-0: no longer listed (the table before: 24 episodes)" in err
    assert "main/mg-te-1" not in err and "main/her-0" not in err
    assert curious_cli(["progress", str(campaign), "--update", str(doc)]) == 0
    assert "fewer episodes" not in capsys.readouterr().err  # said once, by the update that saw it


def test_block_episodes_reads_the_runs_table_of_the_block_alone():
    text = (
        "| run | episodes |\n|---|---:|\n| outside | 9 |\n"
        f"{BEGIN}\nComputed at noon.\n\n"
        "| run | condition | episodes | of |\n|---|---|---:|---:|\n"
        "| a/seed-0 | curious | 83,200 | 300,000 |\n| b/seed-1 | m-uvfa | 0 | 50 |\n\n"
        "| experiment | runs finished | episodes |\n|---|---:|---:|\n| a | 0 of 1 | 83,200 |\n"
        f"{END}\n"
    )
    assert block_episodes(text) == {"a/seed-0": 83_200, "b/seed-1": 0}
    assert block_episodes("no block\n") == {}
    assert block_rows(text)["b/seed-1"] == {
        "run": "b/seed-1",
        "condition": "m-uvfa",
        "episodes": "0",
        "of": "50",
    }
    assert block_rows(text.replace(END, "").replace(BEGIN, "")) == {}
    assert fewer_episodes({"a": 5, "b": 3}, {"a": 5, "b": 4}) == []


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("no markers\n", "must hold one line"),
        (f"{END}\n{BEGIN}\n", "must hold one line"),
        (f"{BEGIN}\n{BEGIN}\n{END}\n", "must hold one line"),
        (f"{BEGIN}\n\xe9t\xe9\n{END}\n".encode("latin-1"), "is not UTF-8 text (invalid"),
    ],
    ids=["no-markers", "reversed", "twice", "latin-1"],
)
def test_update_refuses_a_file_without_one_block(campaign, tmp_path, capsys, content, message):
    """Refused before any run is read, naming the file, which is left as it was."""
    doc = tmp_path / "results.md"
    data = content if isinstance(content, bytes) else content.encode()
    doc.write_bytes(data)
    assert curious_cli(["progress", str(campaign), "--update", str(doc)]) == 2
    err = capsys.readouterr().err
    assert message in err and str(doc) in err and "Traceback" not in err
    assert doc.read_bytes() == data


def test_bad_roots_are_one_line_errors(tmp_path, capsys):
    assert curious_cli(["progress", str(tmp_path / "nowhere")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert curious_cli(["progress", str(tmp_path)]) == 2
    assert "holds no run folder" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("damage", "problem"),
    [
        (lambda run: (run / "config.json").write_text("{not json"), "not valid JSON"),
        (lambda run: (run / "metrics.parquet").write_bytes(b"PAR1 cut short"), "cannot be read"),
        (
            lambda run: (shutil.rmtree(run / "checkpoints"), (run / "checkpoints").touch()),
            "is a file, not a folder of checkpoints",
        ),
    ],
    ids=["config", "metrics", "checkpoints"],
)
def test_an_unreadable_run_is_left_out_with_its_problem(
    campaign, tmp_path, capsys, damage, problem
):
    shutil.copytree(campaign / "main" / "curious-0", tmp_path / "good")
    shutil.copytree(campaign / "main" / "her-0", tmp_path / "bad")
    damage(tmp_path / "bad")
    assert curious_cli(["progress", str(tmp_path)]) == 0
    out, err = capsys.readouterr()
    assert "| good | curious |" in out and "| bad |" not in out
    assert f"left out {tmp_path / 'bad'}" in err and problem in err
    with pytest.raises(AnalysisError, match=problem):  # the library raises unless told otherwise
        progress_table(tmp_path)
    shutil.rmtree(tmp_path / "good")
    assert curious_cli(["progress", str(tmp_path)]) == 2
    assert "no run folder below" in capsys.readouterr().err


def test_a_copied_run_is_listed_once(campaign, tmp_path):
    shutil.copytree(campaign / "main" / "curious-0", tmp_path / "curious-0")
    rows = progress_table([tmp_path, tmp_path / "curious-0"])
    assert len(rows) == 1


def test_a_reproduction_lists_the_runs_its_budget_has_not_started(campaign, tmp_path):
    from curious.reproduction.experiments import get_budget

    out = tmp_path / "out"
    out.mkdir()
    (out / "reproduce.json").write_text(json.dumps({"version": 1, "budget": "smoke"}))
    assert [r.episodes for r in progress_table(out)] == [0] * len(get_budget("smoke").runs())
    shutil.copytree(campaign / "main" / "curious-0", out / "runs" / "main" / "curious" / "seed-0")
    rows = progress_table(out)
    assert len(rows) == len(get_budget("smoke").runs())
    started = [r for r in rows if r.episodes]
    assert [(r.condition, r.seed, r.episodes) for r in started] == [("curious", 0, 24)]
    assert all(r.commits == () and r.checkpoint is None for r in rows if not r.episodes)


def test_a_reproduction_with_its_runs_elsewhere_reads_them_there(campaign, tmp_path):
    """`curious reproduce --runs-dir` keeps the runs outside OUT; reproduce.json says where."""
    from curious.reproduction.experiments import get_budget

    out, runs = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    manifest = {"version": 1, "budget": "smoke", "runs_dir": str(runs)}
    (out / "reproduce.json").write_text(json.dumps(manifest))
    shutil.copytree(campaign / "main" / "curious-0", runs / "main" / "curious" / "seed-0")
    rows = progress_table(out)
    assert len(rows) == len(get_budget("smoke").runs())
    started = [r for r in rows if r.episodes]
    assert [(r.condition, r.seed, r.episodes) for r in started] == [("curious", 0, 24)]


def test_a_shipped_folder_stands_for_the_runs_a_reproduction_beside_it_has_not_started(
    campaign, tmp_path, capsys
):
    """Run folders gone (a new machine): main/curious/seed-0 is shipped, its folder is gone."""
    from curious.reproduction.shipping import ship

    out, held = tmp_path / "out", tmp_path / "held"
    out.mkdir()
    (out / "reproduce.json").write_text(json.dumps({"version": 1, "budget": "smoke"}))
    shutil.copytree(campaign / "main" / "her-0", out / "runs" / "main" / "her" / "seed-0")
    shutil.copytree(campaign / "main" / "curious-0", held / "main" / "curious" / "seed-0")
    data = tmp_path / "data"
    ship(held, data, budget="smoke")
    rows = progress_table([out, data])
    named = {r.name: r for r in rows}
    assert len(rows) == len(named) == len(get_budget("smoke").runs())
    shipped = named["main/curious/seed-0"]
    assert (shipped.episodes, shipped.shipped, shipped.checkpoint) == (24, True, None)
    assert named["main/her/seed-0"].checkpoint == 24 and not named["main/her/seed-0"].shipped
    assert [r.name for r in rows] == sorted(named)

    assert curious_cli(["progress", str(out), str(data)]) == 0
    text = capsys.readouterr().out
    assert "| main/curious/seed-0 | curious | default | 0 | 24 | 24 | 100% | shipped |" in text
    assert "| main/her/seed-0 | her | default | 0 | 24 | 24 | 100% | 24 |" in text


@pytest.mark.parametrize("shipped_episodes", [24, 12])
def test_a_run_both_shipped_and_in_the_reproduction_is_listed_once(
    campaign, tmp_path, capsys, shipped_episodes
):
    """A finished run shipped while its folder is still on the machine: one row, from the
    folder (its checkpoint), marked shipped only if the shipped copy holds all its episodes."""
    from curious.reproduction.shipping import ship

    out = tmp_path / "out"
    out.mkdir()
    (out / "reproduce.json").write_text(json.dumps({"version": 1, "budget": "smoke"}))
    shutil.copytree(campaign / "main" / "curious-0", out / "runs" / "main" / "curious" / "seed-0")
    data = tmp_path / "data"
    ship(out / "runs", data, budget="smoke")
    metrics = data / "main" / "curious" / "seed-0" / "metrics.parquet"
    pd.read_parquet(metrics).head(shipped_episodes).to_parquet(metrics)

    rows = progress_table([out, data])
    named = {r.name: r for r in rows}
    assert len(rows) == len(named) == len(get_budget("smoke").runs())
    row = named["main/curious/seed-0"]
    whole = shipped_episodes == 24
    assert (row.episodes, row.checkpoint, row.shipped) == (24, 24, whole)
    assert row.run.startswith(str(out.resolve()))

    assert curious_cli(["progress", str(out), str(data)]) == 0
    checkpoint = "24, shipped" if whole else "24"
    line = f"| main/curious/seed-0 | curious | default | 0 | 24 | 24 | 100% | {checkpoint} |"
    assert line in capsys.readouterr().out


@pytest.mark.parametrize("at_once", [1, 2])
def test_the_summary_sums_each_experiment_and_projects_the_hours_left(campaign, at_once):
    rows = progress_table(campaign)
    (main,) = experiment_progress(rows)
    assert (main.experiment, main.runs, main.finished) == ("main", 3, 2)
    assert (main.episodes, main.total_episodes, main.left) == (48, 72, 24)
    assert main.run_hours == pytest.approx(sum(r.run_hours for r in rows))
    pace = 48 / (3600 * main.run_hours)  # nothing is training: every run's pace
    assert current_pace(rows) == pytest.approx(pace)
    text = summary_markdown(rows, at_once)
    side = "one at a time" if at_once == 1 else "2 at a time"
    assert f"hours left at {pace:.1f} episodes/s per run, {side} |" in text
    hours = 24 / pace / at_once / 3600
    assert text.endswith(
        f"| main | 2 of 3 | 48 | 72 | 67% | {main.run_hours:.2f} | 24 | {hours:.1f} |\n"
    )


def test_the_pace_is_that_of_the_runs_training_now(campaign):
    """Finished runs that trained on a faster machine do not set the pace of the runs left."""
    done, *_ = progress_table(campaign)
    fast = replace(done, name="main/curious/seed-0", episodes=100, total_episodes=100, run_hours=1)
    slow = replace(done, name="main/her/seed-1", episodes=30, total_episodes=100, run_hours=1)
    new = replace(done, name="sensor_failure/curious/seed-0", episodes=0, run_hours=0.0)
    new = replace(new, total_episodes=50)
    rows = [fast, slow, new]
    assert current_pace(rows) == pytest.approx(30 / 3600)
    parts = {p.experiment: p for p in experiment_progress(rows)}
    assert (parts["main"].left, parts["sensor_failure"].left) == (70, 50)
    text = summary_markdown(rows, 2)
    assert "| main | 1 of 2 | 130 | 200 | 65% | 2.00 | 70 | 1.2 |" in text
    assert "| sensor_failure | 0 of 1 | 0 | 50 | 0% | 0.00 | 50 | 0.8 |" in text
    assert "| all | 1 of 3 | 130 | 250 | 52% | 2.00 | 120 | 2.0 |" in text
    assert current_pace([new]) is None and "| - |" in summary_markdown([new])


def test_the_hours_left_count_the_runs_the_reproduction_trains_at_once(campaign, tmp_path, capsys):
    """`curious progress` divides the hours left by the runs trained side by side: the count
    the reproduction's reproduce.json records (`at_once`, which `curious reproduce` writes), else
    the runs started and not finished; `--at-once N` overrides either."""
    out = tmp_path / "out"
    shutil.copytree(campaign / "main" / "curious-0", out / "runs" / "main" / "curious" / "seed-0")
    manifest = {"version": 1, "budget": "smoke", "at_once": 2}
    (out / "reproduce.json").write_text(json.dumps(manifest))
    assert recorded_at_once(out) == 2 and recorded_at_once(campaign) is None
    assert curious_cli(["progress", str(out)]) == 0
    assert "episodes/s per run, 2 at a time |" in capsys.readouterr().out
    assert curious_cli(["progress", str(out), "--at-once", "1"]) == 0
    assert "episodes/s per run, one at a time |" in capsys.readouterr().out

    rows = progress_table(campaign)  # no reproduce.json: the runs started and not finished
    assert runs_at_once(campaign, rows) == 1  # none training: one
    halfway = [replace(r, episodes=12) for r in rows]
    assert runs_at_once(campaign, halfway) == 3

    for damaged in (0, "2", True):
        (out / "reproduce.json").write_text(json.dumps({**manifest, "at_once": damaged}))
        assert curious_cli(["progress", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "reproduce.json is damaged: at_once" in err, err


def test_at_once_below_one_is_a_one_line_error(campaign, capsys):
    assert curious_cli(["progress", str(campaign), "--at-once", "0"]) == 2
    assert "--at-once must be at least 1" in capsys.readouterr().err


@pytest.fixture(scope="module")
def failing(tmp_path_factory):
    """A smoke run of the sensory-failure variant whose failure starts at episode 12 of 24."""
    out = tmp_path_factory.mktemp("failure") / "sensor_failure" / "curious-0"
    args = ["train", "--condition", "curious", "--seed", "0", "--preset", "smoke"]
    args += ["--variant", "sensor_failure", "--set", "sensor_failure_episode=12"]
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MUJOCO_GL", "disable")
        assert curious_cli([*args, "--out", str(out), "--no-progress"]) == 0
    return out


def test_a_run_with_a_sensory_failure_says_where_it_started(failing, campaign):
    metrics = pd.read_parquet(failing / "metrics.parquet")
    first = int(metrics.loc[metrics["sensor_failure"], "episode"].min())
    assert first == 12  # the fixture's sensor_failure_episode
    (row,) = progress_table(failing)
    assert row.failure == f"from episode {first:,}"
    assert "| sensory failure |" in progress_markdown([row])
    assert f"| from episode {first:,} |" in progress_markdown([row])
    # A table without such a run has no such column.
    assert all(r.failure is None for r in progress_table(campaign))
    assert "sensory failure" not in progress_markdown(progress_table(campaign))


@pytest.mark.parametrize(
    ("setting", "expected"),
    [
        ({"sensor_failure_episode": 50}, "not yet: starts at episode 50"),
        (
            {"sensor_failure_competence": 0.99},
            "not yet: starts when push_cube3's competence reaches 0.99 (now {now:.2f})",
        ),
    ],
)
def test_a_failure_not_started_says_what_it_waits_for(failing, tmp_path, setting, expected):
    run = tmp_path / "run"
    shutil.copytree(failing, run)
    config = json.loads((run / "config.json").read_text())
    config["config"].update({"sensor_failure_episode": -1, "sensor_failure_competence": -1.0})
    config["config"].update(setting)
    (run / "config.json").write_text(json.dumps(config))
    metrics = pd.read_parquet(run / "metrics.parquet")
    metrics["sensor_failure"] = False
    metrics.to_parquet(run / "metrics.parquet")
    (row,) = progress_table(run)
    assert row.failure == expected.format(now=metrics["competence/push_cube3"].iat[-1])


def test_a_laptop_folder_lists_the_study_on_a_mastered_module_as_not_started(tmp_path):
    """Before any of its runs trains, `curious progress` lists sensor_failure_mastered's six runs
    with the episodes each will train, none started."""
    (tmp_path / "reproduce.json").write_text(json.dumps({"version": 1, "budget": "laptop"}))
    rows = [r for r in progress_table(tmp_path) if r.name.startswith("sensor_failure_mastered/")]
    assert sorted(r.name for r in rows) == sorted(
        f"sensor_failure_mastered/{c}/seed-{s}" for c in ("curious", "m-uvfa") for s in (0, 1, 2)
    )
    assert all(r.episodes == 0 and r.total_episodes == 120_000 for r in rows)


def test_a_run_past_its_budget_owes_no_episodes_and_lends_none(campaign):
    """A run extended past its budget (or one whose config sets none) does not make another
    run's episodes left look fewer, nor the count negative."""
    done, *_ = progress_table(campaign)
    over = replace(done, name="main/curious/seed-0", episodes=150, total_episodes=100)
    short = replace(done, name="main/her/seed-0", episodes=40, total_episodes=100)
    unbudgeted = replace(done, name="main/mg-te/seed-0", episodes=20, total_episodes=0)
    (main,) = experiment_progress([over, short, unbudgeted])
    assert (main.finished, main.left) == (2, 60)


def test_update_names_a_folder_below_home_from_home_not_by_this_machines_path(
    campaign, tmp_path, monkeypatch
):
    """The block quotes the command a reader can type: a folder in the home folder as ``~/...``
    (a page is read on other machines), another as given."""
    monkeypatch.setenv("HOME", str(campaign.parent))
    doc = tmp_path / "results.md"
    doc.write_text(f"{BEGIN}\n{END}\n")
    assert curious_cli(["progress", str(campaign), "--update", str(doc)]) == 0
    assert f"Computed by `curious progress ~/{campaign.name}` at" in doc.read_text()
    monkeypatch.setenv("HOME", str(tmp_path / "elsewhere"))
    assert curious_cli(["progress", str(campaign), "--update", str(doc)]) == 0
    assert f"Computed by `curious progress {campaign}` at" in doc.read_text()
