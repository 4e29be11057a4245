"""The replay counts a run keeps (learner.parquet): loaded beside its other tables, shipped with
them, and read as the share of replay spent on distracting modules, the mechanism `lp_uses`
reads beside the share of practice (docs/results.md, "Beyond the paper")."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from test_analysis_synthetic import distractor_modules, write_learner, write_run

from curious import analysis
from curious.analysis import AnalysisError
from curious.runs.folder_layout import LEARNER_FILE
from curious.runs.metrics import LEARNER_STATS
from curious.runs.shipped_folder import LEARNER_DROPPED, shipped_drops

NAMES, ACHIEVABLE = distractor_modules(7)
PER_CYCLE = 8


def _run(root, counts, *, episodes=None, from_episode=0, condition="lp-replay", seed=0):
    """A synthetic run of `distractors_7` whose learner.parquet holds ``counts`` (cycles, 11)."""
    n = episodes or from_episode + PER_CYCLE * len(counts)
    curves = {m: np.full(n, 0.5) for m in NAMES}
    folder = root / condition / f"seed-{seed}"
    write_run(folder, condition=condition, seed=seed, competence=curves, achievable=ACHIEVABLE,
              variant="distractors_7")  # fmt: skip
    write_learner(folder, NAMES, counts, PER_CYCLE, from_episode)
    return folder


def _cycles(n: int, on_distractors: int, on_achievable: int) -> np.ndarray:
    """``n`` cycles, each replaying ``on_distractors`` transitions as every distracting module
    and ``on_achievable`` as every achievable one."""
    row = np.where(ACHIEVABLE, on_achievable, on_distractors)
    return np.tile(row, (n, 1))


def test_the_share_of_replay_on_distracting_modules_is_read_per_bin_and_over_the_run(tmp_path):
    # cycles of 8 episodes: 5 replay only achievable modules, 5 as much on each module
    counts = np.concatenate([_cycles(5, 0, 10), _cycles(5, 10, 10)])
    learner = analysis.load_learner(_run(tmp_path, counts))
    shares = analysis.replay_share(learner, 40)
    assert shares["episodes"].tolist() == [40, 80]
    np.testing.assert_allclose(shares["value"], [0.0, 7 / 11])
    assert shares.attrs["bin_size"] == 40
    assert set(shares["condition"].astype(str)) == {"lp-replay"}
    whole = analysis.replay_share(learner, 80)
    np.testing.assert_allclose(whole["value"], [70 * 5 / (40 * 5 + 110 * 5)])


def test_runs_of_several_module_sets_are_read_each_over_its_own_modules(tmp_path):
    _run(tmp_path / "seven", _cycles(5, 1, 7))  # 7 distracting modules, 4 achievable
    names, achievable = distractor_modules(4)
    folder = tmp_path / "four" / "curious" / "seed-1"
    write_run(folder, condition="curious", seed=1, competence={m: np.full(40, 0.5) for m in names},
              achievable=achievable, variant="distractors_4")  # fmt: skip
    write_learner(folder, names, np.tile(np.where(achievable, 1, 3), (5, 1)), PER_CYCLE)
    shares = analysis.replay_share(analysis.load_learner(tmp_path), 40)
    by_variant = dict(zip(shares["variant"].astype(str), shares["value"], strict=True))
    assert by_variant == pytest.approx({"distractors_7": 7 / 35, "distractors_4": 12 / 16})


def test_a_bin_counts_only_where_the_table_covers_it_whole(tmp_path):
    # the table begins at episode 20 (a run resumed from before it) and ends at 100: of the bins
    # of 40, the first began before it and the third is not complete
    counts = _cycles(10, 10, 10)
    learner = analysis.load_learner(_run(tmp_path, counts, from_episode=20))
    assert learner["from_episode"].eq(20).all() and learner["episode"].max() == 100
    assert analysis.replay_share(learner, 40)["episodes"].tolist() == [80]


def test_cycles_replayed_over_the_whole_goal_give_no_share(tmp_path):
    # her replays no module: its rows are all zero
    counts = np.concatenate([_cycles(5, 0, 0), _cycles(5, 1, 3)])
    learner = analysis.load_learner(_run(tmp_path, counts, condition="her"))
    assert analysis.replay_share(learner, 40)["episodes"].tolist() == [80]


def test_runs_that_kept_no_replay_counts_are_named_not_guessed(tmp_path):
    kept = _run(tmp_path, _cycles(5, 1, 1))
    older = write_run(tmp_path / "curious" / "seed-0", condition="curious", seed=0,
                      competence={m: np.full(40, 0.5) for m in NAMES}, achievable=ACHIEVABLE,
                      variant="distractors_7")  # fmt: skip
    with pytest.raises(AnalysisError, match="has no learner statistics"):
        analysis.load_learner(older)
    assert analysis.has_learner(kept) and not analysis.has_learner(older)
    runs = analysis.load_runs(tmp_path)
    learner = analysis.learner_of(runs)
    assert set(learner["condition"].astype(str)) == {"lp-replay"}
    assert analysis.learner_of(runs[runs["condition"] == "curious"]) is None


def test_a_learner_table_that_disagrees_with_its_config_is_refused(tmp_path):
    folder = _run(tmp_path, _cycles(3, 1, 1))
    table = pq.read_table(folder / LEARNER_FILE)
    pq.write_table(table.rename_columns([c.replace("push_cube9", "lift") for c in
                                         table.column_names]), folder / LEARNER_FILE)  # fmt: skip
    with pytest.raises(AnalysisError, match=r"lacks column.*replay/push_cube9"):
        analysis.load_learner(folder)
    with pytest.raises(AnalysisError, match=r"pass a table from curious\.analysis\.load_learner"):
        analysis.replay_share(analysis.load_runs(folder))


def test_shipping_drops_exactly_the_learner_statistics_and_the_clock():
    assert set(LEARNER_DROPPED) == {*LEARNER_STATS, "wall_time"}


def test_a_shipped_run_carries_its_replay_counts_as_the_run_kept_them(smoke, shipped):
    """Every smoke run that kept a learner.parquet ships it without the statistics nothing reads,
    every replay count as the run wrote it; the share of replay read from either is the same."""
    own = sorted(p.parent for p in (smoke.out / "runs").rglob(LEARNER_FILE))
    assert own, "the smoke runs keep their learner tables"
    for folder in own:
        relative = folder.relative_to(smoke.out / "runs")
        copy = shipped.data / relative / LEARNER_FILE
        assert shipped_drops(pq.read_schema(copy).metadata) == tuple(
            c for c in LEARNER_DROPPED if c in pq.read_schema(folder / LEARNER_FILE).names
        )
        theirs, ours = analysis.load_learner(folder), analysis.load_learner(copy.parent)
        kept = ["from_episode", "episode", *(c for c in ours if c.startswith("replay/"))]
        assert list(ours.columns[-len(kept) :]) == kept
        pd.testing.assert_frame_equal(theirs[kept], ours[kept])


def test_the_smoke_report_gives_each_lp_uses_run_its_share_of_replay(smoke):
    """The `lp_uses` section's per-run table has the share of replay on distracting modules of
    every run, per bin and over the whole run, read from its own learner table."""
    report = (smoke.out / "report.md").read_text()
    section = report.split("transitions replayed as a distracting module, per ", 1)[1]
    width = int(section.split(" ", 1)[0].replace(",", ""))
    rows = [line for line in section.split("\n\n", 1)[0].splitlines()[2:] if line.startswith("|")]
    runs = analysis.load_runs(
        [*(smoke.out / "runs" / "lp_uses").glob("*/seed-*"),
         *(smoke.out / "runs" / "distractors").glob("*@distractors_7/seed-*")]
    )  # fmt: skip
    learner = analysis.learner_of(runs)
    episodes = int(runs["episode"].max()) + 1
    whole = analysis.replay_share(learner, episodes)
    per_bin = analysis.replay_share(learner, width)
    assert len(rows) == len(whole) == runs["run"].nunique() == 4
    cells = {row.split("|")[-2].strip() for row in rows}
    expected = set()
    for run, value in zip(whole["run"], whole["value"], strict=True):
        shares = per_bin.loc[per_bin["run"] == run, "value"]
        assert len(shares) > 0  # a bin narrower than a cycle may hold none of its ends
        expected.add(f"{', '.join(f'{100 * v:.0f} %' for v in shares)} ({100 * value:.0f} %)")
    assert cells == expected
    assert "the replay counts of its learner.parquet" in section


def test_a_learner_table_without_a_cycle_counts_as_none_kept(tmp_path):
    """A run that has not updated yet (or never does) holds an empty table: no replay is read
    from it, and loading it says why."""
    folder = _run(tmp_path, _cycles(0, 1, 1), episodes=40)
    assert not analysis.has_learner(folder)
    assert analysis.learner_of(analysis.load_runs(folder)) is None
    with pytest.raises(AnalysisError, match="has no cycle with updates yet"):
        analysis.load_learner(folder)


def test_the_reports_shares_read_every_run_over_the_same_episodes(tmp_path):
    """In the `lp_uses` table per run, a longer run's shares are read over the bins of the
    shortest run's length, and its share over those episodes, not over its later stretch."""
    from pipelines.report.lp_studies import _per_bin_and_whole

    _run(tmp_path, _cycles(10, 0, 10), seed=0)  # 80 episodes, nothing on the distractors
    _run(tmp_path, np.concatenate([_cycles(10, 0, 10), _cycles(10, 10, 0)]), seed=1)
    cells = _per_bin_and_whole(analysis.replay_share, analysis.load_learner(tmp_path), 40, 80)
    assert sorted(cells.values()) == ["0 %, 0 % (0 %)", "0 %, 0 % (0 %)"]
