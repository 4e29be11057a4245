"""Reproducing the paper: the experiments per budget, and shipping finished runs as data."""
