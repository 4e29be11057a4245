"""Spontaneous forgetting (the paper's Fig. 2b/2c, claim C3): drops of a mastered module's
competence with nothing perturbed, the learning progress they raise, and the practice they draw.

The paper (§4, "Results"): in one CURIOUS run the competence on T3, "previously mastered", drops
around episode 250,000 while the agent trains on other modules; the module's absolute LP rises
over that period, "which in turn triggers an additional focus of the agent towards that task",
and the competence comes back. The sensory failure (`curious.analysis.perturbation`) measures the
same response around a known onset; here the onset is read from the competence alone, by a rule
fixed before any shipped run was read for drops. Per run and achievable module, over the
``competence/<m>``, ``lp/<m>`` and ``p_lp/<m>`` columns of ``metrics.parquet`` (the agent's own
measures at each episode) and the practised ``module`` of each episode:

1. **Mastered.** A module's competence counts once it averages a full window of its
   self-evaluations (``lp_window`` of them, as `curious.analysis.milestones.competence_crossings`
   asks; before, one lucky evaluation reads 1.0). The module is *mastered* from the evaluation at
   which its competence has stood at or above `MASTERED` (0.9) for `MASTERY_HOLD` (half a window,
   rounded up) of its consecutive self-evaluations: nine in ten of its last evaluations succeed,
   and have for a while, so a competence hovering at the line is not called mastered by one
   lucky reading. 0.9 is the level the issue that asks for this analysis names for "mastered"
   and the higher of the report's two test-success milestones (`milestones.LEVELS`).
2. **Drop.** After mastery, the *peak* is the highest competence since the module was mastered.
   A *drop* is detected at the first episode whose competence is `DROP_DEPTH` (0.2) or more below
   the peak. Why 0.2: the competence of a module succeeding with probability 0.9 over a window of
   100 evaluations (the `laptop` runs' ``lp_window``) has a binomial standard deviation of 0.03,
   so the highest and lowest readings over some fifty independent windows of a stable stretch lie
   about 0.15 apart (2.3 standard deviations either side); 0.2 is above that, and a module at 0.9
   that drops by it has lost more than a fifth of its successes. A smaller decline is not counted.
3. **Descent.** The drop's *start* is the first episode of its final descent: the episode after
   the last one, before the drop, whose competence stood within `DESCENT_BAND` (0.1, half the
   depth) of the peak. The *trough* is the lowest competence from the drop until the module
   recovers (or the run ends); ``depth`` is the peak minus the trough.
4. **Recovered.** At the first episode after the drop whose competence is back at or above
   `MASTERED`; ``recovery_episodes`` counts from the drop's episode (NaN: not by the run's end).
   From there the module is read again from step 1 (mastered once more after `MASTERY_HOLD`
   evaluations at 0.9), so a run can show several drops of one module.
5. **Response.** Two spans of episodes, as `perturbation.recovery` compares the episodes before
   the failure with as many after it: *after* is the drop's whole course, from its start to the
   recovery (or the run's end), *before* as many episodes just before the start, but none before
   the module was mastered (the mastered stretch). Over each, with `perturbation`'s own measure:
   the module's mean absolute LP (``lp_before``, ``lp_after``) and mean probability of being
   practised (``p_lp_before``, ``p_lp_after``; the ``p_lp/<m>`` column: p_LP in CURIOUS, uniform
   in M-UVFA, in MG-TE 1 in the epochs of the module's turn and 0 in the others); and the share
   of episodes that practised the module (``practice_before``, ``practice_after``).
   ``lp_trough`` is the LP at the trough. The paper's claim reads as: LP up (``lp_after`` and
   ``lp_trough`` above ``lp_before``), and, where modules are chosen by LP, p_LP and practice up
   too, then the competence back.

Runs without self-evaluations (``her``: its competence columns are NaN) and modules never
mastered have no drop; `mastery` lists every (run, achievable module) with its first mastery and
its drops so that "none seen" is visible. Runs whose sensory failure started are perturbed on
purpose: a drop of the perturbed module is the failure, not forgetting (`perturbation.recovery`
measures it), so callers leave those runs out or read them apart.
"""

from __future__ import annotations

__all__ = ["DESCENT_BAND", "DROP_DEPTH", "MASTERED", "MASTERY_HOLD"]

MASTERED = 0.9
"""Competence, over a full window of the module's self-evaluations, at which it is mastered (and,
after a drop, recovered)."""
MASTERY_HOLD = 0.5
"""Fraction of ``lp_window`` (rounded up): the consecutive self-evaluations of the module over
which its competence must stay at or above `MASTERED` before it counts as mastered."""
DROP_DEPTH = 0.2
"""How far below its peak since mastery the competence must fall for a drop."""
DESCENT_BAND = 0.1
"""A drop's descent starts after the last episode whose competence was within this of the
peak."""
