"""CURIOUS: intrinsically motivated multi-task, multi-goal reinforcement learning."""

__version__ = "0.1.0"

from curious import plugins as _plugins  # after the version, which a plugin may read

_plugins.load()  # the installed plugins' variants, conditions and figures (`curious.plugins`)
