"""The code the pages name is there: every `curious.…` or `pipelines.…` name a page writes in a
code span imports and resolves, and every repository path it writes (`curious/…`, `tools/…`,
`tests/…`) exists, so that a renamed or removed function, module or file cannot live on in
README.md, docs/, data/ or notebooks/ after a refactor."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest
from doc_pages import PAGES, ROOT, page_id

SPAN = re.compile(r"`([^`\s]+)`")
DOTTED = re.compile(r"((?:curious|pipelines)(?:\.\w+)+)(?:\(.*)?")
"""A dotted name in the project's packages, maybe called: `curious.analysis.recovery(runs)`."""
FOLDERS = ("curious", "pipelines", "suite", "tools", "tests", "benchmarks", "notebooks", "docs")
PATH = re.compile(rf"((?:{'|'.join(FOLDERS)})/[\w./-]*\w)(?::\S*)?")
"""A repository path, maybe with a line or a function after a colon: `tools/campaign.py:main`."""
NOT_CODE = re.compile(r"\bkey $")
"""A span that names a metadata key, not code: "(key `curious.shipped`)"."""


def _spans(page: Path) -> list[tuple[int, str]]:
    text = page.read_text()
    return [
        (text.count("\n", 0, m.start()) + 1, m.group(1).rstrip(".,;:"))
        for m in SPAN.finditer(text)
        if not NOT_CODE.search(text[max(0, m.start() - 8) : m.start()])
    ]


def resolves(name: str) -> bool:
    """Whether `name` is a module of the project or an attribute reached from one."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            found: object = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attribute in parts[i:]:
            if not hasattr(found, attribute):
                return False
            found = getattr(found, attribute)
        return True
    return False


def test_the_scan_reads_names_and_paths():
    """The patterns match what the pages write (a pattern that matched nothing would pass)."""
    spans = [s for page in PAGES for _, s in _spans(page)]
    assert sum(bool(DOTTED.fullmatch(s)) for s in spans) > 50
    assert sum(bool(PATH.fullmatch(s)) for s in spans) > 50
    assert resolves("curious.analysis.lowest_competence") and resolves("pipelines.report")
    assert not resolves("curious.analysis.no_such_function") and not resolves("curious.nothing")


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_name_and_path_a_page_gives_is_in_the_code(page: Path, monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "disable")
    missing = []
    for line, span in _spans(page):
        if m := DOTTED.fullmatch(span):
            if not resolves(m.group(1)):
                missing.append(f"line {line}: `{span}` does not resolve")
        elif (m := PATH.fullmatch(span)) and "*" not in span:
            if not (ROOT / m.group(1)).exists():
                missing.append(f"line {line}: `{span}` is not in the repository")
    assert not missing, "\n".join(missing)
