"""Named variants of the Multi-Task Fetch Arm, built by name, dm_control style.

```python
env = load("default", seed=0)

@register
def two_distractors(seed=None, **env_kwargs):
    return build(2, seed=seed, **env_kwargs)
```

The built-in variants are descriptions in `suite.catalog` (their modules and cubes), built here
(`make`); a registered variant is a function that builds the task and returns its environment
(`make_environment`: a `SuiteEnvironment`, or composer's own with `stock=True`), named by its
function's name or the name given to `register`.
"""

from __future__ import annotations

import numpy as np

from suite import layout
from suite.catalog import VariantSpec, all_variants, distractor_spec, find, register
from suite.dm_composer import composer
from suite.environment import make_environment
from suite.task import MultiTaskFetch

__all__ = ["all_variants", "build", "load", "make", "register"]


def load(name: str, seed: int | None = None, **kwargs) -> composer.Environment:
    """Build the variant `name` with the given seed (kwargs go to the variant)."""
    _check_seed(seed)
    variant = find(name)
    if isinstance(variant, VariantSpec):
        return make(variant, seed=seed, **kwargs)
    env = variant(seed=seed, **kwargs)
    if not isinstance(env, composer.Environment):
        raise TypeError(
            f"variant {name!r} built a {type(env).__name__}, not a composer.Environment: its "
            "function returns the environment (suite.build or suite.variants.make give one)"
        )
    return env


def make(spec: VariantSpec, seed: int | None = None, **env_kwargs) -> composer.Environment:
    """The environment of a built-in variant's description; a `ValueError` for a seed that is
    none of None, an integer from 0 to 2**32 - 1, or a `numpy.random.RandomState`."""
    _check_seed(seed)
    task = MultiTaskFetch(spec.modules(), **spec.task_options)
    return make_environment(task, random_state=seed, **env_kwargs)


def _check_seed(seed: object) -> None:
    if seed is None or isinstance(seed, np.random.RandomState):
        return
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed < 2**32:
        raise ValueError(f"seed must be None or an integer from 0 to 2**32 - 1, got {seed!r}")


def build(n_distractors: int, *, seed: int | None = None, **env_kwargs) -> composer.Environment:
    """The paper's modules with `n_distractors` distractor cubes, as an environment."""
    if isinstance(n_distractors, bool) or not isinstance(n_distractors, int | np.integer):
        raise ValueError(f"n_distractors must be an integer, got {n_distractors!r}")
    if not 0 <= n_distractors <= layout.MAX_DISTRACTORS:
        raise ValueError(
            f"n_distractors must be between 0 and {layout.MAX_DISTRACTORS}, got {n_distractors}"
        )
    spec = distractor_spec(f"distractors_{n_distractors}", n_distractors, "")
    return make(spec, seed=seed, **env_kwargs)
