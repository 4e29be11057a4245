"""The training loop (paper Algorithm 1, in cycles) and a run driver with resumable checkpoints.

`Trainer` owns the state of one run: agent, replay, competence queues, RNGs and counters. One
call of `Trainer.cycle()`:

1. runs `episodes_per_worker` rounds of `n_workers` parallel episodes (fewer in the last round
   if `total_episodes` is reached, so episodes are counted exactly). Episode e (global, 0-based)
   is a self-evaluation when e % eval_every == eval_every - 1: no noise, a module drawn
   uniformly, and its final success goes to that module's competence queue. Other episodes
   practise a module drawn by the condition (p_LP for `curious`) with a goal uniform in
   [-1, 1]^3, with exploration noise. With `sensor_failure_episode >= 0`, each environment copy
   runs its episode with the sensory failure switched on when the episode's index has reached it;
2. stores the episodes in the replay and the normaliser statistics;
3. runs `n_updates` gradient steps on relabelled minibatches of `batch_per_worker * n_workers`
   transitions, then one Polyak update of the target networks.

`train()` runs a `Trainer` in a run folder: `metrics.parquet` rows, checkpoints every
`checkpoint_every_cycles` cycles, `--resume`, a progress bar and an optional recorder.

Recording hooks (all optional; `curious.recording.RunRecorder` provides the first three). After
every cycle `train()` calls, with B the cycle's episodes and N the modules:

    recorder.log_episodes(episode=(B,), module=(B,) slot indices, success=(B,), eval=(B,),
                          competence=(B, N), lp=(B, N), p_lp=(B, N), wall_time=(B,))
    recorder.log_replay(episode, counts)     # (N,) substitute-module counts of the cycle's replay
    recorder.log_learner(episode, losses={"critic", "actor"}, q={"target_mean"})
    recorder.close()                         # once, when training stops

and a `Trainer.observer` (e.g. one that captures MuJoCo body poses for 3-D rollouts) is called
around every round of parallel episodes:

    observer.begin_round(episodes, modules, goals, evaluation, envs)   # before the resets
    observer.after_step(t)                   # t = 0 after the resets, then 1..T after each step
    observer.end_round(info)                 # RolloutInfo: states, outcomes, actions, success
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch

from curious import checkpoint
from curious.agent import Agent
from curious.conditions import make_condition
from curious.config import Config, ConfigError
from curious.envs import EnvSpec, GoalEnv
from curious.inputs import GoalBox
from curious.learning_progress import CompetenceTracker
from curious.metrics import MetricsLog
from curious.replay import EpisodeReplay
from curious.rollouts import EpisodeData, run_episodes
from curious.run_folder import RunFolder, config_differences


class RoundObserver(Protocol):
    """Called around every round of parallel episodes (see the module docstring)."""

    def begin_round(
        self,
        episodes: np.ndarray,
        modules: np.ndarray,
        goals: np.ndarray,
        evaluation: np.ndarray,
        envs: Sequence[GoalEnv],
    ) -> None: ...

    def after_step(self, t: int) -> None: ...

    def end_round(self, info: RolloutInfo) -> None: ...


@dataclass
class RolloutInfo:
    """One round of parallel episodes, for recorders that show rollouts."""

    episodes: np.ndarray  # (n,) global episode indices
    modules: np.ndarray  # (n,) module index practised or evaluated
    raw_goals: np.ndarray  # (n, 3) goals in [-1, 1]^3
    goals: np.ndarray  # (n, N, G) goal slots given to the policy
    evaluation: np.ndarray  # (n,) bool
    success: np.ndarray  # (n,) bool, final success of the module
    data: EpisodeData  # states, achieved outcomes, actions


@dataclass
class CycleResult:
    """What one cycle produced, for the run driver and recorders."""

    rows: dict[str, np.ndarray]  # metrics.parquet columns of the cycle's episodes
    module_index: np.ndarray  # (B,) slot index of each episode's module
    competence: np.ndarray  # (B, N) after each episode
    lp: np.ndarray  # (B, N)
    p_lp: np.ndarray  # (B, N)
    losses: dict[str, float]  # means over the cycle's updates, and seconds/* timings
    replay_counts: np.ndarray  # (N,) substitute modules drawn in the cycle's minibatches


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


def _check_replay_fits(config: Config, spec: EnvSpec) -> None:
    """A `ConfigError` before training when the replay would not fit in memory once filled
    (numpy allocates it lazily, so without this a run would fail hours in)."""
    need = EpisodeReplay.bytes_for(spec, config.replay_capacity)
    have = available_memory()
    if need > 0.9 * have:
        raise ConfigError(
            f"the replay keeps {config.replay_capacity:,} episodes, {need / 2**30:.2f} GiB once "
            f"filled, but this machine has {have / 2**30:.2f} GiB available: lower "
            "buffer_episodes (--set buffer_episodes=N keeps the newest N episodes) or "
            "total_episodes"
        )


class Trainer:
    """One run's state and its training cycle."""

    def __init__(self, config: Config, envs: Sequence[GoalEnv]) -> None:
        config.validate()
        if len(envs) != config.n_workers:
            raise ValueError(f"{len(envs)} environments given, config asks for {config.n_workers}")
        self.config = config
        self.envs = list(envs)
        self.spec = envs[0].spec
        for env in self.envs[1:]:
            if env.spec != self.spec:
                raise ValueError("all environment copies must share one EnvSpec")
        if config.torch_threads:
            torch.set_num_threads(config.torch_threads)
        if config.device == "cuda" and not torch.cuda.is_available():
            raise ConfigError("device 'cuda' was asked for but torch sees no CUDA device")
        n = self.spec.n_modules
        self.condition = make_condition(config.condition, n, config.lp_eps)
        self.agent = Agent(self.spec, config, GoalBox.of(self.envs[0]), self.condition.n_experts)
        _check_replay_fits(config, self.spec)
        self.replay = EpisodeReplay(
            self.spec,
            config.replay_capacity,
            holistic=self.condition.holistic,
            active_only=config.replay_active_only,
            moved_threshold=config.moved_threshold,
        )
        self.tracker = CompetenceTracker(n, config.lp_window)
        rollout_seq, replay_seq = np.random.SeedSequence([config.seed, 0xC0]).spawn(2)
        self.rng = np.random.default_rng(rollout_seq)
        self.replay_rng = np.random.default_rng(replay_seq)
        self.episodes = 0
        self.cycles = 0
        self.elapsed = 0.0  # seconds of training before this process (resumed runs)
        self._started = time.perf_counter()
        self._names = np.array(self.spec.module_names, dtype=object)
        self.observer: RoundObserver | None = None
        if config.sensor_failure_episode >= 0:
            for env in self.envs:
                if not callable(getattr(env, "set_sensor_failure", None)):
                    raise ConfigError(
                        f"sensor_failure_episode is set but {type(env).__name__} has no "
                        "set_sensor_failure()"
                    )
                env.set_sensor_failure(False)  # raises on a variant without the failure

    # ------------------------------------------------------------------------------------------
    @property
    def epoch(self) -> int:
        return self.cycles // self.config.n_cycles

    @property
    def done(self) -> bool:
        return self.episodes >= self.config.total_episodes

    def wall_time(self) -> float:
        return self.elapsed + time.perf_counter() - self._started

    def _goals(self, modules: np.ndarray, raw: np.ndarray) -> tuple[np.ndarray, ...]:
        """Goal slots (n, N, G), slot mask (n, N) and task descriptor (n, N) of n episodes.

        The holistic condition draws a goal for every module (the scored module keeps `raw`).
        """
        spec, env = self.spec, self.envs[0]
        n, n_mod, g = len(modules), spec.n_modules, spec.goal_dim
        goals = np.zeros((n, n_mod, g), np.float32)
        rows = np.arange(n)
        if self.condition.holistic:
            raw_all = self.rng.uniform(-1.0, 1.0, (n, n_mod, g))
            raw_all[rows, modules] = raw
            for k in range(n_mod):
                goals[:, k] = env.goal_slot(k, raw_all[:, k])
            return goals, np.ones((n, n_mod), np.float32), np.zeros((n, n_mod), np.float32)
        for k in np.unique(modules):
            sel = np.flatnonzero(modules == k)
            goals[sel, k] = env.goal_slot(int(k), raw[sel])
        task = np.zeros((n, n_mod), np.float32)
        task[rows, modules] = 1.0
        return goals, task.copy(), task

    def _round(self, n: int) -> tuple[RolloutInfo, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """n parallel episodes: choose modules and goals, roll out, store, score.

        Returns the round's RolloutInfo and, per episode, competence, LP, p_LP (n, N) after it
        and its wall time.
        """
        cfg, spec = self.config, self.spec
        n_mod = spec.n_modules
        episodes = self.episodes + np.arange(n)
        evaluation = episodes % cfg.eval_every == cfg.eval_every - 1
        practice = self.condition.practice_probs(self.tracker, self.epoch)
        modules = np.where(
            evaluation,
            self.rng.integers(n_mod, size=n),
            self.rng.choice(n_mod, size=n, p=practice),
        )
        raw = self.rng.uniform(-1.0, 1.0, (n, spec.goal_dim))
        goals, mask, task = self._goals(modules, raw)
        experts = self.condition.acting_experts(modules, self.epoch)
        explore = ~evaluation
        envs = self.envs[:n]

        def act(states: np.ndarray, t: int) -> np.ndarray:
            return self.agent.act(states, goals, mask, task, experts, explore, self.rng)

        if cfg.sensor_failure_episode >= 0:
            for env, e in zip(envs, episodes, strict=True):
                env.set_sensor_failure(bool(e >= cfg.sensor_failure_episode))
        observer = self.observer
        if observer is not None:
            observer.begin_round(episodes, modules, goals, evaluation, envs)
        data = run_episodes(envs, modules, raw, act, observer.after_step if observer else None)
        if self.condition.holistic:
            # The scored module's part of the holistic goal, judged by that module's reward.
            final = data.achieved[:, -1]
            success = np.zeros(n, bool)
            for k in np.unique(modules):
                sel = np.flatnonzero(modules == k)
                success[sel] = self.envs[0].reward(int(k), final[sel], goals[sel, k]) == 0
        else:
            success = data.final_success[np.arange(n), modules]

        self.replay.store(data.states, data.achieved, data.actions, modules, goals)
        self.agent.encoder.update_stats(data.states)

        competence = np.empty((n, n_mod), np.float32)
        lp = np.empty((n, n_mod), np.float32)
        p_lp = np.empty((n, n_mod), np.float32)
        wall = np.empty(n, np.float64)
        for i in range(n):  # one episode at a time: rows hold the values after each episode
            if evaluation[i]:
                self.tracker.add(int(modules[i]), bool(success[i]))
            competence[i] = self.tracker.competence()
            lp[i] = self.tracker.learning_progress()
            p_lp[i] = self.condition.practice_probs(self.tracker, self.epoch)
            wall[i] = self.wall_time()
        self.episodes += n
        info = RolloutInfo(episodes, modules, raw, goals, evaluation, success, data)
        if observer is not None:
            observer.end_round(info)
        return info, competence, lp, p_lp, wall

    def _rows(
        self,
        info: RolloutInfo,
        competence: np.ndarray,
        lp: np.ndarray,
        p_lp: np.ndarray,
        wall: np.ndarray,
    ) -> dict[str, np.ndarray]:
        """metrics.parquet columns of a round."""
        rows: dict[str, np.ndarray] = {
            "episode": info.episodes.astype(np.int64),
            "worker": np.arange(len(info.episodes), dtype=np.int32),
            "module": self._names[info.modules],
            "g0": info.raw_goals[:, 0].astype(np.float32),
            "g1": info.raw_goals[:, 1].astype(np.float32),
            "g2": info.raw_goals[:, 2].astype(np.float32),
            "success": info.success,
            "eval": info.evaluation,
        }
        for prefix, values in (("competence", competence), ("lp", lp), ("p_lp", p_lp)):
            for k, name in enumerate(self.spec.module_names):
                rows[f"{prefix}/{name}"] = values[:, k]
        rows["wall_time"] = wall
        return rows

    def cycle(self) -> CycleResult:
        """One cycle: rollouts, then updates, then the target update (see the module docstring)."""
        cfg, n_mod = self.config, self.spec.n_modules
        timings = dict.fromkeys(("rollout_policy", "rollout_env", "store", "sample", "update"), 0.0)
        parts: list[tuple[RolloutInfo, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        for _ in range(cfg.episodes_per_worker):
            n = min(cfg.n_workers, cfg.total_episodes - self.episodes)
            if n <= 0:
                break
            tic = time.perf_counter()
            part = self._round(n)
            data = part[0].data
            timings["rollout_policy"] += data.policy_seconds
            timings["rollout_env"] += data.env_seconds
            timings["store"] += time.perf_counter() - tic - data.policy_seconds - data.env_seconds
            parts.append(part)

        losses: dict[str, float] = {}
        replay_counts = np.zeros(n_mod, np.int64)
        if cfg.n_updates and self.replay.size:
            expert = self.condition.trained_expert(self.epoch)
            probs = self.condition.replay_probs(self.tracker, self.epoch)
            stats: list[dict[str, torch.Tensor]] = []
            rewards = []
            for _ in range(cfg.n_updates):
                tic = time.perf_counter()
                batch = self.replay.sample(
                    cfg.batch_size, self.replay_rng, self.envs[0], probs, cfg.her_p
                )
                if not self.condition.holistic:
                    replay_counts += np.bincount(batch.module, minlength=n_mod)
                rewards.append(float(batch.reward.mean()))
                toc = time.perf_counter()
                stats.append(self.agent.update(expert, batch))
                timings["sample"] += toc - tic
                timings["update"] += time.perf_counter() - toc
            tic = time.perf_counter()
            self.agent.update_targets(expert)
            losses = {k: float(torch.stack([s[k] for s in stats]).mean()) for k in stats[0]}
            losses["reward_mean"] = float(np.mean(rewards))
            timings["update"] += time.perf_counter() - tic
        losses.update({f"seconds/{k}": v for k, v in timings.items()})
        self.cycles += 1

        row_parts = [self._rows(*part) for part in parts]
        rows = {k: np.concatenate([r[k] for r in row_parts]) for k in row_parts[0]} if parts else {}

        def stack(i: int, width: int) -> np.ndarray:
            if not parts:
                return np.zeros((0, width), np.float32)
            return np.concatenate([part[i] for part in parts])

        module_index = (
            np.concatenate([p[0].modules for p in parts]) if parts else np.zeros(0, np.int64)
        )
        return CycleResult(
            rows=rows,
            module_index=module_index,
            competence=stack(1, n_mod),
            lp=stack(2, n_mod),
            p_lp=stack(3, n_mod),
            losses=losses,
            replay_counts=replay_counts,
        )

    # ------------------------------------------------------------------------------------------
    def state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """(small state for torch.save, replay arrays for npz)."""
        state = {
            "config": self.config.to_dict(),
            "episodes": self.episodes,
            "cycles": self.cycles,
            "elapsed": self.wall_time(),
            "agent": self.agent.state_dict(),
            "tracker": self.tracker.state_dict(),
            "rng": self.rng.bit_generator.state,
            "replay_rng": self.replay_rng.bit_generator.state,
            "env_rng": [env.get_rng_state() for env in self.envs],
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
        for env, env_state in zip(self.envs, state["env_rng"], strict=True):
            env.set_rng_state(env_state)
        torch.set_rng_state(state["torch_rng"])
        self.episodes = int(state["episodes"])
        self.cycles = int(state["cycles"])
        self.elapsed = float(state["elapsed"])
        self._started = time.perf_counter()

    def save_checkpoint(self, directory: Path) -> Path:
        state, replay = self.state_dict()
        return checkpoint.save(directory, self.episodes, state, replay)

    def load_checkpoint(self, path: Path) -> None:
        state, replay = checkpoint.load(path, map_location=self.agent.device)
        self.load_state_dict(state, replay)


# ----------------------------------------------------------------------------------------------
def _progress_text(trainer: Trainer) -> dict[str, str]:
    spec = trainer.spec
    competence = trainer.tracker.competence()
    achievable = np.array(spec.achievable, bool)
    success = competence[achievable].mean() if achievable.any() else float("nan")
    p = trainer.condition.practice_probs(trainer.tracker, trainer.epoch)
    short = [name.replace("cube", "c").replace("_", "") for name in spec.module_names]
    p_text = " ".join(f"{name}:{v:.2f}" for name, v in zip(short, p, strict=True))
    return {"success": f"{success:.2f}", "p_LP": p_text}


def _log_cycle(recorder: Any, trainer: Trainer, result: CycleResult) -> None:
    """Hand one cycle to a recorder (see the module docstring for the calls)."""
    rows = result.rows
    recorder.log_episodes(
        episode=rows["episode"],
        module=result.module_index,
        success=rows["success"],
        eval=rows["eval"],
        competence=result.competence,
        lp=result.lp,
        p_lp=result.p_lp,
        wall_time=rows["wall_time"],
    )
    losses = result.losses
    if hasattr(recorder, "log_replay") and result.replay_counts.sum() > 0:
        recorder.log_replay(trainer.episodes, result.replay_counts)
    if hasattr(recorder, "log_learner") and "critic_loss" in losses:
        recorder.log_learner(
            trainer.episodes,
            losses={"critic": losses["critic_loss"], "actor": losses["actor_loss"]},
            q={"target_mean": losses["q_target_mean"]},
        )


def train(
    config: Config,
    out: str | Path,
    resume: bool = False,
    make_envs: Callable[[Config], Sequence[GoalEnv]] | None = None,
    make_recorder: Callable[[Trainer, RunFolder], Any] | None = None,
    stop_after_cycles: int | None = None,
) -> Trainer:
    """Train `config` in the run folder `out` (created, or continued with `resume=True`).

    `make_envs(config)` builds the `n_workers` environment copies (default: the suite variant
    `config.variant`). `make_recorder(trainer, folder)`, called once the folder is ready (and a
    resumed trainer is at its checkpoint's episode), returns the recorder the loop logs to.
    `stop_after_cycles` ends this call early (after a checkpoint), which is how tests interrupt
    a run. Errors about the folder or the checkpoint are raised before anything in the folder
    is written.
    """
    from tqdm.auto import tqdm

    folder = RunFolder.prepare(out, config, resume)
    if make_envs is None:
        from curious.envs import make_suite_envs

        def make_envs(cfg: Config) -> Sequence[GoalEnv]:
            return make_suite_envs(cfg.variant, cfg.seed, cfg.n_workers)

    trainer = Trainer(config, make_envs(config))
    latest = checkpoint.list_checkpoints(folder.checkpoints) if resume else []
    if latest:
        trainer.load_checkpoint(latest[-1])  # raises on another config, before any write
    metrics = MetricsLog(folder.metrics_path, trainer.spec.module_names) if resume else None

    folder.write_config(config, trainer.spec)
    checkpoint.remove_partial(folder.checkpoints)
    if metrics is None:
        metrics = MetricsLog(folder.metrics_path, trainer.spec.module_names)
    if metrics.n_rows:
        rows_before = metrics.n_rows
        metrics.truncate(trainer.episodes)  # rows logged after the checkpoint are redone
        if metrics.n_rows != rows_before:
            metrics.flush()

    recorder = make_recorder(trainer, folder) if make_recorder is not None else None
    bar = tqdm(
        total=config.total_episodes,
        initial=trainer.episodes,
        unit="ep",
        disable=not config.progress,
        dynamic_ncols=True,
        desc=f"{config.condition} seed {config.seed}",
    )
    cycles_here = 0
    try:
        while not trainer.done:
            result = trainer.cycle()
            cycles_here += 1
            metrics.append(result.rows)
            if recorder is not None and len(result.module_index):
                _log_cycle(recorder, trainer, result)
            bar.update(len(result.rows.get("episode", ())))
            bar.set_postfix(_progress_text(trainer), refresh=False)
            stop_now = stop_after_cycles is not None and cycles_here >= stop_after_cycles
            if trainer.done or stop_now or trainer.cycles % config.checkpoint_every_cycles == 0:
                metrics.flush()
                trainer.save_checkpoint(folder.checkpoints)
            if stop_now:
                break
    finally:
        bar.close()
        if recorder is not None and hasattr(recorder, "close"):
            recorder.close()
    return trainer
