"""What a run's recording keeps, and how much of it: `RecorderSettings`, readable without Rerun
(the command line's help shows its defaults)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RecorderSettings:
    """What a recording keeps, and how much of it (size against detail).

    rollout_every: record an evaluation episode in 3D every this many evaluation episodes
        (the 0th, K-th, 2K-th, ...); 0 records none.
    rollout_stride: keep every k-th step of a recorded rollout (the last step always).
    stats_on_change: write competence, LP and p_LP of a module only where they change (they
        change on that module's evaluation episodes), drawn as steps; False writes every episode.
    stats_keyframe_every: with `stats_on_change`, also write a module's unchanged value once it
        was last written this many episodes ago, so that a run watched live, or a recording cut
        short, draws a module whose value holds (reach at 1.0) up to the present instead of
        ending its line at its last change; 0 never (`close()` writes the final values anyway).
    goal_radius: radius of the sphere drawn around the goal (the success threshold, metres).
    path_radius: line radius of the gripper path (metres).
    flush_rows: scalar rows buffered before they are sent (each send makes one chunk per
        entity, and a chunk costs ~1.2 kB in the file whatever its length).
    flush_seconds: longest time scalars wait in the buffer when only writing the file.
    live_flush_seconds: the same while streaming to a viewer (`spawn`/`connect`).
    compact_on_close: rewrite the file on `close()` with its chunks merged (several times
        smaller; takes well under a second for a laptop run).
    """

    rollout_every: int = 50
    rollout_stride: int = 1
    stats_on_change: bool = True
    stats_keyframe_every: int = 500
    goal_radius: float = 0.05
    path_radius: float = 0.004
    flush_rows: int = 20_000
    flush_seconds: float = 60.0
    live_flush_seconds: float = 2.0
    compact_on_close: bool = True

    def __post_init__(self) -> None:
        if self.rollout_every < 0:
            raise ValueError(f"rollout_every must be >= 0, got {self.rollout_every}")
        if self.rollout_stride < 1:
            raise ValueError(f"rollout_stride must be >= 1, got {self.rollout_stride}")
        if self.stats_keyframe_every < 0:
            raise ValueError(f"stats_keyframe_every must be >= 0, got {self.stats_keyframe_every}")
        if self.goal_radius <= 0 or self.path_radius <= 0:
            raise ValueError("goal_radius and path_radius must be > 0")
        if self.flush_rows < 1 or self.flush_seconds < 0 or self.live_flush_seconds < 0:
            raise ValueError("flush_rows must be >= 1 and the flush intervals >= 0")

    def rollout_due(self, eval_index: int) -> bool:
        """True when the evaluation episode with this 0-based count is to be recorded in 3D."""
        return self.rollout_every > 0 and eval_index % self.rollout_every == 0
