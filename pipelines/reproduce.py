"""Materialise a budget in process, on a Dagster instance kept in the output folder.

`reproduce(...)` is what `curious reproduce` runs:

1. takes the output folder's lock (a second reproduction of the same folder is refused at once
   while this one goes on), then checks everything it can before writing anything: the budget
   and experiments exist; the output folder is new, empty, or was made by the same budget
   (`reproduce.json`); every run
   folder is empty, or holds (part of) the very run its partition should hold; the Ray cluster,
   if one is named, answers;
2. for each experiment, one Dagster run materialises its `runs` asset over all its partitions
   (trained side by side on the pool, a run a process or a Ray task; finished ones are
   skipped, interrupted ones resume);
3. one Dagster run materialises the metrics tables, the figures and `report.md`.

With `from_data` (`curious reproduce --from-data DATA`), step 2 trains nothing: the runs are read
from a shipped data folder (`curious ship`, `pipelines.from_data`), which stands for the runs
root, and steps 1 and 3 are the same. OUT's reproduce.json records DATA, so an output folder
holds either trained runs' results or shipped data's, never both.

The Dagster instance lives in `OUT/.dagster` (sqlite storage, no server, no daemon), so the
history of materialisations is kept with the results and the Dagster UI
(`dagster-webserver -h 127.0.0.1 -m pipelines.code_location`, this machine only) can show it.
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
from pathlib import Path
from typing import TYPE_CHECKING, Any

from curious.reproduction.experiments import (
    Experiment,
    ExperimentError,
    ReproduceBudget,
    get_budget,
)
from curious.reproduction.figures import figures_of
from curious.runs.folder import RunFolder
from curious.runs.folder_errors import RunFolderBusy, RunFolderError
from curious.runs.folder_lock import check_writable, folder_lock
from curious.runs.shipped_folder import shipped_root
from pipelines.executors import busy_description, gpu_sharing_hint
from pipelines.executors import make_pool as default_pool
from pipelines.from_data import ShippedData, ShippedDataError
from pipelines.resources import OutputLayout, Reproduction
from pipelines.training import PartitionResult, RunFolderMismatch, check_not_busy

if TYPE_CHECKING:
    from pipelines.from_data import ShippedData

MANIFEST_VERSION = 1
_COMPUTE_LOGS = (
    "compute_logs:\n"
    "  module: dagster._core.storage.noop_compute_log_manager\n"
    "  class: NoOpComputeLogManager\n"
)
_DAGSTER_YAML = "telemetry:\n  enabled: false\nnux:\n  enabled: false\n" + _COMPUTE_LOGS
"""The instance's settings: no telemetry, no "join the community" dialog in the Dagster UI (its
`nux`), and no capture of the steps' output, which Dagster makes with `tail` and watcher
processes that a Ctrl-C reaches too (each printing a traceback); the runs' own files and the
materialisations keep what a step did. A user turns telemetry on by editing the file, which is
then left as it is."""
_OLD_DAGSTER_YAMLS = (
    "telemetry:\n  enabled: false\n",
    "telemetry:\n  enabled: false\n" + _COMPUTE_LOGS,
)
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
    from_data: Path | None = None
    """The shipped data folder the runs were read from (None: trained)."""
    retried: dict[str, list[str]] = field(default_factory=dict)
    """Run label -> why and from where it was submitted again after its worker was lost."""

    @property
    def trained(self) -> list[PartitionResult]:
        return [r for r in self.results if r.trained]

    @property
    def skipped(self) -> list[PartitionResult]:
        return [r for r in self.results if not r.trained]


def check_output_folder(
    layout: OutputLayout, budget: ReproduceBudget, from_data: Path | None = None
) -> None:
    """Raise `ReproduceError` unless OUT is absent, empty, or made by `budget`, from the same
    shipped data folder (`from_data`) or, without one, from trained runs."""
    out = layout.out
    if out.exists() and not out.is_dir():
        raise ReproduceError(f"--out {out} exists and is not a folder")
    _refuse_shipped("--out", out)
    if layout.manifest.is_file():
        try:
            made_by = layout.budget_name()
            made_from = layout.read_manifest().get("from_data")
        except (OSError, ValueError) as exc:
            raise ReproduceError(f"{layout.manifest} is unreadable ({exc})") from None
        if made_by != budget.name:
            raise ReproduceError(
                f"{out} holds the output of budget {made_by!r}, not {budget.name!r}: pass "
                f"--budget {made_by} to go on with it, or choose another --out "
                f"(default for {budget.name}: {budget.default_out})"
            )
        given = None if from_data is None else str(from_data)
        if made_from != given:
            made = f"from the shipped data in {made_from}" if made_from else "by training"
            asked = f"from {given}" if given else "by training"
            raise ReproduceError(
                f"{out} holds a reproduction made {made}, not {asked}: choose another --out"
            )
        recorded = layout.recorded_runs_dir()
        runs_root = out / "runs" if recorded is None else Path(recorded).resolve()
        if from_data is None and runs_root != layout.runs_root:
            raise ReproduceError(
                f"{out} holds a reproduction whose runs are in {runs_root}, not "
                f"{layout.runs_root}: pass --runs-dir {runs_root}, or leave --runs-dir out, to "
                "go on with them, or choose another --out"
            )
    elif out.is_dir() and any(out.iterdir()):
        raise ReproduceError(
            f"{out} is not empty and was not made by `curious reproduce` (no "
            f"{layout.manifest.name}): choose another --out"
        )
    if from_data is None:  # from shipped data, the folder read stands for the runs
        _refuse_shipped("--runs-dir", layout.runs_root)


def _refuse_shipped(option: str, path: Path) -> None:
    """A `ReproduceError` where `path`, which a reproduction writes in, is or lies in a shipped
    data folder: that holds finished runs' tables only, which a new ship replaces."""
    shipped = shipped_root(path)
    if shipped is not None:
        what = "is a shipped data folder"
        if shipped != path.resolve():
            what = f"lies in the shipped data folder {shipped}"
        raise ReproduceError(
            f"{option} {path} {what} (finished runs' tables only): choose another {option}"
        )


