"""Evaluate a trained run: noise-free episodes per module from its newest checkpoint.

`evaluate(run, ...)` loads the run's newest readable checkpoint (`checkpoint.load_latest`, the
falling-back rule of `--resume`), builds the run's agent and condition, and plays, for every
chosen module, `episodes` noise-free episodes with goals drawn uniformly in that module's goal
space, in batches across environment copies seeded apart from training (stream 0) and from the
test rollouts (stream 1). Scores are the test rollouts' (`Trainer.test_rollouts`): `success`
is the condition's score (for `her` its holistic goal, as the paper), `module_success` whether
the module met its own goal slot; MG-TE plays module m with its expert m. Nothing of the run
folder is written.

`open_run` is the loading half (checkpoint, agent, condition, copies) and
`EvaluationSession.evaluate` the playing half, which takes a round observer as training does:
`curious evaluate --record` records its episodes in 3-D with it
(`curious.watching.recording.evaluation_rrd`)
and `curious render --run` films them (`curious.watching.video`), so that a video or a recording
shows the very episodes `curious evaluate` scores with the same seed.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from curious.agent.conditions import make_condition
from curious.agent.goals import GoalBox
from curious.config import MAX_SEED
from curious.envs.batch import LocalEnvs, ProcessEnvs
from curious.envs.goal_env import suite_env_fns
from curious.runs.folder import RunFolder, config_differences
from curious.runs.shipped_folder import shipped_run_note

if TYPE_CHECKING:
    from curious.agent.goals import GoalInput
    from curious.runs.play import Act, PolicyFor

MAX_EPISODES = 100_000
"""Upper bound of the episodes per module of an evaluation (`curious evaluate --episodes`,
`curious render --episodes`): 1,000 times the default 100, where the 95 % interval of a success
rate is at most 0.6 points wide (2 x 1.96 x sqrt(0.25 / 100,000)); more only plays for longer,
days on a laptop, without saying anything more."""

EVAL_STREAM = 2
"""`suite_env_fns` stream of the evaluation copies (0: training, 1: test rollouts)."""


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate (nan, nan for no episodes)."""
    if n == 0:
        return (math.nan, math.nan)
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    low = 0.0 if successes == 0 else max(0.0, centre - half)  # exact at the ends
    high = 1.0 if successes == n else min(1.0, centre + half)
    return (low, high)


@dataclass
class ModuleEvaluation:
    """One module's episodes: scores, per-episode arrays and their summary."""

    module: str
    episodes: int
    success: float
    """The condition's score (her: the holistic goal's), as the paper plots."""
    low: float
    high: float
    """95 % Wilson interval of `success`."""
    module_success: float
    """Whether the module met its own goal slot (differs from `success` only in her)."""
    distance: float
    """Mean final distance between the module's hindsight outcome and its goal."""
    holistic_distance: float | None
    """her only: mean final distance to the holistic goal (`HolisticGoals.distance`)."""
    per_episode: dict[str, np.ndarray] = field(repr=False)
    """`success`, `module_success`, `distance`, `expert` (the expert that acted), `goal` (the
    raw goal in [-1, 1]^G)."""


@dataclass
class Evaluation:
    """The result of `evaluate`."""

    run: str
    checkpoint: str
    condition: str
    variant: str
    episode: int
    """The training episode of the checkpoint."""
    modules: list[ModuleEvaluation]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no per-episode arrays)."""
        out = asdict(self)
        for row in out["modules"]:
            row.pop("per_episode")
        return out


def _distances(spec: Any, module: int, final: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """(n,) distance between module's hindsight outcome and its placed goal (n, G)."""
    cols = spec.hindsight_columns()[module]
    return np.linalg.norm(final[:, cols].astype(np.float64) - goal, axis=1)


