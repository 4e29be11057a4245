"""A run folder: where one training run (one condition, one seed) keeps everything. `RunFolder`
holds its paths (the names are `curious.runs.folder_layout`'s), writes config.json
(`RunFolder.describe`; its keys are listed in `curious.runs.run_info`), reads it back, and decides
whether a config may go on with the run the folder holds.

Who reads what: training (`prepare`, `write_config`, the paths), `curious evaluate`
(`read_config`), `curious progress` and the analysis (`read_info`, `episodes_logged`,
`newest_checkpoint`), the reproduction pipeline (`check_resumable`, `finished_at`), `curious ship`
(`read_info`, `finished_at`).

`prepare` checks a folder before anything is written: none inside a shipped data folder
(`check_not_shipped`), none new inside another run's folder (`check_not_nested`); a non-empty
folder is only accepted with `resume=True`, and then only for the same config
(`check_resumable`: fields in `RESUMABLE_FIELDS` may change), or with `restart=True` when it
holds a run's files and nothing else (`clear` removes them once every check has passed). A
config.json that is not a run's (damaged, hand-edited into another shape, a setting of the wrong
type) is a `RunFolderError` naming the file. While one process trains in a folder,
`curious.runs.folder_lock` keeps others out.
"""

from __future__ import annotations

import datetime
import json
import os
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any

from curious.config import EARLIER_BEHAVIOUR, RESUMABLE_FIELDS, Config, ConfigError, setting_names
from curious.overrides import format_seeds
from curious.plugins import missing, sources
from curious.runs.folder_errors import ConfigMismatch, RunFolderError
from curious.runs.folder_layout import (
    CHECKPOINTS_DIR,
    CONFIG_FILE,
    LEARNER_FILE,
    METRICS_FILE,
    RECORDING_FILE,
    RUN_ENTRIES,
    TESTS_FILE,
    checkpoint_episodes,
    list_checkpoints,
    shipped_root,
)
from curious.runs.provenance import git_commit, library_versions, machine
from curious.runs.run_info import RunInfo, parse_info

if TYPE_CHECKING:
    from curious.envs.goal_env import EnvSpec


