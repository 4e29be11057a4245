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

import os
from collections.abc import Sequence
from dataclasses import dataclass

from curious.agent.replay import EpisodeReplay
from curious.config import Config, ConfigError
from curious.envs.goal_env import EnvSpec

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


def check_population_memory(
    runs: Sequence[tuple[Config, EnvSpec, int]], copy_bytes: int = 0
) -> None:
    """`check_memory` for runs trained at once in one process, each (config, spec, n_experts):
    their parts add up, and the error says how many runs asked for it."""
    parts = [p for run in runs for p in memory_parts(*run, copy_bytes)]
    _check(parts, f"these {len(runs)} runs trained at once need", " (or train fewer at once)")


def _check(parts: list[Part], needs: str, also: str = "") -> None:
    need = sum(p.nbytes for p in parts)
    have = available_memory()
    if need <= USABLE * have:
        return
    largest = max(parts, key=lambda p: p.nbytes)
    raise ConfigError(
        f"{needs} at least {need / 2**30:,.2f} GiB of memory, {largest.what} "
        f"{largest.nbytes / 2**30:,.2f} GiB of it, but this machine has {have / 2**30:.2f} GiB "
        f"available: {largest.settings}{also}"
    )
