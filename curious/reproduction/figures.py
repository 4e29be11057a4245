"""The figures a reproduction draws, by name: for each, the experiments whose runs it draws, how
it is drawn, what report.md says under it and whether the report shows it.

A figure is one `FigureSpec`, registered with `register_figure` (a decorator on its draw
function). The draw function takes an experiment's tables (`FigureInputs`) and returns a
matplotlib figure whose caption (`supxlabel`) names what it draws; the pipeline saves it as
``figures/<stem>.png`` and ``.svg`` (`FigureSpec.stem`) and the report places it with its text.
Adding a figure is its drawing code, one registered entry and its test (tests/test_figures.py
holds every registered figure to what it needs); a plugin's figure (`curious.plugins`) is drawn
and shown as a built-in one is.

Nothing heavy is imported here, so that registering a figure keeps `curious --help` light: the
draw functions import the analysis when they run.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

    from curious.reproduction.experiments import Experiment


@dataclass
class FigureInputs:
    """What a figure is drawn from: one experiment's runs, as the pipeline holds them."""

    experiment: Experiment
    metrics: pd.DataFrame
    """Every episode of the experiment's runs (`curious.analysis.load_runs`)."""
    folders: tuple[Path, ...]
    """The experiment's run folders, in its partition order."""
    shown_anyway: tuple[Path, ...]
    """Finished runs of variants the experiment leaves out (shipped data that holds them for
    every condition): drawn beside the others where a figure can, never tested."""
    note: str
    """The budget's sentence that ends every caption (`ReproduceBudget.caption_note_for`)."""
    out_dir: Path
    stem: str
    """The figure's file name without its suffix (`FigureSpec.stem`)."""
    load_tests: Callable[[], pd.DataFrame]
    written: dict[str, Path] = field(default_factory=dict)
    """Files the draw function wrote beside the figure (`side_file`), by suffix."""
    load_other: Callable[[str], tuple[pd.DataFrame | None, pd.DataFrame | None]] = lambda _name: (
        None,
        None,
    )
    """Another experiment's tables in the same reproduction, (metrics, tests), each None where
    it has none: what a figure that `FigureSpec.reads` it draws beside its own runs."""

    def other(self, name: str) -> tuple[pd.DataFrame | None, pd.DataFrame | None]:
        """Experiment `name`'s (metrics, tests) in this reproduction (None where absent)."""
        return self.load_other(name)

    def tests(self) -> pd.DataFrame:
        """The experiment's test rollouts (`curious.analysis.load_tests`); an `AnalysisError`
        where its runs have none."""
        return self.load_tests()

    def tests_if_any(self) -> pd.DataFrame | None:
        """The test rollouts, or None where the runs have none (the figure goes without)."""
        from curious.analysis import AnalysisError

        try:
            return self.load_tests()
        except AnalysisError:
            return None

    def side_file(self, suffix: str) -> Path:
        """``<out_dir>/<stem><suffix>``, for numbers written beside the figure (the report may
        read them); the pipeline lists it with the figure."""
        path = self.out_dir / f"{self.stem}{suffix}"
        self.written[suffix.lstrip(".")] = path
        return path


DrawFn = Callable[[FigureInputs], "Figure"]


@dataclass(frozen=True)
class FigureSpec:
    """One registered figure."""

    name: str
    experiments: tuple[str, ...]
    """The experiments whose runs it draws, once for each."""
    draw: DrawFn
    text: str
    """The report's sentence under the figure."""
    untested_text: str | None = None
    """The sentence instead where the runs have no test rollouts and the figure goes without its
    test panel (None: `text` holds either way)."""
    in_report: bool = True
    """Whether report.md shows it (it is drawn either way)."""
    reads: tuple[str, ...] = ()
    """Other experiments whose runs it draws beside its own (`FigureInputs.other`), e.g. the
    shipped runs a study compares its new conditions with; drawn after their tables."""

    def stem(self, experiment: str) -> str:
        """Its file name without suffix: the name, or ``<name>_<experiment>`` for a figure of
        several experiments."""
        return self.name if len(self.experiments) == 1 else f"{self.name}_{experiment}"

    def caption(self, tested: bool = True) -> str:
        """The report's sentence under it (`untested_text` where the runs have no tests)."""
        return self.text if tested or self.untested_text is None else self.untested_text


FIGURES: dict[str, FigureSpec] = {}
"""Every figure by name, the built-in ones first, in the order each experiment shows them (the
first of an experiment opens its section of the report)."""

_RESERVED = "@|/,<> \t\n"


