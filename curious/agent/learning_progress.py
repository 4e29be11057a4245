"""Competence, absolute learning progress and the selection probabilities p_LP (paper §6.2).

Each module keeps its self-evaluation results (1 success, 0 failure) in a queue of the last
2 x `window` results. With n results recorded for a module:

* competence = mean of the last min(n, window) results (0 before any result);
* LP = |mean of the last k results - mean of the k results before them|, k = min(window, n // 2),
  from the third result on (0 while n < 3, as the authors' `CompetenceQueue`, which updates only
  when it holds more than 2 results; flowersteam/curious, baselines/her/queues.py): the paper's
  "current competence against the one measured `window` results before", with the window shrunk
  to what has been recorded so far so that progress shows from the first evaluations on;
* p_LP = eps / N + (1 - eps) * LP / sum(LP), and uniform while sum(LP) = 0.

(The released code divided LP by 2 and measured competence over k results; neither changes p_LP.)

With `Config.lp_measure = "signed"` (not in the paper) LP is max(recent - before, 0) instead: a
rising competence counts, a falling one counts as no progress, so forgetting draws no practice.
"""

from __future__ import annotations

import numpy as np

from curious.config import LP_MEASURES

MIN_RESULTS_FOR_LP = 3
"""A module's LP is 0 until it has this many evaluation results (the authors' queue: size > 2)."""
MASTERED_COMPETENCE = 0.9
"""Competence at which a module counts as mastered: the one threshold that the agent's conditions
and the analysis read (`curious.analysis.drops`, the `sensor_failure_mastered` experiment's
onset, the report). Nine evaluations in ten succeeding: the higher of the report's two test
success milestones."""


def lp_probabilities(lp: np.ndarray, eps: float) -> np.ndarray:
    """p_LP from learning progress (absolute, or signed counted from 0): eps-uniform mixed with
    LP-proportional (eps is `Config.lp_eps`)."""
    lp = np.asarray(lp, dtype=np.float64)
    if np.any(lp < 0):
        raise ValueError("learning progress cannot be negative here (signed LP counts from 0)")
    n = lp.shape[-1]
    total = lp.sum()
    if total <= 0:
        return np.full(n, 1.0 / n)
    p = eps / n + (1.0 - eps) * lp / total
    return p / p.sum()


class CompetenceTracker:
    """Per-module queues of evaluation results and the measures computed from them."""

    def __init__(self, n_modules: int, window: int, measure: str) -> None:
        """`window`: `Config.lp_window`, the results competence averages; `measure`:
        `Config.lp_measure`, what LP measures (`LP_MEASURES`)."""
        if window <= 0:
            raise ValueError(f"window must be > 0, got {window}")
        if measure not in LP_MEASURES:
            raise ValueError(f"unknown LP measure {measure!r}; choose one of {LP_MEASURES}")
        self.n_modules = n_modules
        self.window = window
        self.measure = measure
        self.results = np.zeros((n_modules, 2 * window), dtype=np.float64)
        self.counts = np.zeros(n_modules, dtype=np.int64)
        self._competence = np.zeros(n_modules)
        self._lp = np.zeros(n_modules)

    def add(self, module: int, success: bool) -> None:
        """Record one evaluation result of `module`."""
        m = int(module)
        self.results[m, self.counts[m] % (2 * self.window)] = float(success)
        self.counts[m] += 1
        self._refresh(m)

    def _last(self, m: int, start: int, stop: int) -> np.ndarray:
        """Results with ages in [start, stop) counted back from the newest (age 0)."""
        n = self.counts[m]
        ages = np.arange(start, stop)
        return self.results[m, (n - 1 - ages) % (2 * self.window)]

    def _refresh(self, m: int) -> None:
        n = int(self.counts[m])
        w = self.window
        self._competence[m] = self._last(m, 0, min(n, w)).mean() if n else 0.0
        k = min(w, n // 2)
        if n < MIN_RESULTS_FOR_LP:
            self._lp[m] = 0.0
        else:
            recent = self._last(m, 0, k).mean()
            before = self._last(m, k, 2 * k).mean()
            change = recent - before
            self._lp[m] = abs(change) if self.measure == "absolute" else max(change, 0.0)

    def competence(self) -> np.ndarray:
        """(N,) competence of every module."""
        return self._competence.copy()

    def learning_progress(self) -> np.ndarray:
        """(N,) learning progress of every module, as `measure` says: what p_LP is formed from
        (and the `lp/<module>` columns of metrics.parquet log)."""
        return self._lp.copy()

    def p_lp(self, eps: float) -> np.ndarray:
        """(N,) module selection probabilities (eps is `Config.lp_eps`)."""
        return lp_probabilities(self._lp, eps)

    def state_dict(self) -> dict[str, np.ndarray]:
        return {"results": self.results.copy(), "counts": self.counts.copy()}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        results = np.asarray(state["results"], dtype=np.float64)
        if results.shape != self.results.shape:
            raise ValueError(
                f"competence queues: checkpoint shape {results.shape}, "
                f"expected {self.results.shape}"
            )
        self.results = results.copy()
        self.counts = np.asarray(state["counts"], dtype=np.int64).copy()
        for m in range(self.n_modules):
            self._refresh(m)
