"""When each module is learned: the episodes a run needs to reach a level of test success on
each achievable module, and the order in which its modules' competence crosses a level.

Test success per module (`module_test_success`). The test rollouts of an epoch are spread over
the modules (40 an epoch over 7 modules in the `laptop` preset: about 6 per module), too few
for one epoch's rate to say whether a module is learned. A module's test success at an epoch is
therefore its success rate over the test rollouts of the last ``window`` epochs pooled (5 by
default, as `curious progress` reads "test success, last 5 epochs"), defined once the run has
``window`` epochs of tests. `episodes_to_test_success` gives the training episodes done at the
first epoch where that rate reaches each level (C1's reading: 0.5 and 0.9 per seed), and
`module_success_rates` the rate over a run's last epochs (where each module stands at its end) or
over all of them. ``success`` is what Fig. 2a reads: in ``her``, the holistic goal met, so HER
reaches a level only if it meets its whole goal on that module's tests; ``module_success``
(`SCORES`) is whether the module's own part of the goal was met, the same as ``success`` in every
condition but ``her``, where it is a per-module view that is never the paper's score.

Order of learning (`competence_crossings`, `learning_order`). The first episode at which each
achievable module's competence (the moving success rate of the agent's self-evaluations, the
curves of Supp. Table 1), measured over a full window of evaluations, reaches a level, and the
modules ordered by it. The paper (Supp.
Materials, "Table 1" text): reach is always learned first, push cube 1 always second, then cube 1
above cube 2 and stack in either order (`PAPER_ORDER`). ``follows_paper`` says whether a run's
crossings agree with it: no module of a later group crossed before one of an earlier group
(a module that never crossed counts as crossing after every module that did).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
import pandas as pd

from curious.analysis.loading import AnalysisError, require_count, require_runs, require_tests
from curious.analysis.statistics import FLOAT32_SLACK, RUN_COLUMNS, on_achievable, run_identity
from curious.config import DEFAULT_TEST_EPOCHS

__all__ = [
    "LEVELS",
    "PAPER_ORDER",
    "competence_crossings",
    "episodes_to_test_success",
    "learning_order",
    "module_success_rates",
    "module_test_success",
]

LEVELS: tuple[float, ...] = (0.5, 0.9)
"""The test-success levels whose first crossing the report gives per module and seed."""

PAPER_ORDER: tuple[tuple[str, ...], ...] = (
    ("reach",),
    ("push_cube1",),
    ("cube1_above_cube2", "stack"),
)
"""The order of learning the paper reports (Supp. Materials, "Table 1"): groups in order, the
modules of one group in either order."""

SCORES: tuple[str, ...] = ("success", "module_success")
"""The columns of tests.parquet a module's test success can read: the condition's score (Fig.
2a's), or whether the module's own part of the goal was met."""


def _check_levels(levels: Sequence[float] | float) -> tuple[float, ...]:
    """`levels` as a tuple of floats in (0, 1]; one level may be given alone (`levels=0.5`)."""
    if isinstance(levels, int | float) and not isinstance(levels, bool):
        levels = (levels,)
    elif isinstance(levels, str | bool) or not isinstance(levels, Iterable):
        raise ValueError(f"levels takes numbers in (0, 1], got {levels!r}")
    levels = tuple(float(v) for v in levels)
    if not levels or any(not 0.0 < v <= 1.0 for v in levels):
        raise ValueError(f"levels must lie in (0, 1], got {levels}")
    return levels


def _achievable(identity: pd.DataFrame) -> pd.DataFrame:
    """One row per (run, achievable module): ``run``, ``slot`` (the module's rank among the
    run's achievable ones) and ``module``."""
    return pd.DataFrame(
        [
            (run, slot, module)
            for run, achievable in identity["achievable_modules"].astype(str).items()
            for slot, module in enumerate(m for m in achievable.split(",") if m)
        ],
        columns=["run", "slot", "module"],
    )


def module_success_rates(
    tests: pd.DataFrame, epochs: int | None = DEFAULT_TEST_EPOCHS, score: str = "success"
) -> pd.DataFrame:
    """Each run's test success on each achievable module over its last ``epochs`` epochs, or
    over every epoch (``epochs=None``): where each module stands at the run's end (`curious
    progress` reads the same 5 epochs), or the whole run's rate.

    ``tests`` is a `load_tests` table; ``score`` one of `SCORES`. The epochs are the run's last
    ``epochs`` tested ones (all it has, if fewer). Returns one row per (run, achievable module
    in slot order): the run columns, ``module``, ``episodes`` (training episodes done at the
    run's last test), ``n_tests`` (the module's test rollouts pooled) and ``value`` (the share
    of them whose ``score`` was met; NaN where ``n_tests`` is 0).
    """
    require_tests(tests)
    if score not in SCORES:
        raise AnalysisError(f"score must be one of {', '.join(SCORES)}, got {score!r}")
    if epochs is not None:
        require_count(epochs, "epochs", "epoch")
    epoch = tests["epoch"].to_numpy(np.int64)
    keep = on_achievable(tests)
    if epochs is not None:
        distinct = tests.groupby("run", observed=True)["epoch"].unique()
        first = tests["run"].map(distinct.map(lambda e: np.sort(e)[-epochs:][0]))
        keep &= epoch >= first.to_numpy(np.int64)
    kept = pd.DataFrame(
        {
            "run": tests["run"].to_numpy()[keep],
            "module": tests["module"].astype(str).to_numpy()[keep],
            "won": tests[score].to_numpy(bool)[keep].astype(np.int64),
        }
    )
    counts = kept.groupby(["run", "module"], observed=True)["won"].agg(won="sum", n="size")
    identity = run_identity(tests)
    out = _achievable(identity).join(counts, on=["run", "module"]).fillna({"won": 0, "n": 0})
    out["episodes"] = out["run"].map(tests.groupby("run", observed=True)["episode"].max())
    out["n_tests"] = out["n"].astype(np.int64)
    out["value"] = out["won"] / out["n"].where(out["n"] > 0)
    out = out.join(identity, on="run").sort_values(["run", "slot"], kind="stable")
    out["run"] = out["run"].astype(tests["run"].dtype)
    out["episodes"] = out["episodes"].astype(np.int64)
    out.attrs.update(epochs=epochs, score=score)
    columns = [*RUN_COLUMNS, "module", "episodes", "n_tests", "value"]
    return out[columns].reset_index(drop=True)


def module_test_success(tests: pd.DataFrame, window: int = DEFAULT_TEST_EPOCHS) -> pd.DataFrame:
    """Each run's test success on each achievable module, pooled over the last ``window`` epochs.

    ``tests`` is a `load_tests` table. Returns one row per (run, achievable module, epoch) from
    the run's ``window``-th epoch on, modules in slot order: the run columns, ``module``,
    ``epoch``, ``episodes`` (training episodes done when the epoch's tests ran), ``n_tests`` (the
    module's test rollouts in the window) and ``value`` (their success rate; NaN where
    ``n_tests`` is 0).
    """
    require_tests(tests)
    require_count(window, "window", "epoch")
    epochs = tests.groupby(["run", "epoch"], observed=True, sort=True)["episode"].max()
    epochs = epochs.rename("episodes").reset_index()
    identity = run_identity(tests)
    modules = _achievable(identity)
    hit = on_achievable(tests)
    counts = (
        pd.DataFrame(
            {
                "run": tests["run"].to_numpy()[hit],
                "module": tests["module"].astype(str).to_numpy()[hit],
                "epoch": tests["epoch"].to_numpy(np.int64)[hit],
                "won": tests["success"].to_numpy(bool)[hit].astype(np.int64),
            }
        )
        .groupby(["run", "module", "epoch"], observed=True)["won"]
        .agg(won="sum", n="size")
    )
    grid = modules.merge(epochs, on="run").sort_values(["run", "slot", "epoch"])
    grid = grid.join(counts, on=["run", "module", "epoch"]).fillna({"won": 0, "n": 0})
    rolling = grid.groupby(["run", "module"], observed=True, sort=False)[["won", "n"]].rolling(
        window, min_periods=window
    )
    pooled = rolling.sum().reset_index(level=[0, 1], drop=True)
    grid["n_tests"] = pooled["n"]
    grid["value"] = pooled["won"] / pooled["n"].where(pooled["n"] > 0)
    grid = grid.dropna(subset=["n_tests"])
    out = grid.join(identity, on="run")
    out["run"] = out["run"].astype(tests["run"].dtype)
    out["n_tests"] = out["n_tests"].astype(np.int64)
    out.attrs["window"] = window
    columns = [*RUN_COLUMNS, "module", "epoch", "episodes", "n_tests", "value"]
    return out[columns].reset_index(drop=True)


def episodes_to_test_success(
    tests: pd.DataFrame,
    levels: Sequence[float] | float = LEVELS,
    window: int = DEFAULT_TEST_EPOCHS,
) -> pd.DataFrame:
    """The training episodes each run needed to reach each level of test success per module.

    Reads `module_test_success` (``window`` epochs pooled; a run with fewer epochs has reached
    nothing yet). Returns one row per (run, achievable module in slot order, level): the run
    columns, ``module``, ``level``, ``episodes`` (at the first epoch whose pooled success reached
    the level; NA if none did) and ``last_episodes`` (the run's last tested epoch: a run not
    there yet may still get there).
    """
    levels = _check_levels(levels)
    success = module_test_success(tests, window)
    identity = run_identity(tests)
    base = _achievable(identity).merge(pd.DataFrame({"level": levels}), how="cross")
    reached = [
        success[success["value"] >= level]
        .groupby(["run", "module"], observed=True)["episodes"]
        .min()
        .rename(level)
        for level in levels
    ]
    first = pd.concat(reached, axis=1).rename_axis(columns="level").stack(future_stack=True)
    base = base.join(first.rename("episodes"), on=["run", "module", "level"])
    base["last_episodes"] = base["run"].map(tests.groupby("run", observed=True)["episode"].max())
    out = base.join(identity, on="run").sort_values(["run", "slot", "level"], kind="stable")
    out["run"] = out["run"].astype(tests["run"].dtype)
    out["episodes"] = out["episodes"].astype("Int64")
    out["last_episodes"] = out["last_episodes"].astype(np.int64)
    out = out[[*RUN_COLUMNS, "module", "level", "episodes", "last_episodes"]].reset_index(drop=True)
    out.attrs["window"] = window
    return out


def competence_crossings(df: pd.DataFrame, level: float = 0.5) -> pd.DataFrame:
    """The first episode at which each achievable module's competence reached ``level``.

    Only once the module has a full window of self-evaluations (``lp_window`` of them; one where
    the run does not record it): before, its competence averages the few results recorded so
    far, and one lucky evaluation reads 1.0. ``df`` is a `load_runs` table. Returns one row per
    (run, achievable module): the run columns, ``module``, ``episode`` (NA if never) and
    ``rank`` (1 for the first module to cross, ties sharing a rank; NA if never).
    """
    require_runs(df)
    (level,) = _check_levels([level])
    all_episodes = df["episode"].to_numpy()
    evaluated = df["eval"].to_numpy(bool)
    practised = df["module"].astype(str).to_numpy()
    has_window = df["lp_window"].notna().to_numpy()
    window = df["lp_window"].fillna(1).to_numpy(np.int64)
    rows = []
    for rows_of_run in df.groupby("run", observed=True, sort=True).indices.values():
        at = rows_of_run[np.argsort(all_episodes[rows_of_run], kind="stable")]
        first = at[0]
        for module in str(df["achievable_modules"].iat[first]).split(","):
            if not module:
                continue
            values = df[f"competence/{module}"].to_numpy(np.float64)[at]
            evaluations = np.cumsum(evaluated[at] & (practised[at] == module))
            full = evaluations >= (window[first] if has_window[first] else 1)
            hit = np.flatnonzero(full & (values >= level - FLOAT32_SLACK))
            rows.append(
                {
                    **{c: df[c].iat[first] for c in RUN_COLUMNS},
                    "module": module,
                    "episode": int(all_episodes[at[hit[0]]]) if hit.size else None,
                }
            )
    columns = [*RUN_COLUMNS, "module", "episode"]
    out = pd.DataFrame(rows, columns=columns)
    out["episode"] = out["episode"].astype("Int64")
    out["rank"] = out.groupby("run", observed=True)["episode"].rank(method="min").astype("Int64")
    out.attrs["level"] = level
    return out


def _follows(crossed: dict[str, float], order: Sequence[Sequence[str]]) -> bool | None:
    """Whether no module of a later group of ``order`` crossed before one of an earlier group
    (never = +inf); None when ``order`` names a module the run lacks or nothing crossed."""
    names = [m for group in order for m in group]
    if any(m not in crossed for m in names) or not np.isfinite(list(crossed.values())).any():
        return None
    for i, earlier in enumerate(order):
        for later in order[i + 1 :]:
            for a in earlier:
                for b in later:
                    if np.isfinite(crossed[b]) and crossed[b] < crossed[a]:
                        return False
    return True


def learning_order(
    crossings: pd.DataFrame, order: Sequence[Sequence[str]] = PAPER_ORDER
) -> pd.DataFrame:
    """One row per run of a `competence_crossings` table: ``order`` (the modules that crossed,
    first to last, ties joined by ``=``), ``not_reached`` (the others) and ``follows_paper``
    (see the module doc; NA where it cannot say)."""
    if missing := [c for c in (*RUN_COLUMNS, "module", "episode", "rank") if c not in crossings]:
        raise AnalysisError(
            f"this table lacks {', '.join(missing)}: learning_order takes a "
            "competence_crossings table (learning_order(competence_crossings(runs)))"
        )
    if crossings.empty:
        raise AnalysisError("no module crossings to order: no run with achievable modules")
    if isinstance(order, str) or any(isinstance(group, str) for group in order):
        raise AnalysisError(
            "order takes groups of module names, e.g. [['reach'], ['push_cube1']], not names"
        )
    names = [m for group in order for m in group]
    if not names or len(set(names)) < len(names):
        raise AnalysisError(
            f"order takes each module once, in groups, e.g. [['reach'], ['push_cube1']]; got "
            f"{order!r}"
        )
    # a module of a given order that no run has is a typo; the paper's order on runs without
    # one of its modules (a variant without stack) is NA, as documented
    known = set(crossings["module"].astype(str))
    unknown = sorted({m for group in order for m in group} - known)
    if unknown and order is not PAPER_ORDER:
        raise AnalysisError(
            f"order names modules no run has: {', '.join(unknown)} (have: "
            f"{', '.join(sorted(known))})"
        )
    rows = []
    for _run, group in crossings.groupby("run", observed=True, sort=True):
        done = group.dropna(subset=["episode"]).sort_values(["episode", "module"])
        steps = ["=".join(tied["module"]) for _, tied in done.groupby("episode", sort=True)]
        crossed = {
            str(r.module): float(r.episode) if pd.notna(r.episode) else np.inf
            for r in group.itertuples()
        }
        first = group.iloc[0]
        rows.append(
            {
                **{c: first[c] for c in RUN_COLUMNS},
                "order": " → ".join(steps),
                "not_reached": ", ".join(group.loc[group["episode"].isna(), "module"]),
                "follows_paper": _follows(crossed, order),
            }
        )
    out = pd.DataFrame(rows, columns=[*RUN_COLUMNS, "order", "not_reached", "follows_paper"])
    out["follows_paper"] = out["follows_paper"].astype("boolean")
    return out
