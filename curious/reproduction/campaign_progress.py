"""How far a set of runs has got: one row per run folder, read from the folders alone.

A long campaign (`curious reproduce --budget laptop`, or many `curious train` runs) is stopped and
resumed many times; `progress_table` says where each run stands from what its folder holds: episodes
logged in ``metrics.parquet`` against the config's ``total_episodes``, the newest checkpoint, the
run's own clock, the commits it ran from, and its test success over the last epochs
(``tests.parquet``: noise-free test rollouts, scored as the paper's Fig. 2a, which for the flat
`her` baseline is its holistic goal), and, for a variant with a sensory failure, whether the failure
has started (the first episode ``metrics.parquet`` flags) or how far the perturbed module's
competence is from the run's threshold. A run that has written its config but no episode yet is
listed with 0 episodes; so is a run a reproduction's budget plans that has not started, or one of
the seeds a campaign adds beyond the budget's (`tools/campaign.py --seeds` writes them into
`reproduce.json`). A root may also be a shipped data folder (`curious ship`): its runs are
listed as shipped (no checkpoint), and they stand for the runs of the same path that a reproduction
given beside it has not started, so that a campaign whose machine lost the folders of the runs it
shipped still counts them. A run that both hold is listed once, from the reproduction's folder
(which has its checkpoints and may have gone further), marked shipped when the shipped copy holds
all its episodes.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from os import PathLike
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from curious.analysis.loading import (
    AnalysisError,
    read_run_info,
    run_path_below,
    search_run_folders,
)
from curious.config import DEFAULT_TEST_EPOCHS
from curious.reproduction.experiments import ExperimentError, get_budget
from curious.runs.folder import RunFolder
from curious.runs.folder_errors import RunFolderError
from curious.runs.folder_layout import CONFIG_FILE
from curious.runs.run_info import RunInfo
from curious.runs.shipped_folder import ShippedFolder

if TYPE_CHECKING:
    from curious.reproduction.experiments import ReproduceBudget

__all__ = [
    "DEFAULT_TEST_EPOCHS",
    "ExperimentProgress",
    "RunProgress",
    "current_pace",
    "experiment_progress",
    "progress_markdown",
    "progress_table",
    "recorded_at_once",
    "runs_at_once",
    "summary_markdown",
]


@dataclass(frozen=True)
class RunProgress:
    """Where one run stands."""

    run: str
    condition: str
    variant: str
    seed: int
    episodes: int
    total_episodes: int
    checkpoint: int | None
    run_hours: float
    commits: tuple[str, ...]
    test_episode: int | None
    test_success: float | None
    test_count: int
    module_success: dict[str, float]
    name: str = ""
    """The run's path below the folder it was found in (a reproduction's runs root)."""
    shipped: bool = False
    """A shipped data folder holds all its episodes (a row read from one has no checkpoint)."""
    failure: str | None = None
    """Where the run's sensory failure stands (`_failure`); None for a variant without one."""

    @property
    def done(self) -> float:
        """Fraction of the run's episodes logged."""
        return self.episodes / self.total_episodes if self.total_episodes else 0.0


def _run_folders(root: Path) -> list[Path]:
    """Folders below (or at) `root` that hold a config.json: runs, started or not."""
    if not root.exists():
        raise AnalysisError(f"{root} does not exist")
    if RunFolder(root).has_config:
        return [root]
    found = search_run_folders(root, started_only=False)
    if not found:
        raise AnalysisError(f"{root} holds no run folder (no {CONFIG_FILE} below it)")
    return found


