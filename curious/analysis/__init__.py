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
```

Fig. 2a's "success" is, as in the paper, the success of the noise-free test rollouts run after
every epoch, pooled over those on the run's achievable modules; Fig. 2b/2c, Table 1, the
distractors figure and the recovery read the competence (the moving success rate of the agent's
self-evaluations, which drives learning progress). `curious.analysis.statistics` defines both
precisely. Module and condition colours live in `curious.analysis.palette`, shared with the
Rerun recordings.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

# Public names and the submodule each lives in. They are imported on first use, so that
# `import curious.analysis.palette` (the recording code does) does not pull in pandas, scipy
# and matplotlib.
_EXPORTS: dict[str, str] = {
    **dict.fromkeys(("distractors", "fig2a", "fig2b", "fig2c", "forgetting", "table1"), "figures"),
    **dict.fromkeys(
        (
            "AnalysisError",
            "RunInfo",
            "find_run_folders",
            "load_run",
            "load_runs",
            "load_tests",
            "read_run_info",
            "run_modules",
            "runs_table",
        ),
        "loading",
    ),
    **dict.fromkeys(
        (
            "ALPHA",
            "LEARNED_COMPETENCE",
            "achievable_competence",
            "across_seeds",
            "bin_runs",
            "check_comparable",
            "epoch_success",
            "failure_onsets",
            "final_competence",
            "final_success",
            "nice_bin_size",
            "perturbed_module",
            "recovery",
            "recovery_summary",
            "welch_per_bin",
        ),
        "statistics",
    ),
    "save_figure": "style",
}

__all__ = [
    "ALPHA",
    "LEARNED_COMPETENCE",
    "AnalysisError",
    "RunInfo",
    "achievable_competence",
    "across_seeds",
    "bin_runs",
    "check_comparable",
    "distractors",
    "epoch_success",
    "failure_onsets",
    "fig2a",
    "fig2b",
    "fig2c",
    "final_competence",
    "final_success",
    "find_run_folders",
    "forgetting",
    "load_run",
    "load_runs",
    "load_tests",
    "nice_bin_size",
    "perturbed_module",
    "read_run_info",
    "recovery",
    "recovery_summary",
    "run_modules",
    "runs_table",
    "save_figure",
    "table1",
    "welch_per_bin",
]

if TYPE_CHECKING:
    from curious.analysis.figures import distractors, fig2a, fig2b, fig2c, forgetting, table1
    from curious.analysis.loading import (
        AnalysisError,
        RunInfo,
        find_run_folders,
        load_run,
        load_runs,
        load_tests,
        read_run_info,
        run_modules,
        runs_table,
    )
    from curious.analysis.statistics import (
        ALPHA,
        LEARNED_COMPETENCE,
        achievable_competence,
        across_seeds,
        bin_runs,
        check_comparable,
        epoch_success,
        failure_onsets,
        final_competence,
        final_success,
        nice_bin_size,
        perturbed_module,
        recovery,
        recovery_summary,
        welch_per_bin,
    )
    from curious.analysis.style import save_figure


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'curious.analysis' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"curious.analysis.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
