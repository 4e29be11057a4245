"""The docs' tables of variants and conditions are the registries' built-in entries: a variant
or condition added to curious is documented, and one documented exists (a plugin's entries are
documented by the plugin, so they are not asked for)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from curious.agent.conditions import BUILT_IN_CONDITIONS
from suite.catalog import BUILT_IN

ROOT = Path(__file__).resolve().parents[1]


def first_column(page: Path, header: str) -> list[str]:
    """The names in the first column of the table whose header row starts with `header`."""
    lines = page.read_text(encoding="utf-8").splitlines()
    start = next((i for i, line in enumerate(lines) if line.startswith(f"| {header} |")), None)
    assert start is not None, f"{page.name} has no table headed `{header}`"
    names = []
    for line in lines[start + 2 :]:
        if not line.startswith("|"):
            break
        cell = line.split("|")[1].strip()
        match = re.fullmatch(r"`([^`]+)`", cell)
        assert match, f"{page.name}: a row of the {header} table names no `{header}`: {line}"
        names.append(match.group(1))
    return names


@pytest.mark.parametrize(
    ("page", "header", "registry"),
    [
        ("docs/suite.md", "variant", tuple(BUILT_IN)),
        ("README.md", "condition", BUILT_IN_CONDITIONS),
    ],
)
def test_a_docs_table_lists_the_registry_built_in_entries_in_order(page, header, registry):
    assert tuple(first_column(ROOT / page, header)) == registry
