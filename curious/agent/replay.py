"""Episode replay with sample-time relabelling: task substitution (p_LP) and HER 'future' goals.

Episodes are stored whole in preallocated numpy arrays (first in, first out when the capacity is
below the run's length; the presets keep the whole run, `Config.buffer_episodes`). A minibatch is
built at sample time, with numpy indexing only (loops run over modules, never over transitions):

1. each transition gets a *replay module* drawn from the given module probabilities (p_LP for
   `curious` and `lp-replay`, uniform for `m-uvfa` and `lp-select`, over the modules with an
   episode to replay, `replayable`; the trained expert's module for `mg-te`:
   `curious.agent.conditions`);
2. its episode is drawn among the episodes where that module's outcome changed
   (`active_only`, as the released code's per-module buffers), or among all while there is none
   (only `mg-te` replays a module that has none); its time step t is uniform in [0, T);
3. with probability `her_p` the transition is relabelled: its module becomes the replay module
   and its goal that module's outcome at a step f drawn uniformly in [t+1, T] of the same episode
   (HER 'future'; `achieved[f]` is the outcome after f actions, so the goal is always reached
   strictly after the transition's state s_t). The other transitions keep the module the episode
   practised and the episode's own goal, so that ~(1 - her_p) of every minibatch are real
   (module, goal) pairs, as in the authors' sampler (flowersteam/curious, her.py: only the HER
   indices get a substituted task). An episode's own goal is its slot placed at step t+1
   (`GoalEnv.goal`): goals that follow an object (the suite's `cube1_above_cube2` and `stack`
   follow cube 2) are where the authors' rollout stored them, the goal after the step;
4. the reward is recomputed for each transition's module and goal with the environment's
   vectorised reward, one call per module present in the batch.

The holistic `her` condition replays one goal over all modules (`sample_holistic`, with its
`HolisticGoals`; each condition picks its sampler, `Condition.sample`): episodes are drawn among
all, relabelled goals put every module's outcome at step f into its slot, and the reward is the
goal space's (one distance over every slot at once).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from curious.agent.goals import GoalInput
from curious.envs.goal_env import EnvSpec, GoalEnv

if TYPE_CHECKING:
    from curious.agent.goals import HolisticGoals

GOAL_OWN = -1
"""`Transitions.goal_step` of a transition that kept its episode's module and goal."""


@dataclass
class Transitions:
    """A relabelled minibatch (numpy, ready to be moved to the learner's device)."""

    state: np.ndarray  # (B, S)
    next_state: np.ndarray  # (B, S)
    action: np.ndarray  # (B, A)
    goal: GoalInput[np.ndarray]  # goals (placed after the step), mask, task descriptor
    reward: np.ndarray  # (B,) float32 in {-1, 0}
    module: np.ndarray  # (B,) module of the goal and task descriptor, -1 in the holistic condition
    episode: np.ndarray  # (B,) buffer slot of the source episode
    step: np.ndarray  # (B,) time step t of the transition
    goal_step: np.ndarray  # (B,) step f of a hindsight goal, or GOAL_OWN


