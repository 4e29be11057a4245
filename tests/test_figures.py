"""Every registered figure (`curious.reproduction.figures`), a plugin's among them, has what it
needs: experiments that exist, a file name of its own, the report's text, and a draw function
that draws it from the smoke reproduction's tables with its caption (dm_control's one test over
every registered task)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from curious.reproduction.experiments import experiment_names, get_budget
from curious.reproduction.figures import BUILT_IN_FIGURES, FIGURES, check_figures, figures_of
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


@pytest.mark.parametrize("name", list(FIGURES))
def test_every_figure_is_drawn_from_the_smoke_tables_with_its_caption(name, smoke, tmp_path):
    spec = FIGURES[name]
    assert spec.text.strip() and spec.caption(tested=False).strip()
    trained = [e for e in spec.experiments if e in SMOKE.experiments]
    if not trained:
        pytest.skip(f"figure {name!r}: none of its experiments is in the smoke budget")
    repro = Reproduction(SMOKE, OutputLayout.at(smoke.out), make_pool=LocalPool)
    for experiment in trained:
        e = SMOKE.experiments[experiment]
        inputs = figure_inputs(repro, e, spec, load_metrics(repro, experiment))
        inputs = replace(inputs, out_dir=tmp_path)  # the side files here, not in the output
        fig = spec.draw(inputs)
        assert isinstance(fig, Figure), (name, experiment)
        caption = " ".join(fig.get_supxlabel().split())
        assert caption.endswith(SMOKE.caption_note_for(e)), (name, experiment)
        for path in inputs.written.values():
            assert path.parent == tmp_path and not pd.read_csv(path).empty


@pytest.mark.parametrize("name", ["sensor_failure", "signed_lp"])
def test_a_failure_figures_side_table_holds_its_per_run_values_exactly(name, smoke, tmp_path):
    """The report reads each run's onset, p_LP and practice shares from the CSV beside a failure
    figure: read back, it holds what the analysis computed to the last bit, so that the report's
    tests and readings (a mean rise of p_LP at least another's) are the notebooks'."""
    from curious import analysis

    spec = FIGURES[name]
    experiment = next((e for e in spec.experiments if e in SMOKE.experiments), None)
    if experiment is None:
        pytest.skip(f"figure {name!r}: none of its experiments is in the smoke budget")
    repro = Reproduction(SMOKE, OutputLayout.at(smoke.out), make_pool=LocalPool)
    e = SMOKE.experiments[experiment]
    inputs = figure_inputs(repro, e, spec, load_metrics(repro, experiment))
    inputs = replace(inputs, out_dir=tmp_path)
    spec.draw(inputs)
    written = pd.read_csv(inputs.written["csv"])
    floats = [c for c in written.columns if written[c].dtype == "float64"]
    assert {"p_lp_before", "p_lp_after", "practice_before", "practice_after"} <= set(floats)
    if name == "signed_lp":  # signed LP's runs beside the absolute ones they are read against
        _, per_run = analysis.signed_lp(inputs.other("sensor_failure_mastered")[0], inputs.metrics)
    else:
        _, per_run = analysis.sensor_failure(inputs.metrics)
    expected = per_run.drop(columns=["run"]).reset_index(drop=True)
    assert len(written) == len(expected) > 0
    for column in floats:
        np.testing.assert_array_equal(written[column], expected[column].astype("float64"))
