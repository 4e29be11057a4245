"""The paper's figures from tables of runs (`curious.analysis.load_runs`, `load_tests`).

Every function takes a loaded table (`fig2a` the test rollouts of `curious.analysis.load_tests`,
the others the episodes of `curious.analysis.load_runs`), returns a `matplotlib.figure.Figure`
and, given ``out_dir``, also writes ``<out_dir>/<name>.png`` and ``.svg`` (see `style.save_figure`):

============  ===========================================================================
`fig2a`       average test success over achievable modules per condition in the main
              comparison's episode bins (`statistics.main_comparison`), mean ± std over seeds
              and each seed, stars at the bins where a one-tailed Welch test finds the first
              compared condition better; drawn from the test rollouts (`load_tests`)
`fig2b`       competence of every module, one run
`fig2c`       absolute learning progress of every module, the same run
`table1`      competence and LP of every seed of a condition, one row per seed
`sensor_failure` competence and LP of the perturbed module around the sensory failure, and the
              episodes each condition takes to regain a fraction of its earlier competence,
              where that can be measured
`long_runs`   competence and LP of every module over each whole run of a condition, one row per
              seed, the drops of mastered modules shaded (paper Fig. 2b-c over the long runs)
`distractors` self-evaluated competence over achievable modules at the end of the runs against
              the number of distracting modules
`lp_uses`     beyond the paper: CURIOUS, M-UVFA, `lp-select` and `lp-replay` side by side, each
              run's competence (and test success) at the end and the share of practice spent
              on distracting modules over the runs
`signed_lp`   beyond the paper: the sensory-failure figure of CURIOUS under absolute and
              signed LP
============  ===========================================================================

Every x axis counts episodes (bar the distractors figure's and `lp_uses`' first panels), and
every caption names the seeds, the budget in episodes, the preset and the variant of the runs
drawn; ``note`` adds a sentence at its end (the reproduction says there when a budget is far
below the paper's). Colours and labels of modules and conditions come from
`curious.watching.palette`.
"""

from __future__ import annotations

from curious.analysis.figures.beyond_paper import lp_uses, signed_lp
from curious.analysis.figures.distracting import distractors
from curious.analysis.figures.failure_recovery import sensor_failure
from curious.analysis.figures.fig2 import fig2a, fig2b, fig2c, table1
from curious.analysis.figures.long_runs import long_runs
from curious.analysis.figures.parts import CONDITION_ORDER
from curious.analysis.style import save_figure

__all__ = [
    "CONDITION_ORDER",
    "distractors",
    "fig2a",
    "fig2b",
    "fig2c",
    "long_runs",
    "lp_uses",
    "save_figure",
    "sensor_failure",
    "signed_lp",
    "table1",
]
