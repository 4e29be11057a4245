"""A shipped data folder: finished runs reduced to what the analysis reads, small enough to commit
with the repository (`data/<budget>/`), so that the report, the figures and the notebooks are
redone on a fresh clone without training. `curious ship` writes one
(`curious.reproduction.shipping`);
`curious reproduce --from-data`, the notebooks and `curious.analysis` read it. This module owns
the format.

    shipped.json              what the folder holds (`ShippedManifest`, below)
    <run>/config.json         the run's config.json as it was: identity, resolved settings,
                              library versions and commit (`curious.runs.run_info.RunInfo`)
    <run>/metrics.parquet     the run's metrics.parquet without the columns in METRICS_DROPPED
    <run>/tests.parquet       the run's tests.parquet without TESTS_DROPPED (absent where the
                              run has no test rollouts)
    <run>/learner.parquet     the run's learner.parquet without LEARNER_DROPPED: each cycle's
                              replayed transitions per module (absent where the run kept none,
                              as runs trained before the table did not)

`<run>` is where the run folder lay below the runs root it was shipped from: for a reproduction
the partition's path, `main/curious/seed-0` (`RunSpec.relative_path`). So a shipped run is a run
folder with its tables and its description and nothing else (no checkpoints, no recording): the
analysis loads it as any run folder, and the folder is laid out as a reproduction's runs root.

The tables keep every row, and every column they keep is as the run wrote it (the same Arrow
types, the same values), so every number drawn from them is the run's. They leave out what no
analysis, figure, report or notebook reads: the goal of every episode (`g0..g2`, random floats
that are most of the bytes), the worker, each episode's `success` (the competence, LP and p_LP
computed from the self-evaluations' successes are kept, and with them the episode's `module`
and `eval` flag, from which the order of learning counts each module's evaluations), the
clock of the test rollouts, and the learner's losses, Q values and clock (its replay counts per
module are kept: `lp_uses` reads its share of replay from them). Each reduced table says so in
its parquet metadata (`SHIPPED_KEY`), which `shipped_drops` reads for the loaders. They are
written with zstd (`COMPRESSION`, `LEVEL`), dictionary-encoded only for strings; writing the
same runs again gives the same bytes.

`shipped.json`:

    format    FORMAT
    budget    the budget of the reproduction shipped (its reproduce.json); null for other folders
    runs      one entry per run, sorted by `run`: `run` (its path here), `finished` (false: a
              progress snapshot of a run still training), `episodes` (rows of metrics.parquet),
              `total_episodes` (its budget) and `test_rollouts` (rows of tests.parquet)
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from curious.runs.folder_layout import SHIPPED_MANIFEST_FILE, shipped_root

MANIFEST_FILE = SHIPPED_MANIFEST_FILE
FORMAT = 2
"""1: shipped without `module` and `eval` (the order of learning cannot be read from it)."""
SHIPPED_KEY = b"curious.shipped"
"""Parquet schema metadata of a reduced table: JSON with the format and the columns dropped."""
COMPRESSION = "zstd"
LEVEL = 9
"""zstd level: measured on a `laptop` run, 7.0 bytes per metrics row (level 3: 7.9; 19: 7.0),
written in 20 ms per 13,600 rows."""

METRICS_DROPPED: tuple[str, ...] = ("worker", "g0", "g1", "g2", "success")
"""Columns of metrics.parquet a shipped run leaves out (see the module docstring)."""
TESTS_DROPPED: tuple[str, ...] = ("g0", "g1", "g2", "wall_time")
"""Columns of tests.parquet a shipped run leaves out."""
LEARNER_DROPPED: tuple[str, ...] = ("critic_loss", "actor_loss", "q_target_mean", "wall_time")
"""Columns of learner.parquet a shipped run leaves out: every learner statistic
(`curious.runs.metrics.LEARNER_STATS`) and the clock; `episode` and the `replay/<module>` counts
stay."""


class ShippedError(RuntimeError):
    """A folder that is not a usable shipped data folder, or one that cannot be written."""


@dataclass(frozen=True)
class ShippedRun:
    """One run of a shipped folder, as `shipped.json` lists it."""

    run: str
    """Its path in the shipped folder (POSIX, relative)."""
    finished: bool
    episodes: int
    total_episodes: int
    test_rollouts: int


@dataclass(frozen=True)
class ShippedManifest:
    """What `shipped.json` says: the budget shipped (None: not a reproduction) and the runs."""

    budget: str | None
    runs: tuple[ShippedRun, ...]

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "budget": self.budget,
            "runs": [asdict(r) for r in sorted(self.runs, key=lambda r: r.run)],
        }

    def get(self, run: str | PurePosixPath) -> ShippedRun | None:
        """The entry of the run at `run` (a relative path), None where it was not shipped."""
        key = PurePosixPath(run).as_posix()
        return next((r for r in self.runs if r.run == key), None)


def _run_entry(value: Any, path: Path) -> ShippedRun:
    fields = {
        "run": str,
        "finished": bool,
        "episodes": int,
        "total_episodes": int,
        "test_rollouts": int,
    }
    if not isinstance(value, dict):
        raise ShippedError(f"{path}: a run entry must be an object, got {value!r}")
    for key, kind in fields.items():
        item = value.get(key)
        if not isinstance(item, kind) or (kind is int and isinstance(item, bool)):
            raise ShippedError(f"{path}: run entry {value!r} lacks '{key}' ({kind.__name__})")
    run = PurePosixPath(value["run"])
    if run.is_absolute() or ".." in run.parts or not run.parts:
        raise ShippedError(f"{path}: run path {value['run']!r} must be relative, inside the folder")
    return ShippedRun(**{k: value[k] for k in fields})


class ShippedFolder:
    """Paths and the manifest of one shipped data folder."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)

    @property
    def manifest_path(self) -> Path:
        return self.path / MANIFEST_FILE

    @property
    def is_shipped(self) -> bool:
        """Whether the folder holds a `shipped.json`."""
        return self.manifest_path.is_file()

    def run_path(self, run: str | PurePosixPath) -> Path:
        """The shipped run folder of the run at `run`."""
        return self.path.joinpath(*PurePosixPath(run).parts)

    def read_manifest(self) -> ShippedManifest:
        """`shipped.json`, checked; a `ShippedError` naming the file otherwise."""
        path = self.manifest_path
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ShippedError(
                f"{self.path} is not a shipped data folder: it has no {MANIFEST_FILE} "
                "(`curious ship` writes one)"
            ) from None
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise ShippedError(f"{path} is damaged: {exc}") from None
        if not isinstance(data, dict) or not isinstance(data.get("runs"), list):
            raise ShippedError(f"{path} is damaged: it lists no runs")
        if data.get("format") != FORMAT:
            raise ShippedError(
                f"{path} has format {data.get('format')!r}; this curious reads format {FORMAT}: "
                "ship the runs again with this version"
            )
        budget = data.get("budget")
        if budget is not None and not isinstance(budget, str):
            raise ShippedError(f"{path}: 'budget' must be a name or null, got {budget!r}")
        runs = tuple(_run_entry(r, path) for r in data["runs"])
        return ShippedManifest(budget, runs)

    def write_manifest(self, manifest: ShippedManifest) -> None:
        self.manifest_path.write_text(json.dumps(manifest.to_dict(), indent=2) + "\n")


