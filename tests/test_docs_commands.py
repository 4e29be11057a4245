"""The command lines the docs give work: every option a page writes after `curious COMMAND`
(and `curious bench BENCHMARK`) is one that command takes, so a renamed or removed option
cannot live on in README.md, docs/, data/ or notebooks/."""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import re
from pathlib import Path

import pytest
from doc_pages import PAGES, page_id

from curious.cli import build_parser


def _sub_commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


@functools.cache
def _options(parser: argparse.ArgumentParser) -> frozenset[str]:
    # A benchmark's parser adds its options when it first parses; the missing required
    # arguments then end the parse, which is all this needs.
    with contextlib.redirect_stderr(io.StringIO()), contextlib.suppress(SystemExit):
        parser.parse_known_args([])
    return frozenset(parser._option_string_actions)


COMMANDS = _sub_commands(build_parser())
# `curious COMMAND` then the words up to the end of the code span, table cell or line; a
# trailing backslash continues a shell line.
MENTION = re.compile(rf"curious ({'|'.join(COMMANDS)})\b((?:[ \t]+(?:\\\n[ \t]*)?[^\s`|]+)*)")


def _mentions(page: Path) -> list[tuple[int, str, list[str]]]:
    text = page.read_text()
    return [
        (text.count("\n", 0, m.start()) + 1, m.group(1), m.group(2).replace("\\\n", " ").split())
        for m in MENTION.finditer(text)
    ]


def test_the_pages_name_curious_commands():
    """The scan reads the pages it is meant to (a pattern that matched nothing would pass)."""
    assert sum(len(_mentions(page)) for page in PAGES) > 100


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_option_a_page_gives_a_command_is_one_it_takes(page: Path):
    unknown = []
    for line, command, words in _mentions(page):
        parser = COMMANDS[command]
        name = command
        if command == "bench" and words and not words[0].startswith("-"):
            benchmarks = _sub_commands(parser)
            if words[0] not in benchmarks:
                unknown.append(f"line {line}: curious bench {words[0]}: no such benchmark")
                continue
            parser, name = benchmarks[words[0]], f"bench {words[0]}"
        options = _options(parser)
        for word in words:
            option = word.split("=")[0].rstrip(",.;:)")
            if option.startswith("--") and option not in options:
                unknown.append(f"line {line}: curious {name} {option}")
    assert not unknown, f"{page.name} gives options the commands do not take: {unknown}"