def register_figure(
    name: str,
    experiments: tuple[str, ...] | list[str],
    text: str,
    untested_text: str | None = None,
    in_report: bool = True,
    reads: tuple[str, ...] | list[str] = (),
) -> Callable[[DrawFn], DrawFn]:
    """Register the decorated function as the draw function of figure `name`, drawn for each
    of `experiments` (`curious.reproduction.experiments`) and shown in report.md with `text`
    under it unless `in_report` is False; `reads`: other experiments whose tables it draws
    beside (`FigureInputs.other`)."""
    if not isinstance(name, str) or not name or any(c in name for c in _RESERVED):
        raise ValueError(f"a figure's name is one word without @, |, /, commas, got {name!r}")
    if isinstance(experiments, str):
        experiments = (experiments,)
    experiments = tuple(experiments)
    if not experiments or not all(isinstance(e, str) and e for e in experiments):
        raise ValueError(f"figure {name!r}: name the experiments it draws, got {experiments!r}")
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"figure {name!r}: give the report's text under it")

    def add(draw: DrawFn) -> DrawFn:
        if not callable(draw):
            raise TypeError(f"figure {name!r}: register_figure decorates a function, got {draw!r}")
        spec = FigureSpec(name, experiments, draw, text, untested_text, in_report, tuple(reads))
        if FIGURES.get(name, spec) != spec:
            raise ValueError(f"a figure named {name!r} is already registered")
        FIGURES[name] = spec
        return draw

    return add


def get_figure(name: str) -> FigureSpec:
    """The figure called `name`; a `ValueError` naming the registered ones otherwise."""
    if name not in FIGURES:
        raise ValueError(f"unknown figure {name!r}; figures: {', '.join(FIGURES)}")
    return FIGURES[name]


def figures_of(experiment: str, in_report: bool | None = None) -> tuple[FigureSpec, ...]:
    """The figures drawn for `experiment`, in registration order; with `in_report`, only those
    the report shows (True) or does not (False)."""
    return tuple(
        f
        for f in FIGURES.values()
        if experiment in f.experiments and (in_report is None or f.in_report == in_report)
    )


def check_figures(experiments: Iterable[str]) -> None:
    """A `ValueError` naming a registered figure drawn for an experiment not among
    `experiments` (a misspelt name would leave the figure never drawn)."""
    known = tuple(experiments)
    for spec in FIGURES.values():
        if strangers := [e for e in (*spec.experiments, *spec.reads) if e not in known]:
            raise ValueError(
                f"figure {spec.name!r} is drawn for unknown experiment(s) {', '.join(strangers)}; "
                f"experiments: {', '.join(known)}"
            )


# ----------------------------------------------------------------------- the built-in figures


def _of_curious(function: str) -> DrawFn:
    """Fig. 2b, 2c or Table 1 (`curious.analysis.<function>`) of the experiment's CURIOUS runs."""

    def draw(inputs: FigureInputs) -> Figure:
        from curious import analysis

        return getattr(analysis, function)(inputs.metrics, condition="curious", note=inputs.note)

    return draw


@register_figure(
    "fig2a",
    ("main",),
    "Average test success over the achievable modules per condition, in the episode bins of the "
    "statistics below (paper Fig. 2a).",
)
def _fig2a(inputs: FigureInputs) -> Figure:
    from curious import analysis

    compare = inputs.experiment.compare
    return analysis.fig2a(inputs.tests(), compare=compare, note=inputs.note)


register_figure(
    "fig2b", ("main",), "Competence of every module over one CURIOUS run (paper Fig. 2b)."
)(_of_curious("fig2b"))
register_figure(
    "fig2c",
    ("main",),
    "Absolute learning progress of every module over the same run (paper Fig. 2c).",
)(_of_curious("fig2c"))
register_figure(
    "table1", ("main",), "Competence and learning progress of every CURIOUS seed (paper Table 1)."
)(_of_curious("table1"))


@register_figure(
    "distractors",
    ("distractors",),
    "Self-evaluated competence (left) and test success (right) over the achievable modules at "
    "the end of the runs against the number of distracting modules.",
    untested_text="Self-evaluated competence over the achievable modules at the end of the runs "
    "against the number of distracting modules (the runs have no test rollouts: no test success "
    "panel).",
)
def _distractors(inputs: FigureInputs) -> Figure:
    from curious import analysis

    table, tests = inputs.metrics, None
    if inputs.shown_anyway:  # settings shipped with too few runs for the statistics: beside
        folders = [*inputs.folders, *inputs.shown_anyway]
        table = analysis.load_runs(folders)
        try:
            tests = analysis.load_tests(folders)
        except analysis.AnalysisError:  # runs without test rollouts: the competence panel alone
            tests = None
    else:
        tests = inputs.tests_if_any()
    return analysis.distractors(table, note=inputs.note, tests=tests)


