"""Numbers as the report, README.md and docs/results.md print them.

One rounding per kind of number, so that a number reads the same wherever it appears: the
report (`pipelines/report`) formats with these, and tests/test_docs_numbers.py checks the pages'
numbers against the data with them.
"""

from __future__ import annotations

import math

NONE = "–"
"""What stands for a number there is none of (untested, NaN)."""


def format_p(p: float | None) -> str:
    """A p-value to two significant digits: 0.17, 0.025, 0.0018, 9.7e-06; – where untested
    (None, NaN). With 2 to 5 seeds a side a third digit says nothing."""
    if p is None or not math.isfinite(float(p)):
        return NONE
    return f"{float(p):.2g}"


def format_value(value: float | None, digits: int = 2) -> str:
    """A statistic (t, Z, a mean, a spread) to `digits` decimals; – where there is none (None,
    NaN, inf)."""
    if value is None or not math.isfinite(float(value)):
        return NONE
    return f"{float(value):.{digits}f}"
