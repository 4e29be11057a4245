"""The command lines the docs give work after the install the same page gives, from a fresh
clone: every option a page writes after `curious COMMAND` (and `curious bench BENCHMARK`) is one
that command takes, so a renamed or removed option cannot live on in README.md, docs/, data/ or
notebooks/; and every whole command of their shell blocks and command tables is checked
(tests/doc_commands.py): its program is one whose install the project knows, the page gives
that install, a `curious` command parses, the other programs answer --help, and the commands
that read the shipped runs run."""

from __future__ import annotations

import argparse
import contextlib
import functools
import io
import os
import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest
from doc_commands import PLAIN, PROGRAMS, DocCommand, extras_given, page_commands
from doc_pages import PAGES, ROOT, page_id

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


# Each command a page gives, as a whole (tests/doc_commands.py reads them): its program is one
# the project knows the install of, the page gives that install, a `curious` command parses, the
# other programs answer --help after the test install, and the commands that read the shipped
# runs run, in a checkout as a fresh clone has it.

PAGE_COMMANDS = {page: page_commands(page) for page in PAGES}
ALL_COMMANDS = [c for commands in PAGE_COMMANDS.values() for c in commands]


def test_the_pages_give_whole_commands():
    """The scan reads the pages' shell blocks and command tables (a pattern that matched
    nothing would pass)."""
    assert len(ALL_COMMANDS) > 60
    assert {c.program for c in ALL_COMMANDS} >= {"curious", "pip", "papermill", "jupytext"}


def test_every_program_a_page_runs_is_one_the_project_knows_how_to_install():
    """A new documented program fails here until doc_commands.PROGRAMS says which extra
    installs it (or that the system does): then the tests below check it."""
    unknown = [str(c) for c in ALL_COMMANDS if c.program not in PROGRAMS]
    assert not unknown, f"add these programs to tests/doc_commands.py PROGRAMS: {unknown}"


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_a_page_gives_the_install_each_of_its_commands_needs(page: Path):
    """A command that needs an extra (`papermill`, an MP4 of `curious render`, Ray tasks)
    works after the install the same page gives: `pip install -e ".[EXTRA]"` from a clone."""
    given = extras_given(page)
    missing = [
        f'{c} (needs pip install -e ".[{c.extra}]")'
        for c in PAGE_COMMANDS[page]
        if c.extra and c.extra not in given
    ]
    assert not missing, f"{page.name} gives commands without the install they need: {missing}"


def test_every_extra_a_page_installs_is_one_pyproject_defines():
    import tomllib

    defined = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = set(defined["optional-dependencies"])
    for page in PAGES:
        assert extras_given(page) <= extras, (page.name, extras_given(page) - extras)


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_curious_command_a_page_gives_parses(page: Path):
    """Each whole `curious` command (not one written with `...` for the options given above
    it) parses as the command line would: its subcommand, required arguments, choices and
    values."""
    parser = build_parser()
    failed = []
    for command in PAGE_COMMANDS[page]:
        if command.program != "curious" or command.elided:
            continue
        err = io.StringIO()
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                parser.parse_args(list(command.words[1:]))
        except SystemExit:
            failed.append(f"{command}: {err.getvalue().strip().splitlines()[-1:]}")
    assert not failed, f"{page.name} gives commands that do not parse: {failed}"


def test_the_other_programs_the_pages_run_answer_help_after_the_test_install():
    """Every program the pages run that this project installs is there after the test install
    (`pip install -e ".[test]"`, which holds every extra but `lab`) and answers --help."""
    import tomllib

    test_extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]["test"]
    installed = {PLAIN, *re.findall(r"[a-z]+", test_extra[0].split("[", 1)[1])}
    for program in sorted({c.program for c in ALL_COMMANDS} - {"curious"}):
        extra = PROGRAMS[program]
        if extra is None or extra not in installed:
            continue  # the system's, or an extra the tests leave out (JupyterLab)
        path = shutil.which(program)
        assert path, f"{program} is not installed after pip install -e '.[test]' ({extra!r})"
        done = subprocess.run(
            [path, "--help"], capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL
        )
        assert done.returncode == 0, (program, done.stderr[-500:])


def _runs_here(command: DocCommand) -> bool:
    """A command cheap enough to run in the tests: it reads the shipped runs or the notebooks'
    sources and ends in seconds."""
    words = command.words
    if words[0] in ("jupytext", "papermill") or words[:2] == ("python", "-c"):
        return True
    return words[:2] == ("curious", "progress") and all(w.startswith("data/") for w in words[2:])


RUN_PAGES = [page for page in PAGES if any(_runs_here(c) for c in PAGE_COMMANDS[page])]


@pytest.mark.parametrize("page", RUN_PAGES, ids=page_id)
def test_the_commands_that_read_the_shipped_runs_run_in_a_fresh_checkout(page: Path, tmp_path):
    """Run, in the page's order, in a folder holding what a fresh clone holds of what they read
    (data/ and the notebooks' sources, no runs/), each command that reads the shipped runs or
    the notebooks: a papermill example given a folder a clone does not have fails here.
    Their /tmp/ outputs go to the test's own folder."""
    if not (ROOT / "data" / "laptop" / "shipped.json").is_file():
        pytest.skip("no data/laptop in this checkout")
    checkout = tmp_path / "clone"
    (checkout / "notebooks").mkdir(parents=True)
    for source in (ROOT / "notebooks").glob("*.py"):
        shutil.copy(source, checkout / "notebooks")
    (checkout / "data").symlink_to(ROOT / "data")
    for command in [c for c in PAGE_COMMANDS[page] if _runs_here(c)]:
        line = shlex.join(command.words).replace("'notebooks/*.py'", "notebooks/*.py")
        line = line.replace("/tmp/", f"{tmp_path}/")
        done = subprocess.run(
            ["bash", "-c", line], cwd=checkout, capture_output=True, text=True, timeout=600,
            stdin=subprocess.DEVNULL, env={**os.environ, "MUJOCO_GL": "disable"},
        )  # fmt: skip
        assert done.returncode == 0, f"{command}: {done.stderr[-1500:]}"


def test_no_install_hint_names_the_package_index():
    """The hints the commands print say the install that works from a clone (the project is
    not on the package index, where `curious[...]` names another package)."""
    hinted = [
        f"{path.relative_to(ROOT)}"
        for folder in ("curious", "pipelines")
        for path in (ROOT / folder).rglob("*.py")
        if "pip install 'curious[" in path.read_text()
    ]
    assert not hinted, hinted