@dataclass
class EvaluationSession:
    """A run's newest checkpoint with its agent and condition, and the environment copies that
    play it: what `evaluate` and the videos of `curious render --run` share (`open_run`)."""

    folder: Any
    """The run's `RunFolder`."""
    config: Any
    checkpoint: Path
    episode: int
    """The training episode of the checkpoint."""
    epoch: int
    variant: str
    seed: int
    envs: Any
    """The `EnvBatch` of `copies` evaluation copies (stream `EVAL_STREAM`)."""
    condition: Any
    agent: Any

    @property
    def spec(self) -> Any:
        return self.envs.spec

    @property
    def copies(self) -> int:
        return len(self.envs)

    def modules(self, names: Sequence[str] | None) -> list[str]:
        """The modules to play: `names` (checked against the run's, `EnvSpec.module_index`; a
        module named twice is played once) or all of them."""
        chosen = list(dict.fromkeys(names)) if names else list(self.spec.module_names)
        for name in chosen:
            self.spec.module_index(name)
        return chosen

    def close(self) -> None:
        self.envs.close()

    def __enter__(self) -> EvaluationSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def evaluate(
        self,
        episodes: int,
        modules: Sequence[str] | None = None,
        policy: PolicyFor | None = None,
        observer: Any = None,
        progress: bool = False,
    ) -> Evaluation:
        """Play `episodes` noise-free episodes of each of `modules` (default: all), in the
        order given, with goals drawn uniformly from the session's seed.

        `observer`: a round observer (`curious.runs.hooks.RoundObserver`: the 3-D rollout recorder,
        the video's frame grabber) called around every batch as in training; the episodes it
        sees are numbered 0, 1, ... through the evaluation, module after module (module k's
        j-th episode is k * episodes + j), and all are evaluation episodes. `policy`: as
        `evaluate`'s."""
        from tqdm.auto import tqdm  # it picks notebook or console bars, and warns, when imported

        from curious.runs.play import goal_policy, play_round

        check_episodes(episodes)
        chosen = self.modules(modules)
        env, spec, condition, n = self.envs.reference, self.spec, self.condition, self.copies
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, 0xE7A1]))
        explore = np.zeros(n, bool)
        bar = tqdm(
            total=episodes * len(chosen),
            unit="ep",
            disable=not progress,
            dynamic_ncols=True,
            desc=f"evaluate {self.config.condition}",
        )

        def policy_for(goal: GoalInput[np.ndarray], experts: np.ndarray) -> Act:
            if policy is not None:
                return policy(goal, experts)
            return goal_policy(env, self.agent, goal, experts, explore[: len(experts)], rng)

        results = []
        try:
            for position, name in enumerate(chosen):
                m = spec.module_index(name)
                parts: dict[str, list[np.ndarray]] = {
                    key: []
                    for key in ("success", "module_success", "distance", "expert", "goal", "hol")
                }
                for start in range(0, episodes, n):
                    size = min(n, episodes - start)
                    mods = np.full(size, m, np.int64)
                    raw = rng.uniform(-1.0, 1.0, (size, spec.goal_dim))
                    numbers = position * episodes + start + np.arange(size)
                    played = play_round(
                        self.envs, condition, mods, raw, rng, self.epoch, policy_for,
                        numbers, np.ones(size, bool), np.zeros(size, bool), observer,
                    )  # fmt: skip
                    data, goals, success = played.info.data, played.info.goals, played.info.success
                    experts = played.experts
                    final = data.achieved[:, -1]
                    parts["success"].append(success)
                    parts["module_success"].append(condition.module_success(env, data, mods, goals))
                    parts["distance"].append(
                        _distances(spec, m, final, env.goal(m, goals[:, m], final))
                    )
                    parts["expert"].append(np.asarray(experts, np.int64))
                    parts["goal"].append(raw)
                    holistic = condition.holistic_distance(env, goals, final)
                    if holistic is not None:
                        parts["hol"].append(holistic)
                    bar.update(size)
                per = {k: np.concatenate(v) for k, v in parts.items() if v}
                hol = per.pop("hol", None)
                ok = int(per["success"].sum())
                low, high = wilson_interval(ok, episodes)
                results.append(
                    ModuleEvaluation(
                        module=name,
                        episodes=episodes,
                        success=ok / episodes,
                        low=low,
                        high=high,
                        module_success=float(per["module_success"].mean()),
                        distance=float(per["distance"].mean()),
                        holistic_distance=float(hol.mean()) if hol is not None else None,
                        per_episode=per,
                    )
                )
        finally:
            bar.close()
        return Evaluation(
            run=str(self.folder.path),
            checkpoint=self.checkpoint.name,
            condition=self.config.condition,
            variant=self.variant,
            episode=self.episode,
            modules=results,
        )


def check_episodes(episodes: int) -> None:
    """A `ValueError` naming `--episodes` outside 1 to `MAX_EPISODES`."""
    if not 1 <= episodes <= MAX_EPISODES:
        raise ValueError(
            f"--episodes must be from 1 to {MAX_EPISODES:,} per module, got {episodes:,} "
            "(why: curious.watching.evaluation.MAX_EPISODES)"
        )


def check_seed(seed: int) -> None:
    """A `ValueError` naming `--seed` outside 0 to `curious.config.MAX_SEED`, the seeds the
    suite's episodes take (as `curious render --seed`, which plays the same episodes)."""
    if not 0 <= seed <= MAX_SEED:
        raise ValueError(f"--seed must be from 0 to {MAX_SEED:,}, got {seed}")


