"""Train what an evidence campaign still lacks, two runs at a time, into a `curious reproduce`
output folder.

`curious reproduce` trains every run its experiments name that its output folder does not hold
finished. A campaign on a new machine has shipped some runs already (`curious ship`, committed
under `data/`) whose folders are not there; `reproduce` would train those again. This
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

One fixed commit per experiment: an experiment that commit does not know trains from its own
commit's worktree, with `--only` naming its runs, into the same output folder
(`tools/campaign.sh` runs `--only 'sensor_failure_mastered/*'` from ~/campaign-c5 between the
budget's runs and the seeds beyond them, both from 9972821).

With `--seeds EXPERIMENT=SEEDS` an experiment gets seeds beyond the budget's: runs identical to
the budget's in every setting but the seed (`dataclasses.replace` of the budget's experiment, so
that the campaign's commit, which has no other way to add seeds, builds them), queued after all of
the budget's runs, pattern by pattern of `--only` again, experiment by experiment in the order
`--seeds` names them, and seed by seed. The default for the
`laptop` budget (`DEFAULT_SEEDS`) is the evidence campaign's: the distractors to three seeds,
then the main comparison to five, as the paper's. Their seeds are written in the folder's
`reproduce.json` (`extra_seeds`), so that `curious progress` lists those not started as it lists
the budget's; a later start with fewer (`--seeds none`, the budget's runs alone) keeps them
there. `--plan-only` writes them and stops, so that a campaign of several steps records its
whole plan before its first step trains (`tools/campaign.sh` does). `curious ship` ships them,
and `curious reproduce --from-data` reads a seed beyond the budget's once every run of it in an
experiment is shipped finished.

With `--ship`, each run that finishes is shipped at once into the `--shipped` folder (`curious
ship --keep`, by the checkout this file lies in) and committed there, so that a machine that is lost
loses only the runs in flight. Stopped (Ctrl-C, or the machine going away), the queue is started
again with the same command.
"""

from __future__ import annotations

# ruff: noqa: E402  (the imports of the campaign's code come after the import finders are set)
import argparse
import dataclasses
import fnmatch
import json
import os
import subprocess
import sys
import time
from pathlib import Path

# Only the campaign's worktree (PYTHONPATH) supplies `curious`, `pipelines` and `suite`: an
# editable install of another checkout adds an import finder after the path's, which would
# otherwise supply the modules that the campaign's commit lacks (`curious.reproduction` at
# 9972821) from that checkout, mixing two commits' code in one run.
sys.meta_path[:] = [
    finder
    for finder in sys.meta_path
    if not getattr(finder, "__module__", "").startswith("__editable__")
]

try:
    import curious
except ModuleNotFoundError:
    print(
        "campaign.py: no curious on the path: it imports the campaign's code from its worktree "
        "only, so run it there with PYTHONPATH set (cd ~/campaign && PYTHONPATH=$PWD python "
        f"{Path(__file__).resolve()} ...), or start the campaign with `bash tools/campaign.sh`",
        file=sys.stderr,
    )
    sys.exit(2)
from curious.commands.reproduce import placement_overrides

try:
    from curious.reproduction.experiments import RunSpec, get_budget
except ModuleNotFoundError:  # a campaign commit from before the sub-packages (9972821)
    from curious.experiments import RunSpec, get_budget
try:
    from curious.runs.shipped_folder import ShippedFolder
except ModuleNotFoundError:  # the campaign's commits from before it moved to `curious.runs`
    try:
        from curious.reproduction.shipped_folder import ShippedFolder
    except ModuleNotFoundError:  # and from before the sub-packages (9972821)
        from curious.shipped import ShippedFolder
from pipelines.executors import Job, LocalPool, run_all
from pipelines.reproduce import ReproduceError, _write_manifest, check_output_folder
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


