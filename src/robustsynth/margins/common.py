"""What the margin searches of every plant share: the bisection of a certificate's end, and the scan for the first
exhibited instability (their result shapes, ``Margin`` and ``MarginReport``, are :mod:`robustsynth.results`'s)."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

__all__ = ["bisect", "first_bad"]


def bisect(ok: Callable[[float], bool], good: float, bad: float, tol: float) -> float:
    """Largest step towards ``bad`` where ``ok`` holds, knowing ok(good) and not ok(bad)."""
    while abs(bad - good) > tol:
        mid = (good + bad) / 2.0
        if ok(mid):
            good = mid
        else:
            bad = mid
    return good


def first_bad(bad: Callable[[float], Any], grid: Iterable[float], tol: float, clean: float | None = None
              ) -> tuple[float | None, Any]:
    """Walk ``grid`` (from the configured side outwards) until ``bad`` returns something (a witness), then bisect
    between the last clean value and that one to ``tol``.  ``clean``: a value known clean before the grid's first
    (None: a witness at the grid's first point is returned as found).  Returns (the value, its witness), (None,
    None) when the whole grid is clean."""
    hit, witness, prev = None, None, clean
    for x in grid:
        w = bad(float(x))
        if w is not None:
            hit, witness = float(x), w
            break
        prev = float(x)
    if hit is None or prev is None:
        return hit, witness
    while abs(hit - prev) > tol:
        mid = (prev + hit) / 2.0
        w = bad(mid)
        if w is not None:
            hit, witness = mid, w
        else:
            prev = mid
    return hit, witness
