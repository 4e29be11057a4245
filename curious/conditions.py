"""The conditions the paper compares, as small strategies the training loop asks three things:
which module to practise next, which modules to substitute in replay, and which expert acts or
learns. Everything else (networks, learner, replay, rollouts) is shared.

Common to all: every `eval_every`-th episode is a self-evaluation without exploration noise on a
module drawn uniformly (the released code evaluated "random tasks"), so that every module's
competence queue fills at the same rate whatever the condition selects for practice.

* `curious`: one E-UVFA policy; the next module and the module each relabelled transition is
  replayed as (task replay, `curious.replay`) are drawn from p_LP.
* `m-uvfa`: the same policy with uniform module selection and uniform task replay (the later
  paper's ablation of learning progress).
* `mg-te`: one expert policy per module (each with the E-UVFA input, whose task part is then
  constant), sharing one replay buffer. Epoch e practises module e mod N with expert e mod N and
  trains that expert only, replaying relabelled transitions as its module (with HER goals); an
  evaluation of module m uses expert m.
* `her`: one policy over the holistic goal space: every episode draws a goal for every module at
  once and the reward is 0 only when all of them are met (the paper's flat baseline). The task
  descriptor is zero. To give it per-module competence like the other conditions, each episode
  also names one module, drawn uniformly, whose part of the goal is scored: `success` is whether
  that module's outcome met its slot at the final step.
"""

from __future__ import annotations

import numpy as np

from curious.learning_progress import CompetenceTracker


class Condition:
    """Base strategy: one policy, uniform choices."""

    name = "base"
    holistic = False

    def __init__(self, n_modules: int, lp_eps: float = 0.4) -> None:
        self.n_modules = n_modules
        self.lp_eps = lp_eps

    @property
    def n_experts(self) -> int:
        """Number of actor-critic pairs the condition trains."""
        return 1

    def uniform(self) -> np.ndarray:
        return np.full(self.n_modules, 1.0 / self.n_modules)

    def practice_probs(self, tracker: CompetenceTracker, epoch: int) -> np.ndarray:
        """(N,) probabilities of the module practised in the next training episode."""
        return self.uniform()

    def replay_probs(self, tracker: CompetenceTracker, epoch: int) -> np.ndarray | None:
        """(N,) probabilities of the module relabelled transitions are replayed as (None:
        holistic)."""
        return self.uniform()

    def acting_experts(self, modules: np.ndarray, epoch: int) -> np.ndarray:
        """(W,) index of the expert that acts in each episode."""
        return np.zeros(len(modules), np.int64)

    def trained_expert(self, epoch: int) -> int:
        """The expert whose networks this epoch's updates train."""
        return 0


class Curious(Condition):
    name = "curious"

    def practice_probs(self, tracker: CompetenceTracker, epoch: int) -> np.ndarray:
        return tracker.p_lp(self.lp_eps)

    def replay_probs(self, tracker: CompetenceTracker, epoch: int) -> np.ndarray:
        return tracker.p_lp(self.lp_eps)


class MUVFA(Condition):
    name = "m-uvfa"


class MGTE(Condition):
    name = "mg-te"

    @property
    def n_experts(self) -> int:
        return self.n_modules

    def active(self, epoch: int) -> int:
        return epoch % self.n_modules

    def practice_probs(self, tracker: CompetenceTracker, epoch: int) -> np.ndarray:
        p = np.zeros(self.n_modules)
        p[self.active(epoch)] = 1.0
        return p

    def replay_probs(self, tracker: CompetenceTracker, epoch: int) -> np.ndarray:
        return self.practice_probs(tracker, epoch)

    def acting_experts(self, modules: np.ndarray, epoch: int) -> np.ndarray:
        # Training episodes practise the active module (so its expert acts); evaluations of
        # module m use expert m.
        return np.asarray(modules, np.int64).copy()

    def trained_expert(self, epoch: int) -> int:
        return self.active(epoch)


class HER(Condition):
    name = "her"
    holistic = True

    def replay_probs(self, tracker: CompetenceTracker, epoch: int) -> None:
        return None


CONDITION_CLASSES: dict[str, type[Condition]] = {c.name: c for c in (Curious, MUVFA, MGTE, HER)}


def make_condition(name: str, n_modules: int, lp_eps: float = 0.4) -> Condition:
    """The strategy of condition `name`."""
    if name not in CONDITION_CLASSES:
        raise KeyError(f"unknown condition {name!r}; choose one of {', '.join(CONDITION_CLASSES)}")
    return CONDITION_CLASSES[name](n_modules, lp_eps)
