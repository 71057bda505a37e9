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


@pytest.mark.parametrize("curvature,x_star", [(0.8, -0.9), (0.8, 0.55), (0.8, -0.23), (0.14, 1.0), (0.02, -0.6)])
def test_a_walk_ends_where_its_steps_and_their_parabola_gain_little(curvature, x_star):
    """The walk from a hint (alpha_search._walk) on valleys of several widths, from 0 in steps of 0.1: without
    ``flat`` it goes on while the objective falls and brackets the minimum; with ``flat`` it evaluates a prefix of
    those points, and where it ends early (True: no refinement after it), the last step gained less than that fraction
    and the minimum lies less than that fraction below it (a parabola is exact on these).  The shallow valley
    (0.14, 1.0) is one where a rule on the step's gain alone would stop 3.8 % short: its first steps gain 0.85 % and
    0.77 %, the parabola predicts 2.9 % more."""
    from robustsynth.synthesis.alpha_search import WALK_FLAT, _walk

    f = lambda x: 3.0 + curvature * (x - x_star) ** 2  # noqa: E731
    step = 0.1
    plain, flat_end = _walk(f, 0.0, step, -3.0, 3.0)
    assert not flat_end
    best = min(plain, key=lambda p: p[1])
    assert abs(best[0] - x_star) <= step / 2 + 1e-9  # bracketed: the best point is the grid point nearest x*
    evaluate, calls = _recorder(f)
    pts, flat_end = _walk(evaluate, 0.0, step, -3.0, 3.0, flat=WALK_FLAT)
    assert sorted(pts) == sorted((x, f(x)) for x in calls)
    assert set(x for x, _ in pts) <= set(x for x, _ in plain)
    if flat_end:
        assert len(calls) < len(plain)
        before = min(f(x) for x in calls[:-1])
        assert 0.0 < (before - f(calls[-1])) / before < WALK_FLAT
        assert (f(calls[-1]) - 3.0) / f(calls[-1]) < WALK_FLAT
    else:
        assert sorted(pts) == sorted(plain)


def test_the_flat_rule_ends_the_walks_of_the_committed_valleys_where_the_next_point_was_worse():
    """The objective values the default robot's and turns' walks met (0.1 rad; docs: WALK_FLAT): the rule ends each
    at the best point the whole walk found, one solve sooner; nonlinear-proof's walk is unchanged."""
    from robustsynth.synthesis.alpha_search import WALK_FLAT, _walk

    walks = {  # alpha -> objective, as measured
        "default": {0.1486: 6.15055e-4, 0.1632: 6.26974e-4, 0.13531: 6.1273e-4, 0.12321: 6.18202e-4},
        "turns": {0.21232: 3.33834e-3, 0.23318: math.inf, 0.19333: 3.02299e-3, 0.17604: 2.91402e-3,
                  0.16029: 2.89453e-3, 0.14596: 2.93987e-3},
        "nonlinear-proof": {0.21845: 1.06915e-3, 0.2399: 1.11808e-3, 0.19891: 1.0541e-3, 0.18112: 1.05665e-3},
    }
    for name, table in walks.items():
        x0 = math.log(next(iter(table)))
        step = math.log(list(table)[1]) - x0

        def f(x, table=table):
            (a,) = [a for a in table if abs(math.log(a) - x) < 1e-3]
            return table[a]

        plain, _ = _walk(f, x0, step, -6.0, 0.0)
        pts, flat_end = _walk(f, x0, step, -6.0, 0.0, flat=WALK_FLAT)
        assert min(v for _, v in pts) == min(v for _, v in plain)
        assert (len(pts), flat_end) == ((len(plain), False) if name == "nonlinear-proof" else (len(plain) - 1, True))
