"""Materialise a budget in process, on a Dagster instance kept in the output folder.

`reproduce(...)` is what `curious reproduce` runs:

1. takes the output folder's lock (a second reproduction of the same folder is refused at once
   while this one goes on), then checks everything it can before writing anything: the budget
   and experiments exist; the output folder is new, empty, or was made by the same budget
   (`reproduce.json`); every run
   folder is empty, or holds (part of) the very run its partition should hold; the Ray cluster,
   if one is named, answers;
2. for each experiment, one Dagster run materialises its `runs` asset over all its partitions
   (trained side by side on the pool; finished ones are skipped, interrupted ones resume);
3. one Dagster run materialises the metrics tables, the figures and `report.md`.

The Dagster instance lives in `OUT/.dagster` (sqlite storage, no server, no daemon), so the
history of materialisations is kept with the results and `dagster dev` can show it.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

from curious.experiments import Experiment, ExperimentError, ReproduceBudget, get_budget
from pipelines.resources import OutputLayout, Reproduction
from pipelines.training import PartitionResult, RunFolderMismatch, check_not_busy, folder_state

MANIFEST_VERSION = 1
_DAGSTER_YAML = (
    "telemetry:\n"
    "  enabled: false\n"
    "compute_logs:\n"
    "  module: dagster._core.storage.noop_compute_log_manager\n"
    "  class: NoOpComputeLogManager\n"
)
"""The instance's settings: no telemetry, and no capture of the steps' output, which Dagster
makes with `tail` and watcher processes that a Ctrl-C reaches too (each printing a traceback);
the runs' own files and the materialisations keep what a step did."""
_OLD_DAGSTER_YAML = "telemetry:\n  enabled: false\n"
"""What earlier versions wrote (replaced by `open_instance`)."""
_QUIET_LOGS = {"loggers": {"console": {"config": {"log_level": "CRITICAL"}}}}
"""Dagster's console logger stays silent: a failure reaches the user as one line from
`curious reproduce` (the event log in OUT/.dagster keeps Dagster's account of it)."""


class ReproduceError(RuntimeError):
    """The output folder cannot be used for this budget (nothing was written)."""


@dataclass
class ReproduceResult:
    """What a call of `reproduce` did, and where its products are."""

    budget: str
    experiments: list[str]
    layout: OutputLayout
    results: list[PartitionResult] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def trained(self) -> list[PartitionResult]:
        return [r for r in self.results if r.trained]

    @property
    def skipped(self) -> list[PartitionResult]:
        return [r for r in self.results if not r.trained]


def check_output_folder(layout: OutputLayout, budget: ReproduceBudget) -> None:
    """Raise `ReproduceError` unless OUT is absent, empty, or made by `budget`."""
    out = layout.out
    if out.exists() and not out.is_dir():
        raise ReproduceError(f"--out {out} exists and is not a folder")
    if layout.manifest.is_file():
        try:
            made_by = layout.budget_name()
        except (OSError, ValueError) as exc:
            raise ReproduceError(f"{layout.manifest} is unreadable ({exc})") from None
        if made_by != budget.name:
            raise ReproduceError(
                f"{out} holds the output of budget {made_by!r}, not {budget.name!r}: pass "
                f"--budget {made_by} to go on with it, or choose another --out "
                f"(default for {budget.name}: {budget.default_out})"
            )
        return
    if out.is_dir() and any(out.iterdir()):
        raise ReproduceError(
            f"{out} is not empty and was not made by `curious reproduce` (no "
            f"{layout.manifest.name}): choose another --out"
        )


def check_runs(reproduction: Reproduction, experiments: Sequence[Experiment]) -> dict[str, int]:
    """Every partition's folder state, counted; raises `RunFolderMismatch` for a stranger.

    Every run's config is resolved first, so a bad override fails before anything is written.
    """
    counts: dict[str, int] = {}
    for experiment in experiments:
        for spec in experiment.runs():
            spec.config(reproduction.overrides)
            check_not_busy(spec, reproduction.layout.runs_root)
            state = folder_state(spec, reproduction.layout.runs_root, reproduction.overrides)
            counts[state] = counts.get(state, 0) + 1
    return counts


