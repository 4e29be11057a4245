"""Loading run folders into one table (curious.analysis.loading), on synthetic run folders."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from test_analysis_synthetic import (
    DEFAULT_ACHIEVABLE,
    DEFAULT_MODULES,
    distractor_modules,
    write_distractor_study,
    write_run,
    write_study,
)

from curious.analysis import (
    AnalysisError,
    find_run_folders,
    load_run,
    load_runs,
    load_tests,
    runs_table,
)


def _flat_run(folder, condition="curious", seed=0, n=30, modules=DEFAULT_MODULES, **kw):
    achievable = kw.pop("achievable", DEFAULT_ACHIEVABLE[: len(modules)])
    curves = {m: np.linspace(0.0, 0.5, n) for m in modules}
    return write_run(
        folder, condition=condition, seed=seed, competence=curves, achievable=achievable, **kw
    )


def test_a_root_loads_every_run_with_identity_and_metrics_columns(tmp_path):
    write_study(tmp_path, seeds=(0, 1), n_episodes=200)
    df = load_runs(tmp_path)
    assert len(df) == 3 * 2 * 200
    assert df["run"].nunique() == 6
    runs = runs_table(df)
    assert sorted(zip(runs["condition"], runs["seed"], strict=True)) == sorted(
        (c, s) for c in ("curious", "mg-te", "her") for s in (0, 1)
    )
    assert (runs["n_episodes"] == 200).all() and (runs["last_episode"] == 199).all()
    assert set(runs["variant"]) == {"default"} and set(runs["preset"]) == {"synthetic"}
    assert (runs["n_distractors"] == 3).all()
    assert set(runs["achievable_modules"]) == {"reach,push_cube1,cube1_above_cube2,stack"}
    for column in ("episode", "worker", "module", "g0", "success", "eval", "wall_time"):
        assert column in df.columns
    for module in DEFAULT_MODULES:
        for prefix in ("competence/", "lp/", "p_lp/"):
            assert prefix + module in df.columns
    # Episodes ascend within each run, and the values are the files' values.
    for _, rows in df.groupby("run", observed=True):
        assert (np.diff(rows["episode"].to_numpy()) > 0).all()
    one = df[(df["condition"] == "mg-te") & (df["seed"] == 1)]
    raw = pd.read_parquet(tmp_path / "mg-te" / "seed1" / "metrics.parquet")
    np.testing.assert_array_equal(one["competence/stack"].to_numpy(), raw["competence/stack"])


def test_paths_single_folder_and_root_agree(tmp_path):
    folders = write_study(tmp_path, conditions=("curious", "her"), seeds=(0,), n_episodes=50)
    by_root = load_runs(tmp_path)
    by_list = load_runs(folders)
    pd.testing.assert_frame_equal(by_root, by_list)
    single = load_runs(folders[0])
    assert single["run"].nunique() == 1 and len(single) == 50
    assert len(load_run(folders[1])) == 50


def test_runs_with_different_modules_load_together_with_nan_where_absent(tmp_path):
    write_distractor_study(tmp_path, counts=(0, 7), seeds=(0,), n_episodes=60)
    df = load_runs(tmp_path)
    runs = runs_table(df)
    assert sorted(runs["n_distractors"].unique()) == [0, 7]
    none = df[df["n_distractors"] == 0]
    assert none["competence/push_cube9"].isna().all()
    assert df.loc[df["n_distractors"] == 7, "competence/push_cube9"].notna().all()


def test_sensor_failure_episode_is_read_from_the_nested_config(tmp_path):
    _flat_run(tmp_path / "a", sensor_failure_episode=12)
    _flat_run(tmp_path / "b", seed=1)
    runs = runs_table(load_runs(tmp_path)).set_index("seed")
    assert runs.loc[0, "perturbation_episode"] == 12
    assert pd.isna(runs.loc[1, "perturbation_episode"])


def _edit_config(folder, **changes):
    path = folder / "config.json"
    config = json.loads(path.read_text())
    for key, value in changes.items():
        if value is None:
            config.pop(key)
        else:
            config[key] = value
    path.write_text(json.dumps(config))


def test_missing_paths_and_files_are_named(tmp_path):
    with pytest.raises(AnalysisError, match="does not exist"):
        load_runs(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(AnalysisError, match="holds none"):
        load_runs(tmp_path / "empty")
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(AnalysisError, match="is not a run folder"):
        load_runs(tmp_path / "file.txt")
    half = tmp_path / "half"
    half.mkdir()
    (half / "config.json").write_text("{}")
    with pytest.raises(AnalysisError, match=r"no metrics\.parquet"):
        load_runs(half)
    with pytest.raises(AnalysisError, match=r"no run folders given"):
        load_runs([])


def test_hidden_folders_under_a_root_are_not_searched(tmp_path):
    _flat_run(tmp_path / "runs" / "a")
    hidden = tmp_path / "runs" / ".dagster" / "storage"
    hidden.mkdir(parents=True)
    (hidden / "config.json").write_text("{}")  # not a run folder, and never looked at
    assert find_run_folders(tmp_path / "runs") == [(tmp_path / "runs" / "a").resolve()]


def test_same_folder_twice_is_refused(tmp_path):
    folder = _flat_run(tmp_path / "a")
    with pytest.raises(AnalysisError, match="more than once"):
        find_run_folders([folder, tmp_path])


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"condition": None}, "no 'condition'"),
        ({"seed": "zero"}, "'seed' must be an integer"),
        ({"seed": True}, "'seed' must be an integer"),
        ({"modules": None}, "no 'modules'"),
        ({"achievable": [True]}, "'achievable' must be 7 booleans"),
        ({"modules": ["reach", "reach"]}, "repeats a name"),
    ],
)
def test_bad_config_is_named(tmp_path, change, message):
    folder = _flat_run(tmp_path / "run")
    _edit_config(folder, **change)
    with pytest.raises(AnalysisError, match=message):
        load_runs(folder)


@pytest.mark.parametrize("total", ["abc", -1, 2.5, True])
def test_a_budget_that_is_no_count_of_episodes_is_named(tmp_path, total):
    """`total_episodes` is read by ship, progress and the report: a hand edit that breaks it is
    named with the file, not met as an int() error without one."""
    folder = _flat_run(tmp_path / "run")
    settings = json.loads((folder / "config.json").read_text())["config"]
    _edit_config(folder, config={**settings, "total_episodes": total})
    with pytest.raises(AnalysisError, match=r"config\.json: 'total_episodes' must be a non-neg"):
        load_runs(folder)


def test_config_that_is_not_json_is_named(tmp_path):
    folder = _flat_run(tmp_path / "run")
    (folder / "config.json").write_text("{not json")
    with pytest.raises(AnalysisError, match="not valid JSON"):
        load_runs(folder)


def test_metrics_that_disagree_with_config_are_named(tmp_path):
    folder = _flat_run(tmp_path / "run")
    metrics = pd.read_parquet(folder / "metrics.parquet")
    metrics.drop(columns=["lp/stack"]).to_parquet(folder / "metrics.parquet")
    with pytest.raises(AnalysisError, match=r"lacks column\(s\) lp/stack"):
        load_runs(folder)
    metrics.assign(**{"competence/jump": 0.0}).to_parquet(folder / "metrics.parquet")
    with pytest.raises(AnalysisError, match=r"competence/jump for modules that config\.json"):
        load_runs(folder)
    (folder / "metrics.parquet").write_text("not parquet")
    with pytest.raises(AnalysisError, match="not a readable parquet"):
        load_runs(folder)
    metrics.iloc[:0].to_parquet(folder / "metrics.parquet")
    with pytest.raises(AnalysisError, match="no episodes yet"):
        load_runs(folder)


def test_an_episode_logged_twice_is_refused(tmp_path):
    episodes = np.array([0, 1, 2, 2, 3], dtype=np.int64)
    folder = _flat_run(tmp_path / "run", n=5, episodes=episodes)
    with pytest.raises(AnalysisError, match=r"more than once \(e\.g\. \[2\]\)"):
        load_runs(folder)


def test_runs_of_one_variant_with_different_modules_are_refused(tmp_path):
    _flat_run(tmp_path / "a")
    names, achievable = distractor_modules(4)
    _flat_run(tmp_path / "b", seed=1, modules=names, achievable=achievable)
    with pytest.raises(AnalysisError, match="runs of variant 'default' disagree on their modules"):
        load_runs(tmp_path)


def test_tables_not_from_load_runs_are_refused():
    with pytest.raises(AnalysisError, match=r"pass a table from curious\.analysis\.load_runs"):
        runs_table(pd.DataFrame({"episode": [0, 1]}))


def test_test_rollouts_load_with_the_same_identity_columns(tmp_path):
    write_study(tmp_path, conditions=("curious", "her"), seeds=(0, 1), n_episodes=60)
    tests = load_tests(tmp_path)
    runs = load_runs(tmp_path)
    assert list(tests.columns[:10]) == list(runs.columns[:10])  # identity columns first
    assert set(tests["run"]) == set(runs["run"]) and len(tests) == 4 * 3 * 60
    for column in ("epoch", "episode", "worker", "module", "success", "wall_time"):
        assert column in tests.columns
    for _, rows in tests.groupby("run", observed=True):
        assert (np.diff(rows["episode"].to_numpy()) >= 0).all()
        assert rows["episode"].unique().tolist() == [20, 40, 60]


def test_test_rollouts_that_disagree_with_config_or_are_missing_are_named(tmp_path):
    folder = write_study(tmp_path, conditions=("curious",), seeds=(0,), n_episodes=40)[0]
    tests = pd.read_parquet(folder / "tests.parquet")
    tests.assign(module="fly").to_parquet(folder / "tests.parquet")
    with pytest.raises(AnalysisError, match=r"test rollouts of module\(s\) fly"):
        load_tests(folder)
    tests.iloc[:0].to_parquet(folder / "tests.parquet")
    with pytest.raises(AnalysisError, match="no test rollouts yet"):
        load_tests(folder)
    tests.drop(columns=["epoch"]).to_parquet(folder / "tests.parquet")
    with pytest.raises(AnalysisError, match=r"lacks column\(s\) epoch"):
        load_tests(folder)
    # written before each condition scored its tests by its own rule: her's success was not
    # the paper's, so the table is refused rather than misread
    tests.drop(columns=["module_success"]).to_parquet(folder / "tests.parquet")
    with pytest.raises(AnalysisError, match=r"lacks column module_success.*retrain"):
        load_tests(folder)
    (folder / "tests.parquet").unlink()
    with pytest.raises(AnalysisError, match=r"has no test rollouts \(no tests\.parquet\)"):
        load_tests(folder)
    assert len(load_runs(folder)) == 40  # the episodes still load
