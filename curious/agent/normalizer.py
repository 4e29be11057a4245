"""The running mean/std normaliser of the policy's state input.

Statistics accumulate in float64 on the CPU; `normalize` works on numpy arrays or on torch
tensors (on any device) using float32 copies of the current mean and std. Normalised values are
clipped to [-clip, clip] and the std is floored at `eps` (the authors' 0.01 and 5).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch


def device_copies(
    cache: dict[str, tuple[torch.Tensor, ...]], device: torch.device, *arrays: np.ndarray
) -> tuple[torch.Tensor, ...]:
    """`arrays` as tensors on `device`, made once per device and kept in `cache` (which the
    owner clears when the arrays change)."""
    key = str(device)
    if key not in cache:
        cache[key] = tuple(torch.as_tensor(a, device=device) for a in arrays)
    return cache[key]


class RunningNormalizer:
    """Per-feature running mean and std over `shape`."""

    def __init__(self, shape: tuple[int, ...], eps: float = 0.01, clip: float = 5.0) -> None:
        self.shape = tuple(shape)
        self.eps = float(eps)
        self.clip = float(clip)
        self.count = np.zeros((), dtype=np.float64)
        self.sum = np.zeros(self.shape, dtype=np.float64)
        self.sumsq = np.zeros(self.shape, dtype=np.float64)
        self.mean = np.zeros(self.shape, dtype=np.float32)
        self.std = np.ones(self.shape, dtype=np.float32)
        self._torch: dict[str, tuple[torch.Tensor, ...]] = {}

    def update(self, x: np.ndarray) -> None:
        """Add samples `x` of shape (n, *shape)."""
        x = np.asarray(x, dtype=np.float64).reshape((-1, *self.shape))
        self.count += len(x)
        self.sum += x.sum(axis=0)
        self.sumsq += (x * x).sum(axis=0)
        self._recompute()

    def _recompute(self) -> None:
        if self.count <= 0:  # nothing seen yet: the identity map
            self.mean = np.zeros(self.shape, np.float32)
            self.std = np.ones(self.shape, np.float32)
        else:
            mean = self.sum / self.count
            var = self.sumsq / self.count - mean * mean
            self.mean = mean.astype(np.float32)
            self.std = np.sqrt(np.maximum(self.eps**2, var)).astype(np.float32)
        self._torch.clear()

    def normalize(self, x: Any) -> Any:
        """(x - mean) / std clipped; x of shape (..., *stat shape), numpy or torch."""
        if isinstance(x, torch.Tensor):
            mean, std = device_copies(self._torch, x.device, self.mean, self.std)
            return torch.clamp((x - mean) / std, -self.clip, self.clip)
        return np.clip((np.asarray(x) - self.mean) / self.std, -self.clip, self.clip)

    def state_dict(self) -> dict[str, np.ndarray]:
        return {"count": self.count.copy(), "sum": self.sum.copy(), "sumsq": self.sumsq.copy()}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        for key in ("count", "sum", "sumsq"):
            value = np.asarray(state[key], dtype=np.float64)
            if value.shape != getattr(self, key).shape:
                raise ValueError(
                    f"normaliser {key}: checkpoint shape {value.shape}, "
                    f"expected {getattr(self, key).shape}"
                )
            setattr(self, key, value.copy())
        self._recompute()
