"""C4's own claim: LP-based selection degrades less than uniform selection as distracting
modules are added.

The measure (fixed before any `distractors_0` run was read): each run's self-evaluated
competence over the achievable modules at the common budget (`final_competence`). A
condition's loss is its mean at the fewest distracting modules minus its mean at the most
(0 and 7 in the `laptop` campaign). The test is on the difference of the two conditions'
losses, D = loss(better) - loss(worse), the interaction of condition and setting: its standard
error from the four groups' sample variances, sqrt(sum s^2 / n), its degrees of freedom by the
Welch-Satterthwaite equation over the four groups, and a one-tailed p that D < 0 (the better
condition loses less). Seeds of one setting are independent runs of the other, so the four
groups are independent samples.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from curious.analysis.loading import AnalysisError, first_clash

__all__ = ["compare_degradation"]


def compare_degradation(final: pd.DataFrame, better: str, worse: str) -> dict[str, float]:
    """The test of the module docstring on `final` (rows of `final_competence` with
    ``condition``, ``n_distractors`` and ``value``), between its fewest and most distracting
    modules. Returns ``fewest``, ``most`` (the two settings), ``loss_<condition>`` for both,
    ``difference`` (D), ``se``, ``df``, ``t`` and ``p`` (NaN where a group has fewer than two
    seeds, or no variance at all), and the four groups' sizes ``n_<condition>_<setting>``."""
    missing = [c for c in ("condition", "n_distractors", "value") if c not in final]
    if missing:
        raise AnalysisError(
            f"this table lacks {', '.join(missing)}: pass final_competence (or "
            "final_test_success) of runs with distracting modules"
        )
    if better == worse:
        raise AnalysisError(f"compare_degradation compares two conditions, got '{better}' twice")
    _check_one_run_per_seed(final)
    settings = sorted(int(n) for n in final["n_distractors"].dropna().unique())
    if len(settings) < 2:
        raise AnalysisError(
            f"the degradation needs runs at two numbers of distracting modules, have {settings}"
        )
    fewest, most = settings[0], settings[-1]
    out: dict[str, float] = {"fewest": fewest, "most": most}
    terms, losses = [], {}
    for name in (better, worse):
        means = []
        for setting in (fewest, most):
            rows = (final["condition"] == name) & (final["n_distractors"] == setting)
            values = final.loc[rows, "value"].dropna().to_numpy(float)
            if len(values) == 0:
                raise AnalysisError(f"no runs of condition '{name}' with {setting} distractors")
            out[f"n_{name}_{setting}"] = len(values)
            means.append(values.mean())
            var = values.var(ddof=1) if len(values) >= 2 else np.nan
            terms.append((var / len(values), len(values)))
        losses[name] = means[0] - means[1]
        out[f"loss_{name}"] = float(losses[name])
    difference = losses[better] - losses[worse]
    shares = np.array([share for share, _ in terms])
    sizes = np.array([n for _, n in terms])
    se = float(np.sqrt(shares.sum()))
    out.update(difference=float(difference), se=se, df=np.nan, t=np.nan, p=np.nan)
    if np.all(np.isfinite(shares)) and se > 0:
        df = shares.sum() ** 2 / np.sum(shares**2 / (sizes - 1))
        t = difference / se
        out.update(df=float(df), t=float(t), p=float(stats.t.cdf(t, df)))
    return out


def _check_one_run_per_seed(final: pd.DataFrame) -> None:
    """An `AnalysisError` where a setting (a number of distracting modules) holds runs of
    several variants (the sensory failure's runs have no distractors either), or a condition's
    seed twice there: either would count one seed as several."""
    if "variant" in final:
        variants = final.groupby("n_distractors", observed=True)["variant"].unique()
        for setting, names in variants.items():
            if len(names) > 1:
                raise AnalysisError(
                    f"the runs with {setting} distracting modules are of several variants "
                    f"({', '.join(sorted(map(str, names)))}): select one experiment's runs"
                )
    if "seed" in final:
        keys = ["condition", "n_distractors", "seed"]
        twice = first_clash(final, keys)
        if not twice.empty:
            condition, setting, seed = twice.iloc[0][keys]
            raise AnalysisError(
                f"condition '{condition}' seed {seed} has several runs with {setting} "
                "distracting modules: each seed must count once (a table concatenated twice, "
                "or runs of two experiments?)"
            )
