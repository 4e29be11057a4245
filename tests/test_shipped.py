"""`curious ship` and `curious reproduce --from-data`, on the smoke reproduction.

The smoke output (`conftest.py`, shared with the pipeline and notebook tests) is shipped once
into a data folder; the report, the figures and the tables built from that folder alone must be
those built from the run folders.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest
from shipped_check import check_shipped_folder, files_of

from curious import analysis
from curious.cli import main as curious_cli
from curious.reproduction.experiments import get_budget
from curious.reproduction.shipping import clean_leftovers
from curious.runs.folder import RunFolder
from curious.runs.folder_layout import CONFIG_FILE, LEARNER_FILE, METRICS_FILE, TESTS_FILE
from curious.runs.shipped_folder import (
    LEARNER_DROPPED,
    METRICS_DROPPED,
    TESTS_DROPPED,
    ShippedFolder,
)
from pipelines.resources import OutputLayout

N_SMOKE = len(get_budget("smoke").runs())
"""Runs of a whole smoke reproduction (the shipped campaign of these tests)."""

EXPERIMENTS = ("main", "distractors", "sensor_failure", "sensor_failure_mastered")


def hashes(folder: Path) -> dict[str, str]:
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def cli(args: list[str]) -> tuple[int, str, str]:
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = curious_cli(args)
    return code, stdout.getvalue(), stderr.getvalue()


@pytest.fixture(scope="session")
def from_data(shipped, tmp_path_factory):
    """`curious reproduce --from-data` on the shipped smoke runs, and whether DATA was left as it
    was."""
    out = tmp_path_factory.mktemp("from_data") / "out"
    before = hashes(shipped.data)
    code, stdout, stderr = cli(
        ["reproduce", "--from-data", str(shipped.data), "--out", str(out), "--no-progress"]
    )
    assert code == 0, stderr[-3000:]
    return out, stdout, stderr, hashes(shipped.data) == before


def smoke_runs(smoke) -> list[Path]:
    return sorted(p.parent for p in (smoke.out / "runs").rglob(CONFIG_FILE))


# ------------------------------------------------------------------------------------ curious ship


def test_ship_writes_each_runs_description_and_reduced_tables_and_prints_their_size(smoke, shipped):
    data, sources = shipped.data, smoke_runs(smoke)
    relative = [p.relative_to(smoke.out / "runs").as_posix() for p in sources]
    manifest = ShippedFolder(data).read_manifest()
    assert manifest.budget == "smoke"
    assert [r.run for r in manifest.runs] == sorted(relative)
    assert all(r.finished and r.episodes == r.total_episodes == 24 for r in manifest.runs)
    shipped_tables = (CONFIG_FILE, METRICS_FILE, TESTS_FILE, LEARNER_FILE)
    expected = {"shipped.json"} | {f"{r}/{name}" for r in relative for name in shipped_tables}
    assert files_of(data) == expected  # no checkpoint, no recording
    reduced_tables = (
        (METRICS_FILE, METRICS_DROPPED),
        (TESTS_FILE, TESTS_DROPPED),
        (LEARNER_FILE, LEARNER_DROPPED),
    )
    for source, rel in zip(sources, relative, strict=True):
        target = data / rel
        assert (target / CONFIG_FILE).read_bytes() == (source / CONFIG_FILE).read_bytes()
        for name, dropped in reduced_tables:
            original, reduced = pq.read_table(source / name), pq.read_table(target / name)
            kept = [f for f in original.schema if f.name not in dropped]
            assert list(reduced.schema) == kept  # names, order and Arrow types
            pd.testing.assert_frame_equal(  # NaN where the run has NaN (her's competence)
                reduced.to_pandas(),
                original.select([f.name for f in kept]).to_pandas(),
                check_exact=True,
            )
            codecs = {
                meta.row_group(g).column(c).compression
                for meta in [pq.read_metadata(target / name)]
                for g in range(meta.num_row_groups)
                for c in range(meta.num_columns)
            }
            assert codecs == {"ZSTD"}

    size = sum(p.stat().st_size for p in data.rglob("*") if p.is_file())
    printed = re.search(r"([\d,]+) bytes\)", shipped.stdout)
    assert printed and int(printed.group(1).replace(",", "")) == size
    assert (
        f"shipped {N_SMOKE} finished run(s) of budget smoke from {smoke.out} to {data}"
        in shipped.stdout
    )
    tables = sum((p / name).stat().st_size for p in sources for name in shipped_tables)
    whole = sum(p.stat().st_size for p in (smoke.out / "runs").rglob("*") if p.is_file())
    assert size < tables and size < 0.01 * whole


def test_shipped_tables_load_with_every_number_of_the_run_folders(smoke, shipped):
    """`load_runs` / `load_tests` of the shipped folder: the run folders' rows, identity columns
    and kept columns, value for value and type for type; only the `run` path differs."""

    def relative(table: pd.DataFrame, root: Path) -> pd.DataFrame:
        table = table.copy()
        runs = table["run"].astype(str).map(lambda r: Path(r).relative_to(root.resolve()))
        table["run"] = runs.map(Path.as_posix).astype("category")
        return table

    for experiment in EXPERIMENTS:
        for load, dropped in (
            (analysis.load_runs, METRICS_DROPPED),
            (analysis.load_tests, TESTS_DROPPED),
        ):
            original = relative(load(smoke.out / "runs" / experiment), smoke.out / "runs")
            reduced = relative(load(shipped.data / experiment), shipped.data)
            gone = [c for c in original if c not in reduced]
            assert set(gone) == set(dropped)
            pd.testing.assert_frame_equal(reduced, original.drop(columns=gone))
    layout = OutputLayout.open(shipped.data)  # how the notebooks open their `out`
    assert layout.runs_root == shipped.data.resolve() and layout.budget_name() == "smoke"
    assert len(analysis.load_runs(shipped.data)) == N_SMOKE * 24


def test_shipping_again_replaces_the_folder_with_the_same_bytes(smoke, shipped, tmp_path):
    out = tmp_path / "data" / "smoke"
    assert cli(["ship", str(smoke.out), "--out", str(out)])[0] == 0
    (out / "main" / "stale.txt").write_text("from an earlier ship")
    code, _, stderr = cli(["ship", str(smoke.out), "--out", str(out)])
    assert code == 0, stderr
    assert hashes(out) == hashes(shipped.data)  # deterministic: an unchanged run, an unchanged file
    assert sorted(p.name for p in out.parent.iterdir()) == ["smoke"]  # nothing left beside it


def dead_pid() -> int:
    """The id of a process that has ended."""
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], text=True,
                          capture_output=True, check=True)  # fmt: skip
    return int(done.stdout)


def test_a_ship_cleans_what_a_killed_ship_left_beside_its_out(smoke, shipped, tmp_path):
    """A ship killed while staging leaves `.<out>.shipping-PID`; killed while replacing, it
    leaves `.<out>.old-PID` (with `out`, or in its place). The next ship removes them, puts an
    earlier ship back where it had been set aside with no `out`, and leaves a running ship's."""
    data = tmp_path / "data"
    out, pid = data / "smoke", dead_pid()
    shutil.copytree(shipped.data, data / f".smoke.old-{pid}")  # killed between the two renames
    (data / f".smoke.shipping-{pid}" / "main").mkdir(parents=True)
    (data / f".smoke.shipping-{os.getpid()}").mkdir()  # alive: this process's
    (data / f".other.old-{pid}").mkdir()  # another out's
    clean_leftovers(out)
    assert hashes(out) == hashes(shipped.data)  # put back
    names = sorted(p.name for p in data.iterdir())
    assert names == [f".other.old-{pid}", f".smoke.shipping-{os.getpid()}", "smoke"]
    (data / f".smoke.shipping-{os.getpid()}").rmdir()
    (data / f".smoke.old-{pid}" / "main").mkdir(parents=True)  # killed before its last rmtree
    (data / f".smoke.shipping-{pid}").mkdir()
    code, _, stderr = cli(["ship", str(smoke.out), "--out", str(out)])
    assert code == 0, stderr
    assert sorted(p.name for p in data.iterdir()) == [f".other.old-{pid}", "smoke"]
    assert hashes(out) == hashes(shipped.data)


