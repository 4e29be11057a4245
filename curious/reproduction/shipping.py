"""Ship runs: the run folders below a folder, reduced to a shipped data folder
(`curious.runs.shipped_folder`).

`ship(root, out)` finds every run folder below `root` and ships the finished ones: every episode
of the run's budget logged and a checkpoint taken at the end (`RunFolder.finished_at`, how
`curious reproduce` judges a partition finished). With `unfinished=True` the others go too,
marked as unfinished in `shipped.json` (a progress snapshot); a run that has not logged an
episode has no tables and is never shipped. With `keep=True` the runs an earlier ship put in
`out` stay there unless this one ships them again: a campaign whose machine lost the folders of
runs it had shipped goes on adding runs to the same data folder (a run shipped finished is never
replaced by an unfinished one of the same path).

The new folder is written beside `out`, loaded back with `curious.analysis` (every run, its
episodes and test rollouts counted), and only then put in `out`'s place, so a refused or failed
ship leaves `out` as it was; an `out` holding an earlier shipped folder is replaced as a whole.
A ship stopped by Ctrl-C, SIGTERM or SIGHUP at any step leaves nothing beside `out`: the staging
folder is removed, and the swap into `out`'s place with the removal of the earlier ship runs to
its end before the signal is taken (`signals_held`). What a ship killed outright (SIGKILL, a
lost machine) left beside `out` (its staging folder, the earlier ship it had set aside) is
cleaned by the next ship to the same `out` (`clean_leftovers`).
Nothing below `root` is written. Refused with a `ShippedError` before anything is written: a
`root` that does not exist, holds no run folder, has no finished run (without `unfinished`), or
is a shipped folder itself; an `out` that is a file, a folder holding anything but a shipped
folder of the same budget, inside a run folder, inside `root` (or holding it), or one beside
which nothing can be written (its lock and the new folder are made there).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import pyarrow as pa
import pyarrow.parquet as pq

from curious.runs.folder import RunFolder
from curious.runs.folder_errors import RunFolderBusy, RunFolderError
from curious.runs.folder_layout import CONFIG_FILE, LEARNER_FILE, METRICS_FILE, TESTS_FILE
from curious.runs.folder_lock import check_writable, folder_lock
from curious.runs.shipped_folder import (
    COMPRESSION,
    LEARNER_DROPPED,
    LEVEL,
    MANIFEST_FILE,
    METRICS_DROPPED,
    TESTS_DROPPED,
    ShippedError,
    ShippedFolder,
    ShippedManifest,
    ShippedRun,
    shipped_metadata,
)
from curious.runs.signals import in_main_thread, signals_held


@dataclass(frozen=True)
class ShipResult:
    """What `ship` wrote: the manifest, the runs left out (with why) and the sizes in bytes."""

    out: Path
    manifest: ShippedManifest
    left_out: tuple[str, ...]
    """Runs not shipped, each as `path (why)`."""
    sizes: dict[str, int]
    """Bytes written per file name (`metrics.parquet`, `tests.parquet`, `learner.parquet`,
    `config.json`, `shipped.json`), over every run."""
    seconds: float
    kept: tuple[str, ...] = ()
    """Runs an earlier ship put in `out` that stayed there as they were (`keep`)."""
    unfinished_left_out: int = 0
    """How many of `left_out` had started but not finished (`unfinished` would ship them)."""

    @property
    def bytes(self) -> int:
        return sum(self.sizes.values())


@dataclass(frozen=True)
class _Found:
    folder: RunFolder
    run: PurePosixPath
    episodes: int
    total: int
    finished: bool
    problem: str | None = None
    """Why the run cannot be shipped as it is (a damaged file), or None."""

    @property
    def progress(self) -> str:
        """How far an unfinished run has got, or what is wrong with it, in words."""
        if self.problem is not None:
            return f"{self.run} ({self.problem})"
        if self.episodes == 0:
            return f"{self.run} (not started)"
        if self.episodes >= self.total:
            return f"{self.run} (all {self.total:,} episodes, but no checkpoint at the end)"
        return f"{self.run} ({self.episodes:,} of {self.total:,} episodes)"


def _damage(folder: RunFolder, tests_due: bool) -> str | None:
    """Why a run's metrics.parquet, tests.parquet or learner.parquet that is there cannot be
    read, or why a tests.parquet that is due (`tests_due`: the run finished, and its settings
    ran test rollouts, after every epoch and at the end) is not there; None otherwise."""
    if tests_due and not folder.tests_path.is_file():
        return f"its {folder.tests_path.name} is missing, though the run tested every epoch"
    tables = (folder.metrics_path, folder.tests_path, folder.learner_path)
    present = [p for p in tables if p.is_file()]
    unreadable = RunFolder.unreadable_table(present)
    return None if unreadable is None else f"its {unreadable[0].name} is damaged"


def _inside(path: Path, other: Path) -> bool:
    """Whether `path` is `other` or lies below it (both resolved)."""
    return path == other or other in path.parents


def check_root(root: Path) -> None:
    """A `ShippedError` unless `root` is a folder of runs to ship (not a shipped folder)."""
    if not root.exists():
        raise ShippedError(f"{root} does not exist")
    if not root.is_dir():
        raise ShippedError(f"{root} is a file, not a folder of run folders")
    for folder in (root, *root.parents):
        if ShippedFolder(folder).is_shipped:
            raise ShippedError(
                f"{root} is a shipped data folder ({folder / MANIFEST_FILE}), not the runs it "
                "came from: ship the run folders themselves"
            )


def _check_replaced(out: Path, budget: str | None) -> None:
    """A `ShippedError` where `out` holds runs shipped from another budget than `budget`: a
    ship replaces an earlier ship of the same runs, never another campaign's."""
    if not ShippedFolder(out).is_shipped:
        return
    held = ShippedFolder(out).read_manifest().budget
    if held != budget:

        def runs(name: str | None) -> str:
            return f"the {name} budget's runs" if name else "runs of no reproduction"

        raise ShippedError(
            f"--out {out} holds {runs(held)}, these are {runs(budget)}: shipping there would "
            "replace them; choose another --out (data/<budget>), or remove it first"
        )


