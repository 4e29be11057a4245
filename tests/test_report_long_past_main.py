"""The long runs' table past the main comparison's end (`pipelines.report.long_study`): per run
and module mastered before the main runs end, its lowest competence from there and over the
episodes where the paper saw T3 forgotten, read on made-up runs."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from test_analysis_synthetic import write_run

from curious import analysis
from curious.analysis import load_runs
from pipelines.report import long_study

N = 6_000
MAIN = 3_000
WINDOW = (4_000, 5_000)


def _curves(seed: int) -> dict[str, np.ndarray]:
    """Reach mastered early, down to 0.8 at 3,500 (past the main runs' end) and to 0.9 at 4,500
    (inside the window); push cube 1 mastered only after the main runs' end."""
    reach = np.full(N, 0.97)
    reach[:200] = np.linspace(0.0, 0.97, 200)
    reach[3_500] = 0.8 - 0.01 * seed
    reach[4_500] = 0.9
    push = np.full(N, 0.2)
    push[3_200:] = 0.97
    return {"reach": reach, "push_cube1": push}


@pytest.fixture(scope="module")
def long_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("long")
    for seed in (1, 0):
        write_run(
            root / "curious" / f"seed-{seed}",
            condition="curious",
            seed=seed,
            competence=_curves(seed),
            achievable=[True, True],
        )
    return load_runs(root)


def _lines(table, main_episodes: int | None = MAIN, long_episodes: int = N) -> str:
    experiments = {} if main_episodes is None else {"main": SimpleNamespace(total_episodes=MAIN)}
    repro = SimpleNamespace(budget=SimpleNamespace(experiments=experiments))
    e = SimpleNamespace(total_episodes=long_episodes, conditions=("curious",))
    return "\n".join(long_study.past_the_main_runs(repro, e, table))


def test_each_long_run_s_lowest_competence_past_the_main_runs_and_in_the_paper_s_window(
    long_runs, monkeypatch
):
    monkeypatch.setattr(analysis, "PAPER_FORGETTING_WINDOW", WINDOW)
    text = _lines(long_runs)
    assert "#### Past the main comparison's 3,000 episodes" in text
    assert "| lowest competence from episode 3,000 (at) | lowest from 4,000 to 5,000 (at) |" in text
    rows = [line for line in text.splitlines() if line.startswith("| CURIOUS")]
    assert len(rows) == 2, "reach in each run; push cube 1 was mastered after the main runs' end"
    mastered = [
        int(m) for m in analysis.mastery(long_runs).query("module == 'reach'")["mastered_episode"]
    ]
    assert rows == [  # seed 0 first, whatever the order the runs were written in
        f"| CURIOUS | {seed} | T1 reach | {at:,} | {low} at 3,500 | 0.90 at 4,500 |"
        for seed, at, low in ((0, mastered[0], "0.80"), (1, mastered[1], "0.79"))
    ]


def test_no_table_where_the_runs_cannot_reach_the_paper_s_window_or_no_main_comparison(
    long_runs, monkeypatch
):
    monkeypatch.setattr(analysis, "PAPER_FORGETTING_WINDOW", WINDOW)
    assert _lines(long_runs, long_episodes=WINDOW[1] - 1) == ""
    assert _lines(long_runs, main_episodes=None) == ""