def _tests(folder: RunFolder, achievable: tuple[str, ...], epochs: int) -> tuple[Any, ...]:
    """(episode of the newest test, pooled success, count, per-module success) over the last
    `epochs` epochs of achievable-module tests; Nones where the run has none yet."""
    path = folder.tests_path
    if not path.is_file():
        return None, None, 0, {}
    tests = pd.read_parquet(path, columns=["epoch", "episode", "module", "success"])
    if tests.empty:
        return None, None, 0, {}
    last = np.sort(tests["epoch"].unique())[-epochs:]
    recent = tests[tests["epoch"].isin(last) & tests["module"].astype(str).isin(achievable)]
    per_module = recent.groupby(recent["module"].astype(str), sort=False)["success"].mean()
    success = float(recent["success"].mean()) if len(recent) else None
    modules = {m: float(per_module[m]) for m in achievable if m in per_module.index}
    return int(tests["episode"].max()), success, len(recent), modules


def _failure_columns(info: RunInfo) -> list[str]:
    """The metrics columns `_failure` reads: none for a variant without a sensory failure."""
    modules = info.sensor_failure_modules
    return ["sensor_failure", *(f"competence/{m}" for m in modules)] if modules else []


def _failure(info: RunInfo, metrics: pd.DataFrame) -> str | None:
    """Where a run's sensory failure stands: ``from episode N`` once ``metrics`` (its
    ``episode`` and the `_failure_columns` it holds) flags it, else what it waits for (the
    setting's episode, or the perturbed module's competence against the setting's threshold);
    None for a variant without a failure."""
    modules = info.sensor_failure_modules
    if not modules:
        return None
    if "sensor_failure" in metrics.columns:
        flagged = metrics.loc[metrics["sensor_failure"].fillna(False).astype(bool), "episode"]
        if len(flagged):
            return f"from episode {int(flagged.min()):,}"
    if info.perturbation_episode is not None:
        return f"not yet: starts at episode {info.perturbation_episode:,}"
    if info.failure_competence is None:
        return "never (no episode or competence set)"
    reads = [
        f"{metrics[f'competence/{m}'].iat[-1]:.2f}"
        for m in modules
        if len(metrics) and f"competence/{m}" in metrics.columns
    ]
    now = f" (now {', '.join(reads)})" if reads else ""
    whose = " and ".join(f"{m}'s" for m in modules)
    return f"not yet: starts when {whose} competence reaches {info.failure_competence:.2f}{now}"


def _progress(path: Path, epochs: int, root: Path, shipped: bool = False) -> RunProgress:
    info = read_run_info(path)
    folder = RunFolder(path)
    metrics = pd.DataFrame(columns=["episode", "wall_time"])
    if folder.metrics_path.is_file():
        held = set(pq.read_schema(folder.metrics_path).names)
        extra = [c for c in _failure_columns(info) if c in held]
        metrics = pd.read_parquet(folder.metrics_path, columns=["episode", "wall_time", *extra])
    episodes = len(metrics)
    hours = float(metrics["wall_time"].max()) / 3600 if episodes else 0.0
    test_episode, success, count, modules = _tests(folder, info.achievable_modules, epochs)
    return RunProgress(
        run=str(path),
        condition=info.condition,
        variant=info.variant,
        seed=info.seed,
        episodes=episodes,
        total_episodes=info.total_episodes,
        checkpoint=folder.newest_checkpoint(),
        run_hours=hours,
        commits=info.commits,
        test_episode=test_episode,
        test_success=success,
        test_count=count,
        module_success=modules,
        name=run_path_below(path, root).as_posix(),
        shipped=shipped,
        failure=_failure(info, metrics),
    )


