"""The training loop: paper Algorithm 1, in cycles, on one run's state (`Trainer`).

`Trainer` owns the state of one run: agent, replay, competence queues, RNGs, counters and the
sensory-failure schedule (`curious.runs.sensor_failure`). One call of `Trainer.cycle()`:

1. runs `episodes_per_worker` rounds of `n_workers` parallel episodes (fewer in the last round
   if `total_episodes` is reached, so episodes are counted exactly). Episode e (global, 0-based)
   is a self-evaluation when e % eval_every == eval_every - 1 (except in `her`, which has
   none): no noise, and its final success goes to its module's competence queue. Other
   episodes practise with exploration noise. The condition (`curious.agent.conditions`) draws every
   module (p_LP for `curious`; the evaluations' follow `Config.eval_modules`, decided once per
   cycle) and the goals, uniform in [-1, 1]^3, and scores the episodes. Once the sensory
   failure has started, every episode runs with it;
2. stores the episodes in the replay and the state statistics, and adds the self-evaluations
   to the competence queues;
3. runs `n_updates` gradient steps on relabelled minibatches of `batch_per_worker * n_workers`
   transitions, then one Polyak update of the target networks;
4. after the last cycle of an epoch, runs `test_rollouts_per_worker` rounds of noise-free test
   rollouts on test copies of the environment (modules drawn uniformly, their own random
   stream): the success that Fig. 2a plots (the condition's score: `her`'s is its holistic
   goal's), as the authors' evaluator. They change nothing of training.

With `overlap_rollouts`, step 1 for the next cycle runs in a thread during step 3, acting with a
copy of the policy from before the updates (`curious.runs.overlap.RoundsAhead`); its rounds are
stored and scored at the start of the next cycle. The environment copies step in this process or in
worker processes (`curious.envs.batch`, `env_processes`). A `Trainer.observer`
(`curious.runs.hooks.RoundObserver`) is called around every round of training episodes.

`curious.runs.driver.train` runs a `Trainer` in a run folder (tables, checkpoints, resume,
recorder).
"""

from __future__ import annotations

import contextlib
import functools
import math
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from curious.agent.agent import Agent
from curious.agent.conditions import Condition
from curious.agent.goals import GoalBox, GoalInput
from curious.agent.learning_progress import CompetenceTracker
from curious.agent.replay import EpisodeReplay
from curious.config import Config, ConfigError
from curious.envs.batch import EnvBatch
from curious.runs import checkpoint
from curious.runs.folder import config_differences
from curious.runs.hooks import RolloutInfo, RoundObserver
from curious.runs.memory import checked_condition
from curious.runs.overlap import Minibatches, RoundsAhead
from curious.runs.play import Act, goal_policy, play_round
from curious.runs.sensor_failure import FailureSchedule


@dataclass
class _Collected:
    """A round of episodes rolled out, not yet stored or scored."""

    info: RolloutInfo
    epoch: int  # the epoch of the cycle it belongs to


@dataclass
class RoundResult:
    """One round of parallel episodes and the measures after each of its episodes."""

    info: RolloutInfo
    competence: np.ndarray  # (n, N) after each episode
    lp: np.ndarray  # (n, N)
    p_lp: np.ndarray  # (n, N)
    wall: np.ndarray  # (n,) seconds since the run started


@dataclass
class CycleResult:
    """What one cycle produced, for the run driver and recorders."""

    rows: dict[str, np.ndarray]  # metrics.parquet columns of the cycle's episodes
    module_index: np.ndarray  # (B,) slot index of each episode's module
    competence: np.ndarray  # (B, N) after each episode
    lp: np.ndarray  # (B, N)
    p_lp: np.ndarray  # (B, N)
    losses: dict[str, float]  # means over the cycle's updates, and seconds/* timings
    replay_counts: np.ndarray  # (N,) modules of the cycle's replayed transitions
    tests: dict[str, np.ndarray] | None = None  # tests.parquet rows, after an epoch's last cycle


class _Timings:
    """Seconds spent in a cycle's named parts (`CycleResult.losses`' `seconds/<part>`)."""

    def __init__(self, *parts: str) -> None:
        self.seconds = dict.fromkeys(parts, 0.0)

    def add(self, part: str, seconds: float) -> None:
        self.seconds[part] = self.seconds.get(part, 0.0) + seconds

    @contextlib.contextmanager
    def __call__(self, part: str) -> Iterator[None]:
        """Time the `with` block as `part`."""
        tic = time.perf_counter()
        yield
        self.add(part, time.perf_counter() - tic)


