"""Synthetic run folders for the analysis tests, and checks that they follow the contract.

The writers here produce MADE-UP data: competence curves drawn from logistic functions and
noise, not from any training run. They exist so that the analysis library can be built and
tested before real runs exist. Every config they write says so (``"synthetic": true`` and a
``note``). The folder layout, the ``config.json`` keys and the ``metrics.parquet`` columns and
types follow docs/architecture.md ("A run folder") exactly.

Other analysis tests import the writers from this module.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

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
    lp_window: int = 50,
    n_workers: int = 2,
    episodes: np.ndarray | None = None,
) -> Path:
    """Writes one synthetic run folder from per-module competence arrays (one value per episode).

    LP is |c(t) - c(t - lp_window)|, p_LP follows the paper's formula, the practised module of each
    episode is drawn from p_LP, one episode in ten is an evaluation, and success is drawn with the
    competence of the practised module. ``episodes`` overrides the episode index column (to write
    gaps or repeats on purpose).
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
        },
    }
    (folder / "config.json").write_text(json.dumps(config, indent=2), encoding="utf-8")
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
) -> list[Path]:
    """The main comparison, made up: ``root/<condition>/seed<k>`` for every condition and seed."""
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
                )
            )
    return folders


def write_perturbation_study(
    root: Path,
    perturbation: int = 600,
    n_episodes: int = 1500,
    seeds: Sequence[int] = (0, 1, 2),
    recovery_tau: Mapping[str, float] | None = None,
) -> list[Path]:
    """Made-up sensory-failure runs: push_cube1 is mastered, falls at ``perturbation``, and
    comes back with a time constant per condition (curious faster than m-uvfa by default)."""
    taus = recovery_tau or {"curious": 80.0, "m-uvfa": 220.0}
    folders = []
    t = np.arange(n_episodes, dtype=np.float64)
    for c, tau in taus.items():
        for s in seeds:
            curves = study_curves("curious", s, n_episodes, DEFAULT_MODULES, DEFAULT_ACHIEVABLE)
            after = np.clip(t - perturbation, 0.0, None)
            fall = np.where(t >= perturbation, np.minimum(after / 40.0, 1.0), 0.0)
            dip = 0.6 * fall * np.exp(-np.clip(after - 40.0, 0.0, None) / (tau * (1 + 0.1 * s)))
            curves["push_cube1"] = np.clip(curves["push_cube1"] - dip, 0.0, 1.0)
            folders.append(
                write_run(
                    root / c / f"seed{s}",
                    condition=c,
                    seed=s,
                    competence=curves,
                    achievable=DEFAULT_ACHIEVABLE,
                    variant="sensor_failure",
                    sensor_failure_episode=perturbation,
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
) -> list[Path]:
    """Made-up distractors study: final success falls with more distractors, less for curious."""
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
    assert sorted(p.name for p in folder.iterdir()) == ["config.json", "metrics.parquet"]
    schema = pq.read_schema(folder / "metrics.parquet")
    types = {name: str(schema.field(name).type) for name in schema.names}
    for column, kind in CONTRACT_TYPES.items():
        assert types[column].removeprefix("large_") == kind, column
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
