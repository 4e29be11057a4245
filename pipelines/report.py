"""`report.md`: what a reproduction trained, its figures, and the statistics behind them.

The main comparison's numbers (final success, Welch tests) come from the test rollouts, as Fig.
2a's; the distractors' from the competence; the sensory failure's from `analysis.recovery`, which
reports a recovery only where the failure started and the perturbed module was learned before it;
the sensory failure on a mastered module's from the test rollouts first (`analysis.
recovery_by_tests`, with the Welch test of `analysis.compare_recoveries`), the competence second;
spontaneous forgetting (drops of a mastered module, `analysis.mastery_drops`) is read in the main
comparison and the distractors, whose runs nothing perturbs.

The report is a function of the budget, the combined metrics and test tables and the figures on
disk (nothing in it depends on when it was written), so rebuilding it from the same runs gives the
same bytes. An experiment appears once its metrics table exists, and one the budget leaves out
(`ReproduceBudget.omitted`) gets a sentence saying why; figures are linked relatively, so the
output folder can be moved or shared as a whole.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from curious import analysis
from curious.analysis.palette import condition_label, module_label
from curious.reproduction.experiments import (
    BUDGETS,
    FIGURES,
    Experiment,
    ReproduceBudget,
    get_budget,
)
from curious.runs.folder import RunFolder
from curious.runs.folder_errors import RunFolderError
from pipelines.resources import Reproduction

FIGURE_TEXT: dict[str, str] = {
    "fig2a": "Average test success over the achievable modules per condition, in the episode "
    "bins of the statistics below (paper Fig. 2a).",
    "fig2b": "Competence of every module over one CURIOUS run (paper Fig. 2b).",
    "fig2c": "Absolute learning progress of every module over the same run (paper Fig. 2c).",
    "table1": "Competence and learning progress of every CURIOUS seed (paper Table 1).",
    "distractors": "Self-evaluated competence (left) and test success (right) over the "
    "achievable modules at the end of the runs against the number of distracting modules.",
    "forgetting": "Competence and LP of the perturbed module around the sensory failure, one "
    "line per run.",
    "forgetting_mastered": "Test success, competence and LP of the perturbed module around the "
    "sensory failure, one line per run.",
}
ORDER_LEVEL = 0.5
"""The competence at which the order of learning counts a module as learned."""


@dataclass
class _Tables:
    """One experiment's combined tables: the metrics, and the test rollouts where the runs have
    them, with the test success points drawn from those once."""

    metrics: pd.DataFrame
    tests: pd.DataFrame | None

    @functools.cached_property
    def points(self) -> pd.DataFrame | None:
        """`analysis.epoch_success` of the test rollouts (None without them)."""
        return None if self.tests is None else analysis.epoch_success(self.tests)


def _fmt(value: float, digits: int = 2) -> str:
    return "–" if value is None or not math.isfinite(float(value)) else f"{value:.{digits}f}"


def _mean_std(values: Sequence[float]) -> str:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return "–"
    if v.size == 1:
        return f"{v[0]:.2f} (1 seed)"
    return f"{v.mean():.2f} ± {v.std(ddof=1):.2f} ({v.size} seeds)"


def _table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return [*lines, ""]


def _figure(repro: Reproduction, name: str) -> list[str]:
    png = repro.layout.figures / f"{name}.png"
    if not png.is_file():
        return [f"*Figure `{name}` has not been drawn yet.*", ""]
    rel = png.relative_to(repro.layout.out).as_posix()
    svg = Path(rel).with_suffix(".svg").as_posix()
    return [f"![{name}]({rel})", "", f"{FIGURE_TEXT[name]} ([SVG]({svg}))", ""]


def _seeds(e: Experiment) -> str:
    """An experiment's seeds, with those beyond the budget's named."""
    seeds = ", ".join(map(str, e.seeds))
    if not e.extra_seeds:
        return seeds
    return f"{seeds} ({len(e.seeds)}; {', '.join(map(str, e.extra_seeds))} beyond the budget's)"


def _budgets(repro: Reproduction, experiments: list[Experiment]) -> list[str]:
    rows = []
    for e in experiments:
        config = e.runs()[0].config(repro.overrides)
        rows.append(
            (
                e.name,
                ", ".join(e.conditions),
                ", ".join(e.variants),
                _seeds(e),
                f"{e.total_episodes:,}",
                e.sensor_failure_text,
                f"`{e.train_preset}`: {config.n_workers} workers x {config.episodes_per_worker} "
                f"episodes, {config.n_updates} updates of {config.batch_size} per cycle",
                len(e.runs()),
            )
        )
    header = (
        "experiment",
        "conditions",
        "variants",
        "seeds",
        "episodes per run",
        "sensory failure starts",
        "training preset",
        "runs",
    )
    return _table(header, rows)


def _machines(runs: Iterable[object]) -> tuple[list[str], int]:
    """The machines the runs trained on (their config.json), and how many runs record none."""
    found: dict[str, None] = {}
    unrecorded = 0
    for run in runs:
        try:
            machines = RunFolder(str(run)).read_info().machines
        except RunFolderError:
            machines = ()
        found.update(dict.fromkeys(machines))
        unrecorded += not machines
    return sorted(found), unrecorded


def _compute(tables: dict[str, pd.DataFrame]) -> list[str]:
    """How long the runs trained, read off their own clocks (`wall_time`, seconds of training
    since each run started, resumes included), in all and per experiment with the machines."""
    per_experiment = {
        name: t.groupby("run", observed=True)["wall_time"].max() for name, t in tables.items()
    }
    walls = pd.concat(per_experiment.values())
    if walls.empty:
        return []
    lines = [
        f"Training time, from the runs' own clocks: {len(walls)} runs, "
        f"{walls.sum() / 60:,.1f} run-minutes in all, {walls.min() / 60:.1f} to "
        f"{walls.max() / 60:.1f} min per run (runs that share a machine's cores slow each "
        "other; the test rollouts after the last training episode are not counted).",
        "",
    ]
    for name, wall in per_experiment.items():
        machines, unrecorded = _machines(wall.index)
        where = f"on {'; '.join(machines)}" if machines else "machine not recorded"
        if machines and unrecorded:
            where += f" ({unrecorded} of the runs do not record theirs)"
        lines.append(f"- `{name}`: {len(wall)} runs, {wall.sum() / 3600:,.2f} run-hours, {where}.")
    return [*lines, ""]


def _runs_table(tables: _Tables) -> list[str]:
    """One row per run; its final competence and, with test rollouts, its final test success."""
    table, points = tables.metrics, tables.points
    runs = analysis.runs_table(table)
    final = analysis.final_competence(table).set_index("run")["value"]
    tested = analysis.final_success(points).set_index("run") if points is not None else None
    wall = table.groupby("run", observed=True)["wall_time"].max()
    rows = []
    for _, r in runs.sort_values(["variant", "condition", "seed"]).iterrows():
        folder = Path(str(r["run"]))
        row = [
            "/".join(folder.parts[-3:]),
            r["condition"],
            r["variant"],
            r["seed"],
            f"{int(r['n_episodes']):,}",
            f"{wall[r['run']] / 60:.1f}",
            _fmt(final[r["run"]]),
        ]
        if tested is not None:
            row.append(_tested_cell(tested, r["run"]))
        rows.append(row)
    header = [
        "run folder",
        "condition",
        "variant",
        "seed",
        "episodes",
        "wall time (min)",
        "final competence",
    ]
    if tested is not None:
        header.append("test success at the last epoch (test rollouts)")
    return _table(header, rows)


def _tested_cell(tested: pd.DataFrame, run: object) -> str:
    """A run's test success at the last epoch with the rollouts behind it: an epoch tests a
    few episodes on the achievable modules (fewer, the more distracting modules share the draw),
    so the count says how far to trust the rate."""
    if run not in tested.index:
        return "–"
    value, n = tested.at[run, "value"], tested.at[run, "n_tests"]
    return f"{_fmt(value)} ({int(n)})"


def _final_by_condition(e: Experiment, numbers: dict) -> list[str]:
    """The test success of each condition in the last bin of `analysis.main_comparison`."""
    final = numbers["final"]
    episodes = int(final["episodes"].max())
    parts = [
        f"{condition_label(c)} {_mean_std(final.loc[final['condition'] == c, 'value'])}"
        for c in e.conditions
    ]
    return [
        f"Test success over achievable modules in the last {numbers['bin_size']:,}-episode bin "
        f"(to {episodes:,} episodes; mean ± std over seeds): {'; '.join(parts)}.",
        "",
    ]


def _welch_summary(
    test: pd.DataFrame, better: str, worse: str, what: str, unit: str = ""
) -> list[str]:
    """One sentence on a table of `analysis.welch_per_bin` results."""
    tested = int(test["p"].notna().sum())
    text = (
        f"One-tailed Welch's t-test per {what}, {condition_label(better)} > "
        f"{condition_label(worse)}, alpha = {analysis.ALPHA:g}: significant in "
        f"{int(test['significant'].sum())} of {len(test)}{unit}"
    )
    if tested == 0 and len(test):
        few = int(min(test["n_better"].min(), test["n_worse"].min())) < 2
        why = "fewer than two seeds a side" if few else "no variance across seeds"
        text += f" (none could be tested: {why})"
    elif tested < len(test):
        text += f" ({len(test) - tested} could not be tested: fewer than two seeds or no variance)"
    return [text + ".", ""]


def _episodes(value: object) -> str:
    """An episode count, or – where there is none (NaN or NA)."""
    return "–" if pd.isna(value) or not math.isfinite(float(value)) else f"{float(value):,.0f}"


def _p(value: float) -> str:
    return "–" if not math.isfinite(value) else f"{value:.3g}"


def _welch_points(numbers: dict, better: str, worse: str) -> list[str]:
    """The Welch test per bin of `analysis.main_comparison`, every bin a row."""
    test = numbers["welch"]
    if test.empty:
        return ["No bin is shared by both conditions.", ""]
    lines = _welch_summary(test, better, worse, f"{numbers['bin_size']:,}-episode bin", " bins")
    rows = [
        (
            f"{int(r.episodes):,}",
            f"{_fmt(r.mean_better)} (n={r.n_better})",
            f"{_fmt(r.mean_worse)} (n={r.n_worse})",
            _fmt(r.t),
            _p(r.p),
            "yes" if r.significant else "no",
        )
        for r in test.itertuples()
    ]
    header = ("bin end (episodes)", condition_label(better), condition_label(worse), "t", "p")
    return lines + _table((*header, "p < alpha"), rows)


MAIN_COMPARISON = (
    "The numbers below and Fig. 2a come from one computation, `curious.analysis."
    "main_comparison`: each run's test rollouts pooled per {bin:,}-episode bin "
    "(`analysis.binned_success`, {n} bins), the mean ± std across seeds per bin, "
    "the last bin every run completed, and a one-tailed Welch's t-test per bin."
)


NO_TESTS = (
    "These runs have no test rollouts (`tests.parquet`: trained before test rollouts were "
    "logged, or with `test_rollouts_per_worker=0`), so Fig. 2a and its statistics, which the "
    "paper measured on test rollouts, are not reported; retrain the runs."
)


def _area_under_success(e: Experiment, tests: pd.DataFrame) -> list[str]:
    """Per condition: each seed's test success averaged over every epoch of the common budget
    (`analysis.area_under_success`), and the one-tailed Welch test on it: a reading of the
    comparison that depends on no bin edges."""
    area = analysis.area_under_success(tests)
    rows = [
        (
            condition_label(condition),
            ", ".join(_fmt(v) for v in group.sort_values("seed")["value"]),
            _mean_std(group["value"]),
        )
        for condition, group in _in_order(area, e).groupby("condition", observed=True, sort=False)
    ]
    budget = int(area["episodes"].iat[0])
    lines = [
        "Test success averaged over every epoch of the first "
        f"{budget:,} episodes, per seed (the area under each seed's Fig. 2a curve over the "
        "budget, `analysis.area_under_success`; no bins):",
        "",
        *_table(("condition", "per seed", "mean ± std"), rows),
    ]
    if e.compare is not None:
        test = analysis.welch_per_bin(area, *e.compare)
        if not test.empty:
            r = test.iloc[0]
            verdict = "significant" if r.significant else "not significant"
            lines += [
                f"One-tailed Welch's t-test, {condition_label(e.compare[0])} > "
                f"{condition_label(e.compare[1])}, on it: t = {_fmt(r.t)}, p = {_p(r.p)}, "
                f"{verdict} at alpha = {analysis.ALPHA:g} (n = {r.n_better} and {r.n_worse}).",
                "",
            ]
    return lines


def _episodes_to_success(e: Experiment, tests: pd.DataFrame) -> list[str]:
    """Per condition and seed: the episodes each achievable module needed to reach each level of
    test success (`analysis.episodes_to_test_success`)."""
    table = analysis.episodes_to_test_success(tests)
    levels = sorted(set(table["level"]))
    modules = list(dict.fromkeys(table["module"].astype(str)))
    rows = []
    for (condition, seed), group in _in_order(table, e).groupby(
        ["condition", "seed"], observed=True, sort=False
    ):
        got = group.set_index(["module", "level"])["episodes"]
        cells = [" / ".join(_episodes(got[(m, v)]) for v in levels) for m in modules]
        last = int(group["last_episodes"].max())
        rows.append((condition_label(condition), seed, *cells, f"{last:,}"))
    header = ("condition", "seed", *map(module_label, modules), "tested up to")
    return [
        "Episodes to reach test success "
        f"{' / '.join(_fmt(v, 1) for v in levels)} on each achievable module, per seed: the "
        "first epoch whose test rollouts on the module, pooled over the last "
        f"{table.attrs['window']} epochs, succeed that often (– : not within the run). Read "
        "with Fig. 2a's scoring (HER: its whole goal met).",
        "",
        *_table(header, rows),
    ]


def _in_order(frame: pd.DataFrame, e: Experiment) -> pd.DataFrame:
    """Rows by the experiment's order of conditions, then seed."""
    rank = {c: i for i, c in enumerate(e.conditions)}
    key = frame["condition"].astype(str).map(rank).fillna(len(rank))
    return (
        frame.assign(_rank=key).sort_values(["_rank", "seed"], kind="stable").drop(columns="_rank")
    )


