"""The command lines the repository's pages give (tests/test_docs_commands.py): every line of
their shell code blocks and every command in a table's `command` column, as a program and its
words, with what it needs installed.

`PROGRAMS` says, for every program a page runs, which extra of pyproject.toml installs it; a
page that gives a command of a program not in it fails the tests until it is added, so a new
documented command is always checked.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass
from pathlib import Path

SHELL_BLOCKS = {"bash", "sh", "shell", "console"}
PLAIN = ""
"""The plain install, `pip install -e .`."""
PROGRAMS: dict[str, str | None] = {
    "curious": PLAIN,
    "python": PLAIN,
    "pip": PLAIN,
    "bash": PLAIN,
    "rerun": PLAIN,  # rerun-sdk
    "dagster": PLAIN,
    "dagster-webserver": "ui",
    "jupytext": "notebooks",
    "jupytext-config": "notebooks",
    "papermill": "notebooks",
    "jupyter": "lab",
    "ray": "ray",
    "ssh": None,
    "echo": None,
    "nvidia-cuda-mps-control": None,
}
"""A documented command's program -> the extra that installs it (PLAIN: the plain install), or
None for one this project does not install (the system's)."""
ENV = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*=")
REDIRECT = re.compile(r"^\d?>>?(&\d|\S*)$")
"""A shell redirection; its group is what follows in the same word (empty: the next word)."""
INSTALL = re.compile(r"""pip install -e "?\.\[([a-z,]+)\]"?""")


@dataclass(frozen=True)
class DocCommand:
    """One command a page gives."""

    page: Path
    line: int
    text: str
    words: tuple[str, ...]
    """The words after any VAR=value, shell redirections left out."""

    @property
    def program(self) -> str:
        return self.words[0]

    @property
    def elided(self) -> bool:
        """Written with `...` for options given elsewhere (not a whole command)."""
        return "..." in self.words

    @property
    def extra(self) -> str | None:
        """The extra it needs: its program's, or what some commands need beyond it (an MP4 of
        `curious render`, Ray tasks, the tests)."""
        words = self.words
        if words[:3] == ("python", "-m", "pytest"):
            return "test"
        if words[:2] == ("curious", "render") and any(w.endswith(".mp4") for w in words):
            return "video"
        if words[0] == "curious" and "--ray-address" in words:
            return "ray"
        return PROGRAMS.get(self.program, PLAIN)

    def __str__(self) -> str:
        return f"{self.page.name}:{self.line}: {self.text}"


def _blocks(text: str) -> list[tuple[str, int, list[str]]]:
    """Every fenced code block: its language, the line of its first line, its lines."""
    found, language, start, body = [], None, 0, []
    for number, line in enumerate(text.splitlines(), 1):
        if line.startswith("```"):
            if language is None:
                language, start, body = line[3:].strip(), number + 1, []
            else:
                found.append((language, start, body))
                language = None
        elif language is not None:
            body.append(line)
    return found


def _table_commands(text: str) -> list[tuple[int, str]]:
    """The first code span of each cell under a table header named `command`."""
    found, column = [], None
    for number, line in enumerate(text.splitlines(), 1):
        if not line.startswith("|"):
            column = None
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if column is None:
            column = cells.index("command") if "command" in cells else -1
        elif column >= 0 and column < len(cells) and not set(cells[column]) <= set("-: "):
            span = re.match(r"`([^`]+)`", cells[column])
            if span:
                found.append((number, span.group(1)))
    return found


def _split(number: int, line: str, page: Path) -> list[DocCommand]:
    """A shell line's commands (`&&`, `||`, `|`, `;` between them), comments and redirections
    (`> FILE`, `2>&1`) cut."""
    text = line.split(" #")[0].strip()
    commands, current, target_next = [], [], False
    for word in [*shlex.split(line, comments=True), "&&"]:
        if target_next:
            target_next = False
        elif word in ("&&", "||", "|", ";"):
            while current and ENV.match(current[0]):
                current.pop(0)
            if current:
                commands.append(DocCommand(page, number, text, tuple(current)))
            current = []
        elif REDIRECT.match(word):
            target_next = REDIRECT.match(word).group(1) == ""
        else:
            current.append(word)
    return commands


def page_commands(page: Path) -> list[DocCommand]:
    """Every command `page` gives: its shell blocks' lines (a trailing backslash continues a
    line) and its tables' `command` cells."""
    text = page.read_text()
    lines: list[tuple[int, str]] = []
    for language, start, body in _blocks(text):
        if language not in SHELL_BLOCKS:
            continue
        held: list[str] = []
        for offset, line in enumerate(body):
            held.append(line.rstrip().removesuffix("\\"))
            if not line.rstrip().endswith("\\"):
                lines.append((start + offset - len(held) + 1, " ".join(held)))
                held = []
    lines += _table_commands(text)
    return [c for number, line in lines for c in _split(number, line, page)]


def extras_given(page: Path) -> set[str]:
    """The extras `page` tells the reader to install (`pip install -e ".[a,b]"`)."""
    return {e for group in INSTALL.findall(page.read_text()) for e in group.split(",")}
