"""Competence, learning progress (absolute, and signed) and p_LP on hand-computed sequences."""

import numpy as np
import pytest

from curious.agent.learning_progress import CompetenceTracker, lp_probabilities


def test_competence_and_lp_follow_hand_computed_sequence():
    # Window 3: competence over the last 3 results, LP between the last k and the k before,
    # k = min(3, n // 2). The 8 results overrun the 6-slot queue, so wrap-around is covered.
    tracker = CompetenceTracker(n_modules=2, window=3, measure="absolute")
    results = [0, 0, 1, 1, 1, 1, 0, 0]
    expected_competence = [0, 0, 1 / 3, 2 / 3, 1, 1, 2 / 3, 1 / 3]
    expected_lp = [0, 0, 1, 1, 0.5, 2 / 3, 0, 2 / 3]
    for r, c, lp in zip(results, expected_competence, expected_lp, strict=True):
        tracker.add(0, bool(r))
        assert tracker.competence()[0] == pytest.approx(c)
        assert tracker.learning_progress()[0] == pytest.approx(lp)
        # the other module has no result: no competence, no progress
        assert tracker.competence()[1] == 0 and tracker.learning_progress()[1] == 0


def test_lp_is_absolute_so_forgetting_counts_as_progress():
    tracker = CompetenceTracker(n_modules=1, window=2, measure="absolute")
    for r in [1, 1, 0, 0]:
        tracker.add(0, bool(r))
    assert tracker.competence()[0] == 0
    assert tracker.learning_progress()[0] == pytest.approx(1.0)


def test_p_lp_hand_computed():
    p = lp_probabilities(np.array([0.5, 0.0, 0.25, 0.25]), eps=0.4)
    np.testing.assert_allclose(p, [0.1 + 0.6 * 0.5, 0.1, 0.1 + 0.6 * 0.25, 0.1 + 0.6 * 0.25])
    assert p.sum() == pytest.approx(1.0)


def test_p_lp_uniform_while_no_progress():
    np.testing.assert_allclose(lp_probabilities(np.zeros(7), 0.4), np.full(7, 1 / 7))
    tracker = CompetenceTracker(n_modules=4, window=300, measure="absolute")
    np.testing.assert_allclose(tracker.p_lp(0.4), np.full(4, 0.25))
    # constant results give no progress either
    for _ in range(50):
        tracker.add(2, True)
    np.testing.assert_allclose(tracker.p_lp(0.4), np.full(4, 0.25))


def test_p_lp_of_a_module_without_progress_is_eps_over_n():
    tracker = CompetenceTracker(n_modules=3, window=10, measure="absolute")
    for r in [0] * 10 + [1] * 10:
        tracker.add(0, bool(r))
    p = tracker.p_lp(0.4)
    assert p[1] == pytest.approx(0.4 / 3) and p[2] == pytest.approx(0.4 / 3)
    assert p[0] == pytest.approx(0.4 / 3 + 0.6)


def test_window_300_uses_the_300_results_before():
    tracker = CompetenceTracker(n_modules=1, window=300, measure="absolute")
    for r in [0] * 300 + [1] * 150 + [0] * 150:
        tracker.add(0, bool(r))
    assert tracker.competence()[0] == pytest.approx(0.5)
    assert tracker.learning_progress()[0] == pytest.approx(0.5)
    for _ in range(300):  # 600 more zeros would reach 0; 300 zeros: last 300 all 0
        tracker.add(0, False)
    assert tracker.competence()[0] == 0
    assert tracker.learning_progress()[0] == pytest.approx(0.5)  # the 300 before: 150/300


def test_state_round_trip():
    a = CompetenceTracker(n_modules=3, window=5, measure="absolute")
    rng = np.random.default_rng(0)
    for _ in range(40):
        a.add(int(rng.integers(3)), bool(rng.random() < 0.5))
    b = CompetenceTracker(n_modules=3, window=5, measure="absolute")
    b.load_state_dict(a.state_dict())
    np.testing.assert_array_equal(a.competence(), b.competence())
    np.testing.assert_array_equal(a.learning_progress(), b.learning_progress())
    a.add(1, True)
    b.add(1, True)
    np.testing.assert_array_equal(a.p_lp(0.4), b.p_lp(0.4))


def test_negative_lp_rejected():
    with pytest.raises(ValueError, match="negative"):
        lp_probabilities(np.array([0.1, -0.2]), 0.4)


def test_lp_needs_three_results_as_the_authors_queue():
    """flowersteam/curious, baselines/her/queues.py: CompetenceQueue.update computes CP only
    when it holds more than 2 results."""
    tracker = CompetenceTracker(n_modules=1, window=300, measure="absolute")
    tracker.add(0, False)
    tracker.add(0, True)
    assert tracker.learning_progress()[0] == 0  # two results: no progress yet
    tracker.add(0, False)  # k = 1: |0 - 1|
    assert tracker.learning_progress()[0] == pytest.approx(1.0)


def test_signed_lp_counts_a_rise_and_not_a_fall():
    """`lp_measure=signed` (not in the paper): LP is recent - before, counted as 0 where it is
    negative; the sequence of the first test, whose last step is a fall (1/3 against 1)."""
    tracker = CompetenceTracker(n_modules=2, window=3, measure="signed")
    results = [0, 0, 1, 1, 1, 1, 0, 0]
    expected_lp = [0, 0, 1, 1, 0.5, 2 / 3, 0, 0]  # absolute: the same but 2/3 at the end
    for r, lp in zip(results, expected_lp, strict=True):
        tracker.add(0, bool(r))
        assert tracker.learning_progress()[0] == pytest.approx(lp)
    assert tracker.competence()[0] == pytest.approx(1 / 3)  # competence is measured alike


def test_signed_lp_gives_a_forgotten_module_no_more_than_eps():
    """Forgetting (competence 1 -> 0) draws practice back under the paper's absolute LP, and
    not under signed LP, where the module keeps eps / N."""
    p = {}
    for measure in ("absolute", "signed"):
        tracker = CompetenceTracker(n_modules=3, window=2, measure=measure)
        for r in [0, 0, 1, 1]:
            tracker.add(0, bool(r))  # learning
        for r in [1, 1, 0, 0]:
            tracker.add(1, bool(r))  # forgotten
        p[measure] = tracker.p_lp(0.4)
    np.testing.assert_allclose(p["absolute"], [0.4 / 3 + 0.3, 0.4 / 3 + 0.3, 0.4 / 3])
    np.testing.assert_allclose(p["signed"], [0.4 / 3 + 0.6, 0.4 / 3, 0.4 / 3])


def test_a_checkpoint_holds_results_and_the_measure_is_the_configs():
    """The queues go into a checkpoint; the measure comes from the run's config (which a resumed
    run may not change), so a signed run resumes signed."""
    a = CompetenceTracker(n_modules=2, window=2, measure="signed")
    for r in [1, 1, 1, 0, 0]:  # a fall: |0 - 1| = 1, counted as 0
        a.add(0, bool(r))
    b = CompetenceTracker(n_modules=2, window=2, measure="signed")
    b.load_state_dict(a.state_dict())
    np.testing.assert_array_equal(b.learning_progress(), [0, 0])
    absolute = CompetenceTracker(n_modules=2, window=2, measure="absolute")
    absolute.load_state_dict(a.state_dict())
    np.testing.assert_array_equal(absolute.learning_progress(), [1, 0])
    with pytest.raises(ValueError, match="unknown LP measure 'relative'"):
        CompetenceTracker(n_modules=2, window=2, measure="relative")
