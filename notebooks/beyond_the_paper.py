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
# # Beyond the paper: LP's two uses, and its sign
#
# Two questions the paper does not ask, read by the rules docs/results.md fixed before any of
# their runs trained ("Beyond the paper").
#
# Part 1, **which of LP's two uses does the work** (experiment `lp_uses`). CURIOUS uses learning
# progress to choose the module it practises and the module each relabelled transition is
# replayed as; M-UVFA does neither. `lp-select` keeps the first use alone, `lp-replay` the
# second. Both train on `distractors_7` and are read beside the `distractors` experiment's
# CURIOUS and M-UVFA runs of that variant.
#
# Part 2, **does LP's absolute value matter** (experiment `signed_lp`). With `lp_measure=signed`
# a falling competence counts as no progress, so a failed module's LP is not raised by the
# fall. CURIOUS with signed LP trains on the sensory failure on a mastered module and is read
# beside the `sensor_failure_mastered` experiment's CURIOUS runs (absolute LP, the paper's).
#
# `out` is the output folder of `curious reproduce`, or a shipped data folder such as the
# repository's `data/laptop` (default: the quick budget's output). The `quick` budget trains
# neither experiment; where the folder has no runs of one, its part says so and does nothing.

# %%
# %matplotlib inline
import pandas as pd
from IPython.display import display

from curious import analysis
from curious.reproduction.experiments import get_budget
from curious.runs.folder_layout import METRICS_FILE
from pipelines.resources import OutputLayout

# %% tags=["parameters"]
out = "runs/quick"
fraction = 0.9  # recovery: back at this fraction of the test success before the failure


# %%
def tables_of(experiment: str) -> tuple[pd.DataFrame | None, pd.DataFrame | None]:
    """(metrics, test rollouts) of every run of `experiment` in the folder; None where it has
    none (and no test rollouts where a run has none)."""
    folder = layout.experiment_runs(experiment)
    if not any(folder.rglob(METRICS_FILE)):
        return None, None
    try:
        tests = analysis.load_tests(folder)
    except analysis.AnalysisError:
        tests = None
    return analysis.load_runs(folder), tests


def skipped(experiment: str, part: int) -> None:
    print(
        f"{layout.out} holds no {experiment} runs, so part {part} is skipped. "
        + get_budget(layout.budget_name()).why_absent(experiment)
    )


layout = OutputLayout.open(out)
uses, uses_tests = tables_of("lp_uses")
signed, signed_tests = tables_of("signed_lp")

# %% [markdown]
# ## Part 1: LP's two uses apart
#
# The four conditions side by side (`analysis.lp_uses_tables` adds the `distractors` runs'
# CURIOUS and M-UVFA of the variant): each run's competence over the achievable modules at the
# end and its test success in the last bin, and the share of its training episodes spent on a
# distracting module over the run (solid); dashed, the share of the transitions its updates
# replayed as one, from the replay counts of its `learner.parquet` (`analysis.learner_of`: the
# runs that kept them; runs trained before runs kept them go without).

# %%
if uses is None:
    skipped("lp_uses", 1)
else:
    variant = str(uses["variant"].iat[0])
    metrics, tests = analysis.lp_uses_tables(uses, uses_tests, *tables_of("distractors"), variant)
    learner = analysis.learner_of(metrics)
    display(analysis.lp_uses(metrics, tests, learner=learner))

# %% [markdown]
# Per run: the measures at the end and both shares over the whole run
# (`analysis.distractor_share` and `analysis.replay_share` with the run's length as the bin;
# NaN where the run kept no replay counts).

# %%
if uses is not None:
    final = analysis.final_competence(metrics)
    episodes = int(final["episodes"].iat[0])
    per_run = final[["run", "condition", "seed", "value"]].rename(columns={"value": "competence"})
    if tests is not None:
        tested = analysis.final_test_success(tests).set_index("run")["value"]
        per_run["test_success"] = per_run["run"].map(tested)

    def over_the_run(share: pd.DataFrame) -> pd.Series:
        """Each run's share over its first `episodes` (the bin that ends there)."""
        return share[share["episodes"] == episodes].set_index("run")["value"]

    practice = over_the_run(analysis.distractor_share(metrics, episodes))
    per_run["practice_on_distractors"] = per_run["run"].map(practice)
    replay = pd.Series(dtype=float)
    if learner is not None:
        replay = over_the_run(analysis.replay_share(learner, episodes))
    per_run["replay_on_distractors"] = per_run["run"].map(replay).astype(float)
    display(per_run.drop(columns="run").sort_values(["condition", "seed"]).round(3))

