"""Running mean/std normalisers for the policy's inputs (states and goal slots).

Statistics accumulate in float64 on the CPU; `normalize` works on numpy arrays or on torch
tensors (on any device) using float32 copies of the current mean and std. Normalised values are
clipped to [-clip, clip] and the std is floored at `eps` (the authors' 0.01 and 5).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch


class RunningNormalizer:
    """Per-feature running mean and std over `shape`, optionally one set of statistics per group.

    With `groups=None` the statistics have `shape` (e.g. the state features). With `groups=N` they
    have shape (N, *shape) and every update names the group of each sample: the goal normaliser
    keeps one set per module slot, so that a slot's statistics come only from goals of that
    module (zeros of inactive slots never enter them).
    """

    def __init__(
        self,
        shape: tuple[int, ...],
        groups: int | None = None,
        eps: float = 0.01,
        clip: float = 5.0,
    ) -> None:
        self.shape = tuple(shape)
        self.groups = groups
        self.eps = float(eps)
        self.clip = float(clip)
        stat_shape = ((groups,) if groups else ()) + self.shape
        self.count = np.zeros((groups,) if groups else (), dtype=np.float64)
        self.sum = np.zeros(stat_shape, dtype=np.float64)
        self.sumsq = np.zeros(stat_shape, dtype=np.float64)
        self.mean = np.zeros(stat_shape, dtype=np.float32)
        self.std = np.ones(stat_shape, dtype=np.float32)
        self._torch: dict[str, tuple[torch.Tensor, torch.Tensor]] = {}

    def update(self, x: np.ndarray, group: np.ndarray | None = None) -> None:
        """Add samples `x` of shape (n, *shape); `group` (n,) ints when grouped."""
        x = np.asarray(x, dtype=np.float64).reshape((-1, *self.shape))
        if self.groups:
            if group is None:
                raise ValueError("a grouped normaliser needs the group of every sample")
            group = np.asarray(group, dtype=np.int64).reshape(-1)
            flat = x.reshape(len(x), -1)
            n = self.groups
            self.count += np.bincount(group, minlength=n)
            sums = np.zeros((n, flat.shape[1]))
            sumsq = np.zeros((n, flat.shape[1]))
            np.add.at(sums, group, flat)
            np.add.at(sumsq, group, flat * flat)
            self.sum += sums.reshape(self.sum.shape)
            self.sumsq += sumsq.reshape(self.sumsq.shape)
        else:
            self.count += len(x)
            self.sum += x.sum(axis=0)
            self.sumsq += (x * x).sum(axis=0)
        self._recompute()

    def _recompute(self) -> None:
        count = self.count.reshape(self.count.shape + (1,) * len(self.shape))
        safe = np.maximum(count, 1.0)
        mean = self.sum / safe
        var = self.sumsq / safe - mean * mean
        std = np.sqrt(np.maximum(self.eps**2, var))
        seen = np.broadcast_to(count > 0, mean.shape)
        self.mean = np.where(seen, mean, 0.0).astype(np.float32)
        self.std = np.where(seen, std, 1.0).astype(np.float32)
        self._torch.clear()

    def _stats(self, device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
        key = str(device)
        if key not in self._torch:
            self._torch[key] = (
                torch.as_tensor(self.mean, device=device),
                torch.as_tensor(self.std, device=device),
            )
        return self._torch[key]

    def normalize(self, x: Any) -> Any:
        """(x - mean) / std clipped; x of shape (..., *stat shape), numpy or torch."""
        if isinstance(x, torch.Tensor):
            mean, std = self._stats(x.device)
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
