"""Multi-Task Fetch Arm: a dm_control composer task suite for multi-task, multi-goal RL.

```python
import suite

env = suite.load("default", seed=0)          # a composer.Environment (suite.SuiteEnvironment)
suite.ALL_VARIANTS                            # the registered variant names
env.task.set_next_episode(module="reach", goal=[0.1, -0.3, 0.5])
ts = env.reset()
ts = env.step([0.0, 0.0, 0.0, 1.0])
```

See docs/architecture.md for the contract and docs/suite.md for the observation layout.
"""

from __future__ import annotations

from suite.environment import SuiteEnvironment
from suite.features import StateLayout
from suite.modules import (
    TaskModule,
    affine_slot,
    cube1_above_cube2,
    distance_module,
    module_index,
    perturbation_modules,
    push_cube,
    reach,
    stack,
    standard_modules,
)
from suite.task import OBSERVATION_KEYS, MultiTaskFetch
from suite.variants import all_variants, build, load, register

__all__ = [
    "ALL_VARIANTS",
    "OBSERVATION_KEYS",
    "MultiTaskFetch",
    "StateLayout",
    "SuiteEnvironment",
    "TaskModule",
    "affine_slot",
    "all_variants",
    "build",
    "cube1_above_cube2",
    "distance_module",
    "load",
    "module_index",
    "perturbation_modules",
    "push_cube",
    "reach",
    "register",
    "stack",
    "standard_modules",
]


def __getattr__(name: str):
    # ALL_VARIANTS is computed on access so that variants registered later are listed too.
    if name == "ALL_VARIANTS":
        return all_variants()
    raise AttributeError(f"module 'suite' has no attribute {name!r}")
