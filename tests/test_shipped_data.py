"""What the repository ships in data/ (`curious ship`): every shipped folder loads, and the report
`curious reproduce --from-data` builds from it reads its numbers from its tables.

One case per shipped folder in data/. While data/ ships none (before the `laptop` campaign's
runs finish), the case is skipped with the reason, never passed unchecked; the same check runs
on a shipped smoke reproduction in test_shipped.py.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from shipped_check import check_shipped_folder

from curious.runs.shipped_folder import MANIFEST_FILE, ShippedFolder

DATA = Path(__file__).resolve().parents[1] / "data"
DOCS_IMAGES = Path(__file__).resolve().parents[1] / "docs" / "images"
SHIPPED = sorted(p.parent for p in DATA.glob(f"*/{MANIFEST_FILE}"))
LIMIT = 50_000_000
"""Bytes: the whole of data/ stays well under this (GitHub warns at 50 MB per file)."""

NONE_YET = (
    f"{DATA} ships no data folder yet: `curious ship <reproduction> --out data/<budget>` adds one"
)
CASES = [pytest.param(p, id=p.name) for p in SHIPPED] or [
    pytest.param(None, id="none", marks=pytest.mark.skip(reason=NONE_YET))
]


@pytest.mark.parametrize("data", CASES)
def test_a_shipped_folder_loads_and_the_report_reads_its_numbers_from_it(data, tmp_path):
    report = check_shipped_folder(data, tmp_path / "out")
    budget = ShippedFolder(data).read_manifest().budget
    assert report.startswith(f"# CURIOUS reproduction — budget `{budget}`")
    # the docs show the report's own figures (docs/images/<budget>-<figure>.png)
    for png in sorted(DOCS_IMAGES.glob(f"{budget}-*.png")):
        figure = tmp_path / "out" / "figures" / png.name.removeprefix(f"{budget}-")
        assert figure.is_file(), f"{png.name} is not a figure of the report"
        assert png.read_bytes() == figure.read_bytes(), (
            f"{png.name} is not the report's figure: `curious reproduce --from-data {data} "
            f"--out /tmp/r` and copy /tmp/r/figures/{figure.name} to docs/images/{png.name}"
        )


def test_data_holds_only_shipped_folders_well_under_the_size_limit():
    if not DATA.exists():
        pytest.skip(NONE_YET)
    strangers = sorted(p.name for p in DATA.iterdir() if p not in SHIPPED and p.name != "README.md")
    assert not strangers, f"data/ holds what `curious ship` did not write: {strangers}"
    size = sum(p.stat().st_size for p in DATA.rglob("*") if p.is_file())
    assert size < LIMIT, f"data/ holds {size:,} bytes"
