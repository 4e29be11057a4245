"""Analysis of run folders: loading, statistics and the paper's figures.

Pipelines and notebooks call this package; it reads run folders only (``config.json``,
``metrics.parquet``, ``tests.parquet`` and the replay counts of ``learner.parquet``,
docs/architecture.md) and never the Rerun recording.

```python
from curious import analysis

tests = analysis.load_tests("runs/")                # one row per (run, test rollout)
points = analysis.epoch_success(tests)              # test success over achievable modules
analysis.across_seeds(points)                       # mean, std, n per condition and epoch
analysis.welch_per_bin(points, "curious", "mg-te")  # one-tailed Welch test per epoch
analysis.fig2a(tests, out_dir="figures/")           # figures/fig2a.png and figures/fig2a.svg

runs = analysis.load_runs("runs/")                  # one row per (run, training episode)
analysis.fig2b(runs)                                # competence per module, one run
analysis.recovery(runs)                             # after the sensory failure, where measurable
onsets = analysis.failure_onsets(runs)["onset"]     # each run's first episode with the failure
analysis.recovery_by_tests(tests, onsets)           # ... its recovery by test success
analysis.success_after_onset(tests, onsets, [1_000, 5_000])  # that test success after it
analysis.mastery_drops(runs)                        # spontaneous drops of mastered modules
analysis.episodes_to_test_success(tests)            # per module: episodes to 0.5 and 0.9
analysis.module_success_rates(tests)               # per module: test success at the end
analysis.area_under_success(tests)                  # per run: success over every epoch, no bins
analysis.learning_order(analysis.competence_crossings(runs))  # which module was learned when
analysis.compare_degradation(analysis.final_competence(runs), "curious", "m-uvfa")  # C4's loss
analysis.final_test_success(tests)                  # per run: test success in the last bin
```

Fig. 2a's "success" is, as in the paper, the success of the noise-free test rollouts run after
every epoch, pooled over those on the run's achievable modules; Fig. 2b/2c, Table 1, the
distractors figure and the recovery read the competence (the moving success rate of the agent's
self-evaluations, which drives learning progress). `curious.analysis.statistics` defines both
precisely, `curious.analysis.milestones` when each module is learned,
`curious.analysis.perturbation` the recovery after the sensory failure (of the competence, and
of the test success, the primary measure of the study on a mastered module),
`curious.analysis.after_onset` the course of that test success after the onset, beside the rules,
`curious.analysis.censored` recoveries compared with the runs not recovered counted,
`curious.analysis.drops` the spontaneous drops of mastered modules (forgetting with nothing
perturbed), `curious.analysis.dips` the smaller falls and the practice they draw, and
`curious.analysis.degradation` C4's test of which condition loses less as distracting modules
are added, and `curious.analysis.lp_ablations` the readings beyond the paper (which of LP's two
uses does the work, and whether its sign matters). Module and condition colours live in
`curious.watching.palette`, shared with the Rerun recordings.

The public names are those of `loading`, `statistics`, `milestones`, `perturbation`,
`after_onset`, `censored`, `drops`, `dips`, `degradation`, `lp_ablations` and `figures` (each
module's ``__all__``); this package imports pandas, scipy and matplotlib.
"""

from __future__ import annotations

from curious.analysis import (
    after_onset,
    censored,
    degradation,
    dips,
    drops,
    figures,
    loading,
    lp_ablations,
    milestones,
    perturbation,
    statistics,
)
from curious.analysis.after_onset import *  # noqa: F403
from curious.analysis.censored import *  # noqa: F403
from curious.analysis.degradation import *  # noqa: F403
from curious.analysis.dips import *  # noqa: F403
from curious.analysis.drops import *  # noqa: F403
from curious.analysis.figures import *  # noqa: F403
from curious.analysis.loading import *  # noqa: F403
from curious.analysis.lp_ablations import *  # noqa: F403
from curious.analysis.milestones import *  # noqa: F403
from curious.analysis.perturbation import *  # noqa: F403
from curious.analysis.statistics import *  # noqa: F403

__all__: list[str] = []
__all__ += loading.__all__
__all__ += statistics.__all__
__all__ += milestones.__all__
__all__ += perturbation.__all__
__all__ += after_onset.__all__
__all__ += censored.__all__
__all__ += drops.__all__
__all__ += dips.__all__
__all__ += degradation.__all__
__all__ += lp_ablations.__all__
__all__ += figures.__all__
