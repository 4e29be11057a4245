"""Recoveries compared with the runs not recovered counted as censored
(`curious.analysis.compare_censored_recoveries`): the log-rank statistic against scipy's, its
exact permutation p on splits counted by hand, Gehan's check, and the runs left apart."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from curious.analysis import compare_censored_recoveries, logrank_z
from curious.analysis.loading import AnalysisError


def _table(rows: list[tuple[str, int, str, float | None, float]]) -> pd.DataFrame:
    """(condition, seed, status, episodes to recover or None, episodes left) per run."""
    return pd.DataFrame(
        {
            "run": [f"{c}/seed-{s}" for c, s, *_ in rows],
            "condition": [c for c, *_ in rows],
            "seed": [s for _, s, *_ in rows],
            "status": [status for _, _, status, *_ in rows],
            "recovered": [r is not None for *_, r, _ in rows],
            "recovery_episodes": [np.nan if r is None else r for *_, r, _ in rows],
            "episodes_left": pd.array([left for *_, left in rows], dtype="Int64"),
        }
    )


def test_the_log_rank_statistic_is_scipys_with_the_faster_condition_positive():
    times = np.array([3.0, 5, 7, 9, 11, 4, 8, 12, 15, 20])
    events = np.array([1, 1, 0, 1, 1, 1, 0, 1, 1, 0], bool)
    first = np.r_[np.ones(5, bool), np.zeros(5, bool)]

    def censored(rows: np.ndarray) -> stats.CensoredData:
        return stats.CensoredData(uncensored=times[rows & events], right=times[rows & ~events])

    reference = stats.logrank(censored(first), censored(~first))
    z = logrank_z(times, events, first)[0]
    assert abs(z) == pytest.approx(abs(reference.statistic))
    assert z > 0  # the first group's events come earlier
    assert logrank_z(times, events, ~first)[0] == pytest.approx(-z)


def test_five_early_recoveries_against_five_censored_runs_take_the_smallest_exact_p():
    rows = [("curious", s, "measured", 1_000.0 * (s + 1), 50_000) for s in range(5)]
    rows += [("m-uvfa", s, "measured", None, 14_000 + s) for s in range(5)]
    result = compare_censored_recoveries(_table(rows), "curious", "m-uvfa")
    assert result["splits"] == math.comb(10, 5) == 252
    assert result["p"] == pytest.approx(1 / 252) and result["significant"]
    assert result["p_gehan"] == pytest.approx(1 / 252) and result["gehan"] == 25
    assert (result["recovered_faster"], result["recovered_slower"]) == (5, 0)
    # a censored run counts at the episodes it had: its time is episodes_left
    runs = result["runs"].set_index("run")
    assert runs.at["m-uvfa/seed-3", "time"] == 14_003 and not runs.at["m-uvfa/seed-3", "event"]
    # the other way round, nothing is significant
    reverse = compare_censored_recoveries(_table(rows), "m-uvfa", "curious")
    assert reverse["p"] == pytest.approx(1.0) and not reverse["significant"]


def test_a_censored_run_that_ended_before_a_recovery_leaves_their_order_open():
    """Gehan's pairs: a run censored at 2,000 against a recovery at 5,000 counts 0, not -1."""
    rows = [("curious", 0, "measured", 5_000.0, 60_000), ("m-uvfa", 0, "measured", None, 2_000)]
    result = compare_censored_recoveries(_table(rows), "curious", "m-uvfa")
    assert result["gehan"] == 0
    rows[1] = ("m-uvfa", 0, "measured", None, 9_000)  # censored after the recovery: +1
    assert compare_censored_recoveries(_table(rows), "curious", "m-uvfa")["gehan"] == 1


def test_runs_with_nothing_to_recover_are_returned_apart():
    rows = [("curious", s, "measured", 9_000.0 + s, 60_000) for s in range(3)]
    rows += [("m-uvfa", 0, "measured", 23_000.0, 30_000), ("m-uvfa", 1, "no_onset", None, 0)]
    result = compare_censored_recoveries(_table(rows), "curious", "m-uvfa")
    assert (result["n_faster"], result["n_slower"]) == (3, 1)
    assert result["left_out"]["run"].tolist() == ["m-uvfa/seed-1"]
    assert result["splits"] == 4


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda t: t.drop(columns="episodes_left"), "lacks episodes_left"),
        (lambda t: pd.concat([t, t]), "each seed must count once"),
        (lambda t: t[t["condition"] == "curious"], "no runs of condition 'm-uvfa'"),
    ],
)
def test_a_table_it_cannot_read_is_named(change, message):
    rows = [("curious", 0, "measured", 5_000.0, 60_000), ("m-uvfa", 0, "measured", None, 9_000)]
    with pytest.raises(AnalysisError, match=message):
        compare_censored_recoveries(change(_table(rows)), "curious", "m-uvfa")