class TrainingDiverged(RuntimeError):
    """The networks stopped giving finite numbers (a loss, an action or a weight): the learning
    rates are too high for this run, or a setting of `DIVERGENCE_SETTINGS` is far from the
    authors'. Nothing of the diverged state is written."""


DIVERGENCE_SETTINGS: tuple[str, ...] = (
    "norm_eps",
    "norm_clip",
    "gamma",
    "polyak",
    "action_l2",
    "td3_target_noise",
    "td3_noise_clip",
)
"""Settings besides the learning rates that decide whether the learner's numbers stay finite
(the normaliser's floor and clip, the targets' discount and averaging, the actor's penalty, TD3's
noises): the divergence error names those set apart from the authors' values."""


def diverged(config: Config, episode: int, what: str) -> TrainingDiverged:
    """The error for a run whose `what` stopped being finite at `episode`: it names the
    learning rates, the usual cause, and the `DIVERGENCE_SETTINGS` set apart from the authors'
    values, which may be the cause instead."""
    authors = Config()
    changed = [
        f"{name}={getattr(config, name):g}"
        for name in DIVERGENCE_SETTINGS
        if getattr(config, name) != getattr(authors, name)
    ]
    others = f"; set apart from the authors': {', '.join(changed)}" if changed else ""
    back = ", or these settings back to the authors'" if changed else ""
    return TrainingDiverged(
        f"training diverged at episode {episode:,}: {what} (actor_lr={config.actor_lr:g}, "
        f"critic_lr={config.critic_lr:g}{others}); nothing after the run's last checkpoint was "
        "written; start the run over with lower rates: --restart --set actor_lr=... --set "
        f"critic_lr=... (the authors': 1e-3){back}"
    )