# %% [markdown]
# The four one-tailed Welch tests on the competence at the end (the primary measure): each
# single-use condition against M-UVFA (the use alone helps), CURIOUS against each (the other use
# adds to it), on the seeds all four conditions have, alpha 0.01 after Holm's correction over
# the four (`analysis.compare_lp_uses`); then the reading fixed before the runs
# (`analysis.lp_use_readings`). The same tests on the test success are reported and decide
# nothing. With fewer than two seeds shared, no test: the cell says why.

# %%
if uses is not None:
    measures = {"competence at the end (primary)": final}
    if tests is not None:
        measures["test success in the last bin (secondary)"] = analysis.final_test_success(tests)
    for what, values in measures.items():
        try:
            result = analysis.compare_lp_uses(values)
        except analysis.AnalysisError as exc:
            print(f"{what}: not tested ({exc})")
            continue
        display(result.rename_axis(what).round(4))
        if values is final:
            display(pd.Series(analysis.lp_use_readings(result), name="reading"))

# %% [markdown]
# ## Part 2: signed LP on the sensory failure of a mastered module
#
# Push cube 3's test success, competence and LP around the failure, each run aligned on its
# onset, CURIOUS under absolute LP beside CURIOUS under signed LP (`analysis.signed_lp`, which
# names the signed runs `curious-signed`), and per run (`analysis.recovery`) the onset and the
# module's p_LP and share of practice over the episodes before it and as many after.

# %%
if signed is None:
    skipped("signed_lp", 2)
else:
    absolute, absolute_tests = tables_of("sensor_failure_mastered")
    if absolute is not None and (absolute_tests is None or signed_tests is None):
        absolute_tests = signed_tests = None  # the test panel draws both measures, or neither
    fig, recovery = analysis.signed_lp(absolute, signed, absolute_tests, signed_tests)
    display(fig)
    columns = ["condition", "seed", "status", "perturbation_episode"]
    columns += ["p_lp_before", "p_lp_after", "practice_before", "practice_after"]
    display(recovery[columns].round(3))

# %% [markdown]
# The refocus test: one-tailed Welch that absolute LP raises the failed module's p_LP more
# (after minus before the onset) than signed LP, alpha 0.01 (`analysis.compare_refocus`); the
# practice share's rise beside it, without a test. Then the recovery by test success (C5's
# primary measure: pooled over 5 epochs, back at `fraction` of its level before the onset), each
# run followed to its end and censored there if not recovered, and the one-sided log-rank test
# that absolute LP recovers sooner, with its exact permutation p
# (`analysis.compare_censored_recoveries`; Gehan's statistic beside it, deciding nothing).

# %%
if signed is not None and absolute is not None:
    refocus = analysis.compare_refocus(
        recovery[recovery["condition"] == "curious"],
        recovery[recovery["condition"] == analysis.SIGNED_LP],
    )
    display(pd.Series(refocus, name="refocus"))
if signed is not None and absolute is not None and signed_tests is not None:
    both = analysis.signed_beside_absolute(signed, absolute)
    onsets = analysis.failure_onsets(both)["onset"]
    module = str(recovery["module"].iat[0])
    tests_both = analysis.signed_beside_absolute(signed_tests, absolute_tests)
    by_tests = analysis.recovery_by_tests(tests_both, onsets, module, fraction)
    columns = ["condition", "seed", "status", "onset", "level_before", "recovery_episodes"]
    with pd.option_context("display.max_colwidth", None):
        display(by_tests[[*columns, "note"]].round(3))
    censored = analysis.compare_censored_recoveries(by_tests, "curious", analysis.SIGNED_LP)
    display(pd.Series({k: v for k, v in censored.items() if k not in ("runs", "left_out")}))
elif signed is not None:
    print(
        "The sensor_failure_mastered runs (absolute LP) or the test rollouts of either measure "
        "are not in this folder: the comparison waits for them."
    )
