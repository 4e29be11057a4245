"""Analysis of run folders: loading, statistics and the paper's figures.

Pipelines and notebooks call this package; it reads run folders only (``config.json`` and
``metrics.parquet``, docs/architecture.md) and never the Rerun recording.

```python
from curious import analysis

runs = analysis.load_runs("runs/")                 # one row per (run, episode)
binned = analysis.bin_runs(runs, bin_size=1000)     # success over achievable modules per bin
analysis.across_seeds(binned)                       # mean, std, n per condition and bin
analysis.welch_per_bin(binned, "curious", "mg-te")  # one-tailed Welch test per bin
analysis.fig2a(runs, out_dir="figures/")            # figures/fig2a.png and figures/fig2a.svg
```

"Success" (Fig. 2a, the distractors figure) is the competence averaged over the run's
achievable modules, read at the end of each episode bin; `curious.analysis.statistics` defines
it precisely. Module and condition colours live in `curious.analysis.palette`, shared with the
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
            "read_run_info",
            "run_modules",
            "runs_table",
        ),
        "loading",
    ),
    **dict.fromkeys(
        (
            "ALPHA",
            "achievable_competence",
            "across_seeds",
            "bin_runs",
            "check_comparable",
            "final_competence",
            "most_perturbed_module",
            "nice_bin_size",
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
    "AnalysisError",
    "RunInfo",
    "achievable_competence",
    "across_seeds",
    "bin_runs",
    "check_comparable",
    "distractors",
    "fig2a",
    "fig2b",
    "fig2c",
    "final_competence",
    "find_run_folders",
    "forgetting",
    "load_run",
    "load_runs",
    "most_perturbed_module",
    "nice_bin_size",
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
        read_run_info,
        run_modules,
        runs_table,
    )
    from curious.analysis.statistics import (
        ALPHA,
        achievable_competence,
        across_seeds,
        bin_runs,
        check_comparable,
        final_competence,
        most_perturbed_module,
        nice_bin_size,
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
