"""Evaluate a trained run: noise-free episodes per module from its newest checkpoint.

`evaluate(run, ...)` loads the run's newest readable checkpoint (`checkpoint.load_latest`, the
falling-back rule of `--resume`), builds the run's agent and condition, and plays, for every
chosen module, `episodes` noise-free episodes with goals drawn uniformly in that module's goal
space, in batches across environment copies seeded apart from training (stream 0) and from the
test rollouts (stream 1). Scores are the test rollouts' (`Trainer.test_rollouts`): `success`
is the condition's score (for `her` its holistic goal, as the paper), `module_success` whether
the module met its own goal slot; MG-TE plays module m with its expert m. Nothing of the run
folder is written.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

EVAL_STREAM = 2
"""`suite_env_fns` stream of the evaluation copies (0: training, 1: test rollouts)."""

Policy = Callable[[np.ndarray, np.ndarray, int], np.ndarray]
"""`act(states, achieved, t)` -> actions, as `run_episodes` calls it."""


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


def evaluate(
    run: str | Path,
    episodes: int = 100,
    modules: Sequence[str] | None = None,
    variant: str | None = None,
    seed: int = 0,
    copies: int | None = None,
    processes: int | None = None,
    policy: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], Policy] | None = None,
    progress: bool = False,
) -> Evaluation:
    """Play `episodes` noise-free episodes per module of the run in folder `run`.

    `modules`: names to play (default: all the run's); `variant`: the suite variant to play
    on (default: the run's; its modules must be the run's); `seed`: the evaluation's own seed
    (goals and environment copies; the same seed gives the same numbers); `copies`: episodes
    played at once (default: the run's `n_workers`, at most `episodes`); `processes`: worker
    processes stepping them (default: the run's `env_processes`; the numbers do not depend on
    it). `policy`, for tests:
    `policy(goals, mask, task, experts)` returns the `act` of a batch instead of the agent's.
    Errors (`ValueError`, `RuntimeError`) name what is wrong in one line."""
    import torch
    from tqdm.auto import tqdm

    from curious import checkpoint
    from curious.agent import Agent
    from curious.conditions import make_condition
    from curious.env_batch import LocalEnvs, ProcessEnvs
    from curious.envs import suite_env_fns
    from curious.inputs import GoalBox
    from curious.rollouts import run_episodes
    from curious.run_folder import RunFolder
    from curious.train import goal_policy

    if episodes < 1:
        raise ValueError(f"--episodes must be at least 1, got {episodes}")
    folder = RunFolder(run)
    if not folder.config_path.is_file():
        raise ValueError(f"{folder.path} is not a run folder (no config.json)")
    config = folder.read_config()
    if config.device != "cpu" and not torch.cuda.is_available():
        config = dataclasses.replace(config, device="cpu")  # a GPU run evaluates on a laptop
    run_modules = list(folder.read_stored().get("modules", []))
    latest = checkpoint.load_latest(folder.checkpoints, config.device)
    if latest is None:
        raise ValueError(f"{folder.path} holds no checkpoint to evaluate (in {folder.checkpoints})")
    path, state, _ = latest
    variant = variant or config.variant
    n = max(1, min(episodes, copies or config.n_workers))
    fns = suite_env_fns(variant, seed, n, stream=EVAL_STREAM)
    workers = min(n, config.processes if processes is None else processes)
    if workers < 1:
        raise ValueError(f"--processes must be at least 1, got {processes}")
    envs: LocalEnvs | ProcessEnvs = (
        ProcessEnvs(fns, workers) if workers > 1 else LocalEnvs([fn() for fn in fns])
    )
    env, spec = envs.reference, envs.spec
    if run_modules and list(spec.module_names) != run_modules:
        raise ValueError(
            f"variant {variant!r} has modules {', '.join(spec.module_names)}; the run was "
            f"trained on {', '.join(run_modules)}"
        )
    chosen = list(modules) if modules else list(spec.module_names)
    unknown = [m for m in chosen if m not in spec.module_names]
    if unknown:
        raise ValueError(
            f"unknown module {', '.join(unknown)}; the run's are {', '.join(spec.module_names)}"
        )
    if config.sensor_failure:
        envs.set_sensor_failure(np.zeros(n, bool))  # evaluate the unperturbed agent
    condition = make_condition(config, spec)
    agent = Agent(spec, config, GoalBox.of(env), condition.n_experts)
    try:
        agent.load_state_dict(state["agent"])
    except (KeyError, RuntimeError) as exc:
        raise ValueError(f"checkpoint {path} does not fit the run's agent ({exc})") from None
    epoch = int(state["cycles"]) // config.n_cycles
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0xE7A1]))
    explore = np.zeros(n, bool)

    bar = tqdm(
        total=episodes * len(chosen),
        unit="ep",
        disable=not progress,
        dynamic_ncols=True,
        desc=f"evaluate {config.condition}",
    )
    results = []
    try:
        for name in chosen:
            m = spec.module_index(name)
            parts: dict[str, list[np.ndarray]] = {
                k: [] for k in ("success", "module_success", "distance", "expert", "goal", "hol")
            }
            for start in range(0, episodes, n):
                size = min(n, episodes - start)
                mods = np.full(size, m, np.int64)
                raw = rng.uniform(-1.0, 1.0, (size, spec.goal_dim))
                goals, mask, task = condition.goals(env, mods, raw, rng)
                experts = condition.acting_experts(mods, epoch)
                if policy is not None:
                    act = policy(goals, mask, task, experts)
                else:
                    act = goal_policy(env, agent, goals, mask, task, experts, explore[:size], rng)

                data = run_episodes(envs, mods, raw, act)
                final = data.achieved[:, -1]
                parts["success"].append(condition.success(env, data, mods, goals))
                parts["module_success"].append(condition.module_success(env, data, mods, goals))
                parts["distance"].append(
                    _distances(spec, m, final, env.goal(m, goals[:, m], final))
                )
                parts["expert"].append(np.asarray(experts, np.int64))
                parts["goal"].append(raw)
                if condition.goal_space is not None:
                    space = condition.goal_space
                    parts["hol"].append(space.distance(final, space.place(env, goals, final)))
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
        envs.close()
    return Evaluation(
        run=str(folder.path),
        checkpoint=path.name,
        condition=config.condition,
        variant=variant,
        episode=int(state["episodes"]),
        modules=results,
    )


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
