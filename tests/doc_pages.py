"""The repository's Markdown pages that the docs tests read (test_docs_commands.py,
test_docs_markdown.py): the READMEs, docs/ and the notebooks' pages."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted(
    [
        ROOT / "README.md",
        ROOT / "data" / "README.md",
        *(ROOT / "docs").glob("*.md"),
        *(ROOT / "notebooks").glob("*.md"),
    ]
)


def page_id(page: Path) -> str:
    """A page's test id: its path in the repository."""
    return str(page.relative_to(ROOT))
