"""Beyond the paper: which of LP's two uses does the work, and whether its sign matters.

The rules are docs/results.md's, "Beyond the paper", fixed before any of their runs trained:

* `compare_lp_uses`: on one per-run measure (C4's final competence, or its final test success),
  four one-tailed Welch tests, each single-use condition against M-UVFA (the use alone helps)
  and CURIOUS against each (the other use adds), Holm-corrected over the four, on the seeds all
  four conditions have; `lp_use_readings` turns them into the reading fixed in advance.
* `compare_refocus`: whether absolute LP raises a failed module's p_LP more than signed LP
  (one-tailed Welch on each run's rise, after minus before the onset, from `recovery` tables),
  on the seeds both measures have (`signed_beside_absolute`); `signed_lp_reading` turns it into
  the reading fixed in advance.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from curious.analysis.loading import AnalysisError, require_alpha
from curious.analysis.statistics import ALPHA, holm, welch_greater

__all__ = [
    "LP_USES",
    "SIGNED_LP",
    "compare_lp_uses",
    "compare_refocus",
    "lp_use_readings",
    "lp_uses_tables",
    "signed_beside_absolute",
    "signed_lp_reading",
    "with_paper_pair",
]

LP_USES: dict[str, str] = {"lp-select": "module selection", "lp-replay": "task replay"}
"""The conditions that keep one of LP's two uses, and the use each keeps."""

_BOTH, _NEITHER = "curious", "m-uvfa"

SIGNED_LP = "curious-signed"
"""The condition name CURIOUS's runs with `lp_measure=signed` are read under beside the
absolute ones (`signed_beside_absolute`)."""


def with_paper_pair(own: pd.DataFrame, theirs: pd.DataFrame | None, variant: str) -> pd.DataFrame:
    """``own`` (the `lp_uses` runs' table) with the CURIOUS and M-UVFA rows of ``variant`` in
    ``theirs`` (a `distractors` table of the same kind; None: ``own`` alone)."""
    if theirs is None:
        return own
    keep = theirs["variant"].astype(str).eq(variant) & theirs["condition"].astype(str).isin(
        (_BOTH, _NEITHER)
    )
    return pd.concat([own, theirs[keep]], ignore_index=True)


def lp_uses_tables(
    metrics: pd.DataFrame,
    tests: pd.DataFrame | None,
    their_metrics: pd.DataFrame | None,
    their_tests: pd.DataFrame | None,
    variant: str,
) -> tuple[pd.DataFrame, pd.DataFrame | None]:
    """The `lp_uses` runs' (metrics, tests) with the `distractors` runs' CURIOUS and M-UVFA rows
    of ``variant`` beside them (`with_paper_pair`; their tables None: the own runs alone). The
    tests compare all four conditions or none: None where either side has no test rollouts."""
    both = with_paper_pair(metrics, their_metrics, variant)
    if tests is None or (their_metrics is not None and their_tests is None):
        return both, None
    return both, with_paper_pair(tests, their_tests, variant)


def signed_beside_absolute(signed: pd.DataFrame, absolute: pd.DataFrame | None) -> pd.DataFrame:
    """The CURIOUS rows of ``absolute`` (a `sensor_failure_mastered` table; None: none) and
    those of ``signed`` (a `signed_lp` table of the same kind) named `SIGNED_LP`, one table, on
    the seeds both have (docs/results.md's rule: a seed of one measure alone is not read)."""
    mine = _curious_only(signed, "signed").assign(condition=SIGNED_LP)
    if absolute is None:
        return mine.reset_index(drop=True)
    theirs = _curious_only(absolute, "absolute")
    shared = set(mine["seed"].astype(int)) & set(theirs["seed"].astype(int))
    if not shared:
        raise AnalysisError(
            f"the signed LP runs (seeds {sorted(set(mine['seed'].astype(int)))}) and the "
            f"absolute ones (seeds {sorted(set(theirs['seed'].astype(int)))}) share no seed"
        )
    both = pd.concat([theirs, mine], ignore_index=True)
    return both[both["seed"].astype(int).isin(shared)].reset_index(drop=True)


def _curious_only(table: pd.DataFrame, measure: str) -> pd.DataFrame:
    """``table``'s CURIOUS rows, with a clear error where it has none."""
    mine = table[table["condition"].astype(str) == _BOTH]
    if mine.empty:
        raise AnalysisError(f"the {measure} LP table has no CURIOUS runs")
    return mine


def _pairs() -> list[tuple[str, str]]:
    """(better, worse) of the four tests, in the order docs/results.md gives them."""
    singles = list(LP_USES)
    return [(s, _NEITHER) for s in singles] + [(_BOTH, s) for s in singles]


