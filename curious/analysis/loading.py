"""Run folders into one long table.

A run folder (docs/architecture.md, "A run folder") holds ``config.json`` and ``metrics.parquet``
(one row per episode). `load_runs` reads any set of them into one `pandas.DataFrame` with one row
per (run, episode): the run's identity columns first, then every column of ``metrics.parquet``.

Keys read from ``config.json`` (top level):

=========================  ===================================================================
``condition``              str, e.g. ``"curious"``, ``"mg-te"``, ``"her"``, ``"m-uvfa"``
``seed``                   int
``variant``                str, the suite variant, e.g. ``"default"``
``preset``                 str, e.g. ``"smoke"``, ``"quick"``, ``"laptop"``, ``"paper"``
``modules``                list of str, the modules in slot order
``achievable``             list of bool, one per module (False for distractors)
``sensor_failure_episode`` optional int or null: the first episode run with the sensory failure
                           on (-1 or null: never); looked up at the top level, then anywhere
                           inside nested objects (the resolved config, where `curious train`
                           writes it)
=========================  ===================================================================

Identity columns of the table (the same on every row of a run):
``run`` (the run folder's resolved path), ``condition``, ``seed``, ``variant``, ``preset``,
``modules`` (module names in slot order, comma-joined), ``achievable_modules`` (the achievable
ones, comma-joined), ``n_distractors`` (how many modules are not achievable) and
``perturbation_episode`` (nullable int). String columns (these and ``module``) are categorical.
Runs with different module sets load into one table
(their per-module columns are NaN where a run has no such module); the statistics and figures
check that the runs they compare agree where it matters.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = [
    "CONFIG_FILE",
    "IDENTITY_COLUMNS",
    "METRICS_FILE",
    "PER_MODULE_PREFIXES",
    "AnalysisError",
    "RunInfo",
    "find_run_folders",
    "load_run",
    "load_runs",
    "read_run_info",
    "run_modules",
    "runs_table",
]

CONFIG_FILE = "config.json"
METRICS_FILE = "metrics.parquet"

#: Columns of ``metrics.parquet`` that every run has, whatever its modules.
BASE_COLUMNS: tuple[str, ...] = (
    "episode",
    "worker",
    "module",
    "g0",
    "g1",
    "g2",
    "success",
    "eval",
    "wall_time",
)
#: One column per module with each of these prefixes.
PER_MODULE_PREFIXES: tuple[str, ...] = ("competence/", "lp/", "p_lp/")

IDENTITY_COLUMNS: tuple[str, ...] = (
    "run",
    "condition",
    "seed",
    "variant",
    "preset",
    "modules",
    "achievable_modules",
    "n_distractors",
    "perturbation_episode",
)

PERTURBATION_KEY = "sensor_failure_episode"

PathsOrRoot = str | PathLike[str] | Iterable[str | PathLike[str]]


class AnalysisError(ValueError):
    """A folder is not a readable run folder, or a set of runs cannot be analysed together.

    (Training's own folder errors are `curious.run_folder.RunFolderError`.)"""


@dataclass(frozen=True)
class RunInfo:
    """What ``config.json`` says about one run."""

    path: Path
    condition: str
    seed: int
    variant: str
    preset: str
    module_names: tuple[str, ...]
    achievable: tuple[bool, ...]
    perturbation_episode: int | None

    @property
    def achievable_modules(self) -> tuple[str, ...]:
        """The achievable modules, in slot order."""
        return tuple(m for m, a in zip(self.module_names, self.achievable, strict=True) if a)


def _is_run_folder(path: Path) -> bool:
    return (path / CONFIG_FILE).is_file() and (path / METRICS_FILE).is_file()


def find_run_folders(paths_or_root: PathsOrRoot) -> list[Path]:
    """The run folders named by ``paths_or_root``, resolved and sorted.

    ``paths_or_root`` is one path or several. A path that is itself a run folder (it holds
    ``config.json``) is taken as is; any other directory is searched recursively for run folders
    (a run folder's own sub-folders, such as ``checkpoints/``, and hidden folders are not
    searched).

    Raises `AnalysisError` when a path does not exist, when a search finds no run folder, when a
    folder has ``config.json`` but no ``metrics.parquet`` (a run that has not logged an episode,
    or not a run folder), or when the same folder is named twice.
    """
    if isinstance(paths_or_root, (str, PathLike)):
        given = [Path(paths_or_root)]
    else:
        given = [Path(p) for p in paths_or_root]
    if not given:
        raise AnalysisError("no run folders given: pass a run folder, several, or a root folder")
    found: list[Path] = []
    for path in given:
        if not path.exists():
            raise AnalysisError(f"{path} does not exist")
        if not path.is_dir():
            raise AnalysisError(
                f"{path} is not a run folder: a run folder is a directory holding "
                f"{CONFIG_FILE} and {METRICS_FILE}"
            )
        if (path / CONFIG_FILE).is_file():
            found.append(_checked_run_folder(path))
            continue
        below = _search(path)
        if not below:
            raise AnalysisError(
                f"{path} is not a run folder and holds none: no directory below it has both "
                f"{CONFIG_FILE} and {METRICS_FILE}"
            )
        found.extend(below)
    resolved = [p.resolve() for p in found]
    seen: dict[Path, int] = {}
    for p in resolved:
        seen[p] = seen.get(p, 0) + 1
    twice = sorted(str(p) for p, n in seen.items() if n > 1)
    if twice:
        raise AnalysisError(f"run folder(s) named more than once: {', '.join(twice)}")
    return sorted(resolved)


def _checked_run_folder(path: Path) -> Path:
    if not (path / METRICS_FILE).is_file():
        raise AnalysisError(
            f"{path} has {CONFIG_FILE} but no {METRICS_FILE}: it is not a run folder, or its run "
            "has not logged an episode yet"
        )
    return path


def _search(root: Path) -> list[Path]:
    """Run folders below ``root``; hidden folders (``.dagster``, ``.git``) are not searched."""
    runs: list[Path] = []
    seen: set[Path] = set()
    stack = [root]
    while stack:
        folder = stack.pop()
        if folder.resolve() in seen:  # a symlink loop
            continue
        seen.add(folder.resolve())
        children = sorted(p for p in folder.iterdir() if p.is_dir() and not p.name.startswith("."))
        for child in children:
            if (child / CONFIG_FILE).is_file():
                runs.append(_checked_run_folder(child))
            else:
                stack.append(child)
    return runs


def _find_key(obj: Any, key: str) -> tuple[bool, Any]:
    """Depth-first search for ``key`` in nested mappings; the top level wins."""
    if isinstance(obj, Mapping):
        if key in obj:
            return True, obj[key]
        for value in obj.values():
            hit, found = _find_key(value, key)
            if hit:
                return True, found
    return False, None


def read_run_info(path: str | PathLike[str]) -> RunInfo:
    """Reads and checks the run identity and module set from a run folder's ``config.json``."""
    folder = Path(path)
    config_path = folder / CONFIG_FILE
    if not config_path.is_file():
        raise AnalysisError(
            f"{folder} is not a run folder: no {CONFIG_FILE} (a run folder holds {CONFIG_FILE} "
            f"and {METRICS_FILE}; see docs/architecture.md)"
        )
    try:
        config = json.loads(config_path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise AnalysisError(f"{config_path} is not valid JSON: {exc}") from exc
    if not isinstance(config, dict):
        raise AnalysisError(f"{config_path} must hold a JSON object, not {type(config).__name__}")

    def need(key: str, kind: type | tuple[type, ...], what: str) -> Any:
        if key not in config:
            raise AnalysisError(f"{config_path} has no '{key}' ({what})")
        value = config[key]
        if not isinstance(value, kind) or (isinstance(value, bool) and kind is int):
            raise AnalysisError(f"{config_path}: '{key}' must be {what}, got {value!r}")
        return value

    condition = need("condition", str, "a string")
    seed = need("seed", int, "an integer")
    variant = need("variant", str, "a string")
    preset = need("preset", str, "a string")
    names = need("modules", list, "a list of module names in slot order")
    achievable = need("achievable", list, "a list of booleans, one per module")
    if not names or not all(isinstance(n, str) and n for n in names):
        raise AnalysisError(f"{config_path}: 'modules' must be non-empty strings: {names!r}")
    if len(set(names)) != len(names):
        raise AnalysisError(f"{config_path}: 'modules' repeats a name: {names!r}")
    if any("," in n for n in names):
        raise AnalysisError(f"{config_path}: module names may not contain commas: {names!r}")
    if len(achievable) != len(names) or not all(isinstance(a, bool) for a in achievable):
        raise AnalysisError(
            f"{config_path}: 'achievable' must be {len(names)} booleans (one per module in "
            f"'modules'), got {achievable!r}"
        )
    _, perturbation = _find_key(config, PERTURBATION_KEY)
    if perturbation == -1:  # the training setting's "never"
        perturbation = None
    if perturbation is not None and (
        not isinstance(perturbation, int) or isinstance(perturbation, bool) or perturbation < 0
    ):
        raise AnalysisError(
            f"{config_path}: '{PERTURBATION_KEY}' must be a non-negative integer or null, "
            f"got {perturbation!r}"
        )
    return RunInfo(
        path=folder.resolve(),
        condition=condition,
        seed=seed,
        variant=variant,
        preset=preset,
        module_names=tuple(names),
        achievable=tuple(achievable),
        perturbation_episode=perturbation,
    )


def _read_metrics(info: RunInfo) -> pd.DataFrame:
    metrics_path = info.path / METRICS_FILE
    if not metrics_path.is_file():
        raise AnalysisError(f"{info.path} is not a run folder: no {METRICS_FILE}")
    try:
        metrics = pd.read_parquet(metrics_path)
    except Exception as exc:  # pyarrow raises several types for unreadable files
        raise AnalysisError(f"{metrics_path} is not a readable parquet file: {exc}") from exc
    expected = list(BASE_COLUMNS) + [
        prefix + m for prefix in PER_MODULE_PREFIXES for m in info.module_names
    ]
    missing = [c for c in expected if c not in metrics.columns]
    if missing:
        raise AnalysisError(
            f"{metrics_path} lacks column(s) {', '.join(missing)} (modules in {CONFIG_FILE}: "
            f"{', '.join(info.module_names)})"
        )
    strangers = sorted(
        c
        for c in metrics.columns
        if c.startswith(PER_MODULE_PREFIXES) and c.split("/", 1)[1] not in info.module_names
    )
    if strangers:
        raise AnalysisError(
            f"{metrics_path} has column(s) {', '.join(strangers)} for modules that {CONFIG_FILE} "
            f"does not list ({', '.join(info.module_names)}): metrics and config disagree"
        )
    if metrics.empty:
        raise AnalysisError(f"{metrics_path} has no episodes yet")
    if not pd.api.types.is_integer_dtype(metrics["episode"]):
        raise AnalysisError(
            f"{metrics_path}: 'episode' must be integers, got {metrics['episode'].dtype}"
        )
    episodes = metrics["episode"].to_numpy()
    if episodes.min() < 0:
        raise AnalysisError(f"{metrics_path}: negative episode index {int(episodes.min())}")
    values, counts = np.unique(episodes, return_counts=True)
    if (counts > 1).any():
        twice = values[counts > 1][:5].tolist()
        raise AnalysisError(
            f"{metrics_path}: episode indices logged more than once (e.g. {twice}); each episode "
            "must have exactly one row"
        )
    return metrics.sort_values("episode", kind="stable").reset_index(drop=True)


def load_run(path: str | PathLike[str]) -> pd.DataFrame:
    """One run folder as a table: identity columns, then the columns of ``metrics.parquet``."""
    info = read_run_info(path)
    metrics = _read_metrics(info)
    n = len(metrics)
    identity = {
        "run": str(info.path),
        "condition": info.condition,
        "seed": info.seed,
        "variant": info.variant,
        "preset": info.preset,
        "modules": ",".join(info.module_names),
        "achievable_modules": ",".join(info.achievable_modules),
        "n_distractors": len(info.module_names) - len(info.achievable_modules),
    }
    front = pd.DataFrame({k: np.repeat(np.array([v]), n) for k, v in identity.items()})
    front["seed"] = front["seed"].astype(np.int64)
    front["n_distractors"] = front["n_distractors"].astype(np.int64)
    front["perturbation_episode"] = pd.array([info.perturbation_episode] * n, dtype=pd.Int64Dtype())
    return pd.concat([front, metrics], axis=1)


_CATEGORICAL = ("run", "condition", "variant", "preset", "modules", "achievable_modules", "module")


def load_runs(paths_or_root: PathsOrRoot) -> pd.DataFrame:
    """Any set of run folders (or a root holding them) as one long table, one row per episode.

    Rows are ordered by run folder path, then episode. String columns are categorical, so the
    repetition costs little memory. Raises `AnalysisError`, naming the folder and the
    problem, for anything that is not a run folder following docs/architecture.md, and when two
    runs of the same variant list different modules (one of them was not run on that variant).
    """
    folders = find_run_folders(paths_or_root)
    tables = [load_run(folder) for folder in folders]
    by_variant: dict[str, tuple[str, str]] = {}
    for table in tables:
        variant = table["variant"].iat[0]
        modules = (table["modules"].iat[0], table["achievable_modules"].iat[0])
        first = by_variant.setdefault(variant, (table["run"].iat[0], *modules))
        if first[1:] != modules:
            raise AnalysisError(
                f"runs of variant '{variant}' disagree on their modules: {first[0]} has "
                f"[{first[1]}] (achievable [{first[2]}]) but {table['run'].iat[0]} has "
                f"[{modules[0]}] (achievable [{modules[1]}])"
            )
    table = pd.concat(tables, axis=0, ignore_index=True, sort=False)
    for column in _CATEGORICAL:
        table[column] = table[column].astype("category")
    return table


def runs_table(df: pd.DataFrame) -> pd.DataFrame:
    """One row per run of a loaded table: identity columns plus first/last episode and count."""
    _require_identity(df)
    grouped = df.groupby("run", observed=True, sort=True)
    first = grouped[list(IDENTITY_COLUMNS[1:])].first()
    first["first_episode"] = grouped["episode"].min()
    first["last_episode"] = grouped["episode"].max()
    first["n_episodes"] = grouped["episode"].size()
    return first.reset_index()


def run_modules(df: pd.DataFrame, run: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(all modules in slot order, achievable modules) of one run of a loaded table."""
    _require_identity(df)
    rows = df.loc[df["run"] == run, ["modules", "achievable_modules"]]
    if rows.empty:
        raise AnalysisError(f"no run {run!r} in this table")
    modules, achievable = rows.iloc[0]
    return tuple(str(modules).split(",")), tuple(a for a in str(achievable).split(",") if a)


def _require_identity(df: pd.DataFrame) -> None:
    missing = [c for c in (*IDENTITY_COLUMNS, "episode") if c not in df.columns]
    if missing:
        raise AnalysisError(
            f"this table lacks {', '.join(missing)}: pass a table from curious.analysis.load_runs"
        )
