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
# Part 1 reads the `sensor_failure` experiment; part 2 looks for spontaneous forgetting in the
# CURIOUS runs of the `main` experiment. `out` is the output folder of `curious reproduce`, or
# a shipped data folder such as the repository's `data/laptop` (default: the quick budget's
# output). The `quick` budget leaves the sensory failure out (`curious reproduce --budget laptop
# --experiments sensor_failure` trains it): where the folder has no `sensor_failure` runs, part
# 1's cells say so and do nothing, and part 2 runs all the same.

# %%
# %matplotlib inline
import numpy as np
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
    fig, per_run = analysis.forgetting(df, module=module, fraction=fraction)
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
# ## Part 2: spontaneous forgetting in the main runs
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
