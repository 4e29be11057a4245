"""What the figures share: condition order, run selection, captions, axes, curves and saving."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from curious.analysis.loading import (
    AnalysisError,
    is_integer,
    name_list,
    require_identity,
    require_runs,
    run_modules,
)
from curious.analysis.statistics import (
    nice_bin_size,
)
from curious.analysis.style import (
    episodes_axis,
    save_figure,
    seeds_text,
    wrap_caption,
)
from curious.watching import palette

CONDITION_ORDER: tuple[str, ...] = ("curious", "mg-te", "her", "m-uvfa", "lp-select", "lp-replay")
CURVE_POINTS = 400  # at most this many points per drawn curve of one run
CAPTION_SIZE = 7.5


# ----------------------------------------------------------------------------- selection helpers


def ordered_conditions(df: pd.DataFrame, conditions: Sequence[str] | None) -> list[str]:
    """``conditions`` (all the table's, in the paper's order, where None) checked against the
    table's runs."""
    present = [str(c) for c in df["condition"].unique()]
    conditions = name_list(conditions, "conditions")
    if conditions is None:
        known = [c for c in CONDITION_ORDER if c in present]
        return known + sorted(c for c in present if c not in CONDITION_ORDER)
    missing = [c for c in conditions if c not in present]
    if missing:
        raise AnalysisError(
            f"no runs of condition(s) {', '.join(missing)} (have: {', '.join(sorted(present))})"
        )
    return list(conditions)


def restrict(df: pd.DataFrame, conditions: Sequence[str], variant: str | None) -> pd.DataFrame:
    require_identity(df)
    if variant is not None:
        variants = set(df["variant"].astype(str))
        if variant not in variants:
            raise AnalysisError(
                f"no runs of variant '{variant}' (have: {', '.join(sorted(variants))})"
            )
        df = df[df["variant"] == variant]
    return df[df["condition"].isin(list(conditions))]


def one_run(
    df: pd.DataFrame, condition: str, seed: int | None, variant: str | None
) -> pd.DataFrame:
    """The rows of one run of a `load_runs` table, chosen by condition, seed (lowest if None)
    and variant."""
    require_runs(df)
    if seed is not None and not is_integer(seed):
        raise AnalysisError(f"seed must be an int, got {seed!r}")
    rows = restrict(df, ordered_conditions(df, [condition]), variant)
    seeds = sorted(int(s) for s in rows["seed"].unique())
    if seed is None:
        seed = seeds[0]
    elif seed not in seeds:
        raise AnalysisError(
            f"condition '{condition}' has no seed {seed} (seeds: {', '.join(map(str, seeds))})"
        )
    rows = rows[rows["seed"] == seed]
    runs = rows["run"].astype(str).unique()
    if len(runs) > 1:
        variants = ", ".join(sorted(rows["variant"].astype(str).unique()))
        raise AnalysisError(
            f"condition '{condition}' seed {seed} has {len(runs)} runs (variants {variants}): "
            "pass variant= to choose one"
        )
    require_self_evaluated(rows, condition)
    return rows.sort_values("episode")


def require_self_evaluated(rows: pd.DataFrame, condition: str) -> None:
    """An `AnalysisError` where the runs of ``rows`` have no competence at all: a condition
    that never self-evaluates (HER), whose per-module figures would be empty."""
    columns = [c for c in rows.columns if str(c).startswith("competence/")]
    if not rows[columns].notna().to_numpy().any():
        raise AnalysisError(
            f"condition '{condition}' has no self-evaluated competence in these runs (HER "
            "scores its holistic goal only): draw a condition that self-evaluates"
        )


def runs_of(df: pd.DataFrame) -> pd.DataFrame:
    grouped = df.groupby("run", observed=True)
    out = grouped[["condition", "seed", "variant", "preset"]].first()
    out["n_episodes"] = grouped["episode"].max() + 1
    return out


def setting_text(runs: pd.DataFrame) -> str:
    presets = ", ".join(sorted(runs["preset"].astype(str).unique()))
    variants = ", ".join(sorted(runs["variant"].astype(str).unique()))
    return f"preset {presets}, variant {variants}"


def conditions_text(runs: pd.DataFrame, conditions: Sequence[str]) -> str:
    parts = []
    for c in conditions:
        seeds = runs.loc[runs["condition"] == c, "seed"]
        parts.append(f"{palette.condition_label(c)}: {seeds_text(seeds)}")
    return "; ".join(parts)


def episodes_text(n: int) -> str:
    """``"episode"`` for 1, else ``"1,000 episodes"``."""
    return "episode" if n == 1 else f"{n:,} episodes"