def _check_out(out: Path, root: Path) -> None:
    if out.exists() and not out.is_dir():
        raise ShippedError(f"--out {out} exists and is not a folder")
    if _inside(out, root) or _inside(root, out):
        raise ShippedError(
            f"--out {out} and {root} overlap: choose a folder outside the runs (shipped runs are "
            "run folders, and a later search of the runs would find them)"
        )
    for folder in (out, *out.parents):
        if RunFolder(folder).has_config:
            raise ShippedError(f"--out {out} lies inside the run folder {folder}: choose another")
    if out.is_dir() and any(out.iterdir()) and not ShippedFolder(out).is_shipped:
        raise ShippedError(
            f"--out {out} is not empty and holds no shipped data folder (no shipped.json): "
            "choose another, or an earlier `curious ship` output to replace"
        )


def find_runs(root: Path) -> list[_Found]:
    """Every run folder below `root` (or `root` itself), with its episodes and whether it is
    finished; a `ShippedError` naming the folder for a config.json that is not a run's."""
    from curious.analysis.loading import run_path_below, search_run_folders

    folders = [root] if RunFolder(root).has_config else search_run_folders(root, False)
    found = []
    for path in folders:
        folder = RunFolder(path)
        run = run_path_below(path, root)
        try:
            info = folder.read_info()
        except RunFolderError as exc:
            if path == root:  # the one run asked for
                raise ShippedError(str(exc)) from None
            found.append(_Found(folder, run, 0, 0, False, problem=str(exc)))
            continue
        total = info.total_episodes
        finished = folder.finished_at(total)
        tests_due = finished and bool((info.settings or {}).get("test_rollouts_per_worker"))
        found.append(
            _Found(
                folder,
                run,
                folder.episodes_logged(),
                total,
                finished,
                problem=_damage(folder, tests_due),
            )
        )
    return found


def _reduce(source: Path, target: Path, dropped: tuple[str, ...]) -> int:
    """Write `source` without the columns `dropped` to `target` (see
    `curious.runs.shipped_folder`); its rows."""
    table = pq.read_table(source)
    drop = tuple(c for c in dropped if c in table.column_names)
    table = table.drop_columns(list(drop))
    table = table.replace_schema_metadata(
        {**(table.schema.metadata or {}), **shipped_metadata(drop)}
    )
    strings = [f.name for f in table.schema if pa.types.is_string(f.type)]
    pq.write_table(
        table,
        target,
        compression=COMPRESSION,
        compression_level=LEVEL,
        use_dictionary=strings or False,
    )
    return table.num_rows