def _learning_order(e: Experiment, table: pd.DataFrame) -> list[str]:
    """Per run: the order in which its modules' competence crossed `ORDER_LEVEL`, against the
    paper's (`analysis.learning_order`)."""
    crossings = analysis.competence_crossings(table, level=ORDER_LEVEL)
    order = analysis.learning_order(crossings)
    first = crossings.set_index(["run", "module"])["episode"]
    modules = list(dict.fromkeys(crossings["module"].astype(str)))
    rows = []
    for r in _in_order(order, e).itertuples():
        cells = [_episodes(first[(r.run, m)]) for m in modules]
        verdict = "–" if pd.isna(r.follows_paper) else ("yes" if r.follows_paper else "no")
        rows.append((condition_label(r.condition), r.seed, *cells, r.order or "none", verdict))
    header = ("condition", "seed", *map(module_label, modules), "order", "as the paper")
    paper = " → ".join(" and ".join(group) for group in analysis.PAPER_ORDER)
    return [
        f"Order of learning: the first episode at which each module's competence reached "
        f"{_fmt(ORDER_LEVEL, 1)} over a full window of its self-evaluations (– : not within the "
        f"run), and whether the order agrees with the paper's ({paper}, the last two in either "
        "order; a module not reached counts as after those reached).",
        "",
        *_table(header, rows),
    ]


