"""The numbers README.md and docs/results.md quote are those the shipped runs give.

Each headline number of the README's results table (and the C1 bins table of docs/results.md) is
computed here with `curious.analysis` from `data/laptop`, from the runs the report reads there
(the budget's seeds, and a seed beyond them once all its runs of an experiment are shipped:
`_whole_seeds`), formatted as the pages print it (p-values by
`curious.analysis.formatting.format_p`, as the report), and looked for in the page's text. A
number that changes with the shipped data (a seed shipped whole, as the campaign goes on), or a page
edited by hand away from the data, fails here.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

from curious import analysis
from curious.analysis.formatting import format_p
from curious.commands.progress import block_rows
from curious.reproduction.campaign_progress import progress_table
from curious.reproduction.experiments import get_budget

if TYPE_CHECKING:
    import pandas as pd

    from curious.reproduction.experiments import ReproduceBudget
    from pipelines.from_data import ShippedData

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data" / "laptop"
README = ROOT / "README.md"
RESULTS = ROOT / "docs" / "results.md"
OTHER_COMPARISONS = ("sensor_failure", "distractors", "sensor_failure_mastered")
"""The experiments that compare two conditions beside the main comparison."""

pytestmark = pytest.mark.skipif(
    not (DATA / "shipped.json").exists(), reason=f"{DATA} ships no runs"
)


def _text(path: Path) -> str:
    """The page's text with its line breaks as spaces, so that a number may wrap."""
    return re.sub(r"\s+", " ", path.read_text())


def _summary_row(page: Path, claim: str) -> str:
    """The row of `page`'s table of claims that sums `claim` up ("C1" ... "C5"): a number that
    also stands in the section below is checked in the row itself, not only somewhere on the
    page."""
    (row,) = [line for line in page.read_text().splitlines() if line.startswith(f"| {claim}: ")]
    return row


def _budget_runs(experiment: str, variant: str | None = None) -> list[Path]:
    """The budget's run folders of `experiment` (of one `variant`) in data/laptop, shipped or
    not."""
    runs = get_budget("laptop").experiments[experiment].runs()
    return [DATA / r.relative_path for r in runs if variant is None or r.variant == variant]


def _runs(experiment: str, variant: str | None = None) -> list[Path]:
    """The budget's run folders of `experiment` (of one `variant`), as shipped in data/laptop;
    the test is skipped until all are."""
    paths = _budget_runs(experiment, variant)
    missing = [p for p in paths if not p.is_dir()]
    if missing:
        pytest.skip(f"not shipped yet: {', '.join(str(p.relative_to(DATA)) for p in missing)}")
    return paths


@functools.cache
def _read_by_report() -> tuple[ShippedData, ReproduceBudget]:
    """data/laptop opened once, and the `laptop` budget as it stands for it
    (`ShippedData.stands_for`)."""
    from pipelines.from_data import ShippedData

    shipped = ShippedData.open(DATA)
    return shipped, shipped.stands_for(get_budget("laptop"))


def _whole_seeds(experiment: str, variant: str | None = None) -> list[Path]:
    """The runs of `experiment` (of one `variant`) that the report reads from data/laptop: the
    budget's seeds, and each seed beyond them whose runs of the experiment are all shipped
    finished; skipped while it holds none."""
    shipped, budget = _read_by_report()
    e = budget.experiments[experiment]
    runs = [r for r in e.runs() if variant is None or r.variant == variant]
    if shipped.missing(e) or not runs:
        pytest.skip(f"no seed of {experiment} {variant or ''} shipped whole yet")
    return [DATA / r.relative_path for r in runs]


PROSE = {"push_cube1": "push cube 1", "cube1_above_cube2": "cube 1 above cube 2"}
"""Modules as the pages' prose names them where it differs from the module's own name."""


def _cpus(run: Path) -> set[str]:
    """The CPUs a run trained on, as its config.json records them (start and each resume)."""
    import json

    record = json.loads((run / "config.json").read_text())
    return {m["machine"]["cpu"] for m in (record, *record.get("resumed", []))}


WORDS = {0: "none", 1: "one", 2: "two", 3: "three", 4: "four", 5: "five", 6: "six", 7: "seven",
         8: "eight", 9: "nine", 10: "ten"}  # fmt: skip
"""Small counts as the pages write them in words."""


def _seed(path: Path) -> int:
    """The seed of a run folder named ``seed-K``."""
    return int(path.name.removeprefix("seed-"))


def _mean_std(row) -> str:
    return f"{row['mean']:.2f} ± {row['std']:.2f}"


@pytest.fixture(scope="module")
def main_bins():
    """The main comparison's test success in 5,000-episode bins, and the Welch test per bin."""
    points = analysis.epoch_success(analysis.load_tests(_whole_seeds("main")), bin_size=5_000)
    means = analysis.across_seeds(points).set_index(["condition", "episodes"])
    return means, analysis.welch_per_bin(points, "curious", "mg-te")


def test_c1_final_test_success_and_significant_bins(main_bins):
    means, welch = main_bins
    final = ", ".join(
        f"{name} {_mean_std(means.loc[(condition, 100_000)])}"
        for name, condition in (("CURIOUS", "curious"), ("MG-TE", "mg-te"), ("HER", "her"))
    )
    significant = f"significant in {int(welch['significant'].sum())} of {len(welch)} bins"
    for page in (README, RESULTS):
        text = _text(page)
        assert significant in text, (page.name, significant)
    assert _summary_row(README, "C1").count(significant) == 2, significant
    holm = f"in {int(welch['significant_holm'].sum())} of {len(welch)} after Holm's correction"
    assert significant in _summary_row(RESULTS, "C1") and holm in _summary_row(RESULTS, "C1")
    assert final in _text(README), final
    ahead = (welch["mean_better"] > welch["mean_worse"]).all()
    assert ahead and "CURIOUS ahead in every 5,000-episode bin" in _text(README)


def test_the_pages_count_the_seeds_of_the_other_comparisons_as_the_report_reads_them():
    """The opening of docs/results.md and the README's results count the seeds a side of the
    comparisons beside the main one as the report reads them (seeds whole in every condition),
    and the long runs shipped."""
    _, budget = _read_by_report()
    counts = [len(budget.experiments[e].seeds) for e in OTHER_COMPARISONS]
    lo, hi = min(counts), max(counts)
    spread = f"{lo} to {hi} a side" if lo < hi else f"{lo} a side"
    long = len(list((DATA / "long" / "curious").glob("seed-*")))
    assert f"{spread} in the comparisons beside it" in _text(RESULTS), spread
    assert f"with {spread} in the comparisons beside the main one" in _text(RESULTS), spread
    assert f"(the long runs, CURIOUS alone: {long} of 5 shipped so far)" in _text(RESULTS)
    assert f"{spread} in the other comparisons" in _text(README), spread


def _progress_rows() -> dict[str, tuple[int, str]]:
    """Each run of results.md's progress table: its episodes and its checkpoint cell ("shipped",
    "none" or an episode count)."""
    rows = block_rows(RESULTS.read_text())
    return {
        run: (int(cells["episodes"].replace(",", "")), cells["checkpoint"])
        for run, cells in rows.items()
        if "/seed-" in run
    }


