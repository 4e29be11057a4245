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
# # Main comparison: CURIOUS, MG-TE and HER (paper Fig. 2a)
#
# Average success over the achievable modules for each condition, measured as the paper did on
# the test rollouts: after every epoch, noise-free episodes on modules drawn uniformly
# (`tests.parquet`), their success pooled over those on reach, push, pick-and-place and stack.
# Mean ± std over seeds per episode bin, and a one-tailed Welch's t-test per bin (alpha = 0.01) of
# CURIOUS > MG-TE.
#
# The paper's claim: CURIOUS rises faster than MG-TE (about 150k against 300k episodes), and
# HER, one goal over the holistic goal space, stays flat. With the `quick` budget's 1,000
# episodes per run only the start of the curves is visible; `laptop` and `paper` go further.
#
# `out` is the output folder of `curious reproduce`, or a shipped data folder such as the
# repository's `data/laptop` (default: the quick budget's output).

# %%
# %matplotlib inline
import pandas as pd
from IPython.display import display

from curious import analysis
from pipelines.resources import OutputLayout

# %% tags=["parameters"]
out = "runs/quick"
bin_size = None  # episodes per bin; None: the comparison's bins (analysis.comparison_bin_size)
better, worse = "curious", "mg-te"

# %%
layout = OutputLayout.open(out)
df = analysis.load_runs(layout.experiment_runs("main"))
tests = analysis.load_tests(layout.experiment_runs("main"))
analysis.runs_table(df)[["condition", "seed", "variant", "preset", "n_episodes"]]

# %% [markdown]
# ## Fig. 2a

# %%
fig = analysis.fig2a(tests, compare=(better, worse), bin_size=bin_size)
display(fig)

# %% [markdown]
# ## Mean ± std over seeds, per episode bin
#
# A run's value in a bin is the success rate of the test rollouts, on achievable modules, of the
# epochs in that bin (`n_tests` of them per run); `n` is the number of seeds.

# %%
points = analysis.binned_success(tests, bin_size=bin_size)
summary = analysis.across_seeds(points)
table = summary.pivot(index="episodes", columns="condition", values="mean")
table.iloc[:: max(1, len(table) // 10)].round(3)

# %%
points.groupby("condition", observed=True)["n_tests"].describe()[["mean", "min", "max"]]

# %% [markdown]
# ## Welch's t-test per episode bin
#
# One-tailed (alternative: the first condition's mean is greater), unequal variances. A point
# with fewer than two seeds on a side, or no variance at all, has no p-value.

# %%
welch = analysis.welch_per_bin(points, better, worse)
print(
    f"{better} > {worse} at p < {analysis.ALPHA}: {int(welch['significant'].sum())} of "
    f"{len(welch)} bins; first significant bin: "
    + (
        f"{int(welch.loc[welch['significant'], 'episodes'].iloc[0]):,} episodes"
        if welch["significant"].any()
        else "none"
    )
)
welch.iloc[:: max(1, len(welch) // 10)]

# %% [markdown]
# ## Without bins: the area under each run's curve
#
# Each run's test success averaged over every epoch up to the budget all runs reached
# (`analysis.area_under_success`: the area under its Fig. 2a curve over the budget), which
# depends on no bin edges; then the same one-tailed Welch's t-test across seeds.

# %%
area = analysis.area_under_success(tests)
display(area.pivot(index="condition", columns="seed", values="value").round(3))
analysis.welch_per_bin(area, better, worse)

# %% [markdown]
# ## Episodes to a level of test success, per run and module
#
# The training episodes each run needed for a module's test success, pooled over 5 epochs, to
# reach 0.5 and 0.9 (`analysis.episodes_to_test_success`; NA: not within the run).

# %%
milestones = analysis.episodes_to_test_success(tests).astype({"condition": str, "module": str})
modules = list(dict.fromkeys(milestones["module"]))  # in slot order
milestones.pivot(
    index=["module", "level"], columns=["condition", "seed"], values="episodes"
).reindex(modules, level="module")

# %% [markdown]
# ## Each module at the end, and HER's per-module view
#
# Each module's test success over the last 5 epochs of each run (`analysis.module_success_rates`),
# then the share of all of a run's test rollouts on the module that met the module's own part of
# the goal (`score="module_success"`): the condition's score where it scores one module per
# episode; for HER, scored on its whole goal, a per-module view that is never the paper's score.

# %%
for kw in ({}, {"epochs": None, "score": "module_success"}):
    rates = analysis.module_success_rates(tests, **kw).astype({"condition": str, "module": str})
    display(
        rates.pivot(index=["condition", "seed"], columns="module", values="value")
        .reindex(columns=modules)
        .round(3)
    )

# %% [markdown]
# ## The competence, for comparison
#
# The agent's own success measure (its self-evaluations), which drives learning progress and
# Fig. 2b/2c: averaged over achievable modules, per episode bin.

# %%
competence = analysis.across_seeds(analysis.bin_runs(df))
competence.pivot(index="episodes", columns="condition", values="mean").iloc[::10].round(3)

# %% [markdown]
# ## Final test success per run
#
# At the last epoch every run reached.

# %%
final = analysis.final_success(points)
pd.concat(
    [
        final.groupby("condition", observed=True)["value"].agg(["mean", "std", "size"]),
        final.pivot(index="condition", columns="seed", values="value"),
    ],
    axis=1,
).round(3)
