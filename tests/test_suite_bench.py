"""`curious bench env` runs and reports ours, the physics bound and the peer side by side."""

from __future__ import annotations

import argparse
import math

from benchmarks import env_speed


def test_env_benchmark_reports_all_three():
    parser = argparse.ArgumentParser()
    env_speed.add_arguments(parser)
    args = parser.parse_args(["--episodes", "1"])
    result = env_speed.measure(args)
    assert {"ours", "bound", "peer", "unit"} <= set(result)
    assert result["unit"] == "env steps/s"
    for key in ("ours", "bound", "peer", "bound_static"):
        assert math.isfinite(result[key]) and result[key] > 0, key
    assert result["ours_pct_of_bound"] == 100 * result["ours"] / result["bound"]