def _write_manifest(layout: OutputLayout, budget: ReproduceBudget) -> None:
    layout.out.mkdir(parents=True, exist_ok=True)
    data: dict[str, Any] = {"version": MANIFEST_VERSION, "budget": budget.name}
    if layout.runs_root != layout.out / "runs":
        data["runs_dir"] = str(layout.runs_root)
    if layout.manifest.is_file():
        old = json.loads(layout.manifest.read_text())
        if old == data:
            return
    tmp = layout.manifest.with_name(f".{layout.manifest.name}.tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n")
    os.replace(tmp, layout.manifest)


def open_instance(layout: OutputLayout):
    """The persistent Dagster instance in OUT/.dagster (created on first use)."""
    from dagster import DagsterInstance
    from dagster._core.instance.ref import InstanceRef

    home = layout.dagster_home
    home.mkdir(parents=True, exist_ok=True)
    config = home / "dagster.yaml"
    if not config.exists() or config.read_text() == _OLD_DAGSTER_YAML:
        config.write_text(_DAGSTER_YAML)
    return DagsterInstance.from_ref(InstanceRef.from_dir(str(home)))


@contextlib.contextmanager
def _logging_handlers_kept() -> Any:
    """Keep the process's logging handlers open through a Dagster run.

    An instance with settings (ours turns telemetry off) builds its log handlers with
    `logging.config.dictConfig` at the start of every run, and dictConfig first closes every
    handler registered in the process: a notebook's, absl's (whose `close` also closes the stream
    it writes to, which may be a test runner's capture file), the caller's own. For the length of
    the run the existing handlers are taken off logging's registry, so that dictConfig does not
    see them; they stay attached to their loggers and keep working, and go back on the registry
    (which `logging.shutdown` closes at exit) afterwards.
    """
    with logging._lock:  # the registry is private to logging; its shape is stable since 2.x
        kept, named = logging._handlerList[:], dict(logging._handlers)
        del logging._handlerList[:]
        logging._handlers.clear()
    try:
        yield
    finally:
        with logging._lock:
            logging._handlerList[:0] = [ref for ref in kept if ref() is not None]
            for name, handler in named.items():
                logging._handlers.setdefault(name, handler)


def _materialize(defs, instance, selection, tags: dict[str, str] | None = None) -> None:
    """Materialise `selection` in this process; a Ctrl-C, which Dagster turns into its own
    `DagsterExecutionInterruptedError` (not a `KeyboardInterrupt`), comes out as the
    `KeyboardInterrupt` it was."""
    import dagster as dg
    from dagster._core.errors import DagsterExecutionInterruptedError

    assets = list(defs.assets or [])
    with _logging_handlers_kept():
        try:
            result = dg.materialize(
                assets,
                instance=instance,
                resources=dict(defs.resources or {}),
                selection=selection,
                tags=tags,
                run_config=_QUIET_LOGS,
                raise_on_error=True,
            )
        except DagsterExecutionInterruptedError:
            raise KeyboardInterrupt from None
    if not result.success:  # pragma: no cover - raise_on_error raises first
        raise RuntimeError("a Dagster run failed")


