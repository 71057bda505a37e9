"""The toy objective's certificate rows (tests/objectives/toy_decay.py), on the checker's side: the decay LMIs'
rows that ``stability`` proves, and one figure of its own, the periods in which V halves at the proven rate
(the figure a new objective adds: nothing else in the tool names it)."""

from __future__ import annotations

import math

from robustsynth.certificate.objectives import stability

FIGURE = "toy_half_life"  # [periods]


def rows(cert, family, K, X, lyap, mats, checks, figures):
    failed = stability.rows(cert, family, K, X, lyap, mats, checks, figures)
    if failed is None:  # V(k) <= r^(2k) V(0) halves within ceil(ln 2 / (-2 ln r)) periods
        figures[FIGURE] = math.ceil(math.log(2.0) / (-2.0 * math.log(figures["decay_rate"])))
    return failed