def _reproduction(root: Path) -> tuple[ReproduceBudget, Path] | None:
    """The budget and runs folder of a reproduction's output folder (one with
    `reproduce.json`; its runs lie under `runs/` or where `--runs-dir` put them), else None.
    The seeds a campaign plans beyond the budget's (`extra_seeds`: experiment -> seeds, which
    `tools/campaign.py --seeds` writes) are added to its experiments (`Experiment.with_seeds`)."""
    manifest = root / "reproduce.json"
    if not manifest.is_file():
        return None
    try:
        data = json.loads(manifest.read_text(encoding="utf-8"))
        budget = get_budget(str(data.get("budget", data.get("preset"))))
        runs_dir = data.get("runs_dir")
        if runs_dir is not None and not isinstance(runs_dir, str):
            raise ValueError(f"runs_dir must be a folder path, got {runs_dir!r}")
        extra = data.get("extra_seeds") or {}
        if not isinstance(extra, dict) or not set(extra) <= set(budget.experiments):
            raise ExperimentError(f"extra_seeds {extra!r} names no experiment of {budget.name}")
        experiments = {
            name: e.with_seeds(int(s) for s in extra.get(name, ()))
            for name, e in budget.experiments.items()
        }
    except (json.JSONDecodeError, AttributeError, TypeError, ValueError) as exc:
        raise AnalysisError(f"{manifest} is damaged: {exc}") from exc
    return replace(budget, experiments=experiments), (Path(runs_dir) if runs_dir else root / "runs")


def _planned(budget: ReproduceBudget, runs_root: Path) -> list[RunProgress]:
    """The runs a reproduction plans that have not written their config yet: 0 episodes, so
    the table shows the whole budget."""
    rows = []
    for spec in budget.runs():
        folder = runs_root / spec.relative_path
        if not RunFolder(folder).has_config:
            rows.append(
                RunProgress(
                    run=str(folder.resolve()),
                    condition=spec.condition,
                    variant=spec.variant,
                    seed=spec.seed,
                    episodes=0,
                    total_episodes=spec.total_episodes,
                    checkpoint=None,
                    run_hours=0.0,
                    commits=(),
                    test_episode=None,
                    test_success=None,
                    test_count=0,
                    module_success={},
                    name=spec.relative_path.as_posix(),
                )
            )
    return rows


def _readable_progress(
    path: Path,
    epochs: int,
    where: tuple[Path, bool],
    on_unreadable: Callable[[Path, str], None] | None,
) -> RunProgress | None:
    """`_progress` of one folder; where its files cannot be read and `on_unreadable` is given,
    None after telling it the folder and the problem (else the `AnalysisError`)."""
    try:
        return _progress(path, epochs, *where)
    except AnalysisError as exc:
        error = exc
    except (OSError, ValueError) as exc:  # pyarrow's unreadable files
        error = AnalysisError(f"{path}: a table cannot be read: {exc}")
    except RunFolderError as exc:  # a folder laid out wrong (its checkpoints a file)
        error = AnalysisError(str(exc))
    if on_unreadable is None:
        raise error
    on_unreadable(path, str(error))
    return None


def progress_table(
    roots: str | PathLike[str] | Iterable[str | PathLike[str]],
    epochs: int = DEFAULT_TEST_EPOCHS,
    on_unreadable: Callable[[Path, str], None] | None = None,
) -> list[RunProgress]:
    """Progress of every run folder below `roots` (one path or several), sorted by the runs'
    paths below their roots; a root that is a reproduction's output folder also lists the runs
    its budget has not started, unless a shipped data folder among `roots` holds them.

    A folder whose config or tables cannot be read raises an `AnalysisError`, unless
    `on_unreadable` is given: it is then called with the folder and the problem, and the folder
    is left out (a monitor's table of the other runs, `curious progress`)."""
    if epochs < 1:
        raise AnalysisError(f"epochs must be at least 1, got {epochs}")
    paths = [Path(roots)] if isinstance(roots, (str, PathLike)) else [Path(r) for r in roots]
    if not paths:
        raise AnalysisError("no folder given")

    planned: dict[str, RunProgress] = {}
    found: dict[Path, tuple[Path, bool]] = {}  # run folder -> (its root, shipped)
    for root in paths:
        if root.exists() and not root.is_dir():
            raise AnalysisError(
                f"{root} is a file, not a folder: name a run folder, a folder of them, or a "
                "shipped data folder"
            )
    for root in paths:
        reproduction = _reproduction(root)
        mine = _planned(*reproduction) if reproduction else []
        planned.update((r.run, r) for r in mine)
        runs_root = (reproduction[1] if reproduction else root).resolve()
        shipped = ShippedFolder(root).is_shipped
        try:
            found.update((f.resolve(), (runs_root, shipped)) for f in _run_folders(runs_root))
        except AnalysisError:
            if not mine:  # a reproduction that has started no run yet is not an error
                raise
    read = {
        str(f): _readable_progress(f, epochs, where, on_unreadable) for f, where in found.items()
    }
    rows = {k: r for k, r in read.items() if r is not None}
    if found and not rows and not planned:
        raise AnalysisError(f"no run folder below {', '.join(map(str, paths))} could be read")
    held = {r.name: k for k, r in rows.items() if r.shipped}
    live = {r.name: k for k, r in rows.items() if not r.shipped}
    for name in held.keys() & live.keys():  # one row, the folder's; shipped if the copy is whole
        copy, row = rows.pop(held[name]), rows[live[name]]
        rows[live[name]] = replace(row, shipped=copy.episodes >= row.episodes)
    rows.update((k, r) for k, r in planned.items() if r.name not in held)
    return sorted(rows.values(), key=lambda r: (r.name, r.run))


