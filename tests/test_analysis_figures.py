"""The paper's figures (curious.analysis.figures) from synthetic run folders."""

from __future__ import annotations

import hashlib
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure
from test_analysis_synthetic import (
    write_distractor_study,
    write_perturbation_study,
    write_study,
)

from curious import analysis
from curious.analysis.style import format_episodes, seeds_text
from curious.watching import palette


@pytest.fixture(scope="module")
def studies(tmp_path_factory):
    """Loaded tables of the three made-up studies (main comparison, sensory failure,
    distractors); built once for this module."""
    root = tmp_path_factory.mktemp("studies")
    write_study(root / "main", seeds=(0, 1, 2), n_episodes=600)
    write_perturbation_study(root / "failure", perturbation=300, n_episodes=900, tests_per_epoch=40)
    write_distractor_study(
        root / "distractors", counts=(0, 4, 7), seeds=(0, 1), n_episodes=300, tests_per_epoch=8
    )
    return {
        "main": analysis.load_runs(root / "main"),
        "tests": analysis.load_tests(root / "main"),
        "failure": analysis.load_runs(root / "failure"),
        "failure_tests": analysis.load_tests(root / "failure"),
        "distractors": analysis.load_runs(root / "distractors"),
        "distractors_tests": analysis.load_tests(root / "distractors"),
    }


def _build(name, studies, out_dir=None, note=None):
    """Builds figure ``name``; returns the Figure."""
    kw = {"out_dir": out_dir, "note": note}
    if name == "fig2a":
        return analysis.fig2a(studies["tests"], **kw)
    if name == "fig2b":
        return analysis.fig2b(studies["main"], **kw)
    if name == "fig2c":
        return analysis.fig2c(studies["main"], seed=1, **kw)
    if name == "table1":
        return analysis.table1(studies["main"], **kw)
    if name == "sensor_failure":
        return analysis.sensor_failure(studies["failure"], **kw)[0]
    if name == "distractors":
        tests = studies["distractors_tests"]
        return analysis.distractors(studies["distractors"], tests=tests, **kw)
    if name == "long_runs":
        table = studies["main"]
        return analysis.long_runs(table, dips=analysis.mastery_dips(table, 0.05), **kw)
    raise AssertionError(name)


FIGURES = ("fig2a", "fig2b", "fig2c", "table1", "sensor_failure", "distractors", "long_runs")


def _caption(fig: Figure) -> str:
    return fig._supxlabel.get_text().replace("\n", " ")