def test_the_pages_say_which_long_runs_are_shipped_training_and_queued():
    """What results.md, the README and data/README.md say of the long runs' seeds agrees with the
    shipped folders and with the progress table of results.md: shipped, training (episodes
    logged, not shipped) or queued (none yet)."""
    rows = {run: row for run, row in _progress_rows().items() if run.startswith("long/")}
    assert len(rows) == 5, rows
    # the checkpoint cell: "shipped", or "300,000, shipped" while the run folder keeps its last
    done = {run for run, (_, cell) in rows.items() if cell.endswith("shipped")}
    shipped = sorted(int(run[-1]) for run in done)
    training = sorted(int(run[-1]) for run, (n, _) in rows.items() if run not in done and n)
    queued = sorted(int(run[-1]) for run, (n, _) in rows.items() if not n)
    folders = sorted(int(p.name[-1]) for p in (DATA / "long" / "curious").glob("seed-*"))
    assert shipped == folders, (shipped, folders)

    def seeds(values: list[int]) -> str:
        if len(values) == 1:
            return f"seed {values[0]}"
        if len(values) > 2 and values == list(range(values[0], values[-1] + 1)):
            return f"seeds {values[0]} to {values[-1]}"
        return f"seeds {_listed([str(v) for v in values])}"

    def parts(verb: bool) -> list[str]:
        """What each state's seeds do, with "is"/"are" (results.md's sentences) or without
        (the protocol row and the README's cells)."""
        out = []
        for values, state in ((training, "training"), (queued, "queued")):
            if values:
                be = ("is " if len(values) == 1 else "are ") if verb else ""
                out.append(f"{seeds(values)} {be}{state}")
        return out

    results = _text(RESULTS)
    sentence = " and ".join(parts(verb=True))
    assert sentence in results, sentence
    assert ", ".join(parts(verb=True)) in results, sentence
    assert ", ".join(parts(verb=False)) in _text(README), sentence
    data = _text(ROOT / "data" / "README.md")
    n = len(shipped)
    assert f"as each finishes: {n} run{'s' * (n != 1)}, {seeds(shipped)}." in data


def test_data_readme_counts_the_study_on_a_mastered_module_as_shipped():
    runs = sorted((DATA / "sensor_failure_mastered").glob("*/seed-*"))
    data = _text(ROOT / "data" / "README.md")
    assert f"then): {len(runs)} runs" in data, len(runs)
    assert ("M-UVFA's seed 4 still training" in data) == (len(runs) < 10)
    assert ("M-UVFA's seed 4 still training" in _text(RESULTS)) == (len(runs) < 10)


def test_the_readmes_quickstart_times_are_the_benchmarks_measures():
    """Each time the README gives for the quickstart's first command stands in docs/benchmarks.md's
    table of the quickstart's two commands, which says the machine, date and commit."""
    readme = _text(README)
    opening = readme[readme.index("The first command shows") : readme.index("It writes:")]
    times = re.findall(r"\b\d+ min \d+ s\b|\b\d+ s after it starts", opening)
    assert len(times) == 3, times
    table = (ROOT / "docs" / "benchmarks.md").read_text()
    table = table[table.index("## The quickstart's two commands") :]
    table = table[: table.index("\n## ")] if "\n## " in table else table
    for quoted in times:
        measured = quoted.replace(" after it starts", " to that line")
        assert measured in table, quoted


def test_the_main_comparisons_seeds_are_counted_as_the_report_reads_them():
    """Every place README.md and docs/results.md count the main comparison's seeds says how many
    the report reads (a seed beyond the budget's counts once all its runs are shipped)."""
    seeds = sorted({_seed(p) for p in _whole_seeds("main")})
    n, last = len(seeds), seeds[-1]
    w = WORDS[n]
    readme, results = _text(README), _text(RESULTS)
    for quoted in (f"HER, {n} seeds each](docs/images", f"main comparison; {n} seeds there"):
        assert quoted in readme, quoted
    for quoted in (
        f"and {n} seeds in the main comparison",
        f"reproduced with {n} seeds:",
        f"reproduced in all {w} CURIOUS seeds",
        f"CURIOUS, MG-TE and HER, seeds 0 to {last} (",
        f"CURIOUS, MG-TE and HER, {n} seeds x 100,000 episodes",
        f"HER, {n} seeds each](images",
        f"the mean over {n} seeds",
        f"with {w} seeds a side",
        f"in all {w} seeds; MG-TE",
        f"{n} x 20,000 test rollouts",
        f"MG-TE's {w} seeds ended within",
        f"CURIOUS seeds 0-{last}](images",
        f"In all {w} CURIOUS seeds reach came first",
    ):
        assert quoted in results, quoted


def test_what_the_pages_say_of_the_main_comparisons_seeds_beyond_the_budgets():
    """The seeds beyond the budget's that the report reads are named as read, a seed with only
    some of its runs shipped as waiting, and data/README.md counts the runs shipped."""
    budget = {int(r.seed) for r in get_budget("laptop").experiments["main"].runs()}
    read = sorted({_seed(p) for p in _whole_seeds("main")} - budget)
    shipped = sorted(p for p in (DATA / "main").glob("*/seed-*") if p.is_dir())
    waiting = sorted({_seed(p) for p in shipped} - budget - set(read))
    named = _listed([str(s) for s in read])
    named = f"seed {named}" if len(read) == 1 else f"seeds {named}"
    results = _text(RESULTS)
    for quoted in (f"and {named} the campaign adds", f"for the main comparison ({named} too)"):
        assert quoted in results, quoted
    for seed in waiting:
        for quoted in (
            f"of the main comparison's seed {seed},",
            f"Seed {seed} (the campaign's) will be read the same way",
        ):
            assert quoted in results, quoted
    if not waiting:
        for stale in ("(the campaign's) will be read the same way", "is shipped and waits for"):
            assert stale not in results, stale
    data = _text(ROOT / "data" / "README.md")
    last = max(read or budget)
    assert f"`main/`: CURIOUS, MG-TE and HER, seeds 0-{last}" in data
    assert f"each ({len(shipped)} runs)" in data, len(shipped)


def test_c1_the_bins_not_significant_are_named_with_their_means(main_bins):
    """docs/results.md's C1 statistics name each bin where the Welch test is not significant,
    with both conditions' means and its p."""
    _, welch = main_bins
    text = _text(RESULTS)
    for r in welch[~welch["significant"]].itertuples():
        named = f"ending at {int(r.episodes):,}"
        means = f"({r.mean_better:.2f} against {r.mean_worse:.2f}, p = {format_p(r.p)})"
        assert named in text and means in text, (named, means)
    ends = " and ".join(f"{int(e):,}" for e in welch.loc[~welch["significant"], "episodes"])
    assert f"not in the bins ending at {ends} episodes" in _summary_row(RESULTS, "C1"), ends


def test_c1_mg_tes_spread_in_the_last_bin():
    """The caveat on the last bins' small p: MG-TE's seeds' spread in the last bin."""
    paths = [p for p in _whole_seeds("main") if p.parent.name == "mg-te"]
    points = analysis.epoch_success(analysis.load_tests(paths), bin_size=5_000)
    last = points.loc[points["episodes"] == points["episodes"].max(), "value"]
    spread = f"within {last.max() - last.min():.3f} of each other ({last.min():.3f} to "
    assert f"{spread}{last.max():.3f})" in _text(RESULTS), spread
    epoch = analysis.final_success(analysis.epoch_success(analysis.load_tests(paths)))
    alone = (
        f"(MG-TE {_mean_std(epoch['value'].agg(['mean', 'std']))} over its seeds, about "
        f"{epoch['n_tests'].mean():.0f} test rollouts per run)"
    )
    assert alone in _text(RESULTS), alone


def test_c1_bins_table_of_results_md(main_bins):
    """Every row of docs/results.md's C1 table: the bin ending at each 10,000 episodes."""
    means, welch = main_bins
    p = welch.set_index("episodes")["p"]
    text = RESULTS.read_text()
    for end in range(10_000, 100_001, 10_000):
        cells = [_mean_std(means.loc[(c, end)]) for c in ("curious", "mg-te", "her")]
        row = f"| {end:,} | {' | '.join(cells)} | {format_p(p[end])} |"
        assert row in text, row


