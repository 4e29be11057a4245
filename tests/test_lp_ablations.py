"""The readings of LP's two uses and of its sign (curious/analysis/lp_ablations.py), by the rules
docs/results.md fixed before their runs."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from curious.analysis.loading import AnalysisError
from curious.analysis.lp_ablations import (
    compare_lp_uses,
    compare_refocus,
    lp_use_readings,
)


def _per_run(means: dict[str, float], seeds=(0, 1, 2), spread: float = 0.01) -> pd.DataFrame:
    offsets = np.linspace(-spread, spread, len(seeds))
    return pd.DataFrame(
        [
            {"condition": c, "seed": s, "value": m + o}
            for c, m in means.items()
            for s, o in zip(seeds, offsets, strict=True)
        ]
    )


@pytest.mark.parametrize(
    ("means", "select", "replay"),
    [
        # selection alone carries CURIOUS's gain; replay alone is M-UVFA's level
        ({"curious": 0.41, "m-uvfa": 0.27, "lp-select": 0.41, "lp-replay": 0.27},
         "does the work", "adds nothing measurable"),
        ({"curious": 0.41, "m-uvfa": 0.27, "lp-select": 0.27, "lp-replay": 0.41},
         "adds nothing measurable", "does the work"),
        ({"curious": 0.60, "m-uvfa": 0.27, "lp-select": 0.41, "lp-replay": 0.41},
         "both are needed", "both are needed"),
        # selection helps alone, yet CURIOUS is better still while replay alone does nothing
        ({"curious": 0.60, "m-uvfa": 0.27, "lp-select": 0.41, "lp-replay": 0.27},
         "undecided", "adds nothing measurable"),
    ],
)  # fmt: skip
def test_the_reading_of_each_use_follows_the_rule_fixed_before_the_runs(means, select, replay):
    tests = compare_lp_uses(_per_run(means))
    assert list(zip(tests["better"], tests["worse"], strict=True)) == [
        ("lp-select", "m-uvfa"),
        ("lp-replay", "m-uvfa"),
        ("curious", "lp-select"),
        ("curious", "lp-replay"),
    ]
    assert (tests["p_holm"] >= tests["p"]).all()
    assert lp_use_readings(tests) == {"module selection": select, "task replay": replay}


def test_the_uses_are_compared_on_the_seeds_all_four_conditions_have():
    per_run = pd.concat(
        [
            _per_run({"curious": 0.4, "m-uvfa": 0.27}, seeds=(0, 1, 2, 3, 4)),
            _per_run({"lp-select": 0.4, "lp-replay": 0.3}, seeds=(0, 1, 2)),
        ]
    )
    tests = compare_lp_uses(per_run)
    assert set(tests["n"]) == {3} and set(tests["seeds"]) == {(0, 1, 2)}


def test_holm_corrects_over_the_four_tests():
    tests = compare_lp_uses(
        _per_run(
            {"curious": 0.41, "m-uvfa": 0.27, "lp-select": 0.35, "lp-replay": 0.30}, spread=0.05
        )
    )
    order = np.argsort(tests["p"].to_numpy())
    assert tests["p_holm"].iloc[order[0]] == pytest.approx(min(1.0, 4 * tests["p"].iloc[order[0]]))


def test_bad_tables_are_clear_errors():
    with pytest.raises(AnalysisError, match="no runs of lp-replay"):
        compare_lp_uses(_per_run({"curious": 0.4, "m-uvfa": 0.3, "lp-select": 0.3}))
    with pytest.raises(AnalysisError, match="share 1 seed"):
        compare_lp_uses(
            pd.concat(
                [
                    _per_run({"curious": 0.4, "m-uvfa": 0.3}, seeds=(0, 1)),
                    _per_run({"lp-select": 0.4, "lp-replay": 0.3}, seeds=(1, 2)),
                ]
            )
        )
    with pytest.raises(AnalysisError, match="lacks value"):
        compare_lp_uses(pd.DataFrame({"condition": ["curious"], "seed": [0]}))
    with pytest.raises(AnalysisError, match="its four tests"):
        lp_use_readings(compare_lp_uses(_per_run(dict.fromkeys(
            ("curious", "m-uvfa", "lp-select", "lp-replay"), 0.3))).iloc[:3])  # fmt: skip


def _recovery(rises: list[float], never_started: int = 0) -> pd.DataFrame:
    rows = [
        {"status": "measured", "p_lp_before": 0.3, "p_lp_after": 0.3 + r,
         "practice_before": 0.3, "practice_after": 0.3 + r / 2}
        for r in rises
    ] + [
        {"status": "never_started", "p_lp_before": np.nan, "p_lp_after": np.nan,
         "practice_before": np.nan, "practice_after": np.nan}
    ] * never_started  # fmt: skip
    return pd.DataFrame(rows)


def test_the_refocus_test_asks_whether_absolute_lp_raises_p_lp_more():
    more = compare_refocus(_recovery([0.2, 0.25, 0.3]), _recovery([0.0, 0.01, 0.02], 1))
    assert more["significant"] and more["t"] > 0 and more["left_out"] == 1
    np.testing.assert_allclose(more["rise_signed"], [0.0, 0.01, 0.02])
    np.testing.assert_allclose(more["practice_absolute"], [0.1, 0.125, 0.15])
    same = compare_refocus(_recovery([0.2, 0.25, 0.3]), _recovery([0.2, 0.26, 0.3]))
    assert not same["significant"]
    with pytest.raises(AnalysisError, match="signed table lacks p_lp_before, p_lp_after"):
        compare_refocus(_recovery([0.1]), pd.DataFrame({"status": ["measured"]}))