def check_runs(reproduction: Reproduction, experiments: Sequence[Experiment]) -> dict[str, int]:
    """Every partition's folder state, counted; raises `RunFolderMismatch` for a stranger.

    Every run's config is resolved first, so a bad override fails before anything is written.
    Reading shipped data, every run must be shipped finished (`ReproduceError` else).
    """
    counts: dict[str, int] = {}
    for experiment in experiments:
        if reproduction.data is not None and (lacks := reproduction.data.missing(experiment)):
            raise ReproduceError(
                f"{reproduction.data.path} lacks runs of {experiment.name}: {', '.join(lacks)}"
            )
        for spec in experiment.runs():
            spec.config(reproduction.overrides)
            if reproduction.data is None:
                check_not_busy(spec, reproduction.layout.runs_root)
            state = reproduction.run_state(spec)
            counts[state] = counts.get(state, 0) + 1
    return counts


def _write_manifest(
    layout: OutputLayout,
    budget: ReproduceBudget,
    from_data: Path | None = None,
    at_once: int | None = None,
) -> None:
    """OUT/reproduce.json: the budget, where the runs lie, the shipped data read, and `at_once`,
    how many runs train side by side on this machine (`curious progress` reads it for the hours
    left; None on Ray or from shipped data, where it is left out)."""
    layout.out.mkdir(parents=True, exist_ok=True)
    data: dict[str, Any] = {"version": MANIFEST_VERSION, "budget": budget.name}
    if layout.runs_root != layout.out / "runs":
        data["runs_dir"] = str(layout.runs_root)
    if from_data is not None:
        data["from_data"] = str(from_data)
    if at_once is not None:
        data["at_once"] = at_once
    if layout.manifest.is_file():
        old = json.loads(layout.manifest.read_text())
        if old.get("extra_seeds") and old.get("budget") == budget.name:
            data["extra_seeds"] = old["extra_seeds"]  # a campaign's plan (tools/campaign.py)
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
    if not config.exists() or config.read_text() in _OLD_DAGSTER_YAMLS:
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
    from_data: str | os.PathLike | None = None,
    before_training: Callable[[], None] | None = None,
) -> ReproduceResult:
    """Train and draw everything `budget` asks for (see the module docstring).

    `make_pool` builds the training pool (`pipelines.executors.make_pool`); it is called before
    anything is written, so that a Ray cluster that does not answer fails first. `overrides`
    change single training settings of every run (`--device`); `say` prints progress lines.
    `before_training` is called once every check has passed, before anything is trained (the
    README's job builds the shipped campaign's report there). While it runs, OUT is locked
    against a second reproduction (`ReproduceError`).

    With `from_data`, a shipped data folder (`curious ship`), nothing is trained: the runs are
    read from it (`pipelines.from_data`), by default every experiment it holds complete, into
    OUT (default `runs/<budget>-shipped`); `runs_dir`, `make_pool` and `overrides` must be
    None.
    """
    tic = time.perf_counter()
    chosen = get_budget(budget)
    data = None
    if from_data is not None:
        if runs_dir is not None or make_pool is not None or overrides:
            raise ReproduceError(
                "--from-data reads shipped runs: it takes no --runs-dir, pool or training setting"
            )
        data, chosen, selected = _shipped_data(from_data, chosen, experiments)
        layout = OutputLayout.at(out or f"{chosen.default_out}-shipped", data.path)
    else:
        selected = chosen.select(experiments)
        out = out or chosen.default_out
        if runs_dir is None:  # a reproduction started with --runs-dir goes on there
            runs_dir = OutputLayout.at(out).recorded_runs_dir()
        layout = OutputLayout.at(out, runs_dir)
        _check_places(layout)
    _check_writable(layout)
    with _reproduction_lock(layout):
        return _reproduce(
            chosen, selected, layout, make_pool, overrides, record, progress, say, tic, data,
            before_training,
        )  # fmt: skip


