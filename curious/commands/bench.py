"""`curious bench {env,learner,cycle,rollouts,recording,checkpoint}`: speed benchmarks, ours
side by side with a bound and a peer.

Each benchmark lives in a module of `benchmarks/` and exposes `measure(args) -> dict` with
at least the keys `ours`, `bound`, `peer` and `unit` (plus whatever detail it reports), and
`add_arguments(parser)` for its own options.
"""

from __future__ import annotations

import argparse
import importlib
import json

BENCHMARKS: dict[str, tuple[str, str]] = {
    "env": (
        "benchmarks.env_speed",
        "env steps/s: our suite vs the physics bound vs gymnasium-robotics FetchPickAndPlace",
    ),
    "learner": (
        "benchmarks.learner_speed",
        "DDPG+HER updates/s: ours vs the fp32 compute bound vs Stable-Baselines3",
    ),
    "cycle": (
        "benchmarks.cycle_speed",
        "training episodes/s of whole cycles: worker processes vs the serial path",
    ),
    "rollouts": (
        "benchmarks.rollout_scaling",
        "rollout episodes/s with 1, 2, ... worker processes vs the physics bound per core",
    ),
    "recording": (
        "benchmarks.recording_overhead",
        "training with vs without the Rerun recording: the overhead and the .rrd size",
    ),
    "checkpoint": (
        "benchmarks.checkpoint_cost",
        "a checkpoint's replay: only the new episodes vs the whole replay vs the raw write",
    ),
}


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious bench` and one sub-command per benchmark."""
    parser = sub.add_parser(
        "bench",
        help="speed benchmarks (ours vs bound vs peer)",
        description="Speed benchmarks, each measured side by side with its bound and a peer.",
    )
    bench_sub = parser.add_subparsers(dest="benchmark", metavar="BENCHMARK", required=True)
    for name, (module_name, help_text) in BENCHMARKS.items():
        p = bench_sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument("--json", action="store_true", help="print one JSON object")
        p.set_defaults(func=_run, module_name=module_name)
        try:
            importlib.import_module(module_name).add_arguments(p)
        except ModuleNotFoundError as exc:
            if exc.name != module_name:
                raise


def _run(args: argparse.Namespace) -> int:
    module = importlib.import_module(args.module_name)
    result = module.measure(args)
    if args.json:
        print(json.dumps(result))
    else:
        width = max(len(k) for k in result)
        for key, value in result.items():
            text = f"{value:,.1f}" if isinstance(value, float) else str(value)
            print(f"{key:<{width}}  {text}")
    return 0
