"""`curious progress ROOT [ROOT ...]`: how far every run below ROOT has got, as a table.

    curious progress ~/curious-runs/laptop
    curious progress ~/curious-runs/laptop --update docs/results.md
    curious progress ~/curious-runs/laptop data/laptop   # with the runs shipped from it
    curious progress ~/curious-runs/laptop --at-once 1   # hours left, one run at a time

Read from the run folders alone (config.json, metrics.parquet, tests.parquet, checkpoints/), so
it can be run while the runs train. A second table sums the runs per experiment, with the hours
left at the pace of the runs training now, as many side by side as the reproduction trains
(reproduce.json's `at_once`; else the runs started and not finished; `--at-once N` says
otherwise). `--update FILE` replaces the block between the lines
`<!-- progress:begin -->` and `<!-- progress:end -->` of FILE with both tables and the time they
were computed, leaving the rest of the file as it is, and names on stderr every run the
replaced table gave more episodes than its folder holds now (a folder lost or rolled back).
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
from pathlib import Path

from curious.commands import folder_name
from curious.config import DEFAULT_TEST_EPOCHS

BEGIN = "<!-- progress:begin -->"
END = "<!-- progress:end -->"


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious progress`."""
    parser = sub.add_parser(
        "progress",
        help="how far the runs below a folder have got (episodes, checkpoints, test success)",
        description=__doc__.split("\n\n")[0]
        + "\n\nOne row per run folder: episodes logged against the run's total, the newest "
        "checkpoint, the run's own clock, test success on the achievable modules pooled over "
        "the last epochs (HER scored on its holistic goal, as the paper's Fig. 2a), and the "
        "commits the run was trained from (a '+' marks local changes). Where a run has a "
        "sensory failure (variant sensor_failure), a column says where it stands: 'from "
        "episode N' once the run has flagged it, else what it waits for (its episode, or the "
        "perturbed module's competence against the run's threshold). In a reproduction's "
        "output folder (one holding reproduce.json) the budget's runs that have not started "
        "are listed too, with 0 episodes, and so are those of the seeds a campaign adds beyond "
        "the budget's (reproduce.json's extra_seeds, which tools/campaign.py --seeds writes). "
        "A ROOT that is a shipped data folder (`curious "
        "ship`) lists its runs as shipped, in place of the same runs not started in a "
        "reproduction given beside it (a machine that lost the folders of runs it had "
        "shipped); a run both hold is listed once, from its folder, its checkpoint followed "
        "by 'shipped' when the shipped copy holds all its episodes.\n\nA second table sums "
        "the runs per experiment (the first folder of their paths): runs finished, episodes "
        "logged and left, run-hours so far, and the hours left at the pace of the runs "
        "training now (episodes per run-second of the started, unfinished runs, by their own "
        "clocks; of every run when none is training), as many side by side as the "
        "reproduction trains: the count its reproduce.json records (`at_once`, which `curious "
        "reproduce` writes), else the runs started and not finished (a campaign queue records "
        "none), unless --at-once says otherwise. An estimate, which assumes the runs left cost "
        "what those cost.\n\nA folder whose "
        "config.json or tables cannot be read is left out of the tables, with its problem on "
        "stderr; the command fails only when no folder could be read.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "roots", nargs="+", metavar="ROOT", type=folder_name, help="run folder, or a folder of them"
    )
    parser.add_argument(
        "--epochs",
        type=int,
        default=DEFAULT_TEST_EPOCHS,
        help="pool test success over this many of each run's last epochs (default %(default)s)",
    )
    parser.add_argument(
        "--at-once",
        type=int,
        default=None,
        metavar="N",
        help="runs trained side by side, for the hours left (default: as many as the "
        "reproduction trains: reproduce.json's at_once, else the runs started and not finished)",
    )
    parser.add_argument(
        "--update",
        metavar="FILE",
        help=f"write the tables into FILE between the lines {BEGIN} and {END}; a run the "
        "table replaced gave more episodes than its folder holds now is named on stderr",
    )
    parser.set_defaults(func=run)


def replace_block(text: str, block: str, path: Path) -> str:
    """`text` with the lines between the progress markers replaced by `block`."""
    if text.count(BEGIN) != 1 or text.count(END) != 1 or text.index(BEGIN) > text.index(END):
        raise ValueError(f"{path} must hold one line {BEGIN} followed by one line {END}")
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    return f"{head}{BEGIN}\n{block}{END}{tail}"