def _signal_at(signum: int, target, when, after: bool = False):
    """`target` (a function or method), sending this process `signum` just before it runs (or
    just `after`) where `when(path)` holds for its first argument: a Ctrl-C (or a kill) that
    comes at that very step."""

    def wrapped(path, *args, **kwargs):
        due = when(Path(path))
        if due and not after:
            signal.raise_signal(signum)
        result = target(path, *args, **kwargs)
        if due and after:
            signal.raise_signal(signum)
        return result

    return wrapped


@pytest.mark.parametrize(
    ("step", "signum"),
    [
        ("set the earlier ship aside", signal.SIGINT),
        ("remove the earlier ship", signal.SIGINT),
        ("remove the staging folder", signal.SIGINT),  # a second Ctrl-C, after a first one
        ("remove the earlier ship", signal.SIGTERM),
    ],
    ids=["ctrl-c-setting-aside", "ctrl-c-removing-earlier", "ctrl-c-removing-staging", "kill"],
)
def test_a_ship_stopped_at_any_step_leaves_nothing_beside_its_out(
    smoke, shipped, tmp_path, monkeypatch, step, signum
):
    """Ctrl-C while a ship swapped its output in left `.<out>.old-PID` holding part of the
    earlier ship: now a ship stopped at any step (Ctrl-C: one line, exit status 130; SIGTERM:
    status 143) leaves nothing beside `out`, which holds the earlier ship or the new one whole."""
    import curious.reproduction.shipping as shipping

    data = tmp_path / "data"
    out = data / "smoke"
    shutil.copytree(shipped.data, out)
    (out / "main" / "stale.txt").write_text("from an earlier ship")
    earlier = hashes(out)
    if step == "set the earlier ship aside":  # between the two renames of the swap
        rename = _signal_at(signum, Path.rename, lambda p: p == out.resolve(), after=True)
        monkeypatch.setattr(Path, "rename", rename)
    else:
        prefix = ".smoke.old-" if step == "remove the earlier ship" else ".smoke.shipping-"
        if step == "remove the staging folder":  # the first Ctrl-C, while the ship is checked

            def first_ctrl_c(*args):
                raise KeyboardInterrupt

            monkeypatch.setattr(shipping, "_verify", first_ctrl_c)

        def there(path: Path) -> bool:  # not the removal of a stale one before it is made
            return path.name.startswith(prefix) and path.exists()

        rmtree = _signal_at(signum, shutil.rmtree, there)
        monkeypatch.setattr(shipping.shutil, "rmtree", rmtree)
    if signum == signal.SIGINT:
        # Python's own Ctrl-C handler, as in a terminal (a pytest-xdist worker ignores SIGINT)
        previous = signal.signal(signal.SIGINT, signal.default_int_handler)
        try:
            code, _, stderr = cli(["ship", str(smoke.out), "--out", str(out)])
        finally:
            signal.signal(signal.SIGINT, previous)
        assert code == 130 and stderr == "curious ship: interrupted\n", stderr
    else:
        with pytest.raises(SystemExit) as stopped:
            cli(["ship", str(smoke.out), "--out", str(out)])
        assert stopped.value.code == 128 + signum
    monkeypatch.undo()
    assert sorted(p.name for p in data.iterdir()) == ["smoke"]
    assert hashes(out) in (earlier, hashes(shipped.data))