def _name(row: RunProgress, base: Path | None) -> str:
    path = Path(row.run)
    if base is not None and path != base:  # a run given as the root goes by its own name
        try:
            return str(path.relative_to(base))
        except ValueError:
            pass
    return row.name or path.name


def progress_markdown(
    rows: list[RunProgress],
    base: str | PathLike[str] | None = None,
    epochs: int = DEFAULT_TEST_EPOCHS,
) -> str:
    """A markdown table of `rows`; run names relative to `base` where they lie below it, else
    below the folder each was found in. A shipped run's checkpoint reads `shipped`, after the
    newest checkpoint where its folder is also there. Where a run has a sensory failure, a
    column says where each run's failure stands."""
    root = Path(base).resolve() if base is not None else None
    failures = any(r.failure is not None for r in rows)
    header = (
        "| run | condition | variant | seed | episodes | of | done | checkpoint | run hours "
        f"| episodes/s | test success, last {epochs} epochs (tests) | per achievable module "
        + ("| sensory failure " if failures else "")
        + "| commits |\n"
        + "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|"
        + ("---|" if failures else "")
        + "---|\n"
    )
    lines = []
    for r in rows:
        rate = f"{r.episodes / (r.run_hours * 3600):.1f}" if r.run_hours > 0 else "-"
        success = (
            f"{r.test_success:.2f} ({r.test_count}, at {r.test_episode:,})"
            if r.test_success is not None and r.test_episode is not None
            else "none yet"
        )
        modules = ", ".join(f"{m} {s:.2f}" for m, s in r.module_success.items()) or "-"
        checkpoint = "none" if r.checkpoint is None else f"{r.checkpoint:,}"
        if r.shipped:
            checkpoint = "shipped" if r.checkpoint is None else f"{checkpoint}, shipped"
        lines.append(
            f"| {_name(r, root)} | {r.condition} | {r.variant} | {r.seed} | {r.episodes:,} "
            f"| {r.total_episodes:,} | {r.done:.0%} | {checkpoint} | {r.run_hours:.2f} "
            f"| {rate} | {success} | {modules} "
            + (f"| {r.failure or '-'} " if failures else "")
            + f"| {' '.join(r.commits) or '-'} |"
        )
    return header + "\n".join(lines) + "\n"


@dataclass(frozen=True)
class ExperimentProgress:
    """Where one experiment's runs stand together (the runs whose path starts with its name)."""

    experiment: str
    runs: int
    finished: int
    episodes: int
    total_episodes: int
    run_hours: float
    left: int
    """Episodes its runs have still to log (a run past its budget, or without one, owes none)."""

    @property
    def done(self) -> float:
        """Fraction of its runs' episodes logged."""
        return self.episodes / self.total_episodes if self.total_episodes else 0.0

    @classmethod
    def of(cls, experiment: str, rows: Iterable[RunProgress]) -> ExperimentProgress:
        """`rows` summed under the name `experiment`."""
        rows = list(rows)
        return cls(
            experiment=experiment,
            runs=len(rows),
            finished=sum(r.episodes >= r.total_episodes for r in rows),
            episodes=sum(r.episodes for r in rows),
            total_episodes=sum(r.total_episodes for r in rows),
            run_hours=sum(r.run_hours for r in rows),
            left=sum(max(0, r.total_episodes - r.episodes) for r in rows),
        )


