"""Dagster assets that train every condition and seed and rebuild the figures of the paper."""
