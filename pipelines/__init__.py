"""Dagster assets that train every condition and seed and rebuild the figures of the paper.

    curious reproduce --budget quick                            # the assets, materialised
    dagster-webserver -h 127.0.0.1 -m pipelines.code_location   # their graph in the UI

`pipelines.definitions` builds the `Definitions` of a budget; `pipelines.code_location` is the
module Dagster's tools load, whose `defs` are built from environment variables when it is
imported; importing this package, as every training worker does, imports neither.
"""
