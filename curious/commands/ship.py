"""`curious ship ROOT`: a reproduction's finished runs, reduced to a data folder to commit.

    curious ship runs/laptop                           # -> data/laptop (the budget's name)
    curious ship ~/curious-runs/laptop --out data/laptop --unfinished   # a progress snapshot
    curious ship ~/curious-runs/laptop --out data/laptop --keep   # add to the runs shipped there
    curious reproduce --budget laptop --from-data data/laptop   # the report, without training

ROOT is a `curious reproduce` output folder (its run folders are found where its reproduce.json
says, and its budget is recorded) or any folder of run folders. The data folder holds each
run's config.json and its tables without the columns no analysis reads
(`curious.runs.shipped_folder`);
no checkpoint, no recording. By default only finished runs are shipped; `--unfinished` ships the
others too, marked as unfinished in shipped.json. An --out holding an earlier ship of the same
budget is replaced, or with `--keep` added to: the runs it holds stay unless this ship writes
them again (a run shipped finished is never replaced by an unfinished one), so that runs whose
folders are gone (a new machine, say) stay shipped. Prints what was shipped and the
size written.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from curious.commands import folder_name
from curious.reproduction.experiments import ExperimentError, get_budget
from curious.runs.folder_layout import CONFIG_FILE, LEARNER_FILE, METRICS_FILE, TESTS_FILE
from curious.runs.shipped_folder import MANIFEST_FILE, ShippedFolder
from pipelines.resources import OutputLayout


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious ship`."""
    parser = sub.add_parser(
        "ship",
        help="reduce a reproduction's finished runs to a small data folder to commit",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "root", metavar="ROOT", type=folder_name, help="reproduction output, or folder of runs"
    )
    parser.add_argument(
        "--out",
        default=None,
        help="the data folder to write (default for a reproduction: data/<budget>)",
    )
    parser.add_argument(
        "--unfinished",
        action="store_true",
        help="ship unfinished runs too, marked as such (a progress snapshot)",
    )
    parser.add_argument(
        "--keep",
        action="store_true",
        help="keep the runs --out already holds that ROOT does not ship again",
    )
    parser.set_defaults(func=run)


def _megabytes(n: int) -> str:
    return f"{n / 1e6:.2f} MB"


def run(args: argparse.Namespace) -> int:
    from curious.reproduction.shipping import check_root, ship

    root = Path(args.root)
    check_root(root)  # before --out is asked for: a mistyped ROOT is named first
    layout = OutputLayout.at(root)
    runs_root, budget = None, None
    if layout.manifest.is_file():
        layout = OutputLayout.open(root)
        try:
            budget = layout.budget_name()
        except (OSError, ValueError) as exc:
            raise ValueError(f"{layout.manifest} is unreadable ({exc})") from None
        try:
            get_budget(budget)
        except ExperimentError as exc:
            raise ValueError(f"{layout.manifest} is damaged: {exc}") from None
        runs_root = layout.runs_root
        if ShippedFolder(runs_root).is_shipped:
            raise ValueError(
                f"{root} was built from the shipped data folder {runs_root} (`curious reproduce "
                "--from-data`): its runs are shipped there already"
            )
    if args.out is not None and not args.out.strip():
        raise ValueError("--out is empty: name a folder")
    if args.out is None and budget is None:
        raise ValueError(f"{root} is not a `curious reproduce` output: pass --out")
    out = Path(args.out) if args.out is not None else Path("data", budget or "")
    result = ship(
        root, out, runs_root=runs_root, budget=budget, unfinished=args.unfinished, keep=args.keep
    )

    runs = [r for r in result.manifest.runs if r.run not in result.kept]
    finished = sum(r.finished for r in runs)
    what = f"{finished} finished run(s)" + (
        f" and {len(runs) - finished} unfinished" if finished < len(runs) else ""
    )
    of = f" of budget {budget}" if budget else ""
    print(f"shipped {what}{of} from {root} to {out}")
    if result.kept:
        print(f"  kept from the earlier ship: {', '.join(result.kept)}")
    sizes = result.sizes
    metadata = sizes.get(CONFIG_FILE, 0) + sizes.get(MANIFEST_FILE, 0)
    tables = [METRICS_FILE, TESTS_FILE] + [LEARNER_FILE] * (LEARNER_FILE in sizes)
    print(
        "  "
        + "".join(f"{name} {_megabytes(sizes.get(name, 0))}, " for name in tables)
        + f"{CONFIG_FILE} and {MANIFEST_FILE} {_megabytes(metadata)}: "
        f"{_megabytes(result.bytes)} in all ({result.bytes:,} bytes), "
        f"{sum(r.episodes for r in runs):,} episodes, in {result.seconds:.1f} s"
    )
    if result.left_out:
        hint = " (--unfinished ships those that have started)" if result.unfinished_left_out else ""
        print(f"  left out{hint}: {', '.join(result.left_out)}")
    return 0
