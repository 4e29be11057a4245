"""What every shipped data folder must satisfy, checked on the smoke reproduction shipped in the
tests (test_shipped.py) and on whatever the repository ships in data/ (test_shipped_data.py).

`check_shipped_folder(data, out)`: the manifest lists exactly what the folder holds; every run
loads with `curious.analysis` with the episodes and test rollouts the manifest says (a finished
run: its whole budget); and `curious reproduce --from-data` builds the report from it, the
combined tables behind the report being the shipped tables, and the report's per-run numbers
(episodes, final competence, final test success) those computed from them, with a section on
spontaneous forgetting in each experiment that nothing perturbs, saying "no drop" exactly where
`analysis.mastery_drops` finds none; the runs read are those the folder stands for
(`ShippedData.stands_for`: the variants shipped whole, else the seeds shipped whole, and the
seeds beyond the budget's whose runs are all shipped finished, which the report names). A
folder with no experiment of which some seed is shipped whole (a progress snapshot, or a
campaign shipped run by run as its runs finish) has no report: once its runs are loaded, the
check is skipped with that reason.
"""

from __future__ import annotations

import contextlib
import io
import math
from pathlib import Path

import pandas as pd
import pytest

from curious import analysis
from curious.agent.conditions import CONDITION_CLASSES
from curious.cli import main as curious_cli
from curious.reproduction.experiments import BEYOND_PAPER, get_budget
from curious.runs.folder_layout import CONFIG_FILE, LEARNER_FILE, METRICS_FILE, TESTS_FILE
from curious.runs.shipped_folder import MANIFEST_FILE, ShippedFolder
from pipelines.from_data import ShippedData, ShippedDataError
from pipelines.report.long_study import UNPERTURBED


def files_of(folder: Path) -> set[str]:
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}


def assert_same_table(a: pd.DataFrame, b: pd.DataFrame) -> None:
    """`a` and `b` hold the same columns (in any order) and the same rows. What
    `pd.testing.assert_frame_equal(check_categorical=False, check_like=True)` asserts, with the
    categorical columns compared by their codes over the union of both categories: pandas
    compares their values one by one in Python, minutes for a campaign's million rows."""
    assert sorted(a.columns) == sorted(b.columns), "the same columns"
    b = b[a.columns]
    categorical = [c for c in a.columns if isinstance(a[c].dtype, pd.CategoricalDtype)]
    for c in categorical:
        assert isinstance(b[c].dtype, pd.CategoricalDtype), f"{c}: categorical on both sides"
        union = a[c].cat.categories.union(b[c].cat.categories)
        codes = [t[c].cat.set_categories(union).cat.codes.to_numpy() for t in (a, b)]
        assert len(codes[0]) == len(codes[1]) and (codes[0] == codes[1]).all(), f"{c} differs"
    rest = [c for c in a.columns if c not in categorical]
    pd.testing.assert_frame_equal(a[rest], b[rest])


def _two(value: float) -> str:
    return "–" if pd.isna(value) else f"{value:.2f}"


