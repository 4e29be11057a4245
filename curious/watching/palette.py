"""Fixed names and colours for task modules and conditions.

Figures and Rerun recordings draw every module and every condition in the same colour under the
same name, so that a reader can compare a figure with a recording, or two recordings side by side,
at a glance. This module is plain Python (no matplotlib, no rerun) so that the recording code can
import it cheaply.

Colours are given as ``#rrggbb`` strings (what matplotlib takes) and as ``(r, g, b)`` tuples of
0-255 ints (what Rerun takes). The achievable modules use the Okabe-Ito colour-blind-safe hues;
the distractor modules use muted hues (figures also draw the modules a run's config marks as not
achievable with dashed lines).

Modules the table below does not know (a new module, or a distractor of a larger variant, say
``push_cube9``) still get a stable colour and label: ``push_cube<N>`` is labelled "push cube N"
and any other name gets a colour picked from its CRC-32, so it is the same in every process.
"""

from __future__ import annotations

import re
import zlib
from dataclasses import dataclass

__all__ = [
    "CONDITION_STYLES",
    "MODULE_STYLES",
    "Style",
    "condition_color",
    "condition_label",
    "condition_rgb",
    "module_color",
    "module_label",
    "module_name",
    "module_rgb",
    "module_sort_key",
]


@dataclass(frozen=True)
class Style:
    """How one module or condition is shown: a short label and a ``#rrggbb`` colour."""

    label: str
    color: str

    @property
    def rgb(self) -> tuple[int, int, int]:
        """The colour as 0-255 ints, the form Rerun's `rr.Color`/`colors=` take."""
        return _hex_to_rgb(self.color)


# The paper's modules T1..T7, in slot order. T5-T7 are the distractors of the default variant.
MODULE_STYLES: dict[str, Style] = {
    "reach": Style("T1 reach", "#0072B2"),
    "push_cube1": Style("T2 push cube 1", "#E69F00"),
    "cube1_above_cube2": Style("T3 cube 1 above cube 2", "#009E73"),
    "stack": Style("T4 stack cube 1 on 2", "#D55E00"),
    "push_cube3": Style("T5 push cube 3", "#8C8C8C"),
    "push_cube4": Style("T6 push cube 4", "#B5A27A"),
    "push_cube5": Style("T7 push cube 5", "#8FA8C8"),
}

# Muted hues for modules the table does not name (further distractors and new modules).
_EXTRA_COLORS: tuple[str, ...] = (
    "#A88BB5",
    "#7FB3A8",
    "#C9A3A3",
    "#A3A3C9",
    "#B3B37F",
    "#9C9C9C",
    "#C2A285",
    "#85A2C2",
)

CONDITION_STYLES: dict[str, Style] = {
    "curious": Style("CURIOUS", "#CC3311"),
    "mg-te": Style("MG-TE", "#0077BB"),
    "her": Style("HER", "#555555"),
    "m-uvfa": Style("M-UVFA", "#AA3377"),
    "lp-select": Style("LP-select", "#EE7733"),
    "lp-replay": Style("LP-replay", "#009988"),
    # not a condition: CURIOUS with `lp_measure=signed`, as the `signed_lp` figure names it
    "curious-signed": Style("CURIOUS, signed LP", "#33BBEE"),
}

_PUSH_CUBE = re.compile(r"push_cube(\d+)")


def _hex_to_rgb(color: str) -> tuple[int, int, int]:
    value = color.lstrip("#")
    return (int(value[0:2], 16), int(value[2:4], 16), int(value[4:6], 16))


def _fallback_color(name: str) -> str:
    match = _PUSH_CUBE.fullmatch(name)
    index = int(match.group(1)) if match else zlib.crc32(name.encode("utf-8"))
    return _EXTRA_COLORS[index % len(_EXTRA_COLORS)]


def _module_style(name: str) -> Style:
    style = MODULE_STYLES.get(name)
    if style is not None:
        return style
    match = _PUSH_CUBE.fullmatch(name)
    label = f"push cube {match.group(1)}" if match else name.replace("_", " ")
    return Style(label, _fallback_color(name))


def module_label(name: str) -> str:
    """The label a module is shown under, e.g. ``"T2 push cube 1"`` for ``push_cube1``."""
    return _module_style(name).label


def module_entity(name: str) -> str:
    """The module's entity path part in a Rerun recording, e.g. ``"T2-push_cube1"``: the
    viewer lists a plot's series in entity-path order, so the paper's task number leads and the
    legend reads T1..T7 (then other modules by name)."""
    match = re.match(r"T(\d+) ", module_label(name))
    return f"T{match.group(1)}-{name}" if match else name


def module_name(name: str) -> str:
    """The label without the paper's task number, e.g. ``"push cube 3"``: for variants whose
    slots are not the paper's T1-T7 (in `sensor_failure`, push_cube3 is an achievable module)."""
    return re.sub(r"^T\d+ ", "", module_label(name))


def module_color(name: str) -> str:
    """The module's ``#rrggbb`` colour (fixed for known modules, stable for others)."""
    return _module_style(name).color


def module_rgb(name: str) -> tuple[int, int, int]:
    """The module's colour as a 0-255 ``(r, g, b)`` tuple, for Rerun."""
    return _module_style(name).rgb


def module_sort_key(name: str) -> tuple[int, int, str]:
    """Orders modules as the paper does: T1..T7 first, then ``push_cube<N>`` by N, then names."""
    known = list(MODULE_STYLES)
    if name in known:
        return (0, known.index(name), name)
    match = _PUSH_CUBE.fullmatch(name)
    if match:
        return (1, int(match.group(1)), name)
    return (2, 0, name)


def _condition_style(name: str) -> Style:
    style = CONDITION_STYLES.get(name)
    if style is not None:
        return style
    return Style(name, _fallback_color(name))


def condition_label(name: str) -> str:
    """The label a condition is shown under, e.g. ``"MG-TE"`` for ``mg-te``."""
    return _condition_style(name).label


def condition_color(name: str) -> str:
    """The condition's ``#rrggbb`` colour (fixed for the paper's conditions, stable for others)."""
    return _condition_style(name).color


def condition_rgb(name: str) -> tuple[int, int, int]:
    """The condition's colour as a 0-255 ``(r, g, b)`` tuple, for Rerun."""
    return _condition_style(name).rgb
