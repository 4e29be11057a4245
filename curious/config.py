"""The run configuration: the `Config` dataclass, the bounds and names of its settings, and its
validation (every `Config` that exists can run).

Defaults are the authors' settings (paper §6.2 and their release, flowersteam/curious: the files
named in the field docs are under its baselines/her/), each field saying the authors' value. The
presets that change a run's scale are `curious.presets`; the `key=value` overrides of the
command line are parsed by `curious.overrides`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from curious.registry import condition_names

ALGORITHMS: tuple[str, ...] = ("ddpg", "td3")
LP_MEASURES: tuple[str, ...] = ("absolute", "signed")
"""What LP measures (`Config.lp_measure`, `curious.agent.learning_progress`): `absolute`,
|recent - before| (the paper's), or `signed`, max(recent - before, 0)."""

LEARNER_BACKENDS: tuple[str, ...] = ("autograd", "compiled", "workspace")
DEVICES: tuple[str, ...] = ("cpu", "cuda")
EVAL_MODULE_RULES: tuple[str, ...] = ("released", "uniform")

# Fields that may differ between a run folder's stored config and the config of a `--resume`:
# they change how long or where a run goes on, not what it computes.
RESUMABLE_FIELDS: frozenset[str] = frozenset(
    {
        "total_episodes",
        "device",
        "act_on_cpu",
        "torch_threads",
        "env_processes",
        "prefetch_minibatches",
        "checkpoint_every_cycles",
        "progress",
    }
)


EARLIER_BEHAVIOUR: dict[str, Any] = {"lp_measure": "absolute"}
"""Settings added after runs were made, with the value that gives what those runs computed
without them: a config.json without the setting reads as that value, so that a run made before
it resumes and evaluates as itself (`curious.runs.folder.config_differences`). A setting whose
absence means another computation does not belong here."""


PLACEMENT_FIELDS: frozenset[str] = RESUMABLE_FIELDS - {"total_episodes", "progress"}
"""Settings of where and how fast a run goes that leave what it computes as it is (float
rounding aside): those `curious reproduce --set` may change for every run of a budget."""


MAX_SEED = 2**32 - 1
"""Seeds go from 0 to this: the suite seeds an episode with numpy's 32-bit `RandomState`
(`curious render --seed`), and the learners' torch seeds, derived from the run's, must fit 64
bits."""
MAX_EPISODES = 10**10
"""Upper bound of the settings that count episodes, rounds of episodes or cycles
(`EPISODE_COUNTS`): ten billion episodes, 33,000 times the paper's 300,000, more than any
machine trains in a year; past it a run would go on for ever in practice, and products of these
counts (episodes x steps, cycles x episodes) would leave the 64-bit integers of the tables and
of numpy, where Python's unbounded ints stop with an `OverflowError`."""
EPISODE_COUNTS: tuple[str, ...] = (
    "total_episodes",
    "buffer_episodes",
    "eval_every",
    "sensor_failure_episode",
    "n_cycles",
    "checkpoint_every_cycles",
    "episodes_per_worker",
    "test_rollouts_per_worker",
    "lp_window",
    "n_workers",
    "batch_per_worker",
    "hidden",
    "layers",
)
"""The integer settings bounded by `MAX_EPISODES` (those of sizes, `n_workers` to `layers`, are
bounded by the memory check first, `curious.runs.memory`, this bound keeping the check's sums
within 64 bits)."""
MAX_UPDATES = 100_000
"""Upper bound of `n_updates` (gradient steps per cycle) and `td3_policy_delay` (in gradient
steps): 1,000 times the authors' 100; a cycle of more would spend hours on updates between two
rounds of episodes, a run of them never ending."""
MAX_THREADS = 1_024
"""Upper bound of `torch_threads` and `env_processes`: more threads or processes than any
machine has cores (torch takes the count as a C int)."""
MIN_NORM_EPS = 1e-8
"""Lower bound of `norm_eps`, the floor of the state normaliser's std: states are float32, whose
rounding (about 1e-7 of a value) makes a coordinate that never varies differ from its mean by
that much; divided by a floor far below it, rounding noise becomes a normalised value at the
clip, and a floor below about 1e-19 squares to nothing in float32, where the normaliser divides
by zero and training diverges."""
MAX_NORM_EPS = 1e3
"""Upper bound of `norm_eps`: states are positions (metres), velocities and angles of a few
units at most; with a floor 1,000 times their size every normalised state is 0 to three
decimals and the policy sees nothing (and a floor past 1e154 overflows when squared)."""
MAX_LEARNING_RATE = 1.0
"""Upper bound of `actor_lr` and `critic_lr` (see `Config.validate`)."""
MAX_NOISE = 1.0
"""Upper bound of the action noises, which are fractions of the largest action (1)."""
LEARNED_COMPETENCE = 0.5
"""Competence at which a module counts as learned, for the sensory failure: the `laptop` budget
starts the failure once push_cube3 reaches it (`sensor_failure_competence`), and the recovery
analysis asks it of the perturbed module just before the failure, in runs that set no
`sensor_failure_competence` of their own, before it counts a fall as forgetting. Half the
evaluations succeeding: well above the floor of chance successes of push modules (a goal can lie
within reach of where the cube already is), so that a fall means something was lost."""

DEFAULT_TEST_EPOCHS = 5
"""How many of a run's last epochs its current test success pools (`curious progress`, the
milestones, the recovery by test success): a `laptop` epoch tests each module about 40 / N
times, too few alone to read."""


class ConfigError(ValueError):
    """A configuration that cannot run: unknown preset, condition, key or a bad value."""


@dataclass(frozen=True)
class Config:
    """Everything a training run depends on. One condition, one seed.

    Scale: an *episode* is one rollout of `episode_length` steps in one worker; a *cycle* runs
    `episodes_per_worker` rounds of `n_workers` parallel episodes, then `n_updates` gradient
    steps, then one target-network update; an *epoch* is `n_cycles` cycles (mg-te trains one
    expert per epoch).
    """

    # --- what is run -------------------------------------------------------------------------
    condition: str = "curious"
    """`curious` (LP task selection and replay), `m-uvfa` (uniform selection and replay),
    `mg-te` (one expert per module, trained in turn), `her` (one holistic goal); and, not in the
    paper, `lp-select` (LP selection, uniform replay) and `lp-replay` (uniform selection, LP
    replay)."""
    seed: int = 0
    """Seeds networks, the agent's random choices and every environment copy."""
    preset: str = "paper"
    """Name of the preset the run was resolved from (recorded, not used after resolving): a
    label, so `Config(preset="smoke")` keeps the `paper` numbers; `resolve("smoke")` applies
    the preset."""
    variant: str = "default"
    """Suite variant (`suite.ALL_VARIANTS`) trained on."""
    total_episodes: int = 300_000
    """The run stops after exactly this many training episodes (self-evaluations included, test
    rollouts not), at most `MAX_EPISODES` (ten billion), as every count of episodes, rounds or
    cycles. Authors: 316 epochs x 950 = ~300k."""

    # --- rollouts ----------------------------------------------------------------------------
    n_workers: int = 19
    """Environment copies stepped together in one process (one batched policy call per step).
    Authors: 19 MPI workers (the paper's runs)."""
    env_processes: int = 1
    """Worker processes that step the `n_workers` environment copies at the same time (each a
    share of them; 1 steps them in the training process, 0 takes one per core, at most
    `n_workers`; at most `MAX_THREADS` asked). Whatever the number, a run gives the same
    episodes. With more than 1, `train()` builds the suite's copies in the workers, and the test
    rollouts' copies in as many workers of their own."""
    overlap_rollouts: bool = False
    """Collect the next cycle's episodes while this cycle's updates run (in a thread, with the
    policy as it was before them: acting lags learning by one cycle, and module choices follow
    the competence queues as they were when the cycle's collection began). The authors were
    synchronous; False keeps to them. Checkpoints hold no episodes in flight, so a resumed run
    equals an uninterrupted one either way."""
    episodes_per_worker: int = 2
    """Rounds of `n_workers` parallel episodes per cycle. Authors: rollout_batch_size 2."""
    n_cycles: int = 25
    """Cycles per epoch (25 x 2 x 19 = 950 episodes per epoch with the authors' sizes). Authors:
    25."""
    eval_every: int = 10
    """Every `eval_every`-th episode (by global index) is a self-evaluation without noise, on a
    module chosen as `eval_modules` says; its final success feeds that module's competence.
    Authors: a rollout is a self-evaluation with probability 0.1 (rollout.py); every 10th is the
    same rate, counted exactly. The `her` condition has none (the authors' flat agent)."""
    eval_modules: str = "released"
    """Which modules the single-policy conditions (`curious`, `m-uvfa`, `lp-select`,
    `lp-replay`) self-evaluate and practise. `released`: the authors' code (rollout.py), which
    made the paper's figures: once per cycle, with probability 1 / `eval_every` (the chance that
    their rank-0 worker self-evaluates), every module of the cycle, practised or evaluated, is
    drawn uniformly; otherwise every one is drawn from the practice probabilities (p_LP for
    `curious` and `lp-select`, uniform for the others). Evaluations then follow about
    0.9 p_LP + 0.1 uniform: the module in focus refills its competence queue faster, a neglected
    one slower. `uniform`: the paper's text (§6.2, "evaluates itself on random tasks"):
    evaluations on modules drawn uniformly, practice from the practice probabilities. `mg-te`
    always evaluates its epoch's module with its expert, as the authors' task experts did, and
    `her` never self-evaluates (the authors' flat agent did not), whatever this says."""
    test_rollouts_per_worker: int = 10
    """Noise-free test rollouts per environment copy after every epoch (authors: 5 test
    rollouts x 2 parallel episodes = 10 per worker, 190 per epoch with 19 workers), each on a
    module drawn uniformly with a goal uniform in its space, on copies of their own. They are not
    training episodes: not stored, not counted in `total_episodes`, no effect on competence, LP
    or any random draw of training. Their success (`tests.parquet`) is what Fig. 2a plots, as
    the paper's. 0 runs none."""
    noise_eps: float = 0.2
    """Std of the Gaussian action noise, as a fraction of the maximal action (1), in [0, 1].
    Authors: 0.2 (experiment/config.py)."""
    random_eps: float = 0.3
    """Probability that an exploring step takes a uniform random action instead. Authors: 0.3
    (experiment/config.py)."""

    # --- learner -----------------------------------------------------------------------------
    algorithm: str = "ddpg"
    """`ddpg` (the authors') or `td3` (twin critics, target smoothing, delayed actor)."""
    learner_backend: str = "autograd"
    """How the update runs, the same arithmetic each: `autograd` (the reference, readable),
    `compiled` (each step, losses, backward and Adam, through `torch.compile`; on CUDA each step
    one CUDA graph with a capturable Adam, DDPG's backward traced into it, docs/scaling.md) or
    `workspace` (both passes written out into preallocated buffers; the fastest on a CPU,
    docs/benchmarks.md)."""
    hidden: int = 256
    """Units per hidden layer of actor and critic. Authors: 256."""
    layers: int = 3
    """Hidden layers of actor and critic. Authors: 3."""
    actor_lr: float = 1e-3
    """Adam learning rate of the actor, in (0, 1]. Authors: pi_lr 1e-3."""
    critic_lr: float = 1e-3
    """Adam learning rate of the critic, in (0, 1]. Authors: Q_lr 1e-3. A rate within the range
    may still make training diverge: the first non-finite loss or action stops the run with an
    error naming both rates, its last checkpoint intact
    (`curious.runs.trainer.TrainingDiverged`)."""
    gamma: float = 0.98
    """Discount; targets are clipped to [-1/(1-gamma), 0] (rewards are -1 or 0). Authors:
    1 - 1/T = 0.98 with clip_return."""
    polyak: float = 0.95
    """target <- polyak * target + (1 - polyak) * online, once per cycle. Authors: 0.95."""
    action_l2: float = 1.0
    """Weight of the mean squared (pre-noise) action in the actor loss. Authors: 1.0."""
    batch_per_worker: int = 256
    """Transitions per worker per update; the minibatch is `batch_per_worker * n_workers`, which
    equals the authors' mean of per-worker gradients. Authors: 256 per worker."""
    n_updates: int = 100
    """Gradient steps per cycle, at most `MAX_UPDATES` (100,000). Authors: n_batches 100."""
    prefetch_minibatches: bool = False
    """Draw and relabel the next minibatch in a thread while the learner steps on this one. The
    same draws in the same order, so the same run; it pays where the update does not hold the
    interpreter (`--device cuda`), and hardly on a CPU, where sampling is a few % of a cycle."""
    norm_clip: float = 5.0
    """Normalised states are clipped to [-norm_clip, norm_clip], and scaled goals (`GoalBox`) to
    as many half-widths of their goal space. Authors: 5 (Baselines; unused by their default,
    which trained without normalisation)."""
    norm_eps: float = 0.01
    """Lower bound of the state normaliser's std, in [`MIN_NORM_EPS`, `MAX_NORM_EPS`] (1e-8 to
    1e3). Authors: 0.01."""
    td3_target_noise: float = 0.2
    """TD3's target smoothing noise (std), in [0, 1] of the largest action."""
    td3_noise_clip: float = 0.5
    """TD3's clip of that noise, in [0, 1]."""
    td3_policy_delay: int = 2

    # --- replay ------------------------------------------------------------------------------
    buffer_episodes: int = 0
    """Replay capacity in episodes; 0 keeps every episode of the run (capacity
    `total_episodes`). The authors' per-task buffers (1e6 transitions per worker) evicted nothing
    in a 300k-episode run, so every preset keeps the whole run. A lower capacity evicts the
    oldest episodes first (first in, first out): early experience, such as the first pushes,
    is then no longer replayed. The memory it takes is checked before training starts."""
    her_p: float = 0.8
    """Probability that a replayed transition is relabelled: the replayed module and one of its
    outcomes reached later in the same episode; the others keep their episode's module and goal.
    Authors: replay_k 4, i.e. 0.8 (her.py)."""
    replay_active_only: bool = True
    """Replay a module only on episodes where its outcome changed; falls back to every episode
    while there is none. Authors: one buffer per module holding the episodes where its outcome
    changed (ddpg.py, store_episode)."""
    moved_threshold: float = 1e-3
    """An outcome 'changed' when a goal coordinate moved more than this between the first and
    the final step. Authors: 1e-3 (rollout.py, the `change` flags)."""

    # --- learning progress -------------------------------------------------------------------
    lp_window: int = 300
    """Competence is the mean of a module's last `lp_window` evaluation results; LP compares it
    with the `lp_window` results before. Authors: queue_length 300 (experiment/config.py)."""
    lp_eps: float = 0.4
    """p_LP = lp_eps / N + (1 - lp_eps) * LP / sum(LP). Authors: 0.4 (rollout.py)."""
    lp_measure: str = "absolute"
    """What a module's LP measures, from its competence now (the last `lp_window` results) and
    before (the `lp_window` before them): `absolute`, |now - before|, so that a falling
    competence raises LP and forgetting draws practice back (the paper's, §6.2; authors:
    queues.py); or `signed`, now - before counted as 0 where it is negative, so that only a
    rising competence draws practice (not in the paper). p_LP is formed from it in every
    condition that reads LP (`curious`, `lp-select`, `lp-replay`), for practice and replay
    alike, and the `lp/<module>` columns of metrics.parquet log it (never negative, either
    way). It changes the run: `--resume` refuses another value."""

    # --- perturbation --------------------------------------------------------------------------
    sensor_failure_episode: int = -1
    """From this episode on (global, 0-based) every episode, training and test, runs with the
    sensory failure of the `sensor_failure` variant (cube 3's x reads 5 cm too far, in the state
    and in the outcome of `push_cube3`; the authors switched it on at epoch 250 of 316); -1 never.
    The switch follows each episode's index, so a resumed run switches at the same episode."""
    sensor_failure_competence: float = -1.0
    """Instead of a fixed episode: the failure starts with the first round of episodes after the
    perturbed module's competence, over a full window of `lp_window` evaluations, first reaches
    this value (so that there is something to forget at any budget); -1 never. The episode it
    started at is in `metrics.parquet`."""

    # --- running -----------------------------------------------------------------------------
    device: str = "cpu"
    """`cpu` or `cuda` (networks and updates; environments always run on the CPU)."""
    act_on_cpu: bool = False
    """With `device=cuda`: the rollouts' policy calls run on a CPU copy of the actors, taken
    after each cycle's updates, where a forward pass of `n_workers` rows per step may cost less
    than a round trip to the GPU (the same policy, float rounding aside; no effect on a CPU)."""
    torch_threads: int = 1
    """torch intra-op threads (0 keeps torch's default), at most `MAX_THREADS`."""
    checkpoint_every_cycles: int = 50
    """A checkpoint (and a metrics flush) every this many cycles, and at the end."""
    progress: bool = True
    """Show a progress bar."""

    # ------------------------------------------------------------------------------------------
    @property
    def episodes_per_cycle(self) -> int:
        return self.n_workers * self.episodes_per_worker

    @property
    def batch_size(self) -> int:
        return self.batch_per_worker * self.n_workers

    def samples_per_stored_transition(self, episode_length: int = 50) -> float:
        """Replayed transitions per transition stored, per cycle: `n_updates * batch_size`
        over `episodes_per_cycle * episode_length`. Authors: 100 x 256 / (2 x 50) = 256 per
        worker (experiment/config.py), whatever the number of workers."""
        stored = self.episodes_per_cycle * episode_length
        return self.n_updates * self.batch_size / stored

    @property
    def processes(self) -> int:
        """The environment worker processes this run uses (`env_processes` resolved)."""
        wanted = self.env_processes or os.cpu_count() or 1
        return max(1, min(wanted, self.n_workers))

    @property
    def sensor_failure(self) -> bool:
        """Whether the run switches the sensory failure on at some point."""
        return self.sensor_failure_episode >= 0 or self.sensor_failure_competence != -1.0

    @property
    def replay_capacity(self) -> int:
        """Episodes the replay holds: `buffer_episodes`, or the whole run when it is 0."""
        return self.buffer_episodes or self.total_episodes

    def __post_init__(self) -> None:
        # a numpy scalar (a seed drawn with numpy, a value read from a table) is taken as its
        # Python value, so that config.json can hold it; an int given for a float is taken as
        # that float; nothing else is converted
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.generic):
                value = value.item()
            if str(f.type) == "float" and isinstance(value, int) and not isinstance(value, bool):
                value = float(value)
            object.__setattr__(self, f.name, value)
        self.validate()  # every Config that exists can run: built, replaced or loaded

    def validate(self) -> Config:
        """Raise `ConfigError` naming the first field with a value that cannot run: of the
        wrong type (`n_workers=2.0`, `seed="0"`, `overlap_rollouts="false"`), or out of its
        range."""
        for f in fields(self):
            _check_type(f.name, str(f.type), getattr(self, f.name))
        if not 0 <= self.seed <= MAX_SEED:
            raise ConfigError(f"seed (--seed) must be from 0 to {MAX_SEED:,}, got {self.seed}")
        _check_condition(self.condition)
        if self.algorithm not in ALGORITHMS:
            raise ConfigError(
                f"unknown algorithm {self.algorithm!r}; choose one of {', '.join(ALGORITHMS)}"
            )
        if self.learner_backend not in LEARNER_BACKENDS:
            raise ConfigError(
                f"unknown learner_backend {self.learner_backend!r}; choose one of "
                f"{', '.join(LEARNER_BACKENDS)}"
            )
        if self.eval_modules not in EVAL_MODULE_RULES:
            raise ConfigError(
                f"unknown eval_modules {self.eval_modules!r}; choose one of "
                f"{', '.join(EVAL_MODULE_RULES)}"
            )
        if self.lp_measure not in LP_MEASURES:
            raise ConfigError(
                f"unknown lp_measure {self.lp_measure!r}; choose one of {', '.join(LP_MEASURES)}"
            )
        if self.device not in DEVICES:
            raise ConfigError(f"unknown device {self.device!r}; choose one of {DEVICES}")
        positive = (
            "total_episodes n_workers episodes_per_worker n_cycles eval_every hidden layers "
            "batch_per_worker lp_window checkpoint_every_cycles td3_policy_delay"
        ).split()
        for name in positive:
            if getattr(self, name) <= 0:
                raise ConfigError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.buffer_episodes < 0:
            raise ConfigError(
                f"buffer_episodes must be >= 0 (0 keeps the whole run), got {self.buffer_episodes}"
            )
        stored_at_once = min(self.n_workers, self.total_episodes)
        if 0 < self.buffer_episodes < stored_at_once:
            raise ConfigError(
                f"buffer_episodes must be 0 (the whole run) or at least {stored_at_once:,}, the "
                f"episodes a round stores at once (n_workers), got {self.buffer_episodes:,}"
            )
        if self.env_processes < 0:
            raise ConfigError(
                f"env_processes must be >= 0 (0: one per core), got {self.env_processes}"
            )
        if self.n_updates < 0 or self.torch_threads < 0:
            raise ConfigError("n_updates and torch_threads must be >= 0")
        bounds = dict.fromkeys(EPISODE_COUNTS, ("MAX_EPISODES", MAX_EPISODES))
        bounds.update(
            dict.fromkeys(("n_updates", "td3_policy_delay"), ("MAX_UPDATES", MAX_UPDATES))
        )
        bounds.update(
            dict.fromkeys(("torch_threads", "env_processes"), ("MAX_THREADS", MAX_THREADS))
        )
        for name, (constant, bound) in bounds.items():
            if getattr(self, name) > bound:
                raise ConfigError(
                    f"{name} must be at most {bound:,}, got {getattr(self, name):,} (why: "
                    f"curious.config.{constant})"
                )
        if self.test_rollouts_per_worker < 0:
            raise ConfigError(
                f"test_rollouts_per_worker must be >= 0, got {self.test_rollouts_per_worker}"
            )
        c = self.sensor_failure_competence
        if c != -1.0 and not 0.0 < c <= 1.0:
            raise ConfigError(f"sensor_failure_competence must be in (0, 1] or -1, got {c}")
        if c != -1.0 and self.sensor_failure_episode >= 0:
            raise ConfigError("set sensor_failure_episode or sensor_failure_competence, not both")
        if c != -1.0 and self.condition == "her":
            raise ConfigError(
                "sensor_failure_competence needs self-evaluations, and the her condition has "
                "none (the authors' flat agent); use sensor_failure_episode"
            )
        if self.sensor_failure_episode < -1:
            raise ConfigError(
                f"sensor_failure_episode must be an episode (>= 0) or -1 for never, "
                f"got {self.sensor_failure_episode}"
            )
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, float) and not math.isfinite(value):
                raise ConfigError(f"{f.name} must be a finite number, got {value}")
        if self.norm_clip <= 0:
            raise ConfigError(f"norm_clip must be > 0, got {self.norm_clip}")
        if not MIN_NORM_EPS <= self.norm_eps <= MAX_NORM_EPS:
            raise ConfigError(
                f"norm_eps must be in [{MIN_NORM_EPS:g}, {MAX_NORM_EPS:g}], got {self.norm_eps:g}: "
                "the floor of the normaliser's std, below which float32 rounding noise reaches "
                "the clip, above which every normalised state is about 0 (the authors' is 0.01)"
            )
        for name in ("actor_lr", "critic_lr"):
            if not 0.0 < getattr(self, name) <= MAX_LEARNING_RATE:
                raise ConfigError(
                    f"{name} must be in (0, {MAX_LEARNING_RATE:g}], got {getattr(self, name)}: "
                    "Adam moves every weight by about the learning rate at each step, so a "
                    "rate above 1 cannot learn (the authors' is 1e-3)"
                )
        for name in ("action_l2", "moved_threshold"):
            if getattr(self, name) < 0:
                raise ConfigError(f"{name} must be >= 0, got {getattr(self, name)}")
        for name in ("noise_eps", "td3_target_noise", "td3_noise_clip"):
            if not 0.0 <= getattr(self, name) <= MAX_NOISE:
                raise ConfigError(
                    f"{name} must be in [0, {MAX_NOISE:g}], got {getattr(self, name)}: a fraction "
                    "of the largest action, 1, beyond which every noisy action is clipped to "
                    "the bounds (the authors' noise_eps is 0.2)"
                )
        for name in ("her_p", "lp_eps", "random_eps", "polyak"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ConfigError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if not 0.0 < self.gamma < 1.0:
            raise ConfigError(f"gamma must be in (0, 1), got {self.gamma}")
        return self

    def to_dict(self) -> dict[str, Any]:
        """The settings as plain JSON-able values."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Config:
        """Inverse of `to_dict`; unknown keys and values of the wrong type are errors (an int
        is taken for a float, nothing else is converted)."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"a config is a mapping of settings, got {type(data).__name__}")
        unknown = sorted(set(data) - set(setting_names()))
        if unknown:
            raise ConfigError(f"unknown config keys: {', '.join(unknown)}")
        return cls(**data)


def _check_type(name: str, kind: str, value: Any) -> None:
    """A `ConfigError` unless `value` is of the field's type (`kind`: int, float, bool or str;
    an int counts as a float, a bool as neither number)."""
    fits = {
        "int": isinstance(value, int) and not isinstance(value, bool),
        "float": isinstance(value, int | float) and not isinstance(value, bool),
        "bool": isinstance(value, bool),
        "str": isinstance(value, str),
    }[kind]
    if not fits:
        article = "an" if kind == "int" else "a"
        raise ConfigError(f"{name} must be {article} {kind}, got {value!r}")


def setting_names() -> tuple[str, ...]:
    """Names of the fields a user may set."""
    return tuple(f.name for f in fields(Config))


OWN_OPTIONS: dict[str, str] = {
    "preset": "--preset",
    "condition": "--condition",
    "seed": "--seed (or --seeds)",
}
"""The settings that name a run rather than tune it, each with its own option: as an override
one would silently win over that option (`--condition curious --set condition=her` trains HER),
and `--set seed=3` would give every run of `--seeds 0-4` the same seed."""


def _check_condition(condition: str) -> None:
    names = condition_names()
    if condition not in names:
        raise ConfigError(f"unknown condition {condition!r}; choose one of {', '.join(names)}")
