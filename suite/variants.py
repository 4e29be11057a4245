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

from dm_control import composer

from suite import layout
from suite.catalog import VariantSpec, all_variants, distractor_spec, find, register
from suite.environment import make_environment
from suite.task import MultiTaskFetch

__all__ = ["all_variants", "build", "load", "make", "register"]


def load(name: str, seed: int | None = None, **kwargs) -> composer.Environment:
    """Build the variant `name` with the given seed (kwargs go to the variant)."""
    variant = find(name)
    if isinstance(variant, VariantSpec):
        return make(variant, seed=seed, **kwargs)
    return variant(seed=seed, **kwargs)


def make(spec: VariantSpec, seed: int | None = None, **env_kwargs) -> composer.Environment:
    """The environment of a built-in variant's description."""
    task = MultiTaskFetch(spec.modules(), **spec.task_options)
    return make_environment(task, random_state=seed, **env_kwargs)


def build(n_distractors: int, *, seed: int | None = None, **env_kwargs) -> composer.Environment:
    """The paper's modules with `n_distractors` distractor cubes, as an environment."""
    if not 0 <= n_distractors <= layout.MAX_DISTRACTORS:
        raise ValueError(
            f"n_distractors must be between 0 and {layout.MAX_DISTRACTORS}, got {n_distractors}"
        )
    spec = distractor_spec(f"distractors_{n_distractors}", n_distractors, "")
    return make(spec, seed=seed, **env_kwargs)