def config_differences(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """Keys whose values differ between two config dicts, ignoring resumable fields; a setting
    present on one side only differs (a run saved before the setting existed is another run),
    unless its absence means the value `EARLIER_BEHAVIOUR` names (the computation it had)."""
    keys = (set(a) | set(b)) - RESUMABLE_FIELDS
    a, b = {**EARLIER_BEHAVIOUR, **a}, {**EARLIER_BEHAVIOUR, **b}
    missing = object()
    return sorted(k for k in keys if a.get(k, missing) != b.get(k, missing))


def folders_below(folder: Path, holding: str, most_visited: int = 10_000) -> list[Path]:
    """The folders below `folder` (itself included) that hold a file named `holding`, sorted:
    where a command was given a folder of runs (a reproduction's output, a `--seeds` folder)
    instead of a run, the runs it could mean. A run's checkpoints and hidden folders (.venv,
    .git) are not searched, and the walk stops after `most_visited` folders (a home folder,
    say: the runs found by then are enough to name)."""
    found: list[Path] = []
    for visited, (where, subfolders, files) in enumerate(os.walk(folder)):
        if holding in files:
            found.append(Path(where))
        subfolders[:] = [s for s in subfolders if not s.startswith(".") and s != CHECKPOINTS_DIR]
        if visited >= most_visited:
            break
    return sorted(found)


def name_some(paths: list[Path], most: int = 3) -> str:
    """`a, b, c and 4 more`: the first `most` paths, and how many were left out."""
    named = ", ".join(str(p) for p in paths[:most])
    return named + (f" and {len(paths) - most} more" if len(paths) > most else "")


def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    """Write `data` to `path` through a temporary beside it: a reader never sees half a file."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=False) + "\n")
    os.replace(tmp, path)


class RunFolder:
    """Paths, reading, writing and checks of one run folder."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)

    @property
    def config_path(self) -> Path:
        return self.path / CONFIG_FILE

    @property
    def metrics_path(self) -> Path:
        return self.path / METRICS_FILE

    @property
    def tests_path(self) -> Path:
        return self.path / TESTS_FILE

    @property
    def learner_path(self) -> Path:
        return self.path / LEARNER_FILE

    @property
    def recording_path(self) -> Path:
        return self.path / RECORDING_FILE

    @property
    def checkpoints(self) -> Path:
        return self.path / CHECKPOINTS_DIR

    @property
    def has_config(self) -> bool:
        """Whether the folder holds a config.json: a run, started or not."""
        return self.config_path.is_file()

    @property
    def started(self) -> bool:
        """Whether the run has logged episodes: config.json and metrics.parquet are there."""
        return self.has_config and self.metrics_path.is_file()

    def episodes_logged(self) -> int:
        """Rows of metrics.parquet, read from its footer (0 where there is none yet, or where it
        cannot be read)."""
        if not self.metrics_path.is_file():
            return 0
        import pyarrow.parquet as pq

        try:
            return int(pq.read_metadata(self.metrics_path).num_rows)
        except (OSError, ValueError):
            return 0

    @staticmethod
    def unreadable_table(tables: list[Path]) -> tuple[Path, Exception] | None:
        """The first of `tables` whose parquet footer cannot be read, with why (None: all
        read). Reads footers only: a truncated copy fails there."""
        import pyarrow.parquet as pq

        for table in tables:
            try:
                pq.read_metadata(table)
            except (OSError, ValueError) as exc:
                return table, exc
        return None

    def newest_checkpoint(self) -> int | None:
        """Episodes of the newest complete checkpoint, by its name (None: none)."""
        found = list_checkpoints(self.checkpoints)
        return checkpoint_episodes(found[-1]) if found else None

    def finished_at(self, total_episodes: int) -> bool:
        """Whether the run has reached `total_episodes`: that many episodes logged, and a
        checkpoint taken at (or after) them, so that nothing is left to train."""
        logged = self.episodes_logged() >= total_episodes
        return logged and (self.newest_checkpoint() or 0) >= total_episodes

    def read_stored(self) -> dict[str, Any]:
        """config.json's content, checked to be a run's description: a JSON object whose
        `config` is an object. Anything else is a `RunFolderError` naming the file."""
        path = self.config_path
        if not self.path.exists():
            raise RunFolderError(f"{self.path} does not exist: name a run folder")
        if not self.path.is_dir():
            raise RunFolderError(f"{self.path} is a file, not a run folder")
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise RunFolderError(
                f"{self.path} is not a run folder: it has no {CONFIG_FILE}{self._runs_below()}"
            ) from None
        except (OSError, UnicodeDecodeError) as exc:
            cause = getattr(exc, "strerror", None) or exc
            raise RunFolderError(f"cannot read {path}: {cause}") from None
        damaged = f"{path} is damaged"
        remedy = "restore it, or start a new run in another --out"
        if not text.strip():
            raise RunFolderError(f"{damaged}: it is empty; {remedy}")
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise RunFolderError(f"{damaged}: it is not valid JSON ({exc}); {remedy}") from None
        if not isinstance(data, dict) or not isinstance(data.get("config"), dict):
            raise RunFolderError(
                f"{damaged}: it holds no run's settings (a JSON object with a `config` object); "
                f"{remedy}"
            )
        return data

    def _runs_below(self, resuming: bool = False) -> str:
        """Where this folder holds runs but is none, a clause naming them (empty otherwise):
        the hint for a folder of runs given where one run was meant. `resuming`, for a
        `--seeds` folder (its runs all `seed-K` right below it), also says how to resume them
        all at once."""
        runs = folders_below(self.path, CONFIG_FILE) if self.path.is_dir() else []
        if not runs:
            return ""
        clause = f"; it holds runs: {name_some(runs)}; name one"
        names = [run.relative_to(self.path).as_posix() for run in runs]
        seeds = [n.removeprefix("seed-") for n in names if n.startswith("seed-")]
        if resuming and len(seeds) == len(names) and all(s.isdigit() for s in seeds):
            clause += f", or resume them all with `--seeds {format_seeds([int(s) for s in seeds])}`"
        return clause

    def read_config(self) -> Config:
        """The config stored in config.json; a `RunFolderError` naming the file when it is not
        one this curious can run (a damaged file, a setting of the wrong type or value, a
        condition or variant of a plugin that is not here)."""
        stored = self.read_stored()
        raw = stored["config"]
        absent = missing(stored.get("plugins"), raw.get("condition", ""), raw.get("variant", ""))
        if absent:
            raise RunFolderError(f"{self.path} was trained with the {absent}")
        try:
            return Config.from_dict(raw)
        except ConfigError as exc:
            raise RunFolderError(
                f"{self.config_path} holds settings this curious cannot run ({exc}); restore "
                "it, or start a new run in another --out"
            ) from None

    def read_info(self) -> RunInfo:
        """What config.json says about the run (`RunInfo`), checked: its identity, modules,
        sensory failure and provenance; a `RunFolderError` naming the file otherwise. Reads
        every config.json curious has written (see the module docstring)."""
        return parse_info(self.read_stored(), self.path, self.config_path)

    def check_resumable(self, config: Config) -> None:
        """A `RunFolderError` unless `config` may go on with the run in this folder: config.json
        is there and is a run's, written by a curious that had every setting this one has (but
        those `EARLIER_BEHAVIOUR` reads for a run made before them), with
        settings this curious can run, equal to `config`'s but for `RESUMABLE_FIELDS` (a
        `ConfigMismatch` naming the differences otherwise)."""
        if not self.config_path.exists():
            raise RunFolderError(
                f"nothing to resume: {self.config_path} does not exist"
                f"{self._runs_below(resuming=True)}"
            )
        raw = self.read_stored()["config"]
        lacking = sorted(set(setting_names()) - set(raw) - set(EARLIER_BEHAVIOUR))
        if lacking:
            raise RunFolderError(
                f"cannot resume {self.path}: it was written by another version of curious "
                f"(its config.json lacks {', '.join(lacking)}); start a new run, or resume "
                "with the version that wrote it"
            )
        self.read_config()  # settings of the wrong type or value
        given = config.to_dict()
        differences = {k: (raw.get(k), given.get(k)) for k in config_differences(raw, given)}
        if differences:
            detail = ", ".join(f"{k}: {a!r} -> {b!r}" for k, (a, b) in differences.items())
            raise ConfigMismatch(
                f"cannot resume {self.path} with a different config ({detail}); "
                f"only {', '.join(sorted(RESUMABLE_FIELDS))} may change",
                differences,
            )
        # its replay would not take what the run stored; a checkpoint's name alone can lie
        # (renamed), the metrics table can run past it (killed before the next checkpoint)
        trained = min(self.newest_checkpoint() or 0, self.episodes_logged())
        if config.total_episodes < trained:
            raise RunFolderError(
                f"cannot resume {self.path} with total_episodes={config.total_episodes:,}: the "
                f"run has trained {trained:,} episodes (its newest checkpoint); a run can be "
                "lengthened, not shortened"
            )

    def foreign_entries(self) -> list[str]:
        """Names in the folder that no run writes (what `--restart` would not remove)."""
        if not self.path.is_dir():
            return []
        return sorted(
            entry.name
            for entry in self.path.iterdir()
            if not entry.name.lstrip(".").startswith(RUN_ENTRIES)
        )

    def clear(self) -> None:
        """Remove what a run wrote in the folder (`--restart`), after `prepare` checked that it
        holds nothing else; a folder not made yet has nothing to remove."""
        if not self.path.is_dir():
            return
        for entry in self.path.iterdir():
            if entry.name.lstrip(".").startswith(RUN_ENTRIES):
                if entry.is_dir() and not entry.is_symlink():
                    shutil.rmtree(entry)
                else:
                    entry.unlink()

    @classmethod
    def prepare(
        cls, path: str | os.PathLike, config: Config, resume: bool, restart: bool = False
    ) -> RunFolder:
        """Check that `path` can hold (or go on with) a run of `config`; writes nothing. With
        `restart`, a folder holding a run (and nothing else) is accepted for a new run: `clear`
        then removes the old one."""
        folder = cls(path)
        exists = folder.path.exists()
        if exists and not folder.path.is_dir():
            raise RunFolderError(f"{folder.path} exists and is not a folder")
        folder.check_not_shipped()
        if resume and restart:
            raise RunFolderError(
                "--resume goes on with a run and --restart starts it over: pass one of them"
            )
        non_empty = exists and any(folder.path.iterdir())
        if not resume:
            folder.check_not_nested()
        if restart:
            foreign = folder.foreign_entries()
            if foreign:
                raise RunFolderError(
                    f"{folder.path} holds files that are not a run's ({', '.join(foreign[:5])}); "
                    "--restart removes only a run's files: move them away, or choose another --out"
                )
            return folder
        if not resume:
            if non_empty:
                raise RunFolderError(
                    f"{folder.path} is not empty; pass --resume to continue the run in it, "
                    "--restart to start it over, or choose another --out"
                )
            return folder
        folder.check_resumable(config)
        return folder

    @property
    def holds_a_run(self) -> bool:
        """Whether config.json is a run's description (a config.json of anything else, say a
        project's own settings, is not)."""
        if not self.has_config:
            return False
        try:
            self.read_stored()
        except RunFolderError:
            return False
        return True

    def check_not_nested(self) -> None:
        """A `RunFolderError` where the folder lies inside another run's folder: the search for
        runs (`curious progress`, `curious ship`, the analysis) stops at a run folder, so a run
        inside one would never be found."""
        for parent in self.path.absolute().parents:
            if RunFolder(parent).holds_a_run:
                raise RunFolderError(
                    f"{self.path} lies inside the run folder {parent}, where no search for runs "
                    "would find it: choose an --out outside it"
                )

    def check_not_shipped(self) -> None:
        """A `RunFolderError` where the folder lies in a shipped data folder (`curious ship`'s
        output): its runs are finished runs' tables, without checkpoints to go on from, and what
        `--restart` or a new run wrote there would replace or mix with what the analysis reads."""
        root = shipped_root(self.path)
        if root is not None:
            raise RunFolderError(
                f"{self.path} lies in the shipped data folder {root}: shipped runs are finished "
                "runs' tables (no checkpoints to resume from) and no run trains there; choose an "
                "--out outside it"
            )

    def describe(self, config: Config, spec: EnvSpec) -> dict[str, Any]:
        """The content of config.json (with `plugins` where the condition or the variant came
        from a plugin: its distribution, version and module, `curious.plugins.sources`)."""
        described = {
            "condition": config.condition,
            "seed": config.seed,
            "preset": config.preset,
            "variant": config.variant,
            "modules": list(spec.module_names),
            "achievable": list(spec.achievable),
            "sensor_failure_modules": list(spec.sensor_failure_modules),
            "config": config.to_dict(),
            "versions": library_versions(),
            "git": git_commit(),
            "machine": machine(config.device),
            "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        }
        if plugins := sources(config.condition, config.variant):
            described["plugins"] = plugins
        return described

    def write_config(self, config: Config, spec: EnvSpec) -> None:
        """Create the folder and write config.json (a resumed run records its new settings)."""
        self.path.mkdir(parents=True, exist_ok=True)
        data = self.describe(config, spec)
        if self.config_path.exists():
            old = json.loads(self.config_path.read_text())
            resumed = {
                "at": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                "versions": data["versions"],
                "git": data["git"],
                "machine": data["machine"],
                "config": data["config"],
            }
            if "plugins" in data:
                resumed["plugins"] = data["plugins"]
            for key in ("created", "versions", "git", "plugins"):
                if key in old or key in data:
                    data[key] = old.get(key, data.get(key))
            data["machine"] = old.get("machine")  # None: the first start predates the record
            data["resumed"] = [*old.get("resumed", []), resumed]
        write_json_atomic(self.config_path, data)
