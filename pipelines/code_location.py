"""The code location Dagster's own tools load:

    dagster-webserver -h 127.0.0.1 -m pipelines.code_location   # the asset graph in the UI
    dagster dev -h 127.0.0.1 -m pipelines.code_location          # the same with Dagster's daemon

Its `defs` are built, when it is imported, from the environment variables that
`pipelines.definitions` describes (`CURIOUS_BUDGET`, `CURIOUS_OUT`, ...); nothing else imports it.
"""

from __future__ import annotations

from pipelines.definitions import definitions_from_environment

defs = definitions_from_environment()
