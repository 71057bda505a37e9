"""What the margin searches of every plant share: the bisection (their result shapes, ``Margin`` and
``MarginReport``, are :mod:`robustsynth.results`'s)."""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["bisect"]


def bisect(ok: Callable[[float], bool], good: float, bad: float, tol: float) -> float:
    """Largest step towards ``bad`` where ``ok`` holds, knowing ok(good) and not ok(bad)."""
    while abs(bad - good) > tol:
        mid = (good + bad) / 2.0
        if ok(mid):
            good = mid
        else:
            bad = mid
    return good
