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
# after a sensory failure (from a set episode on, the observed x of one cube reads 5 cm too far)
# CURIOUS recovers faster than uniform module selection (M-UVFA).
#
# Part 1 reads the `sensor_failure` experiment; part 2 looks for spontaneous forgetting in the
# CURIOUS runs of the `main` experiment. `out` is the output folder of `curious reproduce`.

# %%
# %matplotlib inline
import numpy as np
import pandas as pd
from IPython.display import display

from curious import analysis
from pipelines.resources import OutputLayout

# %% tags=["parameters"]
out = "runs/quick"
fraction = 0.9  # recovery: back at this fraction of the competence before the perturbation
module = None  # the module to follow; None: the one whose competence fell most

# %%
layout = OutputLayout.open(out)
df = analysis.load_runs(layout.experiment_runs("sensor_failure"))
runs = analysis.runs_table(df)
runs[["condition", "seed", "variant", "perturbation_episode", "n_episodes"]]

# %% [markdown]
# ## Competence and LP around the perturbation

# %%
fig, per_run = analysis.forgetting(df, module=module, fraction=fraction)
display(fig)

# %% [markdown]
# ## Time to recover, per run and per condition
#
# `recovery_episodes`: episodes from the perturbation until the competence, after its lowest
# point, is back at `fraction` of its level before (NaN: not regained, or nothing to lose).

# %%
per_run.drop(columns=["run"])

# %%
analysis.recovery_summary(per_run)

# %% [markdown]
# ## Module selection after the perturbation
#
# Mean p_LP of the followed module over the episodes before and after the perturbation: with
# LP-based selection it rises when the module's competence drops.

# %%
followed = str(per_run["module"].iat[0])
p = int(per_run["perturbation_episode"].iat[0])
window = max(1, p // 2)
rows = []
for (condition, seed), run in df.groupby(["condition", "seed"], observed=True):
    e = run["episode"].to_numpy()
    values = run[f"p_lp/{followed}"].to_numpy()
    rows.append(
        {
            "condition": condition,
            "seed": seed,
            "p_lp before": float(values[(e >= p - window) & (e < p)].mean()),
            "p_lp after": float(values[(e >= p) & (e < p + window)].mean()),
        }
    )
pd.DataFrame(rows).round(3)

# %% [markdown]
# ## Spontaneous forgetting in the main runs
#
# For every CURIOUS run of the `main` experiment and every achievable module: the largest fall
# of competence from a running peak, where it happened, and the module's LP there.

# %%
main = analysis.load_runs(layout.experiment_runs("main"))
main = main[main["condition"] == "curious"].sort_values(["run", "episode"])
rows = []
for seed, run in main.groupby("seed", observed=True):
    _, achievable = analysis.run_modules(main, str(run["run"].iat[0]))
    for m in achievable:
        competence = run[f"competence/{m}"].to_numpy(dtype=np.float64)
        fall = np.maximum.accumulate(competence) - competence
        at = int(np.argmax(fall))
        rows.append(
            {
                "seed": seed,
                "module": m,
                "largest fall": float(fall[at]),
                "at episode": int(run["episode"].iat[at]),
                "LP there": float(run[f"lp/{m}"].iat[at]),
            }
        )
pd.DataFrame(rows).round(3)
