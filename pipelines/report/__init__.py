"""`report.md`: what a reproduction trained, its figures, and the statistics behind them.

The main comparison's numbers (final success, Welch tests) come from the test rollouts, as Fig.
2a's; the distractors' from the competence; the sensory failure's from `analysis.recovery`, which
reports a recovery only where the failure started and the perturbed module was learned before it;
the sensory failure on a mastered module's from the test rollouts first (`analysis.
recovery_by_tests`, with the Welch test of `analysis.compare_recoveries`), the competence second;
spontaneous forgetting (drops of a mastered module, `analysis.mastery_drops`) is read in the main
comparison, the distractors and the long runs, whose runs nothing perturbs.

The report is a function of the budget, the combined metrics and test tables and the figures on
disk (nothing in it depends on when it was written), so rebuilding it from the same runs gives the
same bytes. An experiment appears once its metrics table exists, and one the budget leaves out
(`ReproduceBudget.omitted`) gets a sentence saying why; figures are linked relatively, so the
output folder can be moved or shared as a whole.

`document` assembles it: the opening (`overview`), then one section per experiment
(`main_comparison`, `distracting_modules`, `sensory_failures`, `long_study`;
`spontaneous_forgetting` for the experiments nothing perturbs), each written with the pieces of
`blocks`.
"""

from __future__ import annotations

from pipelines.report.document import write_report

__all__ = ["write_report"]
