"""The report's opening: what it was built from, the software, the budgets, the compute, and
each experiment's table of runs."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import pandas as pd

from curious import analysis
from curious.reproduction.experiments import BUDGETS, Experiment, ReproduceBudget, get_budget
from curious.runs.folder import RunFolder
from curious.runs.folder_errors import RunFolderError
from pipelines.report.blocks import ExperimentTables, fmt, markdown_table
from pipelines.resources import Reproduction


def _seeds(e: Experiment) -> str:
    """An experiment's seeds, with those beyond the budget's named."""
    seeds = ", ".join(map(str, e.seeds))
    if not e.extra_seeds:
        return seeds
    return f"{seeds} ({len(e.seeds)}; {', '.join(map(str, e.extra_seeds))} beyond the budget's)"


def budgets(repro: Reproduction, experiments: list[Experiment]) -> list[str]:
    """The budgets table: per experiment its conditions, variants, seeds, episodes per run,
    when its sensory failure starts, its training preset and its number of runs."""
    rows = []
    for e in experiments:
        config = e.runs()[0].config(repro.overrides)
        rows.append(
            (
                e.name,
                ", ".join(e.conditions),
                ", ".join(e.variants),
                _seeds(e),
                f"{e.total_episodes:,}",
                e.sensor_failure_text,
                f"`{e.train_preset}`: {config.n_workers} workers x {config.episodes_per_worker} "
                f"episodes, {config.n_updates} updates of {config.batch_size} per cycle",
                len(e.runs()),
            )
        )
    header = (
        "experiment",
        "conditions",
        "variants",
        "seeds",
        "episodes per run",
        "sensory failure starts",
        "training preset",
        "runs",
    )
    return markdown_table(header, rows)


def _machines(runs: Iterable[object]) -> tuple[list[str], int]:
    """The machines the runs trained on (their config.json), and how many runs record none."""
    found: dict[str, None] = {}
    unrecorded = 0
    for run in runs:
        try:
            machines = RunFolder(str(run)).read_info().machines
        except RunFolderError:
            machines = ()
        found.update(dict.fromkeys(machines))
        unrecorded += not machines
    return sorted(found), unrecorded


def compute(tables: dict[str, pd.DataFrame]) -> list[str]:
    """How long the runs trained, read off their own clocks (`wall_time`, seconds of training
    since each run started, resumes included), in all and per experiment with the machines."""
    per_experiment = {
        name: t.groupby("run", observed=True)["wall_time"].max() for name, t in tables.items()
    }
    walls = pd.concat(per_experiment.values())
    if walls.empty:
        return []
    lines = [
        f"Training time, from the runs' own clocks: {len(walls)} runs, "
        f"{walls.sum() / 60:,.1f} run-minutes in all, {walls.min() / 60:.1f} to "
        f"{walls.max() / 60:.1f} min per run (runs that share a machine's cores slow each "
        "other; the test rollouts after the last training episode are not counted).",
        "",
    ]
    for name, wall in per_experiment.items():
        machines, unrecorded = _machines(wall.index)
        where = f"on {'; '.join(machines)}" if machines else "machine not recorded"
        if machines and unrecorded:
            where += f" ({unrecorded} of the runs do not record theirs)"
        lines.append(f"- `{name}`: {len(wall)} runs, {wall.sum() / 3600:,.2f} run-hours, {where}.")
    return [*lines, ""]


def runs_table(tables: ExperimentTables) -> list[str]:
    """One row per run; its final competence and, with test rollouts, its final test success."""
    table, points = tables.metrics, tables.points
    runs = analysis.runs_table(table)
    final = analysis.final_competence(table).set_index("run")["value"]
    tested = analysis.final_success(points).set_index("run") if points is not None else None
    wall = table.groupby("run", observed=True)["wall_time"].max()
    rows = []
    for _, r in runs.sort_values(["variant", "condition", "seed"]).iterrows():
        folder = Path(str(r["run"]))
        row = [
            "/".join(folder.parts[-3:]),
            r["condition"],
            r["variant"],
            r["seed"],
            f"{int(r['n_episodes']):,}",
            f"{wall[r['run']] / 60:.1f}",
            fmt(final[r["run"]]),
        ]
        if tested is not None:
            row.append(_tested_cell(tested, r["run"]))
        rows.append(row)
    header = [
        "run folder",
        "condition",
        "variant",
        "seed",
        "episodes",
        "wall time (min)",
        "final competence",
    ]
    if tested is not None:
        header.append("test success at the last epoch (test rollouts)")
    return markdown_table(header, rows)


def _tested_cell(tested: pd.DataFrame, run: object) -> str:
    """A run's test success at the last epoch with the rollouts behind it: an epoch tests a
    few episodes on the achievable modules (fewer, the more distracting modules share the draw),
    so the count says how far to trust the rate."""
    if run not in tested.index:
        return "–"
    value, n = tested.at[run, "value"], tested.at[run, "n_tests"]
    return f"{fmt(value)} ({int(n)})"


def _versions(table: pd.DataFrame) -> str:
    """The libraries and commit the table's first run started with (its config.json)."""
    try:
        info = RunFolder(str(table["run"].iat[0])).read_info()
    except RunFolderError:
        return ""
    text = ", ".join(f"{k} {v}" for k, v in (info.versions or {}).items() if v)
    git = info.git or {}
    if git.get("commit"):
        text += f"; git {git['commit'][:10]}{' (with local changes)' if git.get('dirty') else ''}"
    return text


def software(tables: dict[str, pd.DataFrame]) -> list[str]:
    """The libraries and commit the runs were trained with, one line; per experiment where the
    experiments' first runs differ (a campaign can train a later experiment from its own
    commit)."""
    by_text: dict[str, list[str]] = {}
    for name, table in tables.items():
        text = _versions(table)
        if text:
            by_text.setdefault(text, []).append(name)
    if not by_text:
        return []
    if len(by_text) == 1:
        return [f"Software: {next(iter(by_text))}.", ""]
    parts = [f"{', '.join(names)}: {text}" for text, names in by_text.items()]
    return [f"Software, per experiment (the first run of each): {'; '.join(parts)}.", ""]


def _episodes_count(n: int) -> str:
    """``"1.46 M"`` from a million on, else ``"24,000"``."""
    return f"{n / 1e6:.2f} M" if n >= 1_000_000 else f"{n:,}"


def built_from(budget: ReproduceBudget, tables: dict[str, pd.DataFrame]) -> list[str]:
    """What the report was built from, counted from its tables (runs, training episodes, per
    experiment), beside what the whole budget trains."""
    whole = get_budget(budget.name) if budget.name in BUDGETS else budget
    specs = whole.runs()
    trains = (
        f"The budget `{budget.name}` as a whole (`curious reproduce --budget {budget.name}`) "
        f"trains {len(specs)} runs, {_episodes_count(sum(s.total_episodes for s in specs))} "
        f"episodes in all — {budget.description}."
    )
    if not tables:
        return [trains, ""]
    per_run = {
        name: t.groupby("run", observed=True)["episode"].max() + 1 for name, t in tables.items()
    }
    n_runs = sum(len(v) for v in per_run.values())
    n_episodes = int(sum(int(v.sum()) for v in per_run.values()))
    parts = ", ".join(
        f"{name} {len(v)} runs ({_episodes_count(int(v.sum()))} episodes)"
        for name, v in per_run.items()
    )
    return [
        f"This report was built from {n_runs} runs, {_episodes_count(n_episodes)} training "
        f"episodes in all: {parts}. {trains}",
        "",
    ]
