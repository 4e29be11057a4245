"""What a run will need, checked before anything is written.

A setting that asks for more memory than the machine has would otherwise fail far from its
cause: numpy allocates the replay lazily (a run fails hours in), a billion-row minibatch ends in
an allocation traceback after the run folder was written, a hundred thousand environment copies
run until the system kills the process. `check_memory` adds up the big parts of a run from its
settings alone and refuses, in one line naming the settings of the parts that take the most,
when they would not fit in the memory this machine can still give.

The sizes are lower bounds (arrays a run surely holds, networks with their gradients, Adam's
moments and targets), so a run that is refused could not have run; one that passes may still
need some more (Python, torch, MuJoCo themselves).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from curious.agent.conditions import Condition, make_condition
from curious.agent.replay import EpisodeReplay
from curious.config import Config, ConfigError
from curious.envs.goal_env import EnvSpec, SuiteEnv

SUITE_COPY_BYTES = 13 * 2**20
"""Memory of one suite environment copy (MuJoCo model, data and dm_control objects): 13.2 MiB
measured over 40 copies of `default` and 20 of `distractors_7` (2026-11-23)."""
USABLE = 0.9
"""Share of the available memory a run may plan to take."""


def available_memory() -> int:
    """Bytes of memory this machine can still give (MemAvailable where Linux reports it)."""
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


@dataclass(frozen=True)
class Part:
    """One big part of a run's memory and the settings that size it."""

    what: str
    settings: str  # how to lower it, naming the settings
    nbytes: int


def _network_params(in_dim: int, out_dim: int, hidden: int, layers: int) -> int:
    return in_dim * hidden + hidden + (layers - 1) * (hidden * hidden + hidden) + hidden * out_dim


def memory_parts(config: Config, spec: EnvSpec, n_experts: int, copy_bytes: int) -> list[Part]:
    """The big parts of a run of `config` on `spec` (see the module docstring); `copy_bytes`:
    the memory of one environment copy still to be built (0 where they exist already)."""
    c, s = config, spec
    n, g, a = s.n_modules, s.goal_dim, s.action_dim
    input_dim = s.state_dim + n * g + n
    copies = c.n_workers * (2 if c.test_rollouts_per_worker else 1)
    cycle_episodes = min(c.episodes_per_cycle, c.total_episodes)
    # A minibatch row: the sampled arrays (states, action, goals, masks, reward, indices), the
    # encoded inputs on the learner's side, and the activations kept for the backward passes of
    # the actor, the critic(s) and the critic under the actor.
    critics = 2 if c.algorithm == "td3" else 1
    row = 4 * (2 * s.state_dim + a + n * g + 2 * n + 1 + s.achieved_dim + g) + 8 * 8
    row += 4 * 2 * input_dim + 4 * 2 * (2 + critics) * c.layers * c.hidden
    per_expert = _network_params(input_dim, a, c.hidden, c.layers)
    per_expert += critics * _network_params(input_dim + a, 1, c.hidden, c.layers)
    return [
        Part(
            "the replay",
            "lower buffer_episodes (--set buffer_episodes=N keeps the newest N episodes) or "
            "total_episodes",
            EpisodeReplay.bytes_for(spec, c.replay_capacity),
        ),
        Part(
            f"{copies:,} environment copies",
            "lower n_workers",
            copies * copy_bytes,
        ),
        Part(
            "a cycle's episodes",
            "lower episodes_per_worker or n_workers",
            EpisodeReplay.bytes_for(spec, cycle_episodes),
        ),
        Part(
            f"minibatches of {c.batch_size:,} transitions",
            "lower batch_per_worker (the minibatch is batch_per_worker x n_workers)",
            (2 if c.prefetch_minibatches else 1) * c.batch_size * row,
        ),
        Part(
            "the networks (with gradients, Adam's moments and targets)",
            "lower hidden or layers",
            n_experts * per_expert * 4 * 5,
        ),
        Part(
            "the competence queues",
            "lower lp_window",
            n * 2 * c.lp_window * 8,
        ),
        Part(
            "an epoch's test rollouts",
            "lower test_rollouts_per_worker",
            c.test_rollouts_per_worker * c.n_workers * (64 + 8 * (s.episode_length + 1)),
        ),
    ]


def check_memory(config: Config, spec: EnvSpec, n_experts: int, copy_bytes: int = 0) -> None:
    """A `ConfigError` naming the settings to lower when a run of `config` would not fit in the
    memory available (see the module docstring)."""
    _check(memory_parts(config, spec, n_experts, copy_bytes), "this run needs")


def checked_condition(config: Config, spec: EnvSpec, copy_bytes: int = 0) -> Condition:
    """The condition of a run of `config` on `spec`, once `check_memory` with its experts has
    passed: a run's one place for both, called before its big allocations (`copy_bytes` as in
    `memory_parts`: called before the copies are built, it counts them too)."""
    condition = make_condition(config, spec)
    check_memory(config, spec, condition.n_experts, copy_bytes)
    return condition


def _check(parts: list[Part], needs: str) -> None:
    need = sum(p.nbytes for p in parts)
    have = available_memory()
    if need <= USABLE * have:
        return
    largest = max(parts, key=lambda p: p.nbytes)
    raise ConfigError(
        f"{needs} at least {need / 2**30:,.2f} GiB of memory, {largest.what} "
        f"{largest.nbytes / 2**30:,.2f} GiB of it, but this machine has {have / 2**30:.2f} GiB "
        f"available: {largest.settings}"
    )


def check_each_fits(configs: Sequence[Config]) -> None:
    """`check_memory` of each of `configs` alone, its suite copies still to be built: what a
    command that trains them in processes of their own checks before any starts."""
    for config in configs:
        spec = _suite_spec(config.variant)
        n_experts = make_condition(config, spec).n_experts
        check_memory(config, spec, n_experts, SUITE_COPY_BYTES)


def runs_that_fit(configs: Sequence[Config]) -> int:
    """How many of `configs`, taken in order, fit in this machine's memory together, each a
    process of its own building its suite copies (at least 1, so that a run too big alone meets
    its own error as it starts). Each run checks its own memory as it starts, not that of the
    runs beside it, so what trains runs side by side (`curious train --seeds`, `curious
    reproduce`) starts no more at a time than this."""
    need = np.cumsum([_run_bytes(config, _suite_spec(config.variant)) for config in configs])
    return max(1, int(np.searchsorted(need, USABLE * available_memory(), side="right")))


@functools.cache
def _suite_spec(variant: str) -> EnvSpec:
    """A suite variant's spec, from one copy built once."""
    return SuiteEnv(variant, seed=0).spec


def _run_bytes(config: Config, spec: EnvSpec) -> int:
    """The big parts of one run whose suite copies are still to be built, added up."""
    n_experts = make_condition(config, spec).n_experts
    return sum(part.nbytes for part in memory_parts(config, spec, n_experts, SUITE_COPY_BYTES))
