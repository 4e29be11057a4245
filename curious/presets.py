"""The four presets (`smoke`, `quick`, `laptop`, `paper`), and `resolve`: a preset with a
condition, a seed and overrides, as one validated `Config`.

A preset changes the scale of a run, never the algorithm: each keeps the authors' networks,
learner settings, HER and replay rules and p_LP unless its comment says otherwise.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from curious.config import OWN_OPTIONS, Config, ConfigError, setting_names

PRESETS: dict[str, dict[str, Any]] = {
    # Every preset keeps the algorithm and its settings (networks, learning rates, discount,
    # noise, HER, replay rules, p_LP) unless it says otherwise below; it changes the scale: the
    # number of workers, the updates per cycle and their minibatch (hence the replay ratio,
    # `Config.samples_per_stored_transition`: the authors' is 256), and the competence window.
    # Seconds: for tests and CI. Tiny networks, a handful of episodes, every code path touched
    # (evaluations, updates, target updates, a checkpoint, an epoch boundary).
    "smoke": dict(
        total_episodes=24,
        n_workers=2,
        episodes_per_worker=2,
        n_cycles=2,
        hidden=32,
        layers=2,
        batch_per_worker=32,
        n_updates=4,
        lp_window=4,
        checkpoint_every_cycles=3,
        eval_every=5,
        test_rollouts_per_worker=1,
    ),
    # A few minutes on a 2-core laptop: enough for reach. Keeps the authors' networks and
    # learner settings. Changes: 2 workers (authors 19), 128 transitions per worker per update
    # (256) and 20 updates per cycle (100), i.e. 25.6 replayed transitions per stored one (256),
    # a competence window of 20 (300), a self-evaluation every 5th episode (10th).
    "quick": dict(
        total_episodes=1_200,
        n_workers=2,
        episodes_per_worker=2,
        n_cycles=25,
        batch_per_worker=128,
        n_updates=20,
        lp_window=20,
        checkpoint_every_cycles=50,
        eval_every=5,
    ),
    # Hours on 2 cores: enough episodes for the developmental phases (reach, then push).
    # Keeps the authors' networks, learner settings and evaluation rate. Changes: 4 workers
    # (authors 19), 128 transitions per worker per update (256) and 40 updates per cycle (100),
    # i.e. 51.2 replayed transitions per stored one (256), a competence window of 100 (300),
    # 100,000 episodes (~300,000).
    "laptop": dict(
        total_episodes=100_000,
        n_workers=4,
        episodes_per_worker=2,
        n_cycles=25,
        batch_per_worker=128,
        n_updates=40,
        lp_window=100,
        checkpoint_every_cycles=100,
    ),
    # The authors' protocol: 19 workers x 2 episodes x 25 cycles per epoch, 100 updates of
    # 256 per worker per cycle (256 replayed transitions per stored one), a window of 300,
    # ~300k episodes. For a cluster node or a GPU.
    "paper": dict(),
}


def resolve(
    preset: str,
    condition: str = "curious",
    seed: int = 0,
    overrides: dict[str, Any] | None = None,
) -> Config:
    """The config of a preset with a condition, a seed and overrides applied, validated.

    `overrides` maps setting names to values (`parse_overrides` turns `["key=value", ...]`
    into one); the preset, condition and seed are this function's own arguments, never
    overrides: one there would label the run with one and train it with another."""
    if preset not in PRESETS:
        raise ConfigError(f"unknown preset {preset!r}; choose one of {', '.join(PRESETS)}")
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ConfigError(
            f"overrides maps setting names to values, got a {type(overrides).__name__}: "
            "parse_overrides turns ['key=value', ...] into one"
        )
    values: dict[str, Any] = dict(PRESETS[preset])
    values.update(condition=condition, seed=seed, preset=preset)
    for key, value in (overrides or {}).items():
        if key not in setting_names():
            raise ConfigError(f"unknown config key {key!r}")
        if key in OWN_OPTIONS:
            raise ConfigError(f"{key} is resolve's own argument, not an override")
        values[key] = value
    return dataclasses.replace(Config(), **values)