def test_c2_order_of_learning_in_every_curious_seed():
    paths = [p for p in _whole_seeds("main") if p.parent.name == "curious"]
    order = analysis.learning_order(analysis.competence_crossings(analysis.load_runs(paths)))
    seeds = len(order)
    assert seeds == len(paths) and order["follows_paper"].all(), order
    assert f"the same order in all {seeds} CURIOUS seeds" in _text(README)
    # reach's crossing in MG-TE is its first full window, the same in every run or not
    mg_te = [p for p in _whole_seeds("main") if p.parent.name == "mg-te"]
    crossings = analysis.competence_crossings(analysis.load_runs(mg_te))
    reach = set(crossings.loc[crossings["module"] == "reach", "episode"])
    if len(reach) == 1:
        assert f"({int(reach.pop()):,} in every MG-TE run)" in _text(RESULTS)
    else:
        assert "in every MG-TE run)" not in _text(RESULTS), sorted(reach)
    # which of the last two came first, per seed (a tie would read as neither)
    steps = {int(r.seed): r.order.split(" → ") for r in order.sort_values("seed").itertuples()}
    stack = [s for s, o in steps.items() if o.index("stack") < o.index("cube1_above_cube2")]
    above = [s for s, o in steps.items() if o.index("cube1_above_cube2") < o.index("stack")]
    assert f"(stack first in {WORDS[len(stack)]})" in _text(README), stack
    reading = (
        f"stack first in seeds {_listed([str(s) for s in stack])}, cube 1 above cube 2 first in "
        f"seeds {_listed([str(s) for s in above])}"
    )
    assert reading in _text(RESULTS), reading


def _report_rows(lines: list[str]) -> list[str]:
    """The rows of the markdown table in a report block's lines, its header first."""
    return [line for line in lines if line.startswith("|")]


def test_c1_episodes_to_test_success_and_c2_order_tables_of_results_md():
    """docs/results.md's table of episodes to test success 0.5 / 0.9 (C1) and its table of the
    order of learning (C2) are the report's, row by row, for every seed the report reads."""
    from pipelines.report.main_comparison import episodes_to_success_table, learning_order_table

    paths = _whole_seeds("main")
    _, budget = _read_by_report()
    main = budget.experiments["main"]
    text = RESULTS.read_text()
    for table in (
        episodes_to_success_table(main, analysis.load_tests(paths)),
        learning_order_table(main, analysis.load_runs(paths)),
    ):
        rows = _report_rows(table)
        assert len(rows) == 2 + len(paths)
        for row in rows:
            assert row in text, row


def test_c1_reading_every_curious_seed_before_any_mg_te_seed():
    """The C1 reading: on push cube 1, stack and cube 1 above cube 2, every CURIOUS seed reached
    each level of test success before any MG-TE seed did (a seed that never reached it counts
    as after), and the means over seeds the page quotes."""
    table = analysis.episodes_to_test_success(analysis.load_tests(_whole_seeds("main")))
    table = table.assign(episodes=table["episodes"].astype("Float64").fillna(np.inf))
    at = table.groupby(["module", "level", "condition"], observed=True)["episodes"]
    for module in ("push_cube1", "stack", "cube1_above_cube2"):
        for level in (0.5, 0.9):
            assert at.max()[(module, level, "curious")] < at.min()[(module, level, "mg-te")]
    text = _text(RESULTS)
    quoted = [("push_cube1", 0.9, "push cube 1"), ("stack", 0.9, "stack")]
    quoted += [("cube1_above_cube2", 0.5, "cube 1 above cube 2")]
    for module, level, name in quoted:
        c, m = (round(at.mean()[(module, level, x)], -2) for x in ("curious", "mg-te"))
        reading = f"{level} on {name} at {c:,.0f} episodes against {m:,.0f}"
        if module != "push_cube1":
            reading = f"{level} on {name} at {c:,.0f} against {m:,.0f}"
        assert reading in text, reading
    # C4's hint across experiments: CURIOUS at 3 distracting modules, the main comparison
    push = table[(table["module"] == "push_cube1") & (table["level"] == 0.5)]
    push = push.loc[push["condition"] == "curious", "episodes"]
    hint = (
        f"CURIOUS passed 0.5 of test success on push cube 1 at {push.min():,.0f}-{push.max():,.0f}"
    )
    assert hint in text, hint


def _listed(values: list[str]) -> str:
    """Values as the pages list them: ``"a, b, c and d"``."""
    return values[0] if len(values) == 1 else f"{', '.join(values[:-1])} and {values[-1]}"


def test_c1_each_module_at_the_end_and_hers_per_module_view():
    """docs/results.md's table of each module at the runs' end is the report's, row by row; the
    reading quotes MG-TE's seeds on the two modules it had not mastered, and the HER paragraph
    its seeds' own-goal rates on reach and push cube 1 (`module_success_rates`)."""
    from pipelines.report.main_comparison import OWN_GOAL_TEXT, module_success_tables

    paths = _whole_seeds("main")
    tests = analysis.load_tests(paths)
    _, budget = _read_by_report()
    lines = module_success_tables(budget.experiments["main"], tests)
    rows = _report_rows(lines[: lines.index(OWN_GOAL_TEXT)])
    assert len(rows) == 2 + len(paths)
    for row in rows:
        assert row in RESULTS.read_text(), row
    end = analysis.module_success_rates(tests).sort_values("seed", kind="stable")
    own = analysis.module_success_rates(tests, epochs=None, score="module_success")
    own = own.sort_values("seed", kind="stable")

    def seeds(table, condition: str, module: str, cell) -> str:
        picked = table[(table["condition"] == condition) & (table["module"] == module)]
        return _listed([cell(v) for v in picked["value"]])

    def rate(v: float) -> str:
        return f"{v:.2f}"

    def share(v: float) -> str:
        return f"{100 * v:.1f} %"

    text = _text(RESULTS)
    for quoted in (
        f"{seeds(end, 'mg-te', 'cube1_above_cube2', rate)} on cube 1 above cube 2 and "
        f"{seeds(end, 'mg-te', 'stack', rate)} on stack",
        f"reach's part of its goal was met in {seeds(own, 'her', 'reach', share)}",
        f"push cube 1's in {seeds(own, 'her', 'push_cube1', share)}",
    ):
        assert quoted in text, quoted


def _seeds_cell(row) -> str:
    """A condition's cell of the C4 tables: mean ± std (N seeds), or the value (1 seed)."""
    if int(row["n"]) == 1:
        return f"{row['mean']:.2f} (1 seed)"
    return f"{_mean_std(row)} ({int(row['n'])} seeds)"


@pytest.mark.parametrize("n_distractors", [0, 4, 7])
def test_c4_competence_per_number_of_distractors(n_distractors):
    runs = analysis.load_runs(_whole_seeds("distractors", f"distractors_{n_distractors}"))
    final = analysis.final_competence(runs)
    means = analysis.across_seeds(final).set_index("condition")
    p = float(analysis.welch_per_bin(final, "curious", "m-uvfa")["p"].iloc[0])
    curious, m_uvfa = means.loc["curious"], means.loc["m-uvfa"]
    results = f"| {n_distractors} | {_seeds_cell(curious)} | {_seeds_cell(m_uvfa)} |"
    cell = f"| {format_p(p)} |"
    assert results in RESULTS.read_text() and cell in RESULTS.read_text(), results
    if int(curious["n"]) == 1 and int(m_uvfa["n"]) == 1:
        readme = (
            f"at {n_distractors}, {curious['mean']:.2f} and {m_uvfa['mean']:.2f} (1 seed so far)"
        )
    else:
        tested = f"p = {format_p(p)}" if np.isfinite(p) else "no spread to test"
        c, m = _mean_std(curious), _mean_std(m_uvfa)
        readme = {
            0: f"at 0, {c} against {m} ({tested})",
            4: f"at 4 distractors CURIOUS {c}, M-UVFA {m} ({tested})",
            7: f"at 7, {c} against {m} ({tested})",
        }[n_distractors]
    assert readme in _text(README), readme


@pytest.mark.parametrize("n_distractors", [0, 4, 7])
def test_c4_test_success_per_number_of_distractors(n_distractors):
    paths = _whole_seeds("distractors", f"distractors_{n_distractors}")
    final = analysis.final_test_success(analysis.load_tests(paths))
    means = analysis.across_seeds(final).set_index("condition")
    welch = analysis.welch_per_bin(final, "curious", "m-uvfa").iloc[0]
    curious, m_uvfa = _seeds_cell(means.loc["curious"]), _seeds_cell(means.loc["m-uvfa"])
    row = f"| {n_distractors} | {curious} | {m_uvfa} | "
    row += f"{welch['t']:.2f} | {format_p(welch['p'])} |" if np.isfinite(welch["p"]) else "– | – |"
    assert row in RESULTS.read_text(), row


