"""The conditions by name: the one registry, below the settings that name them.

A `Config` names its condition, and `Config.validate` checks the name here; the classes are the
agent's (`curious.agent.conditions`), which registers the built-in ones when it is imported and
takes a plugin's through `register_condition`. The registry lies below both so that the settings
never import the agent: `import curious` imports `curious.agent.conditions` first thing (numpy,
not torch), so the built-in conditions are registered before any config is made.
"""

from __future__ import annotations

from typing import Any

CONDITIONS: dict[str, type[Any]] = {}
"""Every condition class by its name: the paper's, in its order, then the two halves of CURIOUS
(`curious.agent.conditions`), then those registered (`register_condition`)."""


def condition_names() -> tuple[str, ...]:
    """The conditions a config may name, in the registry's order."""
    return tuple(CONDITIONS)
