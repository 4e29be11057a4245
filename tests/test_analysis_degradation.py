"""C4's degradation test: which condition loses less competence from the fewest to the most
distracting modules (`analysis.compare_degradation`)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from curious import analysis
from curious.analysis.loading import AnalysisError


def finals(groups: dict[tuple[str, int], list[float]]) -> pd.DataFrame:
    """Rows as `final_competence` gives them: one per run."""
    rows = [
        {"condition": c, "n_distractors": n, "value": v}
        for (c, n), values in groups.items()
        for v in values
    ]
    return pd.DataFrame(rows)


SPREAD = [-0.02, 0.0, 0.02]


def around(mean: float) -> list[float]:
    return [mean + d for d in SPREAD]


def test_losses_and_the_contrast_equal_the_pooled_test_when_the_groups_are_alike():
    """Four groups of 3 seeds with one variance: Welch-Satterthwaite gives the pooled contrast's
    4 (n - 1) degrees of freedom and t = D / sqrt(4 s^2 / n)."""
    final = finals(
        {
            ("curious", 0): around(0.60), ("curious", 4): around(0.55),
            ("curious", 7): around(0.50), ("m-uvfa", 0): around(0.50), ("m-uvfa", 7): around(0.20),
        }
    )  # fmt: skip
    out = analysis.compare_degradation(final, "curious", "m-uvfa")
    assert (out["fewest"], out["most"]) == (0, 7)
    assert out["loss_curious"] == pytest.approx(0.10)
    assert out["loss_m-uvfa"] == pytest.approx(0.30)
    assert out["difference"] == pytest.approx(-0.20)
    var = np.var(SPREAD, ddof=1)
    assert out["se"] == pytest.approx(np.sqrt(4 * var / 3))
    assert out["df"] == pytest.approx(8.0)
    assert out["t"] == pytest.approx(-0.20 / np.sqrt(4 * var / 3))
    assert out["p"] == pytest.approx(stats.t.cdf(out["t"], 8))
    assert out["p"] < 0.01
    assert out["n_curious_0"] == out["n_m-uvfa_7"] == 3


@pytest.mark.parametrize(
    ("curious_at_7", "loses_less"), [(0.50, True), (0.10, False)], ids=["less", "more"]
)
def test_the_p_value_is_one_tailed_towards_the_better_condition_losing_less(
    curious_at_7: float, loses_less: bool
):
    final = finals(
        {
            ("curious", 0): around(0.60), ("curious", 7): around(curious_at_7),
            ("m-uvfa", 0): [0.50, 0.53, 0.49], ("m-uvfa", 7): [0.30, 0.28, 0.33],
        }
    )  # fmt: skip
    p = analysis.compare_degradation(final, "curious", "m-uvfa")["p"]
    assert (p < 0.5) == loses_less


def test_a_group_of_one_seed_gives_the_losses_but_no_test():
    final = finals(
        {
            ("curious", 0): [0.6], ("curious", 7): around(0.5),
            ("m-uvfa", 0): around(0.5), ("m-uvfa", 7): around(0.2),
        }
    )  # fmt: skip
    out = analysis.compare_degradation(final, "curious", "m-uvfa")
    assert out["difference"] == pytest.approx(-0.2)
    assert np.isnan(out["p"]) and np.isnan(out["t"]) and np.isnan(out["df"])


@pytest.mark.parametrize(
    ("groups", "message"),
    [
        ({("curious", 7): [0.5, 0.4], ("m-uvfa", 7): [0.2, 0.3]}, "two numbers of distracting"),
        (
            {("curious", 0): [0.5, 0.4], ("curious", 7): [0.5, 0.4], ("m-uvfa", 7): [0.2, 0.3]},
            "no runs of condition 'm-uvfa' with 0 distractors",
        ),
    ],
    ids=["one setting", "a missing group"],
)
def test_what_cannot_be_compared_is_named(groups: dict, message: str):
    with pytest.raises(AnalysisError, match=message):
        analysis.compare_degradation(finals(groups), "curious", "m-uvfa")


def test_distractor_share_counts_the_episodes_practising_a_module_no_run_can_learn(tmp_path):
    """Per run and complete bin: the share of its episodes whose module is not achievable
    (counted here row by row from metrics.parquet), none without distractors."""
    from tests.test_analysis_synthetic import write_distractor_study

    write_distractor_study(tmp_path, counts=(0, 4), seeds=(0,), n_episodes=250)
    runs = analysis.load_runs(tmp_path)
    share = analysis.distractor_share(runs, bin_size=100)
    assert share.attrs["bin_size"] == 100
    for run, rows in runs.groupby("run", observed=True):
        achievable = str(rows["achievable_modules"].iat[0]).split(",")
        mine = share[share["run"] == run]
        assert list(mine["episodes"]) == [100, 200]  # the third bin is not complete
        for end, value in zip(mine["episodes"], mine["value"], strict=True):
            practised = rows.loc[rows["episode"] < end].tail(100)["module"].astype(str)
            assert value == pytest.approx((~practised.isin(achievable)).mean())
        assert (mine["value"] > 0).all() == (rows["n_distractors"].iat[0] > 0)
