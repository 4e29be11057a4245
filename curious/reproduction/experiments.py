"""What `curious reproduce` trains: the paper's experiments, per budget.

An *experiment* is a set of training runs that one group of figures compares:

* `main` (paper Fig. 2, Table 1): `curious`, `mg-te` and `her` on the default variant
  (4 achievable modules + 3 distractors);
* `distractors`: `curious` against `m-uvfa` (uniform module selection and replay) with 0, 4 and
  7 distracting modules (suite variants `distractors_0`, `distractors_4`, `distractors_7`);
* `sensor_failure`: `curious` against `m-uvfa` on the `sensor_failure` variant (the authors'
  perturbation study: cube 3's observed x reads 5 cm too far, in the state and in push_cube3's
  outcome). The failure starts when push_cube3's competence first reaches a threshold
  (`sensor_failure_competence`), so that it perturbs a module that was learned, whatever the
  budget; the `paper` budget starts it at the authors' fixed epoch instead, and `smoke` at a
  fixed episode, so that the pipeline's tests see a failure start. Where the threshold is not
  reached the report says so instead of measuring a recovery. The `quick` budget leaves this
  experiment out, as the failure did not start in a measured quick reproduction
  (`ReproduceBudget.omitted` gives the reason; the report, a notebook and `select` repeat it).
* `sensor_failure_mastered`: the same conditions and variant, the failure waiting for
  push_cube3's competence to reach `MASTERED_COMPETENCE` (0.9, the threshold of mastery the
  agent and the analysis read), so that it perturbs a mastered module, as the authors did;
  read by the rules docs/results.md fixed before its runs (C5,
  "The study as it will be rerun"): the recovery of push_cube3's test success, CURIOUS against
  M-UVFA (`curious.analysis.recovery_by_tests`). `laptop` trains it on runs long enough for the
  module to be mastered; `smoke` starts it at a fixed episode, as `sensor_failure`'s; `quick` is
  too short for mastery and `paper`'s `sensor_failure` already starts long after it, so both
  leave it out.
* `long` (paper Fig. 2b-c over the paper's episode count): CURIOUS alone on the default
  variant, as in `main`, for 300,000 episodes (the paper's), so that a mastered module has the
  time the paper's Fig. 2b gives it to be forgotten (its drop came near episode 250,000, beyond
  `main`'s 100,000 at `laptop`); read by the drop and dip rules docs/results.md (C3) fixed
  before its runs. `laptop` trains it; `paper`'s `main` already trains CURIOUS that long, and
  `quick` is three hundred times too short, so both leave it out.

A plugin (`curious.plugins`) adds an experiment of its own with `register_experiment`: its runs
at the budgets it names, its figures registered for it (`curious.reproduction.figures`), its
section of the report those figures.

A *run* (`RunSpec`) is one condition, one variant and one seed: one run folder, and one Dagster
partition. Partitions are two-dimensional (Dagster's multi-partitions take exactly two axes):
`condition` x `seed`. Where an experiment trains several variants its condition axis carries the
variant as well: `curious@distractors_4`.

A *budget* (`curious reproduce --budget NAME`) chooses the training preset
(`curious.presets.PRESETS`, what `curious train --preset` takes), the seeds and the episodes per
run of every experiment:

=========  ===============================================================================
`smoke`    seconds per run, for the tests: every figure and the report built from tiny runs
`quick`    the README's job: `main` and `distractors`, short runs (README)
`laptop`   four to nine days on 2 cores (hours on a workstation or a Ray cluster)
`paper`    the authors' protocol, 5 seeds: for a cluster (`--ray-address`) or GPUs
=========  ===============================================================================

The numbers behind `quick` were measured on a 2-core machine; see `ReproduceBudget.notes`.

This module is in `curious`, not in `pipelines/`, although the Dagster assets are its main
readers: `curious progress` (`curious.reproduction.campaign_progress`) lists the runs a
reproduction's budget has not started from it, and `curious reproduce` builds its `--budget`
choices and help from it without loading Dagster. `pipelines/` imports it; of `curious`, only
the command line, the layer above `pipelines/`, imports `pipelines/` (docs/architecture.md).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from fractions import Fraction
from pathlib import PurePosixPath
from typing import Any

from curious.agent.learning_progress import MASTERED_COMPETENCE
from curious.config import LEARNED_COMPETENCE, Config
from curious.presets import PRESETS, resolve
from curious.registry import condition_names

EXPERIMENTS: tuple[str, ...] = (
    "main",
    "distractors",
    "sensor_failure",
    "sensor_failure_mastered",
    "long",
    "lp_uses",
    "signed_lp",
)
"""The built-in experiments' names, in the order they are trained and reported: the paper's
(`long`, the longest runs by far, last of them), then those beyond the paper (`BEYOND_PAPER`);
`experiment_names` adds the registered ones."""

BEYOND_PAPER: tuple[str, ...] = ("lp_uses", "signed_lp")
"""The experiments that ask what the paper does not (docs/results.md, "Beyond the paper"):
trained after the paper's, and captioned as not the paper's."""

REGISTERED_EXPERIMENTS: list[str] = []
"""Experiments added by `register_experiment` (a plugin's), after the built-in ones."""


def experiment_names() -> tuple[str, ...]:
    """Every experiment's name, in the order they are trained and reported: the built-in ones
    (`EXPERIMENTS`), then the registered ones."""
    return (*EXPERIMENTS, *REGISTERED_EXPERIMENTS)


_EXPERIMENT_FIELDS = frozenset(
    {"variant", "total_episodes", "sensor_failure_episode", "sensor_failure_competence"}
)
"""The `Config` fields an `Experiment` sets from its own fields, never through `overrides`."""

VARIANT_SEPARATOR = "@"
"""Joins condition and variant on the condition axis of experiments with several variants."""


class ExperimentError(ValueError):
    """An unknown budget or experiment, or a bad experiment definition."""


@dataclass(frozen=True)
class RunSpec:
    """One training run of an experiment: a condition, a variant and a seed."""

    experiment: str
    condition: str
    variant: str
    seed: int
    train_preset: str
    total_episodes: int
    sensor_failure_episode: int | None = None
    sensor_failure_competence: float | None = None
    variant_in_key: bool = False
    """Whether the condition axis names the variant (experiments with several variants)."""
    overrides: tuple[tuple[str, Any], ...] = ()
    """The experiment's settings beyond the preset (`Experiment.overrides`), as (name, value)."""

    @property
    def condition_key(self) -> str:
        """The run's value on the condition axis: `curious`, or `curious@distractors_4`."""
        if self.variant_in_key:
            return f"{self.condition}{VARIANT_SEPARATOR}{self.variant}"
        return self.condition

    @property
    def seed_key(self) -> str:
        return str(self.seed)

    @property
    def partition_key(self) -> str:
        """Dagster's string for the multi-partition key (`condition|seed`)."""
        return f"{self.condition_key}|{self.seed_key}"

    @property
    def relative_path(self) -> PurePosixPath:
        """Where the run folder lies below the runs root: `<experiment>/<condition>/seed-<s>`."""
        return PurePosixPath(self.experiment, self.condition_key, f"seed-{self.seed}")

    @property
    def label(self) -> str:
        """A short human name, e.g. `distractors: curious@distractors_4 seed 0`."""
        return f"{self.experiment}: {self.condition_key} seed {self.seed}"

    def config(self, overrides: Mapping[str, Any] | None = None) -> Config:
        """The resolved training config of this run (`overrides` change single settings)."""
        values: dict[str, Any] = {
            "variant": self.variant,
            "total_episodes": self.total_episodes,
            "progress": False,
        }
        if self.sensor_failure_episode is not None:
            values["sensor_failure_episode"] = self.sensor_failure_episode
        if self.sensor_failure_competence is not None:
            values["sensor_failure_competence"] = self.sensor_failure_competence
        values.update(self.overrides)
        values.update(overrides or {})
        return resolve(self.train_preset, self.condition, self.seed, values)


@dataclass(frozen=True)
class Experiment:
    """One experiment of a budget: what is trained, and for how long."""

    name: str
    title: str
    conditions: tuple[str, ...]
    variants: tuple[str, ...]
    seeds: tuple[int, ...]
    total_episodes: int
    train_preset: str
    sensor_failure_episode: int | None = None
    """The first episode run with the sensory failure (a fixed onset), or None."""
    sensor_failure_competence: float | None = None
    """The perturbed module's competence at which the failure starts, or None."""
    compare: tuple[str, str] | None = None
    """(better, worse): the pair of conditions of the one-tailed Welch tests in the report."""
    left_out_variants: tuple[str, ...] = ()
    """The budget's variants of this experiment that it lacks (`with_variants`): a shipped data
    folder that holds only some variants' runs finished stands for those alone."""
    extra_seeds: tuple[int, ...] = ()
    """The seeds among `seeds` that are not the budget's (`with_seeds`): runs of the same
    protocol trained beyond it (a campaign that adds seeds), which a shipped data folder or a
    campaign's output folder holds."""
    left_out_seeds: tuple[int, ...] = ()
    """The budget's seeds of this experiment that it lacks (`with_seeds_only`): a shipped data
    folder that holds every run finished for some seeds only (a campaign part-way through an
    experiment) stands for those alone."""
    overrides: tuple[tuple[str, Any], ...] = ()
    """Settings of every run beyond the preset's, as (name, value) pairs of `Config` fields, e.g.
    `(("lp_measure", "signed"),)`: a protocol that differs from another in one setting. The
    fields an experiment sets itself (variant, episodes, the sensory failure) are not among
    them."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or any(c in self.name for c in "@|/,"):
            raise ExperimentError(f"an experiment's name is one word, got {self.name!r}")
        unknown = [c for c in self.conditions if c not in condition_names()]
        if unknown or not self.conditions:
            raise ExperimentError(f"{self.name}: unknown or no conditions {unknown}")
        if not self.variants or not self.seeds:
            raise ExperimentError(f"{self.name}: needs at least one variant and one seed")
        if len(set(self.seeds)) != len(self.seeds) or min(self.seeds) < 0:
            raise ExperimentError(f"{self.name}: seeds must be distinct and >= 0: {self.seeds}")
        if self.train_preset not in PRESETS:
            raise ExperimentError(f"{self.name}: unknown training preset {self.train_preset!r}")
        if self.total_episodes <= 0:
            raise ExperimentError(f"{self.name}: total_episodes must be > 0")
        p, c = self.sensor_failure_episode, self.sensor_failure_competence
        if p is not None and not 0 < p < self.total_episodes:
            raise ExperimentError(
                f"{self.name}: sensor_failure_episode {p} must lie inside the run "
                f"(0 < episode < {self.total_episodes})"
            )
        if c is not None and not 0 < c <= 1:
            raise ExperimentError(f"{self.name}: sensor_failure_competence {c} is not in (0, 1]")
        if p is not None and c is not None:
            raise ExperimentError(
                f"{self.name}: set sensor_failure_episode or sensor_failure_competence, not both"
            )
        if self.compare is not None and not set(self.compare) <= set(self.conditions):
            raise ExperimentError(f"{self.name}: compares {self.compare} outside its conditions")
        if set(self.left_out_variants) & set(self.variants):
            raise ExperimentError(f"{self.name}: variants both kept and left out")
        if not set(self.extra_seeds) <= set(self.seeds):
            raise ExperimentError(
                f"{self.name}: extra seeds {self.extra_seeds} not among its seeds"
            )
        if set(self.left_out_seeds) & set(self.seeds):
            raise ExperimentError(f"{self.name}: seeds both kept and left out")
        names = [name for name, _ in self.overrides]
        if len(set(names)) != len(names):
            raise ExperimentError(f"{self.name}: a setting overridden twice: {names}")
        if owned := sorted(set(names) & _EXPERIMENT_FIELDS):
            raise ExperimentError(
                f"{self.name}: overrides {owned}, which the experiment's own fields set"
            )
        if unknown := sorted(set(names) - {f.name for f in fields(Config)}):
            raise ExperimentError(f"{self.name}: overrides unknown setting(s) {unknown}")

    @property
    def condition_keys(self) -> tuple[str, ...]:
        """Values of the partition's condition axis, in order."""
        return tuple(dict.fromkeys(run.condition_key for run in self.runs()))

    @property
    def seed_keys(self) -> tuple[str, ...]:
        return tuple(str(s) for s in self.seeds)

    def runs(self) -> list[RunSpec]:
        """Every run of the experiment, seed by seed (each seed's variants, then conditions).

        `curious reproduce` trains them in this order, so a campaign stopped part-way holds the
        same seeds of every condition: a comparison, not three seeds of one condition.
        """
        several = len(self.variants) + len(self.left_out_variants) > 1
        return [
            RunSpec(
                experiment=self.name,
                condition=condition,
                variant=variant,
                seed=seed,
                train_preset=self.train_preset,
                total_episodes=self.total_episodes,
                sensor_failure_episode=self.sensor_failure_episode,
                sensor_failure_competence=self.sensor_failure_competence,
                variant_in_key=several,
                overrides=self.overrides,
            )
            for seed in self.seeds
            for variant in self.variants
            for condition in self.conditions
        ]

    def with_variants(self, variants: Iterable[str]) -> Experiment:
        """This experiment with `variants` only (kept in its order), the others left out
        (`left_out_variants`). Its runs keep the whole experiment's paths and partition keys
        (`curious@distractors_7`), so that they name the same run folders."""
        wanted = set(variants)
        if unknown := sorted(wanted - set(self.variants)):
            raise ExperimentError(
                f"{self.name}: no variant(s) {unknown}; its variants: {', '.join(self.variants)}"
            )
        if not wanted:
            raise ExperimentError(f"{self.name}: keep at least one variant")
        kept = tuple(v for v in self.variants if v in wanted)
        dropped = tuple(v for v in self.variants if v not in wanted)
        return replace(self, variants=kept, left_out_variants=self.left_out_variants + dropped)

    def with_seeds(self, seeds: Iterable[int]) -> Experiment:
        """This experiment with `seeds` added after its own (in the order given, those it has
        already left out), named in `extra_seeds`: their runs are the budget's in every setting
        but the seed, so that they extend its comparison rather than start another."""
        added = tuple(dict.fromkeys(int(s) for s in seeds if int(s) not in self.seeds))
        if not added:
            return self
        return replace(self, seeds=self.seeds + added, extra_seeds=self.extra_seeds + added)

    def with_seeds_only(self, seeds: Iterable[int]) -> Experiment:
        """This experiment with `seeds` only (kept in its order); the budget's others are left
        out (`left_out_seeds`), extra ones dropped. Its runs keep their paths and partition
        keys, so that they name the same run folders."""
        wanted = {int(s) for s in seeds}
        if unknown := sorted(wanted - set(self.seeds)):
            raise ExperimentError(
                f"{self.name}: no seed(s) {unknown}; its seeds: {', '.join(map(str, self.seeds))}"
            )
        if not wanted:
            raise ExperimentError(f"{self.name}: keep at least one seed")
        dropped = tuple(s for s in self.budget_seeds if s not in wanted)
        return replace(
            self,
            seeds=tuple(s for s in self.seeds if s in wanted),
            extra_seeds=tuple(s for s in self.extra_seeds if s in wanted),
            left_out_seeds=tuple(sorted(self.left_out_seeds + dropped)),
        )

    @property
    def budget_seeds(self) -> tuple[int, ...]:
        """Its seeds less `extra_seeds`: the budget's own that it holds."""
        return tuple(s for s in self.seeds if s not in self.extra_seeds)

    def run(self, partition_key: str) -> RunSpec:
        """The run of a partition key (`condition|seed`), with a clear error for a stranger."""
        for spec in self.runs():
            if spec.partition_key == partition_key:
                return spec
        raise ExperimentError(
            f"experiment {self.name!r} has no partition {partition_key!r}; partitions: "
            + ", ".join(s.partition_key for s in self.runs())
        )

    @property
    def episodes(self) -> int:
        """Episodes trained in all of the experiment's runs together."""
        return self.total_episodes * len(self.runs())

    @property
    def perturbed(self) -> bool:
        """Whether its runs have a sensory failure (at an episode, or once a competence)."""
        return self.sensor_failure_episode is not None or self.sensor_failure_competence is not None

    @property
    def sensor_failure_text(self) -> str:
        """When the sensory failure starts, in words ("–" without one)."""
        if self.sensor_failure_episode is not None:
            return f"at episode {self.sensor_failure_episode:,}"
        if self.sensor_failure_competence is not None:
            return (
                f"when the perturbed module's competence reaches {self.sensor_failure_competence:g}"
            )
        return "–"


@dataclass(frozen=True)
class ReproduceBudget:
    """A budget: the experiments, seeds and episodes `curious reproduce --budget NAME` trains."""

    name: str
    description: str
    experiments: Mapping[str, Experiment]
    notes: str = ""
    """Where the budgets come from (measured timings) and what the figures can show."""
    caption_note: str = ""
    """A sentence ending every figure's caption (how the budget compares with the paper's); each
    figure's own ending is `caption_note_for` its experiment."""
    default_out: str = field(default="")
    per_experiment_note: str = ""
    """Where set, each figure's caption ends with its own experiment's episodes per run against
    the paper's (`PAPER_EPISODES`) instead of `caption_note`, after this text (the budget's
    preset, e.g. "Budget laptop"); the `laptop` budget's experiments differ in length."""
    omitted: Mapping[str, str] = field(default_factory=dict)
    """Experiment name -> why this budget leaves it out (a clause, no final period), told by the
    report, the notebooks and `select`. Every experiment is either trained or has a reason here."""

    def caption_note_for(self, experiment: Experiment) -> str:
        """`caption_note`, and how many seeds `experiment` reads where the `paper` budget trains
        more: computed, since seeds beyond the budget's (data/laptop's main) can bring it level."""
        note = self.caption_note
        if self.per_experiment_note:
            note = _length_note(self.per_experiment_note, experiment)
        paper = BUDGETS["paper"].experiments.get(experiment.name)
        if not note or paper is None or len(experiment.seeds) >= len(paper.seeds):
            return note
        n = len(experiment.seeds)
        trains = len(paper.seeds)
        return f"{note} {n} seed{'s' if n != 1 else ''} where the `paper` budget trains {trains}."

    def __post_init__(self) -> None:
        names = experiment_names()
        if tuple(self.experiments) != tuple(e for e in names if e in self.experiments):
            raise ExperimentError(
                f"{self.name}: experiments out of order: {tuple(self.experiments)}"
            )
        for key, experiment in self.experiments.items():
            if key != experiment.name:
                raise ExperimentError(f"{self.name}: experiment {key!r} is named {experiment.name}")
        for name in names:
            trained, reason = name in self.experiments, self.omitted.get(name)
            if trained == (reason is not None) or reason == "":
                raise ExperimentError(
                    f"{self.name}: experiment {name!r} must be either trained or omitted with a "
                    "reason"
                )
        if strangers := sorted(set(self.omitted) - set(names)):
            raise ExperimentError(f"{self.name}: omits unknown experiment(s) {strangers}")
        if not self.default_out:
            object.__setattr__(self, "default_out", f"runs/{self.name}")

    def select(self, names: Iterable[str] | None = None) -> list[Experiment]:
        """The experiments called `names` (all when None), in the canonical order."""
        if names is None:
            return list(self.experiments.values())
        wanted = [n.strip() for n in names if n.strip()]
        if not wanted:
            raise ExperimentError(f"no experiment named; choose from {', '.join(self.experiments)}")
        left_out = [n for n in wanted if n in self.omitted]
        if left_out:
            name = left_out[0]
            raise ExperimentError(
                f"budget {self.name!r} has no {name} experiment (budgets with it: "
                f"{', '.join(budgets_with(name))}): {self.omitted[name]}"
            )
        unknown = [n for n in wanted if n not in self.experiments]
        if unknown:
            raise ExperimentError(
                f"unknown experiment(s) {', '.join(map(repr, unknown))}; "
                f"budget {self.name!r} has {', '.join(self.experiments)}"
            )
        return [e for name, e in self.experiments.items() if name in wanted]

    def runs(self, names: Iterable[str] | None = None) -> list[RunSpec]:
        return [run for experiment in self.select(names) for run in experiment.runs()]

    def why_absent(self, name: str) -> str:
        """Why an output folder of this budget has no runs of experiment `name`, in a sentence."""
        if name in self.omitted:
            return f"Budget `{self.name}` leaves out the `{name}` experiment: {self.omitted[name]}."
        return (
            f"The `{name}` experiment has not been reproduced yet: run "
            f"`curious reproduce --budget {self.name} --experiments {name}`."
        )


def _main(train_preset: str, seeds: Sequence[int], episodes: int) -> Experiment:
    return Experiment(
        name="main",
        title="Main comparison: CURIOUS, MG-TE and HER (paper Fig. 2, Table 1)",
        conditions=("curious", "mg-te", "her"),
        variants=("default",),
        seeds=tuple(seeds),
        total_episodes=episodes,
        train_preset=train_preset,
        compare=("curious", "mg-te"),
    )


def _distractors(train_preset: str, seeds: Sequence[int], episodes: int) -> Experiment:
    return Experiment(
        name="distractors",
        title="Distracting modules: CURIOUS against M-UVFA with 0, 4 and 7 distractors",
        conditions=("curious", "m-uvfa"),
        variants=("distractors_0", "distractors_4", "distractors_7"),
        seeds=tuple(seeds),
        total_episodes=episodes,
        train_preset=train_preset,
        compare=("curious", "m-uvfa"),
    )


PAPER_FAILURE_EPISODE = 250 * 950
"""The authors' onset: the start of epoch 250 (of 316) at 950 episodes an epoch, 237,500
(their train.py switches the bias on when `epoch == 250` in the perturbation study)."""


SENSOR_FAILURE_TITLES: dict[str, str] = {
    "sensor_failure": "Sensory failure: CURIOUS against M-UVFA, refocus and recovery",
    "sensor_failure_mastered": "Sensory failure on a mastered module: CURIOUS against M-UVFA, "
    "recovery by test success",
}
"""The experiments of the `sensor_failure` variant, with their titles."""


def _sensor_failure(
    train_preset: str,
    seeds: Sequence[int],
    episodes: int,
    at: int | None = None,
    competence: float | None = None,
    name: str = "sensor_failure",
) -> Experiment:
    return Experiment(
        name=name,
        title=SENSOR_FAILURE_TITLES[name],
        conditions=("curious", "m-uvfa"),
        variants=("sensor_failure",),
        seeds=tuple(seeds),
        total_episodes=episodes,
        train_preset=train_preset,
        sensor_failure_episode=at,
        sensor_failure_competence=competence,
        compare=("curious", "m-uvfa"),
    )


LONG_EPISODES = 300_000
"""The `long` experiment's run length: the paper's (its Fig. 2 spans about 300,000 episodes,
316 epochs of 950 in the authors' release)."""


def _long(train_preset: str, seeds: Sequence[int], episodes: int) -> Experiment:
    return Experiment(
        name="long",
        title="Long CURIOUS runs: spontaneous forgetting over whole runs (paper Fig. 2b-c)",
        conditions=("curious",),
        variants=("default",),
        seeds=tuple(seeds),
        total_episodes=episodes,
        train_preset=train_preset,
    )


LP_USES_VARIANT = "distractors_7"
"""Where `lp_uses` reads LP's two uses apart: the `distractors` experiment's setting with the
widest gap between CURIOUS and M-UVFA, whose runs there it compares with."""


def _lp_uses(train_preset: str, seeds: Sequence[int], episodes: int) -> Experiment:
    return Experiment(
        name="lp_uses",
        title="Beyond the paper: LP's two uses apart, module selection and task replay, with 7 "
        "distracting modules",
        conditions=("lp-select", "lp-replay"),
        variants=(LP_USES_VARIANT,),
        seeds=tuple(seeds),
        total_episodes=episodes,
        train_preset=train_preset,
    )


def _signed_lp(mastered: Experiment) -> Experiment:
    """The study on a mastered module (`mastered`, a budget's `sensor_failure_mastered`) with
    CURIOUS alone and one setting changed: LP signed instead of the paper's absolute."""
    return replace(
        mastered,
        name="signed_lp",
        title="Beyond the paper: signed LP against the paper's absolute LP, sensory failure on a "
        "mastered module",
        conditions=("curious",),
        compare=None,
        overrides=(("lp_measure", "signed"),),
    )


PAPER_EPISODES: dict[str, int | None] = {
    "main": 300_000,
    "distractors": None,
    "sensor_failure": 300_000,
    "sensor_failure_mastered": 300_000,
    "long": 300_000,
    "lp_uses": None,
    "signed_lp": None,
}
"""Episodes per run in the authors' experiment each one reproduces, for the captions: Fig. 2's
runs (about 300,000, 316 epochs of 950 in their release), the sensory failure's (the same runs,
the failure switched on at epoch 250); the paper gives no budget for its distractors study, and
has no experiment of those beyond it (`BEYOND_PAPER`)."""

_FRACTIONS = {(1, 2): "half", (1, 3): "a third", (2, 3): "two thirds", (1, 4): "a quarter",
              (1, 5): "a fifth", (2, 5): "two fifths", (3, 5): "three fifths",
              (1, 6): "a sixth", (1, 10): "a tenth"}  # fmt: skip


def _length_note(prefix: str, experiment: Experiment) -> str:
    """``prefix``'s sentence on the experiment's episodes per run against the paper's."""
    n, paper = experiment.total_episodes, PAPER_EPISODES.get(experiment.name)
    if experiment.name in BEYOND_PAPER:
        return f"{prefix}: {n:,} episodes per run; an experiment beyond the paper's."
    if paper is None:
        return (
            f"{prefix}: {n:,} episodes per run; the paper gives no episode count for this "
            "experiment."
        )
    if n >= paper:
        return (
            f"{prefix}: {n:,} episodes per run, as many as the paper's runs, with the "
            f"`{experiment.train_preset}` preset's other reductions (fewer replayed transitions "
            "per stored one, a shorter competence window)."
        )
    share = Fraction(n, paper).limit_denominator(10)
    words = _FRACTIONS.get((share.numerator, share.denominator), f"{n / paper:.0%}")
    return f"{prefix} (reduced): {n:,} episodes per run, {words} of the paper's {paper:,}."


def _budget(
    name: str,
    description: str,
    notes: str,
    caption_note: str,
    *experiments: Experiment,
    omitted: Mapping[str, str] | None = None,
    per_experiment_note: str = "",
) -> ReproduceBudget:
    return ReproduceBudget(
        name,
        description,
        {e.name: e for e in experiments},
        notes,
        caption_note,
        per_experiment_note=per_experiment_note,
        omitted=dict(omitted or {}),
    )


QUICK_WITHOUT_FAILURE = (
    f"the failure starts once push_cube3's competence reaches {LEARNED_COMPETENCE:g}, "
    "and with 1,000 episodes a run it reached that in none of the 4 runs of a quick "
    "reproduction (2 conditions x 2 seeds): no failure started, so no recovery could be measured; "
    "`curious reproduce --budget laptop --experiments sensor_failure` trains it on longer runs"
)
"""Why the `quick` budget has no `sensor_failure` experiment: in a `quick` reproduction that
trained it (2 conditions x 2 seeds of 1,000 episodes) the failure started in none of the runs,
and the report found no recovery to measure (docs/benchmarks.md, "The quickstart's two
commands", has the measurement with its commit and date).
"""

QUICK_WITHOUT_MASTERY = (
    f"its failure waits for push_cube3's competence to reach {MASTERED_COMPETENCE:g}, which "
    f"1,000 episodes a run are far too short for (the quick runs did not reach "
    f"{LEARNED_COMPETENCE:g}); `curious reproduce --budget laptop --experiments "
    "sensor_failure_mastered` trains it"
)
"""Why the `quick` budget has no `sensor_failure_mastered` experiment."""

PAPER_WITHOUT_MASTERY = (
    "its `sensor_failure` experiment already perturbs a mastered module: the failure starts at "
    "the authors' epoch 250 (episode 237,500), long after push_cube3 is mastered"
)
"""Why the `paper` budget has no `sensor_failure_mastered` experiment."""

QUICK_WITHOUT_LONG = (
    f"its runs are {LONG_EPISODES:,} episodes each, the paper's, three hundred times a quick "
    "run (about half a day a run on 2 cores); `curious reproduce --budget laptop --experiments "
    "long` trains it"
)
"""Why the `quick` budget has no `long` experiment."""

PAPER_WITHOUT_LONG = (
    f"its `main` experiment already trains CURIOUS for {LONG_EPISODES:,} episodes (5 seeds), "
    "the length this experiment gives the `laptop` budget"
)
"""Why the `paper` budget has no `long` experiment."""


QUICK_WITHOUT_LP_USES = (
    "it reads LP's two uses apart where the `laptop` budget's runs of CURIOUS and M-UVFA part "
    "(with 7 distracting modules, push cube 1 learned after 30,000 episodes or more), far "
    "beyond a quick run's 1,000 episodes; `curious reproduce --budget laptop --experiments "
    "lp_uses` trains it"
)
"""Why the `quick` budget has no `lp_uses` experiment (docs/results.md, C4, has the episodes)."""

QUICK_WITHOUT_SIGNED_LP = (
    f"as in the study on a mastered module, its failure waits for push_cube3's competence to reach "
    f"{MASTERED_COMPETENCE:g}, which 1,000 episodes a run are far too short for; `curious "
    "reproduce --budget laptop --experiments signed_lp` trains it"
)
"""Why the `quick` budget has no `signed_lp` experiment."""


def _paper_without(name: str) -> str:
    """Why the `paper` budget has no experiment `name` of those beyond the paper."""
    return (
        "an experiment beyond the paper's, and the `paper` budget trains the authors' protocol "
        f"alone; `curious reproduce --budget laptop --experiments {name}` trains it"
    )


_laptop_mastered = _sensor_failure(
    "laptop", (0, 1, 2), 120_000, competence=MASTERED_COMPETENCE, name="sensor_failure_mastered"
)

BUDGETS: dict[str, ReproduceBudget] = {
    b.name: b
    for b in (
        _budget(
            "smoke",
            "seconds per run, for the tests: every figure and the report from tiny runs",
            "Training preset `smoke` (24 episodes, small networks). Curves are flat: the figures "
            "check that the pipeline works, not what the agent learns. The sensory failure "
            "starts at episode 12 (a fixed episode, so that a failure starts in the tests), where "
            "nothing has been learned: the report says there is nothing to forget.",
            "Budget smoke (for the tests): the curves check the pipeline, not what the agent "
            "learns.",
            _main("smoke", (0, 1), 24),
            _distractors("smoke", (0,), 24),
            _sensor_failure("smoke", (0,), 24, at=12),
            _sensor_failure("smoke", (0,), 24, at=12, name="sensor_failure_mastered"),
            _long("smoke", (0,), 24),
            _lp_uses("smoke", (0,), 24),
            _signed_lp(_sensor_failure("smoke", (0,), 24, at=12, name="sensor_failure_mastered")),
        ),
        _budget(
            "quick",
            "the README's job: 12 runs over two experiments (main, distractors; no sensory "
            "failure) of 1,000 episodes each",
            "Training preset `quick` (2 workers x 2 episodes and 20 updates of 256 per cycle). "
            "12 runs of 1,000 episodes over two experiments: main 3 conditions x 2 seeds, "
            "distractors 2 conditions x 3 settings x 1 seed; the sensory failure is left out "
            "(the `laptop` and `paper` budgets train it). One torch thread per run, 2 runs at a "
            "time. At this budget the agent learns reach and starts on push; the later modules, "
            "their phases and the effects of distractors need the `laptop` or `paper` budget.",
            "Budget quick (small): 1,000 episodes per run, 1/300 of the "
            "paper's; at this budget only the first modules are learned.",
            _main("quick", (0, 1), 1_000),
            _distractors("quick", (0,), 1_000),
            omitted={
                "sensor_failure": QUICK_WITHOUT_FAILURE,
                "sensor_failure_mastered": QUICK_WITHOUT_MASTERY,
                "long": QUICK_WITHOUT_LONG,
                "lp_uses": QUICK_WITHOUT_LP_USES,
                "signed_lp": QUICK_WITHOUT_SIGNED_LP,
            },
        ),
        _budget(
            "laptop",
            "four to nine days on 2 cores (hours on more, or with --ray-address)",
            "Training preset `laptop` (4 workers x 2 episodes and 40 updates of 512 per cycle). "
            "The 25 runs of data/laptop's main comparison, distractors and first sensory "
            "failure trained two at a time on 2-core machines, test rollouts included, at 6.8 "
            "to 8.6 episodes/s each on some and 1.9 to 4.1 on others (the slowest while other "
            "work shared the cores), so the budget's 4.62 M episodes take about 85 h on 2 cores "
            "at the faster pace and 210 h at the slower, a quarter of that on 8; the five long "
            "runs, 1.5 M of them, take most of it. The runs are "
            "independent: `--workers` runs them side by side, `--ray-address` across a cluster; "
            "an interrupted reproduction resumes.",
            "Budget laptop (reduced): 50,000 to 300,000 episodes per run by experiment, the "
            "paper's 300,000 in the long runs alone.",
            _main("laptop", (0, 1, 2), 100_000),
            _distractors("laptop", (0, 1), 50_000),
            _sensor_failure("laptop", (0, 1), 60_000, competence=LEARNED_COMPETENCE),
            _laptop_mastered,
            _long("laptop", (0, 1, 2, 3, 4), LONG_EPISODES),
            _lp_uses("laptop", (0, 1, 2), 50_000),
            _signed_lp(_laptop_mastered),
            per_experiment_note="Budget laptop",
        ),
        _budget(
            "paper",
            "the authors' protocol, 5 seeds: for a cluster (--ray-address) or GPUs",
            "Training preset `paper` (19 workers x 2 episodes x 25 cycles per epoch, 100 updates "
            "per cycle, ~300k episodes per run as in the paper). The sensory failure starts at "
            "episode 237,500, the start of the authors' epoch 250 of 316 (their release's "
            "perturbation study); the analysis still checks that push_cube3 was learned by then "
            "before it measures a recovery. The distractors and sensory-failure budgets are our "
            "choice (the 2018 paper does not give them).",
            "",
            _main("paper", (0, 1, 2, 3, 4), 300_000),
            _distractors("paper", (0, 1, 2, 3, 4), 300_000),
            _sensor_failure("paper", (0, 1, 2, 3, 4), 300_000, at=PAPER_FAILURE_EPISODE),
            omitted={
                "sensor_failure_mastered": PAPER_WITHOUT_MASTERY,
                "long": PAPER_WITHOUT_LONG,
                **{name: _paper_without(name) for name in BEYOND_PAPER},
            },
        ),
    )
}

DEFAULT_BUDGET = "quick"


def budgets_with(experiment: str) -> list[str]:
    """The names of the budgets that train `experiment`, in order."""
    return [name for name, budget in BUDGETS.items() if experiment in budget.experiments]


def register_experiment(
    by_budget: Mapping[str, Experiment], paper_episodes: int | None = None
) -> None:
    """Add an experiment (a plugin's, `curious.plugins`) to the budgets `by_budget` names: budget
    name -> the `Experiment` it trains there, all of one new name. Every other budget leaves it
    out, saying which budgets train it. From then on `curious reproduce --budget B` trains it
    with the rest (`--experiments NAME` alone), draws the figures registered for it
    (`curious.reproduction.figures`) and reports them; `paper_episodes`: the episodes of the
    paper's runs it stands for, for the captions (None: the paper gives none)."""
    wanted = dict(by_budget)
    if not wanted or not all(isinstance(e, Experiment) for e in wanted.values()):
        raise ExperimentError("register_experiment takes budget names -> Experiment, got none")
    names = {e.name for e in wanted.values()}
    if len(names) != 1:
        raise ExperimentError(f"register_experiment: one experiment a call, got {sorted(names)}")
    name = names.pop()
    if name in experiment_names():
        raise ExperimentError(f"an experiment named {name!r} is already registered")
    if unknown := sorted(set(wanted) - set(BUDGETS)):
        raise ExperimentError(f"{name}: unknown budget(s) {unknown}; budgets: {', '.join(BUDGETS)}")
    trained = ", ".join(f"`{b}`" for b in wanted)
    reason = f"it is trained at budget{'s' if len(wanted) > 1 else ''} {trained} only"
    REGISTERED_EXPERIMENTS.append(name)
    try:
        extended = {
            b: replace(budget, experiments={**budget.experiments, name: wanted[b]})
            if b in wanted
            else replace(budget, omitted={**budget.omitted, name: reason})
            for b, budget in BUDGETS.items()
        }
    except ExperimentError:
        REGISTERED_EXPERIMENTS.remove(name)
        raise
    BUDGETS.update(extended)
    PAPER_EPISODES[name] = paper_episodes


def get_budget(name: str) -> ReproduceBudget:
    """The budget called `name` (a clear error naming the known ones otherwise)."""
    if name not in BUDGETS:
        raise ExperimentError(f"unknown budget {name!r}; choose one of {', '.join(BUDGETS)}")
    return BUDGETS[name]


__all__ = [
    "BUDGETS",
    "DEFAULT_BUDGET",
    "EXPERIMENTS",
    "Experiment",
    "ExperimentError",
    "ReproduceBudget",
    "RunSpec",
    "budgets_with",
    "experiment_names",
    "get_budget",
    "register_experiment",
]
