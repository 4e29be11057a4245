"""The names in a run folder, the one place that spells them, so that every reader and writer
agrees on the layout:

    config.json       the run's description (`curious.runs.folder.RunFolder.describe`)
    metrics.parquet   one row per training episode (`curious.runs.metrics`)
    tests.parquet     one row per test rollout (`curious.runs.metrics`)
    learner.parquet   one row per cycle: replay counts, losses, Q (`curious.runs.metrics`)
    recording.rrd     the Rerun recording (written by `curious.watching.recording`)
    checkpoints/      resumable checkpoints, `ep-<episodes, 12 digits>/` (`curious.runs.checkpoint`)

and the mark of a shipped data folder, `shipped.json` at its root
(`curious.runs.shipped_folder`): the runs below it are finished runs' tables, read by the
analysis and never trained into.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from curious.runs.folder_errors import RunFolderError

CONFIG_FILE = "config.json"
METRICS_FILE = "metrics.parquet"
TESTS_FILE = "tests.parquet"
LEARNER_FILE = "learner.parquet"
RECORDING_FILE = "recording.rrd"
CHECKPOINTS_DIR = "checkpoints"
RUN_ENTRIES: tuple[str, ...] = (
    CONFIG_FILE,
    METRICS_FILE,
    TESTS_FILE,
    LEARNER_FILE,
    RECORDING_FILE,
    CHECKPOINTS_DIR,
)
"""What a run writes in its folder (with temporaries named after them, a leading dot aside)."""
EVALUATION_RECORDING_FILE = "evaluation.rrd"
"""Where `curious evaluate --record` writes without a FILE: the current folder, never a run
folder (a run folder holds a run's files only: `--restart` refuses one with more)."""

SHIPPED_MANIFEST_FILE = "shipped.json"
"""The manifest at the root of a shipped data folder (`curious ship`'s output)."""

CHECKPOINT_PREFIX = "ep-"
_CHECKPOINT_NAME = re.compile(r"ep-(\d{12})")


def checkpoint_name(episodes: int) -> str:
    """The name of the checkpoint taken after `episodes` episodes, in `checkpoints/`."""
    return f"{CHECKPOINT_PREFIX}{episodes:012d}"


def checkpoint_episodes(path: str | os.PathLike) -> int | None:
    """The episodes a checkpoint's name says it was taken after; None for another name."""
    match = _CHECKPOINT_NAME.fullmatch(Path(path).name)
    return int(match.group(1)) if match else None


def list_checkpoints(directory: str | os.PathLike) -> list[Path]:
    """Complete checkpoints, oldest first (temporaries, `.tmp-ep-...`, are not listed); a
    `RunFolderError` where `directory` is a file."""
    directory = Path(directory)
    if not directory.exists():
        return []
    if not directory.is_dir():
        raise RunFolderError(f"{directory} is a file, not a folder of checkpoints: move it away")
    found = [p for p in directory.iterdir() if p.is_dir() and checkpoint_episodes(p) is not None]
    return sorted(found, key=lambda p: checkpoint_episodes(p) or 0)


def shipped_root(path: str | os.PathLike) -> Path | None:
    """The shipped data folder that holds `path` (the nearest folder at or above it with a
    `shipped.json`), or None for a path outside any."""
    resolved = Path(path).resolve()
    for folder in (resolved, *resolved.parents):
        if (folder / SHIPPED_MANIFEST_FILE).is_file():
            return folder
    return None