def shipped_run_note(run: str | os.PathLike) -> str:
    """For a run folder of shipped data: a sentence saying what shipped runs carry (their tables
    and description: no recording, no checkpoints) and what reads them; "" otherwise."""
    root = shipped_root(run)
    if root is None:
        return ""
    return (
        f" It lies in the shipped data folder {root} (written by `curious ship`): shipped "
        "runs carry config.json and their tables only, no recording.rrd and no checkpoints. "
        f"`curious reproduce --from-data {root}` and the notebooks read them; to watch or "
        "evaluate a run, train one (`curious train`)."
    )


def shipped_metadata(dropped: tuple[str, ...]) -> dict[bytes, bytes]:
    """The parquet schema metadata that marks a table as reduced, with the columns it drops."""
    return {SHIPPED_KEY: json.dumps({"format": FORMAT, "dropped": list(dropped)}).encode()}


def shipped_drops(metadata: Mapping[bytes, bytes] | None) -> tuple[str, ...]:
    """The columns a table's parquet metadata says shipping left out (empty: a run's own table).
    A `ShippedError` for a mark this curious does not read."""
    raw = (metadata or {}).get(SHIPPED_KEY)
    if raw is None:
        return ()
    try:
        mark = json.loads(raw)
        dropped = tuple(mark["dropped"])
    except (ValueError, KeyError, TypeError):
        raise ShippedError(f"its {SHIPPED_KEY.decode()} metadata is damaged") from None
    if mark.get("format") != FORMAT:
        raise ShippedError(
            f"it was shipped in format {mark.get('format')!r}; this curious reads format "
            f"{FORMAT}: ship the runs again with this version"
        )
    strangers = sorted(set(dropped) - {*METRICS_DROPPED, *TESTS_DROPPED, *LEARNER_DROPPED})
    if strangers:
        raise ShippedError(f"its {SHIPPED_KEY.decode()} metadata drops {', '.join(strangers)}")
    return dropped