def _write(
    found: list[_Found],
    target: Path,
    budget: str | None,
    kept: tuple[ShippedRun, ...],
    held: ShippedFolder,
) -> ShippedManifest:
    """The shipped folder of `found` in `target` (an empty folder), with the runs `kept` copied
    as they are from the earlier ship `held`."""
    runs = list(kept)
    for r in kept:
        shutil.copytree(held.run_path(r.run), ShippedFolder(target).run_path(r.run))
    for f in found:
        folder = ShippedFolder(target).run_path(f.run)
        folder.mkdir(parents=True)
        shutil.copyfile(f.folder.config_path, folder / CONFIG_FILE)
        episodes = _reduce(f.folder.metrics_path, folder / METRICS_FILE, METRICS_DROPPED)
        tests = 0
        if f.folder.tests_path.is_file():
            tests = _reduce(f.folder.tests_path, folder / TESTS_FILE, TESTS_DROPPED)
        if f.folder.learner_path.is_file():
            _reduce(f.folder.learner_path, folder / LEARNER_FILE, LEARNER_DROPPED)
        runs.append(ShippedRun(f.run.as_posix(), f.finished, episodes, f.total, tests))
    manifest = ShippedManifest(budget, tuple(sorted(runs, key=lambda r: r.run)))
    ShippedFolder(target).write_manifest(manifest)
    return manifest


def _verify(target: Path, manifest: ShippedManifest) -> None:
    """Load every shipped run as the analysis will, one at a time; a `ShippedError` where one
    does not load or its rows are not the counts shipped."""
    from curious import analysis

    shipped = ShippedFolder(target)
    for r in manifest.runs:
        path = shipped.run_path(r.run)
        try:
            rows = len(analysis.load_runs(path))
            tests = len(analysis.load_tests(path)) if r.test_rollouts else 0
            if analysis.has_learner(path):
                analysis.load_learner(path)
        except analysis.AnalysisError as exc:
            raise ShippedError(f"the shipped run {r.run} does not load: {exc}") from None
        if (rows, tests) != (r.episodes, r.test_rollouts):
            raise ShippedError(
                f"{r.run}: {rows} episodes and {tests} test rollouts load back, "
                f"{r.episodes} and {r.test_rollouts} were shipped"
            )


def _sizes(target: Path) -> dict[str, int]:
    sizes: dict[str, int] = {}
    for path in target.rglob("*"):
        if path.is_file():
            sizes[path.name] = sizes.get(path.name, 0) + path.stat().st_size
    return sizes


@contextlib.contextmanager
def _locked(out: Path) -> Iterator[None]:
    try:
        with folder_lock(out, activity="shipped"):
            yield
    except RunFolderBusy as exc:
        raise ShippedError(str(exc)) from None


