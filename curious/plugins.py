"""Plugins: installed packages that add suite variants, conditions, figures and experiments to
curious without editing it (docs/extending.md has the recipes).

A plugin is a distribution that declares an entry point in the group `curious.plugins`, naming a
module, as pytest's `pytest11` does:

    [project.entry-points."curious.plugins"]
    lift = "curious_lift"

`import curious` imports every such module once (`load`), so that what it registers
(`suite.register`, `curious.agent.conditions.register_condition`,
`curious.reproduction.figures.register_figure`,
`curious.reproduction.experiments.register_experiment`) counts wherever a built-in one does: in
every `curious` command before it parses its arguments, in the processes that train runs, in
the pipeline and in notebooks. A plugin that fails to import is one line on stderr naming it; the
rest of curious goes on without it. A run folder records the plugin its condition or variant came
from (`sources`), and reading a run whose plugin is missing says which one (`missing`).
"""

from __future__ import annotations

import importlib.metadata
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import suite
import suite.catalog
from curious.registry import CONDITIONS

GROUP = "curious.plugins"
"""The entry-point group a plugin declares its module in."""

_QUIET = "CURIOUS_PLUGIN_ERRORS_SHOWN"
"""Set once a failed plugin has been reported, so that the processes a command starts (which
load the plugins again) do not repeat the line."""


@dataclass(frozen=True)
class Plugin:
    """One entry point of the group: its name, the module it names, and the distribution (name
    and version) that declares it."""

    name: str
    module: str
    distribution: str
    version: str

    @property
    def text(self) -> str:
        """``curious-lift 0.1`` (the distribution, as `pip install` names it)."""
        return f"{self.distribution} {self.version}"

    def record(self) -> dict[str, str]:
        """What a run folder's config.json keeps of it (`sources`)."""
        return {"plugin": self.distribution, "version": self.version, "module": self.module}


LOADED: dict[str, Plugin] = {}
"""The plugins imported, by entry-point value (module, or module:attribute)."""
FAILED: dict[str, tuple[Plugin, str]] = {}
"""The plugins whose module failed to import, with why, by entry-point value."""
_loading = False


def _plugin(entry: importlib.metadata.EntryPoint) -> Plugin:
    dist = entry.dist
    name = dist.name if dist is not None else None
    version = dist.version if dist is not None else None
    return Plugin(entry.name, entry.module, name or "an unnamed distribution", version or "?")


def load() -> tuple[Plugin, ...]:
    """Import every plugin module not imported yet (`import curious` calls this); returns the
    plugins loaded so far. A module that raises is reported in one line on stderr and left
    out; calling again retries nothing that failed."""
    global _loading
    if _loading:  # a plugin module importing curious while it loads
        return tuple(LOADED.values())
    _loading = True
    try:
        for entry in importlib.metadata.entry_points(group=GROUP):
            if entry.value in LOADED or entry.value in FAILED:
                continue
            plugin = _plugin(entry)
            try:
                entry.load()
            except Exception as exc:  # any error of a plugin's import is its own
                why = f"{type(exc).__name__}: {exc}".splitlines()[0]
                FAILED[entry.value] = (plugin, why)
                if not os.environ.get(_QUIET):
                    print(
                        f"curious: warning: plugin {plugin.name!r} ({plugin.text}) did not load "
                        f"({why}); its variants, conditions and figures are missing",
                        file=sys.stderr,
                    )
            else:
                LOADED[entry.value] = plugin
        if FAILED:
            os.environ[_QUIET] = "1"
    finally:
        _loading = False
    return tuple(LOADED.values())


def origin(obj: object) -> Plugin | None:
    """The loaded plugin whose package defines `obj` (a condition class, a variant or a figure's
    draw function), by its module; None for curious's own and a caller's."""
    module = str(getattr(obj, "__module__", "") or "")
    for plugin in LOADED.values():
        package = plugin.module.split(".")[0]
        if module == package or module.startswith(package + "."):
            return plugin
    return None


def sources(condition: str, variant: str) -> dict[str, dict[str, str]]:
    """The plugins a run's condition and variant come from, for its config.json: ``{"condition":
    {"plugin", "version", "module"}, "variant": {...}}``, each only where a plugin gave it."""
    out: dict[str, dict[str, str]] = {}
    for what, obj in (
        ("condition", CONDITIONS.get(condition)),
        ("variant", suite.catalog.REGISTERED.get(variant)),
    ):
        plugin = origin(obj) if obj is not None else None
        if plugin is not None:
            out[what] = plugin.record()
    return out


def _state(distribution: str, what: str, name: str) -> str:
    """Why a plugin's distribution has not registered `what` `name` here, in a clause."""
    if any(p.distribution == distribution for p, _ in FAILED.values()):
        return "which is installed but did not load (see the warning above)"
    try:
        version = importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return f"which is not installed (pip install {distribution})"
    return f"whose installed version, {version}, registers no {what} {name!r}"


def missing(recorded: Any, condition: object, variant: object) -> str | None:
    """Where a run's condition or variant came from a plugin (config.json's `plugins`,
    `recorded`) that has not registered it here, what is missing, in a clause: ``variant 'lift'
    of the plugin curious-lift 0.1, which is not installed (pip install curious-lift)``; None
    where nothing is."""
    if not isinstance(recorded, Mapping):
        return None
    names = {"condition": str(condition), "variant": str(variant)}  # a hand-edited file's too
    known = {
        "condition": names["condition"] in CONDITIONS,
        "variant": names["variant"] in suite.ALL_VARIANTS,
    }
    for what in ("condition", "variant"):
        entry = recorded.get(what)
        if known[what] or not isinstance(entry, Mapping) or not entry.get("plugin"):
            continue
        dist, version = str(entry["plugin"]), entry.get("version", "?")
        state = _state(dist, what, names[what])
        return f"{what} {names[what]!r} of the plugin {dist} {version}, {state}"
    return None
