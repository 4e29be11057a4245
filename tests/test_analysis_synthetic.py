"""Synthetic run folders for the analysis tests, and checks that they follow the contract.

The writers here produce MADE-UP data: competence curves drawn from logistic functions and
noise, not from any training run. They exist so that the analysis library can be built and
tested before real runs exist. Every config they write says so (``"synthetic": true`` and a
``note``). The folder layout, the ``config.json`` keys and the ``metrics.parquet`` and
``tests.parquet`` columns and types follow docs/architecture.md ("A run folder") exactly.

Other analysis tests import the writers from this module.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from curious.runs import metrics as run_tables

DEFAULT_MODULES: tuple[str, ...] = (
    "reach",
    "push_cube1",
    "cube1_above_cube2",
    "stack",
    "push_cube3",
    "push_cube4",
    "push_cube5",
)
DEFAULT_ACHIEVABLE: tuple[bool, ...] = (True, True, True, True, False, False, False)
#: The `sensor_failure` variant's modules (all achievable); its failure perturbs push_cube3.
FAILURE_MODULES: tuple[str, ...] = ("reach", "push_cube1", "cube1_above_cube2", "push_cube3")
SYNTHETIC_NOTE = "made-up test data written by tests/test_analysis_synthetic.py, not a training run"
LP_EPSILON = 0.4


def lp_from_competence(competence: np.ndarray, window: int) -> np.ndarray:
    """|c(t) - c(t - window)|, with c = 0 before the first episode (an empty queue)."""
    padded = np.concatenate([np.zeros((window, *competence.shape[1:])), competence])
    return np.abs(padded[window:] - padded[:-window])


def p_lp(lp: np.ndarray, eps: float = LP_EPSILON) -> np.ndarray:
    """eps / N + (1 - eps) LP / sum LP per row; uniform where every LP is 0."""
    n = lp.shape[1]
    total = lp.sum(axis=1, keepdims=True)
    share = np.divide(lp, total, out=np.full_like(lp, 1.0 / n), where=total > 0)
    return eps / n + (1 - eps) * share


def logistic(n_episodes: int, onset: float, width: float, top: float = 1.0) -> np.ndarray:
    """A rise from 0 to ``top`` centred on episode ``onset`` over about ``4 width`` episodes."""
    t = np.arange(n_episodes, dtype=np.float64)
    return top / (1.0 + np.exp(-(t - onset) / max(width, 1e-9)))


def write_run(
    folder: Path,
    *,
    condition: str,
    seed: int,
    competence: Mapping[str, np.ndarray],
    achievable: Sequence[bool],
    variant: str = "default",
    preset: str = "synthetic",
    sensor_failure_episode: int | None = None,
    sensor_failure_competence: float | None = None,
    sensor_failure_modules: Sequence[str] | None = None,
    failure_onset: int | None = None,
    log_failure: bool = False,
    lp_window: int = 50,
    n_workers: int = 2,
    episodes: np.ndarray | None = None,
    tests_per_epoch: int = 0,
    epoch_episodes: int = 20,
) -> Path:
    """Writes one synthetic run folder from per-module competence arrays (one value per episode).

    LP is |c(t) - c(t - lp_window)|, p_LP follows the paper's formula, the practised module of each
    episode is drawn from p_LP, one episode in ten is an evaluation, and success is drawn with the
    competence of the practised module. ``episodes`` overrides the episode index column (to write
    gaps or repeats on purpose). ``log_failure`` writes the ``sensor_failure`` column, True from
    ``failure_onset`` on (never when None); without it the column is absent, as in runs logged
    before it existed. ``sensor_failure_modules`` is recorded in config.json as training
    records it; None leaves it out, as config.json written before it was recorded.
    ``tests_per_epoch`` > 0 also writes ``tests.parquet`` (`write_tests`).
    """
    names = list(competence)
    if len(achievable) != len(names):
        raise ValueError("one achievable flag per module")
    comp = np.stack([np.asarray(competence[m], dtype=np.float64) for m in names], axis=1)
    n = comp.shape[0]
    rng = np.random.default_rng(10_000 + seed)
    lp = lp_from_competence(comp, lp_window)
    probs = p_lp(lp)
    choice = (np.cumsum(probs, axis=1) < rng.random((n, 1))).sum(axis=1)
    choice = np.minimum(choice, len(names) - 1)
    index = np.arange(n, dtype=np.int64) if episodes is None else np.asarray(episodes, np.int64)
    goals = rng.uniform(-1.0, 1.0, size=(n, 3)).astype(np.float32)
    metrics: dict[str, object] = {
        "episode": index,
        "worker": (np.arange(n) % n_workers).astype(np.int32),
        "module": pd.array([names[i] for i in choice], dtype="string"),
        "g0": goals[:, 0],
        "g1": goals[:, 1],
        "g2": goals[:, 2],
        "success": rng.random(n) < comp[np.arange(n), choice],
        "eval": (np.arange(n) % 10) == 9,
    }
    if log_failure:
        onset = n if failure_onset is None else failure_onset
        metrics["sensor_failure"] = index >= onset
    for j, m in enumerate(names):
        metrics[f"competence/{m}"] = comp[:, j].astype(np.float32)
    for j, m in enumerate(names):
        metrics[f"lp/{m}"] = lp[:, j].astype(np.float32)
    for j, m in enumerate(names):
        metrics[f"p_lp/{m}"] = probs[:, j].astype(np.float32)
    metrics["wall_time"] = np.cumsum(np.full(n, 0.05))
    folder.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(metrics).to_parquet(folder / "metrics.parquet", index=False)
    config = {
        "synthetic": True,
        "note": SYNTHETIC_NOTE,
        "condition": condition,
        "seed": seed,
        "preset": preset,
        "variant": variant,
        "modules": names,
        "achievable": [bool(a) for a in achievable],
        "versions": {"curious": "synthetic"},
        "git_commit": "synthetic",
        "config": {
            "n_workers": n_workers,
            "lp_window": lp_window,
            "sensor_failure_episode": sensor_failure_episode,
            "sensor_failure_competence": sensor_failure_competence,
        },
    }
    if sensor_failure_modules is not None:
        config["sensor_failure_modules"] = list(sensor_failure_modules)
    (folder / "config.json").write_text(json.dumps(config, indent=2), encoding="utf-8")
    if tests_per_epoch:
        write_tests(folder, names, comp, tests_per_epoch, epoch_episodes, seed)
    return folder


def write_learner(
    folder: Path, names: Sequence[str], counts: np.ndarray, per_cycle: int, from_episode: int = 0
) -> Path:
    """Writes ``learner.parquet`` into a run folder as training does (`learner_schema`): one row
    per cycle of ``per_cycle`` episodes from ``from_episode`` on, ``counts`` (cycles, modules) the
    transitions replayed as each module, the learner statistics made up."""
    counts = np.asarray(counts, np.int64)
    cycles = len(counts)
    columns: dict[str, np.ndarray] = {
        "episode": from_episode + per_cycle * np.arange(1, cycles + 1, dtype=np.int64)
    }
    columns |= {f"replay/{m}": counts[:, j] for j, m in enumerate(names)}
    columns |= {stat: np.linspace(1.0, 0.5, cycles) for stat in run_tables.LEARNER_STATS}
    columns["wall_time"] = np.arange(cycles, dtype=np.float64)
    table = pa.table(columns, schema=run_tables.learner_schema(list(names), from_episode))
    path = folder / "learner.parquet"
    pq.write_table(table, path)
    return path


def write_tests(
    folder: Path,
    names: Sequence[str],
    competence: np.ndarray,
    per_epoch: int,
    epoch_episodes: int,
    seed: int,
) -> Path:
    """Made-up ``tests.parquet``: after every ``epoch_episodes`` episodes, ``per_epoch`` test
    rollouts on modules drawn uniformly, each a success with the module's competence then."""
    n = competence.shape[0]
    ends = np.arange(epoch_episodes, n + 1, epoch_episodes)
    rng = np.random.default_rng(20_000 + seed)
    epoch = np.repeat(np.arange(len(ends)), per_epoch)
    episode = np.repeat(ends, per_epoch)
    module = rng.integers(len(names), size=len(epoch))
    goals = rng.uniform(-1.0, 1.0, size=(len(epoch), 3)).astype(np.float32)
    tests = pd.DataFrame(
        {
            "epoch": epoch.astype(np.int64),
            "episode": episode.astype(np.int64),
            "worker": np.tile(np.arange(per_epoch), len(ends)).astype(np.int32),
            "module": pd.array([names[i] for i in module], dtype="string"),
            "g0": goals[:, 0],
            "g1": goals[:, 1],
            "g2": goals[:, 2],
            "success": rng.random(len(epoch)) < competence[episode - 1, module],
            "wall_time": episode * 0.05,
        }
    )
    tests.insert(len(tests.columns) - 1, "module_success", tests["success"])
    tests.to_parquet(folder / "tests.parquet", index=False)
    return folder


