"""The look of every figure, and writing figures to PNG and SVG byte-identically.

Figures are `matplotlib.figure.Figure` objects made without pyplot, so building them changes no
global state (no backend switch, no open-figure registry) and works the same in a notebook, a test
or a pipeline worker. Saving renders PNG with the Agg canvas and SVG with matplotlib's SVG writer
under fixed settings: a fixed ``svg.hashsalt`` (element ids), no dates or software versions in the
metadata, text drawn as paths in the DejaVu Sans font that ships with matplotlib. The same data
therefore gives the same bytes every time.
"""

from __future__ import annotations

import os
import textwrap
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from os import PathLike
from pathlib import Path

import matplotlib as mpl
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, MaxNLocator

__all__ = [
    "RC",
    "budget_text",
    "episodes_axis",
    "format_episodes",
    "new_figure",
    "save_figure",
    "seeds_text",
    "wrap_caption",
]

RC: dict[str, object] = {
    "svg.hashsalt": "curious-figures",
    "svg.fonttype": "path",
    "font.family": "DejaVu Sans",
    "font.size": 9.0,
    "axes.titlesize": 10.0,
    "axes.labelsize": 9.0,
    "legend.fontsize": 8.0,
    "xtick.labelsize": 8.0,
    "ytick.labelsize": 8.0,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "grid.linewidth": 0.6,
    "lines.linewidth": 1.6,
    "legend.frameon": False,
    "savefig.dpi": 150,
    "figure.dpi": 100,
    "path.simplify": True,
}

_PNG_METADATA = {"Software": None}
_SVG_METADATA = {"Date": None, "Creator": None}


@contextmanager
def figure_style() -> Iterator[None]:
    """The rc settings of every figure, scoped to a ``with`` block (nothing global changes)."""
    with mpl.rc_context(RC):
        yield


def new_figure(width: float, height: float) -> Figure:
    """A figure with constrained layout, made inside `figure_style`."""
    return Figure(figsize=(width, height), layout="constrained")


def format_episodes(value: float, _position: object = None) -> str:
    """Tick text for an episode count: ``950``, ``1.5k``, ``150k``, ``1.2M``."""
    magnitude = abs(value)
    if magnitude >= 1_000_000:
        return f"{value / 1_000_000:g}M"
    if magnitude >= 1_000:
        return f"{value / 1_000:g}k"
    return f"{value:g}"


def episodes_axis(ax: Axes, label: bool = True) -> None:
    """Labels ``ax``'s x axis "episodes" with compact integer tick labels (``50k``)."""
    ax.xaxis.set_major_locator(MaxNLocator(nbins=6, integer=True, min_n_ticks=3))
    ax.xaxis.set_major_formatter(FuncFormatter(format_episodes))
    if label:
        ax.set_xlabel("episodes")


def _ranges(values: list[int]) -> list[str]:
    """``[0, 1, 2, 5, 7, 8]`` -> ``["0–2", "5", "7–8"]`` (values sorted, unique)."""
    parts: list[str] = []
    start = 0
    for i in range(1, len(values) + 1):
        if i == len(values) or values[i] != values[i - 1] + 1:
            first, last = values[start], values[i - 1]
            parts.append(str(first) if first == last else f"{first}–{last}")
            start = i
    return parts


def seeds_text(seeds: Iterable[int]) -> str:
    """``"5 seeds (0–4)"``, ``"1 seed (3)"``, ``"3 seeds (0, 2, 7)"``."""
    unique = sorted({int(s) for s in seeds})
    if not unique:
        return "no seeds"
    noun = "seed" if len(unique) == 1 else "seeds"
    return f"{len(unique)} {noun} ({', '.join(_ranges(unique))})"


def budget_text(episodes_per_run: Iterable[int]) -> str:
    """``"1,000 episodes per run"`` or ``"900–1,000 episodes per run"`` when runs differ."""
    values = sorted({int(e) for e in episodes_per_run})
    if not values:
        return "no episodes"
    if len(values) == 1:
        return f"{values[0]:,} episodes per run"
    return f"{values[0]:,}–{values[-1]:,} episodes per run"


def wrap_caption(text: str, width_inches: float) -> str:
    """Wraps caption text (8 pt) to the figure's width."""
    return textwrap.fill(text, width=max(40, int(width_inches * 16.5)), break_on_hyphens=False)


def save_figure(fig: Figure, out_dir: str | PathLike[str], name: str) -> dict[str, Path]:
    """Writes ``<out_dir>/<name>.png`` and ``.svg``; returns ``{"png": path, "svg": path}``.

    Each file is written to a temporary name first and then renamed, so that a reader never sees
    half a figure. The bytes depend only on the figure's content.
    """
    if Path(name).suffix.lower() in (".png", ".svg"):  # `name="fig.png"` wrote fig.png.png
        name = Path(name).stem
    folder = Path(out_dir)
    folder.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    with figure_style():
        for ext, metadata in (("png", _PNG_METADATA), ("svg", _SVG_METADATA)):
            path = folder / f"{name}.{ext}"
            partial = folder / f".{name}.{ext}.partial"
            fig.savefig(partial, format=ext, metadata=metadata)
            os.replace(partial, path)
            paths[ext] = path
    return paths
