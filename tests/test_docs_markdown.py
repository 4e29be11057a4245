"""The pages render as they read: a sentence wrapped just before a comparison (`CURIOUS\n> MG-TE`)
would begin a line with `>`, which Markdown draws as a quote. The pages quote nothing that way
(the paper's words stand in quotation marks), so no line outside a code block may begin so."""

from __future__ import annotations

from pathlib import Path

import pytest
from doc_pages import PAGES, page_id


def _quoted_lines(text: str) -> list[int]:
    """The numbers of the lines outside fenced code blocks that Markdown reads as a quote."""
    quoted, fenced = [], False
    for number, line in enumerate(text.splitlines(), start=1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
        elif not fenced and line.lstrip().startswith(">"):
            quoted.append(number)
    return quoted


def test_the_scan_finds_a_wrapped_comparison_and_skips_code():
    text = "Welch test, CURIOUS\n> MG-TE: p = 0.004\n```\n> a shell prompt\n```\n"
    assert _quoted_lines(text) == [2]


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_no_line_of_a_page_turns_into_a_quote(page: Path):
    assert _quoted_lines(page.read_text()) == [], f"{page.name}: rewrap these lines"
