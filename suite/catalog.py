"""The suite's registry of variants by name, readable without building any: the built-in
variants as descriptions (their modules and cubes), and the variants registered by a caller.

`suite.variants` builds them (with dm_control and MuJoCo); what only needs their names or their
modules (`suite.ALL_VARIANTS`, the command line's help, a config's validation) reads them here,
where nothing heavier than numpy is imported.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from suite.layout import N_REACHABLE
from suite.modules import TaskModule, perturbation_modules, standard_modules


@dataclass(frozen=True)
class VariantSpec:
    """A built-in variant: what `suite.variants` builds for its name."""

    name: str
    description: str
    modules: Callable[[], tuple[TaskModule, ...]]
    """The task's modules, in slot order."""
    task_options: Mapping[str, int]
    """`suite.task.MultiTaskFetch`'s keyword arguments: `n_cubes`, and where they differ from its
    defaults `n_reachable` and `failing_cube`."""

    @property
    def module_names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.modules())


def distractor_spec(name: str, n_distractors: int, description: str) -> VariantSpec:
    """The paper's modules with `n_distractors` distractor cubes (`suite.build`)."""
    return VariantSpec(
        name,
        description,
        functools.partial(standard_modules, n_distractors),
        {"n_cubes": N_REACHABLE + n_distractors},
    )


BUILT_IN: dict[str, VariantSpec] = {
    spec.name: spec
    for spec in (
        distractor_spec(
            "default",
            3,
            "The paper's env: 4 achievable modules and 3 distractor cubes (7 modules, 5 cubes).",
        ),
        distractor_spec("distractors_0", 0, "The 4 achievable modules alone (2 cubes)."),
        distractor_spec(
            "distractors_4", 4, "4 achievable modules and 4 distractor cubes (8 modules, 6 cubes)."
        ),
        distractor_spec(
            "distractors_7", 7, "4 achievable modules and 7 distractor cubes (11 modules, 9 cubes)."
        ),
        VariantSpec(
            "sensor_failure",
            "The authors' perturbation study: 4 achievable modules on 3 reachable cubes, no "
            "distractors. `env.task.set_sensor_failure(True)`, at a moment the caller chooses, "
            "makes cube 3's perceived x read +0.05 m, in the state and in push_cube3's outcome.",
            perturbation_modules,
            {"n_cubes": 3, "n_reachable": 3, "failing_cube": 3},
        ),
    )
}
"""The built-in variants, in the order they are listed."""

VariantFn = Callable[..., Any]
"""A registered variant: `fn(seed=None, **env_kwargs)` -> a composer environment."""
REGISTERED: dict[str, VariantFn] = {}
"""Variants a caller registered (`suite.register`), by name, after the built-in ones."""


def all_variants() -> tuple[str, ...]:
    """Names of the built-in variants, then of the registered ones, in registration order."""
    return (*BUILT_IN, *REGISTERED)


class VariantNames(Sequence[str]):
    """The names of the variants, read at each use: the built-in ones, then those registered so
    far (`ALL_VARIANTS`, a live view, so that a variant registered later is listed too)."""

    def __getitem__(self, index):  # type: ignore[override]
        return all_variants()[index]

    def __len__(self) -> int:
        return len(BUILT_IN) + len(REGISTERED)

    def __iter__(self) -> Iterator[str]:
        return iter(all_variants())

    def __contains__(self, name: object) -> bool:
        return name in BUILT_IN or name in REGISTERED

    def __repr__(self) -> str:
        return repr(all_variants())


ALL_VARIANTS = VariantNames()
"""The variants' names, built-in then registered (`suite.ALL_VARIANTS`)."""


def find(name: str) -> VariantSpec | VariantFn:
    """The built-in variant's description, or the registered variant's function, of `name`; a
    `ValueError` naming the known variants for any other."""
    if isinstance(name, str) and name in BUILT_IN:
        return BUILT_IN[name]
    if isinstance(name, str) and name in REGISTERED:
        return REGISTERED[name]
    raise ValueError(f"unknown variant {name!r}; known variants: {', '.join(all_variants())}")


def register(fn_or_name: VariantFn | str | None = None) -> Callable:
    """Register a variant under its function's name: `@register` or `@register("name")`."""

    def add(fn: VariantFn, name: str) -> VariantFn:
        if not callable(fn):
            raise TypeError(f"register takes a function that builds the variant, got {fn!r}")
        if not isinstance(name, str) or not name or any(c in name for c in "<>/@ \t\n"):
            raise ValueError(
                f"a variant's name is one word, without /, @ or <>, got {name!r} (a lambda "
                "is named with register('name')(fn))"
            )
        if name in BUILT_IN or (name in REGISTERED and REGISTERED[name] is not fn):
            raise ValueError(f"a variant named {name!r} is already registered")
        REGISTERED[name] = fn
        return fn

    if callable(fn_or_name):
        return add(fn_or_name, fn_or_name.__name__)
    if fn_or_name is not None and not isinstance(fn_or_name, str):
        raise ValueError(f"register takes a variant's name or its function, got {fn_or_name!r}")

    def decorator(fn: VariantFn) -> VariantFn:
        return add(fn, fn_or_name or fn.__name__)

    return decorator