def experiment_progress(rows: list[RunProgress]) -> list[ExperimentProgress]:
    """`rows` summed per experiment (the first part of each run's path below its root), in
    order of first appearance; a run found outside any experiment folder counts under ''."""
    groups: dict[str, list[RunProgress]] = {}
    for r in rows:
        groups.setdefault(r.name.split("/")[0] if "/" in r.name else "", []).append(r)
    return [ExperimentProgress.of(name, group) for name, group in groups.items()]


def current_pace(rows: list[RunProgress]) -> float | None:
    """Episodes per second per run, by the runs' own clocks, of the runs training now (started
    and unfinished: the machine at work), else of every run that has logged an episode; None
    where none has."""
    timed = [r for r in rows if r.run_hours > 0 and r.episodes]
    now = [r for r in timed if r.episodes < r.total_episodes] or timed
    if not now:
        return None
    return sum(r.episodes for r in now) / (3600 * sum(r.run_hours for r in now))


def recorded_at_once(root: str | PathLike[str]) -> int | None:
    """How many runs the reproduction in `root` trains side by side, as its `reproduce.json`
    records it (`at_once`, which `curious reproduce` writes for a pool on one machine); None
    where the folder has no reproduce.json or it records none (Ray, or an earlier version)."""
    manifest = Path(root) / "reproduce.json"
    if not manifest.is_file():
        return None
    try:
        value = json.loads(manifest.read_text(encoding="utf-8")).get("at_once")
    except (json.JSONDecodeError, AttributeError) as exc:
        raise AnalysisError(f"{manifest} is damaged: {exc}") from exc
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise AnalysisError(f"{manifest} is damaged: at_once must be a count >= 1, got {value!r}")
    return value


def runs_at_once(
    roots: str | PathLike[str] | Iterable[str | PathLike[str]], rows: list[RunProgress]
) -> int:
    """How many runs train side by side, for the hours left: what the first of `roots` that is
    a reproduction records (`recorded_at_once`), else the runs started and not finished (those
    training now: a campaign queue writes no count), at least 1."""
    paths = [roots] if isinstance(roots, (str, PathLike)) else list(roots)
    for root in paths:
        recorded = recorded_at_once(root)
        if recorded is not None:
            return recorded
    return max(1, sum(0 < r.episodes < r.total_episodes for r in rows))


def summary_markdown(rows: list[RunProgress], at_once: int = 1) -> str:
    """A markdown table of `rows` per experiment, with the hours left at the current pace
    (`current_pace`) with `at_once` runs training side by side."""
    if at_once < 1:
        raise AnalysisError(f"at_once must be at least 1, got {at_once}")
    pace = current_pace(rows)
    side = "one at a time" if at_once == 1 else f"{at_once} at a time"
    left_head = f"hours left at {pace:.1f} episodes/s per run, {side}" if pace else "hours left"
    lines = [
        f"| experiment | runs finished | episodes | of | done | run-hours so far | episodes left "
        f"| {left_head} |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    parts = experiment_progress(rows)
    for p in [*parts, ExperimentProgress.of("all", rows)] if len(parts) > 1 else parts:
        hours = f"{p.left / pace / at_once / 3600:.1f}" if pace else "-"
        lines.append(
            f"| {p.experiment or '-'} | {p.finished} of {p.runs} | {p.episodes:,} "
            f"| {p.total_episodes:,} | {p.done:.0%} | {p.run_hours:.2f} | {p.left:,} | {hours} |"
        )
    return "\n".join(lines) + "\n"