def _sensor_failure(with_tests: bool) -> DrawFn:
    """The sensory-failure figure of one experiment of the variant, its per-run recovery
    written beside it (`<stem>.csv`, which the report reads); `with_tests`: its runs' test
    success drawn above (the primary measure of the study on a mastered module)."""

    def draw(inputs: FigureInputs) -> Figure:
        from curious import analysis

        tests = inputs.tests_if_any() if with_tests else None
        fig, per_run = analysis.sensor_failure(
            inputs.metrics, note=inputs.note, name=inputs.stem, tests=tests
        )
        csv = inputs.side_file(".csv")
        per_run.drop(columns=["run"]).to_csv(csv, index=False)  # exact: the report reads it
        return fig

    return draw


register_figure(
    "sensor_failure",
    ("sensor_failure",),
    "Competence and LP of the perturbed module around the sensory failure, one line per run.",
)(_sensor_failure(with_tests=False))
register_figure(
    "sensor_failure_mastered",
    ("sensor_failure_mastered",),
    "Test success, competence and LP of the perturbed module around the sensory failure, one "
    "line per run.",
    untested_text="Competence and LP of the perturbed module around the sensory failure, one "
    "line per run (the runs have no test rollouts: no test success panel).",
)(_sensor_failure(with_tests=True))


@register_figure(
    "long_runs",
    ("long",),
    "Competence and absolute LP of every module over each whole long run, one row per seed, the "
    "drops of mastered modules shaded (paper Fig. 2b-c).",
)
def _long_runs(inputs: FigureInputs) -> Figure:
    from curious import analysis

    dips = analysis.mastery_dips(inputs.metrics, analysis.TEST_DEPTH)
    return analysis.long_runs(inputs.metrics, dips=dips, note=inputs.note)


@register_figure(
    "lp_uses",
    ("lp_uses",),
    "Competence (left) and test success (middle) over the achievable modules at the end of each "
    "run, and the share of practice (solid) and of replay (dashed, the runs that kept their "
    "replay counts) on distracting modules over the runs (right): LP-select and LP-replay beside "
    "the `distractors` experiment's CURIOUS and M-UVFA runs of the same variant.",
    untested_text="Competence over the achievable modules at the end of each run (left), and the "
    "share of practice (solid) and of replay (dashed, the runs that kept their replay counts) on "
    "distracting modules over the runs (right): LP-select and LP-replay beside the "
    "`distractors` experiment's CURIOUS and M-UVFA runs of the same variant (the runs have no "
    "test rollouts: no test success panel).",
    reads=("distractors",),
)
def _lp_uses(inputs: FigureInputs) -> Figure:
    from curious import analysis

    metrics, tests = analysis.lp_uses_tables(
        inputs.metrics,
        inputs.tests_if_any(),
        *inputs.other("distractors"),
        inputs.experiment.variants[0],
    )
    learner = analysis.learner_of(metrics)
    return analysis.lp_uses(metrics, tests, note=inputs.note, learner=learner)


@register_figure(
    "signed_lp",
    ("signed_lp",),
    "Test success, competence and LP of the perturbed module around the sensory failure, one line "
    "per run: CURIOUS with signed LP beside the `sensor_failure_mastered` experiment's CURIOUS "
    "runs (absolute LP, the paper's).",
    untested_text="Competence and LP of the perturbed module around the sensory failure, one "
    "line per run: CURIOUS with signed LP beside the `sensor_failure_mastered` experiment's "
    "CURIOUS runs (the runs have no test rollouts: no test success panel).",
    reads=("sensor_failure_mastered",),
)
def _signed_lp(inputs: FigureInputs) -> Figure:
    from curious import analysis

    absolute, absolute_tests = inputs.other("sensor_failure_mastered")
    signed, signed_tests = inputs.metrics, inputs.tests_if_any()
    if absolute is not None and (absolute_tests is None or signed_tests is None):
        absolute_tests = signed_tests = None  # the test panel draws both measures, or neither
    fig, per_run = analysis.signed_lp(
        absolute, signed, absolute_tests, signed_tests, note=inputs.note, name=inputs.stem
    )
    per_run.drop(columns=["run"]).to_csv(inputs.side_file(".csv"), index=False)  # exact, as above
    return fig


BUILT_IN_FIGURES: tuple[str, ...] = tuple(FIGURES)
"""The figures curious itself draws."""
