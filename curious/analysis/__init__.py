"""Analysis of run folders: loading, statistics and the paper's figures.

Pipelines and notebooks call this package; it reads run folders only (``config.json``,
``metrics.parquet`` and ``tests.parquet``, docs/architecture.md) and never the Rerun recording.

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
analysis.recovery_by_tests(tests, analysis.failure_onsets(runs)["onset"])  # ... by test success
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
`curious.analysis.censored` recoveries compared with the runs not recovered counted,
`curious.analysis.drops` the spontaneous drops of mastered modules (forgetting with nothing
perturbed), `curious.analysis.dips` the smaller falls and the practice they draw, and
`curious.analysis.degradation` C4's test of which condition loses less as distracting modules
are added, and `curious.analysis.lp_ablations` the readings beyond the paper (which of LP's two
uses does the work, and whether its sign matters). Module and condition colours live in
`curious.watching.palette`, shared with the Rerun recordings.

The public names are those of `loading`, `statistics`, `milestones`, `perturbation`, `censored`,
`drops`, `dips`, `degradation`, `lp_ablations` and `figures` (each module's ``__all__``); this
package imports pandas, scipy and matplotlib.
"""

from __future__ import annotations

from curious.analysis.censored import MAX_SPLITS, compare_censored_recoveries, logrank_z
from curious.analysis.degradation import compare_degradation
from curious.analysis.dips import (
    DIP_COLUMNS,
    DIP_DEPTHS,
    DIP_WINDOW,
    TEST_DEPTH,
    dip_responses,
    dip_test,
    mastery_dips,
)
from curious.analysis.drops import (
    DESCENT_BAND,
    DROP_COLUMNS,
    DROP_DEPTH,
    MASTERED_COMPETENCE,
    MASTERY_COLUMNS,
    MASTERY_HOLD,
    mastery,
    mastery_drops,
)
from curious.analysis.figures import (
    CONDITION_ORDER,
    distractors,
    fig2a,
    fig2b,
    fig2c,
    long_runs,
    lp_uses,
    save_figure,
    sensor_failure,
    signed_lp,
    table1,
)
from curious.analysis.loading import (
    IDENTITY_COLUMNS,
    PER_MODULE_PREFIXES,
    AnalysisError,
    RunInfo,
    find_run_folders,
    is_integer,
    load_run,
    load_runs,
    load_tests,
    name_list,
    read_run_info,
    require_count,
    require_identity,
    require_runs,
    require_tests,
    require_values,
    run_modules,
    run_path_below,
    runs_table,
    search_run_folders,
)
from curious.analysis.lp_ablations import (
    LP_USES,
    SIGNED_LP,
    compare_lp_uses,
    compare_refocus,
    lp_use_readings,
    signed_beside_absolute,
    with_paper_pair,
)
from curious.analysis.milestones import (
    LEVELS,
    PAPER_ORDER,
    competence_crossings,
    episodes_to_test_success,
    learning_order,
    module_success_rates,
    module_test_success,
)
from curious.analysis.perturbation import (
    LEARNED_COMPETENCE,
    RECOVERY_BY_TESTS_COLUMNS,
    RECOVERY_COLUMNS,
    compare_recoveries,
    failure_onsets,
    perturbed_module,
    recovery,
    recovery_by_tests,
    recovery_summary,
)
from curious.analysis.statistics import (
    ALPHA,
    COMPARISON_BINS,
    FLOAT32_SLACK,
    RUN_COLUMNS,
    achievable_competence,
    across_seeds,
    area_under_success,
    bin_runs,
    binned_success,
    check_comparable,
    comparison_bin_size,
    distractor_share,
    epoch_success,
    final_competence,
    final_success,
    final_test_success,
    holm,
    main_comparison,
    nice_bin_size,
    on_achievable,
    run_arrays,
    welch_greater,
    welch_per_bin,
)

__all__ = [
    "ALPHA",
    "COMPARISON_BINS",
    "CONDITION_ORDER",
    "DESCENT_BAND",
    "DIP_COLUMNS",
    "DIP_DEPTHS",
    "DIP_WINDOW",
    "DROP_COLUMNS",
    "DROP_DEPTH",
    "FLOAT32_SLACK",
    "IDENTITY_COLUMNS",
    "LEARNED_COMPETENCE",
    "LEVELS",
    "LP_USES",
    "MASTERED_COMPETENCE",
    "MASTERY_COLUMNS",
    "MASTERY_HOLD",
    "MAX_SPLITS",
    "PAPER_ORDER",
    "PER_MODULE_PREFIXES",
    "RECOVERY_BY_TESTS_COLUMNS",
    "RECOVERY_COLUMNS",
    "RUN_COLUMNS",
    "SIGNED_LP",
    "TEST_DEPTH",
    "AnalysisError",
    "RunInfo",
    "achievable_competence",
    "across_seeds",
    "area_under_success",
    "bin_runs",
    "binned_success",
    "check_comparable",
    "compare_censored_recoveries",
    "compare_degradation",
    "compare_lp_uses",
    "compare_recoveries",
    "compare_refocus",
    "comparison_bin_size",
    "competence_crossings",
    "dip_responses",
    "dip_test",
    "distractor_share",
    "distractors",
    "episodes_to_test_success",
    "epoch_success",
    "failure_onsets",
    "fig2a",
    "fig2b",
    "fig2c",
    "final_competence",
    "final_success",
    "final_test_success",
    "find_run_folders",
    "holm",
    "is_integer",
    "learning_order",
    "load_run",
    "load_runs",
    "load_tests",
    "logrank_z",
    "long_runs",
    "lp_use_readings",
    "lp_uses",
    "main_comparison",
    "mastery",
    "mastery_dips",
    "mastery_drops",
    "module_success_rates",
    "module_test_success",
    "name_list",
    "nice_bin_size",
    "on_achievable",
    "perturbed_module",
    "read_run_info",
    "recovery",
    "recovery_by_tests",
    "recovery_summary",
    "require_count",
    "require_identity",
    "require_runs",
    "require_tests",
    "require_values",
    "run_arrays",
    "run_modules",
    "run_path_below",
    "runs_table",
    "save_figure",
    "search_run_folders",
    "sensor_failure",
    "signed_beside_absolute",
    "signed_lp",
    "table1",
    "welch_greater",
    "welch_per_bin",
    "with_paper_pair",
]
