"""Shipped runs in place of trained ones: `curious reproduce --from-data DATA`.

A shipped data folder (`curious.runs.shipped_folder`, written by `curious ship`) is laid
out as a
reproduction's runs root, so the pipeline reads it as one (`OutputLayout.runs_root`): the `runs`
asset checks that every partition's run is there and finished instead of training it, and the
metrics, figures and report are built from its tables as from any run folders. Nothing is ever
written into DATA.

A partition's state in DATA (`ShippedData.state`): `new` where the run was not shipped, `partial`
where it was shipped unfinished (a progress snapshot), `finished` where it was shipped finished.
A shipped run whose config.json names another run than the partition's (condition, variant,
seed, training preset, episodes, sensory failure) raises `RunFolderMismatch`. That check reads
the run's identity only (`RunInfo`, which reads every version of config.json), not every
setting as a resume does, so that runs shipped by an earlier curious stay readable when later
versions add settings.

An experiment of several variants whose runs DATA holds finished for some variants only stands
for those (`ShippedData.stands_for`): a campaign that trained `distractors_7` alone rebuilds the
distractors' figure and report for 7 distracting modules, and the report names the variants left
out. Likewise an experiment whose runs DATA holds finished for some of the budget's seeds only
(a campaign part-way through it) stands for those seeds, and the report names the seeds left out.
Seeds beyond the budget's count too: a seed of which DATA holds every run of an experiment
(each condition of each variant it stands for) shipped finished is added to the experiment
(`Experiment.with_seeds`), so that a campaign that trained seeds 3 and 4 of the main comparison
from the same protocol is read with all five, and the report says which seeds are beyond the
budget's. A seed shipped for some of those runs only is left out until the others are shipped.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path, PurePosixPath

from curious.reproduction.experiments import Experiment, ReproduceBudget, RunSpec
from curious.runs.folder import RunFolder
from curious.runs.folder_errors import RunFolderError
from curious.runs.shipped_folder import ShippedError, ShippedFolder, ShippedManifest
from pipelines.training import FINISHED, NEW, PARTIAL, RunFolderMismatch


class ShippedDataError(RuntimeError):
    """A shipped data folder that cannot stand for the runs asked for (nothing was written)."""


@dataclass(frozen=True)
class ShippedData:
    """A shipped data folder and its manifest, read once."""

    path: Path
    manifest: ShippedManifest

    @classmethod
    def open(cls, path: str | Path) -> ShippedData:
        """The shipped folder at `path`; a `ShippedDataError` where it is not one."""
        folder = ShippedFolder(Path(path).resolve())
        if folder.path.exists() and not folder.path.is_dir():
            raise ShippedDataError(
                f"--from-data {path} is a file, not a folder: name a shipped data folder "
                "(`curious ship`, e.g. data/laptop)"
            )
        if not folder.path.is_dir():
            raise ShippedDataError(f"--from-data {path} does not exist")
        try:
            data = cls(folder.path, folder.read_manifest())
        except ShippedError as exc:
            raise ShippedDataError(f"--from-data: {exc}") from None
        data.check_whole()
        return data

    def check_whole(self) -> None:
        """A `ShippedDataError`, before anything is written, where a run shipped.json lists is
        gone or has a file that cannot be read (a truncated copy, a bad merge): named with the
        way out, where later steps would fail on it in their own words."""
        for entry in self.manifest.runs:
            folder = RunFolder(ShippedFolder(self.path).run_path(entry.run))
            tables = [folder.metrics_path] + [folder.tests_path] * (entry.test_rollouts > 0)
            problem = None
            if not folder.path.is_dir():
                problem = "its folder is gone"
            else:
                try:
                    folder.read_info()
                except RunFolderError as exc:  # its own way out is a training run's
                    problem = str(exc).split("; ")[0]
                unreadable = None if problem else RunFolder.unreadable_table(tables)
                if unreadable is not None:
                    table, exc = unreadable
                    problem = f"its {table.name} cannot be read ({exc})"
            if problem is not None:
                raise ShippedDataError(
                    f"--from-data {self.path} is damaged: {entry.run}, which shipped.json lists: "
                    f"{problem}; restore the folder (`git checkout -- {self.path}` for the "
                    "repository's data) or ship it again"
                )

    def state(self, spec: RunSpec) -> str:
        """`new`, `partial` or `finished` (see the module docstring)."""
        entry = self.manifest.get(spec.relative_path)
        if entry is None:
            return NEW
        folder = RunFolder(ShippedFolder(self.path).run_path(entry.run))
        try:
            info = folder.read_info()
        except RunFolderError as exc:
            raise RunFolderMismatch(str(exc)) from None
        expected = {
            "condition": spec.condition,
            "variant": spec.variant,
            "seed": spec.seed,
            "preset": spec.train_preset,
            "total_episodes": spec.total_episodes,
            "sensor_failure_episode": spec.sensor_failure_episode,
            "sensor_failure_competence": spec.sensor_failure_competence,
        }
        shipped = {
            "condition": info.condition,
            "variant": info.variant,
            "seed": info.seed,
            "preset": info.preset,
            "total_episodes": info.total_episodes,
            "sensor_failure_episode": info.perturbation_episode,
            "sensor_failure_competence": info.failure_competence,
        }
        differ = [k for k in expected if expected[k] != shipped[k]]
        if differ:
            detail = ", ".join(f"{k}: {shipped[k]!r} != {expected[k]!r}" for k in differ)
            raise RunFolderMismatch(
                f"{folder.path} holds another run than {spec.label} ({detail}): it was not "
                "shipped from this budget's reproduction"
            )
        return FINISHED if entry.finished and entry.episodes >= spec.total_episodes else PARTIAL

    def missing(self, experiment: Experiment) -> list[str]:
        """The runs of `experiment` that DATA lacks or holds unfinished, in words."""
        out = []
        for spec in experiment.runs():
            state = self.state(spec)
            if state == NEW:
                out.append(f"{spec.relative_path} (not shipped)")
            elif state == PARTIAL:
                entry = self.manifest.get(spec.relative_path)
                assert entry is not None
                out.append(
                    f"{spec.relative_path} (shipped unfinished: {entry.episodes:,} of "
                    f"{spec.total_episodes:,} episodes)"
                )
        return out

    def check_budget(self, budget: ReproduceBudget) -> None:
        """A `ShippedDataError` where DATA was shipped from another budget's reproduction."""
        shipped = self.manifest.budget
        if shipped is not None and shipped != budget.name:
            raise ShippedDataError(
                f"{self.path} holds runs of budget {shipped!r}, not {budget.name!r}: pass "
                f"--budget {shipped}"
            )

    def stands_for(self, budget: ReproduceBudget) -> ReproduceBudget:
        """`budget` as DATA can stand for it: an experiment of several variants whose runs DATA
        holds finished for some variants only (a campaign that trained `distractors_7` alone) is
        cut to those variants (`Experiment.with_variants`, the others named as left out). One
        still lacking runs whose runs DATA holds finished for some seeds only (a campaign that
        shipped seed 0 of every condition) is cut to those seeds (`Experiment.with_seeds_only`,
        the others named as left out); every other experiment stays whole, and `select` says
        what it lacks. Then each experiment gets the seeds beyond the budget's whose runs (of
        the variants it stands for) DATA holds all finished (`extra_seeds`)."""
        experiments = {}
        for name, experiment in budget.experiments.items():
            if len(experiment.variants) > 1:
                complete = [
                    v
                    for v in experiment.variants
                    if not self.missing(experiment.with_variants([v]))
                ]
                if 0 < len(complete) < len(experiment.variants):
                    experiment = experiment.with_variants(complete)
            if self.missing(experiment):
                complete_seeds = [s for s in experiment.seeds if self._seed_complete(experiment, s)]
                if complete_seeds:
                    experiment = experiment.with_seeds_only(complete_seeds)
            extra = [s for s in self.seeds_beyond(experiment) if self._seed_complete(experiment, s)]
            experiments[name] = experiment.with_seeds(extra)
        return replace(budget, experiments=experiments)

    def _seed_complete(self, experiment: Experiment, seed: int) -> bool:
        """Whether DATA holds every run of `experiment` (its variants, each condition) with
        `seed` finished."""
        return not self.missing(_seed_alone(experiment, seed))

    def left_out_runs(self, experiment: Experiment) -> list[RunSpec]:
        """The finished runs DATA holds of the variants `experiment` leaves out
        (`Experiment.left_out_variants`), for each such variant that has at least one of every
        condition: runs too few for the experiment's statistics that its figure still draws
        (the distractors for 4 distracting modules, shipped for seed 0 alone), in partition
        order."""
        if not experiment.left_out_variants:
            return []
        others = replace(
            experiment,
            variants=experiment.left_out_variants,
            left_out_variants=experiment.variants,
            extra_seeds=(),
        )
        out = []
        for variant in others.variants:
            specs = [s for s in others.runs() if s.variant == variant and self.state(s) == FINISHED]
            if {s.condition for s in specs} == set(experiment.conditions):
                out += specs
        return out

    def _finished_seeds(self, experiment: Experiment) -> list[tuple[str, int]]:
        """(run, seed) of each run DATA holds finished in `experiment`'s folder, in DATA's
        order (the seed from the path's last part, `seed-<s>`)."""
        out = []
        for run in self.manifest.runs:
            parts = PurePosixPath(run.run).parts
            if run.finished and len(parts) == 3 and parts[0] == experiment.name:
                seed = parts[2].removeprefix("seed-")
                if parts[2].startswith("seed-") and seed.isdigit():
                    out.append((run.run, int(seed)))
        return out

    def seeds_beyond(self, experiment: Experiment) -> list[int]:
        """The seeds, in order, of the runs DATA holds finished in `experiment`'s folder that are
        neither among its seeds nor the budget's left out."""
        seeds = {seed for _, seed in self._finished_seeds(experiment)}
        return sorted(seeds - set(experiment.seeds) - set(experiment.left_out_seeds))

    def waiting_runs(self, experiment: Experiment) -> list[str]:
        """The runs DATA holds finished of the seeds beyond `experiment`'s that it does not read
        (`seeds_beyond`: a seed not yet shipped for every run of the experiment), in DATA's
        order: a campaign part-way through a seed, which the report names."""
        waiting = set(self.seeds_beyond(experiment))
        return [run for run, seed in self._finished_seeds(experiment) if seed in waiting]

    def awaited_runs(self, experiment: Experiment) -> list[str]:
        """What DATA lacks of the seeds whose runs `waiting_runs` names, in words (`missing`):
        the runs to ship before the report reads that seed."""
        return [
            gap
            for seed in self.seeds_beyond(experiment)
            for gap in self.missing(_seed_alone(experiment, seed))
        ]

    def select(self, budget: ReproduceBudget, names: Sequence[str] | None) -> list[Experiment]:
        """The experiments to build from DATA: those named (each complete in DATA, else a
        `ShippedDataError` naming what it lacks), or, with no names, every experiment of the
        budget that DATA holds complete (at least one)."""
        chosen = budget.select(names)
        if names is None:
            complete = [e for e in chosen if not self.missing(e)]
            if not complete:
                raise ShippedDataError(
                    f"{self.path} holds no experiment of budget {budget.name!r} whose runs are "
                    f"all shipped and finished ({self._lacks(chosen)})"
                )
            return complete
        lacking = [e for e in chosen if self.missing(e)]
        if lacking:
            raise ShippedDataError(
                f"{self.path} lacks runs of {', '.join(e.name for e in lacking)}: "
                f"{self._lacks(lacking)}; ship them once finished (`curious ship`), or leave "
                "those experiments out"
            )
        return chosen

    def _lacks(self, experiments: Sequence[Experiment]) -> str:
        gaps = [m for e in experiments for m in self.missing(e)]
        return ", ".join(gaps[:4]) + (f" and {len(gaps) - 4} more" if len(gaps) > 4 else "")


def _seed_alone(experiment: Experiment, seed: int) -> Experiment:
    """`experiment` with `seed` as its one seed (its variants and conditions kept)."""
    return replace(experiment, seeds=(seed,), extra_seeds=(), left_out_seeds=())