def _forgetting(e: Experiment, table: pd.DataFrame) -> list[str]:
    """Spontaneous forgetting (`analysis.mastery_drops`): per run, each achievable module's
    mastery and deepest fall after it, and every drop of a mastered module with its response."""
    read = analysis.mastery(table)
    drops = analysis.mastery_drops(table)
    windows = sorted({int(w) for w in table["lp_window"].dropna()})
    hold = (
        f"{math.ceil(analysis.MASTERY_HOLD * windows[0])} consecutive self-evaluations (a "
        f"window: {windows[0]})"
        if len(windows) == 1
        else f"{analysis.MASTERY_HOLD:g} of a window of consecutive self-evaluations"
    )
    lines = [
        "### Spontaneous forgetting",
        "",
        "The paper's Fig. 2b: a mastered module's competence drops, its "
        "LP rises, the agent practises it more. Rule (`curious.analysis.drops`, fixed before "
        "the runs were read): a module is mastered once its competence, over a full window of "
        f"its self-evaluations, has stood at or above {_fmt(analysis.MASTERED, 1)} for {hold}; "
        f"a drop is a fall of {_fmt(analysis.DROP_DEPTH, 1)} or more below its peak since "
        f"mastery; it recovers when back at {_fmt(analysis.MASTERED, 1)}. Per run and "
        "achievable module: the episode it was first mastered and the deepest fall of its "
        "competence below its peak while mastered (– : never mastered; HER has no "
        "self-evaluations, so no competence).",
        "",
    ]
    modules = list(dict.fromkeys(read["module"].astype(str)))
    with_variant = table["variant"].nunique() > 1
    rows = []
    for _, group in _in_order(read, e).groupby("run", observed=True, sort=False):
        first = group.iloc[0]
        by_module = group.set_index("module")
        cells = []
        for m in modules:
            if m not in by_module.index or pd.isna(by_module.at[m, "mastered_episode"]):
                cells.append("–")
            else:
                r = by_module.loc[m]
                cells.append(f"{int(r.mastered_episode):,} ({_fmt(r.deepest_fall)})")
        evaluated = bool(group["evaluated"].any())
        found = int(group["n_drops"].sum())
        mastered = int(group["mastered_episodes"].sum())
        row = [condition_label(first["condition"]), first["seed"]]
        if with_variant:
            row.insert(1, first["variant"])
        rows.append(
            (
                *row,
                *cells,
                f"{mastered:,}" if evaluated else "–",
                str(found) if evaluated else "no self-evaluations",
            )
        )
    header: tuple[str, ...] = ("condition", "seed")
    if with_variant:
        header = ("condition", "variant", "seed")
    header += (
        *(f"{module_label(m)}: mastered at (deepest fall)" for m in modules),
        "module-episodes mastered",
        "drops",
    )
    lines += _table(header, rows)
    if drops.empty:
        return [*lines, "No drop of a mastered module in these runs.", ""]
    rows = [
        (
            condition_label(r.condition),
            r.seed,
            module_label(str(r.module)),
            f"{int(r.drop_episode):,}",
            f"{_fmt(r.peak)} → {_fmt(r.trough)} at {int(r.trough_episode):,}",
            f"{_fmt(r.lp_before)} → {_fmt(r.lp_trough)}",
            f"{_fmt(r.p_lp_before)} → {_fmt(r.p_lp_after)}",
            f"{r.practice_before:.0%} → {r.practice_after:.0%}",
            _episodes(r.recovery_episodes) if r.recovered else "not by the run's end",
        )
        for r in _in_order(drops, e).itertuples()
    ]
    header = (
        "condition",
        "seed",
        "module",
        "drop at episode",
        "peak → trough",
        "LP before → at trough",
        "p_LP before → after",
        "practised before → after",
        "episodes to recover",
    )
    return [
        *lines,
        "Each drop: where it was detected, its depth, and the module's mean LP, mean p_LP and "
        "share of episodes practising it over its course (start of the fall to recovery) "
        "against as many mastered episodes before it.",
        "",
        *_table(header, rows),
    ]


