"""Train what an evidence campaign still lacks, two runs at a time, into a `curious reproduce`
output folder.

`curious reproduce` trains every run its experiments name that its output folder does not hold
finished. A campaign whose machine came back empty has shipped some runs already (`curious ship`,
committed under `data/`) and has lost their folders; `reproduce` would train those again. This
queue trains the runs that match `--only`, in the budget's own order (experiment by experiment,
seed by seed), leaving out every run that `--shipped` holds finished, with the same call
`reproduce` makes for each partition (`pipelines.training.run_partition`: a new folder starts, a
partial one resumes from its last checkpoint, a finished one is skipped). The folder gets the
`reproduce.json` that `reproduce` writes, so `curious progress` reads it and `curious reproduce`
can go on with it later.

Run it from the campaign's worktree, so that the code that trains is the campaign's commit:

    cd ~/campaign && PYTHONPATH=$HOME/campaign MUJOCO_GL=disable \
        python /work/main/tools/campaign.py --out ~/curious-runs/laptop \
        --shipped /work/main/data/laptop --set torch_threads=1

Stopped (Ctrl-C, or the machine's session ending), it is started again with the same command.
"""

from __future__ import annotations

import argparse
import fnmatch
import sys
import time
from pathlib import Path

from curious.config import parse_overrides
from curious.experiments import RunSpec, get_budget
from curious.shipped import ShippedFolder
from pipelines.executors import Job, LocalPool, run_all
from pipelines.reproduce import _write_manifest, check_output_folder
from pipelines.resources import OutputLayout

DEFAULT_ONLY = ("main/*", "sensor_failure/*", "distractors/*@distractors_7/*")
"""The campaign's runs (docs/results.md): the main comparison, the sensory failure, then the
distractors' `distractors_7` variant."""


def shipped_finished(data: Path | None) -> set[str]:
    """The runs (`<experiment>/<condition>/seed-<s>`) that the shipped folder holds finished."""
    if data is None:
        return set()
    folder = ShippedFolder(data)
    if not folder.is_shipped:
        raise SystemExit(f"--shipped {data}: no shipped data folder there (no shipped.json)")
    return {run.run for run in folder.read_manifest().runs if run.finished}


def queue(budget: str, only: tuple[str, ...], shipped: set[str]) -> list[RunSpec]:
    """The runs to train without the shipped ones: pattern by pattern of `only`, and in the
    budget's order (experiment by experiment, seed by seed) within a pattern."""
    specs = [
        spec
        for experiment in get_budget(budget).experiments.values()
        for spec in experiment.runs()
        if str(spec.relative_path) not in shipped
    ]
    return [
        spec
        for pattern in only
        for spec in specs
        if fnmatch.fnmatchcase(str(spec.relative_path), pattern)
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="the reproduce output folder")
    parser.add_argument("--budget", default="laptop", help="the budget (default laptop)")
    parser.add_argument(
        "--only",
        action="append",
        help="glob over runs' paths below the runs root, repeatable "
        f"(default: {' '.join(DEFAULT_ONLY)})",
    )
    parser.add_argument(
        "--shipped", type=Path, help="a shipped data folder: its finished runs are not trained"
    )
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="as reproduce's --set"
    )
    parser.add_argument("--workers", type=int, default=2, help="runs side by side (default 2)")
    parser.add_argument("--dry-run", action="store_true", help="list the queue and stop")
    args = parser.parse_args(argv)

    budget = get_budget(args.budget)
    layout = OutputLayout.at(args.out)
    check_output_folder(layout, budget)
    overrides = parse_overrides(args.set)
    shipped = shipped_finished(args.shipped)
    specs = queue(budget.name, tuple(args.only or DEFAULT_ONLY), shipped)
    import curious

    print(f"curious from {Path(curious.__file__).parent}; {len(specs)} runs queued", flush=True)
    for spec in specs:
        print(f"  {spec.relative_path} ({spec.total_episodes:,} episodes)", flush=True)
    if args.dry_run:
        return 0
    _write_manifest(layout, budget)
    jobs = [Job(spec, str(layout.runs_root), overrides) for spec in specs]
    tic = time.time()
    pool = LocalPool(args.workers)
    try:
        for result in run_all(pool, jobs):
            print(f"{time.strftime('%H:%M:%S')} {result}", flush=True)
    finally:
        pool.close()
    print(f"done in {(time.time() - tic) / 3600:.2f} h", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
