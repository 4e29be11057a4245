"""The one Dagster resource the assets share: where things live and where training runs.

`Reproduction` is a plain object handed to Dagster as the `reproduction` resource. It knows the
budget, the output folder's layout and the pool that trains partitions (created on
first use, so building the definitions, e.g. for `dagster dev`, starts no process and contacts no
cluster).

Output folder layout (`OutputLayout`):

    OUT/reproduce.json          which budget made this folder (checked on every later call)
    OUT/runs/<experiment>/<condition>/seed-<s>/    run folders (or --runs-dir on shared storage)
    OUT/metrics/<experiment>.parquet               the combined metrics table of an experiment
    OUT/metrics/<experiment>.tests.parquet         its combined test rollouts (Fig. 2a), where
                                                   every run has them
    OUT/figures/<name>.png|.svg                    the figures
    OUT/figures/<name>.csv                         the numbers behind a figure's statistics
    OUT/report.md                                  figures, seeds, budgets and statistics
    OUT/.dagster/                                  the embedded Dagster instance (DAGSTER_HOME)
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from curious.experiments import Experiment, ReproduceBudget, RunSpec
from pipelines.executors import Job, Pool, run_all
from pipelines.training import (
    FINISHED,
    PARTIAL,
    PartitionResult,
    episodes_logged,
    folder_state,
    run_folder,
)


@dataclass(frozen=True)
class OutputLayout:
    """Paths of one reproduction's output folder (see the module docstring)."""

    out: Path
    runs_root: Path

    @classmethod
    def at(cls, out: str | Path, runs_dir: str | Path | None = None) -> OutputLayout:
        out = Path(out).resolve()
        return cls(out, Path(runs_dir).resolve() if runs_dir else out / "runs")

    @classmethod
    def open(cls, out: str | Path) -> OutputLayout:
        """The layout of an existing output folder; its runs_dir comes from reproduce.json.

        A relative `out` that does not exist here is also looked for from the parent folders
        (a notebook runs in notebooks/, the default output lies in the repository's root).
        """
        given = Path(out)
        candidates = [given]
        if not given.is_absolute():
            candidates += [parent / given for parent in Path.cwd().parents]
        for path in candidates:
            manifest = path / "reproduce.json"
            if manifest.is_file():
                data = json.loads(manifest.read_text())
                return cls.at(path, data.get("runs_dir"))
        raise FileNotFoundError(
            f"no `curious reproduce` output at {out} (no reproduce.json there or above the "
            "current folder): run `curious reproduce` first, or pass the output folder"
        )

    @property
    def manifest(self) -> Path:
        return self.out / "reproduce.json"

    def budget_name(self) -> str | None:
        """The budget that made this folder, from reproduce.json (None without one).

        Raises OSError or ValueError on an unreadable manifest. Folders made before budgets were
        named apart from training presets call it `preset`.
        """
        if not self.manifest.is_file():
            return None
        manifest = json.loads(self.manifest.read_text())
        name = (
            manifest.get("budget", manifest.get("preset")) if isinstance(manifest, dict) else None
        )
        if not isinstance(name, str):
            raise ValueError("it names no budget")
        return name

    @property
    def figures(self) -> Path:
        return self.out / "figures"

    @property
    def metrics_dir(self) -> Path:
        return self.out / "metrics"

    @property
    def report(self) -> Path:
        return self.out / "report.md"

    @property
    def dagster_home(self) -> Path:
        return self.out / ".dagster"

    def metrics(self, experiment: str) -> Path:
        return self.metrics_dir / f"{experiment}.parquet"

    def tests(self, experiment: str) -> Path:
        """The combined test rollouts of an experiment's runs (`curious.analysis.load_tests`)."""
        return self.metrics_dir / f"{experiment}.tests.parquet"

    def experiment_runs(self, experiment: str) -> Path:
        return self.runs_root / experiment


def _print(message: str) -> None:
    from tqdm.auto import tqdm

    tqdm.write(message, file=sys.stderr)


@dataclass
class Reproduction:
    """Shared by every asset: budget, output layout, the training pool and the display."""

    budget: ReproduceBudget
    layout: OutputLayout
    make_pool: Callable[[], Pool]
    overrides: dict[str, Any] = field(default_factory=dict)
    record: bool = True
    progress: bool = True
    say: Callable[[str], None] = _print
    results: list[PartitionResult] = field(default_factory=list)
    _pool: Pool | None = None

    @property
    def pool(self) -> Pool:
        if self._pool is None:
            self._pool = self.make_pool()
        return self._pool

    def close(self) -> None:
        if self._pool is not None:
            self._pool.close()
            self._pool = None

    def experiment(self, name: str) -> Experiment:
        return self.budget.experiments[name]

    def train(self, experiment: Experiment, specs: Sequence[RunSpec]) -> list[PartitionResult]:
        """Bring every run of `specs` to its budget on the pool, with a progress bar.

        Runs whose folders already hold the finished run are not sent to the pool at all.
        """

        root = self.layout.runs_root
        results: dict[str, PartitionResult] = {}
        todo: list[Job] = []
        for spec in specs:
            if folder_state(spec, root, self.overrides) == FINISHED:
                folder = run_folder(spec, root)
                results[spec.partition_key] = PartitionResult(
                    spec.partition_key, str(folder), FINISHED, episodes_logged(folder), 0.0, False
                )
            else:
                todo.append(Job(spec, str(root), dict(self.overrides), self.record))
        if results:
            self.say(f"  {experiment.name}: {len(results)} run(s) already finished, not retrained")
        if todo:
            results.update(self._train(experiment, todo))
        ordered = [results[s.partition_key] for s in specs]
        self.results.extend(ordered)
        return ordered

    def _train(self, experiment: Experiment, jobs: list[Job]) -> dict[str, PartitionResult]:
        from tqdm.auto import tqdm

        bar = tqdm(
            total=sum(j.spec.total_episodes for j in jobs),
            unit="ep",
            desc=f"{experiment.name} ({len(jobs)} runs)",
            disable=not self.progress,
            dynamic_ncols=True,
            file=sys.stderr,
        )
        tic = time.perf_counter()
        done = {"trained": 0}

        def on_progress(seen: int, _total: int) -> None:
            bar.update(seen - bar.n)
            bar.set_postfix(done, refresh=False)

        def on_done(job: Job, result: PartitionResult) -> None:
            done["trained"] += 1
            how = "resumed, " if result.state_before == PARTIAL else ""
            self.say(
                f"  {job.spec.label}: {how}{result.episodes:,} episodes in {result.seconds:.0f} s"
            )

        try:
            results = run_all(self.pool, jobs, on_progress, on_done)
        finally:
            bar.close()
        self.say(
            f"  {experiment.name}: {len(results)} run(s) trained in "
            f"{time.perf_counter() - tic:.0f} s on {self.pool.description}"
        )
        return {r.partition_key: r for r in results}
