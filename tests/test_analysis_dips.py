"""Dips of mastered modules (`curious.analysis.dips`) on made-up competence curves: where the rule
puts each dip at both depths, which are read, the response and its excess over matched windows
computed as the rule says, and the exact sign-flip test."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_analysis_synthetic import write_run

from curious.analysis import (
    DIP_COLUMNS,
    dip_responses,
    dip_test,
    load_runs,
    longest_per_seed,
    mastery,
    mastery_dips,
    shorter_of_seed,
)
from curious.analysis.loading import AnalysisError

N = 40_000
TOP = 0.97
WINDOW = 2_000


def _reach() -> np.ndarray:
    """Mastered at 0.97 after about 5,000 episodes; a dip of 0.12 at 6,000 (too soon after the
    mastery to read), one of 0.12 over 20,000-24,000, one of 0.06 over 30,000-31,000 (a dip at
    0.05 only), one of 0.17 from 39,000 to the end (too late to read)."""
    t = np.arange(N, dtype=np.float64)
    curve = TOP / (1 + np.exp(-(t - 3_500) / 200))
    curve[5_000:] = TOP
    curve[6_000:6_500] = 0.85
    curve[20_000:24_000] = 0.85
    curve[30_000:31_000] = 0.91
    curve[39_000:] = 0.80
    return curve


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("dips")
    unmastered = np.full(N, 0.8)
    unmastered[10_000:12_000] = 0.4
    curves = {"reach": _reach(), "push_cube1": np.full(N, 0.95), "cube1_above_cube2": unmastered}
    write_run(root / "run", condition="curious", seed=0, competence=curves, achievable=[True] * 3)
    return load_runs(root)


def test_each_dip_is_found_where_the_rule_puts_it_at_both_depths(runs):
    deep = dip_responses(runs, depth=0.1, window=WINDOW)
    assert list(deep.columns) == list(DIP_COLUMNS)
    assert deep["module"].tolist() == ["reach"] * 3  # a flat module and an unmastered one: none
    assert deep["detect_episode"].tolist() == [6_000, 20_000, 39_000]
    assert deep["trough"].round(2).tolist() == [0.85, 0.85, 0.80]
    assert deep["peak"].round(2).tolist() == [TOP] * 3
    # ends back within half the depth of the peak; the last dip never does
    assert deep["end_episode"].tolist()[:2] == [6_500, 24_000]
    assert pd.isna(deep["end_episode"].iat[2])
    assert deep["status"].tolist() == ["before_mastery", "read", "past_end"]
    mastered = int(mastery(runs).set_index("module").at["reach", "mastered_episode"])
    assert (deep["mastered_episode"] == mastered).all() and 6_000 - WINDOW < mastered < 6_000
    shallow = mastery_dips(runs, depth=0.05)
    assert shallow["detect_episode"].tolist() == [6_000, 20_000, 30_000, 39_000]


def test_the_response_and_its_excess_are_the_window_means_the_rule_names(runs):
    table = runs.sort_values("episode")
    episodes = table["episode"].to_numpy()
    p_lp = table["p_lp/reach"].to_numpy(np.float64)
    practised = (table["module"].astype(str) == "reach").to_numpy(np.float64)

    def change(values: np.ndarray, at: int) -> float:
        before = values[(episodes >= at - WINDOW) & (episodes < at)].mean()
        return values[(episodes >= at) & (episodes < at + WINDOW)].mean() - before

    deep = dip_responses(runs, depth=0.1, window=WINDOW).set_index("detect_episode")
    read = deep.loc[20_000]
    assert read["p_lp_change"] == pytest.approx(change(p_lp, 20_000), abs=1e-6)
    assert read["practice_change"] == pytest.approx(change(practised, 20_000), abs=1e-9)
    # matched windows: every WINDOW-th episode from the mastery whose two windows meet no dip's
    # exclusion (6,000: 4,000-8,000; 20,000: 18,000-24,000; 39,000: 37,000 to past the end)
    mastered = int(read["mastered_episode"])
    excluded = [(4_000, 8_000), (18_000, 24_000), (37_000, 41_000)]
    centres = [
        c
        for c in range(mastered + WINDOW, N - WINDOW + 1, WINDOW)
        if all(c + WINDOW <= lo or c - WINDOW >= hi for lo, hi in excluded)
    ]
    assert read["n_matched"] == len(centres) > 5
    matched = np.mean([change(p_lp, c) for c in centres])
    assert read["matched_p_lp_change"] == pytest.approx(matched, abs=1e-6)
    assert read["excess_p_lp"] == pytest.approx(change(p_lp, 20_000) - matched, abs=1e-6)
    # the LP spike of the fall lies in the window after the detection: p_LP up
    assert read["p_lp_change"] > 0 and read["excess_p_lp"] > 0
    # dips not read have no response
    assert deep.loc[[6_000, 39_000], ["p_lp_change", "excess_p_lp"]].isna().all().all()


def test_the_sign_flip_test_counts_every_flip_with_the_run_as_the_unit():
    def table(values: dict[str, list[float]]) -> pd.DataFrame:
        rows = [(run, v) for run, vs in values.items() for v in vs]
        return pd.DataFrame(rows, columns=["run", "excess_p_lp"]).assign(excess_practice=np.nan)

    # three runs all above 0: only the observed signs reach the observed mean, 1 of 8
    result = dip_test(table({"a": [1.0, 3.0], "b": [2.0], "c": [3.0]}))
    assert (result["n_runs"], result["n_dips"], result["n_positive"]) == (3, 4, 3)
    assert result["mean"] == pytest.approx(7 / 3) and result["p"] == pytest.approx(1 / 8)
    assert not result["significant"]  # no test of 3 runs reaches 0.01
    # +1 and -1: the mean 0 is reached by 3 of the 4 flips
    assert dip_test(table({"a": [1.0], "b": [-1.0]}))["p"] == pytest.approx(3 / 4)
    # seven runs above 0: 1 / 128 < 0.01
    seven = dip_test(table({str(i): [0.1 + i] for i in range(7)}))
    assert seven["p"] == pytest.approx(1 / 128) and seven["significant"]
    empty = dip_test(table({}))
    assert empty["n_runs"] == 0 and np.isnan(empty["p"]) and not empty["significant"]
    with pytest.raises(AnalysisError, match="excess_p_lp or excess_practice"):
        dip_test(table({"a": [1.0]}), column="p_lp_change")


def test_a_pool_keeps_one_run_per_condition_variant_and_seed_the_longest(tmp_path):
    """A `long` run retraces the `main` run of its seed: the shorter is left out of a pool whose
    unit is a run; another seed, condition or variant is another unit; of two runs of one
    length, the first by name stays."""
    curve = {"reach": np.linspace(0.0, 1.0, 3_000)}

    def run(name: str, n: int, **kw) -> None:
        kw = {"condition": "curious", "seed": 0, **kw}
        short = {m: c[:n] for m, c in curve.items()}
        write_run(tmp_path / name, competence=short, achievable=[True], **kw)

    run("long/curious/seed-0", 3_000)
    run("main/curious/seed-0", 1_000)
    run("main/curious/seed-1", 1_000, seed=1)
    run("main/m-uvfa/seed-0", 1_000, condition="m-uvfa")
    run("distractors/curious@distractors_4/seed-0", 1_000, variant="distractors_4")
    run("twin-a/curious/seed-2", 1_000, seed=2)
    run("twin-b/curious/seed-2", 1_000, seed=2)
    table = load_runs(tmp_path)
    left = shorter_of_seed(table)
    assert [Path(r).relative_to(tmp_path).as_posix() for r in left["run"]] == [
        "main/curious/seed-0",
        "twin-b/curious/seed-2",
    ]
    assert [Path(r).parts[-3] for r in left["kept"]] == ["long", "twin-a"]
    assert left["episodes"].tolist() == [1_000, 1_000]
    assert left["kept_episodes"].tolist() == [3_000, 1_000]
    kept = longest_per_seed(table)
    assert kept["run"].nunique() == 5
    assert not kept["run"].astype(str).isin(left["run"]).any()
    assert len(kept) == len(table) - 2_000  # every row of the runs kept, none of the others


@pytest.mark.parametrize(
    "kwargs, message",
    [({"depth": 0.0}, "depth must be in"), ({"window": 0}, "window must be"),
     ({"window": 2.5}, "window must be")],
)  # fmt: skip
def test_bad_arguments_are_named(runs, kwargs, message):
    with pytest.raises(ValueError, match=message):
        dip_responses(runs, **kwargs)
