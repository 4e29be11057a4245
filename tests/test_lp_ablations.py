"""The readings of LP's two uses and of its sign (curious/analysis/lp_ablations.py), by the rules
docs/results.md fixed before their runs."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from curious import analysis
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


@pytest.fixture(scope="module")
def beyond(tmp_path_factory):
    """Made-up runs of both questions: the four conditions on 7 distracting modules, and the
    sensory failure under absolute and signed LP."""
    from test_analysis_synthetic import (
        distractor_modules,
        study_curves,
        write_learner,
        write_perturbation_study,
        write_run,
    )

    from curious import analysis

    root = tmp_path_factory.mktemp("beyond")
    names, achievable = distractor_modules(7)
    for i, c in enumerate(("curious", "m-uvfa", "lp-select", "lp-replay")):
        for s in (0, 1, 2):
            curves = study_curves("curious", s, 300, names, achievable)
            for m in names[:4]:
                curves[m] = np.clip(curves[m] * (1 - 0.1 * i), 0.0, 1.0)
            folder = root / "uses" / c / f"seed-{s}"
            write_run(folder, condition=c, seed=s, competence=curves, achievable=achievable,
                      variant="distractors_7", tests_per_epoch=8)  # fmt: skip
            if c.startswith("lp-"):  # the shipped CURIOUS and M-UVFA runs kept no replay counts
                counts = np.where(achievable, 30, 10 * (i - 1))  # lp-select 10, lp-replay 20
                write_learner(folder, names, np.tile(counts, (30, 1)), per_cycle=10)
    write_perturbation_study(
        root / "absolute", perturbation=300, n_episodes=900, recovery_tau={"curious": 80.0},
        tests_per_epoch=40,
    )  # fmt: skip
    write_perturbation_study(
        root / "signed", perturbation=300, n_episodes=900, recovery_tau={"curious": 200.0},
        tests_per_epoch=40,
    )  # fmt: skip
    return {name: (analysis.load_runs(root / name), analysis.load_tests(root / name))
            for name in ("uses", "absolute", "signed")}  # fmt: skip


def test_the_lp_uses_figure_sets_the_four_conditions_side_by_side(beyond, tmp_path):
    from curious.analysis.figures.beyond_paper import LP_USE_ORDER, lp_uses
    from curious.watching.palette import condition_color

    runs, tests = beyond["uses"]
    fig = lp_uses(runs, tests, out_dir=tmp_path, learner=analysis.learner_of(runs))
    assert (tmp_path / "lp_uses.png").stat().st_size > 0
    left, middle, right = fig.axes[:3]
    assert "test success" in middle.get_ylabel()
    assert [t.get_text() for t in left.get_xticklabels()] == [
        "M-UVFA", "LP-replay", "LP-select", "CURIOUS"
    ]  # fmt: skip
    assert len(left.collections) >= len(LP_USE_ORDER)  # a dot per run, per condition
    assert "distracting module" in right.get_ylabel()
    dashed = [line for line in right.get_lines() if line.get_linestyle() == "--"]
    # the share of replay where the runs kept their counts: 7 x 10 of 7 x 10 + 4 x 30, and 7 x 20
    # of 7 x 20 + 4 x 30 in every bin
    first = {line.get_color(): line.get_ydata()[0] for line in dashed}
    assert first == pytest.approx(
        {condition_color("lp-select"): 70 / 190, condition_color("lp-replay"): 140 / 260}
    )
    text = fig.get_supxlabel()
    assert "neither is in the paper" in text and "3 seeds (0–2)" in text
    assert "(M-UVFA, CURIOUS: none drawn, their runs' replay counts covering" in text
    without = lp_uses(runs, tests)
    assert not [line for line in without.axes[2].get_lines() if line.get_linestyle() == "--"]
    assert "no run's replay counts cover a whole bin" in without.get_supxlabel()


def test_the_signed_lp_figure_draws_both_measures_as_two_conditions(beyond, tmp_path):
    from curious.analysis.figures.beyond_paper import SIGNED_LP, signed_lp
    from curious.watching.palette import condition_label

    (absolute, tests_a), (signed, tests_s) = beyond["absolute"], beyond["signed"]
    fig, per_run = signed_lp(absolute, signed, tests_a, tests_s, out_dir=tmp_path)
    assert (tmp_path / "signed_lp.png").stat().st_size > 0
    assert set(per_run["condition"]) == {"curious", SIGNED_LP}
    assert condition_label(SIGNED_LP) == "CURIOUS, signed LP"
    legend = " ".join(
        t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()
    )
    assert "signed LP" in legend
    with pytest.raises(AnalysisError, match="of both measures' runs, or of neither"):
        signed_lp(absolute, signed, tests_a, None)


@pytest.mark.parametrize(
    ("absolute", "signed", "reading"),
    [
        ([0.2, 0.25, 0.3], [0.0, 0.01, 0.02], "the absolute value matters"),
        ([0.2, 0.25, 0.3], [0.2, 0.27, 0.31], "the refocus comes from relearning progress"),
        # not significant, yet signed LP rose less: too few seeds to say
        ([0.1, 0.3, 0.5], [0.0, 0.2, 0.45], "undecided"),
        ([0.2], [0.1], "undecided"),  # one run a side: no test
    ],
)
def test_the_reading_of_lps_sign_follows_the_rule_fixed_before_the_runs(absolute, signed, reading):
    from curious.analysis.lp_ablations import signed_lp_reading

    assert signed_lp_reading(compare_refocus(_recovery(absolute), _recovery(signed))) == reading


def test_signed_lp_is_read_against_absolute_lp_on_the_seeds_both_have():
    """Absolute LP's runs of seeds 0-4 against signed LP's of seeds 0-2 (and a seed 7 absolute
    LP lacks): both measures on seeds 0-2 only."""
    from curious.analysis.lp_ablations import SIGNED_LP, signed_beside_absolute

    absolute = pd.DataFrame({"condition": ["curious"] * 5 + ["m-uvfa"], "seed": [0, 1, 2, 3, 4, 0]})
    signed = pd.DataFrame({"condition": "curious", "seed": [0, 1, 2, 7]})
    both = signed_beside_absolute(signed, absolute)
    assert both.groupby("condition")["seed"].apply(sorted).to_dict() == {
        "curious": [0, 1, 2],
        SIGNED_LP: [0, 1, 2],
    }
    assert signed_beside_absolute(signed, None)["seed"].tolist() == [0, 1, 2, 7]
    with pytest.raises(AnalysisError, match="share no seed"):
        signed_beside_absolute(signed.assign(seed=[5, 6, 8, 9]), absolute)


def test_the_smoke_report_reads_lps_sign_by_the_rule_fixed_before_the_runs(smoke):
    """The `signed_lp` section gives the reading fixed before the runs after its refocus test:
    one run a side at `smoke`, so no test, and the reading is undecided."""
    report = (smoke.out / "report.md").read_text()
    section = report[report.index("One-tailed Welch's t-test that absolute LP raises") :]
    refocus, reading = section.split("\n\n")[:2]
    assert "not tested (fewer than two runs a side, or no variance)" in refocus
    assert reading == "The reading fixed before the runs: undecided."