DEFAULT_SEEDS: dict[str, dict[str, tuple[int, ...]]] = {
    "laptop": {"distractors": (0, 1, 2), "main": (0, 1, 2, 3, 4)},
}
"""Budget -> experiment -> its seeds in the campaign, the budget's and beyond (`--seeds`), the
experiments' seeds beyond the budget's queued in this order: for `laptop`, the evidence
campaign's: the distractors' seed 2 of every variant (three seeds a side for C4, which two seeds
leave untested), then main's seeds 3 and 4 (five seeds, as the paper's, so that C1's per-bin
Welch tests do not hang on one seed), all trained from the commit of seeds 0-2 (9972821) so that
all are one protocol. The distractors come first because C1 already has a reading at three seeds
and C4 none at two, and because their runs are half as long (50,000 episodes): a machine lost
mid-run loses less."""


def parse_seeds(text: str) -> tuple[int, ...]:
    """`0-4` -> (0, 1, 2, 3, 4); `0,2,5` -> (0, 2, 5); ranges and single seeds mix."""
    seeds: list[int] = []
    for part in text.split(","):
        first, dash, last = part.strip().partition("-")
        if not first.isdigit() or (dash and not last.isdigit()):
            raise ValueError(f"seeds {text!r}: write them as 0-4 or 0,2,5")
        seeds += range(int(first), int(last) + 1) if dash else [int(first)]
    return tuple(dict.fromkeys(seeds))


def parse_seed_options(values: list[str]) -> dict[str, tuple[int, ...]]:
    """`--seeds` values (`main=0-4`, repeatable; `none`, alone: the budget's seeds only) as
    experiment -> seeds."""
    seeds: dict[str, tuple[int, ...]] = {}
    for value in (v for v in values if v != "none"):
        name, equals, text = value.partition("=")
        if not equals or not name.strip():
            raise ValueError(f"--seeds {value!r}: write EXPERIMENT=SEEDS, e.g. main=0-4")
        seeds[name.strip()] = seeds.get(name.strip(), ()) + parse_seeds(text)
    return seeds


def beyond(budget: str, seeds: dict[str, tuple[int, ...]]) -> dict[str, tuple[int, ...]]:
    """Experiment -> the seeds among `seeds` (experiment -> seeds) that its budget lacks, the
    experiments and their seeds in the order given; a `ValueError` for an experiment the budget
    does not train."""
    experiments = get_budget(budget).experiments
    if strangers := sorted(set(seeds) - set(experiments)):
        raise ValueError(
            f"--seeds: budget {budget} trains no {', '.join(strangers)} "
            f"(its experiments: {', '.join(experiments)})"
        )
    added = {
        name: tuple(s for s in chosen if s not in experiments[name].seeds)
        for name, chosen in seeds.items()
    }
    return {name: extra for name, extra in added.items() if extra}


def shipped_finished(data: Path | None) -> set[str]:
    """The runs (`<experiment>/<condition>/seed-<s>`) that the shipped folder holds finished."""
    if data is None:
        return set()
    folder = ShippedFolder(data)
    if not folder.is_shipped:
        raise ValueError(f"--shipped {data}: no shipped data folder there (no shipped.json)")
    return {run.run for run in folder.read_manifest().runs if run.finished}


def queue(
    budget: str,
    only: tuple[str, ...],
    shipped: set[str],
    seeds: dict[str, tuple[int, ...]] | None = None,
) -> list[RunSpec]:
    """The runs to train without the shipped ones: pattern by pattern of `only`, and in the
    budget's order (experiment by experiment, seed by seed) within a pattern; then the runs of
    the seeds `seeds` (experiment -> seeds) adds beyond the budget's, experiment by experiment
    in the order `seeds` names them, each in the same way. A run that
    several patterns match is queued at the first. A `ValueError` for a pattern that matches no
    run of the budget or of the seeds added (a typo would otherwise queue nothing, silently)."""
    experiments = get_budget(budget).experiments
    added = beyond(budget, seeds or {})
    # the budget's runs, then one group per experiment given seeds beyond them
    phases = [
        [spec for experiment in experiments.values() for spec in experiment.runs()],
        *(
            dataclasses.replace(experiments[name], seeds=extra).runs()
            for name, extra in added.items()
        ),
    ]
    every = [str(spec.relative_path) for specs in phases for spec in specs]
    if unmatched := [p for p in only if not fnmatch.filter(every, p)]:
        raise ValueError(
            f"--only {' '.join(unmatched)} matches no run of budget {budget} (its runs look "
            f"like {every[0]}, {every[-1]})"
        )
    queued: dict[str, RunSpec] = {}
    for specs in phases:
        for pattern in only:
            for spec in specs:
                path = str(spec.relative_path)
                if path not in shipped and fnmatch.fnmatchcase(path, pattern):
                    queued.setdefault(path, spec)
    return list(queued.values())


