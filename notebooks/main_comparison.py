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
# Average success over the achievable modules (competence, i.e. self-evaluation success rate,
# averaged over reach, push, pick-and-place and stack) for each condition, mean ± std over
# seeds, and a one-tailed Welch's t-test per episode bin (alpha = 0.01) of CURIOUS > MG-TE.
#
# The paper's claim: CURIOUS rises faster than MG-TE (about 150k against 300k episodes), and
# HER, one goal over the holistic goal space, stays flat. With the `quick` preset's small
# budgets only the start of the curves is visible; `laptop` and `paper` go further.
#
# `out` is the output folder of `curious reproduce` (default: the quick preset's).

# %%
# %matplotlib inline
import pandas as pd
from IPython.display import display

from curious import analysis
from pipelines.resources import OutputLayout

# %% tags=["parameters"]
out = "runs/quick"
bin_size = None  # episodes per bin; None chooses about 50 bins
better, worse = "curious", "mg-te"

# %%
layout = OutputLayout.open(out)
df = analysis.load_runs(layout.experiment_runs("main"))
analysis.runs_table(df)[["condition", "seed", "variant", "preset", "n_episodes"]]

# %% [markdown]
# ## Fig. 2a

# %%
fig = analysis.fig2a(df, compare=(better, worse), bin_size=bin_size)
display(fig)

# %% [markdown]
# ## Mean ± std over seeds, per bin
#
# A run's value in a bin is its success at the bin's end (competence is already a moving
# average); `n` is the number of seeds.

# %%
binned = analysis.bin_runs(df, bin_size=bin_size)
summary = analysis.across_seeds(binned)
table = summary.pivot(index="episodes", columns="condition", values="mean")
table.iloc[:: max(1, len(table) // 10)].round(3)

# %% [markdown]
# ## Welch's t-test per bin
#
# One-tailed (alternative: the first condition's mean is greater), unequal variances. A bin
# with fewer than two seeds on a side, or no variance at all, has no p-value.

# %%
welch = analysis.welch_per_bin(binned, better, worse)
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
# ## Final success per run

# %%
final = analysis.final_competence(df)
pd.concat(
    [
        final.groupby("condition", observed=True)["value"].agg(["mean", "std", "size"]),
        final.pivot(index="condition", columns="seed", values="value"),
    ],
    axis=1,
).round(3)