def _main(repro: Reproduction, e: Experiment, tables: _Tables) -> list[str]:
    lines = [*_figure(repro, "fig2a")]
    points = tables.points
    if tables.tests is None or points is None:  # both or neither
        lines += [NO_TESTS, ""]
    else:
        compare = e.compare if e.compare is not None else (None, None)
        numbers = analysis.main_comparison(tables.tests, *compare)
        n_bins = numbers["points"]["episodes"].nunique()
        lines += [MAIN_COMPARISON.format(bin=numbers["bin_size"], n=n_bins), ""]
        lines += _final_by_condition(e, numbers)
        if e.compare is not None:
            lines += _welch_points(numbers, *e.compare)
        lines += _area_under_success(e, tables.tests)
        lines += _episodes_to_success(e, tables.tests)
    for name in ("fig2b", "fig2c", "table1"):
        lines += _figure(repro, name)
    lines += _learning_order(e, tables.metrics)
    lines += _forgetting(e, tables.metrics)
    return lines


def _distractors(repro: Reproduction, e: Experiment, tables: _Tables) -> list[str]:
    lines = [*_figure(repro, "distractors")]
    extra = repro.left_out_runs(e)  # settings shipped with too few runs: shown, not tested
    final = analysis.final_competence(tables.metrics)
    shown = final
    if extra:
        shown = pd.concat(
            [final, analysis.final_competence(analysis.load_runs(extra))], ignore_index=True
        )
    lines += [
        "Competence (self-evaluation success rate) over achievable modules after "
        f"{int(final['episodes'].iat[0]):,} episodes, mean ± std over seeds:",
        "",
        *_per_setting(e, final, shown, "setting (competence at the end)"),
    ]
    if e.compare is not None:
        lines += _degradation(shown, *e.compare)
    if tables.tests is not None:
        tested = analysis.final_test_success(tables.tests)
        shown = tested
        if extra:
            more = analysis.final_test_success(analysis.load_tests(extra))
            shown = pd.concat([tested, more], ignore_index=True)
        end, width = int(tested["episodes"].iat[0]), int(tested.attrs["bin_size"])
        lines += [
            "Test success (the noise-free test rollouts on achievable modules, pooled per run) "
            f"over episodes {max(end - width, 0) + 1:,}–{end:,}, mean ± std over seeds:",
            "",
            *_per_setting(e, tested, shown, "setting (test success at the end)"),
        ]
    return lines + _forgetting(e, tables.metrics)