def line_width(i: int, n: int) -> float:
    """Width of the i-th of n condition curves: the first widest, so that curves which coincide
    (as conditions can, early in small runs) show as a wide line with a thinner one inside."""
    return 1.6 + 1.6 * (n - 1 - i) / max(n - 1, 1)


def caption(fig: Figure, text: str, note: str | None = None) -> None:
    """The caption under the axes; ``note`` (e.g. "Small budget: ...") ends it."""
    if note:
        text = f"{text} {note.strip()}"
    width = fig.get_figwidth()
    fig.supxlabel(wrap_caption(text, width), fontsize=CAPTION_SIZE, ha="left", x=0.01)


def legend_right(ax: Axes, handles: list | None = None, labels: list | None = None) -> None:
    """A legend beside ``ax``, top-aligned with it (constrained layout makes room for it)."""
    args = () if handles is None else (handles, labels)
    ax.legend(*args, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)


def finish(fig: Figure, out_dir: str | PathLike[str] | None, name: str) -> Figure:
    if out_dir is not None:
        save_figure(fig, out_dir, name)
    return fig


def curve_bin(n_episodes: int) -> int:
    return nice_bin_size(n_episodes, CURVE_POINTS) if n_episodes > CURVE_POINTS else 1


def module_series(run: pd.DataFrame, prefix: str, bin_size: int) -> tuple[np.ndarray, dict]:
    """End-of-bin values of ``<prefix><module>`` for one run: (episodes, {module: values})."""
    modules, _ = run_modules(run, str(run["run"].iat[0]))
    episodes = run["episode"].to_numpy()
    ends = (np.arange((int(episodes[-1]) + 1) // bin_size) + 1) * bin_size
    at = np.searchsorted(episodes, ends - 1, side="right") - 1
    keep = at >= 0
    return ends[keep], {m: run[prefix + m].to_numpy()[at[keep]] for m in modules}


def draw_modules(ax: Axes, run: pd.DataFrame, prefix: str, bin_size: int) -> None:
    _, achievable = run_modules(run, str(run["run"].iat[0]))
    x, series = module_series(run, prefix, bin_size)
    for module, values in series.items():
        ax.plot(
            x,
            values,
            color=palette.module_color(module),
            linestyle="-" if module in achievable else "--",
            linewidth=1.5 if module in achievable else 1.1,
            label=palette.module_label(module) + ("" if module in achievable else " (distractor)"),
        )
    episodes_axis(ax)


def competence_axis(ax: Axes, label: str = "competence (success rate)") -> None:
    ax.set_ylim(-0.03, 1.03)
    ax.set_ylabel(label)


def lp_axis(ax: Axes, top: float) -> None:
    ax.set_ylim(0.0, max(0.05, top * 1.08))
    ax.set_ylabel("absolute LP (Δ success rate)")


def drawn_ceiling(run: pd.DataFrame, prefix: str, bin_size: int) -> float:
    """The highest value `draw_modules` draws of one run's ``<prefix><module>`` columns (its
    samples at the ends of ``bin_size``-episode bins), so that an axis fits the curves drawn
    rather than a spike between two samples."""
    _, series = module_series(run, prefix, bin_size)
    values = [v for v in series.values() if len(v)]
    if not values:
        return 0.0
    top = np.nanmax(np.concatenate(values).astype(np.float64))
    return float(top) if np.isfinite(top) else 0.0


def lp_ceiling(df: pd.DataFrame) -> float:
    columns = [c for c in df.columns if c.startswith("lp/")]
    top = np.nanmax(df[columns].to_numpy(dtype=np.float64)) if columns else 0.0
    return float(top) if np.isfinite(top) else 0.0


# ----------------------------------------------------------------------------- Fig. 2a


def test_runs_of(tests: pd.DataFrame) -> pd.DataFrame:
    """One row per run of a tests table; ``n_episodes``: training episodes at its last test."""
    grouped = tests.groupby("run", observed=True)
    out = grouped[["condition", "seed", "variant", "preset"]].first()
    out["n_episodes"] = grouped["episode"].max()
    return out


def draw_mean_std(
    ax: Axes,
    s: pd.DataFrame,
    color: str,
    width: float,
    label: str | None,
    alpha: float = 0.2,
    linestyle: str = "-",
) -> None:
    """One condition's mean curve and, with several seeds, its ± std band (opacity ``alpha``)."""
    ax.plot(s["episodes"], s["mean"], color=color, linewidth=width, label=label, ls=linestyle)
    if (s["n"] > 1).any():
        ax.fill_between(
            s["episodes"],
            s["mean"] - s["std"],
            s["mean"] + s["std"],
            color=color,
            alpha=alpha,
            linewidth=0,
        )
