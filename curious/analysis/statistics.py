"""Statistics over loaded runs: success over achievable modules, episode bins, seeds, and Welch
tests: the comparison of conditions (Fig. 2a, the distractors). Recovery after the sensory
failure is `curious.analysis.perturbation`.

Test success (the y axis of the paper's Fig. 2a, `epoch_success`). After every epoch the trainer
runs noise-free test rollouts on separate environment copies, modules drawn uniformly and goals
uniform (``tests.parquet``; the authors' evaluator). A run's success at an epoch is the success
rate of that epoch's test rollouts **pooled over those on achievable modules**, plotted at the
number of training episodes done when they ran. Pooled rather than a mean of per-module rates:
the authors' evaluator pooled the epoch's test episodes; since modules are drawn uniformly, the
pooled rate estimates the mean of the per-module rates without bias; and it is defined at every
epoch, where a per-module rate is not (with 20 test rollouts an epoch over 7 modules, the
`quick` preset's, a module gets none in about one epoch in twenty, and a module with one test
would weigh as much as one with six). An epoch without any test on an achievable module has NaN
success and is left out rather than guessed. In ``her`` a row's ``success`` is its holistic goal
met (the paper's score, whichever module the row names), so its rows on achievable modules are a
uniform subsample of that one measure.

Competence (`achievable_competence`, Fig. 2b/2c, the distractors figure, recovery). For each run
and each episode, the mean, over the modules the run's config marks as achievable, of the
``competence/<module>`` columns of ``metrics.parquet``: each is the success rate of that module's
last self-evaluation episodes (the agent's own competence measure, the one learning progress is
computed from), after that episode. Distractor modules are left out of the mean. A NaN competence
(a module not yet measured, if the agent writes NaN for that) makes the mean NaN, and the bin is
then left out of the statistics rather than guessed.

Episode bins. Bins are ``[k w, (k + 1) w)`` for a bin width of ``w`` episodes, labelled by their
end, ``episodes = (k + 1) w`` (the number of episodes run when the bin closes). A run's value in a
bin is its value **at the end of the bin** (the row of the last episode ``< (k + 1) w``): competence
is already a moving average over evaluation episodes, so sampling it is a faithful, lag-free
reading of "competence after so many episodes", where a mean inside the bin would add a lag of
half a bin. A run contributes only the bins it completed, so seeds with equal budgets line up
exactly.

Across seeds: mean and sample standard deviation (``ddof=1``, NaN for one seed) per condition and
bin, with the number of seeds ``n``. Between two conditions: Welch's t-test per bin
(`scipy.stats.ttest_ind` with ``equal_var=False`` and ``alternative="greater"``: one-tailed, the
alternative being that the first condition's mean is greater), significant where ``p < alpha``
(alpha = 0.01 as in the paper). A bin where either condition has fewer than two seeds gets
``p = NaN`` and is not significant.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Sequence

import numpy as np
import pandas as pd
from scipy import stats

from curious.analysis.loading import (
    AnalysisError,
    first_clash,
    name_list,
    require_alpha,
    require_count,
    require_episode,
    require_learner,
    require_runs,
    require_tests,
    require_values,
)

__all__ = [
    "ALPHA",
    "COMPARISON_BINS",
    "FLOAT32_SLACK",
    "RUN_COLUMNS",
    "achievable_competence",
    "across_seeds",
    "area_under_success",
    "bin_runs",
    "binned_success",
    "check_comparable",
    "comparison_bin_size",
    "distractor_share",
    "epoch_success",
    "final_competence",
    "final_success",
    "final_test_success",
    "holm",
    "main_comparison",
    "nice_bin_size",
    "on_achievable",
    "replay_share",
    "run_arrays",
    "welch_greater",
    "welch_per_bin",
]

ALPHA = 0.01

COMPARISON_BINS = 20
"""The main comparison is read in this many episode bins of a run's budget (`comparison_bin_size`:
5,000 episodes for the `laptop` budget's 100,000): Fig. 2a's points, its Welch tests, the final
success and the report's numbers all come from `main_comparison` on these bins."""