def _shipped_data(
    path: str | os.PathLike, budget: ReproduceBudget, experiments: Sequence[str] | None
) -> tuple[ShippedData, ReproduceBudget, list[Experiment]]:
    """The shipped data folder at `path`, checked against `budget`, the budget as it can stand
    for it (`ShippedData.stands_for`) and the experiments to build from it; `ReproduceError`
    where it cannot stand for them."""
    try:
        data = ShippedData.open(path)
        data.check_budget(budget)
        budget = data.stands_for(budget)
        return data, budget, data.select(budget, experiments)
    except ShippedDataError as exc:
        raise ReproduceError(str(exc)) from None


def _check_places(layout: OutputLayout) -> None:
    """A `ReproduceError`, before anything is written, where OUT or the runs folder lies in a
    run folder (the search for runs stops at one, so nothing trained there would be found), or
    where the runs folder is another reproduction's output (its runs lie in its own runs folder:
    naming the output instead would train every run anew beside them)."""
    for option, path in (("--out", layout.out), ("--runs-dir", layout.runs_root)):
        for folder in (path, *path.parents):
            if RunFolder(folder).holds_a_run:
                raise ReproduceError(
                    f"{option} {path} lies in the run folder {folder}, where no search for runs "
                    f"would find what this trains: choose another {option}"
                )
    other = OutputLayout.at(layout.runs_root)
    if layout.runs_root != layout.out and other.manifest.is_file():
        raise ReproduceError(
            f"--runs-dir {layout.runs_root} is a reproduction's output ({other.manifest.name}), "
            f"not the folder of its runs: name that ({other.runs_root}, unless it was started "
            "with a --runs-dir of its own)"
        )


def _check_writable(layout: OutputLayout) -> None:
    """A `ReproduceError` naming `--out` where OUT (its lock beside it, its report and figures
    in it) cannot be written, before anything is locked or trained."""
    try:
        check_writable(layout.out, "--out", folder=True)
    except RunFolderError as exc:
        raise ReproduceError(str(exc)) from None


@contextlib.contextmanager
def _reproduction_lock(layout: OutputLayout) -> Iterator[None]:
    """Hold OUT's lock for the whole reproduction: a second `curious reproduce` of the same
    folder is refused at once (`ReproduceError`) while the first goes on; nothing is left
    behind (`curious.runs.folder_lock.folder_lock`)."""
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
    data: ShippedData | None = None,
    before_training: Callable[[], None] | None = None,
) -> ReproduceResult:
    import dagster as dg

    from pipelines.assets import figure_key, metrics_key, partitions_of, runs_key
    from pipelines.definitions import build_definitions

    check_output_folder(layout, chosen, None if data is None else data.path)
    repro = Reproduction(
        budget=chosen,
        layout=layout,
        make_pool=make_pool or (lambda: default_pool(None)),
        overrides=dict(overrides or {}),
        record=record,
        progress=progress,
        data=data,
    )
    if say is not None:
        repro.say = say
    counts = check_runs(repro, selected)
    names = ", ".join(e.name for e in selected)
    if data is not None:
        repro.say(
            f"curious reproduce --budget {chosen.name} --from-data {data.path}: {names}; "
            f"{sum(counts.values())} shipped runs read, none trained"
        )
    else:
        pool = repro.pool  # connects to Ray (or fails) before anything is written
        if before_training is not None:
            before_training()
        to_train = counts.get("partial", 0) + counts.get("new", 0)
        repro.say(
            f"curious reproduce --budget {chosen.name}: {names}; "
            f"{sum(counts.values())} runs ({counts.get('finished', 0)} finished, "
            f"{counts.get('partial', 0)} to resume, {counts.get('new', 0)} new) on "
            f"{busy_description(pool, to_train)}"
        )
        hint = gpu_sharing_hint(pool, repro.overrides.get("device"))
        if hint is not None:
            repro.say(hint)
    local = data is None and repro.pool.local
    at_once = getattr(repro.pool, "workers", None) if local else None  # a LocalPool's
    _write_manifest(layout, chosen, None if data is None else data.path, at_once)
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
                        *(figure_key(e.name, f.name) for f in figures_of(e.name)),
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
        repro.say_retried()
        repro.close()
    return ReproduceResult(
        budget=chosen.name,
        experiments=[e.name for e in selected],
        layout=layout,
        results=list(repro.results),
        seconds=time.perf_counter() - tic,
        from_data=None if data is None else data.path,
        retried=dict(repro.retried),
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
