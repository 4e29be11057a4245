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

import importlib
from typing import Any

from suite.catalog import all_variants, register
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

_BUILDING: dict[str, str] = {
    "SuiteEnvironment": "suite.environment",
    "StateLayout": "suite.features",
    "OBSERVATION_KEYS": "suite.task",
    "MultiTaskFetch": "suite.task",
    "build": "suite.variants",
    "load": "suite.variants",
}
"""Names whose modules import dm_control and MuJoCo, imported on first use: `import suite` and
its variant names and modules (`ALL_VARIANTS`, `suite.catalog`) stay light."""

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


def __getattr__(name: str) -> Any:
    # ALL_VARIANTS is computed on access so that variants registered later are listed too.
    if name == "ALL_VARIANTS":
        return all_variants()
    if name in _BUILDING:
        value = getattr(importlib.import_module(_BUILDING[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'suite' has no attribute {name!r}")