def open_run(
    run: str | Path,
    episodes: int = 100,
    variant: str | None = None,
    seed: int = 0,
    copies: int | None = None,
    processes: int | None = None,
) -> EvaluationSession:
    """Load the newest readable checkpoint of the run in folder `run` (the falling-back rule of
    `--resume`; its replay is not read) and build its agent, its condition and the copies that
    will play `episodes` episodes per module. Close the session (or use it in `with`) to stop
    the copies' worker processes. Arguments and errors: as `evaluate`'s."""
    import torch

    from curious.agent.agent import Agent
    from curious.runs import checkpoint

    check_episodes(episodes)
    check_seed(seed)
    folder = RunFolder(run)
    info = folder.read_info()  # a RunFolderError naming what is missing or damaged
    config = folder.read_config()
    if config.device != "cpu" and not torch.cuda.is_available():
        config = dataclasses.replace(config, device="cpu")  # a GPU run evaluates on a laptop
    run_modules = list(info.module_names)
    latest = checkpoint.load_latest(folder.checkpoints, config.device, replay=False)
    if latest is None:
        raise ValueError(
            f"{folder.path} holds no checkpoint of a trained agent (in {folder.checkpoints})."
            + shipped_run_note(folder.path)
        )
    path, state, _ = latest
    differs = config_differences(state["config"], folder.read_config().to_dict())
    if differs:  # a hand-edited config.json: the agent and its scoring are the checkpoint's
        raise ValueError(
            f"checkpoint {path} is from another config than {folder.config_path} (differs in "
            f"{', '.join(differs)}): restore config.json, as `--resume` would need it"
        )
    variant = config.variant if variant is None else variant  # '' is no variant
    n = max(1, min(episodes, copies or config.n_workers))
    fns = suite_env_fns(variant, seed, n, stream=EVAL_STREAM)
    workers = min(n, config.processes if processes is None else processes)
    if workers < 1:
        raise ValueError(f"--processes must be at least 1, got {processes}")
    envs: LocalEnvs | ProcessEnvs = (
        ProcessEnvs(fns, workers) if workers > 1 else LocalEnvs([fn() for fn in fns])
    )
    try:
        env, spec = envs.reference, envs.spec
        if run_modules and list(spec.module_names) != run_modules:
            raise ValueError(
                f"variant {variant!r} has modules {', '.join(spec.module_names)}; the run was "
                f"trained on {', '.join(run_modules)}"
            )
        if config.sensor_failure:
            envs.set_sensor_failure(np.zeros(n, bool))  # evaluate the unperturbed agent
        condition = make_condition(config, spec)
        agent = Agent(spec, config, GoalBox.of(env), condition.n_experts)
        try:
            agent.load_state_dict(state["agent"])
        except (KeyError, RuntimeError) as exc:
            raise ValueError(f"checkpoint {path} does not fit the run's agent ({exc})") from None
    except BaseException:
        envs.close()
        raise
    return EvaluationSession(
        folder=folder,
        config=config,
        checkpoint=path,
        episode=int(state["episodes"]),
        epoch=int(state["cycles"]) // config.n_cycles,
        variant=variant,
        seed=seed,
        envs=envs,
        condition=condition,
        agent=agent,
    )


def evaluate(
    run: str | Path,
    episodes: int = 100,
    modules: Sequence[str] | None = None,
    variant: str | None = None,
    seed: int = 0,
    copies: int | None = None,
    processes: int | None = None,
    policy: PolicyFor | None = None,
    progress: bool = False,
    observer: Any = None,
) -> Evaluation:
    """Play `episodes` noise-free episodes per module of the run in folder `run`.

    `modules`: names to play (default: all the run's); `variant`: the suite variant to play
    on (default: the run's; its modules must be the run's); `seed`: the evaluation's own seed
    (goals and environment copies; the same seed gives the same numbers); `copies`: episodes
    played at once (default: the run's `n_workers`, at most `episodes`); `processes`: worker
    processes stepping them (default: the run's `env_processes`; the numbers do not depend on
    it). `observer`: as `EvaluationSession.evaluate`'s. `policy`, for tests:
    `policy(goal, experts)` returns the `act` of a batch instead of the agent's.
    Errors (`ValueError`, `RuntimeError`) name what is wrong in one line."""
    with open_run(run, episodes, variant, seed, copies, processes) as session:
        return session.evaluate(episodes, modules, policy, observer, progress)


def evaluation_table(result: Evaluation) -> str:
    """A plain-text table of `result`, one row per module."""
    her = any(r.holistic_distance is not None for r in result.modules)
    head = ["module", "episodes", "success", "95% interval", "final distance"]
    if her:
        head[2] = "success (holistic)"
        head += ["module_success", "holistic distance"]
    rows = [head]
    for r in result.modules:
        row = [
            r.module,
            str(r.episodes),
            f"{r.success:.3f}",
            f"[{r.low:.3f}, {r.high:.3f}]",
            f"{r.distance:.3f}",
        ]
        if her:
            row += [f"{r.module_success:.3f}", f"{r.holistic_distance:.3f}"]
        rows.append(row)
    widths = [max(len(row[i]) for row in rows) for i in range(len(head))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)) for row in rows]
    title = (
        f"{result.run}: {result.condition} on {result.variant}, checkpoint {result.checkpoint} "
        f"(episode {result.episode})"
    )
    return "\n".join([title, *lines]) + "\n"
