"""Every registered figure (`curious.reproduction.figures`), a plugin's among them, has what it
needs: experiments that exist, a file name of its own, the report's text, and a draw function
that draws it from the smoke reproduction's tables with its caption (dm_control's one test over
every registered task)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from curious import analysis
from curious.reproduction.experiments import experiment_names, get_budget
from curious.reproduction.figures import (
    BUILT_IN_FIGURES,
    FIGURES,
    FigureInputs,
    FigureSpec,
    check_figures,
    figures_of,
)
from pipelines.assets import figure_inputs, load_metrics
from pipelines.executors import LocalPool
from pipelines.resources import OutputLayout, Reproduction

SMOKE = get_budget("smoke")


def test_the_built_in_figures_are_registered_each_in_its_place():
    assert set(BUILT_IN_FIGURES) <= set(FIGURES)
    assert [f.name for f in figures_of("main")][:4] == ["fig2a", "fig2b", "fig2c", "table1"]
    for name in ("distractors", "sensor_failure", "sensor_failure_mastered"):
        assert figures_of(name)[0].name == name  # opens its section, names its .csv
    assert figures_of("long")[0].name == "long_runs"


def test_every_figure_names_known_experiments_and_a_file_of_its_own():
    check_figures(experiment_names())
    stems = [f.stem(e) for f in FIGURES.values() for e in f.experiments]
    assert len(stems) == len(set(stems)), stems


def _smoke_inputs(spec: FigureSpec, experiment: str, smoke, out_dir: Path) -> FigureInputs:
    """What `spec` draws from for `experiment` in the smoke reproduction, its side files
    written to `out_dir` rather than into that output."""
    repro = Reproduction(SMOKE, OutputLayout.at(smoke.out), make_pool=LocalPool)
    inputs = figure_inputs(
        repro, SMOKE.experiments[experiment], spec, load_metrics(repro, experiment)
    )
    return replace(inputs, out_dir=out_dir)


@pytest.mark.parametrize("name", list(FIGURES))
def test_every_figure_is_drawn_from_the_smoke_tables_with_its_caption(name, smoke, tmp_path):
    spec = FIGURES[name]
    assert spec.text.strip() and spec.caption(tested=False).strip()
    trained = [e for e in spec.experiments if e in SMOKE.experiments]
    if not trained:
        pytest.skip(f"figure {name!r}: none of its experiments is in the smoke budget")
    for experiment in trained:
        inputs = _smoke_inputs(spec, experiment, smoke, tmp_path)
        fig = spec.draw(inputs)
        assert isinstance(fig, Figure), (name, experiment)
        caption = " ".join(fig.get_supxlabel().split())
        note = SMOKE.caption_note_for(SMOKE.experiments[experiment])
        assert caption.endswith(note), (name, experiment)
        for path in inputs.written.values():
            assert path.parent == tmp_path and not pd.read_csv(path).empty


@pytest.mark.parametrize(
    ("name", "per_run_of"),
    [
        ("sensor_failure", lambda inputs: analysis.sensor_failure(inputs.metrics)[1]),
        (  # signed LP's runs beside the absolute ones they are read against
            "signed_lp",
            lambda inputs: analysis.signed_lp(
                inputs.other("sensor_failure_mastered")[0], inputs.metrics
            )[1],
        ),
    ],
)
def test_a_failure_figures_side_table_holds_its_per_run_values_exactly(
    name, per_run_of, smoke, tmp_path
):
    """The report reads each run's onset, p_LP and practice shares from the CSV beside a failure
    figure: read back, it holds what the analysis computed to the last bit, so that the report's
    tests and readings (a mean rise of p_LP at least another's) are the notebooks'."""
    spec = FIGURES[name]
    experiment = next((e for e in spec.experiments if e in SMOKE.experiments), None)
    if experiment is None:
        pytest.skip(f"figure {name!r}: none of its experiments is in the smoke budget")
    inputs = _smoke_inputs(spec, experiment, smoke, tmp_path)
    spec.draw(inputs)
    written = pd.read_csv(inputs.written["csv"])
    floats = [c for c in written.columns if written[c].dtype == "float64"]
    assert {"p_lp_before", "p_lp_after", "practice_before", "practice_after"} <= set(floats)
    expected = per_run_of(inputs).drop(columns=["run"]).reset_index(drop=True)
    assert len(written) == len(expected) > 0
    for column in floats:
        np.testing.assert_array_equal(written[column], expected[column].astype("float64"))