class Trainer:
    """One run's state and its training cycle."""

    def __init__(
        self,
        config: Config,
        envs: EnvBatch,
        test_envs: EnvBatch | None = None,
        condition: Condition | None = None,
    ) -> None:
        """`envs`: the `n_workers` training copies (`curious.envs.batch`: a list of copies
        stepped in this process is a `LocalEnvs` of them); `test_envs`: as many copies for the
        test rollouts (default: the training copies, whose random streams the tests then
        advance; `curious.runs.driver.train` gives copies of their own). `condition`: the run's
        from `curious.runs.memory.checked_condition`, where the caller checked the memory before
        building the copies (`curious.runs.driver.train` does); else that is called here."""
        self.config = config
        self.envs = envs
        self.test_envs = test_envs if test_envs is not None else envs
        for copies in (self.envs, self.test_envs):
            if not isinstance(copies, EnvBatch):
                raise TypeError(
                    "Trainer takes an EnvBatch of environment copies, got "
                    f"{type(copies).__name__}: wrap a list of copies in "
                    "curious.envs.batch.LocalEnvs"
                )
            if len(copies) != config.n_workers:
                raise ValueError(
                    f"{len(copies)} environments given, config asks for {config.n_workers}"
                )
            if copies.spec != envs.spec:
                raise ValueError("all environment copies must share one EnvSpec")
        self.env = self.envs.reference
        """A copy in this process for goal slots and rewards (what does not step)."""
        self.spec = self.envs.spec
        if config.torch_threads:
            torch.set_num_threads(config.torch_threads)
        if config.device == "cuda" and not torch.cuda.is_available():
            raise ConfigError("device 'cuda' was asked for but torch sees no CUDA device")
        n = self.spec.n_modules
        if condition is None:
            condition = checked_condition(config, self.spec)  # before the big allocations
        self.condition = condition
        self.agent = Agent(self.spec, config, GoalBox.of(self.env), self.condition.n_experts)
        self.replay = EpisodeReplay(
            self.spec,
            config.replay_capacity,
            active_only=config.replay_active_only,
            moved_threshold=config.moved_threshold,
        )
        self.tracker = CompetenceTracker(n, config.lp_window, config.lp_measure)
        rollout_seq, replay_seq, test_seq = np.random.SeedSequence([config.seed, 0xC0]).spawn(3)
        self.rng = np.random.default_rng(rollout_seq)
        self.replay_rng = np.random.default_rng(replay_seq)
        self.test_rng = np.random.default_rng(test_seq)
        self.episodes = 0
        self.cycles = 0
        self.elapsed = 0.0  # seconds of training before this process (resumed runs)
        self.last_checkpoint: Path | None = None
        """The checkpoint this state last went to or came from: the next one writes only the
        replay's episodes after it (`curious.runs.checkpoint`)."""
        self._started = time.perf_counter()
        self._names = np.array(self.spec.module_names, dtype=object)
        self.observer: RoundObserver | None = None
        self.failure = FailureSchedule(config, self.spec, self.env, (self.envs, self.test_envs))
        self._ahead: RoundsAhead[list[_Collected]] = RoundsAhead()  # overlap_rollouts
        self._minibatches = Minibatches(config.prefetch_minibatches)

    # ------------------------------------------------------------------------------------------
    @property
    def epoch(self) -> int:
        return self.cycles // self.config.n_cycles

    @property
    def done(self) -> bool:
        return self.episodes >= self.config.total_episodes

    def wall_time(self) -> float:
        return self.elapsed + time.perf_counter() - self._started

    def cycle(self, drain: bool = False) -> CycleResult:
        """One cycle of Algorithm 1 (the steps of the module docstring).

        With `overlap_rollouts`, the rounds scored now were collected during the previous
        cycle's updates, and the next cycle's rounds are collected during this one's, with the
        policy as it is before them; `drain` (before a checkpoint) scores those too, so that a
        checkpoint holds no rounds in flight.
        """
        cfg = self.config
        timings = _Timings("rollout_policy", "rollout_env", "store", "sample", "update")
        # 1-2. roll out rounds of parallel episodes; store them, score the self-evaluations
        rounds = [self._score(c, timings) for c in self._rounds_to_score()]
        if cfg.overlap_rollouts and not self.done:
            self._collect_ahead()  # the next cycle's rounds, beside this cycle's updates
        # 3. gradient steps on relabelled minibatches, then the target networks
        losses, replay_counts = self._update(timings)
        if drain:
            rounds += [self._score(c, timings) for c in self._ahead.take() or ()]
        self.cycles += 1
        # 4. after an epoch's last cycle (and the run's), the test rollouts
        tests = None
        if cfg.test_rollouts_per_worker and (self.cycles % cfg.n_cycles == 0 or self.done):
            with timings("test"):
                tests = self.test_rollouts()
        losses.update({f"seconds/{k}": v for k, v in timings.seconds.items()})
        return self._result(rounds, losses, replay_counts, tests)

    def _rounds_to_score(self) -> Iterable[_Collected]:
        """This cycle's rounds: those collected during the previous cycle's updates, else
        collected now by the policy as it is. Serially, each round is scored before the next
        one is collected; with `overlap_rollouts`, all are collected first, as a cycle's rounds
        collected ahead are."""
        ahead = self._ahead.take()
        if ahead is not None:
            return ahead
        rounds = self._rounds(self.epoch, self._acting_agent(frozen=False))
        return list(rounds) if self.config.overlap_rollouts else rounds

    def _rounds(self, epoch: int, agent: Agent, ahead: bool = False) -> Iterator[_Collected]:
        """The rounds of one cycle from episode `self.episodes` on, each collected when asked
        for: its modules and the failure's start follow the competence queues as they are then
        (a caller that scores each round before asking for the next updates them in between).
        `ahead` (collected in a thread beside the updates): the failure's start is left to the
        training thread, which decided it before."""
        cfg, start = self.config, self.episodes
        lead = self.condition.lead_draw(self.rng)
        for _ in range(cfg.episodes_per_worker):
            n = min(cfg.n_workers, cfg.total_episodes - start)
            if n <= 0:
                return
            if not ahead:
                self.failure.start_if_due(start, self.tracker)
            yield self._collect(n, start, epoch, agent, lead)
            start += n

    def _collect(
        self, n: int, start: int, epoch: int, agent: Agent, lead: bool | None
    ) -> _Collected:
        """n parallel episodes from episode `start` on: choose modules and goals, roll out with
        `agent`'s policy, judge success (`lead`: the cycle's `Condition.lead_draw`). Touches the
        training copies, the rollout stream and the observer, nothing the learner or the test
        rollouts use (so it may run beside them)."""
        cfg, spec, condition = self.config, self.spec, self.condition
        episodes = start + np.arange(n)
        evaluation = episodes % cfg.eval_every == cfg.eval_every - 1
        evaluation &= condition.self_evaluates
        modules = condition.modules(evaluation, self.tracker, epoch, self.rng, lead)
        raw = self.rng.uniform(-1.0, 1.0, (n, spec.goal_dim))
        failing = self.failure.apply(self.envs, episodes)
        explore = ~evaluation

        def policy_for(goal: GoalInput[np.ndarray], experts: np.ndarray) -> Act:
            return self._policy(agent, goal, experts, explore, self.rng, start)

        played = play_round(
            self.envs, condition, modules, raw, self.rng, epoch, policy_for,
            episodes, evaluation, failing, self.observer,
        )  # fmt: skip
        return _Collected(played.info, epoch)

    def _policy(
        self,
        agent: Agent,
        goal: GoalInput[np.ndarray],
        experts: np.ndarray,
        explore: np.ndarray,
        rng: np.random.Generator,
        episode: int,
    ) -> Act:
        """`goal_policy` for a round of episodes from episode `episode` on, which raises
        `TrainingDiverged` when it gives a non-finite action."""
        policy = goal_policy(self.env, agent, goal, experts, explore, rng)

        def act(states: np.ndarray, achieved: np.ndarray, t: int) -> np.ndarray:
            actions = policy(states, achieved, t)
            if not np.isfinite(actions).all():
                raise diverged(self.config, episode, "the policy's actions are not finite")
            return actions

        return act

    def _score(self, collected: _Collected, timings: _Timings) -> RoundResult:
        """Store a round's episodes, add its evaluations to the competence queues, and the
        measures after each of its episodes (the metrics rows)."""
        timings.add("rollout_policy", collected.info.data.policy_seconds)
        timings.add("rollout_env", collected.info.data.env_seconds)
        with timings("store"):
            info, n_mod = collected.info, self.spec.n_modules
            data, modules, n = info.data, info.modules, len(info.episodes)
            self.replay.store(data.states, data.achieved, data.actions, modules, info.goals)
            self.agent.encoder.update_stats(data.states)
            competence = np.empty((n, n_mod), np.float32)
            lp = np.empty((n, n_mod), np.float32)
            p_lp = np.empty((n, n_mod), np.float32)
            wall = np.empty(n, np.float64)
            for i in range(n):  # one episode at a time: rows hold the values after each episode
                if info.evaluation[i]:
                    self.tracker.add(int(modules[i]), bool(info.success[i]))
                competence[i] = self.tracker.competence()
                lp[i] = self.tracker.learning_progress()
                p_lp[i] = self.condition.practice_probs(self.tracker, collected.epoch)
                wall[i] = self.wall_time()
            if not self.condition.self_evaluates:  # never measured (her): no competence, no LP
                competence[:] = np.nan
                lp[:] = np.nan
            self.episodes += n
        return RoundResult(info, competence, lp, p_lp, wall)

    def _acting_agent(self, frozen: bool) -> Agent:
        """Who acts in the rollouts: a copy of the policy as it is now when it must stay so
        while the agent learns (`frozen`), or on the CPU (`act_on_cpu` with a GPU); else the
        agent itself."""
        on_cpu = self.config.act_on_cpu and self.agent.device.type != "cpu"
        if frozen or on_cpu:
            return self.agent.acting_copy("cpu" if on_cpu else None)
        return self.agent

    def _collect_ahead(self) -> None:
        """Start collecting the next cycle's rounds in a thread, with a copy of the policy as it
        is before this cycle's updates."""
        next_epoch = (self.cycles + 1) // self.config.n_cycles
        acting = self._acting_agent(frozen=True)
        self.failure.start_if_due(self.episodes, self.tracker)  # decided here, read in the thread
        self._ahead.start(lambda: list(self._rounds(next_epoch, acting, ahead=True)))

    def _update(self, timings: _Timings) -> tuple[dict[str, float], np.ndarray]:
        """`n_updates` gradient steps of the trained expert on relabelled minibatches, then one
        Polyak update of its target networks: the losses' means over the cycle (none without
        updates) and the (N,) modules of the replayed transitions. `TrainingDiverged` when a
        mean loss is not finite."""
        cfg, n_mod = self.config, self.spec.n_modules
        replay_counts = np.zeros(n_mod, np.int64)
        if not (cfg.n_updates and self.replay.size):
            return {}, replay_counts
        expert = self.condition.trained_expert(self.epoch)
        probs = self.condition.replay_probs(self.tracker, self.epoch, self.replay.replayable())
        stats: list[dict[str, torch.Tensor]] = []
        rewards = []
        draw = functools.partial(
            self.condition.sample,
            self.replay, cfg.batch_size, self.replay_rng, self.env, probs, cfg.her_p,
        )  # fmt: skip
        for batch, waited in self._minibatches(draw, cfg.n_updates):
            timings.add("sample", waited)
            with timings("update"):
                if probs is not None:  # per-module replay (not the holistic condition)
                    replay_counts += np.bincount(batch.module, minlength=n_mod)
                rewards.append(float(batch.reward.mean()))
                stats.append(self.agent.update(expert, batch))
        with timings("update"):
            self.agent.update_targets(expert)
            losses = {k: float(torch.stack([s[k] for s in stats]).mean()) for k in stats[0]}
            bad = sorted(k for k, v in losses.items() if not math.isfinite(v))
            if bad:
                verb = "is" if len(bad) == 1 else "are"
                raise diverged(
                    cfg, self.episodes, f"the updates' {', '.join(bad)} {verb} not finite"
                )
            losses["reward_mean"] = float(np.mean(rewards))
        return losses, replay_counts

    def test_rollouts(self) -> dict[str, np.ndarray]:
        """`test_rollouts_per_worker` rounds of noise-free episodes on the test copies, modules
        drawn uniformly and goals uniform, from the test stream; tests.parquet rows: `success`
        is the condition's score (the paper's), `module_success` whether the named module met
        its own goal slot (the same but in `her`, where it is a per-module view).

        Nothing of training changes: no storage, no statistics, no competence, and the training
        copies and random streams are not touched (the authors' separate evaluator).
        """
        cfg, spec = self.config, self.spec
        envs, n = self.test_envs, len(self.test_envs)
        episodes = np.full(n, self.episodes)
        failing = self.failure.apply(envs, episodes)
        explore, evaluation = np.zeros(n, bool), np.ones(n, bool)
        condition, env = self.condition, self.env

        def policy_for(goal: GoalInput[np.ndarray], experts: np.ndarray) -> Act:
            return self._policy(self.agent, goal, experts, explore, self.test_rng, self.episodes)

        names = ("worker", "module", "raw", "ok", "module_ok")
        parts: dict[str, list[np.ndarray]] = {k: [] for k in names}
        for _ in range(cfg.test_rollouts_per_worker):
            modules = self.test_rng.integers(spec.n_modules, size=n)
            raw = self.test_rng.uniform(-1.0, 1.0, (n, spec.goal_dim))
            info = play_round(
                envs, condition, modules, raw, self.test_rng, self.epoch, policy_for,
                episodes, evaluation, failing,
            ).info  # fmt: skip
            parts["worker"].append(np.arange(n, dtype=np.int32))
            parts["module"].append(modules)
            parts["raw"].append(raw.astype(np.float32))
            parts["ok"].append(info.success)
            parts["module_ok"].append(condition.module_success(env, info.data, modules, info.goals))
        raw = np.concatenate(parts["raw"])
        rows = len(raw)
        return {
            "epoch": np.full(rows, (self.cycles - 1) // cfg.n_cycles, np.int64),  # just run
            "episode": np.full(rows, self.episodes, np.int64),
            "worker": np.concatenate(parts["worker"]),
            "module": self._names[np.concatenate(parts["module"])],
            "g0": raw[:, 0],
            "g1": raw[:, 1],
            "g2": raw[:, 2],
            "success": np.concatenate(parts["ok"]),
            "module_success": np.concatenate(parts["module_ok"]),
            "wall_time": np.full(rows, self.wall_time()),
        }

    def _rows(self, round_: RoundResult) -> dict[str, np.ndarray]:
        """metrics.parquet columns of a round."""
        info = round_.info
        rows: dict[str, np.ndarray] = {
            "episode": info.episodes.astype(np.int64),
            "worker": np.arange(len(info.episodes), dtype=np.int32),
            "module": self._names[info.modules],
            "g0": info.raw_goals[:, 0].astype(np.float32),
            "g1": info.raw_goals[:, 1].astype(np.float32),
            "g2": info.raw_goals[:, 2].astype(np.float32),
            "success": info.success,
            "eval": info.evaluation,
            "sensor_failure": info.sensor_failure,
        }
        for prefix in ("competence", "lp", "p_lp"):
            values = getattr(round_, prefix)
            for k, name in enumerate(self.spec.module_names):
                rows[f"{prefix}/{name}"] = values[:, k]
        rows["wall_time"] = round_.wall
        return rows

    def _result(
        self,
        rounds: list[RoundResult],
        losses: dict[str, float],
        replay_counts: np.ndarray,
        tests: dict[str, np.ndarray] | None,
    ) -> CycleResult:
        """A cycle's scored rounds and measures as one `CycleResult`."""
        n_mod = self.spec.n_modules
        parts = [self._rows(r) for r in rounds]
        rows = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]} if parts else {}

        def stack(name: str) -> np.ndarray:
            if not rounds:
                return np.zeros((0, n_mod), np.float32)
            return np.concatenate([getattr(r, name) for r in rounds])

        module_index = (
            np.concatenate([r.info.modules for r in rounds]) if rounds else np.zeros(0, np.int64)
        )
        return CycleResult(
            rows=rows,
            module_index=module_index,
            competence=stack("competence"),
            lp=stack("lp"),
            p_lp=stack("p_lp"),
            losses=losses,
            replay_counts=replay_counts,
            tests=tests,
        )

    # ------------------------------------------------------------------------------------------
    def state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """(small state for torch.save, replay arrays for npz)."""
        if self._ahead.in_flight:
            raise RuntimeError("rounds are in flight: run cycle(drain=True) before a checkpoint")
        state = {
            "config": self.config.to_dict(),
            "episodes": self.episodes,
            "cycles": self.cycles,
            "elapsed": self.wall_time(),
            "agent": self.agent.state_dict(),
            "tracker": self.tracker.state_dict(),
            "rng": self.rng.bit_generator.state,
            "replay_rng": self.replay_rng.bit_generator.state,
            "test_rng": self.test_rng.bit_generator.state,
            "failure_start": self.failure.start,
            "env_rng": self.envs.get_rng_states(),
            "test_env_rng": self.test_envs.get_rng_states(),
            "torch_rng": torch.get_rng_state(),
        }
        return state, self.replay.state_dict()

    def load_state_dict(self, state: dict[str, Any], replay: dict[str, np.ndarray]) -> None:
        diff = config_differences(state["config"], self.config.to_dict())
        if diff:
            raise checkpoint.CheckpointError(
                f"checkpoint is from another config (differs in {', '.join(diff)})"
            )
        if len(state["env_rng"]) != len(self.envs):
            raise checkpoint.CheckpointError("checkpoint has a different number of workers")
        self.agent.load_state_dict(state["agent"])
        self.tracker.load_state_dict(state["tracker"])
        self.replay.load_state_dict(replay)
        self.rng.bit_generator.state = state["rng"]
        self.replay_rng.bit_generator.state = state["replay_rng"]
        self.test_rng.bit_generator.state = state["test_rng"]
        self.failure.start = state["failure_start"]
        self.envs.set_rng_states(state["env_rng"])
        if self.test_envs is not self.envs:
            self.test_envs.set_rng_states(state["test_env_rng"])
        # a checkpoint is loaded onto the agent's device; the CPU generator's state must be a CPU
        # ByteTensor (on a GPU, torch.load moved it there and set_rng_state refused it)
        torch.set_rng_state(state["torch_rng"].cpu())
        self.episodes = int(state["episodes"])
        self.cycles = int(state["cycles"])
        self.elapsed = float(state["elapsed"])
        self._started = time.perf_counter()

    def close(self) -> None:
        """Finish rounds in flight, and stop the rollout and sampling threads and the
        environment workers."""
        self._ahead.close()
        self._minibatches.close()
        self.envs.close()
        self.test_envs.close()

    def finite(self) -> bool:
        """Whether every weight of every network is a finite number."""
        nets = [net for e in self.agent.experts for net in (e.actor, e.critics)]
        return all(bool(torch.isfinite(p).all()) for net in nets for p in net.parameters())

    def ensure_finite(self) -> None:
        """`TrainingDiverged` when a weight is no longer finite (the last step of a cycle may
        make it so with every loss of the cycle finite): checked before anything of a
        checkpoint is written."""
        if not self.finite():
            raise diverged(self.config, self.episodes, "the networks' weights are not finite")

    def save_checkpoint(self, directory: Path) -> Path:
        """Checkpoint the run (`curious.runs.checkpoint.save`), never a diverged one."""
        self.ensure_finite()
        state, replay = self.state_dict()
        path = checkpoint.save(directory, self.episodes, state, replay, base=self.last_checkpoint)
        self.last_checkpoint = path
        return path

    def load_checkpoint(self, path: Path) -> None:
        state, replay = checkpoint.load(path, self.agent.device, into=self.replay.load_room())
        self.load_state_dict(state, replay)
        self.last_checkpoint = path
