"""Recovery times compared with the runs not recovered counted, not left out (C5 with five seeds a
side, docs/results.md: "Five seeds a side: rules fixed before seeds 3 and 4 trained").

`perturbation.compare_recoveries` (Welch) gives a run that had not recovered by its end no number,
so a slow condition's slowest runs leave its mean. Here each run is followed from its onset to
its end: a recovered run is an *event* at its episodes to recover, a run not recovered is
*censored* at the episodes it had after its onset (``episodes_left``). Two statistics compare
the conditions, both with their exact permutation p (every split of the runs into groups of
the conditions' sizes, the times and events fixed: 252 splits for five runs a side, where the
chi-square approximation of a log-rank test is rough):

- the **log-rank** statistic, the decision: over the distinct event times, the events of the
  faster condition minus those expected were both conditions alike, standardised (Z); one-sided,
  large when the faster condition recovers sooner. Its normal-approximation p is given beside.
- **Gehan's** generalised Wilcoxon statistic, a check that does not decide: over every pair of
  runs of the two conditions, +1 where the faster condition's run surely recovered first (an
  event before the other's time), -1 where the other's did, 0 where censoring leaves it open.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd
from scipy import stats

from curious.analysis.loading import AnalysisError, require_alpha
from curious.analysis.perturbation import _check_one_run_per_seed
from curious.analysis.statistics import ALPHA

__all__ = ["MAX_SPLITS", "compare_censored_recoveries", "logrank_z"]

MAX_SPLITS = 1_000_000
"""The exact permutation p enumerates every split of the runs; above this many it refuses."""


def logrank_z(times: np.ndarray, events: np.ndarray, in_first: np.ndarray) -> np.ndarray:
    """The standardised log-rank statistic of the first group against the rest, one per row of
    ``in_first`` (splits, runs: True for the first group's runs): (observed - expected events
    of the first group) / sqrt(variance), over the distinct event times, a censored run at risk
    at its own time. Positive where the first group has more events early than expected. NaN
    where the variance is 0 (no event, or no run at risk in one group at any event time)."""
    times = np.asarray(times, np.float64)
    events = np.asarray(events, bool)
    groups = np.atleast_2d(np.asarray(in_first, np.float64))
    moments = np.unique(times[events])
    at_risk = (times[:, None] >= moments[None, :]).astype(np.float64)  # runs x moments
    died = ((times[:, None] == moments[None, :]) & events[:, None]).astype(np.float64)
    n, d = at_risk.sum(axis=0), died.sum(axis=0)
    n1 = groups @ at_risk  # splits x moments
    observed = groups @ died.sum(axis=1)
    expected = (n1 * (d / n)).sum(axis=1)
    spread = np.where(n > 1, d * (n - d) / (n**2 * np.maximum(n - 1, 1)), 0.0)
    variance = (n1 * (n - n1) * spread).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(variance > 0, (observed - expected) / np.sqrt(variance), np.nan)


def _gehan(times: np.ndarray, events: np.ndarray, in_first: np.ndarray) -> np.ndarray:
    """Gehan's statistic of the first group against the rest, one per row of ``in_first``."""
    earlier = events[:, None] & (times[:, None] < times[None, :])  # run i surely before run j
    score = earlier.astype(np.float64) - earlier.T.astype(np.float64)
    groups = np.atleast_2d(np.asarray(in_first, np.float64))
    return ((groups @ score) * (1.0 - groups)).sum(axis=1)


def compare_censored_recoveries(
    per_run: pd.DataFrame, faster: str, slower: str, alpha: float = ALPHA
) -> dict[str, object]:
    """One-sided test that ``faster`` recovers in fewer episodes than ``slower``, the runs not
    recovered censored at their ``episodes_left`` (the module doc).

    ``per_run`` is a `recovery_by_tests` table (``condition``, ``status``, ``recovered``,
    ``recovery_episodes``, ``episodes_left``): runs whose ``status`` is not ``measured`` (the
    failure never started, or there was no level before it) have nothing to recover and are
    returned apart (``left_out``). Returns a dict: ``faster``, ``slower``, ``alpha``,
    ``n_faster`` and ``n_slower`` (runs compared), ``recovered_faster`` and
    ``recovered_slower``, ``z`` (the log-rank statistic), ``p`` (its exact permutation p),
    ``p_normal`` (its normal-approximation p), ``gehan`` and ``p_gehan``, ``splits`` (how many
    were enumerated), ``significant`` (``p < alpha``), ``runs`` (the rows compared, with
    ``time`` and ``event``) and ``left_out``."""
    require_alpha(alpha)
    if faster == slower:
        raise AnalysisError(f"compare_censored_recoveries compares two conditions, got '{faster}'")
    needed = ("condition", "status", "recovered", "recovery_episodes", "episodes_left")
    if missing := [c for c in needed if c not in per_run]:
        raise AnalysisError(
            f"this table lacks {', '.join(missing)}: pass a recovery_by_tests table"
        )
    _check_one_run_per_seed(per_run)
    pair = per_run[per_run["condition"].astype(str).isin([faster, slower])]
    for name in (faster, slower):
        if not (pair["condition"] == name).any():
            present = sorted(set(per_run["condition"].astype(str)))
            raise AnalysisError(
                f"no runs of condition '{name}' (have: {', '.join(present) or 'none'})"
            )
    measured = pair["status"] == "measured"
    runs = pair[measured].copy()
    runs["event"] = runs["recovered"].astype(bool)
    left = runs["episodes_left"].astype("Float64").to_numpy(np.float64, na_value=np.nan)
    runs["time"] = np.where(runs["event"], runs["recovery_episodes"].to_numpy(np.float64), left)
    first = (runs["condition"] == faster).to_numpy()
    n, k = len(runs), int(first.sum())
    out: dict[str, object] = {
        "faster": faster,
        "slower": slower,
        "alpha": alpha,
        "n_faster": k,
        "n_slower": n - k,
        "recovered_faster": int(runs["event"][first].sum()),
        "recovered_slower": int(runs["event"][~first].sum()),
        "runs": runs,
        "left_out": pair[~measured],
    }
    splits = math.comb(n, k)
    if splits > MAX_SPLITS:
        raise AnalysisError(
            f"{splits:,} splits of {n} runs: the exact p enumerates at most {MAX_SPLITS:,}"
        )
    times, events = runs["time"].to_numpy(np.float64), runs["event"].to_numpy(bool)
    z = p = p_normal = gehan = p_gehan = np.nan
    if k and n - k:
        every = np.zeros((splits, n))
        for row, chosen in enumerate(itertools.combinations(range(n), k)):
            every[row, list(chosen)] = 1.0
        z = float(logrank_z(times, events, first)[0])
        if np.isfinite(z):
            all_z = logrank_z(times, events, every)
            p = float(np.mean(np.nan_to_num(all_z, nan=-np.inf) >= z - 1e-9))
            p_normal = float(stats.norm.sf(z))
        gehan = float(_gehan(times, events, first)[0])
        p_gehan = float(np.mean(_gehan(times, events, every) >= gehan - 1e-9))
    out.update(
        z=z,
        p=p,
        p_normal=p_normal,
        gehan=gehan,
        p_gehan=p_gehan,
        splits=splits,
        significant=bool(p < alpha) if np.isfinite(p) else False,
    )
    return out
