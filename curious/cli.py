"""The `curious` command line: one sub-command per module of `curious.commands`.

Each sub-command module exposes `register(subparsers)`, which adds its parser and sets
`func` on it; heavy imports (torch, MuJoCo, Dagster, Ray) happen inside the command, so that
`curious --help` answers at once. The dependency runs one way: this module loads the
sub-commands; they import nothing from it (what they share is in `curious.commands`).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

from curious.commands import CommandParser, refuse
from curious.gl import gl_for_command, rendering_problem, renders

COMMAND_MODULES: tuple[str, ...] = (
    "curious.commands.train",
    "curious.commands.view",
    "curious.commands.render",
    "curious.commands.bench",
    "curious.commands.reproduce",
    "curious.commands.ship",
    "curious.commands.progress",
    "curious.commands.evaluate",
)


def version() -> str:
    """The installed curious version."""
    try:
        return importlib.metadata.version("curious")
    except importlib.metadata.PackageNotFoundError:
        return "unknown (not installed)"


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every sub-command that is installed."""
    parser = CommandParser(
        prog="curious",
        description=(
            "CURIOUS: intrinsically motivated multi-task, multi-goal RL on the Multi-Task "
            "Fetch Arm. Train agents, watch runs in Rerun, benchmark, and rebuild the "
            "figures of the paper."
        ),
    )
    parser.add_argument("--version", action="version", version=f"curious {version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:
                continue
            raise
        module.register(sub)
    return parser


def _one_line_warnings(prefix: str, default: Callable[..., str]) -> Callable[..., str]:
    """A `warnings.formatwarning` that prints curious's own warnings (a damaged checkpoint
    passed over, ...) as one line, as its errors are, and other libraries' as they are."""
    package = Path(__file__).resolve().parent

    def format_warning(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        line: str | None = None,
    ) -> str:
        if not Path(filename).resolve().is_relative_to(package):
            return default(message, category, filename, lineno, line)
        return f"{prefix}: warning: {message}\n"

    return format_warning


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `curious` console script. Bad input is one line on stderr (exit
    status 2), and so is a Ctrl-C, whenever it comes (exit status 130), and each of curious's
    own warnings."""
    words = list(sys.argv[1:] if argv is None else argv)
    command = next((w for w in words if w[:1] != "-"), None)
    prefix = f"curious {command}" if command else "curious"
    default_format = warnings.formatwarning
    try:
        warnings.formatwarning = _one_line_warnings(prefix, default_format)
        return _main(argv, words)
    except KeyboardInterrupt:
        print(f"{prefix}: interrupted", file=sys.stderr)
        return 130
    finally:
        warnings.formatwarning = default_format


def _main(argv: list[str] | None, words: list[str]) -> int:
    gl_for_command(words)  # before anything imports MuJoCo (the parser does)
    if renders(words):
        problem = rendering_problem()
        if problem:
            print(f"curious render: error: {problem}", file=sys.stderr)
            return 2
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 2
    try:
        result = args.func(args)
    except (ValueError, RuntimeError, OSError) as exc:
        # Bad input and unusable paths (missing, a file for a folder, no permission, a full
        # disk) are reported in one line; CURIOUS_DEBUG=1 shows the traceback.
        return refuse(args.command, exc)
    except MemoryError as exc:  # numpy's "Unable to allocate 931. GiB ..." of a count too large
        return refuse(args.command, exc, message=f"not enough memory: {exc}; lower the counts")
    return int(result or 0)


if __name__ == "__main__":
    sys.exit(main())
