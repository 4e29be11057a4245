"""What a run folder's config.json says about its run (`RunInfo`), read from every version of the
file curious has written: one written before a key existed lacks it, and reads as its run was.

    condition, seed, preset, variant  the run's identity (the same as in `config`)
    modules, achievable               module names in slot order, and whether each is achievable
    sensor_failure_modules            the modules the variant's sensory failure perturbs (empty:
                                      none), from the env (`EnvSpec.sensor_failure_modules`);
                                      config.json written before it was recorded lacks it, and
                                      `RunInfo` derives it from the variant's definition
    config                            the resolved settings (`Config.to_dict`)
    versions, git, created            libraries, source commit and time of the first start
    machine                           the machine of the first start (`provenance.machine`):
                                      processor, cores, system, and the GPU where it trains on
                                      one; absent or null where the first start predates it
    resumed                           one entry per resume: its time, libraries, commit, machine,
                                      settings (and plugins)
    plugins                           where the condition or the variant came from a plugin, its
                                      distribution, version and module (`curious.plugins`);
                                      absent for curious's own

A config.json that is not a run's (a missing key, a value of the wrong type) is a
`RunFolderError` naming the file; a hand-edited provenance entry reads as empty.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from curious.envs.goal_env import suite_sensor_failure_modules
from curious.runs.folder_errors import RunFolderError
from curious.runs.provenance import machine_text


@dataclass(frozen=True)
class RunInfo:
    """What a run folder's config.json says about its run (`RunFolder.read_info`)."""

    path: Path
    condition: str
    seed: int
    variant: str
    preset: str
    module_names: tuple[str, ...]
    achievable: tuple[bool, ...]
    perturbation_episode: int | None = None
    """The setting `sensor_failure_episode` (None: never, or not set)."""
    failure_competence: float | None = None
    """The setting `sensor_failure_competence`: the perturbed module's competence at which the
    failure was to start (None: not used)."""
    recorded_failure_modules: tuple[str, ...] | None = None
    """config.json's `sensor_failure_modules`; None where it predates that record."""
    settings: Mapping[str, Any] | None = None
    """The resolved settings (config.json's `config`)."""
    versions: Mapping[str, Any] | None = None
    """Library versions of the first start."""
    git: Mapping[str, Any] | None = None
    """Source commit of the first start: `commit` and `dirty` (local changes)."""
    resumed: tuple[Mapping[str, Any], ...] = ()
    """One entry per resume: `at`, `versions`, `git`, `machine`, `config`."""
    machine: Mapping[str, Any] | None = None
    """The machine of the first start (`machine`; None where config.json predates it)."""

    @property
    def achievable_modules(self) -> tuple[str, ...]:
        """The achievable modules, in slot order."""
        return tuple(m for m, a in zip(self.module_names, self.achievable, strict=True) if a)

    @functools.cached_property
    def sensor_failure_modules(self) -> tuple[str, ...]:
        """The modules the variant's sensory failure perturbs (empty: none): as config.json
        records them, else (a run written before they were recorded) from the variant's own
        definition, `curious.envs.goal_env.suite_sensor_failure_modules`."""
        if self.recorded_failure_modules is not None:
            return self.recorded_failure_modules

        found = suite_sensor_failure_modules(self.variant)
        return tuple(m for m in found if m in self.module_names)

    @property
    def total_episodes(self) -> int:
        """The run's budget in episodes (its latest `total_episodes`; 0 where not set)."""
        return int((self.settings or {}).get("total_episodes", 0))

    @property
    def machines(self) -> tuple[str, ...]:
        """The machines the run trained on, first start then resumes (`machine_text`), without
        repeats; starts that predate the record are left out."""
        entries = [self.machine or {}, *(r.get("machine", {}) for r in self.resumed)]
        texts = (machine_text(e) for e in entries if isinstance(e, Mapping))
        return tuple(dict.fromkeys(t for t in texts if t))

    @property
    def commits(self) -> tuple[str, ...]:
        """Short commits the run was trained from, first start then resumes, without repeats; a
        commit with local changes is marked with '+'."""
        out: list[str] = []
        for entry in [self.git or {}, *(r.get("git", {}) for r in self.resumed)]:
            commit = entry.get("commit") if isinstance(entry, Mapping) else None
            if commit:
                text = commit[:7] + ("+" if entry.get("dirty") else "")
                if text not in out:
                    out.append(text)
        return tuple(out)


