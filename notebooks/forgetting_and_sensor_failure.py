# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Forgetting and the sensory failure
#
# The paper's claims: a drop of competence on a mastered module raises its absolute learning
# progress, which draws the agent back to it (forgetting, Fig. 2b around 250k episodes); and
# after a sensory failure CURIOUS recovers faster than uniform module selection (M-UVFA).
#
# The failure (the `sensor_failure` variant, the authors' perturbation study): cube 3's observed
# x reads 5 cm too far, in the state and in push_cube3's outcome, so the perceived success of
# push_cube3 drops and the agent must relearn it. It starts at a set episode, or when
# push_cube3's competence first reaches a threshold; where it started is read from the runs'
# metrics (the first episode with `sensor_failure` on). A recovery is measured only in runs
# where the failure started and push_cube3 was learned before it; the others say why not.
#
# Part 1 reads the `sensor_failure` experiment (the failure starts once push_cube3 is learned);
# part 2 the `sensor_failure_mastered` experiment (once it is mastered), read by its fixed rules:
# recovery by test success first, the Welch test on the episodes to recover; part 3 looks for
# spontaneous forgetting in the `main`, `distractors` and `long` runs. `out` is the output folder
# of `curious reproduce`, or a shipped data folder such as the repository's `data/laptop`
# (default: the quick budget's output). The `quick` budget leaves both sensory-failure
# experiments out (`curious reproduce --budget laptop --experiments
# sensor_failure,sensor_failure_mastered` trains them): where the folder has no runs of one,
# its part says so and does nothing, and the other parts run all the same.

# %%
# %matplotlib inline
from pathlib import Path

import pandas as pd
from IPython.display import display

from curious import analysis
from curious.reproduction.experiments import get_budget
from curious.runs.folder_layout import METRICS_FILE
from pipelines.resources import OutputLayout

# %% tags=["parameters"]
out = "runs/quick"
fraction = 0.9  # recovery: back at this fraction of the competence before the perturbation
module = None  # the module to follow; None: the one the runs' sensory failure perturbs

# %% [markdown]
# ## Part 1: the sensory failure
#
# `has_failure`: whether the output folder holds `sensor_failure` runs; every cell of part 1
# does nothing without them.

# %%
layout = OutputLayout.open(out)
has_failure = any(layout.experiment_runs("sensor_failure").rglob(METRICS_FILE))
if has_failure:
    df = analysis.load_runs(layout.experiment_runs("sensor_failure"))
    runs = analysis.runs_table(df).set_index("run")
    runs = runs.join(analysis.failure_onsets(df)[["onset", "source"]])
    columns = ["condition", "seed", "variant", "perturbation_episode", "failure_competence"]
    display(runs[[*columns, "onset"]])
else:
    print(
        f"{layout.out} holds no sensor_failure runs, so part 1 is skipped. "
        + get_budget(layout.budget_name()).why_absent("sensor_failure")
    )

# %% [markdown]
# ## Competence and LP around the perturbation

# %%
if has_failure:
    fig, per_run = analysis.sensor_failure(df, module=module, fraction=fraction)
    display(fig)

# %% [markdown]
# ## Time to recover, per run and per condition
#
# `status`: `measured` where the failure started and the module was learned before it,
# `not_learned` (nothing to forget) or `never_started`; `note` says it in words.
# `recovery_episodes` (measured runs only): episodes from the failure until the competence,
# after its lowest point, is back at `fraction` of its level before (NaN: not regained).

# %%
if has_failure:
    columns = ["condition", "seed", "status", "perturbation_episode", "recovery_episodes", "note"]
    display(per_run[columns])
    display(analysis.recovery_summary(per_run))

# %% [markdown]
# ## The competence drop, the LP rise and the shift of module selection
#
# Per run where the failure started: the competence drop to the trough, and the followed
# module's mean absolute LP and mean probability of being practised (`p_lp`: p_LP with
# LP-based selection, uniform in M-UVFA) over the episodes before the failure and as many from
# it on (`analysis.recovery`'s `pre_window`, a tenth of those before it by default). With
# LP-based selection both rise when the module's competence drops.

# %%
if has_failure:
    columns = ["competence_drop", "lp_before", "lp_after", "p_lp_before", "p_lp_after"]
    started = per_run[per_run["status"] != "never_started"]
    display(started[["condition", "seed", "perturbation_episode", *columns]].round(3))

