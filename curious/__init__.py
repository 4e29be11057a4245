"""CURIOUS: intrinsically motivated multi-task, multi-goal reinforcement learning."""

__version__ = "0.1.0"
