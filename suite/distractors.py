"""Placement and random walk of the out-of-reach distractor cubes (vectorised).

Distractors start near fixed points beyond the arm's reach and, every env step, move by
N(0, 0.005^2) in x and y. A move that would end within 0.05 m of another cube is redrawn (a few
times; a distractor that finds no free move stays put), and every move is clipped to the region
`layout.DISTRACTOR_X_RANGE x layout.DISTRACTOR_Y_RANGE`: on the table, and beyond the arm's
reach.
"""

from __future__ import annotations

import numpy as np

from suite import layout

_LOW = np.array([layout.DISTRACTOR_X_RANGE[0], layout.DISTRACTOR_Y_RANGE[0]])
_HIGH = np.array([layout.DISTRACTOR_X_RANGE[1], layout.DISTRACTOR_Y_RANGE[1]])
_SEP2 = layout.DISTRACTOR_MIN_SEPARATION**2
MAX_REDRAWS = 10


def start_positions(n: int, random_state: np.random.RandomState) -> np.ndarray:
    """Start xy (n, 2) of `n` distractors: the fixed start points plus a little noise."""
    if n > layout.MAX_DISTRACTORS:
        raise ValueError(f"at most {layout.MAX_DISTRACTORS} distractors, got {n}")
    noise = layout.DISTRACTOR_START_NOISE
    xy = layout.DISTRACTOR_STARTS[:n] + random_state.uniform(-noise, noise, size=(n, 2))
    return np.clip(xy, _LOW, _HIGH)


class DistractorWalk:
    """One random-walk step for the distractors among `n_cubes` cubes (the last `n` ones)."""

    def __init__(self, n_cubes: int, n_distractors: int) -> None:
        self.n_cubes = n_cubes
        self.n = n_distractors
        self.first = n_cubes - n_distractors
        # Candidate k is compared with every current cube and every other candidate, but not
        # with its own current position nor with itself: those pairs are pushed out of range.
        self._self_pairs = np.zeros((n_distractors, n_cubes + n_distractors))
        for k in range(n_distractors):
            self._self_pairs[k, self.first + k] = np.inf
            self._self_pairs[k, n_cubes + k] = np.inf
        self._points = np.zeros((n_cubes + n_distractors, 2))

    def _colliding(self, candidate: np.ndarray) -> np.ndarray:
        """Which candidates end within the minimum separation of another cube (or candidate)."""
        points = self._points
        points[self.n_cubes :] = candidate
        diff = candidate[:, None, :] - points
        diff *= diff
        d2 = diff[..., 0] + diff[..., 1]
        d2 += self._self_pairs
        return (d2 < _SEP2).any(axis=1)

    def step(self, xy: np.ndarray, random_state: np.random.RandomState) -> np.ndarray:
        """New xy (n, 2) of the distractors, given the current xy (n_cubes, 2) of all cubes."""
        if self.n == 0:
            return np.zeros((0, 2))
        current = xy[self.first :]
        candidate = random_state.normal(0.0, layout.DISTRACTOR_WALK_STD, (self.n, 2))
        candidate += current
        np.maximum(candidate, _LOW, out=candidate)
        np.minimum(candidate, _HIGH, out=candidate)
        self._points[: self.n_cubes] = xy
        for _ in range(MAX_REDRAWS):
            bad = self._colliding(candidate)
            if not bad.any():
                return candidate
            redraw = current[bad] + random_state.normal(
                0.0, layout.DISTRACTOR_WALK_STD, (int(bad.sum()), 2)
            )
            candidate[bad] = np.clip(redraw, _LOW, _HIGH)
        # Whoever still collides stays where it is; the others were checked against the current
        # positions of everyone, so every pair stays apart.
        bad = self._colliding(candidate)
        candidate[bad] = current[bad]
        return candidate