def test_c4_per_run_table_of_results_md():
    """docs/results.md's C4 table per run is the report's (`per_run_table`): competence and
    test success at the end, test success and the share of episodes on a distracting module
    per 10,000 episodes, for every run the report reads."""
    from pipelines.report.blocks import ExperimentTables
    from pipelines.report.distracting_modules import per_run_table

    paths = _whole_seeds("distractors")
    _, budget = _read_by_report()
    tables = ExperimentTables(analysis.load_runs(paths), analysis.load_tests(paths))
    text = RESULTS.read_text()
    rows = _report_rows(per_run_table(budget.experiments["distractors"], tables))
    assert len(rows) == 2 + len(paths)
    for row in rows:
        assert row in text, row


def test_c4_degradation_between_the_settings_shipped():
    """The degradation test over the settings whose runs are all shipped (4 and 7 until
    `distractors_0` is)."""
    paths = _whole_seeds("distractors")
    final = analysis.final_competence(analysis.load_runs(paths))
    d = analysis.compare_degradation(final, "curious", "m-uvfa")
    text = _text(RESULTS)
    reading = (
        f"from {d['fewest']} to {d['most']}, a difference of {d['difference']:+.2f} "
        f"(t = {d['t']:.2f}, {d['df']:.1f} degrees of freedom, p = {format_p(d['p'])} that CURIOUS "
        "loses less)"
    )
    assert reading in text, reading
    # the same p where the pages sum C4 up, beside the comparison at 7 it repeats
    p = format_p(d["p"])
    at_7 = final[final["variant"] == f"distractors_{d['most']}"]
    p_7 = format_p(float(analysis.welch_per_bin(at_7, "curious", "m-uvfa")["p"].iloc[0]))
    assert f"CURIOUS degrades less (p = {p})" in _text(README), p
    assert f"one-tailed that CURIOUS loses less, p = {p});" in text, p
    assert f"significant at {d['most']} (p = {p_7})" in text, p_7
    assert f"both are significant, at p = {p} and {p_7}." in text, (p, p_7)
    # the rows that sum C4 up: the losses, the test and the comparison at the most distractors
    loss, other = f"{d['loss_curious']:.2f}", f"{d['loss_m-uvfa']:.2f}"
    most = int(d["most"])
    seeds = f"{int(d[f'n_curious_{most}'])} seeds a side"
    row = _summary_row(RESULTS, "C4")
    assert f"CURIOUS's competence fell by {loss} and M-UVFA's by {other}" in row, (loss, other)
    assert f"loses less, p = {p});" in row and f"significant at {d['most']} (p = {p_7})" in row
    assert f"reproduced with {seeds}" in row, seeds
    row = _summary_row(README, "C4")
    assert f"CURIOUS lost {loss}, M-UVFA {other}" in row and f"degrades less (p = {p})" in row
    assert f"{seeds}:" in row, seeds


def test_c3_no_drop_of_a_mastered_module():
    """The C3 reading over every shipped run that self-evaluates (HER does not), of the main
    comparison and of the distractors' settings whose runs are all shipped."""
    paths = [p for p in _whole_seeds("main") if p.parent.name != "her"]
    paths += _whole_seeds("distractors")
    table = analysis.mastery(analysis.load_runs(paths))
    runs, deepest = len(paths), float(table["deepest_fall"].max())
    assert int(table["n_drops"].sum()) == 0
    readme = (
        f"no mastered module fell by 0.2 in {runs} runs of 100,000 episodes or fewer (deepest "
        f"fall {deepest:.2f})"
    )
    assert readme in _text(README), readme
    falls = np.sort(table["deepest_fall"].dropna().to_numpy())[::-1]
    others = f"the deepest fall below a peak was {falls[0]:.2f}, and every other was "
    assert f"{others}{falls[1]:.2f} or less" in _text(RESULTS), others
    episodes = int(table["mastered_episodes"].sum()) / 1e6
    results = (
        f"Over about {episodes:.2f} million module-episodes of mastered modules in {runs} runs"
    )
    assert results in _text(RESULTS), results


@functools.cache
def _mastered_study() -> tuple[list[Path], pd.DataFrame, pd.DataFrame]:
    """The study on a mastered module as the report reads it, loaded once: its run folders,
    their metrics (`load_runs`) and each run's recovery by test success (`recovery_by_tests`)."""
    paths = _whole_seeds("sensor_failure_mastered")
    runs = analysis.load_runs(paths)
    onsets = analysis.failure_onsets(runs)["onset"]
    return paths, runs, analysis.recovery_by_tests(analysis.load_tests(paths), onsets)


def test_c3_no_drop_in_the_study_on_a_mastered_module():
    """C3's paragraph on the study on a mastered module's runs: how many, the episodes from
    which CURIOUS mastered the two later modules, the module-episodes mastered and the deepest
    fall, over the seeds the report reads."""
    paths, runs, _ = _mastered_study()
    table = analysis.mastery(runs)
    assert int(table["n_drops"].sum()) == 0
    mastered = table.dropna(subset=["mastered_episode"])
    n, seeds = len(paths), sorted(table["seed"].unique())
    text = _text(RESULTS)
    assert (
        f"In the {WORDS[n]} runs of the study on a mastered module (seeds 0 to {seeds[-1]}," in text
    )
    assert f"(reach and push cube 1 in all {WORDS[n]} runs;" in text
    assert all((mastered["module"] == m).sum() == n for m in ("reach", "push_cube1"))
    for module, name in (
        ("cube1_above_cube2", "cube 1 above cube 2"),
        ("push_cube3", "push cube 3"),
    ):
        at = mastered[(mastered["condition"] == "curious") & (mastered["module"] == module)]
        episodes = _listed([f"{int(e):,}" for e in at.sort_values("seed")["mastered_episode"]])
        assert f"{name} from {episodes}" in text, episodes
    total = int(mastered["mastered_episodes"].sum())
    deepest = float(mastered["deepest_fall"].max())
    assert f"{total:,} module-episodes in all, fell at most {deepest:.2f} below their peaks" in text


def test_c3_when_each_module_was_first_mastered_in_the_main_comparison():
    """C3's ranges of the episode at which each module was first mastered, per condition of the
    main comparison, over its modules mastered in some run (`mastery`)."""
    paths = [p for p in _whole_seeds("main") if p.parent.name != "her"]
    table = analysis.mastery(analysis.load_runs(paths)).dropna(subset=["mastered_episode"])
    text = _text(RESULTS)
    for condition, label in (("curious", "CURIOUS"), ("mg-te", "MG-TE")):
        at = table[table["condition"] == condition].groupby("module", observed=True, sort=False)
        ranges = ", ".join(
            f"{PROSE.get(str(m), m)} {_span(int(e.min()), int(e.max()))}"
            for m, e in at["mastered_episode"]
        )
        assert f"{label} main, {ranges}" in text, ranges


def _span(first: int, last: int) -> str:
    """A range of episodes as the pages write it: ``"2,409-12,349"``, or one episode alone."""
    return f"{first:,}" if first == last else f"{first:,}-{last:,}"


def test_c3_table_per_condition_of_results_md():
    """docs/results.md's C3 table is the report's per condition and variant (`mastery_summary`),
    the main comparison's rows then the distractors', for every seed the report reads."""
    from pipelines.report.spontaneous_forgetting import mastery_summary

    _, budget = _read_by_report()
    text = RESULTS.read_text()
    for name in ("main", "distractors"):
        read = analysis.mastery(analysis.load_runs(_whole_seeds(name)))
        for row in _report_rows(mastery_summary(budget.experiments[name], read)):
            assert row in text, row


def test_c5_refocus_and_recoveries():
    table = analysis.recovery(analysis.load_runs(_runs("sensor_failure")))
    table = table.sort_values(["condition", "seed"]).set_index(["condition", "seed"])
    readme, results = _text(README), RESULTS.read_text()
    for seed in (0, 1):
        row = table.loc[("curious", seed)]
        refocus = f"{row['p_lp_before']:.2f} → {row['p_lp_after']:.2f}"
        assert refocus in readme and refocus in results, refocus
    recovered = table[table["recovered"]]["recovery_episodes"].astype(int)
    for condition, seed in recovered.index:
        episodes = f"{recovered[(condition, seed)]:,}"
        assert f"{episodes} episodes" in results and episodes in readme, (condition, seed)
    assert not table.loc[("m-uvfa", 0), "recovered"]