class EpisodeReplay:
    """Fixed-capacity store of whole episodes and the relabelling sampler."""

    def __init__(
        self,
        spec: EnvSpec,
        capacity: int,
        active_only: bool = True,
        moved_threshold: float = 1e-3,
    ) -> None:
        self.spec = spec
        self.capacity = int(capacity)
        self.active_only = active_only
        self.moved_threshold = moved_threshold
        T, n, g = spec.episode_length, spec.n_modules, spec.goal_dim
        self.states = np.zeros((capacity, T + 1, spec.state_dim), np.float32)
        self.achieved = np.zeros((capacity, T + 1, spec.achieved_dim), np.float32)
        self.actions = np.zeros((capacity, T, spec.action_dim), np.float32)
        self.modules = np.zeros(capacity, np.int64)
        self.goals = np.zeros((capacity, n, g), np.float32)
        self.moved = np.zeros((capacity, n), bool)
        self.size = 0
        self.ptr = 0
        self.evicted = False
        """Whether an episode was ever stored over another: until then the slots hold every
        episode in the order stored, so a checkpoint need write only those after the last one."""
        self._hindsight = spec.hindsight_columns()  # (N, G)
        self._pools: list[np.ndarray] | None = None  # per module: episodes its outcome moved in

    @staticmethod
    def bytes_for(spec: EnvSpec, capacity: int) -> int:
        """Memory that a replay of `capacity` episodes of `spec` takes once filled."""
        T, n = spec.episode_length, spec.n_modules
        floats = (T + 1) * (spec.state_dim + spec.achieved_dim) + T * spec.action_dim
        per_episode = 4 * (floats + n * spec.goal_dim) + 8 + n  # + module index, moved flags
        return int(capacity) * per_episode

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.arrays().values())

    def arrays(self) -> dict[str, np.ndarray]:
        """The stored arrays, whole (every slot), by their names in `state_dict`."""
        return {
            "states": self.states,
            "achieved": self.achieved,
            "actions": self.actions,
            "modules": self.modules,
            "goals": self.goals,
            "moved": self.moved,
        }

    def load_room(self) -> dict[str, np.ndarray] | None:
        """The arrays a checkpoint's replay may be read straight into (`arrays()`), while this
        replay holds nothing; None once it holds episodes, since a load refused after the read
        (another run's checkpoint) must leave a replay in use as it was."""
        return self.arrays() if self.size == 0 else None

    def store(
        self,
        states: np.ndarray,
        achieved: np.ndarray,
        actions: np.ndarray,
        modules: np.ndarray,
        goals: np.ndarray,
    ) -> None:
        """Add E episodes: states/achieved (E, T+1, .), actions (E, T, A), modules (E,),
        goals (E, N, G) (zero outside the practised slot, except in the holistic condition)."""
        e = len(states)
        if e > self.capacity:
            raise ValueError(f"{e} episodes do not fit a replay of {self.capacity}")
        idx = (self.ptr + np.arange(e)) % self.capacity
        self.evicted |= self.size + e > self.capacity
        self.states[idx] = states
        self.achieved[idx] = achieved
        self.actions[idx] = actions
        self.modules[idx] = modules
        self.goals[idx] = goals
        outcome = achieved[:, :, self._hindsight]  # (E, T+1, N, G)
        change = np.abs(outcome[:, -1] - outcome[:, 0]).max(axis=-1)
        self.moved[idx] = change > self.moved_threshold
        self.ptr = int((self.ptr + e) % self.capacity)
        self.size = min(self.size + e, self.capacity)
        self._pools = None

    # -------------------------------------------------------------------------------------------
    def _pool_list(self) -> list[np.ndarray]:
        """Per module, the episodes its outcome moved in (recomputed once per store)."""
        if self._pools is None:
            moved = self.moved[: self.size]
            self._pools = [np.flatnonzero(moved[:, k]) for k in range(moved.shape[1])]
        return self._pools

    def replayable(self) -> np.ndarray:
        """(N,) bool: the modules that have an episode to replay (one where their outcome
        moved, with `active_only`; any stored episode otherwise)."""
        if not self.active_only:
            return np.full(self.spec.n_modules, self.size > 0)
        return np.array([pool.size > 0 for pool in self._pool_list()], bool)

    def _episodes_for(self, module: int, n: int, rng: np.random.Generator) -> np.ndarray:
        if self.active_only:
            pool = self._pool_list()[module]
            if pool.size:
                return pool[rng.integers(pool.size, size=n)]
        return rng.integers(self.size, size=n)

    def sample(
        self,
        batch_size: int,
        rng: np.random.Generator,
        env: GoalEnv,
        module_probs: np.ndarray | None,
        her_p: float,
    ) -> Transitions:
        """A relabelled minibatch of per-module goals: `module_probs` (N,), the probabilities of
        the module each transition is replayed as; `her_p`, `Config.her_p`."""
        self._check_filled()
        if module_probs is None:
            raise ValueError("module_probs are needed to substitute modules")
        spec = self.spec
        n_mod, T, B = spec.n_modules, spec.episode_length, batch_size
        replay_module = rng.choice(n_mod, size=B, p=np.asarray(module_probs, dtype=np.float64))
        episode = np.empty(B, np.int64)
        for k in range(n_mod):
            sel = np.flatnonzero(replay_module == k)
            if sel.size:
                episode[sel] = self._episodes_for(k, sel.size, rng)
        step = rng.integers(T, size=B)
        her = rng.random(B) < her_p
        future = step + 1 + (rng.random(B) * (T - step)).astype(np.int64)

        module = np.where(her, replay_module, self.modules[episode])
        goal = self.goals[episode, module]  # the episode's own slot where it kept its module
        cols = self._hindsight[module[her]]  # (nh, G)
        goal[her] = self.achieved[episode[her, None], future[her, None], cols]
        goal_step = np.where(her, future, GOAL_OWN)
        next_achieved = self.achieved[episode, step + 1]
        own = np.flatnonzero(~her)  # the slot's goal after the step
        goal[own] = env.row_goals(module[own], goal[own], next_achieved[own])
        reward = env.row_rewards(module, next_achieved, goal)

        goals = np.zeros((B, n_mod, spec.goal_dim), np.float32)
        goals[np.arange(B), module] = goal
        return Transitions(
            state=self.states[episode, step],
            next_state=self.states[episode, step + 1],
            action=self.actions[episode, step],
            goal=GoalInput.modular(goals, module),
            reward=reward,
            module=module,
            episode=episode,
            step=step,
            goal_step=goal_step,
        )

    def _check_filled(self) -> None:
        if self.size == 0:
            raise RuntimeError("cannot sample from an empty replay")

    def sample_holistic(
        self,
        goal_space: HolisticGoals,
        batch_size: int,
        rng: np.random.Generator,
        env: GoalEnv,
        her_p: float,
    ) -> Transitions:
        """The flat baseline's minibatch (flowersteam/curious her.py,
        `make_sample_her_transitions`: episodes drawn among all, HER 'future' goals over the
        whole goal vector, the env's flat reward)."""
        self._check_filled()
        T, B = self.spec.episode_length, batch_size
        episode = rng.integers(self.size, size=B)
        step = rng.integers(T, size=B)
        her = rng.random(B) < her_p
        future = step + 1 + (rng.random(B) * (T - step)).astype(np.int64)
        goals = self.goals[episode]  # (B, N, G) copy
        goals[her] = goal_space.hindsight(self.achieved[episode[her], future[her]])
        goal_step = np.where(her, future, GOAL_OWN)
        next_achieved = self.achieved[episode, step + 1]
        own = np.flatnonzero(~her)
        if own.size:  # the slots' goals after the step (the suite's T3/T4 goals follow cube 2)
            goals[own] = goal_space.place(env, goals[own], next_achieved[own])
        reward = goal_space.reward(next_achieved, goals)
        return Transitions(
            state=self.states[episode, step],
            next_state=self.states[episode, step + 1],
            action=self.actions[episode, step],
            goal=GoalInput.holistic(goals),
            reward=reward,
            module=np.full(B, -1, np.int64),
            episode=episode,
            step=step,
            goal_step=goal_step,
        )

    # -------------------------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        n = self.size
        return {
            **{key: array[:n] for key, array in self.arrays().items()},
            "size": np.int64(n),
            "ptr": np.int64(self.ptr),
            "evicted": np.bool_(self.evicted),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Load a `state_dict`, into a replay of the same or a larger capacity (a run resumed
        with more episodes); episodes are laid out oldest first, so eviction order is kept. An
        array that is already this replay's first episodes (read into `arrays()` by
        `curious.runs.checkpoint.load`) is not copied."""
        n = int(state["size"])
        if n > self.capacity:
            raise ValueError(f"checkpoint replay holds {n} episodes, capacity is {self.capacity}")
        oldest = int(state["ptr"]) % n if n else 0  # a full ring's oldest episode sits at ptr
        for key, target in self.arrays().items():
            array = np.asarray(state[key])
            if oldest:  # no copy of the whole replay where it is laid out oldest first
                array = np.roll(array, -oldest, axis=0)
            if array.shape[1:] != target.shape[1:]:
                raise ValueError(
                    f"replay {key}: checkpoint shape {array.shape[1:]}, expected {target.shape[1:]}"
                )
            if not (len(array) == n and _is_first_episodes_of(array, target)):
                target[:n] = array  # a length other than n raises here, as it always did
        self.size = n
        self.ptr = n % self.capacity
        # a dict without the flag (written before it existed) is taken as evicted unless its
        # pointer says the ring never wrapped
        ptr = int(state["ptr"])
        self.evicted = bool(state["evicted"]) if "evicted" in state else ptr != n
        self._pools = None


def _is_first_episodes_of(array: np.ndarray, target: np.ndarray) -> bool:
    """Whether `array` starts where `target` does, laid out alike: `target[:len(array)]`."""
    return (
        array.ctypes.data == target.ctypes.data
        and array.dtype == target.dtype
        and array.strides == target.strides
        and array.shape[1:] == target.shape[1:]
    )
