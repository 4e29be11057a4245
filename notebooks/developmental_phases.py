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
# # Developmental phases (paper Fig. 2b, 2c and Table 1)
#
# The paper's claim: a CURIOUS agent learns reach first, then push, then pick-and-place and
# stack in an order that varies between seeds; the absolute learning progress (LP) of a module
# is high while it is being learned and low once it is solved, or when it cannot be learned
# (the distractors); module selection follows LP (p_LP).
#
# `out` is the output folder of `curious reproduce`, or a shipped data folder such as the
# repository's `data/laptop` (default: the quick budget's output); `condition` and `seed` pick
# the run of Fig. 2b/2c (`seed = None`: the lowest).

# %%
# %matplotlib inline
from IPython.display import display
from matplotlib.figure import Figure

from curious import analysis
from curious.watching import palette
from pipelines.resources import OutputLayout

# %% tags=["parameters"]
out = "runs/quick"
condition = "curious"
seed = None
learned_at = analysis.LEARNED_COMPETENCE  # a module counts as learned at this competence

# %%
layout = OutputLayout.open(out)
df = analysis.load_runs(layout.experiment_runs("main"))
runs = df[df["condition"] == condition]
modules, achievable = analysis.run_modules(df, str(runs["run"].iat[0]))
print(f"{runs['run'].nunique()} {condition} run(s); modules: {', '.join(modules)}")

# %% [markdown]
# ## Fig. 2b: competence per module

# %%
analysis.fig2b(df, condition=condition, seed=seed)

# %% [markdown]
# ## Fig. 2c: absolute learning progress per module

# %%
analysis.fig2c(df, condition=condition, seed=seed)

# %% [markdown]
# ## Module selection: p_LP over episodes
#
# The probability of practising each module, sampled along the run (eps = 0.4 keeps a floor
# of 0.4 / N per module).

# %%
one = runs[runs["seed"] == (runs["seed"].min() if seed is None else seed)].sort_values("episode")
step = max(1, len(one) // 300)
sampled = one.iloc[::step]
fig = Figure(figsize=(7.2, 3.6), layout="constrained")
ax = fig.add_subplot()
ax.stackplot(
    sampled["episode"],
    [sampled[f"p_lp/{m}"] for m in modules],
    labels=[palette.module_label(m) for m in modules],
    colors=[palette.module_color(m) for m in modules],
    alpha=0.85,
)
ax.set_xlabel("episodes")
ax.set_ylabel("p_LP (stacked)")
ax.set_ylim(0, 1)
ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False, fontsize=8)
ax.set_title(f"Module selection probability p_LP, {condition} seed {int(one['seed'].iat[0])}")
fig.supxlabel(
    f"The probability of practising each module after every episode of one run "
    f"({int(one['episode'].max()) + 1:,} episodes), stacked; eps = 0.4 keeps a floor of 0.4 / "
    f"{len(modules)} per module.",
    fontsize=7.5,
    ha="left",
    x=0.01,
)
display(fig)

# %% [markdown]
# ## Table 1: competence and LP of every seed

# %%
analysis.table1(df, condition=condition)

# %% [markdown]
# ## Order of learning
#
# The first episode at which each achievable module's competence reached `learned_at` over a
# full window of its self-evaluations, per seed (empty: not reached within the budget), and
# whether the order agrees with the paper's: reach, then push, then the other two in either
# order (`analysis.PAPER_ORDER`).

# %%
crossings = analysis.competence_crossings(runs, level=learned_at)
display(crossings.pivot(index="seed", columns="module", values="episode")[list(achievable)])
display(analysis.learning_order(crossings)[["seed", "order", "not_reached", "follows_paper"]])
