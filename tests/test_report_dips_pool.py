"""The pool the dips' test decides on (`pipelines.report.long_study`, docs/results.md, C3's rules):
a report that lacks one of the named runs reads the test without deciding and names what it lacks;
one that holds them all decides; one that holds more decides on the named runs alone and reads
the rest beside."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
from test_analysis_synthetic import write_run

from curious.analysis import load_runs
from pipelines.report import long_study

VARIANTS = ("distractors_0", "distractors_4")


def _report(tmp_path: Path, long_seeds, distractor_seeds, monkeypatch) -> tuple[list[str], list]:
    """The long section's test lines over made-up runs: main seeds 0 and 1, the long runs of
    `long_seeds`, the distractors runs of `distractor_seeds` (two variants); the deciding pool
    named as long seeds 0, 1 and distractors seed 0. Returns the lines and, per call of the
    test's reading, the runs it read (experiment, variant, seed)."""
    curve = {"reach": np.linspace(0.0, 1.0, 300)}

    def run(experiment: str, folder: str, seed: int, n: int, variant: str = "default") -> None:
        short = {m: c[:n] for m, c in curve.items()}
        write_run(
            tmp_path / "runs" / experiment / folder / f"seed-{seed}",
            condition="curious",
            seed=seed,
            competence=short,
            achievable=[True],
            variant=variant,
        )

    for seed in (0, 1):
        run("main", "curious", seed, 200)
    for seed in long_seeds:
        run("long", "curious", seed, 300)
    for seed in distractor_seeds:
        for v in VARIANTS:
            run("distractors", f"curious@{v}", seed, 200, variant=v)
    tables = tmp_path / "metrics"
    tables.mkdir()
    for experiment in ("main", "long", "distractors"):
        if (tmp_path / "runs" / experiment).is_dir():
            load_runs(tmp_path / "runs" / experiment).to_parquet(tables / f"{experiment}.parquet")
    experiments = {
        "main": SimpleNamespace(variants=("default",), left_out_variants=()),
        "long": SimpleNamespace(variants=("default",), left_out_variants=()),
        "distractors": SimpleNamespace(variants=VARIANTS[:1], left_out_variants=VARIANTS[1:]),
    }
    repro = SimpleNamespace(
        layout=SimpleNamespace(metrics=lambda name: tables / f"{name}.parquet"),
        budget=SimpleNamespace(experiments=experiments),
    )
    monkeypatch.setattr(long_study, "DECIDING_SEEDS", {"long": (0, 1), "distractors": (0,)})
    read: list = []
    by_depth = long_study._by_depth

    def recording(pooled, decides):
        read.append((sorted(long_study.units(pooled)), decides))
        return by_depth(pooled, decides)

    monkeypatch.setattr(long_study, "_by_depth", recording)
    return long_study.pooled_dips(repro), read


def test_a_pool_lacking_a_named_run_decides_nothing_and_names_it(tmp_path, monkeypatch):
    lines, read = _report(tmp_path, long_seeds=(0,), distractor_seeds=(0,), monkeypatch=monkeypatch)
    text = "\n".join(lines)
    assert "(the test that decides" not in text
    assert "(the depth tested; this reading does not decide)" in text
    assert "It decides nothing" in text and "lacks 1 of them: long seed 1." in text
    assert "(4 runs of main, distractors, long)" in text  # main seed 1 stands while long's lacks
    assert [decides for _, decides in read] == [False]


def test_the_named_pool_whole_decides(tmp_path, monkeypatch):
    lines, read = _report(tmp_path, (0, 1), (0,), monkeypatch)
    text = "\n".join(lines)
    assert "(the test that decides, alpha = 0.01)" in text
    assert "It decides nothing" not in text and "The verdict" not in text
    assert len(read) == 1 and read[0][1] is True
    assert read[0][0] == [  # the main runs left out for the long runs of their seeds
        ("distractors", "distractors_0", 0),
        ("distractors", "distractors_4", 0),
        ("long", "default", 0),
        ("long", "default", 1),
    ]


def test_runs_beyond_the_named_pool_are_read_beside_the_verdict(tmp_path, monkeypatch):
    lines, read = _report(tmp_path, (0, 1), (0, 1), monkeypatch)
    text = "\n".join(lines)
    assert "(6 runs of main, distractors, long)" in text
    assert (
        "The verdict, on the 4 runs named before the long runs shipped (docs/results.md, C3's "
        "rules), without distractors distractors_0 seed 1, distractors distractors_4 seed 1:"
    ) in text
    (whole, beside), (verdict, decides) = read
    assert len(whole) == 6 and beside is False
    assert decides is True and {u[2] for u in verdict if u[0] == "distractors"} == {0}
