"""Multi-Task Fetch Arm: a dm_control composer task suite for multi-task, multi-goal RL.

```python
import suite

env = suite.load("default", seed=0)          # a suite.environment.SuiteEnvironment
suite.ALL_VARIANTS                            # the registered variant names
env.task.set_next_episode(module="reach", goal=[0.1, -0.3, 0.5])
ts = env.reset()
ts = env.step([0.0, 0.0, 0.0, 1.0])
```

See docs/architecture.md for the contract and docs/suite.md for the observation layout.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from suite.catalog import ALL_VARIANTS, all_variants, register
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

if TYPE_CHECKING:
    from dm_control import composer


def load(name: str, seed: int | None = None, **kwargs: Any) -> composer.Environment:
    """Build the variant `name` with the given seed (kwargs go to the variant): `suite.variants`,
    which imports dm_control and MuJoCo, imported here at the first call, so that `import suite`
    and the variants' names and modules stay light."""
    from suite.variants import load as load_variant

    return load_variant(name, seed, **kwargs)


def build(n_distractors: int, *, seed: int | None = None, **kwargs: Any) -> composer.Environment:
    """The paper's modules with `n_distractors` distractor cubes, as an environment
    (`suite.variants.build`, imported at the first call as `load` imports it)."""
    from suite.variants import build as build_variant

    return build_variant(n_distractors, seed=seed, **kwargs)


__all__ = [
    "ALL_VARIANTS",
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