# Made-up onsets of the four achievable modules, as fractions of the budget.
_ONSETS = {"curious": (0.05, 0.2, 0.4, 0.55), "mg-te": (0.1, 0.45, 0.8, 1.1), "m-uvfa": None}


def study_curves(
    condition: str, seed: int, n_episodes: int, modules: Sequence[str], achievable: Sequence[bool]
) -> dict[str, np.ndarray]:
    """Made-up competence curves: `curious` learns the four modules early, `mg-te` later,
    `her` and distractors stay near 0; each seed jitters onsets and adds noise."""
    rng = np.random.default_rng(seed * 7919 + sum(map(ord, condition)))
    curves: dict[str, np.ndarray] = {}
    onsets = _ONSETS.get(condition) or _ONSETS["curious"]
    k = 0
    for module, ok in zip(modules, achievable, strict=True):
        if not ok or condition == "her":
            base = np.full(n_episodes, 0.02)
        else:
            onset = onsets[min(k, 3)] * n_episodes * (1 + 0.08 * rng.standard_normal())
            base = logistic(n_episodes, onset, 0.03 * n_episodes, top=0.95)
            k += 1
        noise = 0.015 * rng.standard_normal(n_episodes)
        curves[module] = np.clip(base + noise, 0.0, 1.0)
    return curves