def ship(
    root: str | os.PathLike,
    out: str | os.PathLike,
    runs_root: str | os.PathLike | None = None,
    budget: str | None = None,
    unfinished: bool = False,
    keep: bool = False,
) -> ShipResult:
    """Ship the runs below `root` into `out` (see the module docstring). For a reproduction's
    output folder `root`, `runs_root` is where its run folders lie (their paths in `out` are
    relative to it) and `budget` its budget, recorded in `shipped.json`. With `keep`, the runs
    `out` holds that this ship does not replace stay in it."""
    tic = time.perf_counter()
    root, out = Path(root).resolve(), Path(out).resolve()
    runs = Path(runs_root).resolve() if runs_root is not None else root
    check_root(root)
    _check_out(out, root)
    _check_out(out, runs)
    try:  # the lock and the new folder are made beside `out`
        check_writable(out, "--out")
    except RunFolderError as exc:
        raise ShippedError(str(exc)) from None
    _check_replaced(out, budget)
    found = find_runs(runs) if runs.is_dir() else []
    if not found:
        raise ShippedError(f"{root} holds no run folder (no {CONFIG_FILE} below it)")
    damaged = [f for f in found if f.problem is not None]
    whole = [f for f in found if f.problem is None]
    not_started = [f for f in whole if f.episodes == 0]
    running = [f for f in whole if not f.finished and f.episodes > 0]
    chosen = [f for f in whole if f.finished or (unfinished and f.episodes > 0)]
    left_out = [f.progress for f in damaged + not_started]
    if not unfinished:
        left_out += [f.progress for f in running]
    if not chosen:
        detail = ", ".join(sorted(left_out)[:5]) + (", ..." if len(left_out) > 5 else "")
        hint = "; pass --unfinished to ship those started as a progress snapshot"
        hint = hint if running and not unfinished else ""
        raise ShippedError(
            f"none of the {len(found)} run(s) below {runs} is finished ({detail}){hint}"
        )
    with _locked(out), _stopped_by_signals():
        with signals_held():
            clean_leftovers(out)
        _check_out(out, root)  # again, now that no other ship can write it
        _check_replaced(out, budget)
        earlier = ShippedFolder(out)
        held = earlier.read_manifest().runs if keep and earlier.is_shipped else ()
        finished = {r.run for r in held if r.finished}  # never replaced by an unfinished run
        for f in [f for f in chosen if not f.finished and f.run.as_posix() in finished]:
            chosen.remove(f)
            left_out.append(f"{f.run} (unfinished here, shipped finished in {out} already)")
        shipping = {f.run.as_posix() for f in chosen}
        kept = tuple(r for r in held if r.run not in shipping)
        staging = out.with_name(f".{out.name}.shipping-{os.getpid()}")
        shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir(parents=True)
        try:
            manifest = _write(chosen, staging, budget, kept, earlier)
            _verify(staging, manifest)
            sizes = _sizes(staging)
            with signals_held():
                _replace(staging, out)
        finally:
            with signals_held():
                shutil.rmtree(staging, ignore_errors=True)
    return ShipResult(
        out,
        manifest,
        tuple(sorted(left_out)),
        sizes,
        time.perf_counter() - tic,
        tuple(r.run for r in kept),
        0 if unfinished else len(running),
    )


@contextlib.contextmanager
def _stopped_by_signals() -> Iterator[None]:
    """SIGTERM and SIGHUP raise `SystemExit` (status 128 + the signal) while the block runs, as
    Ctrl-C raises `KeyboardInterrupt`, so that the ship's cleanup runs before it ends (by
    default they end the process at once, leaving its staging folder beside `out`)."""
    if not in_main_thread():
        yield
        return

    def stop(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    previous = {sig: signal.signal(sig, stop) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)


def _alive(pid: int) -> bool:
    """Whether process `pid` runs on this machine (this one does)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's
        return True
    return True


def clean_leftovers(out: Path) -> list[Path]:
    """Remove what ships killed before their end left beside `out`, and return it: their
    staging folders (`.<out>.shipping-PID`) and the earlier ships they had set aside
    (`.<out>.old-PID`), of processes no longer running. An earlier ship set aside where `out` is
    missing (a ship killed between the two renames of `_replace`) is put back in `out`'s place
    instead, as a failed ship leaves `out`: the newest such, where there are several. Called
    with `out`'s lock held, so that no running ship's folders are touched."""
    if not out.parent.is_dir():
        return []
    pattern = re.compile(rf"\.{re.escape(out.name)}\.(shipping|old)-(\d+)")
    leftovers = []
    for path in out.parent.iterdir():
        match = pattern.fullmatch(path.name)
        if match and not _alive(int(match.group(2))):
            leftovers.append((match.group(1), path))
    set_aside = sorted(
        (p for kind, p in leftovers if kind == "old" and p.is_dir()),
        key=lambda p: p.stat().st_mtime,
        reverse=True,
    )
    if set_aside and not out.exists():
        set_aside[0].rename(out)
        leftovers = [(kind, p) for kind, p in leftovers if p != set_aside[0]]
    for _, path in leftovers:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
    return [p for _, p in leftovers]


def _replace(staging: Path, out: Path) -> None:
    """Put `staging` in `out`'s place; an earlier shipped folder there goes."""
    old = out.with_name(f".{out.name}.old-{os.getpid()}")
    if out.exists():
        out.rename(old)
    staging.rename(out)
    shutil.rmtree(old, ignore_errors=True)