def _per_setting(e: Experiment, final: pd.DataFrame, shown: pd.DataFrame, what: str) -> list[str]:
    """A measure per run (`final`, the experiment's runs; `shown`, those and the settings shipped
    with too few runs) as a table per number of distractors, with the Welch test per setting."""
    test = None
    if e.compare is not None:
        tests = [
            analysis.welch_per_bin(group, *e.compare).assign(n_distractors=n_d)
            for n_d, group in final.groupby("n_distractors", observed=True)
        ]
        test = pd.concat(tests, ignore_index=True).set_index("n_distractors")
    rows = []
    for n_d, group in shown.groupby("n_distractors", observed=True, sort=True):
        row: list[object] = [int(n_d)]
        row += [_mean_std(group.loc[group["condition"] == c, "value"]) for c in e.conditions]
        if test is not None:
            row += (
                [_fmt(test.loc[n_d, "t"]), _p(test.loc[n_d, "p"])]
                if n_d in test.index
                else ["–", "– (not tested: too few runs shipped)"]
            )
        rows.append(row)
    header: tuple[str, ...] = ("distracting modules", *map(condition_label, e.conditions))
    if test is None:
        return _table(header, rows)
    return [
        *_table((*header, "Welch t", "p"), rows),
        *_welch_summary(test, *e.compare, what),
    ]


def _degradation(final: pd.DataFrame, better: str, worse: str) -> list[str]:
    """C4's own test (`analysis.compare_degradation`), where two settings were shipped."""
    if final["n_distractors"].nunique() < 2:
        return []
    try:
        d = analysis.compare_degradation(final, better, worse)
    except analysis.AnalysisError as error:
        return [
            f"The loss from the fewest to the most distracting modules: not tested ({error}).",
            "",
        ]
    a, b = condition_label(better), condition_label(worse)
    text = (
        f"From {d['fewest']:.0f} to {d['most']:.0f} distracting modules the mean competence fell "
        f"by {d[f'loss_{better}']:.2f} for {a} and by {d[f'loss_{worse}']:.2f} for {b}: a "
        f"difference of {d['difference']:+.2f}"
    )
    if math.isfinite(d["p"]):
        text += (
            f" (Welch-Satterthwaite over the four groups: t = {d['t']:.2f}, "
            f"{d['df']:.1f} degrees of freedom, one-tailed p = {_p(d['p'])} that {a} loses less)"
        )
    else:
        text += " (not tested: a group with fewer than two seeds, or no variance)"
    return [text + ".", ""]


def _onsets_text(per_run: pd.DataFrame) -> str:
    """Where the failures started, over the runs."""
    onsets = per_run["perturbation_episode"].dropna().astype(int)
    n = len(per_run)
    if onsets.empty:
        return f"It never started in any of the {n} runs."
    low, high = onsets.min(), onsets.max()
    where = f"episode {low:,}" if low == high else f"episodes {low:,}–{high:,}"
    if len(onsets) == n:
        return f"It started at {where} in every run."
    return f"It started at {where} in {len(onsets)} of {n} runs, and never in the others."


def _recovery_rows(summary: pd.DataFrame) -> list[tuple[str, ...]]:
    """Per condition, over its measured runs: the recovery numbers."""
    return [
        (
            condition_label(r.condition),
            f"{int(r.n_measured)}/{int(r.n_runs)}",
            f"{int(r.n_dropped)}",
            f"{int(r.n_recovered)}",
            _fmt(r.pre_competence),
            _fmt(r.threshold),
            _episodes(r.mean_recovery_episodes),
            _episodes(r.std_recovery_episodes),
        )
        for r in summary.itertuples()
        if r.n_measured
    ]