def block_rows(text: str) -> dict[str, dict[str, str]]:
    """Each run of the progress block of `text` (the first table, as `progress_markdown` writes
    it): its cells by column name; empty where there is no block or no such table."""
    if text.count(BEGIN) != 1 or text.count(END) != 1:
        return {}
    block = text.split(BEGIN, 1)[1].split(END, 1)[0]
    rows: dict[str, dict[str, str]] = {}
    header: list[str] | None = None
    for line in block.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if not line.startswith("|"):
            if header is not None:
                break  # the first table ended
            continue
        if header is None:
            if cells[0] == "run":
                header = cells
            continue
        if set(line.strip()) <= set("|-: "):
            continue  # the alignment row
        rows[cells[0]] = dict(zip(header, cells, strict=False))  # a short row keeps its cells
    return rows


def block_episodes(text: str) -> dict[str, int]:
    """The episodes of each run in the progress block of `text` (the `episodes` column of
    `block_rows`); empty where there is no block or no such table."""
    episodes: dict[str, int] = {}
    for run, cells in block_rows(text).items():
        value = cells.get("episodes", "").replace(",", "")
        if value.isdigit():
            episodes[run] = int(value)
    return episodes


def fewer_episodes(before: dict[str, int], now: dict[str, int]) -> list[str]:
    """One line per run the table before listed with more episodes than the runs hold now,
    or that the runs no longer list: a run folder lost or rolled back, which the page should
    say beside the block, since the next table will not show it."""
    lines = []
    for run, was in before.items():
        if run not in now:
            lines.append(f"{run}: no longer listed (the table before: {was:,} episodes)")
        elif now[run] < was:
            lines.append(f"{run}: {now[run]:,} episodes, the table before: {was:,}")
    return lines


def _read_text(path: Path) -> str:
    """`path`'s text, or a ValueError naming it where it is not UTF-8."""
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        problem = f"{exc.reason} at byte {exc.start:,}"
        raise ValueError(f"--update {path} is not UTF-8 text ({problem})") from None


def run(args: argparse.Namespace) -> int:
    from curious.analysis import AnalysisError
    from curious.reproduction.campaign_progress import (
        progress_markdown,
        progress_table,
        runs_at_once,
        summary_markdown,
    )

    if args.epochs < 1:
        raise ValueError(f"--epochs must be at least 1, got {args.epochs}")
    if args.at_once is not None and args.at_once < 1:
        raise ValueError(f"--at-once must be at least 1, got {args.at_once}")
    if args.update is not None and not args.update.strip():
        raise ValueError("--update is empty: name the Markdown file whose block to replace")
    path = Path(args.update) if args.update is not None else None
    if path is not None and path.is_dir():
        raise ValueError(f"--update {path} is a folder: name the Markdown file in it")
    if path is not None and not path.is_file():
        raise FileNotFoundError(f"{path} does not exist; create it with the two marker lines")
    if path is not None and not os.access(path, os.W_OK):  # a read-only file or file system
        raise ValueError(f"--update {path} cannot be written (read-only)")
    if path is not None:
        replace_block(_read_text(path), "", path)  # the markers, before any run is read

    def skip(folder: Path, problem: str) -> None:
        print(f"curious progress: left out {folder}: {problem}", file=sys.stderr)

    try:
        rows = progress_table(args.roots, args.epochs, on_unreadable=skip)
        at_once = args.at_once or runs_at_once(args.roots, rows)
    except AnalysisError as exc:
        raise ValueError(str(exc)) from exc
    base = args.roots[0] if len(args.roots) == 1 else None
    table = progress_markdown(rows, base, args.epochs) + "\n" + summary_markdown(rows, at_once)
    if path is None:
        sys.stdout.write(table)
        return 0
    now = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    roots = " ".join(_home_relative(r) for r in args.roots)
    given = f" --at-once {args.at_once}" if args.at_once is not None else ""
    block = f"Computed by `curious progress {roots}{given}` at {now}.\n\n{table}"
    text = _read_text(path)
    updated = replace_block(text, block, path)
    path.write_text(updated, encoding="utf-8")
    print(f"updated {path} ({len(rows)} runs)")
    if lost := fewer_episodes(block_episodes(text), block_episodes(updated)):
        print(
            f"curious progress: fewer episodes than the table this one replaced in {path} "
            "(a run folder lost or rolled back; the table no longer shows what was there, so "
            "say so beside it):\n  " + "\n  ".join(lost),
            file=sys.stderr,
        )
    return 0


def _home_relative(folder: Path) -> str:
    """``folder`` as the block names it: below the home folder as ``~/...`` (a page quotes the
    command, not one machine's home), else as given."""
    try:
        return (
            "~/" + Path(folder).expanduser().resolve().relative_to(Path.home().resolve()).as_posix()
        )
    except ValueError:
        return str(folder)
