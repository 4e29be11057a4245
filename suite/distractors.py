"""Placement and random walk of the out-of-reach distractor cubes (vectorised).

Distractors start near fixed points beyond the arm's reach and, every env step, move by
N(0, 0.005^2) in x and y. A move that would end within 0.05 m of another cube is redrawn (99 draws
in all, as the authors do; a distractor that finds no free move stays put), and every move is
clipped to the region `layout.DISTRACTOR_X_RANGE x layout.DISTRACTOR_Y_RANGE`: on the table, and
beyond the arm's reach (the authors' walk has no bound; docs/suite.md says what that changes).
"""

from __future__ import annotations

import numpy as np

from suite import layout

_LOW = np.array([layout.DISTRACTOR_X_RANGE[0], layout.DISTRACTOR_Y_RANGE[0]])
_HIGH = np.array([layout.DISTRACTOR_X_RANGE[1], layout.DISTRACTOR_Y_RANGE[1]])
MAX_REDRAWS = layout.DISTRACTOR_MAX_DRAWS - 1  # after the first draw of a step


def start_positions(n: int, random_state: np.random.RandomState) -> np.ndarray:
    """Start xy (n, 2) of `n` distractors: the fixed start points plus U(-0.01, 0.01) in x and
    U(-0.02, 0.02) in y."""
    if n > layout.MAX_DISTRACTORS:
        raise ValueError(f"at most {layout.MAX_DISTRACTORS} distractors, got {n}")
    noise = layout.DISTRACTOR_START_NOISE
    xy = layout.DISTRACTOR_STARTS[:n] + random_state.uniform(-noise, noise, size=(n, 2))
    return np.clip(xy, _LOW, _HIGH)


class DistractorWalk:
    """The random walk of the distractors among `n_cubes` cubes (the last `n` ones).

    Positions are complex numbers x + iy, so that all pairwise distances come from one
    subtraction and one `abs`, and an episode's steps are drawn at reset: at these sizes numpy's
    per-call cost, not arithmetic, is what a step costs.
    """

    def __init__(self, n_cubes: int, n_distractors: int, episode_steps: int = 50) -> None:
        self.n_cubes = n_cubes
        self.n = n_distractors
        self.first = n_cubes - n_distractors
        self._episode_steps = episode_steps
        # Every cube (the distractors at their current positions), then every candidate;
        # candidate k is compared with all of them except its own current position and itself
        # (those pairs get an infinite distance).
        self._points = np.zeros(n_cubes + n_distractors, dtype=np.complex128)
        self._points_xy = self._points.view(np.float64).reshape(-1, 2)
        self._others = self._points_xy[: self.first]
        self._current = self._points_xy[self.first : n_cubes]
        self._candidate = self._points_xy[n_cubes:]
        self._candidate_column = self._points[n_cubes:, None]
        self._self_pairs = np.zeros((n_distractors, n_cubes + n_distractors))
        for k in range(n_distractors):
            self._self_pairs[k, self.first + k] = np.inf
            self._self_pairs[k, n_cubes + k] = np.inf
        self._moves = np.zeros((0, n_distractors, 2))
        self._t = 0

    def reset(self, random_state: np.random.RandomState) -> None:
        """Start an episode: draw its steps."""
        self._moves = random_state.normal(
            0.0, layout.DISTRACTOR_WALK_STD, (self._episode_steps, self.n, 2)
        )
        self._t = 0

    def next_move(self, random_state: np.random.RandomState) -> np.ndarray:
        """This step's move (n, 2), drawn at reset (or now, past the episode's length)."""
        if self._t < len(self._moves):
            move = self._moves[self._t]
        else:  # stepped past the episode's length: draw as we go
            move = random_state.normal(0.0, layout.DISTRACTOR_WALK_STD, (self.n, 2))
        self._t += 1
        return move

    def _too_close(self) -> np.ndarray:
        """Which candidates end within the minimum separation of another cube or candidate."""
        d = np.abs(self._candidate_column - self._points)
        d += self._self_pairs
        return d.min(axis=1) < layout.DISTRACTOR_MIN_SEPARATION

    def step(
        self, others_xy: np.ndarray, xy: np.ndarray, random_state: np.random.RandomState
    ) -> np.ndarray:
        """The distractors' new xy (n, 2), given their current xy (n, 2) and the other cubes'
        (n_cubes - n, 2). The result is a view into the walk's buffers: copy it to keep it."""
        current, candidate = self._current, self._candidate
        if self.n == 0:
            return current
        self._others[:] = others_xy
        current[:] = xy
        np.add(current, self.next_move(random_state), out=candidate)
        np.maximum(candidate, _LOW, out=candidate)
        np.minimum(candidate, _HIGH, out=candidate)
        d = np.abs(self._candidate_column - self._points)
        d += self._self_pairs
        if d.min() < layout.DISTRACTOR_MIN_SEPARATION:
            self._redraw(random_state)
        return candidate

    def _redraw(self, random_state: np.random.RandomState) -> None:
        """Redraw the candidates that end too close to another cube; whoever still collides
        after `MAX_REDRAWS` redraws stays where it is. The others were checked against the current
        positions of everyone, so every pair stays apart."""
        current, candidate = self._current, self._candidate
        for _ in range(MAX_REDRAWS):
            bad = self._too_close()
            if not bad.any():
                return
            redraw = current[bad] + random_state.normal(
                0.0, layout.DISTRACTOR_WALK_STD, (int(bad.sum()), 2)
            )
            candidate[bad] = np.clip(redraw, _LOW, _HIGH)
        bad = self._too_close()
        candidate[bad] = current[bad]