def recorded_seeds(layout: OutputLayout) -> dict[str, tuple[int, ...]]:
    """The seeds beyond the budget's that the folder's reproduce.json records (`extra_seeds`),
    none where it has no reproduce.json yet."""
    if not layout.manifest.is_file():
        return {}
    extra = json.loads(layout.manifest.read_text()).get("extra_seeds") or {}
    return {name: tuple(seeds) for name, seeds in extra.items()}


def record_seeds(layout: OutputLayout, added: dict[str, tuple[int, ...]]) -> None:
    """Write the seeds beyond the budget's into the folder's reproduce.json (`extra_seeds`),
    which `curious progress` reads; nothing where none is added."""
    if not added:
        return
    data = json.loads(layout.manifest.read_text())
    data["extra_seeds"] = {name: list(extra) for name, extra in added.items()}
    tmp = layout.manifest.with_name(f".{layout.manifest.name}.tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n")
    os.replace(tmp, layout.manifest)


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
        "--seeds",
        action="append",
        metavar="EXPERIMENT=SEEDS",
        help="an experiment's seeds, the budget's and beyond (0-4 or 0,2,5), repeatable; "
        "'none': the budget's only (default for laptop: "
        + " ".join(f"{k}={min(v)}-{max(v)}" for k, v in DEFAULT_SEEDS["laptop"].items())
        + ", the evidence campaign)",
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
    parser.add_argument(
        "--plan-only",
        action="store_true",
        help="record the seeds beyond the budget's that the queue trains in the output folder's "
        "reproduce.json (the plan `curious progress` counts), then stop without training",
    )
    args = parser.parse_args(argv)
    if args.ship and args.shipped is None:
        parser.error("--ship needs --shipped: the data folder to ship into")
    if args.plan_only and args.dry_run:
        parser.error("--plan-only writes the plan, --dry-run writes nothing: give one")

    if args.workers < 1:
        parser.error(f"--workers must be at least 1, got {args.workers}")
    try:  # every refusal before anything is written, in one line
        budget = get_budget(args.budget)
        layout = OutputLayout.at(args.out)
        check_output_folder(layout, budget)
        overrides = placement_overrides(args.set)  # the budget defines the runs
        seeds = parse_seed_options(args.seeds) if args.seeds else DEFAULT_SEEDS.get(budget.name, {})
        added = beyond(budget.name, seeds)
        shipped = shipped_finished(args.shipped)
        specs = queue(budget.name, tuple(args.only or DEFAULT_ONLY), shipped, seeds)
        for spec in specs:
            spec.config(overrides)  # a bad setting or seed
    except (ValueError, ReproduceError) as exc:
        parser.error(str(exc))

    # the seeds beyond the budget's that this queue trains, not the whole plan (`--only` and
    # the runs shipped leave some out)
    queued = {(spec.experiment, spec.seed) for spec in specs}
    beyond_text = "; ".join(
        f"{name} seed{'s' * (len(shown) > 1)} {', '.join(map(str, shown))}"
        for name, extra in added.items()
        if (shown := [seed for seed in extra if (name, seed) in queued])
    )
    print(
        f"curious from {Path(curious.__file__).parent}; {len(specs)} runs queued"
        + (f" (beyond the budget's: {beyond_text})" if beyond_text else ""),
        flush=True,
    )
    for spec in specs:
        print(f"  {spec.relative_path} ({spec.total_episodes:,} episodes)", flush=True)
    if args.dry_run:
        return 0
    # a phase that queues fewer seeds (`--seeds none`) keeps the plan an earlier one recorded;
    # read here, not left to `_write_manifest`, whose copy at the campaign's commits drops it
    plan = recorded_seeds(layout)
    for name, extra in added.items():
        plan[name] = tuple(dict.fromkeys(plan.get(name, ()) + extra))
    _write_manifest(layout, budget)
    record_seeds(layout, plan)
    if args.plan_only:
        return 0
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