def _failure_runs(repro: Reproduction, e: Experiment) -> tuple[list[str], pd.DataFrame | None]:
    """A sensory-failure experiment's figure and the opening of its section, with the per-run
    recovery of competence its figure asset wrote beside it (None before it is drawn)."""
    name = FIGURES[e.name][0]
    lines = [*_figure(repro, name)]
    csv = repro.layout.figures / f"{name}.csv"
    if not csv.is_file():
        return lines, None
    per_run = pd.read_csv(csv)
    module = str(per_run["module"].iat[0])
    lines += [
        f"Module followed: `{module}`, the one the variant's sensory failure perturbs. The "
        f"failure starts {e.sensor_failure_text}. {_onsets_text(per_run)} A recovery is "
        f"measured only in runs where the failure started and `{module}` was learned before it "
        "(its competence just before the failure at least "
        f"{' or '.join(sorted({_fmt(v) for v in per_run['learned_threshold']}))}); the others "
        "say why there is nothing to measure.",
        "",
    ]
    return lines, per_run


def _sensor_failure(repro: Reproduction, e: Experiment, tables: _Tables) -> list[str]:
    lines, per_run = _failure_runs(repro, e)
    if per_run is None:
        return lines
    rows = [
        (
            condition_label(r.condition),
            r.seed,
            "never" if pd.isna(r.perturbation_episode) else f"{int(r.perturbation_episode):,}",
            _fmt(r.onset_competence),
            _fmt(r.pre_competence),
            _fmt(r.competence_drop),
            f"{_fmt(r.lp_before)} → {_fmt(r.lp_after)}",
            f"{_fmt(r.p_lp_before)} → {_fmt(r.p_lp_after)}",
            _episodes(r.recovery_episodes),
            r.note,
        )
        for r in _in_order(per_run, e).itertuples()
    ]
    header = (
        "condition",
        "seed",
        "failure from episode",
        "competence at the onset",
        "pre-failure mean",
        "drop from the pre-failure mean",
        "LP before → after",
        "p_LP before → after",
        "recovery (episodes)",
        "outcome",
    )
    lines += [
        "Per run, two levels before the failure: the competence at the onset (its last value "
        "before the failure, the level that started it) and the pre-failure mean (the mean "
        "competence over the last p/10 episodes before a failure at episode p); then the drop from "
        "the pre-failure mean to the trough, the module's mean absolute LP and mean probability "
        "of being practised (p_LP; uniform in M-UVFA) over those episodes before the failure and "
        "as many from it on, and the episodes to regain 90 % of the pre-failure mean (0: it "
        "never fell below).",
        "",
    ]
    lines += _table(header, rows)
    measured = _recovery_rows(analysis.recovery_summary(per_run))
    if not measured:
        return [*lines, "No recovery can be measured in these runs.", ""]
    header = (
        "condition",
        "measured runs",
        "dropped",
        "recovered",
        "pre-failure mean",
        "threshold (90 % of it)",
        "mean recovery (episodes)",
        "std",
    )
    return lines + _table(header, measured)


RECOVERED_FRACTION = 0.9
"""The share of its level before at which a run's test success counts as back (docs/results.md,
C5's fixed rules)."""

PRIMARY_RULE = (
    "Recovery by test success, the primary measure (rules fixed in docs/results.md before the "
    "runs; `curious.analysis.recovery_by_tests`): `{module}`'s test success pooled over {window} "
    "epochs ({span:,} episodes); its level before is the rate over the {window} epochs tested "
    "before the onset; a run has recovered at the first epoch whose pooled epochs were all "
    "tested after the onset and whose rate is back at {percent:g} % of that level or above, "
    "the episodes to recover counting from the onset. The competence's return to 90 % of its "
    "pre-failure mean (`curious.analysis.recovery`, as in the other sensory-failure study) is "
    "the secondary measure. LP, p_LP and the share of training episodes that practised the "
    "module are means over the p/10 episodes before a failure at episode p and as many from it."
)


def _primary_cell(t: object) -> str:
    """A run's recovery of test success, or why it has no number."""
    if t.status == "no_onset":
        return "no onset"
    if t.status == "no_level":
        return "no level before"
    if bool(t.recovered):
        return f"{_episodes(t.recovery_episodes)} episodes"
    return f"not by its end ({_episodes(t.episodes_left)} episodes after the onset)"


def _secondary_cell(r: object) -> str:
    """A run's recovery of competence, or why it has no number."""
    if r.status != "measured":
        return "–"
    if not bool(r.dropped):
        return "never below 90 %"
    if bool(r.recovered):
        return f"{_episodes(r.recovery_episodes)} episodes"
    return "not by its end"


def _share(before: float, after: float) -> str:
    if not (math.isfinite(before) and math.isfinite(after)):
        return "–"
    return f"{before:.0%} → {after:.0%}"


def _primary_summary(e: Experiment, by_tests: pd.DataFrame) -> list[str]:
    """Per condition, the runs recovered by test success and their episodes to recover."""
    parts = []
    for c in e.conditions:
        mine = by_tests[by_tests["condition"] == c]
        back = mine.loc[mine["recovered"].astype(bool), "recovery_episodes"]
        text = f"{condition_label(c)} {len(back)} of {len(mine)} runs"
        if len(back) == 1:
            text += f", after {back.iat[0]:,.0f} episodes"
        elif len(back) > 1:
            text += f", after {back.mean():,.0f} ± {back.std(ddof=1):,.0f} episodes (mean ± std)"
        parts.append(text)
    return [f"Recovered by test success: {'; '.join(parts)}.", ""]