# %% [markdown]
# ## Part 2: the sensory failure on a mastered module
#
# The same failure, starting once push_cube3's competence reaches 0.9 (a mastered module, as the
# authors perturbed it), in runs long enough after it for a recovery to be seen. Its rules were
# fixed before its runs were read (docs/results.md, C5): the primary measure is the module's
# test success (noise-free test rollouts on modules drawn uniformly, so both conditions are
# measured alike) pooled over 5 epochs, back at `fraction` of its level over the 5 epochs before
# the onset, pooling only epochs tested after it; the secondary, the agent's own competence, as
# in part 1. A run still training is read as far as it got.

# %%
mastered_runs = layout.experiment_runs("sensor_failure_mastered")
has_mastered = any(mastered_runs.rglob(METRICS_FILE))
if has_mastered:
    dfm = analysis.load_runs(mastered_runs)
    tests_m = analysis.load_tests(mastered_runs)
    onsets = analysis.failure_onsets(dfm)["onset"]
    fig, per_run_m = analysis.sensor_failure(
        dfm, fraction=fraction, tests=tests_m, name="sensor_failure_mastered"
    )
    display(fig)
else:
    print(
        f"{layout.out} holds no sensor_failure_mastered runs, so part 2 is skipped. "
        + get_budget(layout.budget_name()).why_absent("sensor_failure_mastered")
    )

# %% [markdown]
# Per run (`analysis.recovery_by_tests`): the onset, the test success before it (over
# `n_before` rollouts), the lowest pooled rate after it, and the episodes to recover from the
# onset, or why there is no number (`status`: `no_onset`, the failure never started;
# `no_level`, nothing tested before it; `note` says it in words). Beside it, the recovery of
# the competence (`recovery_episodes_competence`, NaN where not measured or not regained).

# %%
if has_mastered:
    by_tests = analysis.recovery_by_tests(tests_m, onsets, fraction=fraction)
    competence = per_run_m.set_index("run")["recovery_episodes"]
    by_tests = by_tests.join(competence.rename("recovery_episodes_competence"), on="run")
    columns = ["condition", "seed", "status", "onset", "level_before", "n_before", "trough"]
    columns += ["recovery_episodes", "recovery_episodes_competence", "note"]
    with pd.option_context("display.max_colwidth", None):  # each note whole
        display(by_tests[columns].round(3))

# %% [markdown]
# One-tailed Welch's t-test on the episodes to recover by test success, CURIOUS faster than
# M-UVFA (the experiment's comparison), at alpha 0.01; a run not recovered by its end is listed
# and given no number, and with fewer than two recovered runs a side `p` is NaN (not tested).

# %%
if has_mastered:
    faster, slower = get_budget(layout.budget_name()).experiments["sensor_failure_mastered"].compare
    test = analysis.compare_recoveries(by_tests, faster, slower)
    display(pd.Series({k: v for k, v in test.items() if k != "unrecovered"}))
    with pd.option_context("display.max_colwidth", None):
        display(test["unrecovered"][["condition", "seed", "note"]])

# %% [markdown]
# The test fixed for five seeds a side (docs/results.md, C5): every run followed from its onset
# to its end, a run not recovered censored at the episodes it had; one-sided log-rank test,
# CURIOUS sooner, with its exact permutation p over every split of the runs
# (`analysis.compare_censored_recoveries`), and Gehan's statistic beside it as a check.

# %%
if has_mastered:
    censored = analysis.compare_censored_recoveries(by_tests, faster, slower)
    display(pd.Series({k: v for k, v in censored.items() if k not in ("runs", "left_out")}))
    display(censored["runs"][["condition", "seed", "time", "event"]])

# %% [markdown]
# Beside the rules, the course of each recovery: the module's pooled test success at fixed
# distances after the onset (`analysis.success_after_onset`, the window ending at the first
# epoch tested at or after each point; NaN: not tested that late), and, after each run's
# crossing, the epochs whose pooled rate was under its threshold again (`analysis.returns_below`).

# %%
if has_mastered:
    after = analysis.success_after_onset(tests_m, onsets, [1_000, 2_000, 5_000, 10_000, 20_000])
    display(after.pivot_table("value", ["condition", "seed"], "offset").round(2))
    display(analysis.returns_below(tests_m, by_tests).round(3))

