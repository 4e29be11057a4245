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

Run it from the campaign's worktree, so that the code that trains is the campaign's commit
(9972821): it imports `curious` and `pipelines` from there, so it uses only what that commit has
(`pipelines.reproduce._write_manifest` among them):

    cd ~/campaign && PYTHONPATH=$HOME/campaign MUJOCO_GL=disable \
        python /work/main/tools/campaign.py --out ~/curious-runs/laptop \
        --shipped /work/main/data/laptop --set torch_threads=1

With `--ship`, each run that finishes is shipped at once into the `--shipped` folder (`curious
ship --keep`, by the checkout this file lies in) and committed there, so that a machine that comes
back empty loses only the runs in flight. Stopped (Ctrl-C, or the machine's session ending), the
queue is started again with the same command.
"""

from __future__ import annotations

import argparse
import fnmatch
import os
import subprocess
import sys
import time
from pathlib import Path

import curious
from curious.config import parse_overrides

try:
    from curious.reproduction.experiments import RunSpec, get_budget
    from curious.reproduction.shipped_folder import ShippedFolder
except ModuleNotFoundError:  # a campaign commit from before the sub-packages (9972821)
    from curious.experiments import RunSpec, get_budget
    from curious.shipped import ShippedFolder
from pipelines.executors import Job, LocalPool, run_all
from pipelines.reproduce import _write_manifest, check_output_folder
from pipelines.resources import OutputLayout
from pipelines.training import PartitionResult

DEFAULT_ONLY = (
    "main/*",
    "sensor_failure/*",
    "distractors/*@distractors_7/*",
    "distractors/*@distractors_4/*",
    "distractors/*@distractors_0/*",
)
"""The campaign's runs (docs/results.md): the main comparison, the sensory failure, the
distractors' `distractors_7` variant, then, as far as the compute allows, `distractors_4` and
`distractors_0`, which C4's claim of a smaller degradation needs."""


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


CHECKOUT = Path(__file__).resolve().parents[1]
"""The checkout this file lies in: its `curious ship` ships the finished runs."""


def ship_and_commit(out: Path, data: Path, run: str) -> None:
    """Ship the finished runs of `out` into `data`, keeping what it holds, and commit `data`
    where it lies in a git repository; a failure is printed, the queue goes on."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    ship = [sys.executable, "-m", "curious.cli", "ship", str(out), "--out", str(data), "--keep"]
    steps = [ship]
    inside = subprocess.run(
        ["git", "-C", str(data), "rev-parse", "--show-toplevel"], capture_output=True, text=True
    )
    if inside.returncode == 0:
        message = f"{data.name}: {run} shipped as soon as it finished (tools/campaign.py --ship)"
        steps += [
            ["git", "-C", str(data), "add", "--", "."],
            ["git", "-C", str(data), "commit", "-q", "-m", message, "--", "."],
        ]
    for step in steps:
        for attempt in range(5):  # another git command may hold the index for a moment
            done = subprocess.run(step, cwd=CHECKOUT, env=env, capture_output=True, text=True)
            if done.returncode == 0 or "index.lock" not in done.stderr:
                break
            time.sleep(10 * (attempt + 1))
        print(done.stdout, done.stderr, sep="", end="", flush=True)
        if done.returncode != 0:
            print(f"{' '.join(step[:4])} ... failed ({done.returncode})", flush=True)
            return


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
    parser.add_argument(
        "--ship",
        action="store_true",
        help="ship each run that finishes into --shipped at once, and commit it there",
    )
    parser.add_argument("--workers", type=int, default=2, help="runs side by side (default 2)")
    parser.add_argument("--dry-run", action="store_true", help="list the queue and stop")
    args = parser.parse_args(argv)
    if args.ship and args.shipped is None:
        parser.error("--ship needs --shipped: the data folder to ship into")

    budget = get_budget(args.budget)
    layout = OutputLayout.at(args.out)
    check_output_folder(layout, budget)
    overrides = parse_overrides(args.set)
    shipped = shipped_finished(args.shipped)
    specs = queue(budget.name, tuple(args.only or DEFAULT_ONLY), shipped)

    print(f"curious from {Path(curious.__file__).parent}; {len(specs)} runs queued", flush=True)
    for spec in specs:
        print(f"  {spec.relative_path} ({spec.total_episodes:,} episodes)", flush=True)
    if args.dry_run:
        return 0
    _write_manifest(layout, budget)
    jobs = [Job(spec, str(layout.runs_root), overrides) for spec in specs]
    tic = time.time()
    pool = LocalPool(args.workers)

    def on_done(job: Job, result: PartitionResult) -> None:
        print(f"{time.strftime('%H:%M:%S')} {result}", flush=True)
        if args.ship:
            ship_and_commit(layout.out, args.shipped.resolve(), str(job.spec.relative_path))

    try:
        run_all(pool, jobs, on_done=on_done)
    finally:
        pool.close()
    print(f"done in {(time.time() - tic) / 3600:.2f} h", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