def test_the_default_out_of_a_reproduction_is_data_and_its_budget(smoke, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, stdout, _ = cli(["ship", str(smoke.out)])
    assert code == 0 and "to data/smoke" in stdout
    assert ShippedFolder(tmp_path / "data" / "smoke").read_manifest().budget == "smoke"


# ---------------------------------------------------------------------- reproduce --from-data


def test_the_dagster_line_a_reproduction_ends_with_serves_this_machine_only(smoke, from_data):
    """The closing line that starts the Dagster UI on a reproduction's output, trained or read
    from shipped data, binds it to the loopback address: nobody else who can reach the machine
    browses the runs."""
    for stdout in (smoke.stdout, from_data[1]):
        (line,) = [text for text in stdout.splitlines() if text.strip().startswith("Dagster:")]
        words = shlex.split(line.split(":", 1)[1])
        server = words[words.index("dagster-webserver") + 1 :]
        assert "-h" in server and server[server.index("-h") + 1] == "127.0.0.1", line


def test_report_and_figures_from_the_shipped_data_are_those_of_the_run_folders(
    smoke, shipped, from_data
):
    """Built from the shipped tables alone, through the same Dagster assets: the same report.md
    (every table, every Welch test, byte for byte), the same figures and the same combined
    tables (less the columns shipping leaves out); nothing trained, DATA untouched."""
    out, stdout, stderr, untouched = from_data
    assert untouched
    assert (out / "report.md").read_bytes() == (smoke.out / "report.md").read_bytes()
    figures = sorted(p.name for p in (smoke.out / "figures").iterdir())
    assert sorted(p.name for p in (out / "figures").iterdir()) == figures
    for name in figures:
        assert (out / "figures" / name).read_bytes() == (smoke.out / "figures" / name).read_bytes()
    for experiment in EXPERIMENTS:
        for suffix, dropped in ((".parquet", METRICS_DROPPED), (".tests.parquet", TESTS_DROPPED)):
            ours = pd.read_parquet(out / "metrics" / f"{experiment}{suffix}")
            theirs = pd.read_parquet(smoke.out / "metrics" / f"{experiment}{suffix}")
            for table, root in ((ours, shipped.data), (theirs, smoke.out / "runs")):
                table["run"] = table["run"].astype(str).str.removeprefix(str(root.resolve()))
            pd.testing.assert_frame_equal(ours, theirs.drop(columns=list(dropped)))
    assert "Done in" in stdout and f"{N_SMOKE} shipped run(s) read, none trained" in stdout
    assert "curious reproduce --budget smoke --from-data" in stderr
    assert not (out / "runs").exists()
    manifest = json.loads((out / "reproduce.json").read_text())
    assert manifest["from_data"] == manifest["runs_dir"] == str(shipped.data.resolve())
    assert OutputLayout.open(out).runs_root == shipped.data.resolve()  # notebooks on `out` too


def test_shipped_runs_of_some_variants_rebuild_those_variants_figures_and_numbers(smoke, tmp_path):
    """A campaign that trained the distractors for 7 distracting modules alone (as the `laptop`
    campaign does): `--from-data` builds the distractors' figure and report from those runs, with
    the numbers the whole smoke reproduction has for 7, and names the variants left out."""
    root = tmp_path / "out"
    for source in smoke_runs(smoke):
        rel = source.relative_to(smoke.out / "runs")
        if rel.parts[0] == "main" or rel.parts[1].endswith("@distractors_7"):
            shutil.copytree(source, root / "runs" / rel, ignore=shutil.ignore_patterns("*.rrd"))
    shutil.copy(smoke.out / "reproduce.json", root)
    data, out = tmp_path / "data", tmp_path / "report"
    assert cli(["ship", str(root), "--out", str(data)])[0] == 0
    code, _, err = cli(["reproduce", "--from-data", str(data), "--out", str(out), "--no-progress"])
    assert code == 0, err[-3000:]
    report = (out / "report.md").read_text()
    assert "Variants left out: distractors_0, distractors_4, whose runs" in report
    assert (
        "Not in this report (not shipped yet): sensor_failure, sensor_failure_mastered, long, "
        "lp_uses, signed_lp, whose runs the data this report was built from does not hold all "
        "finished; `curious reproduce --budget smoke --experiments "
        "sensor_failure,sensor_failure_mastered,long,lp_uses,signed_lp` trains them." in report
    )
    assert "shipped, left out by" not in report  # main is read: nothing shipped goes unread
    row = next(line for line in report.splitlines() if line.startswith("| 7 |"))
    assert row in (smoke.out / "report.md").read_text().splitlines()
    asked = tmp_path / "asked"
    code, _, err = cli(
        ["reproduce", "--from-data", str(data), "--out", str(asked), "--experiments",
         "distractors", "--no-progress"]
    )  # fmt: skip
    assert code == 0, err[-3000:]
    asked_report = (asked / "report.md").read_text()
    assert (
        "Not in this report (shipped, left out by `--experiments`): main; the same command with "
        "them in `--experiments`, or without it, reads them." in asked_report
    )
    assert "Not in this report (not shipped yet): sensor_failure, sensor_failure_mastered, " in (
        asked_report
    )
    assert not any(line.startswith(("| 0 |", "| 4 |")) for line in report.splitlines())
    assert (out / "figures" / "distractors.png").is_file()
    metrics = pd.read_parquet(out / "metrics" / "distractors.parquet")
    assert set(metrics["variant"].astype(str)) == {"distractors_7"}


def test_runs_of_a_left_out_variant_with_every_condition_are_shown_untested(shipped, tmp_path):
    """`ShippedData.left_out_runs`: of the variants an experiment leaves out (too few seeds
    shipped), the finished runs of those that have every condition, for the figure and the
    table; a variant missing a condition gives none."""
    from dataclasses import replace

    from curious.reproduction.experiments import get_budget
    from pipelines.from_data import ShippedData

    data = tmp_path / "smoke"
    shutil.copytree(shipped.data, data)
    shutil.rmtree(data / "distractors" / "m-uvfa@distractors_0")
    folder = ShippedFolder(data)
    manifest = folder.read_manifest()
    runs = tuple(r for r in manifest.runs if "m-uvfa@distractors_0" not in r.run)
    folder.write_manifest(type(manifest)("smoke", runs))
    two_seeds = replace(get_budget("smoke").experiments["distractors"], seeds=(0, 1))
    experiment = two_seeds.with_variants(["distractors_7"])
    shown = ShippedData.open(data).left_out_runs(experiment)
    assert [s.relative_path.as_posix() for s in shown] == [
        "distractors/curious@distractors_4/seed-0",
        "distractors/m-uvfa@distractors_4/seed-0",
    ]
    assert ShippedData.open(data).left_out_runs(two_seeds) == []  # nothing left out


def test_a_seed_beyond_the_budgets_is_read_with_its_seeds_once_all_its_runs_are_shipped(
    extra_seed, tmp_path
):
    """Main's seed 2, beyond the smoke budget's 0 and 1, shipped by a campaign
    (`tools/campaign.py --seeds main=2`): `--from-data` reads main with its three seeds and the
    report says which seed is beyond the budget's; the repository's data check passes. Shipped
    for two of its three conditions, the seed is left out until the third is shipped."""
    from curious.reproduction.experiments import get_budget
    from pipelines.from_data import ShippedData

    report = check_shipped_folder(extra_seed.data, tmp_path / "out")
    assert "| main | curious, mg-te, her | default | 0, 1, 2 (3; 2 beyond the budget's) |" in report
    assert "Seeds beyond the budget's: 2 (the budget trains 0, 1)" in report
    assert "| main/her/seed-2 | her | default | 2 | 24 |" in report
    assert report.count("beyond the budget's") == 2  # main only: the others are the budget's
    metrics = pd.read_parquet(tmp_path / "out" / "metrics" / "main.parquet")
    assert sorted(metrics["seed"].unique()) == [0, 1, 2]
    assert metrics.groupby("seed", observed=True)["condition"].nunique().tolist() == [3, 3, 3]

    data = tmp_path / "data" / "smoke"
    shutil.copytree(extra_seed.data, data)
    shutil.rmtree(data / "main" / "her" / "seed-2")
    folder = ShippedFolder(data)
    manifest = folder.read_manifest()
    runs = tuple(r for r in manifest.runs if r.run != "main/her/seed-2")
    folder.write_manifest(type(manifest)("smoke", runs))
    main = ShippedData.open(data).stands_for(get_budget("smoke")).experiments["main"]
    assert main.seeds == (0, 1) and not main.extra_seeds and not main.left_out_seeds
    assert {s.seed for s in main.runs()} == {0, 1}
    # the report names the runs it holds back
    waiting = ["main/curious/seed-2", "main/mg-te/seed-2"]
    assert ShippedData.open(data).waiting_runs(main) == waiting
    report = check_shipped_folder(data, tmp_path / "out-waiting")
    assert ShippedData.open(data).awaited_runs(main) == ["main/her/seed-2 (not shipped)"]
    assert f"Shipped, not read yet: {', '.join(waiting)}, of a seed beyond" in report
    assert "shipped finished; still to ship: main/her/seed-2 (not shipped)." in report
    assert "beyond the budget's)" not in report  # nor does any table count seed 2


def test_an_experiment_shipped_whole_for_some_seeds_is_read_from_those(extra_seed, tmp_path):
    """A campaign part-way through an experiment: main's seed 1 lacks its HER run, so main is
    read from seed 0 and seed 2 (beyond the budget's, shipped whole), and the report names
    seed 1 as left out; once no seed is whole, main is not built at all."""
    from curious.reproduction.experiments import get_budget
    from pipelines.from_data import ShippedData

    data = tmp_path / "data" / "smoke"
    shutil.copytree(extra_seed.data, data)
    folder = ShippedFolder(data)

    def drop(run: str) -> None:
        shutil.rmtree(data / run)
        manifest = folder.read_manifest()
        folder.write_manifest(
            type(manifest)("smoke", tuple(r for r in manifest.runs if r.run != run))
        )

    drop("main/her/seed-1")
    report = check_shipped_folder(data, tmp_path / "out")
    assert "| main | curious, mg-te, her | default | 0, 2 (2; 2 beyond the budget's) |" in report
    assert (
        "Seeds left out: 1, whose runs the data this report was built from does not hold all "
        "finished; read from seeds 0, 2 alone." in report
    )
    assert "Seeds beyond the budget's: 2 (the budget trains 0, 1)" in report
    assert "main/curious/seed-1" not in report and report.count("Seeds left out") == 1
    metrics = pd.read_parquet(tmp_path / "out" / "metrics" / "main.parquet")
    assert sorted(metrics["seed"].unique()) == [0, 2]

    drop("main/her/seed-2")
    drop("main/mg-te/seed-0")
    stands_for = ShippedData.open(data).stands_for(get_budget("smoke"))
    main = stands_for.experiments["main"]
    assert main.seeds == (0, 1) and not main.left_out_seeds and not main.extra_seeds
    assert "main" not in [e.name for e in ShippedData.open(data).select(stands_for, None)]
    args = ["reproduce", "--from-data", str(data), "--experiments", "main"]
    code, _, err = cli([*args, "--out", str(tmp_path / "none")])
    assert code == 2 and not (tmp_path / "none").exists()
    assert "lacks runs of main: main/mg-te/seed-0 (not shipped)" in err


def test_the_shipped_smoke_folder_passes_the_repository_data_check(shipped, from_data):
    """The check test_shipped_data.py applies to data/, on a folder known to be good (its
    report: the `--from-data` build of the fixture)."""
    report = check_shipped_folder(shipped.data, from_data[0], built=True)
    assert "| main/curious/seed-0 | curious | default | 0 | 24 |" in report


def test_an_output_folder_holds_trained_or_shipped_results_never_both(smoke, from_data, tmp_path):
    out = from_data[0]
    code, _, err = cli(["reproduce", "--budget", "smoke", "--out", str(out), "--no-progress"])
    assert code == 2 and err.count("\n") == 1
    assert "made from the shipped data in" in err and "not by training" in err
    data = tmp_path / "data"
    assert cli(["ship", str(smoke.out), "--out", str(data)])[0] == 0
    before = hashes(smoke.out)
    code, _, err = cli(["reproduce", "--from-data", str(data), "--out", str(smoke.out)])
    assert code == 2 and err.count("\n") == 1 and "made by training, not from" in err
    assert hashes(smoke.out) == before


# ---------------------------------------------------------------------- unfinished runs


def partial_copy(smoke, out: Path, experiment: str = "main") -> Path:
    """A smoke output in `out` with the runs of `experiment` only (no recordings), and
    <experiment>/curious/seed-0 cut to its first 12 episodes: a run still training."""
    for source in smoke_runs(smoke):
        rel = source.relative_to(smoke.out / "runs")
        if rel.parts[0] == experiment:
            shutil.copytree(source, out / "runs" / rel, ignore=shutil.ignore_patterns("*.rrd"))
    shutil.copy(smoke.out / "reproduce.json", out)
    folder = RunFolder(out / "runs" / experiment / "curious" / "seed-0")
    table = pq.read_table(folder.metrics_path)
    pq.write_table(table.slice(0, 12), folder.metrics_path)
    return folder.path


def test_unfinished_runs_are_shipped_only_when_asked_and_marked(smoke, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    root = tmp_path / "out"
    partial_copy(smoke, root)
    code, stdout, _ = cli(["ship", str(root), "--out", str(tmp_path / "finished")])
    assert code == 0
    left = "left out (--unfinished ships those that have started): main/curious/seed-0 (12 of 24 "
    assert f"{left}episodes)" in stdout
    runs = ShippedFolder(tmp_path / "finished").read_manifest().runs
    assert len(runs) == 5 and "main/curious/seed-0" not in [r.run for r in runs]

    snapshot = tmp_path / "snapshot"
    code, stdout, _ = cli(["ship", str(root), "--out", str(snapshot), "--unfinished"])
    assert code == 0 and "5 finished run(s) and 1 unfinished" in stdout
    entry = ShippedFolder(snapshot).read_manifest().get("main/curious/seed-0")
    assert entry is not None and not entry.finished and entry.episodes == 12
    assert len(analysis.load_runs(snapshot / "main" / "curious" / "seed-0")) == 12

    # seed 1 is shipped whole: main is read from it, seed 0 named as left out
    code, _, err = cli(["reproduce", "--from-data", str(snapshot), "--out", "seed-1"])
    assert code == 0, err
    report = (tmp_path / "seed-1" / "report.md").read_text()
    assert "Seeds left out: 0, whose runs the data this report was built from" in report
    assert "| main | curious, mg-te, her | default | 1 |" in report

    # no seed whole: refused, naming the unfinished runs
    folder = RunFolder(root / "runs" / "main" / "her" / "seed-1")
    pq.write_table(pq.read_table(folder.metrics_path).slice(0, 12), folder.metrics_path)
    code, stdout, _ = cli(["ship", str(root), "--out", str(snapshot), "--unfinished"])
    assert code == 0 and "4 finished run(s) and 2 unfinished" in stdout
    for extra in (["--experiments", "main"], []):
        code, _, err = cli(["reproduce", "--from-data", str(snapshot), *extra])
        assert code == 2 and err.count("\n") == 1, err
        assert "main/curious/seed-0 (shipped unfinished: 12 of 24 episodes)" in err
    assert not (tmp_path / "runs").exists()


def test_a_run_whose_metrics_are_damaged_is_named_so_not_as_not_started(smoke, tmp_path):
    root = tmp_path / "out"
    folder = RunFolder(partial_copy(smoke, root))
    folder.metrics_path.write_bytes(b"PAR1 cut short")
    code, stdout, _ = cli(["ship", str(root), "--out", str(tmp_path / "data"), "--unfinished"])
    assert code == 0 and "main/curious/seed-0 (its metrics.parquet is damaged)" in stdout
    # no run is unfinished, so --unfinished is not offered: it would ship no more
    code, stdout, _ = cli(["ship", str(root), "--out", str(tmp_path / "more")])
    assert code == 0 and "left out: main/curious/seed-0 (its metrics.parquet is damaged)" in stdout


def test_a_finished_run_without_its_test_rollouts_is_left_out_and_named(smoke, tmp_path):
    """A finished run whose settings ran test rollouts but whose tests.parquet is gone (deleted,
    not copied) was shipped as a run of 0 test rollouts; it is left out and named, the others
    shipped."""
    root = tmp_path / "out"
    partial_copy(smoke, root)
    RunFolder(root / "runs" / "main" / "her" / "seed-1").tests_path.unlink()
    code, stdout, err = cli(["ship", str(root), "--out", str(tmp_path / "data")])
    assert code == 0, err
    assert "main/her/seed-1 (its tests.parquet is missing, though the run tested" in stdout
    shipped = {r.run for r in ShippedFolder(tmp_path / "data").read_manifest().runs}
    assert "main/her/seed-1" not in shipped and "main/her/seed-0" in shipped


def test_a_run_with_a_damaged_file_is_left_out_and_named_the_others_shipped(smoke, tmp_path):
    """One run of many with a damaged tests.parquet, learner.parquet or config.json stopped the
    whole ship (in pyarrow's words for the first); a damaged metrics.parquet was already left out
    so."""
    root = tmp_path / "out"
    partial_copy(smoke, root)
    runs = root / "runs" / "main"
    RunFolder(runs / "mg-te" / "seed-0").tests_path.write_bytes(b"PAR1 cut short")
    RunFolder(runs / "her" / "seed-0").config_path.write_text("")
    RunFolder(runs / "mg-te" / "seed-1").learner_path.write_bytes(b"PAR1 cut short")
    code, stdout, err = cli(["ship", str(root), "--out", str(tmp_path / "data")])
    assert code == 0, err
    assert "main/mg-te/seed-0 (its tests.parquet is damaged)" in stdout
    assert "main/her/seed-0 (" in stdout and "config.json is damaged: it is empty" in stdout
    assert "main/mg-te/seed-1 (its learner.parquet is damaged)" in stdout
    shipped = {r.run for r in ShippedFolder(tmp_path / "data").read_manifest().runs}
    assert not shipped & {"main/mg-te/seed-0", "main/her/seed-0", "main/mg-te/seed-1"}
    assert "main/curious/seed-1" in shipped


def test_keep_adds_to_an_earlier_ship_whose_run_folders_are_gone(smoke, shipped, tmp_path):
    """Run folders gone (a new machine): the data folder holds every smoke run shipped; the new runs
    root holds only main's, one of them still training. `--keep` ships main's finished runs again
    (the same bytes), keeps every other run, and keeps the finished copy of the unfinished run."""
    out = tmp_path / "data" / "smoke"
    shutil.copytree(shipped.data, out)
    root = tmp_path / "out"
    partial_copy(smoke, root)
    code, stdout, stderr = cli(["ship", str(root), "--out", str(out), "--keep", "--unfinished"])
    assert code == 0, stderr
    assert "shipped 5 finished run(s) of budget smoke" in stdout
    assert "kept from the earlier ship: distractors/" in stdout
    assert f"main/curious/seed-0 (unfinished here, shipped finished in {out} already)" in stdout
    assert hashes(out) == hashes(shipped.data)

    code, stdout, _ = cli(["ship", str(root), "--out", str(out)])  # without --keep: replaced
    assert code == 0 and "kept" not in stdout
    runs = [r.run for r in ShippedFolder(out).read_manifest().runs]
    assert len(runs) == 5 and all(r.startswith("main/") for r in runs)


# ------------------------------------------------------------------------------------ refusals


def refusal(tmp_path: Path, smoke, case: str) -> tuple[list[str], str]:
    """The command line of one refused call, and what its one line says."""
    runs = smoke.out / "runs" / "main"
    if case == "missing root":
        return ["ship", str(tmp_path / "nowhere"), "--out", str(tmp_path / "d")], "does not exist"
    if case == "empty root":
        (tmp_path / "empty").mkdir()
        return ["ship", str(tmp_path / "empty"), "--out", str(tmp_path / "d")], "holds no run"
    if case == "nothing finished":
        partial_copy(smoke, tmp_path / "out", "sensor_failure")
        shutil.rmtree(tmp_path / "out" / "runs" / "sensor_failure" / "m-uvfa")
        return ["ship", str(tmp_path / "out"), "--out", str(tmp_path / "d")], (
            "is finished (sensor_failure/curious/seed-0 (12 of 24 episodes)); pass --unfinished"
        )
    if case == "out inside a run folder":
        other = tmp_path / "other"
        other.mkdir()
        shutil.copy(runs / "curious" / "seed-0" / CONFIG_FILE, other)
        return ["ship", str(runs), "--out", str(other / "d")], "lies inside the run folder"
    if case == "out inside the runs":
        return ["ship", str(runs), "--out", str(runs / "d")], "overlap"
    if case == "out holds other files":
        (tmp_path / "d").mkdir()
        (tmp_path / "d" / "notes.txt").write_text("mine")
        return ["ship", str(runs), "--out", str(tmp_path / "d")], "holds no shipped data folder"
    if case == "out holds another budget":
        assert cli(["ship", str(runs), "--out", str(tmp_path / "d")])[0] == 0  # budget: none
        return ["ship", str(smoke.out), "--out", str(tmp_path / "d")], (
            "holds runs of no reproduction, these are the smoke budget's runs: shipping there"
        )
    if case == "out is a file":
        (tmp_path / "d").write_text("")
        return ["ship", str(runs), "--out", str(tmp_path / "d")], "is not a folder"
    if case == "root is shipped":
        data = tmp_path / "data"
        assert cli(["ship", str(runs), "--out", str(data)])[0] == 0
        return ["ship", str(data), "--out", str(tmp_path / "d")], "is a shipped data folder"
    if case == "no out for runs":
        return ["ship", str(runs)], "is not a `curious reproduce` output: pass --out"
    if case == "not shipped data":
        return ["reproduce", "--from-data", str(runs)], "is not a shipped data folder"
    data = tmp_path / "data"
    assert cli(["ship", str(smoke.out), "--out", str(data)])[0] == 0
    if case == "another budget":
        return ["reproduce", "--budget", "quick", "--from-data", str(data)], (
            "not 'quick': pass --budget smoke"
        )
    if case == "a run not shipped":
        shutil.rmtree(data / "main" / "her")
        shipped = ShippedFolder(data)
        manifest = shipped.read_manifest()
        kept = tuple(r for r in manifest.runs if not r.run.startswith("main/her/"))
        shipped.write_manifest(type(manifest)("smoke", kept))
        return ["reproduce", "--experiments", "main", "--from-data", str(data)], (
            "lacks runs of main: main/her/seed-0 (not shipped), main/her/seed-1 (not shipped)"
        )
    assert case == "a training option"
    return ["reproduce", "--from-data", str(data), "--workers", "2"], (
        "--from-data trains nothing, so --workers would do nothing"
    )


@pytest.mark.parametrize(
    "case",
    [
        "missing root",
        "empty root",
        "nothing finished",
        "out inside a run folder",
        "out inside the runs",
        "out holds other files",
        "out holds another budget",
        "out is a file",
        "root is shipped",
        "no out for runs",
        "not shipped data",
        "another budget",
        "a run not shipped",
        "a training option",
    ],
)
def test_a_refused_call_says_why_in_one_line_and_writes_nothing(smoke, tmp_path, case, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "case").mkdir()
    args, why = refusal(tmp_path / "case", smoke, case)
    before_smoke, before = hashes(smoke.out), files_of(tmp_path)
    code, _, err = cli(args)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"curious {args[0]}: error: ") and why in err, err
    assert files_of(tmp_path) == before and hashes(smoke.out) == before_smoke


def test_a_table_shipped_in_a_format_this_curious_does_not_read_is_named(shipped, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(shipped.data / "main" / "curious" / "seed-0", run)
    table = pq.read_table(run / METRICS_FILE)
    mark = {b"curious.shipped": json.dumps({"format": 99, "dropped": ["g0"]}).encode()}
    pq.write_table(table.replace_schema_metadata(mark), run / METRICS_FILE)
    with pytest.raises(
        analysis.AnalysisError, match=r"metrics.parquet: it was shipped in format 99"
    ):
        analysis.load_runs(run)


def test_dagster_definitions_read_shipped_data_from_the_environment(shipped, tmp_path, monkeypatch):
    """`CURIOUS_FROM_DATA` (what `curious reproduce --from-data` prints for the Dagster UI): the
    runs asset reads DATA, which is the runs root, and nothing is written by loading them."""
    from pipelines.definitions import reproduction_from_environment
    from pipelines.from_data import ShippedDataError
    from pipelines.training import FINISHED

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("CURIOUS_BUDGET", "smoke")
    monkeypatch.setenv("CURIOUS_FROM_DATA", str(shipped.data))
    monkeypatch.delenv("CURIOUS_OUT", raising=False)
    repro = reproduction_from_environment()
    assert repro.data is not None and repro.data.path == shipped.data.resolve()
    assert repro.layout.runs_root == shipped.data.resolve()
    assert repro.layout.out == (tmp_path / "runs" / "smoke-shipped").resolve()
    spec = repro.budget.experiments["main"].runs()[0]
    assert repro.run_state(spec) == FINISHED
    assert not any(tmp_path.iterdir())
    monkeypatch.setenv("CURIOUS_BUDGET", "quick")
    with pytest.raises(ShippedDataError, match="holds runs of budget 'smoke', not 'quick'"):
        reproduction_from_environment()


def _table() -> pd.DataFrame:
    return pd.DataFrame(
        {
            "module": pd.Categorical(["reach", "stack", None, "reach"]),
            "episode": [0, 1, 2, 3],
            "competence": [0.0, 0.5, 0.25, 1.0],
        }
    )


@pytest.mark.parametrize(
    ("change", "same"),
    [
        (lambda t: t[["competence", "episode", "module"]], True),
        (lambda t: t.assign(module=t["module"].cat.reorder_categories(["stack", "reach"])), True),
        (lambda t: t.assign(module=pd.Categorical(["reach", "reach", None, "reach"])), False),
        (lambda t: t.assign(module=pd.Categorical(["reach", "stack", "reach", "reach"])), False),
        (lambda t: t.assign(competence=[0.0, 0.5, 0.25, 0.9]), False),
        (lambda t: t.drop(columns="episode"), False),
        (lambda t: t.iloc[:3], False),
    ],
    ids=[
        "column order",
        "category order",
        "a value",
        "a missing value",
        "a number",
        "a column",
        "a row",
    ],
)
def test_the_shipped_tables_comparison_sees_every_difference(change, same):
    """`assert_same_table`: the check of a shipped folder's combined tables, by category codes."""
    from shipped_check import assert_same_table

    if same:
        assert_same_table(_table(), change(_table()))
    else:
        with pytest.raises(AssertionError):
            assert_same_table(_table(), change(_table()))


def test_shipping_an_output_built_from_shipped_data_is_refused_naming_the_data(
    shipped, from_data, tmp_path
):
    """`curious ship` of a `reproduce --from-data` output read "none of the runs ... is finished
    (... no checkpoint at the end)", and with --unfinished failed on the shipped tables'
    missing columns: its runs are the data folder's, shipped already."""
    out, *_ = from_data
    code, _, err = cli(["ship", str(out), "--out", str(tmp_path / "again"), "--unfinished"])
    assert code == 2 and err.count("\n") == 1, err
    assert f"was built from the shipped data folder {shipped.data.resolve()}" in err
    assert not (tmp_path / "again").exists()


@pytest.mark.parametrize(
    ("damage", "problem"),
    [
        ("metrics", "its metrics.parquet cannot be read ("),
        ("config", "config.json is damaged: it is empty"),
        ("folder", "its folder is gone"),
    ],
)
def test_damaged_shipped_data_is_named_before_anything_is_written(
    shipped, tmp_path, damage, problem
):
    """A shipped run cut short, emptied or gone failed later in pyarrow's words, or as "does not
    exist: name a run folder", and left reproduce.json behind."""
    data = tmp_path / "data"
    shutil.copytree(shipped.data, data)
    run = ShippedFolder(data).run_path("main/curious/seed-0")
    if damage == "metrics":
        (run / METRICS_FILE).write_bytes(b"PAR1 cut short")
    elif damage == "config":
        (run / CONFIG_FILE).write_text("")
    else:
        shutil.rmtree(run)
    out = tmp_path / "out"
    code, _, err = cli(["reproduce", "--from-data", str(data), "--out", str(out), "--no-progress"])
    assert code == 2 and err.count("\n") == 1, err
    assert f"--from-data {data} is damaged: main/curious/seed-0, which shipped.json lists: " in err
    assert problem in err and "or ship it again" in err
    assert not out.exists()
