"""Named variants of the Multi-Task Fetch Arm, registered dm_control style.

```python
@register
def default(seed=None, **env_kwargs): ...

env = load("default", seed=0)
```

A variant is a function that builds the task and returns its environment (`make_environment`:
a `SuiteEnvironment`, or composer's own with `stock=True`). Its name is the function's name (or
the name given to `register`).
"""

from __future__ import annotations

from collections.abc import Callable

from dm_control import composer

from suite import layout
from suite.environment import make_environment
from suite.modules import perturbation_modules, standard_modules
from suite.task import N_REACHABLE, MultiTaskFetch

VariantFn = Callable[..., composer.Environment]
_REGISTRY: dict[str, VariantFn] = {}


def register(fn_or_name: VariantFn | str | None = None) -> Callable:
    """Register a variant under its function's name: `@register` or `@register("name")`."""

    def add(fn: VariantFn, name: str) -> VariantFn:
        if name in _REGISTRY and _REGISTRY[name] is not fn:
            raise ValueError(f"a variant named {name!r} is already registered")
        _REGISTRY[name] = fn
        return fn

    if callable(fn_or_name):
        return add(fn_or_name, fn_or_name.__name__)

    def decorator(fn: VariantFn) -> VariantFn:
        return add(fn, fn_or_name or fn.__name__)

    return decorator


def all_variants() -> tuple[str, ...]:
    """Names of the registered variants, in registration order."""
    return tuple(_REGISTRY)


def load(name: str, seed: int | None = None, **kwargs) -> composer.Environment:
    """Build the variant `name` with the given seed (kwargs go to the variant)."""
    if not isinstance(name, str) or name not in _REGISTRY:
        known = ", ".join(_REGISTRY)
        raise ValueError(f"unknown variant {name!r}; known variants: {known}")
    return _REGISTRY[name](seed=seed, **kwargs)


def build(n_distractors: int, *, seed: int | None = None, **env_kwargs) -> composer.Environment:
    """The paper's modules with `n_distractors` distractor cubes, as an environment."""
    if not 0 <= n_distractors <= layout.MAX_DISTRACTORS:
        raise ValueError(
            f"n_distractors must be between 0 and {layout.MAX_DISTRACTORS}, got {n_distractors}"
        )
    task = MultiTaskFetch(standard_modules(n_distractors), n_cubes=N_REACHABLE + n_distractors)
    return make_environment(task, random_state=seed, **env_kwargs)


@register
def default(seed: int | None = None, **env_kwargs) -> composer.Environment:
    """The paper's env: 4 achievable modules and 3 distractor cubes (7 modules, 5 cubes)."""
    return build(3, seed=seed, **env_kwargs)


@register
def distractors_0(seed: int | None = None, **env_kwargs) -> composer.Environment:
    """The 4 achievable modules alone (2 cubes)."""
    return build(0, seed=seed, **env_kwargs)


@register
def distractors_4(seed: int | None = None, **env_kwargs) -> composer.Environment:
    """4 achievable modules and 4 distractor cubes (8 modules, 6 cubes)."""
    return build(4, seed=seed, **env_kwargs)


@register
def distractors_7(seed: int | None = None, **env_kwargs) -> composer.Environment:
    """4 achievable modules and 7 distractor cubes (11 modules, 9 cubes)."""
    return build(7, seed=seed, **env_kwargs)


@register
def sensor_failure(seed: int | None = None, **env_kwargs) -> composer.Environment:
    """The authors' perturbation study: 4 achievable modules on 3 reachable cubes, no
    distractors. `env.task.set_sensor_failure(True)`, at a moment the caller chooses, makes cube
    3's perceived x read +0.05 m, in the state and in push_cube3's outcome."""
    task = MultiTaskFetch(perturbation_modules(), n_cubes=3, n_reachable=3, failing_cube=3)
    return make_environment(task, random_state=seed, **env_kwargs)
