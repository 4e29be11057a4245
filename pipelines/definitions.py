"""The Dagster `Definitions` of one budget, for `curious reproduce` and the Dagster UI.

`build_definitions(reproduction)` holds every experiment's assets (see `pipelines.assets`) and
the `reproduction` resource. `definitions_from_environment()` builds them from environment
variables, which is what `dagster-webserver -m pipelines.code_location` (or `dagster dev`) loads:

    CURIOUS_BUDGET       budget: smoke, quick, laptop or paper (default: quick)
    CURIOUS_OUT          output folder (default: the budget's, e.g. runs/quick)
    CURIOUS_RUNS_DIR     run folders, e.g. on shared storage (default: $CURIOUS_OUT/runs)
    CURIOUS_RAY_ADDRESS  train partitions as Ray tasks there (default: local processes)
    CURIOUS_WORKERS      local worker processes (default: one per core)
    CURIOUS_FROM_DATA    read the runs from this shipped data folder instead of training them
                         (as `curious reproduce --from-data`; CURIOUS_RUNS_DIR is then unused)

To see the runs `curious reproduce` made in the UI, point Dagster at its instance:
`DAGSTER_HOME=runs/quick/.dagster CURIOUS_BUDGET=quick dagster-webserver -h 127.0.0.1
-m pipelines.code_location` (on the loopback address, this machine only; another machine
reaches it through an SSH tunnel).

`CURIOUS_PRESET`, the variable's name before budgets were named apart from training presets,
is refused with an error naming `CURIOUS_BUDGET` rather than ignored (ignored, the default
budget would be loaded in place of the one meant).
"""

from __future__ import annotations

import os

import dagster as dg

from curious.reproduction.experiments import DEFAULT_BUDGET, ExperimentError, get_budget
from curious.runs.side_by_side import MAX_WORKERS
from pipelines.assets import RESOURCE, all_assets
from pipelines.executors import make_pool
from pipelines.from_data import ShippedData
from pipelines.resources import OutputLayout, Reproduction


def build_definitions(reproduction: Reproduction) -> dg.Definitions:
    """Every asset of the reproduction's budget, with `reproduction` as the shared resource."""
    experiments = list(reproduction.budget.experiments.values())
    return dg.Definitions(
        assets=all_assets(experiments),
        resources={RESOURCE: dg.ResourceDefinition.hardcoded_resource(reproduction)},
    )


def reproduction_from_environment() -> Reproduction:
    """The `Reproduction` the environment variables of the module docstring describe."""
    if "CURIOUS_PRESET" in os.environ and "CURIOUS_BUDGET" not in os.environ:
        raise ExperimentError(
            f"CURIOUS_PRESET is no longer read: set CURIOUS_BUDGET={os.environ['CURIOUS_PRESET']} "
            "instead (the budget, as in `curious reproduce --budget`)"
        )
    budget = get_budget(os.environ.get("CURIOUS_BUDGET") or DEFAULT_BUDGET)
    data = None
    if os.environ.get("CURIOUS_FROM_DATA"):
        data = ShippedData.open(os.environ["CURIOUS_FROM_DATA"])
        data.check_budget(budget)
        budget = data.stands_for(budget)
    out = os.environ.get("CURIOUS_OUT") or (
        budget.default_out if data is None else f"{budget.default_out}-shipped"
    )
    runs_dir = os.environ.get("CURIOUS_RUNS_DIR") if data is None else data.path
    layout = OutputLayout.at(out, runs_dir)
    address = os.environ.get("CURIOUS_RAY_ADDRESS") or None
    workers = _workers_from(os.environ.get("CURIOUS_WORKERS"))
    return Reproduction(
        budget=budget,
        layout=layout,
        make_pool=lambda: make_pool(address, workers),
        progress=False,
        data=data,
    )


def definitions_from_environment() -> dg.Definitions:
    return build_definitions(reproduction_from_environment())


def _workers_from(text: str | None) -> int | None:
    """`CURIOUS_WORKERS` as a number of worker processes (None: unset, one per core), refused in
    one line where it is not a whole number from 1 to `MAX_WORKERS`."""
    if not text:
        return None
    try:
        workers = int(text)
    except ValueError:
        workers = 0
    if not 1 <= workers <= MAX_WORKERS:
        raise ValueError(
            f"CURIOUS_WORKERS must be a whole number of worker processes from 1 to "
            f"{MAX_WORKERS:,}, got {text!r}"
        )
    return workers
