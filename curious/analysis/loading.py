"""Run folders into long tables.

A run folder (docs/architecture.md, "A run folder") holds ``config.json``, ``metrics.parquet``
(one row per training episode) and, in runs trained with test rollouts, ``tests.parquet`` (one row
per noise-free test rollout, run after every epoch). `load_runs` reads any set of run folders into
one `pandas.DataFrame` with one row per (run, episode): the run's identity columns first, then
every column of ``metrics.parquet``. `load_tests` reads the same folders' ``tests.parquet`` into
one row per (run, test rollout), with the same identity columns; a run without test rollouts (one
trained before they were logged, or with ``test_rollouts_per_worker=0``) is an `AnalysisError`.
`load_learner` reads their ``learner.parquet`` (one row per training cycle with updates: the
transitions replayed as each module, ``replay/<module>``), where the runs kept one.

A shipped data folder (`curious.runs.shipped_folder`, written by ``curious ship``: a
reproduction's runs
reduced to what the analysis reads, e.g. the repository's ``data/laptop``) is a folder of run
folders too, and loads wherever run folders do: ``load_runs("data/laptop/main")``. Its tables
lack the columns shipping leaves out (the goals, the worker, the raw self-evaluations, the
tests' clock, and the learner's losses, Q and clock; their parquet metadata says which), and
every column they keep is the run's own.

What ``config.json`` says about a run is read by `curious.runs.folder.RunFolder.read_info`, which
knows every version of the file (`read_run_info` here raises its errors as `AnalysisError`).

Identity columns of the table (the same on every row of a run):
``run`` (the run folder's resolved path), ``condition``, ``seed``, ``variant``, ``preset``,
``modules`` (module names in slot order, comma-joined), ``achievable_modules`` (the achievable
ones, comma-joined), ``n_distractors`` (how many modules are not achievable),
``perturbation_episode`` (nullable int: the config's ``sensor_failure_episode``),
``failure_competence`` (nullable float: the config's ``sensor_failure_competence``),
``perturbed_modules`` (the modules the variant's sensory failure perturbs, comma-joined; empty
for a variant without one) and ``lp_window`` (nullable int: the config's ``lp_window``, the
evaluation results a module's competence averages once it has that many). Where the failure
actually started is in the ``sensor_failure`` column of ``metrics.parquet`` (runs trained before
that column existed lack it); `curious.analysis.perturbation.failure_onsets` reads it.
String columns (these and ``module``) are categorical.
Runs with different module sets load into one table
(their per-module columns are NaN where a run has no such module); the statistics and figures
check that the runs they compare agree where it matters.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from os import PathLike
from pathlib import Path, PurePosixPath

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
from pandas.api.types import union_categoricals

from curious.runs.folder import RunFolder
from curious.runs.folder_errors import RunFolderError
from curious.runs.folder_layout import CONFIG_FILE, LEARNER_FILE, METRICS_FILE, TESTS_FILE
from curious.runs.metrics import learner_begins, tests_schema
from curious.runs.run_info import RunInfo
from curious.runs.shipped_folder import ShippedError, shipped_drops

__all__ = [
    "IDENTITY_COLUMNS",
    "PER_MODULE_PREFIXES",
    "AnalysisError",
    "RunInfo",
    "find_run_folders",
    "has_learner",
    "is_integer",
    "learner_of",
    "load_learner",
    "load_run",
    "load_runs",
    "load_tests",
    "name_list",
    "read_run_info",
    "require_count",
    "require_identity",
    "require_learner",
    "require_runs",
    "require_tests",
    "require_values",
    "run_modules",
    "run_path_below",
    "runs_table",
    "search_run_folders",
]

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
#: Columns of ``tests.parquet``.
TEST_COLUMNS: tuple[str, ...] = tuple(tests_schema().names)
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
    "failure_competence",
    "perturbed_modules",
    "lp_window",
)

PathsOrRoot = str | PathLike[str] | Iterable[str | PathLike[str]]


class AnalysisError(ValueError):
    """A folder is not a readable run folder, or a set of runs cannot be analysed together.

    (Training's own folder errors are `curious.runs.folder_errors.RunFolderError`.)"""


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
    elif isinstance(paths_or_root, Iterable) and not isinstance(paths_or_root, bytes):
        given = [_given_path(p) for p in paths_or_root]
    else:
        raise AnalysisError(
            f"pass a run folder, several, or a root folder (paths), got {paths_or_root!r}"
        )
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
        if RunFolder(path).has_config:
            found.append(_checked_run_folder(path))
            continue
        below = search_run_folders(path)
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


def _given_path(path: object) -> Path:
    """One of the paths given to `find_run_folders`, or an `AnalysisError` for what is none."""
    if not isinstance(path, (str, PathLike)):
        raise AnalysisError(f"pass run folders as paths, got {path!r}")
    return Path(path)


def _checked_run_folder(path: Path) -> Path:
    if not RunFolder(path).started:
        raise AnalysisError(
            f"{path} has {CONFIG_FILE} but no {METRICS_FILE}: it is not a run folder, or its run "
            "has not logged an episode yet"
        )
    return path


def search_run_folders(root: Path, started_only: bool = True) -> list[Path]:
    """Run folders below ``root``; hidden folders (``.dagster``, ``.git``) are not searched.
    With ``started_only``, a folder with ``config.json`` but no ``metrics.parquet`` is an
    `AnalysisError`; without, it is listed (a run that has not logged an episode yet)."""
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
            if RunFolder(child).has_config:
                runs.append(_checked_run_folder(child) if started_only else child)
            else:
                stack.append(child)
    return runs


def run_path_below(path: Path, root: Path) -> PurePosixPath:
    """A run folder found by `search_run_folders(root)` as a path below `root`; its name where
    it is `root` itself (a single run folder given as the root)."""
    return PurePosixPath(path.name if path == root else path.relative_to(root).as_posix())


def read_run_info(path: str | PathLike[str]) -> RunInfo:
    """What a run folder's ``config.json`` says about its run (identity, modules, sensory
    failure), checked (`curious.runs.folder.RunFolder.read_info`); an `AnalysisError` naming the
    file and the problem otherwise."""
    try:
        return RunFolder(path).read_info()
    except RunFolderError as exc:
        raise AnalysisError(str(exc)) from None


def _shipped_drops(path: Path) -> tuple[str, ...]:
    """The columns a shipped run's table leaves out (`curious.runs.shipped_folder`); none
    for a run's own."""
    try:
        return shipped_drops(pq.read_schema(path).metadata)
    except ShippedError as exc:
        raise AnalysisError(f"{path}: {exc}") from None


def _read_metrics(info: RunInfo) -> pd.DataFrame:
    metrics_path = RunFolder(info.path).metrics_path
    if not metrics_path.is_file():
        raise AnalysisError(f"{info.path} is not a run folder: no {METRICS_FILE}")
    try:
        metrics = pd.read_parquet(metrics_path)
    except Exception as exc:  # pyarrow raises several types for unreadable files
        raise AnalysisError(f"{metrics_path} is not a readable parquet file: {exc}") from exc
    dropped = _shipped_drops(metrics_path)
    expected = [c for c in BASE_COLUMNS if c not in dropped] + [
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


def _identity(info: RunInfo, n: int) -> pd.DataFrame:
    """The identity columns of one run, repeated on ``n`` rows."""
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
    front = pd.DataFrame(
        {
            k: _repeated(v, n) if isinstance(v, str) else np.full(n, v, dtype=np.int64)
            for k, v in identity.items()
        }
    )
    front["perturbation_episode"] = _repeated_or_missing(info.perturbation_episode, n, np.int64)
    front["failure_competence"] = _repeated_or_missing(info.failure_competence, n, np.float64)
    front["perturbed_modules"] = _repeated(",".join(info.sensor_failure_modules), n)
    window = (info.settings or {}).get("lp_window")
    front["lp_window"] = _repeated_or_missing(window, n, np.int64)
    return front


def _repeated(value: str, n: int) -> pd.Categorical:
    """`value` on `n` rows as a categorical of one category: no string is built per row."""
    return pd.Categorical.from_codes(np.zeros(n, dtype=np.int8), categories=pd.Index([value]))


def _repeated_or_missing(
    value: float | None, n: int, dtype: type
) -> pd.api.extensions.ExtensionArray:
    """`value` on `n` rows as a nullable array (Int64 or Float64), all missing where None."""
    missing = np.full(n, value is None)
    values = np.full(n, 0 if value is None else value, dtype=dtype)
    kind = pd.arrays.IntegerArray if dtype is np.int64 else pd.arrays.FloatingArray
    return kind(values, missing)


def load_run(path: str | PathLike[str]) -> pd.DataFrame:
    """One run folder as a table: identity columns (its strings categorical, as in
    `load_runs`), then the columns of ``metrics.parquet``."""
    info = read_run_info(path)
    metrics = _read_metrics(info)
    return pd.concat([_identity(info, len(metrics)), metrics], axis=1)


_CATEGORICAL = (
    "run",
    "condition",
    "variant",
    "preset",
    "modules",
    "achievable_modules",
    "perturbed_modules",
    "module",
)


def load_runs(paths_or_root: PathsOrRoot) -> pd.DataFrame:
    """Any set of run folders (or a root holding them) as one long table, one row per episode.

    Rows are ordered by run folder path, then episode. String columns are categorical, so the
    repetition costs little memory. Raises `AnalysisError`, naming the folder and the
    problem, for anything that is not a run folder following docs/architecture.md, and when two
    runs of the same variant list different modules (one of them was not run on that variant).
    """
    folders = find_run_folders(paths_or_root)
    return _combined([load_run(folder) for folder in folders])


def _combined(tables: list[pd.DataFrame]) -> pd.DataFrame:
    """One table from per-run tables; runs of one variant must list the same modules."""
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
    # Categorical columns are joined by their categories' union: concatenated as they are,
    # columns of different categories would turn into one string per row first.
    shared = [c for c in _CATEGORICAL if all(c in table for table in tables)]
    unions = {
        column: union_categoricals(
            [table[column].astype("category") for table in tables], sort_categories=True
        )
        for column in shared
    }
    table = pd.concat(
        [t.drop(columns=shared) for t in tables], axis=0, ignore_index=True, sort=False
    )
    for column in _CATEGORICAL:
        if column in unions:
            table[column] = unions[column]
        elif column in table:  # a shipped run's metrics have no `module`
            table[column] = table[column].astype("category")
    columns = list(dict.fromkeys(c for t in tables for c in t.columns))
    return table[columns]


def _read_tests(info: RunInfo) -> pd.DataFrame:
    """One run's ``tests.parquet``, checked; an `AnalysisError` where the run has none."""
    path = RunFolder(info.path).tests_path
    if not path.is_file():
        raise AnalysisError(
            f"{info.path} has no test rollouts (no {TESTS_FILE}): the run was trained before "
            "test rollouts were logged, or with test_rollouts_per_worker=0. Fig. 2a and its "
            "Welch tests are measured on test rollouts, as the paper's: retrain the run"
        )
    try:
        tests = pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises several types for unreadable files
        raise AnalysisError(f"{path} is not a readable parquet file: {exc}") from exc
    dropped = _shipped_drops(path)
    missing = [c for c in TEST_COLUMNS if c not in tests.columns and c not in dropped]
    if missing == ["module_success"]:
        raise AnalysisError(
            f"{path} lacks column module_success: it was written before the test rollouts "
            "were scored by each condition's own rule (her's holistic goal, as the paper's), so "
            "its success may not be the paper's: retrain the run"
        )
    if missing:
        raise AnalysisError(f"{path} lacks column(s) {', '.join(missing)}")
    if tests.empty:
        raise AnalysisError(
            f"{info.path} has no test rollouts yet ({TESTS_FILE} is empty: no epoch has ended)"
        )
    strangers = sorted(set(tests["module"].astype(str)) - set(info.module_names))
    if strangers:
        raise AnalysisError(
            f"{path} has test rollouts of module(s) {', '.join(strangers)} that {CONFIG_FILE} "
            f"does not list ({', '.join(info.module_names)})"
        )
    return tests.sort_values(["episode", "worker"], kind="stable").reset_index(drop=True)


def load_tests(paths_or_root: PathsOrRoot) -> pd.DataFrame:
    """The test rollouts of any set of run folders (or a root holding them), one row per rollout.

    Identity columns as in `load_runs`, then the columns of ``tests.parquet``: ``epoch``,
    ``episode`` (training episodes done when the test ran), ``worker``, ``module``, ``g0..g2``,
    ``success`` (the condition's score, the paper's: in ``her``, its holistic goal met),
    ``module_success`` (``module`` met its own goal slot: a per-module view, the same as
    ``success`` but in ``her``) and ``wall_time``. Rows are ordered by run folder path, then
    episode and worker.
    Raises `AnalysisError` naming the folder for a run without test rollouts: there is no
    fallback to the competence of ``metrics.parquet``, which measures something else.
    """
    return _load_each(paths_or_root, _read_tests)


def _load_each(paths_or_root: PathsOrRoot, read: Callable[[RunInfo], pd.DataFrame]) -> pd.DataFrame:
    """One table of ``read``'s table of each run folder, its identity columns in front."""
    tables = []
    for folder in find_run_folders(paths_or_root):
        info = read_run_info(folder)
        table = read(info)
        tables.append(pd.concat([_identity(info, len(table)), table], axis=1))
    return _combined(tables)


def has_learner(path: str | PathLike[str]) -> bool:
    """Whether the run folder at ``path`` kept a ``learner.parquet`` with a cycle in it (runs
    trained before the table existed did not, nor do shipped runs of them, nor a run that has
    not updated yet)."""
    path = RunFolder(path).learner_path
    if not path.is_file():
        return False
    try:
        return pq.read_metadata(path).num_rows > 0
    except (OSError, ValueError):  # a damaged table: `load_learner` says what is wrong
        return True


def _read_learner(info: RunInfo) -> pd.DataFrame:
    """One run's ``learner.parquet``, checked, with ``from_episode`` (where the table begins:
    0 for a run that kept it from its start) as its first column."""
    path = RunFolder(info.path).learner_path
    if not path.is_file():
        raise AnalysisError(
            f"{info.path} has no learner statistics (no {LEARNER_FILE}): the run was trained "
            "before runs kept them, so what it replayed cannot be read"
        )
    try:
        table = pq.read_table(path)
    except Exception as exc:  # pyarrow raises several types for unreadable files
        raise AnalysisError(f"{path} is not a readable parquet file: {exc}") from exc
    _shipped_drops(path)
    learner = table.to_pandas()
    expected = ["episode", *(f"replay/{m}" for m in info.module_names)]
    if missing := [c for c in expected if c not in learner.columns]:
        raise AnalysisError(
            f"{path} lacks column(s) {', '.join(missing)} (modules in {CONFIG_FILE}: "
            f"{', '.join(info.module_names)})"
        )
    replayed = [c for c in learner.columns if c.startswith("replay/")]
    if strangers := sorted(set(replayed) - set(expected)):
        raise AnalysisError(
            f"{path} has column(s) {', '.join(strangers)} for modules that {CONFIG_FILE} does "
            f"not list ({', '.join(info.module_names)}): learner table and config disagree"
        )
    if learner.empty:
        raise AnalysisError(f"{path} has no cycle with updates yet")
    if (learner[replayed].to_numpy() < 0).any():
        raise AnalysisError(f"{path}: a replay count is negative")
    learner.insert(0, "from_episode", np.int64(learner_begins(table.schema)))
    return learner.sort_values("episode", kind="stable").reset_index(drop=True)


def load_learner(paths_or_root: PathsOrRoot) -> pd.DataFrame:
    """The learner statistics of any set of run folders (or a root holding them), one row per
    training cycle with updates.

    Identity columns as in `load_runs`, then ``from_episode`` (where the run's table begins: 0
    for a run that kept it from its start, later for one resumed from before the table existed
    or whose table was lost), ``episode`` (the episodes done after the cycle) and
    ``replay/<module>`` (the transitions replayed as each module in the cycle; all 0 in a
    condition that replays over the whole goal, as ``her`` does), with the learner statistics
    (losses, Q) and clock where the folder has them (shipped runs leave them out). Raises
    `AnalysisError` naming the folder for a run without the table (`has_learner` says which
    have one).
    """
    return _load_each(paths_or_root, _read_learner)


def learner_of(df: pd.DataFrame) -> pd.DataFrame | None:
    """The `load_learner` table of the runs of ``df`` (any table with a ``run`` column, e.g. a
    `load_runs` one) that kept one (`has_learner`), or None where none did: what a reading of
    replay draws beside the runs' other tables, their older runs going without."""
    require_identity(df)
    kept = [run for run in df["run"].astype(str).unique() if has_learner(run)]
    return load_learner(kept) if kept else None


def runs_table(df: pd.DataFrame) -> pd.DataFrame:
    """One row per run of a loaded table: identity columns plus first/last episode and count."""
    require_identity(df)
    grouped = df.groupby("run", observed=True, sort=True)
    first = grouped[list(IDENTITY_COLUMNS[1:])].first()
    first["first_episode"] = grouped["episode"].min()
    first["last_episode"] = grouped["episode"].max()
    first["n_episodes"] = grouped["episode"].size()
    return first.reset_index()


def run_modules(df: pd.DataFrame, run: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(all modules in slot order, achievable modules) of one run of a loaded table."""
    require_identity(df)
    rows = df.loc[df["run"] == run, ["modules", "achievable_modules"]]
    if rows.empty:
        raise AnalysisError(f"no run {run!r} in this table")
    modules, achievable = rows.iloc[0]
    return tuple(str(modules).split(",")), tuple(a for a in str(achievable).split(",") if a)


def name_list(value: Sequence[str] | None, argument: str) -> list[str] | None:
    """``value`` (a sequence of names, or None) as a list; an `AnalysisError` for a single
    string, which would otherwise be read letter by letter."""
    if value is None:
        return None
    if isinstance(value, str):
        raise AnalysisError(f"{argument} takes a sequence of names, e.g. [{value!r}], not a str")
    return [str(v) for v in value]


def is_integer(value: object) -> bool:
    """Whether ``value`` is an integer (Python's or numpy's), not a bool, float or string."""
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _kind(df: pd.DataFrame) -> str | None:
    """``"runs"`` for a `load_runs` table (per-module competence), ``"tests"`` for a
    `load_tests` one (``success`` without competence), else None: for the hint of an error."""
    if any(str(c).startswith("competence/") for c in df.columns):
        return "runs"
    return "tests" if "success" in df else None


def require_count(value: object, name: str, unit: str = "") -> None:
    """A `ValueError` unless ``value`` is an integer >= 1 (``name``, in ``unit``s): a window or
    a bin width, which a float or a bool would turn into float labels or a pandas error."""
    if not is_integer(value) or value < 1:
        raise ValueError(
            f"{name} must be an integer >= 1{f' {unit}' if unit else ''}, got {value!r}"
        )


def require_episode(value: object, name: str) -> None:
    """A `ValueError` unless ``value`` is an episode: an integer >= 0 (a string, a float or a
    bool read as one would compare as something else)."""
    if not is_integer(value) or value < 0:
        raise ValueError(f"{name} must be an episode, an integer >= 0, got {value!r}")


def require_alpha(alpha: object) -> None:
    """A `ValueError` unless ``alpha`` is a significance level, a number in (0, 1)."""
    number = isinstance(alpha, int | float | np.floating) and not isinstance(alpha, bool)
    if not number or not 0 < alpha < 1:
        raise ValueError(f"alpha must be in (0, 1), got {alpha!r}")


def _require_rows(df: pd.DataFrame) -> None:
    """An `AnalysisError` for a table without rows (one filtered to nothing)."""
    if df.empty:
        raise AnalysisError(
            "this table has no rows (filtered to nothing? check the condition, variant or "
            "module it was selected by)"
        )


def require_identity(df: pd.DataFrame) -> None:
    """An `AnalysisError` unless ``df`` has rows with the identity columns and ``episode``: a
    `load_runs` or a `load_tests` table."""
    missing = [c for c in (*IDENTITY_COLUMNS, "episode") if c not in df.columns]
    if missing:
        raise AnalysisError(
            f"this table lacks {', '.join(missing)}: pass a table from curious.analysis.load_runs"
        )
    _require_rows(df)


def require_runs(df: pd.DataFrame) -> None:
    """An `AnalysisError` unless ``df`` is a table of runs (`load_runs`, metrics.parquet's
    rows): identity columns, ``episode`` and the per-module competence, with rows."""
    require_identity(df)
    found = _kind(df)
    if found != "runs":
        kind = "a table of test rollouts (load_tests)" if found else "not a runs table"
        raise AnalysisError(
            f"this table has no competence/<module> columns, {kind}: pass a table from "
            "curious.analysis.load_runs (metrics.parquet)"
        )


def require_learner(df: pd.DataFrame) -> None:
    """An `AnalysisError` unless ``df`` is a table of learner statistics (`load_learner`), with
    rows: identity columns, ``from_episode``, ``episode`` and the ``replay/<module>`` counts."""
    missing = [c for c in (*IDENTITY_COLUMNS, "from_episode", "episode") if c not in df]
    if missing or not any(str(c).startswith("replay/") for c in df.columns):
        said = ", ".join(missing) if missing else "replay/<module> columns"
        raise AnalysisError(
            f"this table lacks {said}: pass a table from curious.analysis.load_learner "
            "(learner.parquet)"
        )
    _require_rows(df)


def require_tests(df: pd.DataFrame) -> None:
    """An `AnalysisError` unless ``df`` is a table of test rollouts (`load_tests`), with rows."""
    missing = [
        c for c in (*IDENTITY_COLUMNS, "epoch", "episode", "module", "success") if c not in df
    ]
    if missing:
        raise AnalysisError(
            f"this table lacks {', '.join(missing)}: Fig. 2a and its statistics read the test "
            "rollouts; pass a table from curious.analysis.load_tests (tests.parquet), not "
            "load_runs (metrics.parquet)"
        )
    _require_rows(df)


def require_values(df: pd.DataFrame, what: str, per: Sequence[str] = ()) -> None:
    """An `AnalysisError` unless ``df`` holds one value per run and point (`what` takes it):
    ``run``, ``condition``, ``seed``, ``episodes`` and ``value``, as `epoch_success`,
    `binned_success`, `bin_runs`, `final_competence` and `final_test_success` return, and no
    run twice at a point (or twice per point and ``per``'s columns): a table of one value per
    module (`module_success_rates`) would otherwise count each module as a seed."""
    missing = [c for c in ("run", "condition", "seed", "episodes", "value") if c not in df]
    if missing:
        kind = {
            "runs": " (this is a table of runs: pass it through bin_runs or final_competence)",
            "tests": " (this is a table of test rollouts: pass it through epoch_success first)",
            None: "",
        }[_kind(df)]
        raise AnalysisError(
            f"{what} takes one value per run and point (epoch_success, binned_success, "
            f"bin_runs or final_competence); this table lacks {', '.join(missing)}{kind}"
        )
    keys = list(dict.fromkeys(["run", "episodes", *per]))
    rows = first_clash(df, keys)
    if rows.empty:
        return
    first = rows.iloc[0]
    varying = [c for c in rows.columns if c not in keys and c != "value" and _varies(rows[c])]
    one_per = f" (one per {varying[0]})" if varying else ""
    hint = f", or pass by=(..., {varying[0]!r})" if varying and what == "across_seeds" else ""
    raise AnalysisError(
        f"{what} takes one value per run and point; this table holds {len(rows)} for run "
        f"{first['run']} at episode {first['episodes']}{one_per}, which would count as "
        f"{len(rows)} seeds: select one{hint}"
    )


def first_clash(df: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """The rows of ``df`` that share the first repeated value of ``keys`` (empty where every
    row's keys are its own): what a check that each seed counts once names in its error."""
    repeated = df[df.duplicated(keys, keep=False)]
    if repeated.empty:
        return repeated
    first = repeated.iloc[0]
    return repeated[(repeated[keys] == first[keys]).all(axis=1)]


def _varies(column: pd.Series) -> bool:
    """Whether a column holds more than one value (NaN or unhashable cells count as none)."""
    try:
        return column.nunique(dropna=True) > 1
    except TypeError:  # lists, arrays
        return False