FLOAT32_SLACK = 1e-6
"""Competences are stored as float32 (0.7 reads 0.69999999): comparisons with a level allow
this much."""

RUN_COLUMNS: tuple[str, ...] = (
    "run",
    "condition",
    "seed",
    "variant",
    "preset",
    "achievable_modules",
    "n_distractors",
)
"""The columns that say which run a row of a per-run table belongs to."""


def run_identity(frame: pd.DataFrame) -> pd.DataFrame:
    """Each run's `RUN_COLUMNS` but ``run`` (its first row's), indexed by ``run``: what a per-run
    table joins to say which run a row belongs to."""
    return frame.groupby("run", observed=True, sort=True)[list(RUN_COLUMNS[1:])].first()


def achievable_competence(df: pd.DataFrame) -> pd.Series:
    """Per row: mean of ``competence/<m>`` over the run's achievable modules (see module doc)."""
    require_runs(df)
    out = np.full(len(df), np.nan)
    for achievable, rows in df.groupby("achievable_modules", observed=True).indices.items():
        modules = [m for m in str(achievable).split(",") if m]
        if not modules:
            raise AnalysisError("a run has no achievable module: nothing to average success over")
        columns = [f"competence/{m}" for m in modules]
        values = df[columns].to_numpy(dtype=np.float64)[rows]
        out[rows] = values.mean(axis=1)
    return pd.Series(out, index=df.index, name="achievable_competence")


def nice_bin_size(n_episodes: int, target_bins: int = 50) -> int:
    """The largest of 1, 2, 5, 10, 20, 50, ... that gives at least ``target_bins`` bins."""
    numbers = all(
        isinstance(v, int | float | np.number) and not isinstance(v, bool)
        for v in (n_episodes, target_bins)
    )
    finite = numbers and np.isfinite(n_episodes) and np.isfinite(target_bins)
    if not finite or n_episodes < 1 or target_bins < 1:
        raise ValueError(
            f"need n_episodes >= 1 and target_bins >= 1, got {n_episodes}, {target_bins}"
        )
    raw = n_episodes / target_bins
    best = 1
    scale = 1
    while scale <= raw:
        for step in (1, 2, 5):
            if step * scale <= raw:
                best = step * scale
        scale *= 10
    return best


def run_arrays(
    df: pd.DataFrame, values: np.ndarray
) -> Iterator[tuple[str, int, np.ndarray, np.ndarray]]:
    """Yields (run, first row index, episodes, values) per run of a loaded table, episodes
    ascending; ``values`` is aligned with ``df``'s rows (one value per row, or one row of
    several columns per row)."""
    for run, rows in df.groupby("run", observed=True, sort=True).indices.items():
        episodes = df["episode"].to_numpy()[rows]
        order = np.argsort(episodes, kind="stable")
        yield run, rows[order[0]], episodes[order], values[rows][order]


def _values(df: pd.DataFrame, values: pd.Series | str | None) -> np.ndarray:
    if values is None:
        return achievable_competence(df).to_numpy()
    if isinstance(values, str):
        if values not in df.columns:
            raise KeyError(f"no column {values!r} in the table")
        values = df[values]
    if len(values) != len(df):
        raise ValueError(f"values has {len(values)} rows, the table {len(df)}")
    if isinstance(values, pd.Series):
        if not pd.api.types.is_numeric_dtype(values) and not pd.api.types.is_bool_dtype(values):
            raise AnalysisError(f"values {values.name!r} holds no numbers ({values.dtype})")
        if not values.index.equals(df.index):  # aligned by label, as pandas aligns
            if values.index.has_duplicates or not values.index.isin(df.index).all():
                raise ValueError(
                    "values is a Series whose index is not the table's rows: pass a column "
                    "name, or a Series computed from this table"
                )
            values = values.reindex(df.index)
    return np.asarray(values, dtype=np.float64)