# %% [markdown]
# ## Part 3: spontaneous forgetting
#
# In every run of the `main`, `distractors` and `long` experiments that has self-evaluations (HER
# has none), each achievable module is read by the rule of `curious.analysis.drops`: mastered once
# its competence over a full window has stood at or above 0.9 for half a window of
# self-evaluations; a drop is a fall of 0.2 or more below its peak since mastery. First, per run
# and module, the deepest fall of its competence below its peak while mastered
# (`analysis.mastery`; NaN: never mastered); then every drop (`analysis.mastery_drops`) with
# its LP, p_LP and practice share before and over its course. An empty table of drops is a
# result: no mastered module was forgotten.

# %%
folders = [layout.experiment_runs(e) for e in ("main", "distractors", "long")]
spontaneous = analysis.load_runs([f for f in folders if any(f.rglob(METRICS_FILE))])
read = analysis.mastery(spontaneous)
read = read[read["evaluated"]].astype({"condition": str, "variant": str, "module": str})
read["experiment"] = [Path(run).parts[-3] for run in read["run"].astype(str)]  # main, long...
modules = list(dict.fromkeys(read["module"]))  # in the runs' order
index = ["experiment", "condition", "variant", "seed"]
falls = read.pivot(index=index, columns="module", values="deepest_fall")
display(falls[modules].round(2))

# %%
drops = analysis.mastery_drops(spontaneous)
columns = ["condition", "variant", "seed", "module", "drop_episode", "peak", "trough"]
columns += ["lp_before", "lp_trough", "p_lp_before", "p_lp_after", "recovery_episodes"]
drops[columns].round(3)

# %% [markdown]
# The mechanism at any size (`curious.analysis.dips`, its rule fixed before the runs were read):
# every dip of a mastered module's competence of 0.1 (the depth tested) and of 0.05 below its
# peak, the change of the module's p_LP and share of practice from the 5,000 episodes before the
# dip to the 5,000 after, and its excess over the same module's windows without a dip; then, per
# condition, the one-sided exact sign-flip test of the runs' mean excess (a run one unit). A
# `long` run retraces the `main` run of its seed over the main run's episodes, so the test keeps
# one run per condition, variant and seed, the longest (`analysis.longest_per_seed`).

# %%
display(analysis.shorter_of_seed(spontaneous).rename_axis("left out of the test"))
units = analysis.longest_per_seed(spontaneous)
for depth in analysis.DIP_DEPTHS:
    found = analysis.dip_responses(units, depth)
    print(f"depth {depth:g}: {len(found)} dips,", dict(found["status"].value_counts()))
    for condition, own in found.groupby("condition", observed=True):
        tests = {c: analysis.dip_test(own, c) for c in ("excess_p_lp", "excess_practice")}
        summary = {
            c: {k: t[k] for k in ("n_runs", "n_dips", "mean", "p")} for c, t in tests.items()
        }
        display(pd.DataFrame(summary).rename_axis(f"{condition}, depth {depth:g}"))

# %% [markdown]
# Past the main comparison's end, in the `long` runs (C3 at the paper's episode count): per run
# and module mastered before the main runs end, its lowest competence from there to the run's
# end and over episodes 245,000 to 255,000, where the paper saw T3 forgotten
# (`analysis.lowest_competence`, `analysis.PAPER_FORGETTING_WINDOW`; a reading beside the drop
# rule, as in the report). A budget whose long runs stop before that window (or that has none,
# as `quick`) shows nothing here.

# %%
budget = get_budget(layout.budget_name())
long_folder = layout.experiment_runs("long")
start, stop = analysis.PAPER_FORGETTING_WINDOW
if (
    {"main", "long"} <= set(budget.experiments)
    and budget.experiments["long"].total_episodes >= stop
    and any(long_folder.rglob(METRICS_FILE))
):
    long_runs = analysis.load_runs(long_folder)
    long_read = analysis.mastery(long_runs)
    past = analysis.lowest_competence(
        long_runs, budget.experiments["main"].total_episodes, read=long_read
    )
    near = analysis.lowest_competence(long_runs, start, stop, read=long_read)
    keys = ["run", "seed", "module", "mastered_episode"]
    display(
        past.merge(near, on=keys, how="left", suffixes=("", f"_{start}_{stop}"))[
            [*keys[1:], "low", "low_episode", f"low_{start}_{stop}", f"low_episode_{start}_{stop}"]
        ]
    )