def compare_lp_uses(per_run: pd.DataFrame, alpha: float = ALPHA) -> pd.DataFrame:
    """The four one-tailed Welch tests of LP's uses on ``per_run`` (one row per run:
    ``condition``, ``seed``, ``value``; e.g. `final_competence`), on the seeds all four
    conditions have.

    Returns one row per test: ``better``, ``worse``, ``n``, ``seeds``, ``mean_better``,
    ``mean_worse``, ``t``, ``p`` (uncorrected), ``p_holm`` (over the four) and ``significant``
    (``p_holm < alpha``).
    """
    require_alpha(alpha)
    if missing := [c for c in ("condition", "seed", "value") if c not in per_run]:
        raise AnalysisError(f"this table lacks {', '.join(missing)}: one row per run is needed")
    conditions = per_run["condition"].astype(str)
    wanted = [_BOTH, _NEITHER, *LP_USES]
    if absent := [c for c in wanted if not (conditions == c).any()]:
        present = sorted(set(conditions))
        raise AnalysisError(
            f"no runs of {', '.join(absent)} (have: {', '.join(present) or 'none'}); the "
            "comparison needs curious, m-uvfa, lp-select and lp-replay"
        )
    seeds_of = {c: set(per_run.loc[conditions == c, "seed"].astype(int)) for c in wanted}
    if any(len(per_run[(conditions == c)]) != len(seeds_of[c]) for c in wanted):
        raise AnalysisError("a condition has two runs of one seed: pass one experiment's runs")
    shared = sorted(set.intersection(*seeds_of.values()))
    if len(shared) < 2:
        raise AnalysisError(f"the four conditions share {len(shared)} seed(s); a test needs 2")
    kept = per_run[per_run["seed"].astype(int).isin(shared)]
    value = {
        c: kept.loc[kept["condition"].astype(str) == c, "value"].to_numpy(float) for c in wanted
    }
    rows = []
    for better, worse in _pairs():
        t, p = welch_greater(value[better], value[worse])
        rows.append(
            {
                "better": better,
                "worse": worse,
                "n": len(shared),
                "seeds": tuple(shared),
                "mean_better": float(np.mean(value[better])),
                "mean_worse": float(np.mean(value[worse])),
                "t": t,
                "p": p,
            }
        )
    out = pd.DataFrame(rows)
    out["p_holm"] = holm(out["p"].to_numpy())
    out["significant"] = out["p_holm"] < alpha
    out.attrs["alpha"] = alpha
    return out


def lp_use_readings(tests: pd.DataFrame) -> dict[str, str]:
    """The reading docs/results.md fixed for each use, from a `compare_lp_uses` table: "does the
    work", "both are needed", "adds nothing measurable" or "undecided"."""
    beats = {(r.better, r.worse): bool(r.significant) for r in tests.itertuples()}
    if set(beats) != set(_pairs()):
        raise AnalysisError("pass the table compare_lp_uses returns (its four tests)")
    alone = {s: beats[(s, _NEITHER)] for s in LP_USES}
    added_to = {s: beats[(_BOTH, s)] for s in LP_USES}
    both = all(alone.values()) and all(added_to.values())
    readings = {}
    for single, use in LP_USES.items():
        if both:
            verdict = "both are needed"
        elif alone[single] and not added_to[single]:
            verdict = "does the work"
        elif not alone[single]:
            verdict = "adds nothing measurable"
        else:
            verdict = "undecided"
        readings[use] = verdict
    return readings


def compare_refocus(
    absolute: pd.DataFrame, signed: pd.DataFrame, alpha: float = ALPHA
) -> dict[str, object]:
    """One-tailed Welch test that absolute LP raises the failed module's p_LP more than signed LP.

    ``absolute`` and ``signed`` are `recovery` tables (``status``, ``p_lp_before``,
    ``p_lp_after``, ``practice_before``, ``practice_after``) of the two measures' runs; runs
    whose failure never started have no rise and are counted apart (``left_out``). Returns a
    dict: ``rise_absolute`` and ``rise_signed`` (each run's p_LP after minus before),
    ``practice_absolute`` and ``practice_signed`` (the practice share's rise, reported without a
    test), ``t``, ``p``, ``alpha``, ``significant`` and ``left_out``.
    """
    require_alpha(alpha)
    needed = ("status", "p_lp_before", "p_lp_after", "practice_before", "practice_after")
    rises: dict[str, np.ndarray] = {}
    practice: dict[str, np.ndarray] = {}
    left_out = 0
    for name, table in (("absolute", absolute), ("signed", signed)):
        if missing := [c for c in needed if c not in table]:
            raise AnalysisError(
                f"the {name} table lacks {', '.join(missing)}: pass a recovery table"
            )
        started = table[table["status"] != "never_started"]
        left_out += len(table) - len(started)
        rises[name] = (started["p_lp_after"] - started["p_lp_before"]).to_numpy(float)
        practice[name] = (started["practice_after"] - started["practice_before"]).to_numpy(float)
    t, p = welch_greater(rises["absolute"], rises["signed"])
    return {
        "rise_absolute": rises["absolute"],
        "rise_signed": rises["signed"],
        "practice_absolute": practice["absolute"],
        "practice_signed": practice["signed"],
        "t": t,
        "p": p,
        "alpha": alpha,
        "significant": bool(p < alpha) if np.isfinite(p) else False,
        "left_out": left_out,
    }


def signed_lp_reading(refocus: dict[str, object]) -> str:
    """The reading docs/results.md fixed for LP's sign, from a `compare_refocus` result: "the
    absolute value matters" (the refocus test significant), "the refocus comes from relearning
    progress" (not significant, and signed LP's mean rise of p_LP at least absolute LP's), else
    "undecided" (not significant with signed LP's rise the smaller, or no test)."""
    if refocus.get("significant"):
        return "the absolute value matters"
    rises = [np.asarray(refocus[k], np.float64) for k in ("rise_absolute", "rise_signed")]
    if not np.isfinite(float(refocus["p"])) or not all(r.size for r in rises):
        return "undecided"
    if rises[1].mean() >= rises[0].mean():
        return "the refocus comes from relearning progress"
    return "undecided"