def parse_info(data: dict[str, Any], folder: Path, config_path: Path) -> RunInfo:
    """`RunInfo` from config.json's content, checked; a `RunFolderError` naming the file."""

    def need(key: str, kind: type, what: str) -> Any:
        if key not in data:
            raise RunFolderError(f"{config_path} has no '{key}' ({what})")
        value = data[key]
        if not isinstance(value, kind) or (isinstance(value, bool) and kind is int):
            raise RunFolderError(f"{config_path}: '{key}' must be {what}, got {value!r}")
        return value

    condition = need("condition", str, "a string")
    seed = need("seed", int, "an integer")
    variant = need("variant", str, "a string")
    preset = need("preset", str, "a string")
    names = need("modules", list, "a list of module names in slot order")
    achievable = need("achievable", list, "a list of booleans, one per module")
    if not names or not all(isinstance(n, str) and n for n in names):
        raise RunFolderError(f"{config_path}: 'modules' must be non-empty strings: {names!r}")
    if len(set(names)) != len(names):
        raise RunFolderError(f"{config_path}: 'modules' repeats a name: {names!r}")
    if any("," in n for n in names):
        raise RunFolderError(f"{config_path}: module names may not contain commas: {names!r}")
    if len(achievable) != len(names) or not all(isinstance(a, bool) for a in achievable):
        raise RunFolderError(
            f"{config_path}: 'achievable' must be {len(names)} booleans (one per module in "
            f"'modules'), got {achievable!r}"
        )
    recorded = data.get("sensor_failure_modules")
    if recorded is not None and (
        not isinstance(recorded, list) or not all(m in names for m in recorded)
    ):
        raise RunFolderError(
            f"{config_path}: 'sensor_failure_modules' must list modules of 'modules', got "
            f"{recorded!r}"
        )
    settings = data["config"]
    total = settings.get("total_episodes", 0)
    if not isinstance(total, int) or isinstance(total, bool) or total < 0:
        raise RunFolderError(
            f"{config_path}: 'total_episodes' must be a non-negative integer, got {total!r}"
        )
    resumed = data.get("resumed")
    return RunInfo(
        path=folder.resolve(),
        condition=condition,
        seed=seed,
        variant=variant,
        preset=preset,
        module_names=tuple(names),
        achievable=tuple(achievable),
        perturbation_episode=_failure_episode(settings, config_path),
        failure_competence=_failure_competence(settings, config_path),
        recorded_failure_modules=None if recorded is None else tuple(recorded),
        settings=settings,
        versions=_mapping(data.get("versions")),
        git=_mapping(data.get("git")),
        resumed=tuple(_mapping(r) for r in resumed) if isinstance(resumed, list) else (),
        machine=_mapping(data.get("machine")),
    )


def _mapping(value: Any) -> Mapping[str, Any]:
    """A provenance entry of config.json, or an empty one where it is not an object (provenance
    is for reading; a hand-edited entry does not make the run unreadable)."""
    return value if isinstance(value, dict) else {}


def _failure_episode(settings: Mapping[str, Any], config_path: Path) -> int | None:
    """The setting `sensor_failure_episode` (None where absent, null or -1: never)."""
    value = settings.get("sensor_failure_episode")
    if value is None or value == -1:
        return None
    if not isinstance(value, int) or isinstance(value, bool) or value < 0:
        raise RunFolderError(
            f"{config_path}: 'sensor_failure_episode' must be a non-negative integer, -1 or "
            f"null, got {value!r}"
        )
    return value


def _failure_competence(settings: Mapping[str, Any], config_path: Path) -> float | None:
    """The setting `sensor_failure_competence` (None where absent, null or -1: not used)."""
    value = settings.get("sensor_failure_competence")
    if value is None or value == -1:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= 1:
        raise RunFolderError(
            f"{config_path}: 'sensor_failure_competence' must be a number in (0, 1], -1 or "
            f"null, got {value!r}"
        )
    return float(value)