def _recovery_welch(e: Experiment, by_tests: pd.DataFrame, faster: str, slower: str) -> list[str]:
    """The one-tailed Welch test on the episodes to recover, and the runs given no number."""
    test = analysis.compare_recoveries(by_tests, faster, slower)
    head = (
        f"One-tailed Welch's t-test on the episodes to recover by test success, "
        f"{condition_label(faster)} faster than {condition_label(slower)}, alpha = "
        f"{test['alpha']:g}: "
    )
    if math.isfinite(test["p"]):
        verdict = "significant" if test["significant"] else "not significant"
        head += (
            f"t = {_fmt(test['t'])}, p = {_p(test['p'])}, {verdict} ({test['n_faster']} and "
            f"{test['n_slower']} recovered runs)."
        )
    else:
        head += (
            f"not tested ({test['n_faster']} and {test['n_slower']} recovered runs: fewer than "
            "two a side, or no variance)."
        )
    lines = [head, ""]
    unrecovered = _in_order(test["unrecovered"], e)
    if len(unrecovered):
        lines += ["Runs without a recovery by test success, given no number:", ""]
        lines += [
            f"- {condition_label(t.condition)} seed {t.seed}: {t.note}."
            for t in unrecovered.itertuples()
        ]
        lines.append("")
    return lines


def _sensor_failure_mastered(repro: Reproduction, e: Experiment, tables: _Tables) -> list[str]:
    """The study on a mastered module: per run, its recovery by test success (primary) and by
    competence (secondary), with the refocus, and the Welch test on the episodes to recover."""
    lines, per_run = _failure_runs(repro, e)
    if per_run is None:
        return lines
    if tables.tests is None:
        return [*lines, NO_TESTS, ""]
    module = str(per_run["module"].iat[0])
    onsets = analysis.failure_onsets(tables.metrics)["onset"]
    by_tests = analysis.recovery_by_tests(tables.tests, onsets, module, RECOVERED_FRACTION)
    window = int(by_tests["window"].max())
    span = window * int(by_tests["epoch_episodes"].max())
    rule = PRIMARY_RULE.format(
        module=module, window=window, span=span, percent=RECOVERED_FRACTION * 100
    )
    lines += [rule, ""]
    secondary = per_run.set_index(["condition", "seed"])
    rows = []
    for t in _in_order(by_tests, e).itertuples():
        r = next(secondary.loc[[(t.condition, t.seed)]].itertuples())
        rows.append(
            (
                condition_label(t.condition),
                t.seed,
                "never" if pd.isna(t.onset) else f"{int(t.onset):,}",
                "–" if pd.isna(t.level_before) else f"{t.level_before:.2f} ({t.n_before})",
                "–" if pd.isna(t.trough) else f"{t.trough:.2f} at {int(t.trough_episode):,}",
                f"{_fmt(r.lp_before)} → {_fmt(r.lp_after)}",
                f"{_fmt(r.p_lp_before)} → {_fmt(r.p_lp_after)}",
                _share(r.practice_before, r.practice_after),
                _primary_cell(t),
                _secondary_cell(r),
            )
        )
    header = (
        "condition",
        "seed",
        "failure from episode",
        "test success before (rollouts)",
        "test success trough",
        "LP before → after",
        "p_LP before → after",
        "practised before → after",
        "recovery by test success (primary)",
        "recovery by competence (secondary)",
    )
    lines += _table(header, rows)
    lines += _primary_summary(e, by_tests)
    if e.compare is not None:
        lines += _recovery_welch(e, by_tests, *e.compare)
    return lines


SECTIONS = {
    "main": _main,
    "distractors": _distractors,
    "sensor_failure": _sensor_failure,
    "sensor_failure_mastered": _sensor_failure_mastered,
}


def _versions(table: pd.DataFrame) -> str:
    """The libraries and commit the table's first run started with (its config.json)."""
    try:
        info = RunFolder(str(table["run"].iat[0])).read_info()
    except RunFolderError:
        return ""
    text = ", ".join(f"{k} {v}" for k, v in (info.versions or {}).items() if v)
    git = info.git or {}
    if git.get("commit"):
        text += f"; git {git['commit'][:10]}{' (with local changes)' if git.get('dirty') else ''}"
    return text


def _software(tables: dict[str, pd.DataFrame]) -> list[str]:
    """The libraries and commit the runs were trained with, one line; per experiment where the
    experiments' first runs differ (a campaign can train a later experiment from its own
    commit)."""
    by_text: dict[str, list[str]] = {}
    for name, table in tables.items():
        text = _versions(table)
        if text:
            by_text.setdefault(text, []).append(name)
    if not by_text:
        return []
    if len(by_text) == 1:
        return [f"Software: {next(iter(by_text))}.", ""]
    parts = [f"{', '.join(names)}: {text}" for text, names in by_text.items()]
    return [f"Software, per experiment (the first run of each): {'; '.join(parts)}.", ""]


def _episodes_count(n: int) -> str:
    """``"1.46 M"`` from a million on, else ``"24,000"``."""
    return f"{n / 1e6:.2f} M" if n >= 1_000_000 else f"{n:,}"


