"""The searches every plant's margins share (margins/common.py): the bisection of a certificate's end and the scan
for the first exhibited instability, checked against a threshold known in closed form."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.margins.common import bisect, first_bad

TOL = 1e-6  # the searches' resolution here


@settings(max_examples=60, deadline=None)
@given(edge=st.floats(0.05, 0.95), up=st.booleans())
def test_first_bad_brackets_the_threshold_within_its_tolerance(edge: float, up: bool) -> None:
    """Upwards (a delay) or downwards (a slip): the value found is bad, within TOL beyond the threshold, and its
    witness is the one ``bad`` gave there; the scan stops at the first bad point of the grid."""
    calls: list[float] = []

    def bad(x: float):
        calls.append(x)
        return {"at": x} if (x >= edge if up else x <= edge) else None

    grid = np.linspace(0.0, 1.0, 11) if up else np.linspace(1.0, 0.0, 11)
    hit, witness = first_bad(bad, grid[1:], TOL, clean=float(grid[0]))
    assert witness == {"at": hit} and abs(hit - edge) <= TOL and (hit >= edge if up else hit <= edge)
    scanned = [x for x in calls if x in grid]
    assert len(scanned) == int(np.argmax([(x >= edge if up else x <= edge) for x in grid[1:]])) + 1


def test_first_bad_says_none_for_a_clean_grid_and_takes_a_bad_first_point_as_found() -> None:
    assert first_bad(lambda x: None, [0.1, 0.2], TOL) == (None, None)
    assert first_bad(lambda x: "w", [0.1, 0.2], TOL) == (0.1, "w")  # nothing known clean before it: no bisection
    hit, w = first_bad(lambda x: "w" if x >= 0.15 else None, [0.2], TOL, clean=0.1)
    assert w == "w" and 0.15 <= hit <= 0.15 + TOL


@given(edge=st.floats(0.01, 0.99))
def test_bisect_finds_the_last_good_value(edge: float) -> None:
    good = bisect(lambda x: x <= edge, 0.0, 1.0, TOL)
    assert good <= edge < good + TOL + 1e-15