def reproduce(
    budget: str,
    experiments: Sequence[str] | None = None,
    out: str | os.PathLike | None = None,
    runs_dir: str | os.PathLike | None = None,
    make_pool: Callable[[], Any] | None = None,
    overrides: dict[str, Any] | None = None,
    record: bool = True,
    progress: bool = True,
    say: Callable[[str], None] | None = None,
) -> ReproduceResult:
    """Train and draw everything `budget` asks for (see the module docstring).

    `make_pool` builds the training pool (`pipelines.executors.make_pool`); it is called before
    anything is written, so that a Ray cluster that does not answer fails first. `overrides`
    change single training settings of every run (`--device`); `say` prints progress lines.
    While it runs, OUT is locked against a second reproduction (`ReproduceError`).
    """
    tic = time.perf_counter()
    chosen = get_budget(budget)
    selected = chosen.select(experiments)
    layout = OutputLayout.at(out or chosen.default_out, runs_dir)
    with _reproduction_lock(layout):
        return _reproduce(
            chosen, selected, layout, make_pool, overrides, record, progress, say, tic
        )


@contextlib.contextmanager
def _reproduction_lock(layout: OutputLayout) -> Iterator[None]:
    """Hold OUT's lock for the whole reproduction: a second `curious reproduce` of the same
    folder is refused at once (`ReproduceError`) while the first goes on; nothing is left
    behind (`curious.run_folder.folder_lock`)."""
    from curious.run_folder import RunFolderBusy, RunFolderError, folder_lock

    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(folder_lock(layout.out, activity="reproduced"))
        except RunFolderBusy as exc:
            raise ReproduceError(str(exc)) from None
        except RunFolderError as exc:
            raise ReproduceError(f"--out {layout.out}: {exc}") from None
        yield


def _reproduce(
    chosen: ReproduceBudget,
    selected: Sequence[Experiment],
    layout: OutputLayout,
    make_pool: Callable[[], Any] | None,
    overrides: dict[str, Any] | None,
    record: bool,
    progress: bool,
    say: Callable[[str], None] | None,
    tic: float,
) -> ReproduceResult:
    import dagster as dg

    from pipelines.assets import FIGURES, figure_key, metrics_key, partitions_of, runs_key
    from pipelines.definitions import build_definitions
    from pipelines.executors import make_pool as default_pool

    check_output_folder(layout, chosen)
    repro = Reproduction(
        budget=chosen,
        layout=layout,
        make_pool=make_pool or (lambda: default_pool(None)),
        overrides=dict(overrides or {}),
        record=record,
        progress=progress,
    )
    if say is not None:
        repro.say = say
    counts = check_runs(repro, selected)
    pool = repro.pool  # connects to Ray (or fails) before anything is written
    repro.say(
        f"curious reproduce --budget {chosen.name}: {', '.join(e.name for e in selected)}; "
        f"{sum(counts.values())} runs ({counts.get('finished', 0)} finished, "
        f"{counts.get('partial', 0)} to resume, {counts.get('new', 0)} new) on {pool.description}"
    )
    _write_manifest(layout, chosen)
    defs = build_definitions(repro)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", dg.BetaWarning)
            warnings.simplefilter("ignore", dg.PreviewWarning)
            instance = open_instance(layout)
            try:
                for experiment in selected:
                    keys = partitions_of(experiment).get_partition_keys()
                    _materialize(
                        defs,
                        instance,
                        [runs_key(experiment.name)],
                        tags={
                            "dagster/asset_partition_range_start": keys[0],
                            "dagster/asset_partition_range_end": keys[-1],
                            "curious/budget": chosen.name,
                        },
                    )
                downstream = [
                    key
                    for e in selected
                    for key in (
                        metrics_key(e.name),
                        *(figure_key(e.name, f) for f in FIGURES[e.name]),
                    )
                ]
                _materialize(
                    defs,
                    instance,
                    [*downstream, dg.AssetKey("report")],
                    tags={"curious/budget": chosen.name},
                )
            finally:
                instance.dispose()
    finally:
        repro.close()
    return ReproduceResult(
        budget=chosen.name,
        experiments=[e.name for e in selected],
        layout=layout,
        results=list(repro.results),
        seconds=time.perf_counter() - tic,
    )


__all__ = [
    "ExperimentError",
    "ReproduceError",
    "ReproduceResult",
    "RunFolderMismatch",
    "check_output_folder",
    "open_instance",
    "reproduce",
]
