"""The one Dagster resource the assets share: where things live and where training runs.

`Reproduction` is a plain object handed to Dagster as the `reproduction` resource. It knows the
budget, the output folder's layout and the pool that trains partitions (created on
first use, so building the definitions, e.g. for the Dagster UI, starts no process and contacts no
cluster), or the shipped data folder read in place of training (`curious reproduce --from-data`,
`pipelines.from_data`).

It sends an experiment's runs still to train to the pool, one run a job, in the budget's order,
on this machine no more at a time than fit in its memory together (`Reproduction.at_once`).

Output folder layout (`OutputLayout`):

    OUT/reproduce.json          which budget made this folder (checked on every later call)
    OUT/runs/<experiment>/<condition>/seed-<s>/    run folders (or --runs-dir on shared storage;
                                                   with --from-data, the shipped data folder)
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
from typing import TYPE_CHECKING, Any

from curious.reproduction.experiments import Experiment, ReproduceBudget, RunSpec
from curious.runs.memory import runs_that_fit
from curious.runs.shipped_folder import ShippedFolder
from pipelines.executors import Job, Pool, busy_description, run_all
from pipelines.from_data import ShippedDataError
from pipelines.training import (
    FINISHED,
    PARTIAL,
    PartitionResult,
    episodes_logged,
    folder_state,
    run_folder,
)

if TYPE_CHECKING:
    import pandas as pd

    from pipelines.from_data import ShippedData


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
        """The layout of an existing output folder; its runs_dir comes from reproduce.json. A
        shipped data folder (`curious.runs.shipped_folder`) opens too, as its own runs
        root: the notebooks take either as their `out`.

        A relative `out` that does not exist here is also looked for from the parent folders
        (a notebook runs in notebooks/, the default output lies in the repository's root).
        """
        given = Path(out)
        candidates = [given]
        if not given.is_absolute():
            candidates += [parent / given for parent in Path.cwd().parents]
        for path in candidates:
            layout = cls.at(path)
            if layout.manifest.is_file():
                return cls.at(path, layout.manifest_runs_dir())
            if ShippedFolder(path).is_shipped:  # its runs lie in it, as in a runs root
                return cls.at(path, path)
        raise FileNotFoundError(
            f"no `curious reproduce` output or shipped data folder at {out} (no reproduce.json "
            "or shipped.json there or above the current folder): run `curious reproduce` "
            "first, or pass the output folder"
        )

    @property
    def manifest(self) -> Path:
        return self.out / "reproduce.json"

    def read_manifest(self) -> dict[str, Any]:
        """reproduce.json's content: OSError where it cannot be read, ValueError where it is not
        a JSON object."""
        data = json.loads(self.manifest.read_text())
        if not isinstance(data, dict):
            raise ValueError("it is not a JSON object")
        return data

    def manifest_runs_dir(self) -> str | None:
        """The runs folder reproduce.json records (None: the folder's own runs/); a ValueError
        naming the file where it cannot be read or its runs_dir is not a folder path."""
        try:
            recorded = self.read_manifest().get("runs_dir")
        except (OSError, ValueError) as exc:
            raise ValueError(f"{self.manifest} is unreadable ({exc})") from None
        if recorded is not None and not isinstance(recorded, str):
            raise ValueError(
                f"{self.manifest} is damaged: runs_dir must be a folder path, got {recorded!r}"
            )
        return recorded or None

    def recorded_runs_dir(self) -> str | None:
        """`manifest_runs_dir`, or None where reproduce.json is unreadable or damaged
        (`pipelines.reproduce.check_output_folder` names it)."""
        try:
            return self.manifest_runs_dir()
        except ValueError:
            return None

    def budget_name(self) -> str | None:
        """The budget that made this folder, from reproduce.json (None without one).

        Raises OSError or ValueError on an unreadable manifest. Folders made before budgets were
        named apart from training presets call it `preset`. A shipped data folder's budget is
        its shipped.json's.
        """
        if not self.manifest.is_file():
            shipped = ShippedFolder(self.out)
            return shipped.read_manifest().budget if shipped.is_shipped else None
        manifest = self.read_manifest()
        name = manifest.get("budget", manifest.get("preset"))
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

    def read_tables(self, experiment: str) -> tuple[pd.DataFrame | None, pd.DataFrame | None]:
        """(metrics, tests) an experiment's `metrics` asset wrote here, each None where it wrote
        none (not trained here, or not finished): what a figure or a report section that reads
        another experiment draws beside its own runs (`FigureSpec.reads`)."""
        import pandas as pd

        metrics, tests = self.metrics(experiment), self.tests(experiment)
        if not metrics.is_file():
            return None, None
        return pd.read_parquet(metrics), pd.read_parquet(tests) if tests.is_file() else None


def _print(message: str) -> None:
    from tqdm.auto import tqdm  # it picks notebook or console bars, and warns, when imported

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
    data: ShippedData | None = None
    """The shipped data folder read instead of training (`curious reproduce --from-data`); its
    path is the layout's runs root."""
    retried: dict[str, list[str]] = field(default_factory=dict)
    """Run label -> why and from where it was submitted again, each time its worker was lost
    (`pipelines.executors.run_all`), in order."""
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

    def say_retried(self) -> None:
        """A line for each run submitted again after its worker was lost: how often, and each
        time why and from where (said at the end of a reproduction, whatever ended it)."""
        if not self.retried:
            return
        self.say(f"{len(self.retried)} run(s) submitted again after their worker was lost:")
        for label, notes in self.retried.items():
            times = "once" if len(notes) == 1 else f"{len(notes)} times"
            self.say(f"  {label}: {times}: {' | '.join(notes)}")

    def experiment(self, name: str) -> Experiment:
        return self.budget.experiments[name]

    def left_out_runs(self, experiment: Experiment) -> list[Path]:
        """The run folders of the variants the experiment leaves out that shipped data holds
        finished for every condition (`ShippedData.left_out_runs`; none when training): the
        distractors figure and the report show them beside the experiment's, untested."""
        if self.data is None:
            return []
        return [run_folder(s, self.layout.runs_root) for s in self.data.left_out_runs(experiment)]

    def run_state(self, spec: RunSpec) -> str:
        """`new`, `partial` or `finished`: of the run folder (`pipelines.training.folder_state`),
        or of the shipped run where the runs are read from shipped data
        (`pipelines.from_data.ShippedData.state`)."""
        if self.data is not None:
            return self.data.state(spec)
        return folder_state(spec, self.layout.runs_root, self.overrides)

    def train(self, experiment: Experiment, specs: Sequence[RunSpec]) -> list[PartitionResult]:
        """Bring every run of `specs` to its budget on the pool, with a progress bar.

        Runs whose folders already hold the finished run are not sent to the pool at all; the
        others go a run a job, in the order of `specs` (the budget's, so that a reproduction
        stopped part-way holds comparable seeds). From shipped data nothing is trained, and a
        run that is not there finished is an error.
        """
        if self.data is not None:
            return self._read_shipped(experiment, specs)
        root = self.layout.runs_root
        results: dict[str, PartitionResult] = {}
        todo: list[RunSpec] = []
        for spec in specs:
            if folder_state(spec, root, self.overrides) == FINISHED:
                folder = run_folder(spec, root)
                results[spec.partition_key] = PartitionResult(
                    spec.partition_key, str(folder), FINISHED, episodes_logged(folder), 0.0, False
                )
            else:
                todo.append(spec)
        if results:
            self.say(f"  {experiment.name}: {len(results)} run(s) already finished, not retrained")
        if todo:
            jobs = [Job(spec, str(root), dict(self.overrides), self.record) for spec in todo]
            results.update(self._train(experiment, jobs))
        ordered = [results[s.partition_key] for s in specs]
        self.results.extend(ordered)
        return ordered

    def _read_shipped(
        self, experiment: Experiment, specs: Sequence[RunSpec]
    ) -> list[PartitionResult]:
        """The shipped runs of `specs`, checked to be there and finished; nothing is trained."""
        assert self.data is not None
        lacking = [s for s in specs if self.data.state(s) != FINISHED]
        if lacking:
            raise ShippedDataError(
                f"{self.data.path} lacks finished runs of {experiment.name}: "
                + ", ".join(str(s.relative_path) for s in lacking)
            )
        results = []
        for spec in specs:
            entry = self.data.manifest.get(spec.relative_path)
            assert entry is not None
            folder = run_folder(spec, self.layout.runs_root)
            results.append(
                PartitionResult(
                    spec.partition_key, str(folder), FINISHED, entry.episodes, 0.0, False, "shipped"
                )
            )
        self.say(f"  {experiment.name}: {len(results)} shipped run(s) read from {self.data.path}")
        self.results.extend(results)
        return results

    def at_once(self, jobs: Sequence[Job]) -> int | None:
        """Jobs trained at a time on this machine: as many, in order, as fit in its memory
        together (`curious.runs.memory.runs_that_fit`), since each run checks its own memory as
        it starts, not that of the runs beside it, and a `paper` run's replay grows to about
        5 GB; None on Ray, whose tasks hold their nodes' memory."""
        if not self.pool.local:
            return None

        return runs_that_fit([job.spec.config(self.overrides) for job in jobs])

    def _train(self, experiment: Experiment, jobs: list[Job]) -> dict[str, PartitionResult]:
        from tqdm.auto import tqdm  # it picks notebook or console bars, and warns, when imported

        bar = tqdm(
            total=sum(job.spec.total_episodes for job in jobs),
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

        def on_retry(job: Job, note: str) -> None:
            self.retried.setdefault(job.spec.label, []).append(note)
            self.say(f"  {job.spec.label}: {note}")

        at_once = self.at_once(jobs)
        try:
            results = run_all(
                self.pool, jobs, on_progress, on_done, at_once=at_once, on_retry=on_retry
            )
        finally:
            bar.close()
        busy = busy_description(self.pool, min(len(jobs), at_once or len(jobs)))
        self.say(
            f"  {experiment.name}: {len(results)} run(s) trained in "
            f"{time.perf_counter() - tic:.0f} s on {busy}"
        )
        return {r.partition_key: r for r in results}
