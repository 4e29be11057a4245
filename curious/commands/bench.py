"""`curious bench {env,learner,relabel,cycle,rollouts,seeds,recording,checkpoint,resume,heap}`:
speed and memory benchmarks, ours side by side with a bound and a peer.

Each benchmark lives in a module of `benchmarks/` and exposes `measure(args) -> dict` with
at least the keys `ours`, `bound`, `peer` and `unit` (plus whatever detail it reports), and
`add_arguments(parser)` for its own options.
"""

from __future__ import annotations

import argparse
import importlib
import json
from typing import Any

from curious.commands import CommandParser

BENCHMARKS: dict[str, tuple[str, str]] = {
    "env": (
        "benchmarks.env_speed",
        "env steps/s: our suite vs the physics bound vs gymnasium-robotics FetchPickAndPlace",
    ),
    "learner": (
        "benchmarks.learner_speed",
        "DDPG+HER updates/s: ours vs the fp32 compute bound vs Stable-Baselines3",
    ),
    "relabel": (
        "benchmarks.relabel_speed",
        "relabelled minibatches/s from the suite's replay: row by row vs module by module",
    ),
    "cycle": (
        "benchmarks.cycle_speed",
        "training episodes/s of whole cycles: rollouts overlapped with updates vs the serial path",
    ),
    "rollouts": (
        "benchmarks.rollout_scaling",
        "rollout episodes/s with 1, 2, ... worker processes vs the physics bound per core",
    ),
    "seeds": (
        "benchmarks.seeds_speed",
        "training episodes/s of runs side by side: curious train --seeds vs processes started "
        "by hand",
    ),
    "recording": (
        "benchmarks.recording_overhead",
        "training with vs without the Rerun recording: the overhead and the .rrd size",
    ),
    "checkpoint": (
        "benchmarks.checkpoint_cost",
        "a checkpoint's replay: only the new episodes vs the whole replay vs the raw write",
    ),
    "resume": (
        "benchmarks.resume_memory",
        "a resume's memory: the replay read into its own arrays vs read, copied and kept vs "
        "the replay's bytes",
    ),
    "heap": (
        "benchmarks.heap_growth",
        "a training process's heap: freed memory given back vs the allocators' defaults vs "
        "what it holds in use",
    ),
}


class _BenchmarkParser(CommandParser):
    """A benchmark's parser, which imports the benchmark's module for its options only when the
    command line names that benchmark: `curious --help` and `curious bench --help` import no
    benchmark (they import torch and MuJoCo)."""

    def __init__(self, *args: Any, module_name: str | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._module_name = module_name

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        if self._module_name is not None:
            name, self._module_name = self._module_name, None
            try:
                importlib.import_module(name).add_arguments(self)
            except ModuleNotFoundError as exc:
                if exc.name != name:
                    raise
        return super().parse_known_args(args, namespace)


def register(sub: argparse._SubParsersAction) -> None:
    """Add `curious bench` and one sub-command per benchmark."""
    parser = sub.add_parser(
        "bench",
        help="speed benchmarks (ours vs bound vs peer)",
        description="Speed benchmarks, each measured side by side with its bound and a peer.",
    )
    bench_sub = parser.add_subparsers(
        dest="benchmark", metavar="BENCHMARK", required=True, parser_class=_BenchmarkParser
    )
    for name, (module_name, help_text) in BENCHMARKS.items():
        p = bench_sub.add_parser(
            name, help=help_text, description=help_text, module_name=module_name
        )
        p.add_argument("--json", action="store_true", help="print one JSON object")
        p.set_defaults(func=_run, module_name=module_name)


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
