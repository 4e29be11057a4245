"""The distractors' section (C4): competence and test success per number of distracting modules,
the Welch test per setting and the test of which condition loses less."""

from __future__ import annotations

import math

import pandas as pd

from curious import analysis
from curious.reproduction.experiments import Experiment
from curious.watching.palette import condition_label
from pipelines.report.blocks import (
    ExperimentTables,
    fmt,
    fmt_p,
    in_order,
    lead_figure,
    markdown_table,
    mean_std,
    other_figures,
    welch_summary,
)
from pipelines.report.spontaneous_forgetting import spontaneous_forgetting
from pipelines.resources import Reproduction


def distractors(repro: Reproduction, e: Experiment, tables: ExperimentTables) -> list[str]:
    """The distractors' section: the figure, competence and test success per number of
    distracting modules with their tests, then spontaneous forgetting."""
    tested = tables.tests is not None
    lines = [*lead_figure(repro, e, tested), *other_figures(repro, e, tested)]
    extra = repro.left_out_runs(e)  # settings shipped with too few runs: shown, not tested
    final = shown = tables.final
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
        tested = shown = tables.final_tested
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
    return lines + per_run_table(e, tables) + spontaneous_forgetting(e, tables.metrics)


PER_RUN_BINS = 5
"""The per-run table's bins over a run's budget (`analysis.nice_bin_size`): 10,000 episodes of
50,000."""


def per_run_table(e: Experiment, tables: ExperimentTables) -> list[str]:
    """Per run of the experiment, in order of distractors, condition and seed: the competence
    and test success at the end, the test success in each of `PER_RUN_BINS` bins, and the share
    of its training episodes that practised a distracting module in each (`none` without
    distractors)."""
    final = tables.final
    episodes = int(final["episodes"].iat[0])
    width = analysis.nice_bin_size(episodes, PER_RUN_BINS)
    shares = analysis.distractor_share(tables.metrics, width).groupby("run", observed=True)
    tested_at = "test success"  # "–" in every row: the runs have no test rollouts
    tested = per_bin = None
    if tables.tests is not None:
        last = tables.final_tested
        start = int(last["episodes"].iat[0]) - int(last.attrs["bin_size"]) + 1
        tested_at = f"test success, episodes {start:,}-{int(last['episodes'].iat[0]):,}"
        tested = last.set_index("run")["value"]
        points = analysis.epoch_success(tables.tests, width)
        per_bin = points.groupby("run", observed=True)["value"]
    rows = []
    for r in in_order(final, e).sort_values("n_distractors", kind="stable").itertuples():
        rows.append(
            (
                int(r.n_distractors),
                f"{condition_label(r.condition)} {int(r.seed)}",
                fmt(r.value),
                "–" if tested is None else fmt(tested[r.run]),
                "–" if per_bin is None else " / ".join(map(fmt, per_bin.get_group(r.run))),
                ", ".join(f"{100 * v:.0f} %" for v in shares.get_group(r.run)["value"])
                if r.n_distractors
                else "none",
            )
        )
    header = (
        "distracting modules",
        "run",
        f"competence at {episodes:,}",
        tested_at,
        f"test success per {width:,} episodes",
        f"episodes on a distracting module, per {width:,}",
    )
    return ["Per run:", "", *markdown_table(header, rows)]


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
        row += [mean_std(group.loc[group["condition"] == c, "value"]) for c in e.conditions]
        if test is not None:
            row += (
                [fmt(test.loc[n_d, "t"]), fmt_p(test.loc[n_d, "p"])]
                if n_d in test.index
                else ["–", "– (not tested: too few runs shipped)"]
            )
        rows.append(row)
    header: tuple[str, ...] = ("distracting modules", *map(condition_label, e.conditions))
    if test is None:
        return markdown_table(header, rows)
    return [
        *markdown_table((*header, "Welch t", "p"), rows),
        *welch_summary(test, *e.compare, what),
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
            f"{d['df']:.1f} degrees of freedom, one-tailed p = {fmt_p(d['p'])} that {a} loses less)"
        )
    else:
        text += " (not tested: a group with fewer than two seeds, or no variance)"
    return [text + ".", ""]
