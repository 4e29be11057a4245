"""The conditions the paper compares, and two that split CURIOUS in halves, as small strategies
the training loop asks: which modules the next episodes practise or evaluate and with which
goals, how an episode is scored, which modules relabelled transitions are replayed as, and which
expert acts or learns. Everything else (networks, learner, replay, rollouts) is shared.

Self-evaluations. Every `eval_every`-th episode is a self-evaluation without exploration noise;
its final success goes to that module's competence queue. Which module it evaluates, and which
the practice episodes practise, follows `Config.eval_modules` in the single-policy conditions:

* `released` (the authors' code, flowersteam/curious baselines/her/rollout.py, which made the
  paper's figures): there, rank 0 draws the module of every worker's episodes from its own
  selection probabilities, and a worker that self-evaluates keeps the module it was given; only
  rank 0's own self-evaluations (probability 0.1 per call of `generate_rollouts`) switch its
  probabilities to uniform, and then for every worker. One such call is one of our cycles (19
  workers x 2 episodes = our `n_workers` x `episodes_per_worker`), the 0.1 is our
  1 / `eval_every`, so once per cycle, with that probability, every module of the cycle is drawn
  uniformly, and otherwise every one from the practice probabilities (`lead_draw`, `modules`).
  Evaluations and practice then both follow about 0.9 p + 0.1 uniform: the module in focus
  refills its competence queue many times faster than a neglected one, which sharpens its LP and
  slows the notice of forgetting elsewhere. (The released code also made rank 0's own
  evaluations, 1/19 of all, always uniform; ours keep the fixed evaluation schedule, so that
  share follows the cycle's draw like the others: docs/agent.md.)
* `uniform` (the paper's text, §6.2: the agent "evaluates itself on random tasks"): evaluations
  on modules drawn uniformly, practice from the practice probabilities, so that every module's
  queue fills at the same rate.

The conditions:

* `curious`: one E-UVFA policy; the next module and the module each relabelled transition is
  replayed as (task replay, `curious.agent.replay`) are drawn from p_LP, the latter over the modules
  that have an episode to replay (the authors' buffers with something in them, ddpg.py
  `sample_batch`: eps / n + (1 - eps) LP / sum LP over those n modules).
* `m-uvfa`: the same policy with uniform module selection and uniform task replay over the
  modules that have an episode to replay (the later paper's ablation of learning progress).
* `lp-select` and `lp-replay` (not in the paper): each keeps one of CURIOUS's two uses of LP and
  takes M-UVFA's uniform draw for the other. `lp-select` practises modules drawn from p_LP and
  replays transitions as modules drawn uniformly over those with an episode to replay;
  `lp-replay` practises modules drawn uniformly and replays as modules drawn from p_LP over
  those. Together with `curious` and `m-uvfa` they separate what choosing the module to practise
  and choosing the module to replay as each contribute.
* `mg-te`: one expert policy per module (each with the E-UVFA input, whose task part is then
  constant), sharing one replay buffer. Epoch e belongs to module e mod N: expert e mod N plays
  every episode of the epoch on its module, self-evaluations included (the authors' task-expert
  workers keep their one-hot selection probabilities when they self-evaluate, rollout.py), and
  only that expert trains, replaying relabelled transitions as its module (with HER goals). Its
  competence queue fills during its epochs only. The test rollouts evaluate module m with
  expert m (the authors' evaluator).
* `her`: one policy over the holistic goal space (`HolisticGoals`): every episode draws a goal
  for every module at once, and both its reward and its success are one Euclidean distance over
  all the modules' goal coordinates at once, within the success distance (gym_flowers
  multi_task_fetch_arm_v0.py `compute_reward` with `set_flat_env`, reached through her.py), with
  no stack guard. No holistic goal corresponds to a real situation, which is why the paper's HER
  line stays flat. The task descriptor is zero. It never self-evaluates (the authors' flat
  workers never exploit, rollout.py), so it has no competence (NaN in metrics.parquet). Each
  episode still names one module, drawn uniformly, whose part of the goal is recorded in the
  tables (g0..g2); `module_success` of tests.parquet says whether that module's own reward was
  met at the final step, a per-module view that is never the paper's score.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from curious.agent.goals import GoalInput, HolisticGoals
from curious.agent.learning_progress import CompetenceTracker, lp_probabilities
from curious.envs.goal_env import EnvSpec, GoalEnv
from curious.registry import CONDITIONS

if TYPE_CHECKING:
    from curious.agent.replay import EpisodeReplay, Transitions
    from curious.config import Config
    from curious.envs.rollout import EpisodeData


class Condition:
    """Base strategy: one policy, per-module goals, uniform choices."""

    name = "base"
    self_evaluates = True
    """Whether every `eval_every`-th episode is a noise-free self-evaluation."""
    follows_lead = True
    """Whether `Config.eval_modules` = `released` draws this condition's modules (see the
    module docstring)."""

    def __init__(self, spec: EnvSpec, lp_eps: float, eval_modules: str, eval_every: int) -> None:
        """`lp_eps`, `eval_modules`, `eval_every`: the `Config` settings (`make_condition`)."""
        self.spec = spec
        self.n_modules = spec.n_modules
        self.lp_eps = lp_eps
        self.eval_modules = eval_modules
        self.eval_every = eval_every

    @property
    def n_experts(self) -> int:
        """Number of actor-critic pairs the condition trains."""
        return 1

    def uniform(self) -> np.ndarray:
        return np.full(self.n_modules, 1.0 / self.n_modules)

    # -- which modules ------------------------------------------------------------------------
    def practice_probs(self, tracker: CompetenceTracker, epoch: int) -> np.ndarray:
        """(N,) probabilities of the module practised in the next training episode (p_lp in
        metrics.parquet)."""
        return self.uniform()

    def lead_draw(self, rng: np.random.Generator) -> bool | None:
        """Drawn once at the start of every cycle: whether the cycle's modules are all uniform
        (the released code's rank 0 self-evaluates, probability 1 / `eval_every`); None, with
        nothing drawn, where that rule does not apply."""
        if self.eval_modules != "released" or not self.follows_lead:
            return None
        return bool(rng.random() < 1.0 / self.eval_every)

    def modules(
        self,
        evaluation: np.ndarray,
        tracker: CompetenceTracker,
        epoch: int,
        rng: np.random.Generator,
        lead: bool | None,
    ) -> np.ndarray:
        """(n,) module of each of a round's episodes (`evaluation` (n,) marks the
        self-evaluations; `lead` is the cycle's `lead_draw`)."""
        n, n_mod = len(evaluation), self.n_modules
        practice = self.practice_probs(tracker, epoch)
        if lead is not None:  # `released`: one distribution for the whole cycle
            return rng.choice(n_mod, size=n, p=self.uniform() if lead else practice)
        return np.where(
            evaluation, rng.integers(n_mod, size=n), rng.choice(n_mod, size=n, p=practice)
        )

    # -- goals and scores ---------------------------------------------------------------------
    def goals(
        self, env: GoalEnv, modules: np.ndarray, raw: np.ndarray, rng: np.random.Generator
    ) -> GoalInput[np.ndarray]:
        """The goal input of n episodes of `modules` (n,) with goals `raw` (n, G) in
        [-1, 1]^G: the practised module's slot, mask and task descriptor only."""
        n, n_mod, g = len(modules), self.n_modules, self.spec.goal_dim
        goals = np.zeros((n, n_mod, g), np.float32)
        for k in np.unique(modules):
            sel = np.flatnonzero(modules == k)
            goals[sel, k] = env.goal_slot(int(k), raw[sel])
        return GoalInput.modular(goals, modules)

    def module_success(
        self, env: GoalEnv, data: EpisodeData, modules: np.ndarray, goals: np.ndarray
    ) -> np.ndarray:
        """(n,) bool: whether each episode's module met its own goal slot at the final step."""
        return data.final_success[np.arange(len(modules)), modules]

    def holistic_distance(
        self, env: GoalEnv, goals: np.ndarray, final: np.ndarray
    ) -> np.ndarray | None:
        """(n,) distance of the final outcomes to the whole goal, where the condition scores
        one (the flat baseline); None where it scores one module per episode."""
        return None

    def success(
        self, env: GoalEnv, data: EpisodeData, modules: np.ndarray, goals: np.ndarray
    ) -> np.ndarray:
        """(n,) bool: the condition's score of each episode at its final step (what competence,
        metrics.parquet and Fig. 2a read)."""
        return self.module_success(env, data, modules, goals)

    # -- replay and experts -------------------------------------------------------------------
    def sample(
        self,
        replay: EpisodeReplay,
        batch_size: int,
        rng: np.random.Generator,
        env: GoalEnv,
        module_probs: np.ndarray | None,
        her_p: float,
    ) -> Transitions:
        """A relabelled minibatch from `replay` (`module_probs`: this cycle's `replay_probs`):
        task replay and HER goals, per module."""
        return replay.sample(batch_size, rng, env, module_probs, her_p)

    def replay_probs(
        self, tracker: CompetenceTracker, epoch: int, replayable: np.ndarray
    ) -> np.ndarray | None:
        """(N,) probabilities of the module relabelled transitions are replayed as (None:
        holistic). `replayable` (N,) bool marks the modules with an episode to replay; the
        others get none of the minibatch (the authors' empty buffers)."""
        return _over(replayable, lambda mask: np.full(mask.sum(), 1.0 / mask.sum()))

    def acting_experts(self, modules: np.ndarray, epoch: int) -> np.ndarray:
        """(W,) index of the expert that acts in each episode."""
        return np.zeros(len(modules), np.int64)

    def trained_expert(self, epoch: int) -> int:
        """The expert whose networks this epoch's updates train."""
        return 0


def _over(replayable: np.ndarray, probs_of: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """(N,) probabilities that `probs_of(mask)` gives over the modules of `mask`: the
    `replayable` ones (zero elsewhere), or every module while none is replayable."""
    mask = np.asarray(replayable, bool)
    if not mask.any():
        mask = np.ones_like(mask)
    out = np.zeros(mask.shape, np.float64)
    out[mask] = probs_of(mask)
    return out


class LPSelect(Condition):
    """LP's first use alone (not in the paper): modules practised from p_LP, as `curious`;
    relabelled transitions replayed as modules drawn uniformly, as `m-uvfa`."""

    name = "lp-select"

    def practice_probs(self, tracker: CompetenceTracker, epoch: int) -> np.ndarray:
        return tracker.p_lp(self.lp_eps)


class LPReplay(Condition):
    """LP's second use alone (not in the paper): modules practised uniformly, as `m-uvfa`;
    relabelled transitions replayed as modules drawn from p_LP over the replayable ones, as
    `curious`."""

    name = "lp-replay"

    def replay_probs(
        self, tracker: CompetenceTracker, epoch: int, replayable: np.ndarray
    ) -> np.ndarray:
        lp = tracker.learning_progress()
        return _over(replayable, lambda mask: lp_probabilities(lp[mask], self.lp_eps))


class Curious(LPSelect, LPReplay):
    """The paper's agent: LP chooses both the module practised and the module replayed as."""

    name = "curious"


class MUVFA(Condition):
    name = "m-uvfa"


class MGTE(Condition):
    name = "mg-te"
    follows_lead = False

    @property
    def n_experts(self) -> int:
        return self.n_modules

    def active(self, epoch: int) -> int:
        return epoch % self.n_modules

    def practice_probs(self, tracker: CompetenceTracker, epoch: int) -> np.ndarray:
        p = np.zeros(self.n_modules)
        p[self.active(epoch)] = 1.0
        return p

    def modules(
        self,
        evaluation: np.ndarray,
        tracker: CompetenceTracker,
        epoch: int,
        rng: np.random.Generator,
        lead: bool | None,
    ) -> np.ndarray:
        # Every episode of the epoch, self-evaluations included, is the active module's.
        return np.full(len(evaluation), self.active(epoch), np.int64)

    def replay_probs(
        self, tracker: CompetenceTracker, epoch: int, replayable: np.ndarray
    ) -> np.ndarray:
        # Always the trained expert's module; while it has no episode to replay, the replay
        # draws from every episode (docs/agent.md).
        return self.practice_probs(tracker, epoch)

    def acting_experts(self, modules: np.ndarray, epoch: int) -> np.ndarray:
        # Training episodes are the active module's (its expert acts); a test rollout of module
        # m uses expert m.
        return np.asarray(modules, np.int64).copy()

    def trained_expert(self, epoch: int) -> int:
        return self.active(epoch)


class HER(Condition):
    """The flat baseline, whole: its goal space, its score, no self-evaluation, no task replay."""

    name = "her"
    self_evaluates = False
    follows_lead = False

    def __init__(self, spec: EnvSpec, lp_eps: float, eval_modules: str, eval_every: int) -> None:
        super().__init__(spec, lp_eps, eval_modules, eval_every)
        self.goal_space = HolisticGoals(spec)
        """The holistic goal space: one goal over every module's slot at once."""

    def modules(
        self,
        evaluation: np.ndarray,
        tracker: CompetenceTracker,
        epoch: int,
        rng: np.random.Generator,
        lead: bool | None,
    ) -> np.ndarray:
        # The module an episode names (its recorded goal part) is uniform.
        return rng.integers(self.n_modules, size=len(evaluation))

    def goals(
        self, env: GoalEnv, modules: np.ndarray, raw: np.ndarray, rng: np.random.Generator
    ) -> GoalInput[np.ndarray]:
        return GoalInput.holistic(self.goal_space.draw(env, modules, raw, rng))

    def success(
        self, env: GoalEnv, data: EpisodeData, modules: np.ndarray, goals: np.ndarray
    ) -> np.ndarray:
        final = data.achieved[:, -1]
        return self.goal_space.success(final, self.goal_space.place(env, goals, final))

    def module_success(
        self, env: GoalEnv, data: EpisodeData, modules: np.ndarray, goals: np.ndarray
    ) -> np.ndarray:
        # The named module's own reward at the final step, from its slot of the holistic goal.
        final = data.achieved[:, -1]
        goal = env.row_goals(modules, goals[np.arange(len(modules)), modules], final)
        return env.row_rewards(modules, final, goal) == 0

    def holistic_distance(
        self, env: GoalEnv, goals: np.ndarray, final: np.ndarray
    ) -> np.ndarray | None:
        return self.goal_space.distance(final, self.goal_space.place(env, goals, final))

    def sample(
        self,
        replay: EpisodeReplay,
        batch_size: int,
        rng: np.random.Generator,
        env: GoalEnv,
        module_probs: np.ndarray | None,
        her_p: float,
    ) -> Transitions:
        # Episodes among all, HER goals over the whole goal vector, the flat reward.
        return replay.sample_holistic(self.goal_space, batch_size, rng, env, her_p)

    def replay_probs(self, tracker: CompetenceTracker, epoch: int, replayable: np.ndarray) -> None:
        return None


_BUILT_IN: tuple[type[Condition], ...] = (Curious, MUVFA, MGTE, HER, LPSelect, LPReplay)
CONDITION_CLASSES: dict[str, type[Condition]] = CONDITIONS
"""Every condition by its name: the paper's, in its order, then the two halves of CURIOUS, then
those registered (`register_condition`). The one registry, `curious.registry.CONDITIONS`, which
the settings read without importing the agent."""
CONDITION_CLASSES.update({c.name: c for c in _BUILT_IN})
BUILT_IN_CONDITIONS: tuple[str, ...] = tuple(c.name for c in _BUILT_IN)
"""The conditions curious itself defines (README's table lists them)."""

_RESERVED = "@|/,<> \t\n"
"""Characters a condition's name may not hold: it names run folders and partition keys
(`curious@distractors_4`, `condition|seed`)."""


def register_condition(cls: type[Condition]) -> type[Condition]:
    """Add a condition under its class's `name` (a class decorator): from then on configs,
    `curious train --condition`, experiments and the tables take it as they take a built-in one.
    A plugin's module calls it when it is loaded (`curious.plugins`)."""
    if not isinstance(cls, type) or not issubclass(cls, Condition):
        raise TypeError(f"register_condition takes a subclass of Condition, got {cls!r}")
    name = cls.__dict__.get("name")
    if not isinstance(name, str) or not name or any(c in name for c in _RESERVED):
        raise ValueError(
            f"{cls.__name__} needs a `name` of its own: one word without @, |, /, commas or "
            f"spaces, got {name!r}"
        )
    if CONDITION_CLASSES.get(name, cls) is not cls:
        raise ValueError(f"a condition named {name!r} is already registered")
    CONDITION_CLASSES[name] = cls
    return cls


def make_condition(config: Config, spec: EnvSpec) -> Condition:
    """The strategy of `config.condition` over the modules of `spec`."""
    name = config.condition
    if name not in CONDITION_CLASSES:
        raise KeyError(f"unknown condition {name!r}; choose one of {', '.join(CONDITION_CLASSES)}")
    return CONDITION_CLASSES[name](spec, config.lp_eps, config.eval_modules, config.eval_every)