def write_study(
    root: Path,
    conditions: Sequence[str] = ("curious", "mg-te", "her"),
    seeds: Sequence[int] = (0, 1, 2),
    n_episodes: int = 1200,
    preset: str = "synthetic",
    tests_per_epoch: int = 60,
) -> list[Path]:
    """The main comparison, made up: ``root/<condition>/seed<k>`` for every condition and seed,
    with test rollouts (``tests_per_epoch`` every 20 episodes; 0 writes none)."""
    folders = []
    for c in conditions:
        for s in seeds:
            curves = study_curves(c, s, n_episodes, DEFAULT_MODULES, DEFAULT_ACHIEVABLE)
            folders.append(
                write_run(
                    root / c / f"seed{s}",
                    condition=c,
                    seed=s,
                    competence=curves,
                    achievable=DEFAULT_ACHIEVABLE,
                    preset=preset,
                    tests_per_epoch=tests_per_epoch,
                )
            )
    return folders


def failure_curves(
    seed: int, n_episodes: int, onset: int | None, tau: float, learned: bool = True
) -> dict[str, np.ndarray]:
    """Made-up competence of the sensor_failure variant's modules: push_cube3 rises early (or,
    not ``learned``, stays at chance) and, from ``onset``, falls by 0.6 and comes back with time
    constant ``tau``."""
    achievable = (True,) * len(FAILURE_MODULES)
    curves = study_curves("curious", seed, n_episodes, FAILURE_MODULES, achievable)
    if not learned:
        curves["push_cube3"] = np.full(n_episodes, 0.1)
    elif onset is not None:
        t = np.arange(n_episodes, dtype=np.float64)
        after = np.clip(t - onset, 0.0, None)
        fall = np.where(t >= onset, np.minimum(after / 40.0, 1.0), 0.0)
        dip = 0.6 * fall * np.exp(-np.clip(after - 40.0, 0.0, None) / tau)
        curves["push_cube3"] = np.clip(curves["push_cube1"] - dip, 0.0, 1.0)
    else:
        curves["push_cube3"] = curves["push_cube1"]
    return curves


def write_perturbation_study(
    root: Path,
    perturbation: int = 600,
    n_episodes: int = 1500,
    seeds: Sequence[int] = (0, 1, 2),
    recovery_tau: Mapping[str, float] | None = None,
    tests_per_epoch: int = 0,
) -> list[Path]:
    """Made-up sensory-failure runs of the sensor_failure variant: push_cube3 is mastered, falls
    at ``perturbation`` (logged in the ``sensor_failure`` column) and comes back with a time
    constant per condition (curious faster than m-uvfa by default); ``tests_per_epoch`` > 0
    adds test rollouts (`write_tests`)."""
    taus = recovery_tau or {"curious": 80.0, "m-uvfa": 220.0}
    folders = []
    for c, tau in taus.items():
        for s in seeds:
            curves = failure_curves(s, n_episodes, perturbation, tau * (1 + 0.1 * s))
            folders.append(
                write_run(
                    root / c / f"seed{s}",
                    condition=c,
                    seed=s,
                    competence=curves,
                    achievable=(True,) * len(FAILURE_MODULES),
                    variant="sensor_failure",
                    sensor_failure_episode=perturbation,
                    failure_onset=perturbation,
                    log_failure=True,
                    tests_per_epoch=tests_per_epoch,
                )
            )
    return folders


