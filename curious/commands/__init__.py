"""Sub-commands of the `curious` command line, one module each, and what they share: the help
formatter, the `--set` option and the check of a folder argument. `curious.cli` loads them; they
import nothing from it."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from typing import Any

import suite
from curious.watching.recording.settings import RecorderSettings
from suite.catalog import BUILT_IN


def refuse(command: str, exc: BaseException, status: int = 2, message: str | None = None) -> int:
    """Print `exc` (or `message`, where it says it better) as `curious COMMAND`'s one-line error
    on stderr and return the exit `status`; with `CURIOUS_DEBUG` set, raise `exc` instead, so
    that its traceback shows (every command's refusals go through here, so the variable works
    for all of them)."""
    if os.environ.get("CURIOUS_DEBUG"):
        raise exc
    print(f"curious {command}: error: {message or exc}", file=sys.stderr)
    return status


class CommandParser(argparse.ArgumentParser):
    """The parser of `curious` and of each of its sub-commands: a word a sub-command does not
    know (a mistyped option) is refused by that sub-command, with its own usage and name
    (`curious bench learner: error: unrecognized arguments: --updates 0`), not by the top-level
    parser, whose usage does not list the option meant. argparse hands every word after a
    sub-command's name to that sub-command, so none of them is the parent's to take.
    Sub-parsers are of this class too: `add_subparsers` makes them of their parent's class."""

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        namespace, extras = super().parse_known_args(args, namespace)
        if extras:
            self.error(f"unrecognized arguments: {' '.join(extras)}")
        return namespace, extras


def folder_name(text: str) -> str:
    """An argparse `type` for a folder argument: an empty one (an unset shell variable) names
    nothing, and is refused rather than read as the current folder."""
    if not text.strip():
        raise argparse.ArgumentTypeError("is empty: name a folder")
    return text


def add_set_option(parser: argparse.ArgumentParser, help_text: str) -> None:
    """`--set KEY=VALUE` (repeatable) into `args.overrides`
    (`curious.overrides.parse_overrides`)."""
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help=help_text
    )


def _suite_variants() -> str:
    return ", ".join(suite.ALL_VARIANTS)


def _suite_modules() -> str:
    names: dict[str, None] = {}
    for spec in BUILT_IN.values():  # described, not built
        names.update(dict.fromkeys(spec.module_names))
    return ", ".join(names)


def _rollout_every() -> str:
    return str(RecorderSettings().rollout_every)


HELP_FIELDS: dict[str, Callable[[], str]] = {
    "variants": _suite_variants,
    "modules": _suite_modules,
    "rollout_every": _rollout_every,
}
"""Values that help texts name as `{field}`: filled in only when a help text is printed, so
that `curious` starts without importing MuJoCo or Rerun."""


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Shows defaults, and fills `{variants}`, `{modules}` and `{rollout_every}` in help texts
    (the suite's registered names, the recorder's default) when the help is printed."""

    def _fill(self, text: str) -> str:
        for field, value in HELP_FIELDS.items():
            if "{" + field + "}" in text:
                text = text.replace("{" + field + "}", value())
        return text

    def add_text(self, text: str | None) -> None:
        super().add_text(self._fill(text) if text else text)

    def _expand_help(self, action: argparse.Action) -> str:
        return self._fill(super()._expand_help(action))