@pytest.mark.parametrize("name", FIGURES)
def test_every_figure_writes_png_and_svg_and_rebuilds_byte_identical(name, studies, tmp_path):
    first = _build(name, studies, tmp_path / "a")
    _build(name, studies, tmp_path / "b")
    for ext in ("png", "svg"):
        a = (tmp_path / "a" / f"{name}.{ext}").read_bytes()
        b = (tmp_path / "b" / f"{name}.{ext}").read_bytes()
        assert len(a) > 10_000
        assert hashlib.sha256(a).digest() == hashlib.sha256(b).digest(), f"{name}.{ext} differs"
    assert (tmp_path / "a" / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    svg = ET.fromstring((tmp_path / "a" / f"{name}.svg").read_bytes())
    assert svg.tag.endswith("svg")
    text = (tmp_path / "a" / f"{name}.svg").read_text()
    assert "dc:date" not in text and "Matplotlib v" not in text
    assert not list((tmp_path / "a").glob(".*partial"))
    # Captions say seeds and budget; x axes count episodes (the distractors figure counts
    # distracting modules).
    caption = _caption(first)
    assert "seed" in caption and "episodes" in caption
    assert not re.search(r"seeds \d+ seed", caption), caption
    assert not re.search(r"\. [a-z]", caption), f"a sentence starts in lower case: {caption}"
    assert "preset synthetic" in caption
    labels = {ax.get_xlabel() for ax in first.axes if ax.get_xlabel()}
    if name == "distractors":
        assert labels == {"distracting modules"}
    elif name == "sensor_failure":
        assert labels == {"episodes since the sensory failure"}
    else:
        assert labels == {"episodes"}


@pytest.mark.parametrize("name", FIGURES)
def test_every_caption_ends_with_the_note_it_is_given(name, studies):
    plain = _caption(_build(name, studies))
    noted = _caption(_build(name, studies, note="Budget quick (small)."))
    assert "Budget quick" not in plain
    assert noted.startswith(plain) and noted.endswith("Budget quick (small).")


def test_fig2a_dots_are_the_significant_points_of_the_test_rollouts(studies):
    points = analysis.binned_success(studies["tests"])
    test = analysis.welch_per_bin(points, "curious", "mg-te")
    assert 0 < test["significant"].sum() < len(test)  # the made-up data leave both kinds
    fig = analysis.fig2a(studies["tests"])
    (dots,) = [line for line in fig.axes[0].lines if line.get_label().startswith("p < 0.01")]
    np.testing.assert_array_equal(dots.get_xdata(), test.loc[test["significant"], "episodes"])
    # one point per comparison bin (600 episodes: bins of 20), at the bin's end
    assert points.attrs["bin_size"] == analysis.comparison_bin_size(600) == 20
    assert sorted(points["episodes"].unique()) == list(range(20, 601, 20))
    curve = next(line for line in fig.axes[0].lines if line.get_label() == "CURIOUS")
    mean = analysis.across_seeds(points).query("condition == 'curious'")
    np.testing.assert_allclose(curve.get_ydata(), mean["mean"])
    caption = _caption(fig)
    assert "3 seeds (0–2)" in caption and "600 episodes per run" in caption
    assert "test success" in caption.lower() and "each 20-episode bin" in caption
    n = int(test["significant"].sum())
    assert f"significant in {n} of {len(test)} bins" in caption
    assert f"({n} of {len(test)} bins)" in dots.get_label()


def test_fig2a_draws_the_comparison_bins_with_every_seed_and_the_counts_the_report_quotes(
    studies,
):
    """Fig. 2a is drawn from `main_comparison`, the numbers the report quotes: its points are
    the bins of the Welch tests, each seed has its own thin line, and the caption counts the
    significant bins as `main_comparison` does."""
    tests = studies["tests"]
    numbers = analysis.main_comparison(tests, "curious", "mg-te", bin_size=100)
    fig = analysis.fig2a(tests, bin_size=100)
    lines = fig.axes[0].lines
    seeds = [line for line in lines if line.get_label() == "_seed"]
    assert len(seeds) == 9  # 3 conditions x 3 seeds
    assert all(list(line.get_xdata()) == list(range(100, 601, 100)) for line in seeds)
    (dots,) = [line for line in lines if line.get_label().startswith("p < 0.01")]
    welch = numbers["welch"]
    np.testing.assert_array_equal(dots.get_xdata(), welch.loc[welch["significant"], "episodes"])
    assert numbers["n_bins"] == 6 and numbers["bin_size"] == 100
    text = f"significant in {numbers['n_significant']} of 6 bins"
    assert text in _caption(fig)
    final = numbers["final_summary"].set_index("condition")
    assert set(final.index) == {"curious", "mg-te", "her"} and (final["n"] == 3).all()
    assert (final["episodes"] == 600).all()


def test_fig2a_from_the_competence_table_or_without_test_rollouts_is_refused(studies, tmp_path):
    with pytest.raises(analysis.AnalysisError, match=r"from curious\.analysis\.load_tests"):
        analysis.fig2a(studies["main"])
    write_study(tmp_path, conditions=("curious",), seeds=(0,), n_episodes=40, tests_per_epoch=0)
    with pytest.raises(analysis.AnalysisError, match="has no test rollouts"):
        analysis.load_tests(tmp_path)


def test_fig2a_draws_no_dots_between_equal_conditions(studies):
    df = studies["tests"]
    # The mg-te runs against a relabelled copy of themselves: identical numbers, no dot.
    mg_te = df[df["condition"] == "mg-te"]
    twin = mg_te.assign(condition="curious", run=mg_te["run"].astype(str) + "-twin")
    equal = pd.concat([mg_te.astype({"condition": str, "run": str}), twin], ignore_index=True)
    points = analysis.epoch_success(equal)
    assert not analysis.welch_per_bin(points, "curious", "mg-te")["significant"].any()
    fig = analysis.fig2a(equal)
    (dots,) = [line for line in fig.axes[0].lines if line.get_label().startswith("p < 0.01")]
    assert len(dots.get_xdata()) == 0


def test_fig2a_without_a_compared_condition_says_so(studies):
    only = studies["tests"][studies["tests"]["condition"] != "mg-te"]
    with pytest.raises(analysis.AnalysisError, match="pass compare=None"):
        analysis.fig2a(only)
    fig = analysis.fig2a(only, compare=None)
    assert not [line for line in fig.axes[0].lines if line.get_label().startswith("p <")]


def test_module_figures_use_the_palette(studies):
    fig = analysis.fig2b(studies["main"], seed=2)
    lines = {line.get_label(): line for line in fig.axes[0].lines}
    assert lines["T1 reach"].get_color() == palette.module_color("reach")
    assert lines["T5 push cube 3 (distractor)"].get_linestyle() == "--"
    assert "seed 2" in fig._suptitle.get_text()
    with pytest.raises(analysis.AnalysisError, match="has no seed 9"):
        analysis.fig2b(studies["main"], seed=9)


def test_lp_axes_fit_the_curves_they_draw(studies):
    """Fig. 2c's and Table 1's LP axes end just above the highest LP drawn, not at a spike
    between two samples."""
    fig = analysis.fig2c(studies["main"], seed=1)
    ax = fig.axes[0]
    drawn = max(float(np.nanmax(line.get_ydata())) for line in ax.lines)
    assert ax.get_ylim()[1] == pytest.approx(max(0.05, drawn * 1.08))
    table = analysis.table1(studies["main"])
    right = table.axes[1::2]
    drawn = max(float(np.nanmax(line.get_ydata())) for ax in right for line in ax.lines)
    assert all(ax.get_ylim()[1] == pytest.approx(max(0.05, drawn * 1.08)) for ax in right)
    # a spike between two samples (bins of 2 episodes sample episodes 1, 3, 5, ...) is not drawn
    # and does not stretch the axis
    from curious.analysis.figures.parts import drawn_ceiling, lp_ceiling

    main = studies["main"]
    run = main[main["run"] == main["run"].iat[0]].sort_values("episode").copy()
    run.loc[run["episode"] == 4, "lp/reach"] = 5.0
    assert lp_ceiling(run) == pytest.approx(5.0)
    assert drawn_ceiling(run, "lp/", 2) < 1.0


def test_table1_has_a_row_per_seed(studies):
    fig = analysis.table1(studies["main"])
    assert len(fig.axes) == 2 * 3
    assert [ax.get_ylabel() for ax in fig.axes[::2]] == [f"seed {s}\ncompetence" for s in range(3)]


def test_the_sensor_failure_figure_follows_the_perturbed_module_and_states_recovery_times(studies):
    fig, per_run = analysis.sensor_failure(studies["failure"], fraction=0.9)
    assert fig.axes[0].get_ylabel() == "competence of push cube 3"  # the variant's module
    assert set(per_run["module"]) == {"push_cube3"}
    assert (per_run["status"] == "measured").all() and per_run["recovered"].all()
    assert (per_run["perturbation_episode"] == 300).all()
    assert set(per_run["onset_source"]) == {"metrics"}  # read from the sensor_failure column
    summary = analysis.recovery_summary(per_run).set_index("condition")
    # The made-up m-uvfa runs recover with a longer time constant than the curious ones.
    assert (
        summary.loc["curious", "mean_recovery_episodes"]
        < summary.loc["m-uvfa", "mean_recovery_episodes"]
    )
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    mean = summary.loc["curious", "mean_recovery_episodes"]
    assert any(
        f"regained after {mean:,.0f}" in label and "(3/3 seeds)" in label for label in labels
    )
    assert "episode 300 in every run" in _caption(fig)
    # x counts episodes since the failure: the curves cross 0 where the failure started
    line = fig.axes[0].lines[0]
    assert line.get_xdata().min() < 0 < line.get_xdata().max()


def test_the_sensor_failure_figure_with_test_rollouts_draws_the_primary_measure_above(studies):
    """Given the runs' test rollouts (the study on a mastered module), a panel above the others
    draws push cube 3's pooled test success, aligned on the onset, with a circle where each run
    came back by `recovery_by_tests`; each run's legend entry gives that recovery first."""
    fig, per_run = analysis.sensor_failure(studies["failure"], tests=studies["failure_tests"])
    tested, top, bottom = fig.axes[:3]
    assert tested.get_ylabel() == "test success of push cube 3"
    assert top.get_ylabel() == "competence of push cube 3"
    by_tests = analysis.recovery_by_tests(
        studies["failure_tests"], per_run.set_index("run")["perturbation_episode"]
    )
    assert by_tests["recovered"].all()
    circles = sorted(line.get_xdata()[0] for line in tested.lines if line.get_marker() == "o")
    assert circles == sorted(by_tests["recovery_episodes"])
    labels = [t.get_text() for t in bottom.get_legend().get_texts()]
    first = by_tests.sort_values("seed").iloc[0]
    episodes = int(first["recovery_episodes"])
    assert any(
        label.startswith(f"CURIOUS seed 0: tests back after {episodes:,}; competence 90%")
        for label in labels
    )
    assert top.get_xlim()[1] > by_tests["recovery_episodes"].max()
    # the per-run legend sits under the panels, so that however long its entries the panels
    # keep the figure's width
    fig.draw_without_rendering()
    legend = bottom.get_legend().get_window_extent()
    assert legend.y1 < bottom.get_window_extent().y0
    assert all(ax.get_position().width > 0.8 for ax in (tested, top, bottom))
    assert "Top: its test success (noise-free test rollouts" in _caption(fig)
    assert "pooled over 5 epochs (100 episodes)" in _caption(fig)


SHIPPED = Path(__file__).resolve().parents[1] / "data" / "laptop"


@pytest.mark.skipif(not (SHIPPED / "sensor_failure").is_dir(), reason="no shipped runs")
def test_the_sensor_failure_figure_draws_every_run_over_its_whole_recovery():
    """The shipped sensory-failure runs: one line per run, an x axis reaching past every
    recovery (5,998 and 6,918 episodes after the onset), and the run that never recovered
    (M-UVFA seed 0, which ends 5,328 episodes after its failure) shown with a cross."""
    df = analysis.load_runs(SHIPPED / "sensor_failure")
    fig, per_run = analysis.sensor_failure(df)
    top, bottom = fig.axes[:2]
    recovered = per_run.loc[per_run["recovered"], "recovery_episodes"]
    assert top.get_xlim()[1] > recovered.max() > 6_000
    labels = [t.get_text() for t in bottom.get_legend().get_texts()]
    assert len(labels) == len(per_run) == 4
    assert "M-UVFA seed 0: not regained by its end (5,328 after)" in labels
    assert "CURIOUS seed 0: 90% regained after 6,918" in labels
    runs = [line for line in top.lines if len(line.get_xdata()) > 10]
    assert len(runs) == 4
    crosses = [line for line in top.lines if line.get_marker() == "X"]
    circles = [line for line in top.lines if line.get_marker() == "o"]
    assert len(crosses) == 1 and len(circles) == 3
    assert sorted(x for c in circles for x in c.get_xdata()) == sorted(recovered.astype(int))


def _seed_patterns() -> list[tuple[float, ...]]:
    """The on-off dash pattern of each of `SEED_STYLES`, in points at a line width of 1."""
    from matplotlib import rcParams

    from curious.analysis.figures.failure_recovery import SEED_STYLES

    named = {
        "-": (),
        "--": tuple(rcParams["lines.dashed_pattern"]),
        ":": tuple(rcParams["lines.dotted_pattern"]),
        "-.": tuple(rcParams["lines.dashdot_pattern"]),
    }
    return [named[s] if isinstance(s, str) else tuple(s[1]) for s in SEED_STYLES]


def test_five_seeds_of_a_condition_draw_in_five_line_styles():
    """The sensory-failure figures tell a condition's runs apart by line style, seed by seed: the
    five seeds a side of the study on a mastered module need five patterns (its seed 3 was drawn
    like seed 0 while there were four)."""
    patterns = _seed_patterns()
    assert len(set(patterns[:5])) == 5, patterns


@pytest.mark.skipif(not (SHIPPED / "sensor_failure").is_dir(), reason="no shipped runs")
def test_the_run_legend_shows_a_whole_period_of_every_line_style():
    """Each handle of the figure's run legend is long enough to show one whole period of any
    seed's line style at the widest line drawn (dashes scale with the width): shorter, the
    dash-dot-dot of seed 4 showed as seed 1's dashes and seed 3's dash-dot as seed 0's line."""
    from matplotlib import rcParams

    fig, _ = analysis.sensor_failure(analysis.load_runs(SHIPPED / "sensor_failure"))
    legend = fig.axes[1].get_legend()
    assert legend.get_title().get_text() == "each run"
    assert rcParams["lines.scale_dashes"]
    width = max(line.get_linewidth() for line in legend.get_lines())
    longest = max(sum(pattern) for pattern in _seed_patterns()) * width
    assert legend.handlelength * legend.prop.get_size_in_points() >= longest


def test_distractors_plots_one_line_per_condition_over_distractor_counts(studies):
    fig = analysis.distractors(studies["distractors"])
    ax = fig.axes[0]
    assert list(ax.get_xticks()) == [0, 4, 7]
    final = analysis.final_competence(studies["distractors"])
    means = final.groupby(["condition", "n_distractors"])["value"].mean()
    containers = {c.get_label(): c for c in ax.containers}
    line = containers["CURIOUS"].lines[0]
    np.testing.assert_allclose(line.get_ydata(), means.loc["curious"].to_numpy())


def test_distractors_draws_the_test_success_beside_the_competence(studies):
    """Given the runs' test rollouts, a second panel: each setting's test success at the end
    (`final_test_success`), its bins named in the caption; rollouts of other runs are refused."""
    df, tests = studies["distractors"], studies["distractors_tests"]
    assert len(analysis.distractors(df).axes) == 1
    fig = analysis.distractors(df, tests=tests)
    left, right = fig.axes
    assert left.get_ylabel().startswith("self-evaluated competence")
    assert right.get_ylabel().startswith("test success") and list(right.get_xticks()) == [0, 4, 7]
    final = analysis.final_test_success(tests)
    means = final.groupby(["condition", "n_distractors"])["value"].mean()
    for label, condition in (("CURIOUS", "curious"), ("M-UVFA", "m-uvfa")):
        line = {c.get_label(): c for c in right.containers}[label].lines[0]
        np.testing.assert_allclose(line.get_ydata(), means.loc[condition].to_numpy())
    end, width = int(final["episodes"].iat[0]), final.attrs["bin_size"]
    assert f"pooled per run over episodes {end - width + 1:,}–{end:,}" in _caption(fig)
    with pytest.raises(analysis.AnalysisError, match="same runs"):
        analysis.distractors(df, tests=tests[tests["n_distractors"] != 7])


def test_distractors_names_what_it_plots_and_shows_each_settings_seeds(studies):
    """The y axis says self-evaluated competence (not "final success"); a setting of the
    paper's without runs keeps its tick, saying so; each tick says how many seeds it has."""
    df = studies["distractors"]
    fig = analysis.distractors(df[df["n_distractors"] != 0])
    ax = fig.axes[0]
    assert ax.get_ylabel().startswith("self-evaluated competence")
    assert "final success" not in ax.get_ylabel() + fig._suptitle.get_text()
    assert [t.get_text() for t in ax.get_xticklabels()] == [
        "0\n(no runs)",
        "4\n(2 seeds)",
        "7\n(2 seeds)",
    ]
    assert "no runs with 0, which the paper also compares" in _caption(fig)
    one = df[(df["seed"] == 0) | (df["n_distractors"] == 7)]
    labels = [t.get_text() for t in analysis.distractors(one).axes[0].get_xticklabels()]
    assert labels == ["0\n(1 seed)", "4\n(1 seed)", "7\n(2 seeds)"]


def test_episode_ticks_read_in_thousands():
    assert [format_episodes(v) for v in (0, 950, 1500, 150_000, 1_200_000)] == [
        "0",
        "950",
        "1.5k",
        "150k",
        "1.2M",
    ]


def test_palette_is_fixed_and_rerun_ready():
    assert palette.module_color("reach") == "#0072B2"
    assert palette.module_rgb("reach") == (0x00, 0x72, 0xB2)
    assert palette.module_label("cube1_above_cube2") == "T3 cube 1 above cube 2"
    assert palette.condition_label("mg-te") == "MG-TE"
    colours = [palette.condition_color(c) for c in ("curious", "mg-te", "her", "m-uvfa")]
    assert len(set(colours)) == 4
    # Modules beyond the table: stable labels and colours, distinct among extra distractors.
    assert palette.module_label("push_cube9") == "push cube 9"
    extra = [palette.module_color(f"push_cube{i}") for i in range(6, 10)]
    assert len(set(extra)) == 4 and palette.module_color("push_cube9") == extra[-1]
    assert palette.module_color("wave_hello") == "#B3B37F"  # from the name (crc32), not hash()
    assert all(0 <= v <= 255 for v in palette.module_rgb("wave_hello"))
    names = ["push_cube10", "stack", "zz", "reach", "push_cube8"]
    assert sorted(names, key=palette.module_sort_key) == [
        "reach",
        "stack",
        "push_cube8",
        "push_cube10",
        "zz",
    ]


def test_public_names_resolve_and_the_palette_imports_alone():
    import importlib

    for sub in ("loading", "statistics", "perturbation", "drops", "figures"):
        module = importlib.import_module(f"curious.analysis.{sub}")
        for name in module.__all__:
            assert getattr(analysis, name) is getattr(module, name), name
            assert name in analysis.__all__
    for name in ("load_runs", "recovery", "save_figure", "LEARNED_COMPETENCE", "ALPHA"):
        assert name in analysis.__all__
    with pytest.raises(AttributeError):
        _ = analysis.no_such_name
    # The recording code imports the palette; that must not pull in the plotting stack.
    code = (
        "import sys, curious.watching.palette as p; p.module_rgb('reach'); "
        "print(sorted(m for m in ('matplotlib', 'pandas', 'scipy') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_the_long_runs_figure_draws_every_seed_whole_and_marks_drops_and_dips(studies):
    """One row of panels (competence, LP) per seed of the condition, each over its whole run;
    a drop of a mastered module shaded on both panels, each dip a triangle at its trough."""
    table = studies["main"]
    seeds = sorted(int(s) for s in table.loc[table["condition"] == "curious", "seed"].unique())
    dips = pd.DataFrame(
        {
            "run": [str(table.loc[table["condition"] == "curious", "run"].iat[0])],
            "module": ["reach"],
            "trough_episode": [300],
            "trough": [0.42],
        }
    )
    fig = analysis.long_runs(table, dips=dips)
    assert len(fig.axes) == 2 * len(seeds)
    assert fig.axes[0].get_ylabel().startswith(f"seed {seeds[0]}")
    marks = [line for ax in fig.axes for line in ax.lines if line.get_marker() == "v"]
    assert len(marks) == 1 and list(marks[0].get_xdata()) == [300]
    text = _caption(fig)
    assert "Triangles: the troughs of the 1 dip (" in text
    assert text.startswith(f"CURIOUS: {seeds_text(seeds)}; ")
    with pytest.raises(analysis.AnalysisError, match="no seed"):
        analysis.long_runs(table, seeds=[99])