def test_c5_the_first_studys_practice_and_competence_over_the_stretch_every_run_has():
    """The study on a module just learned: over the episodes every run had after its onset (the
    shortest stretch, M-UVFA seed 0's), each run's share of episodes on push cube 3 before and
    after the onset, and its competence at the table's points, read from the runs' metrics."""
    from curious.watching.palette import condition_label

    runs = analysis.load_runs(_runs("sensor_failure"))
    onsets = analysis.failure_onsets(runs)["onset"]
    text = _text(RESULTS)
    stretch = min(
        int(g["episode"].max()) + 1 - int(onsets[str(run)]) for run, g in runs.groupby("run")
    )
    assert f"practised, {stretch:,} episodes before → after" in text
    assert f"over the {stretch:,} episodes after each onset (the stretch every run has)" in text
    points = (1_000, 2_000, 3_000, 4_000, 5_000, stretch - 1)
    assert "| | at onset | " + " | ".join(f"+{d:,}" for d in points) + " |" in text
    for run, g in runs.groupby("run", observed=True):
        onset, episode = int(onsets[str(run)]), g["episode"].to_numpy()
        on_it = g["module"].astype(str).to_numpy() == "push_cube3"
        before = on_it[(episode >= onset - stretch) & (episode < onset)].mean()
        after = on_it[(episode >= onset) & (episode < onset + stretch)].mean()
        label, seed = condition_label(str(g["condition"].iat[0])), int(g["seed"].iat[0])
        assert f"| {label} | {seed} | {onset:,} |" in text, (label, seed)
        share = f"| {100 * before:.0f} % → {100 * after:.0f} % |"
        assert share in text, (label, seed, share)
        competence = g["competence/push_cube3"].to_numpy()
        at = [competence[episode == onset - 1][0]]
        at += [competence[episode == onset + d][0] for d in points]
        cells = " | ".join(f"{c:.2f}" for c in at)
        quoted = f"| {label} {seed} (onset {onset:,}) | {cells} |"
        last = f"{label} {seed}'s competence was {at[-1]:.2f} at {points[-1]:,} episodes after"
        assert quoted in text or last in text, (quoted, last)


def test_c5_on_a_mastered_module_by_its_fixed_rules():
    """Each run's row of the study on a mastered module as the report writes it (onset, level
    before, trough, the primary and secondary recoveries), the README's recoveries by test
    success, the episodes a run not recovered by its end had left, and the Welch test on the
    recovered runs once it can be computed."""
    from curious.watching.palette import condition_label
    from pipelines.report.blocks import fmt, fmt_p
    from pipelines.report.sensory_failures import primary_cell, secondary_cell

    _, runs, by_tests = _mastered_study()
    competence = analysis.recovery(runs).set_index(["condition", "seed"])
    results, readme = _text(RESULTS), _text(README)
    recovered: dict[str, list[str]] = {"curious": [], "m-uvfa": []}
    for t in by_tests.sort_values("seed").itertuples():
        assert t.status == "measured", t.note
        c = next(competence.loc[[(t.condition, t.seed)]].itertuples())
        cells = (
            f"| {condition_label(t.condition)} | {t.seed} | {int(t.onset):,} | "
            f"{t.level_before:.2f} ({t.n_before}) | {t.trough:.2f} at {int(t.trough_episode):,} |"
        )
        recoveries = f"| {primary_cell(t)} | {secondary_cell(c)} |"
        assert cells in results and recoveries in results, cells + recoveries
        if t.recovered:
            recovered[t.condition].append(f"{int(t.recovery_episodes):,}")
        else:
            unrecovered = f"not within the {int(t.episodes_left):,} episodes"
            assert unrecovered in readme and unrecovered in results, unrecovered
            assert unrecovered in _summary_row(RESULTS, "C5"), unrecovered
            assert unrecovered in _summary_row(README, "C5"), unrecovered
    for condition, ns in recovered.items():
        listed = " and ".join([", ".join(ns[:-1]), ns[-1]] if len(ns) > 1 else ns)
        quoted = f"{listed} episodes (CURIOUS)" if condition == "curious" else f"{listed} (M-UVFA)"
        assert not ns or quoted in readme, quoted
        summed = (
            f"CURIOUS's test success back after {listed} episodes"
            if condition == "curious"
            else f"M-UVFA's after {listed}"
        )
        assert not ns or summed in _summary_row(RESULTS, "C5"), summed
    test = analysis.compare_recoveries(by_tests, "curious", "m-uvfa")
    if np.isfinite(test["p"]):
        welch = f"t = {fmt(test['t'])}, p = {fmt_p(test['p'])}"
        assert welch in results, welch
        assert f"p = {fmt_p(test['p'])}" in readme, welch


def test_c5_the_course_after_the_onset_and_the_returns_below_the_threshold():
    """The readings beside C5's fixed rules, as the report writes them: each run's test success at
    the table's distances after its onset (`success_after_onset`), with the table's caption, and
    after each crossing the epochs back under the run's threshold (`returns_below`)."""
    from pipelines.report.sensory_failures import (
        after_onset_offsets,
        after_onset_rows,
        returns_clauses,
    )

    _, budget = _read_by_report()
    e = budget.experiments["sensor_failure_mastered"]
    paths, runs, by_tests = _mastered_study()
    tests = analysis.load_tests(paths)
    onsets = analysis.failure_onsets(runs)["onset"]
    offsets = after_onset_offsets(by_tests)
    text = _text(RESULTS)
    header = "| | " + " | ".join(f"+{d:,}" for d in offsets) + " |"
    assert header in text, header
    caption = "pooled over the 5 epochs ending at the first epoch tested at or after each point"
    assert caption in text, caption
    after = analysis.success_after_onset(tests, onsets, offsets)
    rows = after_onset_rows(e, after)
    assert len(rows) == len(paths)
    for row in rows:
        line = "| " + " | ".join(row) + " |"
        assert line in text, line
    clauses = returns_clauses(e, analysis.returns_below(tests, by_tests))
    assert len(clauses) == int(by_tests["recovered"].sum())
    for clause in clauses:
        assert clause in text, clause


P_QUOTED = re.compile(r"\bp(?: =| is)? (\d[\d.e-]*\d|\d)(?: (?:to|and) (\d[\d.e-]*\d|\d))?\b")
"""A p-value as the pages quote it: "p = 0.0018", "p 0.0017 to 0.0021", "exact p is 0.05",
"at p = 0.0011 and 0.0018"."""


def test_every_p_value_the_pages_quote_is_rounded_as_the_report_rounds_it():
    """One rounding everywhere: every p the README and docs/results.md quote reads as
    `format_p` writes it, which the report formats with (C1's unbinned p was 1e-05, 9.7e-06 and
    9.68e-06 on three pages)."""
    from pipelines.report.blocks import fmt_p

    assert fmt_p(9.68e-06) == format_p(9.68e-06) == "9.7e-06"
    assert fmt_p(float("nan")) == format_p(None) == "–"
    quoted = [(page.name, x) for page in (README, RESULTS) for m in P_QUOTED.finditer(_text(page))
              for x in m.groups() if x]  # fmt: skip
    assert len(quoted) > 30, quoted
    other = [(page, x, format_p(float(x))) for page, x in quoted if format_p(float(x)) != x]
    assert not other, f"p-values not rounded as format_p rounds them: {other}"


