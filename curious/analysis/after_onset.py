"""The perturbed module's test success after the failure, read beside C5's fixed rules.

`perturbation.recovery_by_tests` gives each run one number, the first epoch back at 90 % of the
level before. Two readings size what that number hides (docs/results.md, "The study on a mastered
module: what its runs show"), neither a rule nor a test:

- `success_after_onset`: the module's pooled test success at fixed distances after each
  run's onset, the course of the recovery;
- `returns_below`: after a run's crossing, the epochs whose pooled rate was under its threshold
  again: a first crossing of a noisy rate is not a return held.

Both pool the test rollouts as the primary measure does (`milestones.module_test_success`,
5 epochs) and only windows wholly after the onset.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from curious.analysis.loading import AnalysisError, require_tests
from curious.analysis.milestones import module_test_success
from curious.analysis.perturbation import (
    _RATE_SLACK,
    _epoch_grid,
    _identity_by_path,
    _onsets_by_run,
    perturbed_module,
)
from curious.analysis.statistics import RUN_COLUMNS
from curious.config import DEFAULT_TEST_EPOCHS

__all__ = ["returns_below", "success_after_onset"]


def _after_onset(
    tests: pd.DataFrame,
    onsets: pd.Series | Mapping[str, object],
    module: str | None,
    window: int,
) -> pd.DataFrame:
    """The module's pooled test success at each epoch whose window lies wholly after its run's
    onset: ``run`` (as text), ``episodes``, ``since`` (episodes from the onset), ``value`` and
    ``n_tests``, in each run's order of epochs."""
    require_tests(tests)
    module = module if module is not None else perturbed_module(tests)
    grid = _epoch_grid(tests, _onsets_by_run(onsets))
    first_after = grid["position"].where(grid["after"]).groupby(grid["run"]).min()
    pooled = module_test_success(tests, window)
    pooled = pooled[pooled["module"].astype(str) == module]
    pooled = pooled.assign(run=pooled["run"].astype(str))
    rates = pooled[["run", "epoch", "value", "n_tests"]].merge(
        grid[["run", "epoch", "episodes", "position", "onset"]], on=["run", "epoch"]
    )
    rates = rates.join(first_after.rename("first_after"), on="run")
    rates = rates[rates["position"] >= rates["first_after"] + window - 1]
    rates["since"] = (rates["episodes"] - rates["onset"]).astype(np.int64)
    return rates.sort_values(["run", "position"]).reset_index(drop=True)


def success_after_onset(
    tests: pd.DataFrame,
    onsets: pd.Series | Mapping[str, object],
    offsets: Sequence[int],
    module: str | None = None,
    window: int = DEFAULT_TEST_EPOCHS,
) -> pd.DataFrame:
    """Each run's test success on the module at fixed distances after its onset.

    ``tests`` is a `load_tests` table, ``onsets`` each run's first episode with the failure
    (``failure_onsets(runs)["onset"]``), ``offsets`` the distances in episodes. For each run with
    an onset and each offset d: the rate pooled over the ``window`` epochs ending at the first
    epoch tested at or after onset + d whose window lies wholly after the onset (``episodes``,
    ``value``, ``n_tests``), NaN where the run was not tested that late. One row per (run,
    offset), with the run's columns and its ``onset``.
    """
    if not offsets or any(int(d) <= 0 for d in offsets):
        raise AnalysisError(f"offsets must be positive episodes after the onset, got {offsets}")
    rates = _after_onset(tests, onsets, module, window)
    rows = []
    for run, mine in rates.groupby("run", sort=True):
        onset = int(mine["onset"].iat[0])
        for d in offsets:
            late = mine[mine["since"] >= int(d)]
            hit = late.iloc[0] if len(late) else None
            rows.append(
                {
                    "run": run,
                    "onset": onset,
                    "offset": int(d),
                    "episodes": np.nan if hit is None else float(hit["episodes"]),
                    "value": np.nan if hit is None else float(hit["value"]),
                    "n_tests": 0 if hit is None else int(hit["n_tests"]),
                }
            )
    out = pd.DataFrame(rows, columns=["run", "onset", "offset", "episodes", "value", "n_tests"])
    return out.join(_identity_by_path(tests), on="run")[
        [*RUN_COLUMNS, "onset", "offset", "episodes", "value", "n_tests"]
    ]


def returns_below(
    tests: pd.DataFrame,
    by_tests: pd.DataFrame,
    window: int = DEFAULT_TEST_EPOCHS,
) -> pd.DataFrame:
    """After each recovered run's crossing, the epochs its pooled test success was under its
    threshold again.

    ``by_tests`` is `recovery_by_tests` of the same ``tests``; its recovered runs are read, with
    their ``threshold`` and ``recovered_episode``. Per run: ``n_after`` (epochs tested after the
    crossing), ``n_below`` (of those, the ones whose pooled rate was under the threshold) and
    ``last_below`` (episodes from the onset to the last of them; NA where none), with the run's
    columns, ``onset`` and ``threshold``.
    """
    missing = {"run", "recovered", "recovered_episode", "threshold", "onset", "module"} - set(
        by_tests
    )
    if missing:
        raise AnalysisError(f"by_tests must be recovery_by_tests' table; missing {sorted(missing)}")
    back = by_tests[by_tests["recovered"].astype(bool)].copy()
    back["run"] = back["run"].astype(str)
    module = str(back["module"].iat[0]) if len(back) else None
    onsets = back.set_index("run")["onset"]
    columns = [*RUN_COLUMNS, "onset", "threshold", "n_after", "n_below", "last_below"]
    if back.empty:
        return pd.DataFrame(columns=columns)
    rates = _after_onset(tests, onsets, module, window).join(
        back.set_index("run")[["threshold", "recovered_episode"]], on="run"
    )
    later = rates[rates["episodes"] > rates["recovered_episode"].astype(np.int64)]
    below = later[later["value"] < later["threshold"] - _RATE_SLACK]
    out = back.set_index("run")[["onset", "threshold"]]
    out["n_after"] = later.groupby("run").size().reindex(out.index, fill_value=0)
    out["n_below"] = below.groupby("run").size().reindex(out.index, fill_value=0)
    out["last_below"] = below.groupby("run")["since"].max().reindex(out.index).astype("Int64")
    out = out.join(_identity_by_path(tests)).rename_axis("run").reset_index()
    return out[columns]