def _longer_than_every_run(bin_size: int, last: int, verb: str) -> AnalysisError:
    """The error for a bin no run completed (an empty table, read downstream as no data)."""
    return AnalysisError(
        f"bin_size {bin_size:,} is longer than every run (the longest {verb} episode "
        f"{last:,}): choose a smaller one, or None for the default"
    )


def bin_runs(
    df: pd.DataFrame, values: pd.Series | str | None = None, bin_size: int | None = None
) -> pd.DataFrame:
    """Each run's value at the end of each episode bin it completed.

    ``values`` is a column name, a Series aligned with ``df``, or None for
    `achievable_competence`. ``bin_size`` defaults to `nice_bin_size` of the longest run.
    Returns one row per (run, bin): the run's identity columns, ``bin`` (k), ``episodes`` (the bin
    end, ``(k + 1) * bin_size``) and ``value``.
    """
    require_runs(df)
    data = _values(df, values)
    if bin_size is None:
        bin_size = nice_bin_size(int(df["episode"].max()) + 1)
    require_count(bin_size, "bin_size", "episode")
    parts = []
    for _run, first, episodes, run_values in run_arrays(df, data):
        n_bins = (int(episodes[-1]) + 1) // bin_size
        if n_bins == 0:
            continue
        ends = (np.arange(n_bins) + 1) * bin_size
        at = np.searchsorted(episodes, ends - 1, side="right") - 1
        ok = at >= 0
        columns = {c: np.repeat(np.array([df[c].iat[first]]), ok.sum()) for c in RUN_COLUMNS}
        columns["bin"] = np.arange(n_bins)[ok]
        columns["episodes"] = ends[ok]
        columns["value"] = run_values[at[ok]]
        parts.append(pd.DataFrame(columns))
    columns = [*RUN_COLUMNS, "bin", "episodes", "value"]
    if not parts:
        if len(df):
            raise _longer_than_every_run(bin_size, int(df["episode"].max()), "ends at")
        return pd.DataFrame(columns=columns)
    out = pd.concat(parts, ignore_index=True)
    out.attrs["bin_size"] = bin_size
    return out[columns]


def check_comparable(runs: pd.DataFrame, conditions: Sequence[str] | None = None) -> None:
    """Raises `AnalysisError` unless the runs can be averaged and compared as seeds.

    The runs (rows of a loaded or binned table, restricted to ``conditions`` when given) must
    share their achievable modules (else "average over achievable modules" means different
    things), and each (condition, seed) must be a single run (else a seed would count twice).
    """
    if conditions is not None:
        runs = runs[runs["condition"].isin(list(conditions))]
    per_run = runs.groupby("run", observed=True)[
        ["condition", "seed", "variant", "achievable_modules"]
    ].first()
    sets = sorted(per_run["achievable_modules"].astype(str).unique())
    if len(sets) > 1:
        raise AnalysisError(
            "these runs have different achievable modules, so their averages do not compare: "
            + "; ".join(f"[{s}]" for s in sets)
            + " (select one variant first)"
        )
    twice = per_run.groupby(["condition", "seed"], observed=True).size()
    twice = twice[twice > 1]
    if not twice.empty:
        condition, seed = twice.index[0]
        clash = per_run[(per_run["condition"] == condition) & (per_run["seed"] == seed)]
        raise AnalysisError(
            f"condition '{condition}' seed {seed} has {len(clash)} runs (variants "
            f"{', '.join(sorted(clash['variant'].astype(str)))}): select one run per seed, e.g. "
            "by variant, before comparing"
        )


