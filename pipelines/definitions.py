"""The Dagster `Definitions` of one reproduce preset, for `curious reproduce` and `dagster dev`.

`build_definitions(reproduction)` holds every experiment's assets (see `pipelines.assets`) and
the `reproduction` resource. `definitions_from_environment()` builds them from environment
variables, which is what `dagster dev -m pipelines` loads:

    CURIOUS_PRESET       reproduce preset (default: quick)
    CURIOUS_OUT          output folder (default: the preset's, e.g. runs/quick)
    CURIOUS_RUNS_DIR     run folders, e.g. on shared storage (default: $CURIOUS_OUT/runs)
    CURIOUS_RAY_ADDRESS  train partitions as Ray tasks there (default: local processes)
    CURIOUS_WORKERS      local worker processes (default: one per core)

To see the runs `curious reproduce` made in the UI, point Dagster at its instance:
`DAGSTER_HOME=runs/quick/.dagster CURIOUS_PRESET=quick dagster dev -m pipelines`.
"""

from __future__ import annotations

import os

import dagster as dg

from curious.experiments import DEFAULT_PRESET, get_preset
from pipelines.assets import RESOURCE, all_assets
from pipelines.executors import make_pool
from pipelines.resources import OutputLayout, Reproduction


def build_definitions(reproduction: Reproduction) -> dg.Definitions:
    """Every asset of the reproduction's preset, with `reproduction` as the shared resource."""
    experiments = list(reproduction.preset.experiments.values())
    return dg.Definitions(
        assets=all_assets(experiments),
        resources={RESOURCE: dg.ResourceDefinition.hardcoded_resource(reproduction)},
    )


def reproduction_from_environment() -> Reproduction:
    """The `Reproduction` the environment variables of the module docstring describe."""
    preset = get_preset(os.environ.get("CURIOUS_PRESET", DEFAULT_PRESET))
    layout = OutputLayout.at(
        os.environ.get("CURIOUS_OUT") or preset.default_out, os.environ.get("CURIOUS_RUNS_DIR")
    )
    address = os.environ.get("CURIOUS_RAY_ADDRESS") or None
    workers = int(os.environ["CURIOUS_WORKERS"]) if os.environ.get("CURIOUS_WORKERS") else None
    return Reproduction(
        preset=preset,
        layout=layout,
        make_pool=lambda: make_pool(address, workers),
        progress=False,
    )


def definitions_from_environment() -> dg.Definitions:
    return build_definitions(reproduction_from_environment())