def test_c1_area_under_success_per_seed_and_its_welch_test():
    """C1's reading without bins: each seed's success over every epoch, and the Welch test."""
    area = analysis.area_under_success(analysis.load_tests(_whole_seeds("main")))
    text = _text(RESULTS)
    labels = {"curious": "CURIOUS", "mg-te": "MG-TE"}
    for condition, means in analysis.across_seeds(area).set_index("condition").iterrows():
        assert _mean_std(means) in text, (condition, _mean_std(means))
        if condition in labels:
            values = area[area["condition"] == condition].sort_values("seed")["value"]
            seeds = f"{labels[condition]} {_listed([f'{v:.2f}' for v in values])}"
            assert f"{seeds} ({_mean_std(means)})" in text, seeds
    test = analysis.welch_per_bin(area, "curious", "mg-te").iloc[0]
    assert f"t = {test['t']:.2f}, p = {format_p(test['p'])}" in text
    assert f"without bins (p = {format_p(test['p'])})" in _text(README)
    assert f"without bins (p = {format_p(test['p'])})" in text
    ours = {int(r.seed) for r in get_budget("laptop").experiments["main"].runs()}
    if set(area["seed"]) != ours:
        three = analysis.welch_per_bin(area[area["seed"].isin(ours)], "curious", "mg-te").iloc[0]
        assert (
            f"(with the budget's three: t = {three['t']:.2f}, p = {format_p(three['p'])})" in text
        )


def test_the_protocols_compute_is_the_runs_own_clocks():
    """The protocol's compute row: each experiment's run-hours over the budget's seeds, their
    total, and each seed beyond the budget's that the report reads, by the runs' own clocks,
    over the experiments the report reads (those still training are in the progress table)."""
    names = {
        "main": "main comparison",
        "sensor_failure": "sensory failure",
        "distractors": "distractors",
        "sensor_failure_mastered": "sensory failure on a mastered module",
    }
    later = {"long": "long runs", "lp_uses": "LP's two uses", "signed_lp": "signed LP"}
    text, budget = _text(RESULTS), get_budget("laptop")
    shipped, read = _read_by_report()
    whole = [name for name, e in read.experiments.items() if not shipped.missing(e)]
    assert set(names) <= set(whole), whole
    names |= later
    total, count = 0.0, 0
    for name in whole:  # the budget's runs the report reads: an experiment cut to its seeds shipped
        ours = {r.relative_path for r in budget.experiments[name].runs()}
        kept = [r.relative_path for r in read.experiments[name].runs() if r.relative_path in ours]
        rows = progress_table([DATA / path for path in kept])
        hours = sum(r.run_hours for r in rows)
        total, count = total + hours, count + len(rows)
        if name == "distractors":
            per = [
                f"`{v}` {sum(r.run_hours for r in rows if r.variant == v):.2f}"
                for v in ("distractors_7", "distractors_4", "distractors_0")
            ]
            quoted = f"distractors {hours:.2f} ({len(rows)} runs: {', '.join(per)})"
        elif name == "main":
            quoted = f"main comparison {hours:.2f} run-hours ({len(rows)} runs)"
        else:
            quoted = f"{names[name]} {hours:.2f} ({len(rows)} run{'s' * (len(rows) != 1)})"
        assert quoted in text, quoted
    assert f"{count} runs, {total:.2f} run-hours" in text
    for name in whole:
        ours = {r.relative_path for r in budget.experiments[name].runs()}
        beyond: dict[int, list[Path]] = {}
        for r in read.experiments[name].runs():
            if r.relative_path not in ours:
                beyond.setdefault(r.seed, []).append(DATA / r.relative_path)
        for seed, paths in beyond.items():
            hours = sum(r.run_hours for r in progress_table(paths))
            whose = f"the {names[name]}'" if names[name].endswith("s") else f"the {names[name]}'s"
            quoted = f"{whose} seed {seed}, {hours:.2f} more ({len(paths)} runs)"
            assert quoted in text, quoted
    # runs shipped that the report does not read yet (a seed with only some of its runs shipped)
    from curious.watching.palette import condition_label

    read_paths = {r.relative_path for e in read.experiments.values() for r in e.runs()}
    for name in whole:
        for path in sorted((DATA / name).glob("*/seed-*")):
            if path.relative_to(DATA).as_posix() in {str(p) for p in read_paths}:
                continue
            (row,) = progress_table([path])
            label = condition_label(path.parent.name.split("@")[0])
            quoted = f"its {label} seed {_seed(path)}, {row.run_hours:.2f} more (1 run)"
            assert "shipped and not read yet" in text and quoted in text, quoted


def test_the_machines_row_names_every_run_trained_on_the_intel_xeon():
    """The protocol's machines row: the runs that started or resumed on an Intel Xeon, by folder,
    every other on an AMD EPYC, as each run's config.json records its machines."""
    intel, amd = set(), set()
    for config in DATA.glob("**/config.json"):
        cpus = _cpus(config.parent)
        run = config.parent.relative_to(DATA).as_posix()
        assert len(cpus) == 1, f"{run} trained on several machines: say which in the row"
        (intel if "Intel" in cpus.pop() else amd).add(run)
    row = next(line for line in RESULTS.read_text().splitlines() if line.startswith("| machines"))
    named = set(re.findall(r"`([^`]+/seed-\d+)`", row.split(";")[0]))
    assert named == intel, f"the Intel runs: {sorted(intel)}"
    assert "every other run on an AMD EPYC" in row and amd


def test_the_laptop_budgets_time_is_the_pace_its_shipped_runs_trained_at():
    """The `laptop` budget's notes, the README's budgets table and docs/scaling.md give its time
    on 2 cores from the paces of the budget's runs of the main comparison, the distractors and
    the first sensory failure shipped here (episodes per second of each run's own clock, as
    `curious progress` reads them), which fall in two groups, by machine: the faster boots' runs
    at 6 episodes/s and over, the slower ones' under. Runs shipped later (the study on a
    mastered module, seeds beyond the budget's) leave these numbers as they are."""
    runs = [p for e in ("main", "distractors", "sensor_failure") for p in _runs(e)]
    paces = np.asarray([r.episodes / (r.run_hours * 3600) for r in progress_table(runs)])
    fast, slow = paces[paces >= 6], paces[paces < 6]
    episodes = sum(r.total_episodes for r in get_budget("laptop").runs())
    hours = [round(episodes / (2 * p.mean()) / 3600 / 5) * 5 for p in (fast, slow)]
    notes = re.sub(r"\s+", " ", get_budget("laptop").notes)
    assert f"The {len(paces)} runs of data/laptop's" in notes
    for group in (fast, slow):
        assert f"{group.min():.1f} to {group.max():.1f}" in notes
    assert f"{episodes / 1e6:.2f} M episodes" in notes
    assert f"about {hours[0]} h on 2 cores at the faster pace and {hours[1]} h" in notes
    assert f"about {hours[0]} to {hours[1]} h on 2 cores" in _text(ROOT / "docs" / "scaling.md")
    days = f"{WORDS[round(hours[0] / 24)]} to {WORDS[round(hours[1] / 24)]} days on 2 cores"
    assert days in _text(README) and days in get_budget("laptop").description


def test_c1_the_bins_significant_after_holms_correction(main_bins):
    """Beside the paper's uncorrected count, the count after Holm's correction for the bins'
    tests, and the bins it loses with their p."""
    _, welch = main_bins
    holm = f"in {int(welch['significant_holm'].sum())} of {len(welch)} after Holm's correction"
    lost = welch[welch["significant"] & ~welch["significant_holm"]]
    p = f"p {format_p(lost['p'].min())} to {format_p(lost['p'].max())}"
    text = _text(RESULTS)
    assert holm in text and f"{holm} for the {len(welch)} tests" in text
    assert p in text and "20,000 and 45,000 to 55,000 episodes" in text
    assert list(lost["episodes"]) == [20_000, 45_000, 50_000, 55_000]
    corrected = f"({int(welch['significant_holm'].sum())} of {len(welch)} after Holm's correction)"
    assert corrected in _text(README)


@functools.cache
def _curious_runs(*experiments: str) -> pd.DataFrame:
    """The CURIOUS runs of `experiments` that the report reads from data/laptop, loaded once."""
    import pandas as pd

    table = pd.concat([analysis.load_runs(_whole_seeds(e)) for e in experiments], ignore_index=True)
    return table[table["condition"] == "curious"]


def _shipped_dips(depth: float):
    return analysis.dip_responses(_curious_runs("main", "distractors"), depth)