def across_seeds(binned: pd.DataFrame, by: Sequence[str] = ("condition",)) -> pd.DataFrame:
    """Mean, sample std (ddof=1) and count over runs, per ``by`` + ``episodes``.

    NaN values (see the module doc) are left out and not counted in ``n``. Each group's runs
    must be one per seed: runs of several variants (or experiments) under one condition and
    seed are an `AnalysisError` naming them, not averaged as if they were seeds (select a
    variant first, or add ``"variant"`` or ``"n_distractors"`` to ``by``).
    """
    by = name_list(by, "by") or []
    require_values(binned, "across_seeds", per=[c for c in by if c in binned])
    if missing := [c for c in by if c not in binned]:
        raise AnalysisError(f"by names no column {', '.join(map(repr, missing))} of this table")
    keys = [*by, "seed"]
    telling = [c for c in ("variant", "preset", "n_distractors") if c in binned]
    shown = list(dict.fromkeys([*keys, *telling]))
    per_run = binned.groupby("run", observed=True)[shown].first()
    clash = first_clash(per_run, keys)
    if not clash.empty:
        first = clash.iloc[0]
        differ = [c for c in telling if c not in keys and clash[c].astype(str).nunique() > 1]
        if differ:
            column = differ[0]
            values = ", ".join(sorted(clash[column].astype(str)))
            fix = f"select one {column}, or pass by=(..., {column!r})"
        else:  # the same settings: runs of two folders (two experiments, or a copy)
            values = ", ".join(map(str, clash.index))
            column, fix = "runs", "read one experiment's runs (one folder) at a time"
        raise AnalysisError(
            f"{', '.join(f'{k} {first[k]}' for k in keys)} has {len(clash)} runs (their {column}: "
            f"{values}): {fix}, so that each seed counts once"
        )
    keys = [*by, "episodes"]
    valid = binned.dropna(subset=["value"])
    grouped = valid.groupby(keys, observed=True, sort=True)["value"]
    out = grouped.agg(mean="mean", std=lambda v: v.std(ddof=1), n="size").reset_index()
    out["n"] = out["n"].astype(np.int64)
    return out


def welch_per_bin(
    binned: pd.DataFrame, better: str, worse: str, alpha: float = ALPHA
) -> pd.DataFrame:
    """One-tailed Welch's t-test per bin that ``better`` has a greater mean than ``worse``.

    Returns one row per bin both conditions reach: ``episodes``, ``n_better``, ``n_worse``,
    ``mean_better``, ``mean_worse``, ``t``, ``p`` and ``significant`` (``p < alpha``; False where
    p is NaN, i.e. fewer than two seeds on a side or no variance at all), and ``p_holm`` and
    ``significant_holm``: the same tests corrected for their number by `holm` (the paper
    corrects nothing; both readings are given).
    """
    require_alpha(alpha)
    require_values(binned, "welch_per_bin")
    if not isinstance(better, str) or not isinstance(worse, str):
        raise AnalysisError(
            f"welch_per_bin compares two conditions by name, got {better!r} and {worse!r}"
        )
    if better == worse:
        raise AnalysisError(f"welch_per_bin compares two conditions, got '{better}' twice")
    present = set(binned["condition"].astype(str))
    for name in (better, worse):
        if name not in present:
            raise AnalysisError(
                f"no runs of condition '{name}' (have: {', '.join(sorted(present)) or 'none'})"
            )
    check_comparable(binned, [better, worse])
    valid = binned.dropna(subset=["value"])
    a_groups = {
        e: g.to_numpy() for e, g in valid[valid["condition"] == better].groupby("episodes")["value"]
    }
    b_groups = {
        e: g.to_numpy() for e, g in valid[valid["condition"] == worse].groupby("episodes")["value"]
    }
    rows = []
    for episodes in sorted(set(a_groups) & set(b_groups)):
        a, b = a_groups[episodes], b_groups[episodes]
        t, p = welch_greater(a, b)
        rows.append(
            {
                "episodes": int(episodes),
                "n_better": len(a),
                "n_worse": len(b),
                "mean_better": float(a.mean()),
                "mean_worse": float(b.mean()),
                "t": t,
                "p": p,
                "significant": bool(p < alpha) if np.isfinite(p) else False,
            }
        )
    columns = [
        "episodes",
        "n_better",
        "n_worse",
        "mean_better",
        "mean_worse",
        "t",
        "p",
        "significant",
    ]
    out = pd.DataFrame(rows, columns=columns)
    out["p_holm"] = holm(out["p"].to_numpy(np.float64))
    out["significant_holm"] = out["p_holm"] < alpha  # NaN compares False
    return out


