"""`learner.parquet`: the replay counts and learner statistics a recording shows, a row per cycle
with updates, kept across resumes as the other tables are; one that cannot be read is set aside,
never a reason a run cannot resume (`curious.runs.metrics.LearnerLog`)."""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
import pytest
from toy_env import make_toy_envs

from curious.presets import resolve
from curious.runs.driver import train
from curious.runs.metrics import LEARNER_STATS, learner_begins

SMALL = dict(n_workers=2, episodes_per_worker=2, progress=False, checkpoint_every_cycles=2)


class LearnerCalls:
    """A recorder that keeps the replay and learner calls, as (kind, episode, values)."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def log_episodes(self, **columns):
        pass

    def log_tests(self, episode, module, success, wall_time):
        pass

    def log_replay(self, episode, counts, wall_time):
        self.calls.append(("replay", episode, tuple(int(c) for c in counts)))

    def log_learner(self, episode, losses, q, wall_time):
        self.calls.append(("learner", episode, {**losses, **q}))

    def checkpoint(self):
        pass

    def close(self):
        pass

    def close_after_error(self):
        pass


def run(out, total, resume=False, recorder=None, stop=None):
    config = resolve("smoke", "curious", 0, {**SMALL, "total_episodes": total})
    return train(
        config,
        out,
        resume=resume,
        make_envs=lambda c: make_toy_envs(c.seed, c.n_workers),
        make_recorder=(lambda trainer, folder: recorder) if recorder is not None else None,
        stop_after_cycles=stop,
    )


def test_a_run_writes_a_row_per_cycle_with_what_its_recorder_got(tmp_path):
    recorder = LearnerCalls()
    trainer = run(tmp_path / "r", 20, recorder=recorder)
    table = pq.read_table(tmp_path / "r" / "learner.parquet")
    assert learner_begins(table.schema) == 0
    names = trainer.spec.module_names
    want = ["episode", *(f"replay/{n}" for n in names), *LEARNER_STATS, "wall_time"]
    assert table.column_names == want
    rows = table.to_pylist()
    assert [r["episode"] for r in rows] == [4, 8, 12, 16, 20]  # every cycle's end
    got = []
    for r in rows:
        got.append(("replay", r["episode"], tuple(r[f"replay/{n}"] for n in names)))
        stats = {name: r[column] for column, (_, name) in LEARNER_STATS.items()}
        got.append(("learner", r["episode"], stats))
    assert got == recorder.calls
    assert np.all(np.diff(table["wall_time"].to_numpy()) >= 0)


def test_a_resume_keeps_the_rows_up_to_its_checkpoint_and_sets_a_damaged_table_aside(tmp_path):
    """Stopped after 3 cycles (its checkpoint at 12: the row of 12 is kept, as the recording
    keeps it), resumed, the table is the uninterrupted run's; one that cannot be read at a
    resume is kept aside, with a warning, and a new one begins at the resumed episode."""
    run(tmp_path / "whole", 24)
    run(tmp_path / "split", 24, stop=3)
    assert pq.read_table(tmp_path / "split" / "learner.parquet")["episode"].to_pylist() == [
        4, 8, 12,
    ]  # fmt: skip
    run(tmp_path / "split", 24, resume=True)

    def rows(folder):
        return pq.read_table(tmp_path / folder / "learner.parquet").drop_columns("wall_time")

    assert rows("split").equals(rows("whole"))

    run(tmp_path / "damaged", 24, stop=3)
    (tmp_path / "damaged" / "learner.parquet").write_bytes(b"not a table")
    with pytest.warns(RuntimeWarning, match="kept as learner.parquet.unreadable"):
        run(tmp_path / "damaged", 24, resume=True)
    table = pq.read_table(tmp_path / "damaged" / "learner.parquet")
    assert learner_begins(table.schema) == 12
    assert table["episode"].to_pylist() == [16, 20, 24]
    assert (tmp_path / "damaged" / "learner.parquet.unreadable").read_bytes() == b"not a table"