def test_c3_the_dips_in_the_shipped_runs():
    """C3's reading (b) on the main comparison's and the distractors' CURIOUS runs: what each
    depth found and read, and the sign-flip test of the read dips' excess."""
    text = _text(RESULTS)
    deep = _shipped_dips(analysis.TEST_DEPTH)
    read = deep[deep["status"] == "read"]
    assert read.empty and len(deep) == 1
    only = deep.iloc[0]
    where = f"({only.peak:.2f} to {only.trough:.2f}, detected at {int(only.detect_episode):,})"
    assert where in text
    gap = int(only.detect_episode - only.mastered_episode)
    assert f"{gap:,} episodes after that module's mastery, too soon to read" in text
    shallow = _shipped_dips(0.05)
    counts = shallow["status"].value_counts()
    found = f"{len(shallow)} dips, {counts['read']} read ({counts['before_mastery']} too soon"
    assert found in text
    p_lp, practice = (analysis.dip_test(shallow, c) for c in ("excess_p_lp", "excess_practice"))
    n = p_lp["n_runs"]
    assert f"in {n} runs. Their p_LP rose by {p_lp['mean']:.2f} more" in text
    assert f"(in {p_lp['n_positive']} runs of {n} above 0)" in text
    assert f"by {practice['mean']:.2f} more ({practice['n_positive']} of {n})" in text
    assert (
        f"exact sign-flip p = {format_p(p_lp['p'])} for both" in text and p_lp["p"] == practice["p"]
    )
    assert f"{n} runs allowing {format_p(1 / 2**n)} at the least" in text
    rose = shallow.loc[shallow["status"] == "read", "p_lp_change"]
    assert f"after {int((rose > 0).sum())} of the {len(rose)} read dips it rose" in text
    assert f"(by up to {rose.max():.2f})" in text


def test_c3_each_shipped_long_run_retraces_the_main_run_of_its_seed():
    """Why the dips' test keeps one run per seed (results.md, C3's rules): over the main run's
    episodes, a long run logged what the main comparison's run of its seed logged, every column
    but the clock."""
    import pandas as pd

    from curious.runs.folder_layout import METRICS_FILE

    pairs = [
        (long, DATA / "main" / "curious" / long.name)
        for long in sorted((DATA / "long" / "curious").glob("seed-*"))
        if (DATA / "main" / "curious" / long.name).is_dir()
    ]
    if not pairs:
        pytest.skip("no long run shipped yet")
    assert "had logged over those episodes exactly what the shipped" in _text(RESULTS)
    for long, main in pairs:
        short = pd.read_parquet(main / METRICS_FILE).drop(columns="wall_time")
        extended = pd.read_parquet(long / METRICS_FILE).drop(columns="wall_time")
        extended = extended[extended["episode"] < len(short)].reset_index(drop=True)
        pd.testing.assert_frame_equal(extended, short, obj=f"{long.name}: long against main")


LONG_MODULES = ("reach", "push_cube1", "stack", "cube1_above_cube2")
"""The long runs' table's modules, in the order they were first mastered in seed 0."""


def _machines(run: Path) -> str:
    """The CPUs a run trained on, as the pages name them."""
    return " and ".join(sorted("Intel Xeon" if "Intel" in c else "AMD EPYC" for c in _cpus(run)))


