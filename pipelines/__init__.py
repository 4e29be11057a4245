"""Dagster assets that train every condition and seed and rebuild the figures of the paper.

    dagster-webserver -h 127.0.0.1 -m pipelines   # the asset graph in the UI (needs curious[ui])
    curious reproduce --budget quick              # the same assets, materialised in process

`defs` (the `Definitions` Dagster loads) is built on first access from environment variables
(`pipelines.definitions`), so importing this package, as every training worker does, stays cheap.
"""

from __future__ import annotations

from typing import Any


def __getattr__(name: str) -> Any:
    if name == "defs":
        from pipelines.definitions import definitions_from_environment

        value = definitions_from_environment()
        globals()["defs"] = value
        return value
    raise AttributeError(f"module 'pipelines' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), "defs"})