def _built_from(budget: ReproduceBudget, tables: dict[str, pd.DataFrame]) -> list[str]:
    """What the report was built from, counted from its tables (runs, training episodes, per
    experiment), beside what the whole budget trains."""
    whole = get_budget(budget.name) if budget.name in BUDGETS else budget
    specs = whole.runs()
    trains = (
        f"The budget `{budget.name}` as a whole (`curious reproduce --budget {budget.name}`) "
        f"trains {len(specs)} runs, {_episodes_count(sum(s.total_episodes for s in specs))} "
        f"episodes in all — {budget.description}."
    )
    if not tables:
        return [trains, ""]
    per_run = {
        name: t.groupby("run", observed=True)["episode"].max() + 1 for name, t in tables.items()
    }
    n_runs = sum(len(v) for v in per_run.values())
    n_episodes = int(sum(int(v.sum()) for v in per_run.values()))
    parts = ", ".join(
        f"{name} {len(v)} runs ({_episodes_count(int(v.sum()))} episodes)"
        for name, v in per_run.items()
    )
    return [
        f"This report was built from {n_runs} runs, {_episodes_count(n_episodes)} training "
        f"episodes in all: {parts}. {trains}",
        "",
    ]


def _shown_anyway(repro: Reproduction, e: Experiment) -> str:
    """The runs of left-out variants the figure and the table still show, in a sentence."""
    extra = repro.left_out_runs(e)
    if not extra:
        return ""
    names = ", ".join("/".join(p.parts[-3:]) for p in extra)
    return (
        f" The finished runs shipped of those ({names}) are drawn in the figure and listed in "
        "the table below, without a test."
    )


def write_report(repro: Reproduction) -> tuple[Path, list[str]]:
    """Write report.md for every experiment whose metrics table exists; returns (path, names)."""
    layout, budget = repro.layout, repro.budget
    tables = {
        name: pd.read_parquet(layout.metrics(name))
        for name in budget.experiments
        if layout.metrics(name).is_file()
    }
    by_experiment = {
        name: _Tables(
            table,
            pd.read_parquet(layout.tests(name)) if layout.tests(name).is_file() else None,
        )
        for name, table in tables.items()
    }
    included = [budget.experiments[name] for name in tables]
    lines = [
        f"# CURIOUS reproduction — budget `{budget.name}`",
        "",
        *_built_from(budget, tables),
        budget.notes,
        "",
    ]
    if budget.omitted:
        lines += [" ".join(budget.why_absent(name) for name in budget.omitted), ""]
    if not included:
        lines += ["No experiment has finished yet.", ""]
    else:
        lines += _software(tables)
        lines += ["## Budgets", ""]
        lines += _budgets(repro, included)
        lines += _compute(tables)
        lines += [
            "Fig. 2a and the main comparison's numbers are the success of the test rollouts "
            "(noise-free, after every epoch, modules drawn uniformly), pooled over those on the "
            "achievable modules, as in the paper; the other figures and numbers read the "
            "competence (the moving success rate of the agent's self-evaluations). x axes count "
            "training episodes (self-evaluations included, test rollouts not).",
            "",
        ]
    for e in included:
        lines += [f"## {e.title}", ""]
        if e.left_out_variants:
            lines += [
                f"Variants left out: {', '.join(e.left_out_variants)}, whose runs the data this "
                f"report was built from does not hold finished; read from "
                f"{', '.join(e.variants)} alone.{_shown_anyway(repro, e)}",
                "",
            ]
        if e.left_out_seeds:
            kept = ", ".join(map(str, e.seeds))
            lines += [
                f"Seeds left out: {', '.join(map(str, e.left_out_seeds))}, whose runs the data "
                f"this report was built from does not hold all finished; read from "
                f"{'seed' if len(e.seeds) == 1 else 'seeds'} {kept} alone.",
                "",
            ]
        if e.extra_seeds:
            extra, own = e.extra_seeds, sorted(e.budget_seeds + e.left_out_seeds)
            lines += [
                f"Seeds beyond the budget's: {', '.join(map(str, extra))} (the budget trains "
                f"{', '.join(map(str, own))}), trained with the budget's settings in all but the "
                f"seed; read with the others, {len(e.seeds)} seeds of every condition.",
                "",
            ]
        lines += SECTIONS[e.name](repro, e, by_experiment[e.name])
        lines += ["### Runs", "", *_runs_table(by_experiment[e.name])]
    missing = [name for name in budget.experiments if name not in tables]
    command = f"`curious reproduce --budget {budget.name} --experiments {','.join(missing)}`"
    if missing and included and repro.data is not None:
        lines += [
            f"Not in this report (not shipped yet): {', '.join(missing)}, whose runs the data "
            f"this report was built from does not hold all finished; {command} trains them.",
            "",
        ]
    elif missing and included:
        lines += [
            f"Not in this report (not reproduced yet): {', '.join(missing)}; run {command}.",
            "",
        ]
    layout.out.mkdir(parents=True, exist_ok=True)
    tmp = layout.report.with_name(f".{layout.report.name}.tmp")
    tmp.write_text("\n".join(lines).rstrip() + "\n", encoding="utf-8")
    tmp.replace(layout.report)
    return layout.report, [e.name for e in included]