@functools.cache
def _long_read(run: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A long run's table and its `mastery`, read once for the row and the words of the test."""
    table = analysis.load_runs(run)
    return table, analysis.mastery(table)


def _long_run_row(run: Path) -> str:
    """A long run's row of results.md's table "The long runs as they ship", computed from its
    folder: its clock and machines, when each module was first mastered, the module-episodes
    read as mastered, the drops by 0.2, the deepest fall below a peak, the lowest competence
    after episode 100,000 of a module mastered before it, cube 1 above cube 2's lowest over the
    paper's window, and the dips read at 0.1 and 0.05."""
    import pandas as pd

    (row,) = progress_table(run)
    table, read = _long_read(run)
    by_module = read.set_index("module")
    first = by_module["mastered_episode"].reindex(list(LONG_MODULES))
    at = ", ".join("never" if pd.isna(x) else f"{int(x):,}" for x in first)
    deepest = by_module["deepest_fall"].idxmax()
    late = analysis.lowest_competence(table, 100_000, read=read)
    after = "–"
    if len(late):
        low = late.loc[late["low"].idxmin()]
        after = f"{low['low']:.2f} ({_words(low['module'])}, at {int(low['low_episode']):,})"
    window = analysis.lowest_competence(table, *analysis.PAPER_FORGETTING_WINDOW, read=read)
    t3 = window.set_index("module")["low"].get("cube1_above_cube2")
    dips = [
        int((analysis.dip_responses(table, depth)["status"] == "read").sum())
        for depth in (analysis.TEST_DEPTH, 0.05)
    ]
    return (
        f"| `{run.relative_to(DATA).as_posix()}` | {row.episodes:,}, {row.run_hours:.2f} h "
        f"({_machines(run)}) | {at} | {int(by_module['mastered_episodes'].sum()):,} | "
        f"{int(by_module['n_drops'].sum())} | {by_module.at[deepest, 'deepest_fall']:.2f} "
        f"({_words(deepest)}) | {after} | {'–' if t3 is None else f'{t3:.2f}'} | "
        f"{dips[0]}, {dips[1]} |"
    )


def _words(module: str) -> str:
    """A module as the pages' prose names it: "push cube 1", "cube 1 above cube 2", "stack"."""
    return PROSE.get(module, module)


def _long_words_opening(
    run: Path, machine: str, text: str, words: str
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Checks what every long run's reading opens with: its episodes, commit, run-hours and
    machine (in `text`), then its modules in the order it mastered them, each with the episode,
    and its module-episodes read as mastered (in `words`, the run's own paragraph); returns the
    run's table and its `mastery`."""
    (hours,) = [r.run_hours for r in progress_table(run)]
    assert _machines(run) == machine
    assert f"(300,000 episodes, commit 24d01ae, {hours:.2f} run-hours on the {machine})" in text
    table, mastered = _long_read(run)
    first = mastered.set_index("module")["mastered_episode"].sort_values()
    order = [f"{_words(m)} at {int(e):,}" for m, e in first.items()]
    order[0] = order[0].replace(" at ", " at episode ", 1)
    assert f"({', '.join(order)})" in words
    assert f"{int(mastered['mastered_episodes'].sum()):,} module-episodes read as mastered" in words
    return table, mastered


def test_c3_the_long_runs_as_they_ship():
    """C3 on the long runs shipped so far (results.md, "The long runs as they ship", by the
    amended rules): how many, a row per run of its masteries, drops, falls and dips, seed 0's
    reading in words, and the dips' test on the pool as the report reads it, which cannot
    decide before the five are shipped."""
    shipped = sorted((DATA / "long" / "curious").glob("seed-*"))
    if not shipped:
        pytest.skip("no long run shipped yet")
    text = _text(RESULTS)
    assert f"{WORDS[len(shipped)]} run{'s' if len(shipped) > 1 else ''} of five so far" in text, (
        "a long run shipped: read it"
    )
    rows = [_long_run_row(run) for run in shipped]
    missing = [row for row in rows if row not in text]
    assert not missing, "the long runs' table lacks these rows:\n" + "\n".join(missing)
    # seed 0's reading in words
    run = DATA / "long" / "curious" / "seed-0"
    table, mastered = _long_words_opening(run, "Intel Xeon", text, text)
    read = mastered.set_index("module")
    assert analysis.mastery_drops(table).empty and int(read["n_drops"].sum()) == 0
    deepest = read["deepest_fall"].idxmax()
    assert deepest == "cube1_above_cube2"
    assert f"cube 1 above cube 2's {read.at[deepest, 'deepest_fall']:.2f} at 78,889" in text
    # the report's table past the main comparison's end (`analysis.lowest_competence`)
    late = analysis.lowest_competence(table, 100_000, read=mastered)
    assert sorted(late["module"]) == sorted(read.index), "all four mastered before 100,000"
    lowest = late.loc[late["low"].idxmin()]
    low, episode = lowest["low"], int(lowest["low_episode"])
    assert lowest["module"] == "stack" and f"went below {low:.2f} (stack, at {episode:,})" in text
    assert f"(seed 0: after episode 100,000 no mastered module below {low:.2f})" in text
    assert f"(seed 0: after episode 100,000 none below {low:.2f})" in _text(README)
    window = analysis.lowest_competence(table, *analysis.PAPER_FORGETTING_WINDOW, read=mastered)
    t3 = window.set_index("module").at["cube1_above_cube2", "low"]
    assert analysis.PAPER_FORGETTING_WINDOW == (245_000, 255_000)
    assert t3 == 1.0 and "stood at 1.00 from 245,000 to 255,000" in text
    deep = analysis.dip_responses(table, analysis.TEST_DEPTH)
    assert deep["detect_episode"].tolist() == [78_889] and deep["status"].tolist() == [
        "before_mastery"
    ]
    shallow = analysis.dip_responses(table, 0.05)
    past = shallow[shallow["detect_episode"] >= 100_000]
    assert len(past) == 1 and past.iloc[0]["status"] == "read"
    d = past.iloc[0]
    assert f"stack at {int(d.detect_episode):,} ({d.peak:.2f} to {d.trough:.2f})" in text
    assert f"p_LP rose by {d.p_lp_change:.2f} and its share of practice by " in text
    assert f"{d.practice_change:.2f}, against {d.p_lp_change - d.excess_p_lp:.3f} and " in text
    assert f"{d.practice_change - d.excess_practice:.3f}" in text
    # the pool as the report reads it: one run per seed, the long run for the main run of its seed
    pooled = analysis.longest_per_seed(_curious_runs("main", "distractors", "long"))
    runs = pooled["run"].nunique()
    standing = "; ".join(
        f"`long/curious/{r.name}` standing for `main/curious/{r.name}`" for r in shipped
    )
    assert (
        runs == 14
        and f"*The dips' test on the pool as it stands* ({runs} runs, {standing})" in text
    )
    pool = text[text.index("*The dips' test on the pool as it stands*") :]
    for depth in (analysis.TEST_DEPTH, 0.05):
        found = analysis.dip_responses(pooled, depth)
        p_lp, practice = (analysis.dip_test(found, c) for c in ("excess_p_lp", "excess_practice"))
        n = p_lp["n_runs"]
        if n == 0:
            assert f"at {depth:g} no dip read" in pool
            continue
        runs_word = f"{n} run{'s' * (n != 1)}"
        assert f"at {depth:g}, {p_lp['n_dips']} read dips in {runs_word}, p_LP's excess" in pool
        assert f"{p_lp['mean']:+.2f} by run (above 0 in {p_lp['n_positive']} of {n})" in pool
        assert p_lp["p"] == practice["p"]
        assert f"exact sign-flip p = {format_p(p_lp['p'])} for p_LP and practice alike" in pool
    assert len(shipped) < 5 and "This reading decides nothing" in text
    # the summary table's row gives the pool as it stands
    assert (
        f"in {practice['n_positive']} of {n} CURIOUS runs (p = {format_p(practice['p'])} on the "
        "pool as it stands" in text
    )


def test_c3_long_seed_1_in_words():
    """Seed 1's reading in results.md: its one drop by 0.2 (cube 1 above cube 2, near the run's
    end) with its LP, p_LP and practice over its course, and its two dips read at 0.1."""
    run = DATA / "long" / "curious" / "seed-1"
    if not run.is_dir():
        pytest.skip("long seed 1 not shipped yet")
    text = _text(RESULTS)
    words = text[text.index("Seed 1, in words:") : text.index("*The dips' test on the pool")]
    table, mastered = _long_words_opening(run, "AMD EPYC", text, words)
    (drop,) = analysis.mastery_drops(table).itertuples()
    assert drop.module == "cube1_above_cube2"
    assert (
        f"fell from {drop.peak:.2f} (its descent from {drop.start_episode:,}), was read as a drop "
        f"at {drop.drop_episode:,}, reached {drop.trough:.2f} at {drop.trough_episode:,} and was "
        f"back at 0.9 at {drop.recovery_episode:,}, {int(drop.recovery_episodes):,} episodes "
        "after the drop"
    ) in words
    assert (
        f"(mean {drop.lp_before:.2f} before, {drop.lp_after:.2f} over the course, "
        f"{drop.lp_trough:.2f} at the trough)"
    ) in words
    assert drop.p_lp_after < drop.p_lp_before and drop.practice_after < drop.practice_before
    assert (
        f"({drop.p_lp_before:.2f} to {drop.p_lp_after:.2f}, and {drop.practice_before:.0%} to "
        f"{drop.practice_after:.0%})".replace("%", " %")
    ) in words
    window = analysis.lowest_competence(table, *analysis.PAPER_FORGETTING_WINDOW, read=mastered)
    low = window.set_index("module").at["cube1_above_cube2", "low"]
    assert f"255,000 the module stood no lower than {low:.2f}" in words
    deep = analysis.dip_responses(table, analysis.TEST_DEPTH)
    assert deep["status"].tolist() == ["read", "read", "past_end"]
    first, second = (d for d in deep.itertuples() if d.status == "read")
    assert (
        f"at {first.detect_episode:,} ({first.peak:.2f} to {first.trough:.2f}) and "
        f"{second.detect_episode:,} ({second.peak:.2f} to {second.trough:.2f})"
    ) in words
    assert (
        f"its p_LP rose by {first.p_lp_change:.2f} and {second.p_lp_change:.2f} and its share of "
        f"practice by {first.practice_change:.2f} and {second.practice_change:.2f}, against "
        f"{first.p_lp_change - first.excess_p_lp:+.3f} and "
        f"{first.practice_change - first.excess_practice:+.3f}"
    ) in words
    assert f"(detected at {deep.iloc[2].detect_episode:,})" in words
    shallow = analysis.dip_responses(table, 0.05)
    assert (
        f"At 0.05, {WORDS[len(shallow)]}, {WORDS[int((shallow.status == 'read').sum())]}" in words
    )


def test_c5_the_censored_reading_on_the_seeds_shipped():
    """The log-rank test fixed for five seeds a side, on the seeds whole in both conditions, as
    results.md gives it: while seeds 3 and 4 train (its amendment of 2026-12-06), replaced in
    the same words as each seed ships and deciding nothing, as fewer than five a side cannot
    reach alpha; with five a side, over the 252 splits, the test that decides C5 on a mastered
    module, its verdict in results.md and the README."""
    _, budget = _read_by_report()
    n = len(budget.experiments["sensor_failure_mastered"].seeds)
    _, _, by_tests = _mastered_study()
    test = analysis.compare_censored_recoveries(by_tests, "curious", "m-uvfa")
    assert test["n_faster"] == test["n_slower"] == n
    text, readme = _text(RESULTS), _text(README)
    assert f"**The censored reading at {WORDS[n]} seeds a side** (the rules fixed for five" in text
    assert (
        f"Z = {test['z']:.2f}, exact permutation p = {format_p(test['p'])} over the "
        f"{test['splits']} splits of {WORDS[2 * n]} runs into {WORDS[n]} and {WORDS[n]}" in text
    )
    assert f"(normal approximation {format_p(test['p_normal'])})" in text
    assert f"Gehan's check {test['gehan']:.0f}, exact p = {format_p(test['p_gehan'])}" in text
    if n < 5:
        assert 1 / test["splits"] > test["alpha"], "fewer than five a side decides nothing"
        smallest = f"exact p = {format_p(test['p'])}, the smallest {WORDS[n]} a side allow being"
        assert smallest in text
        assert f"the smallest exact p is {format_p(1 / test['splits'])}" in text
        assert (
            f"censored, exact p = {format_p(test['p'])}, deciding nothing under five seeds a side)"
            in readme
        )
        return
    assert test["splits"] == 252 and test["alpha"] == 0.01, test
    verdict = f"{'significant' if test['significant'] else 'not significant'} at alpha 0.01"
    assert f"exact p = {format_p(test['p'])}, {verdict}" in text, verdict
    assert f"exact p = {format_p(test['p'])}, {verdict}" in readme, verdict
