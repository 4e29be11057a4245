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
`curious.analysis.palette`, shared with the Rerun recordings.

The public names are those of `loading`, `statistics`, `milestones`, `perturbation`, `censored`,
`drops`, `dips`, `degradation`, `lp_ablations` and `figures` (each module's ``__all__``),
imported on first use, so that ``import curious.analysis.palette`` (the recording code does)
does not pull in pandas, scipy and matplotlib.
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import Any

DEFAULT_TEST_EPOCHS = 5
"""How many of a run's last epochs its current test success pools (`curious progress`, the
milestones); defined here, where nothing heavy is imported, so that `curious progress --help`
shows it without loading pandas. A `laptop` epoch tests each module about 40 / N times, too
few alone to read."""

_PUBLIC_MODULES = (
    "loading",
    "statistics",
    "milestones",
    "perturbation",
    "censored",
    "drops",
    "dips",
    "degradation",
    "lp_ablations",
    "figures",
)
"""The submodules whose ``__all__`` make this package's names, looked up in this order."""


def _public_names() -> list[str]:
    return sorted(
        {n for m in _PUBLIC_MODULES for n in importlib.import_module(f"{__name__}.{m}").__all__}
    )


def __getattr__(name: str) -> Any:
    if name == "__all__":
        return _public_names()
    if name.startswith("__") or importlib.util.find_spec(f"{__name__}.{name}") is not None:
        # a submodule not imported yet (`from curious.analysis import palette` imports it then)
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    for sub in _PUBLIC_MODULES:
        module = importlib.import_module(f"{__name__}.{sub}")
        if name in module.__all__:
            value = getattr(module, name)
            globals()[name] = value
            return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_public_names()))
