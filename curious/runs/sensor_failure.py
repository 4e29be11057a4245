"""When a run's sensory failure starts (the paper's perturbation study, Section 4.4).

The `sensor_failure` variant perturbs what the agent perceives of cube 3 (`docs/suite.md`). A
run switches the failure on either at a fixed episode (`Config.sensor_failure_episode`, the
authors' epoch 250) or with the first round of episodes after the perturbed module's
competence, over a full window of `lp_window` self-evaluations, reaches
`Config.sensor_failure_competence`. From its first episode on, every episode runs with it,
training and test alike; the episode it started at (`start`) is part of the run's checkpoint, so
a resumed run keeps it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from curious.agent.learning_progress import CompetenceTracker
from curious.config import Config, ConfigError
from curious.envs.batch import EnvBatch
from curious.envs.goal_env import EnvSpec, GoalEnv


class FailureSchedule:
    """A run's sensory-failure schedule: which episodes run with the failure, and switching it
    in the environment copies. A run without the failure gets one that never starts."""

    def __init__(
        self, config: Config, spec: EnvSpec, env: GoalEnv, copies: Sequence[EnvBatch]
    ) -> None:
        """`env`: a copy in this process (asked what it perturbs); `copies`: every batch of
        copies the run steps, whose failure is switched off here. A `ConfigError` where the env
        cannot have the failure the config asks for."""
        self.enabled = config.sensor_failure
        self.threshold = config.sensor_failure_competence
        self.window = config.lp_window
        self.start: int | None = None
        """First episode run with the failure (None: not started); saved in checkpoints."""
        self.module = -1
        """Index of the module the failure perturbs (-1: the env does not say)."""
        if self.enabled:
            self.module = self._check(config, spec, env, copies)
            if config.sensor_failure_episode >= 0:
                self.start = config.sensor_failure_episode

    def _check(
        self, config: Config, spec: EnvSpec, env: GoalEnv, copies: Sequence[EnvBatch]
    ) -> int:
        """Switch the failure off in every copy (a `ConfigError` where it cannot be); return the
        index of the module it perturbs (-1 when the env does not say)."""
        if not callable(getattr(env, "set_sensor_failure", None)):
            raise ConfigError(
                f"the sensory failure is set but {type(env).__name__} has no set_sensor_failure()"
            )
        env.set_sensor_failure(False)  # raises on a variant without the failure
        for batch in copies:
            batch.set_sensor_failure(np.zeros(len(batch), bool))
        name = getattr(env, "sensor_failure_module", None)
        if name is None:
            if config.sensor_failure_competence != -1.0:
                raise ConfigError(
                    "sensor_failure_competence needs an env that names the module its "
                    "failure perturbs (sensor_failure_module)"
                )
            return -1
        return spec.module_index(name)

    def on(self, episodes: np.ndarray) -> np.ndarray:
        """(n,) bool: which of these episodes run with the failure."""
        if self.start is None:
            return np.zeros(len(episodes), bool)
        return np.asarray(episodes) >= self.start

    def start_if_due(self, episode: int, tracker: CompetenceTracker) -> None:
        """Start the failure at `episode` if the perturbed module's competence reached the
        threshold, measured over a full window of its evaluations (a few lucky results are not a
        learned module)."""
        if self.start is None and self.threshold != -1.0:
            m = self.module
            full = tracker.counts[m] >= self.window
            if full and tracker.competence()[m] >= self.threshold:
                self.start = episode

    def apply(self, envs: EnvBatch, episodes: np.ndarray) -> np.ndarray:
        """Switch the failure on or off in the first copies of `envs` for a round of these
        episodes; (n,) bool, which run with it."""
        failing = self.on(episodes)
        if self.enabled:
            envs.set_sensor_failure(failing)
        return failing
