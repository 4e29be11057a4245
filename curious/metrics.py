"""`metrics.parquet`: one row per episode, columns as in docs/architecture.md.

Rows accumulate in memory and the file is rewritten atomically at every flush (write a temporary
file beside it, then rename over it), so a run killed at any moment, SIGKILL included, leaves the
last flushed file complete and readable. On resume the rows beyond the checkpoint's episode
count are dropped, so rows and checkpoint always agree.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq


def metrics_schema(module_names: Sequence[str]) -> pa.Schema:
    """The columns, in order, for a run over `module_names`."""
    columns = [
        ("episode", pa.int64()),
        ("worker", pa.int32()),
        ("module", pa.string()),
        ("g0", pa.float32()),
        ("g1", pa.float32()),
        ("g2", pa.float32()),
        ("success", pa.bool_()),
        ("eval", pa.bool_()),
    ]
    for prefix in ("competence", "lp", "p_lp"):
        columns += [(f"{prefix}/{name}", pa.float32()) for name in module_names]
    columns.append(("wall_time", pa.float64()))
    return pa.schema(columns)


class MetricsLog:
    """The episode rows of one run, flushed atomically to a parquet file."""

    def __init__(self, path: str | os.PathLike, module_names: Sequence[str]) -> None:
        self.path = Path(path)
        self.schema = metrics_schema(module_names)
        self._tables: list[pa.Table] = []
        if self.path.exists():
            table = pq.read_table(self.path)
            if table.schema.names != self.schema.names:
                raise ValueError(
                    f"{self.path} has columns {table.schema.names}, expected {self.schema.names}"
                )
            self._tables.append(table.cast(self.schema))

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

    def truncate(self, n_episodes: int) -> None:
        """Keep only rows of episodes 0 .. n_episodes - 1."""
        table = self.table()
        mask = pa.compute.less(table["episode"], pa.scalar(n_episodes, pa.int64()))
        self._tables = [table.filter(mask)]

    def flush(self) -> None:
        """Rewrite the file atomically with every row so far."""
        table = self.table()
        tmp = self.path.with_name(f".{self.path.name}.tmp")
        pq.write_table(table, tmp)
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp, self.path)