def distractor_modules(n_distractors: int) -> tuple[tuple[str, ...], tuple[bool, ...]]:
    """Four achievable modules and ``n_distractors`` push modules on cubes 3, 4, ..."""
    names = (*DEFAULT_MODULES[:4], *(f"push_cube{3 + i}" for i in range(n_distractors)))
    return names, (True,) * 4 + (False,) * n_distractors


def write_distractor_study(
    root: Path,
    counts: Sequence[int] = (0, 4, 7),
    seeds: Sequence[int] = (0, 1, 2),
    n_episodes: int = 800,
    tests_per_epoch: int = 0,
) -> list[Path]:
    """Made-up distractors study: final success falls with more distractors, less for curious;
    ``tests_per_epoch`` > 0 writes test rollouts too (`write_run`)."""
    penalty = {"curious": 0.03, "m-uvfa": 0.09}
    folders = []
    for c, per_distractor in penalty.items():
        for k in counts:
            names, achievable = distractor_modules(k)
            for s in seeds:
                curves = study_curves("curious", s, n_episodes, names, achievable)
                for m in names[:4]:
                    curves[m] = np.clip(curves[m] * (1 - per_distractor * k), 0.0, 1.0)
                folders.append(
                    write_run(
                        root / f"distractors{k}" / c / f"seed{s}",
                        condition=c,
                        seed=s,
                        competence=curves,
                        achievable=achievable,
                        variant=f"distractors{k}",
                        tests_per_epoch=tests_per_epoch,
                    )
                )
    return folders


# ----------------------------------------------------------------------------- tests of the writer

CONTRACT_TYPES = {
    "episode": "int64",
    "worker": "int32",
    "module": "string",
    "g0": "float",
    "g1": "float",
    "g2": "float",
    "success": "bool",
    "eval": "bool",
    "wall_time": "double",
}


def test_synthetic_run_folder_follows_the_contract(tmp_path):
    folder = write_study(tmp_path, conditions=("curious",), seeds=(0,), n_episodes=300)[0]
    names = ["config.json", "metrics.parquet", "tests.parquet"]
    assert sorted(p.name for p in folder.iterdir()) == names
    schema = pq.read_schema(folder / "metrics.parquet")
    types = {name: str(schema.field(name).type) for name in schema.names}
    for column, kind in CONTRACT_TYPES.items():
        assert types[column].removeprefix("large_") == kind, column
    # tests.parquet: the trainer's schema, column for column
    written = pq.read_schema(folder / "tests.parquet")
    for field in run_tables.tests_schema():
        assert str(written.field(field.name).type).removeprefix("large_") == str(field.type)
    for prefix in ("competence/", "lp/", "p_lp/"):
        for module in DEFAULT_MODULES:
            assert types[prefix + module] == "float", prefix + module
    config = json.loads((folder / "config.json").read_text())
    assert config["synthetic"] is True and "not a training run" in config["note"]
    assert config["modules"] == list(DEFAULT_MODULES)
    assert config["achievable"] == list(DEFAULT_ACHIEVABLE)


def test_synthetic_p_lp_is_a_distribution_and_follows_lp(tmp_path):
    folder = write_study(tmp_path, conditions=("curious",), seeds=(0,), n_episodes=400)[0]
    metrics = pd.read_parquet(folder / "metrics.parquet")
    probs = metrics[[f"p_lp/{m}" for m in DEFAULT_MODULES]].to_numpy(np.float64)
    np.testing.assert_allclose(probs.sum(axis=1), 1.0, atol=1e-5)
    assert (probs >= LP_EPSILON / len(DEFAULT_MODULES) - 1e-6).all()
    lp = metrics[[f"lp/{m}" for m in DEFAULT_MODULES]].to_numpy(np.float64)
    busy = lp.sum(axis=1) > 0.05
    assert (probs[busy].argmax(axis=1) == lp[busy].argmax(axis=1)).all()
