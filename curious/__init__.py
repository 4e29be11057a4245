"""CURIOUS: intrinsically motivated multi-task, multi-goal reinforcement learning."""

__version__ = "0.1.0"

# After the version, which a plugin may read: the built-in conditions registered
# (`curious.registry`), then the installed plugins' variants, conditions and figures
# (`curious.plugins`), before any config is made.
from curious import plugins as _plugins
from curious.agent import conditions as _conditions  # noqa: F401

_plugins.load()