def holm(p: np.ndarray) -> np.ndarray:
    """Holm's step-down adjusted p values of a family of tests (NaN where a test has no p,
    and left out of the family's size): the i-th smallest of m p values times (m - i + 1),
    made non-decreasing and capped at 1, so that `adjusted < alpha` controls the chance of any
    false rejection among them at alpha."""
    p = np.asarray(p, dtype=np.float64)
    out = np.full(p.shape, np.nan)
    tested = np.flatnonzero(np.isfinite(p))
    order = tested[np.argsort(p[tested], kind="stable")]
    m = order.size
    scaled = p[order] * (m - np.arange(m))
    out[order] = np.minimum(np.maximum.accumulate(scaled), 1.0)
    return out


def welch_greater(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """One-tailed Welch's t-test that ``a``'s mean is the greater: (t, p), both NaN with fewer
    than two values a side."""
    if len(a) < 2 or len(b) < 2:
        return np.nan, np.nan
    with warnings.catch_warnings():  # a side of equal values (HER's zeros) makes scipy warn
        # of precision loss in its variance, which is 0 then: the test stands on the other's
        warnings.filterwarnings("ignore", "Precision loss occurred", RuntimeWarning)
        result = stats.ttest_ind(a, b, equal_var=False, alternative="greater")
    return float(result.statistic), float(result.pvalue)


def final_competence(df: pd.DataFrame, at_episode: int | None = None) -> pd.DataFrame:
    """Each run's average success over achievable modules after episode ``at_episode``.

    ``at_episode`` defaults to the last episode that every run reached (the common budget), so
    that longer runs are not favoured. Returns one row per run: identity columns, ``episodes``
    (``at_episode + 1``) and ``value``.
    """
    require_runs(df)
    last_per_run = df.groupby("run", observed=True)["episode"].max()
    if at_episode is None:
        at_episode = int(last_per_run.min())
    require_episode(at_episode, "at_episode")
    short = last_per_run[last_per_run < at_episode]
    if not short.empty:
        raise AnalysisError(
            f"run {short.index[0]} ends at episode {int(short.iloc[0])}, before {at_episode}"
        )
    data = achievable_competence(df).to_numpy()
    rows = []
    for _run, first, episodes, values in run_arrays(df, data):
        at = int(np.searchsorted(episodes, at_episode, side="right")) - 1
        row = {c: df[c].iat[first] for c in RUN_COLUMNS}
        row.update(episodes=at_episode + 1, value=float(values[at]) if at >= 0 else np.nan)
        rows.append(row)
    return pd.DataFrame(rows, columns=[*RUN_COLUMNS, "episodes", "value"])


def on_achievable(tests: pd.DataFrame) -> np.ndarray:
    """(n,) bool: whether each row's module (a test rollout's, or the module a training episode
    practised) is achievable in its run."""
    out = np.zeros(len(tests), bool)
    module = tests["module"].astype(str).to_numpy()
    for achievable, rows in tests.groupby("achievable_modules", observed=True).indices.items():
        out[rows] = np.isin(module[rows], [m for m in str(achievable).split(",") if m])
    return out


def epoch_success(tests: pd.DataFrame, bin_size: int | None = None) -> pd.DataFrame:
    """Each run's test success over achievable modules, one point per epoch (see module doc).

    ``tests`` is a `load_tests` table. With ``bin_size`` (episodes), the test rollouts of the
    epochs that ended in ``((k - 1) w, k w]`` are pooled into one point at ``k w``, and a run
    contributes only the bins it completed. Returns one row per (run, point), in the form
    `across_seeds` and `welch_per_bin` take: the run columns, ``episodes`` (training episodes
    done when the tests ran, or the bin end), ``epoch`` (the point's last epoch), ``n_tests``
    (test rollouts on achievable modules pooled) and ``value`` (their success rate; NaN where
    ``n_tests`` is 0).
    """
    require_tests(tests)
    if bin_size is not None:
        require_count(bin_size, "bin_size", "episode")
    hit = on_achievable(tests)
    episodes = tests["episode"].to_numpy(np.int64)
    points = episodes if bin_size is None else -(-episodes // bin_size) * bin_size
    frame = pd.DataFrame(
        {
            "run": tests["run"].to_numpy(),
            "episodes": points,
            "epoch": tests["epoch"].to_numpy(np.int64),
            "hit": hit.astype(np.int64),
            "value": np.where(hit, tests["success"].to_numpy(np.float64), np.nan),
        }
    )
    grouped = frame.groupby(["run", "episodes"], sort=True)
    out = grouped.agg(epoch=("epoch", "max"), n_tests=("hit", "sum"), value=("value", "mean"))
    out = out.reset_index()
    last = pd.Series(episodes, index=frame["run"]).groupby(level=0).max()
    out = out[out["episodes"] <= out["run"].map(last)]
    if out.empty and bin_size is not None:
        raise _longer_than_every_run(bin_size, int(episodes.max()), "was tested up to")
    identity = run_identity(tests)
    out = out.join(identity, on="run")
    out["run"] = out["run"].astype(tests["run"].dtype)
    out.attrs["bin_size"] = bin_size
    return out[[*RUN_COLUMNS, "episodes", "epoch", "n_tests", "value"]].reset_index(drop=True)


def final_success(points: pd.DataFrame) -> pd.DataFrame:
    """Each run's test success at the last point every run reached (the common budget).

    ``points`` is an `epoch_success` table; longer runs are read at the common budget, so that
    they are not favoured. Returns one row per run: run columns, ``episodes``, ``n_tests`` and
    ``value``.
    """
    require_values(points, "final_success")
    if points.empty:
        raise AnalysisError("no test success points: the runs have no test rollouts yet")
    common = points.groupby("run", observed=True)["episodes"].max().min()
    upto = points[points["episodes"] <= common]
    last = upto.loc[upto.groupby("run", observed=True)["episodes"].idxmax()]
    columns = [*RUN_COLUMNS, "episodes", "n_tests", "value"]
    return last[columns].sort_values("run").reset_index(drop=True)


def area_under_success(tests: pd.DataFrame) -> pd.DataFrame:
    """Each run's test success averaged over every epoch up to the common budget: the area under
    its Fig. 2a curve divided by the budget, a summary of how fast it learned that depends on no
    bin edges (C1's reading beside the per-bin tests).

    ``tests`` is a `load_tests` table. Each epoch's success is `epoch_success`'s (its test
    rollouts on achievable modules pooled); the epochs are those every run reached (a longer run
    is read at the common budget, so it is not favoured), each weighing the same, as the epochs
    are evenly spaced; epochs without a test on an achievable module are left out (a run with
    none by then, as a `smoke` run can be, has ``n_epochs`` 0 and ``value`` NaN). Returns one
    row per run in the form `welch_per_bin` takes (all at one ``episodes``, the common budget):
    the run columns, ``episodes``, ``n_epochs`` and ``value``.
    """
    points = epoch_success(tests)
    if points.empty:
        raise AnalysisError("no test success points: the runs have no test rollouts yet")
    for column in ("preset", "variant"):
        kinds = sorted(points[column].astype(str).unique()) if column in points else []
        if len(kinds) > 1:
            raise AnalysisError(
                f"these runs are of different {column}s ({', '.join(kinds)}): each would be "
                f"read up to the shortest one's budget, so their areas do not compare; select "
                f"one {column} (one experiment)"
            )
    common = int(points.groupby("run", observed=True)["episodes"].max().min())
    upto = points[points["episodes"] <= common]
    grouped = upto.groupby("run", observed=True, sort=True)
    out = grouped[list(RUN_COLUMNS[1:])].first()
    out["episodes"] = common
    out["n_epochs"] = grouped["value"].count().astype(np.int64)  # NaN: no achievable test
    out["value"] = grouped["value"].mean()
    out = out.reset_index()
    return out[[*RUN_COLUMNS, "episodes", "n_epochs", "value"]]


def comparison_bin_size(n_episodes: int) -> int:
    """The main comparison's bin width for runs of ``n_episodes`` (`COMPARISON_BINS` bins,
    rounded down to 1, 2 or 5 times a power of ten by `nice_bin_size`): 5,000 for 100,000."""
    return nice_bin_size(n_episodes, COMPARISON_BINS)


def binned_success(tests: pd.DataFrame, bin_size: int | None = None) -> pd.DataFrame:
    """`epoch_success` in the main comparison's bins: the test rollouts of each run pooled per
    ``bin_size``-episode bin (default `comparison_bin_size` of the longest run's training
    episodes at its last test). ``attrs["bin_size"]`` says which width was used."""
    require_tests(tests)
    if bin_size is None:
        bin_size = comparison_bin_size(max(int(tests["episode"].max()), 1))
    return epoch_success(tests, bin_size)


def final_test_success(tests: pd.DataFrame, bin_size: int | None = None) -> pd.DataFrame:
    """Each run's test success over achievable modules in the last bin every run completed: the
    test-rollout counterpart of `final_competence` (the distractors' second measure, C4).

    The bins are the main comparison's (`binned_success`: by default 20 over the longest run's
    budget, rounded down: the last 5,000 of 100,000 episodes, 2,000 of 50,000), read by
    `final_success` at the common budget. Returns one row per run: the run columns,
    ``episodes`` (the bin's end), ``n_tests`` and ``value``, in the form `welch_per_bin` and
    `across_seeds` take.
    """
    points = binned_success(tests, bin_size)
    final = final_success(points)
    final.attrs["bin_size"] = points.attrs["bin_size"]
    return final


def distractor_share(df: pd.DataFrame, bin_size: int | None = None) -> pd.DataFrame:
    """Each run's share of training episodes that practised a distracting module (one its run
    cannot achieve), per ``bin_size``-episode bin it completed: how much of its practice a
    condition spends where nothing can be learned (C4's mechanism; M-UVFA's uniform choice puts
    it at distractors / modules).

    ``df`` is a `load_runs` table (its ``module`` column: the module each episode practised).
    ``bin_size`` defaults to `nice_bin_size` of the longest run. Returns one row per (run, bin):
    the run columns, ``episodes`` (the bin's end) and ``value`` (the share, 0 to 1).
    """
    require_runs(df)
    if "module" not in df:
        raise AnalysisError("this table has no module column: it says which module was practised")
    episode = df["episode"].to_numpy(np.int64)
    if bin_size is None:
        bin_size = nice_bin_size(int(episode.max()) + 1)
    require_count(bin_size, "bin_size", "episode")
    frame = pd.DataFrame(
        {
            "run": df["run"].to_numpy(),
            "episodes": (episode // bin_size + 1) * bin_size,
            "value": (~on_achievable(df)).astype(np.float64),
        }
    )
    out = frame.groupby(["run", "episodes"], observed=True, sort=True)["value"].mean()
    out = out.reset_index()
    done = pd.Series(episode + 1, index=frame["run"]).groupby(level=0, observed=True).max()
    out = out[out["episodes"] <= out["run"].map(done).astype(np.int64)]
    identity = run_identity(df)
    out = out.join(identity, on="run")
    out.attrs["bin_size"] = bin_size
    return out[[*RUN_COLUMNS, "episodes", "value"]].reset_index(drop=True)


def replay_share(learner: pd.DataFrame, bin_size: int | None = None) -> pd.DataFrame:
    """Each run's share of replayed transitions assigned to a distracting module, per
    ``bin_size``-episode bin its table covers whole: how much of its learning a condition spends
    on what cannot be learned, where `distractor_share` measures its practice.

    ``learner`` is a `load_learner` table (``replay/<module>``: the transitions each training
    cycle replayed as each module). A cycle that ended at ``e`` episodes counts in the bin of its
    last episode, ``((e - 1) // w + 1) w``, as in the episode bins above; a bin counts where the
    run completed it and its table covers it from its start (``from_episode``), and where
    something was replayed as a module (never in a condition that replays over the whole goal,
    as ``her`` does). ``bin_size`` defaults to `nice_bin_size` of the longest run; the run's
    length in episodes gives one share over the whole run. Returns one row per (run, bin): the
    run columns, ``episodes`` (the bin's end) and ``value`` (the share, 0 to 1).
    """
    require_learner(learner)
    episode = learner["episode"].to_numpy(np.int64)
    if bin_size is None:
        bin_size = nice_bin_size(int(episode.max()))
    require_count(bin_size, "bin_size", "episode")
    distracting = np.zeros(len(learner), np.float64)
    replayed = np.zeros(len(learner), np.float64)
    for (modules, achievable), rows in learner.groupby(
        ["modules", "achievable_modules"], observed=True
    ).indices.items():
        names = [m for m in str(modules).split(",") if m]
        counts = learner[[f"replay/{m}" for m in names]].to_numpy(np.float64)[rows]
        distractors = ~np.isin(names, [m for m in str(achievable).split(",") if m])
        distracting[rows] = counts[:, distractors].sum(axis=1)
        replayed[rows] = counts.sum(axis=1)
    frame = pd.DataFrame(
        {
            "run": learner["run"].to_numpy(),
            "episodes": ((episode - 1) // bin_size + 1) * bin_size,
            "distracting": distracting,
            "replayed": replayed,
        }
    )
    sums = frame.groupby(["run", "episodes"], observed=True, sort=True)[
        ["distracting", "replayed"]
    ].sum()
    out = sums.reset_index()
    done = learner.groupby("run", observed=True)["episode"].max()
    begins = learner.groupby("run", observed=True)["from_episode"].first()
    whole = (out["episodes"] <= out["run"].map(done).astype(np.int64)) & (
        out["episodes"] - bin_size >= out["run"].map(begins).astype(np.int64)
    )
    out = out[whole & (out["replayed"] > 0)]
    out = out.assign(value=out["distracting"] / out["replayed"])
    identity = run_identity(learner)
    out = out.join(identity, on="run")
    out.attrs["bin_size"] = bin_size
    return out[[*RUN_COLUMNS, "episodes", "value"]].reset_index(drop=True)


def main_comparison(
    tests: pd.DataFrame,
    better: str | None = None,
    worse: str | None = None,
    alpha: float = ALPHA,
    bin_size: int | None = None,
) -> dict[str, object]:
    """The main comparison's numbers, from one computation shared by Fig. 2a, the report and
    whatever quotes them: the test success of every run in the comparison's bins
    (`binned_success`), their mean ± std across seeds per condition and bin (`across_seeds`),
    each run's value in the last bin every run completed (`final_success`), and, given
    ``better`` and ``worse``, the one-tailed Welch test per bin (`welch_per_bin`).

    Returns a dict: ``bin_size``, ``points``, ``summary``, ``final`` (one row per run),
    ``final_summary`` (per condition: ``mean``, ``std``, ``n``, at ``episodes``), and ``welch``
    (None without a pair) with ``n_significant`` and ``n_bins``.
    """
    points = binned_success(tests, bin_size)
    final = final_success(points)
    grouped = final.groupby("condition", observed=True)["value"]
    final_summary = grouped.agg(mean="mean", std=lambda v: v.std(ddof=1), n="size").reset_index()
    final_summary["episodes"] = int(final["episodes"].max())
    out: dict[str, object] = {
        "bin_size": int(points.attrs["bin_size"]),
        "points": points,
        "summary": across_seeds(points),
        "final": final,
        "final_summary": final_summary,
        "welch": None,
        "n_significant": 0,
        "n_bins": 0,
    }
    if better is not None and worse is not None:
        welch = welch_per_bin(points, better, worse, alpha)
        out.update(welch=welch, n_significant=int(welch["significant"].sum()), n_bins=len(welch))
    return out
