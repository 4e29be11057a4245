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
# # Distracting modules
#
# The claim: with more impossible modules (pushing cubes out of reach), module selection by
# learning progress (CURIOUS) loses less than uniform selection (M-UVFA), because LP stays
# near zero on what cannot be learned and the agent stops practising and replaying it.
#
# The `distractors` experiment trains both conditions with 0, 4 and 7 distracting modules.
# `out` is the output folder of `curious reproduce`, or a shipped data folder such as the
# repository's `data/laptop` (default: the quick budget's output).

# %%
# %matplotlib inline
import pandas as pd
from IPython.display import display
from matplotlib.figure import Figure

from curious import analysis
from curious.watching import palette
from pipelines.resources import OutputLayout

# %% tags=["parameters"]
out = "runs/quick"
better, worse = "curious", "m-uvfa"

# %%
layout = OutputLayout.open(out)
df = analysis.load_runs(layout.experiment_runs("distractors"))
tests = analysis.load_tests(layout.experiment_runs("distractors"))
analysis.runs_table(df)[["condition", "seed", "variant", "n_distractors", "n_episodes"]]

# %% [markdown]
# ## Competence and test success against the number of distracting modules
#
# Left, the competence at the end (the agent's own self-evaluations, the measure C4's tests
# use); right, the noise-free test rollouts on the achievable modules in the last of the main
# comparison's bins (`analysis.final_test_success`).

# %%
analysis.distractors(df, conditions=[better, worse], tests=tests)

# %%
final = analysis.final_competence(df)
final.groupby(["n_distractors", "condition"], observed=True)["value"].agg(
    ["mean", "std", "size"]
).unstack("condition").round(3)

# %%
tested = analysis.final_test_success(tests)
tested.groupby(["n_distractors", "condition"], observed=True)["value"].agg(
    ["mean", "std", "size"]
).unstack("condition").round(3)

# %% [markdown]
# ## Welch's t-test per setting
#
# One-tailed, `better` > `worse`, on the competence at the end of the runs (needs at least two
# seeds a side).

# %%
pd.concat(
    [
        analysis.welch_per_bin(group, better, worse).assign(n_distractors=n)
        for n, group in final.groupby("n_distractors", observed=True)
    ],
    ignore_index=True,
)

# %% [markdown]
# ## Who loses more as distractors are added
#
# C4's own test (`analysis.compare_degradation`): each condition's loss of mean competence from
# the fewest to the most distracting modules shipped, and a one-tailed test that `better` loses
# less (Welch-Satterthwaite over the four groups; NaN with fewer than two seeds in a group).

# %%
pd.Series(analysis.compare_degradation(final, better, worse))

# %% [markdown]
# ## Learning curves per setting
#
# Test success over achievable modules, from the runs' test rollouts (drawn as Fig. 2a is), one
# figure per number of distractors.

# %%
tests = analysis.load_tests(layout.experiment_runs("distractors"))
for variant in sorted(tests["variant"].astype(str).unique()):
    n = int(tests.loc[tests["variant"] == variant, "n_distractors"].iat[0])
    title = f"Test success over achievable modules, {n} distracting modules ({variant})"
    display(analysis.fig2a(tests, variant=variant, compare=None, title=title))

# %% [markdown]
# ## Attention paid to the distractors
#
# The summed probability of practising a distracting module (p_LP over the modules that are not
# achievable), averaged over seeds. Uniform selection gives it n_distractors / n_modules all
# along; LP-based selection should bring it down towards its floor, eps x that share.

# %%
fig = Figure(figsize=(7.2, 3.8), layout="constrained")
ax = fig.add_subplot()
for (condition, _variant), group in df.groupby(["condition", "variant"], observed=True):
    modules, achievable = analysis.run_modules(df, str(group["run"].iat[0]))
    distracting = [m for m in modules if m not in achievable]
    if not distracting:
        continue
    share = group[[f"p_lp/{m}" for m in distracting]].sum(axis=1)
    curve = share.groupby(group["episode"]).mean()
    curve = curve.iloc[:: max(1, len(curve) // 300)]
    ax.plot(
        curve.index,
        curve.to_numpy(),
        color=palette.condition_color(str(condition)),
        linestyle="-" if len(distracting) > 4 else "--",
        label=f"{palette.condition_label(str(condition))}, {len(distracting)} distractors",
    )
ax.set_xlabel("episodes")
ax.set_ylabel("p(practise a distractor)")
ax.set_ylim(0, 1)
ax.legend(frameon=False, fontsize=8)
ax.set_title("Probability of practising a distracting module")
seeds = ", ".join(str(s) for s in sorted(df["seed"].unique()))
fig.supxlabel(
    f"Summed p_LP of the modules that are not achievable, mean over seeds ({seeds}) per "
    "episode; dashed: 4 distractors or fewer, solid: more. Uniform selection keeps it at "
    "n_distractors / n_modules.",
    fontsize=7.5,
    ha="left",
    x=0.01,
)
display(fig)
