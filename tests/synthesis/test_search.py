"""The alpha search's refinement (``synthesis.alpha_search._parabolic``) on functions whose minimum is
known: few evaluations on a smooth valley, the minimum to the stop tolerance, and the golden-section
fallback beside an infeasible (infinite) point."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robustsynth.synthesis.alpha_search import HINT_STOP_REL, REFINE_STEPS, _parabolic


def _recorder(f):
    calls = []

    def evaluate(x: float) -> float:
        calls.append(x)
        return f(x)

    return evaluate, calls


@pytest.mark.parametrize("x_star", [-1.7, -1.2, -0.9])
def test_a_smooth_valley_is_found_in_a_step_or_two(x_star):
    f = lambda x: 3.0 + 0.8 * (x - x_star) ** 2 + 0.1 * (x - x_star) ** 3  # noqa: E731
    pts = [(x, f(x)) for x in (-2.2, -1.3, -0.4)]  # the walk's bracket: the best point inside
    evaluate, calls = _recorder(f)
    _parabolic(evaluate, pts)
    assert 1 <= len(calls) <= REFINE_STEPS
    best = min([f(x) for x, _ in pts] + [f(x) for x in calls])
    assert best <= 3.0 * (1 + 10 * HINT_STOP_REL)  # the minimum's value to (ten times) the stop tolerance


def test_an_infinite_neighbour_hands_over_to_the_golden_section():
    f = lambda x: math.inf if x > -0.9 else 2.0 + (x + 1.0) ** 2  # noqa: E731  feasible up to -0.9
    pts = [(-1.5, f(-1.5)), (-1.2, f(-1.2)), (-0.8, f(-0.8))]
    evaluate, calls = _recorder(f)
    _parabolic(evaluate, pts)
    assert calls  # the golden section evaluated inside [-1.5, -0.8]
    assert all(-1.5 < x < -0.8 for x in calls)
    assert min(f(x) for x in calls) < f(-1.2)


def test_a_minimum_at_the_end_of_the_points_is_searched_towards_its_neighbour():
    """No parabola through an end point: a golden section between it and its neighbour (a minimum
    inside that interval is found; one at the very end stays there)."""
    f = lambda x: (x + 1.9) ** 2  # noqa: E731  minimum between the first two points
    evaluate, calls = _recorder(f)
    _parabolic(evaluate, [(x, f(x)) for x in np.linspace(-2, -1, 5)])
    assert calls and all(-2.0 < x < -1.75 for x in calls)
    assert min(f(x) for x in calls) < f(-2.0)


def test_a_step_predicted_to_gain_nothing_is_not_taken():
    """On a narrow bracket whose middle point is the minimum to within the tolerance, the parabola's
    predicted gain is below HINT_STOP_REL: with ``predict`` no solve is spent; without it one is."""
    f = lambda x: 1.0 + 0.5 * (x + 1.003) ** 2  # noqa: E731  predicted gain 4.5e-6 < HINT_STOP_REL
    pts = [(x, f(x)) for x in (-1.1, -1.0, -0.9)]
    evaluate, calls = _recorder(f)
    _parabolic(evaluate, pts, predict=True)
    assert calls == []
    _parabolic(evaluate, pts, predict=False)
    assert len(calls) >= 1


@pytest.mark.parametrize("x_star", [-1.7, -1.2, -0.9])
def test_a_costly_refinement_stops_at_the_first_step_that_gains_little(x_star):
    """The cost rule (issue 51, alpha_search._refine): on a problem whose solve is costly every refinement step but
    the last lowers the best objective by at least COSTLY_GAIN, the last by less, and it takes no more steps than the
    same refinement without the rule (which goes on to HINT_STOP_REL); without it, _parabolic itself."""
    from robustsynth.synthesis.alpha_search import COSTLY_GAIN, _refine
    from robustsynth.synthesis.runner import _Best

    f = lambda x: 3.0 + 0.8 * (x - x_star) ** 2 + 0.1 * (x - x_star) ** 3  # noqa: E731
    pts = [(x, f(x)) for x in (-2.2, -1.3, -0.4)]

    def run(costly):
        best = _Best(value=min(v for _, v in pts))
        seen = [best.value]

        def evaluate(x: float) -> float:
            v = f(x)
            best.value = min(best.value, v)
            seen.append(best.value)
            return v

        _refine(evaluate, pts, best, costly, lambda _m: None)
        return seen

    costly, cheap = run(True), run(False)
    gains = [(a - b) / a for a, b in zip(costly, costly[1:])]
    assert gains and all(g >= COSTLY_GAIN for g in gains[:-1]) and gains[-1] < COSTLY_GAIN
    assert len(costly) <= len(cheap)
    evaluate, calls = _recorder(f)
    _parabolic(evaluate, pts)
    assert len(calls) == len(cheap) - 1