def check_shipped_folder(data: Path, out: Path, built: bool = False) -> str:
    """Check the shipped folder `data` (see the module docstring), building its report in `out`
    (`built`: `out` already holds what `curious reproduce --from-data DATA --out OUT` wrote);
    returns the report's text."""
    shipped = ShippedFolder(data)
    manifest = shipped.read_manifest()
    assert manifest.runs, f"{data} ships no run"
    expected_files = {MANIFEST_FILE}
    for r in manifest.runs:
        expected_files |= {f"{r.run}/{CONFIG_FILE}", f"{r.run}/{METRICS_FILE}"}
        if r.test_rollouts:
            expected_files.add(f"{r.run}/{TESTS_FILE}")
        # runs trained before the table have none; the experiments beyond the paper read it
        if r.run.split("/")[0] in BEYOND_PAPER or analysis.has_learner(shipped.run_path(r.run)):
            expected_files.add(f"{r.run}/{LEARNER_FILE}")
            last = analysis.load_learner(shipped.run_path(r.run))["episode"].max()
            assert last == r.episodes if r.finished else last <= r.episodes, f"{r.run}'s cycles"
    assert files_of(data) == expected_files, "the folder holds what shipped.json lists, only"

    for r in manifest.runs:
        runs = analysis.load_runs(shipped.run_path(r.run))
        assert len(runs) == r.episodes
        assert runs["episode"].tolist() == list(range(r.episodes)), f"{r.run}: every episode"
        if r.finished:
            assert r.episodes == r.total_episodes
        if r.test_rollouts:
            assert len(analysis.load_tests(shipped.run_path(r.run))) == r.test_rollouts

    if manifest.budget is None:
        pytest.skip(f"{data} was not shipped from a reproduction: it has no report to build")
    try:
        stands_for = ShippedData.open(data).stands_for(get_budget(manifest.budget))
        ShippedData.open(data).select(stands_for, None)
    except ShippedDataError as exc:
        pytest.skip(f"{data} loads; no report is built until an experiment is shipped whole: {exc}")
    if not built:
        stderr = io.StringIO()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(stderr):
            code = curious_cli(
                ["reproduce", "--from-data", str(data), "--out", str(out), "--no-progress"]
            )
        assert code == 0, stderr.getvalue()[-3000:]
    report = (out / "report.md").read_text(encoding="utf-8")
    built = sorted(p.stem for p in (out / "metrics").glob("*.parquet") if ".tests" not in p.name)
    assert built, "the report covers at least one experiment"
    # spontaneous forgetting is read in every experiment of the paper's that nothing perturbs
    unperturbed = [
        e for e in built if not stands_for.experiments[e].perturbed and e not in BEYOND_PAPER
    ]
    assert report.count("### Spontaneous forgetting") == len(unperturbed)
    without_drops = 0
    n_runs = 0
    for experiment in built:
        combined = pd.read_parquet(out / "metrics" / f"{experiment}.parquet")
        n_runs += combined["run"].nunique()
        # runs of variants too few for the statistics are shown, untested (`left_out_runs`)
        shown = ShippedData.open(data).left_out_runs(stands_for.experiments[experiment])
        for n in sorted({int(s.variant.rsplit("_", 1)[-1]) for s in shown}):
            row = next(x for x in report.splitlines() if x.startswith(f"| {n} |"))
            assert row.endswith("| – | – (not tested: too few runs shipped) |"), row
        # An experiment shipped whole for some variants only is built from those (the others
        # are named as left out), and a seed beyond the budget's is read once all its runs of
        # those variants are shipped finished: the other runs shipped are not the report's.
        chosen = stands_for.experiments[experiment]
        paths = {str(data.resolve().joinpath(*s.relative_path.parts)) for s in chosen.runs()}
        assert set(combined["run"].astype(str)) == paths, f"{experiment}: the runs read"
        seeds = combined.groupby("seed")["run"].nunique()
        per_seed = len(chosen.conditions) * len(chosen.variants)
        assert (seeds == per_seed).all(), f"{experiment}: every seed a whole comparison"
        if chosen.extra_seeds:
            beyond = ", ".join(map(str, chosen.extra_seeds))
            assert f"Seeds beyond the budget's: {beyond} (" in report, "extra seeds named"
        if chosen.left_out_seeds:
            left = ", ".join(map(str, chosen.left_out_seeds))
            assert f"Seeds left out: {left}, whose runs" in report, "left-out seeds named"
        runs = analysis.load_runs(data / experiment)
        runs = runs[runs["run"].astype(str).isin(paths)].reset_index(drop=True)
        assert_same_table(combined, runs)
        tests = analysis.load_tests(data / experiment)
        tests = tests[tests["run"].astype(str).isin(paths)].reset_index(drop=True)
        final_test = analysis.final_success(analysis.epoch_success(tests)).set_index("run")
        final_competence = analysis.final_competence(runs).set_index("run")["value"]
        # every run that self-evaluates (all but her) has a final competence: one left out of
        # the table would read None below, rendered "–" as her's, and pass unnoticed
        competence = {str(run): value for run, value in final_competence.items()}
        conditions = runs.groupby("run", observed=True)["condition"].first()
        for run, condition in conditions.items():
            if CONDITION_CLASSES[str(condition)].self_evaluates:
                value = competence.get(str(run))
                assert value is not None and math.isfinite(value), (
                    f"{experiment}: {run} self-evaluates, yet has no final competence ({value})"
                )
        for run, rows in runs.groupby("run", observed=True):
            relative = Path(str(run)).relative_to(data.resolve()).as_posix()
            line = next(x for x in report.splitlines() if x.startswith(f"| {relative} |"))
            cells = [c.strip() for c in line.strip("|").split("|")]
            assert cells[4] == f"{len(rows):,}", f"{relative}: episodes in the report"
            assert cells[6] == _two(final_competence.get(run)), f"{relative}: final competence"
            tested = (
                f"{_two(final_test.at[run, 'value'])} ({final_test.at[run, 'n_tests']})"
                if run in final_test.index
                else "–"
            )
            assert cells[7] == tested, f"{relative}: test success and its rollouts"
        if experiment in unperturbed:
            without_drops += analysis.mastery_drops(runs).empty
    assert report.count("No drop of a mastered module in these runs.") == without_drops
    if "long" in built:  # the dips' test: one run per seed, the longest (`longest_per_seed`)
        pooled = pd.concat(
            [pd.read_parquet(out / "metrics" / f"{e}.parquet") for e in UNPERTURBED if e in built]
        )
        pooled = pooled[pooled["condition"] == "curious"]
        left = analysis.shorter_of_seed(pooled)
        line = next(x for x in report.splitlines() if x.startswith("The dips' test over every"))
        assert f"({pooled['run'].nunique() - len(left)} runs of " in line, line
        assert (", the longest; left out: " in line) == (not left.empty), line
        for r in left.itertuples():
            pair = "/".join(Path(r.run).parts[-3:]) + " (for " + "/".join(Path(r.kept).parts[-3:])
            assert pair in line, line
    assert f"This report was built from {n_runs} runs, " in report, "the header counts its runs"
    return report
