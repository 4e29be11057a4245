"""The run's tables: `metrics.parquet` (one row per training episode), `tests.parquet` (one row
per test rollout) and `learner.parquet` (one row per cycle with updates: what the recording shows
of the replay and the learner, whose replay counts the analysis reads), columns as in
docs/architecture.md.

Rows accumulate in memory and the file is rewritten atomically at every flush (write a temporary
file beside it, then rename over it), so a run killed at any moment, SIGKILL included, leaves the
last flushed file complete and readable. On resume the rows beyond the checkpoint's episode
count are dropped, so rows and checkpoint always agree.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from curious.runs.folder_errors import RunFolderError

_EPISODE_COLUMNS: list[tuple[str, pa.DataType]] = [
    ("episode", pa.int64()),
    ("worker", pa.int32()),
    ("module", pa.string()),
    ("g0", pa.float32()),
    ("g1", pa.float32()),
    ("g2", pa.float32()),
    ("success", pa.bool_()),
]
"""What both tables say of an episode: which, on which copy, its module and goal, its success."""


def metrics_schema(module_names: Sequence[str]) -> pa.Schema:
    """The columns, in order, for a run over `module_names`."""
    columns = [
        *_EPISODE_COLUMNS,
        ("eval", pa.bool_()),
        ("sensor_failure", pa.bool_()),
    ]
    for prefix in ("competence", "lp", "p_lp"):
        columns += [(f"{prefix}/{name}", pa.float32()) for name in module_names]
    columns.append(("wall_time", pa.float64()))
    return pa.schema(columns)


def tests_schema() -> pa.Schema:
    """The columns of `tests.parquet`: the noise-free test rollouts run after every epoch.

    `episode` is the number of training episodes done when the test ran (test rollouts are not
    training episodes and are not counted in it); `worker` is the test copy that ran it.
    `success` is the condition's score, the paper's (in `her`, its holistic goal met);
    `module_success` whether `module` met its own goal slot (the same, except in `her`).
    """
    return pa.schema(
        [
            ("epoch", pa.int64()),
            *_EPISODE_COLUMNS,
            ("module_success", pa.bool_()),
            ("wall_time", pa.float64()),
        ]
    )


class TableLog:
    """Rows of one table of a run, flushed atomically to a parquet file."""

    def __init__(self, path: str | os.PathLike, schema: pa.Schema) -> None:
        self.path = Path(path)
        self.schema = schema
        self._tables: list[pa.Table] = []
        if self.path.exists():
            try:
                table = pq.read_table(self.path)
            except (OSError, pa.ArrowInvalid) as exc:
                reason = str(exc).split(f"'{self.path}': ", 1)[-1]  # pyarrow's names the file
                raise RunFolderError(
                    f"{self.path} is damaged, not a table the run can go on from ({reason}); "
                    "restore it, or start the run over with --restart"
                ) from None
            if table.schema.names != self.schema.names:
                raise ValueError(f"{self.path} is not this run's table: {self._differences(table)}")
            self._tables.append(table.cast(self.schema))

    def _differences(self, table: pa.Table) -> str:
        """How `table`'s columns differ from the schema's, in a line (a shipped table lacks
        most of them; another run's names other modules)."""
        names, wanted = table.schema.names, self.schema.names
        missing = [n for n in wanted if n not in names]
        extra = [n for n in names if n not in wanted]
        said = [f"it lacks {', '.join(missing)}"] if missing else []
        said += [f"it has {', '.join(extra)}, which this run does not write"] if extra else []
        said = said or ["its columns are in another order"]
        return "; ".join(said) + (
            " (a table of another run, or one reduced by `curious ship`: a run goes on only from"
            " its own tables)"
        )

    @property
    def n_rows(self) -> int:
        return sum(t.num_rows for t in self._tables)

    def append(self, columns: dict[str, np.ndarray]) -> None:
        """Add rows given as one array per column (every column of the schema)."""
        missing = [n for n in self.schema.names if n not in columns]
        if missing:
            raise KeyError(f"metrics rows lack columns {missing}")
        arrays = [pa.array(columns[f.name], type=f.type) for f in self.schema]
        self._tables.append(pa.Table.from_arrays(arrays, schema=self.schema))

    def table(self) -> pa.Table:
        if not self._tables:
            return self.schema.empty_table()
        table = pa.concat_tables(self._tables).combine_chunks()
        self._tables = [table]
        return table

    def truncate(self, n_episodes: int, inclusive: bool = False) -> None:
        """Keep only rows whose `episode` is below `n_episodes` (or equal, with `inclusive`)."""
        table = self.table()
        keep = pa.compute.less_equal if inclusive else pa.compute.less
        self._tables = [table.filter(keep(table["episode"], pa.scalar(n_episodes, pa.int64())))]

    def flush(self) -> None:
        """Rewrite the file atomically with every row so far. A failed write (a full disk)
        leaves the file as it was and raises an OSError naming it (pyarrow's names neither the
        file nor, in its strerror, the cause alone)."""
        table = self.table()
        tmp = self.path.with_name(f".{self.path.name}.tmp")
        try:
            pq.write_table(table, tmp)
            with open(tmp, "rb") as handle:
                os.fsync(handle.fileno())
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            reason = os.strerror(exc.errno) if exc.errno else str(exc)
            raise OSError(exc.errno, reason, str(self.path)) from exc
        os.replace(tmp, self.path)


class MetricsLog(TableLog):
    """`metrics.parquet`: one row per training episode."""

    def __init__(self, path: str | os.PathLike, module_names: Sequence[str]) -> None:
        super().__init__(path, metrics_schema(module_names))


class TestsLog(TableLog):
    """`tests.parquet`: one row per test rollout."""

    __test__ = False  # not a pytest class

    def __init__(self, path: str | os.PathLike) -> None:
        super().__init__(path, tests_schema())

    def truncate(self, n_episodes: int, inclusive: bool = True) -> None:
        """Keep the tests run at or before `n_episodes` training episodes (a checkpoint at
        n episodes was written after the test of its last cycle)."""
        super().truncate(n_episodes, inclusive)


LEARNER_STATS: dict[str, tuple[str, str]] = {
    "critic_loss": ("losses", "critic"),
    "actor_loss": ("losses", "actor"),
    "q_target_mean": ("q", "target_mean"),
}
"""The learner statistics a run records, each a column of `learner.parquet` named as the trainer
names it (`CycleResult.losses`), with its group and name in the recording (`losses/critic`)."""

_FROM_EPISODE = b"from_episode"


def learner_schema(module_names: Sequence[str], from_episode: int = 0) -> pa.Schema:
    """The columns of `learner.parquet`, in order: `episode` (the episodes done after the cycle,
    where the recording logs it), `replay/<module>` (the cycle's replayed transitions of each
    module, counted), the `LEARNER_STATS` (means over the cycle's updates; NaN in a cycle
    without them) and `wall_time`; `from_episode` in the file's metadata (`LearnerLog`)."""
    columns = [("episode", pa.int64())]
    columns += [(f"replay/{name}", pa.int64()) for name in module_names]
    columns += [(name, pa.float64()) for name in LEARNER_STATS]
    columns.append(("wall_time", pa.float64()))
    return pa.schema(columns, metadata={_FROM_EPISODE: str(from_episode).encode()})


def learner_begins(schema: pa.Schema) -> int:
    """The episode a `learner.parquet` of this schema begins at (`LearnerLog.from_episode`)."""
    return int((schema.metadata or {}).get(_FROM_EPISODE, b"0"))


class LearnerLog(TableLog):
    """`learner.parquet`: the replay counts and learner statistics of each cycle with updates,
    the series a recording shows under `replay/`, `losses/` and `q/`, so that a recording rebuilt
    from the tables holds them too (`curious.watching.recording.resume.rebuild_from_tables`).

    `from_episode` is where the table begins: 0 for a run that wrote it from its start; a run
    from before the table, or whose table was lost, begins it where it resumes, so that a
    rebuilt recording can say from which episode these series are there (and the analysis which
    stretch its replay counts cover). The table is never a reason a run cannot resume: one that
    cannot be read is set aside as `learner.parquet.unreadable`, with a warning, and a new one
    begins.
    """

    def __init__(self, path: str | os.PathLike, module_names: Sequence[str], episodes: int) -> None:
        path = Path(path)
        try:
            begins = learner_begins(pq.read_schema(path)) if path.exists() else episodes
            super().__init__(path, learner_schema(module_names, begins))
        except (OSError, ValueError, RunFolderError) as exc:  # pyarrow's are among them
            aside = path.with_name(f"{path.name}.unreadable")
            os.replace(path, aside)
            warnings.warn(
                f"{path} could not be read ({exc}); it is kept as {aside.name}, and the replay "
                f"and learner statistics are kept again from episode {episodes:,}",
                RuntimeWarning,
                stacklevel=2,
            )
            begins = episodes
            super().__init__(path, learner_schema(module_names, begins))
        self.from_episode = begins
        self._replay_columns = [f"replay/{name}" for name in module_names]

    def truncate(self, n_episodes: int, inclusive: bool = True) -> None:
        """Keep the rows of the cycles up to a checkpoint at `n_episodes` (the last of them at
        `n_episodes` itself)."""
        super().truncate(n_episodes, inclusive)

    def append_cycle(
        self, episode: int, replay_counts: np.ndarray, losses: dict[str, float], wall: float
    ) -> dict[str, np.ndarray] | None:
        """The row of a cycle that ended at `episode` episodes, appended and returned; None (no
        row) for a cycle without updates, which the recording shows nothing of either."""
        if not (replay_counts.sum() > 0 or any(k in losses for k in LEARNER_STATS)):
            return None
        row: dict[str, np.ndarray] = {"episode": np.array([episode], np.int64)}
        for column, count in zip(self._replay_columns, replay_counts, strict=True):
            row[column] = np.array([count], np.int64)
        for stat in LEARNER_STATS:
            row[stat] = np.array([losses.get(stat, np.nan)], np.float64)
        row["wall_time"] = np.array([wall], np.float64)
        self.append(row)
        return row
