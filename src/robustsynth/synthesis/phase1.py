"""Infeasibility where the solver fails (issue 51): the invariance LMIs as phase-1 problems over intervals of alpha.

On the robot proof's larger problems (three command intervals in a period, wide slip boxes) Clarabel often ends
in a numerical error instead of 'infeasible': the problem has no solution, its infeasibility certificate forms,
and the residuals stall (docs/theory.md §9, §6j).  A phase-1 problem always has a solution: maximize t with every
vertex LMI >= t I and the set's position extents bounded, X_00, X_11 <= kappa (:func:`~.lmis.build_invariance`
with ``phase1``).  Its maximum t* < 0 says that the LMIs have no solution whose set keeps |e_x|, |e_y| <= sqrt(kappa).  With the parameters of an
interval [alpha_lo, alpha_hi] of the line search (``1 - alpha_lo`` before X, ``sum beta <= alpha_hi``) the problem
relaxes the LMIs of every alpha in it, so a few such problems cover the whole search range, not only its grid.
A subset of the vertices is a relaxation too: the vertices with every uncertain instant at an end of its range
(no triangle's tangent point) go first, being fewer; an interval they do not settle is halved, and a half they
still do not settle is solved with all of them.

Said plainly: t* is the solver's optimum (Clarabel at its tolerances, 'optimal' or 'optimal_inaccurate'), not a
certificate re-checked in numpy; an interval counts only with t* <= -T_PROVEN.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from ..model.vertices import TANGENTS
from .lmis import build_invariance
from .solve import solve, solve_all

__all__ = ["Phase1", "prove_no_set", "settles", "PHASE1_BOX", "T_PROVEN", "INTERVALS"]

# X_00, X_11 <= PHASE1_BOX [m^2]: the set {xi' X^-1 xi <= 1} keeps |e_x|, |e_y| <= 1 m (the other states are bounded
# by the heading and motor rows already); a set larger than that is of no use on a path of metre-scale segments
PHASE1_BOX = 1.0
T_PROVEN = 1e-7  # an interval counts as proven only with t* <= -T_PROVEN (far beyond the solver's 1e-9 tolerances)
INTERVALS = 8  # log-spaced intervals over the alpha range, each halved once where it does not settle
PARALLEL = 2  # intervals solved at once, each on its own copy of the problem (this machine's two cores)


def settles(t: float | None) -> bool:
    """Whether a phase-1 maximum t* (None: the solver failed) shows its interval has no set: t* <= -T_PROVEN."""
    return t is not None and t <= -T_PROVEN


@dataclass
class Phase1:
    """What the phase-1 problems showed over [alpha_lo, alpha_hi]: per interval (lo, hi, t*, vertices used, status);
    ``proven``: every interval has t* <= -T_PROVEN."""

    alpha_lo: float
    alpha_hi: float
    intervals: list[tuple[float, float, float | None, int, str]] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def proven(self) -> bool:
        return bool(self.intervals) and all(settles(t) for _, _, t, _, _ in self.intervals)

    def summary(self) -> str:
        if not self.proven:
            return f"phase-1 over [{self.alpha_lo:.3g}, {self.alpha_hi:.3g}]: not settled ({self._unsettled()})"
        worst = max(float(t) for _, _, t, _, _ in self.intervals)
        return (f"no set with |e_x|, |e_y| <= {math.sqrt(PHASE1_BOX):g} m at any alpha in [{self.alpha_lo:.3g}, {self.alpha_hi:.3g}] "
                f"({len(self.intervals)} phase-1 problems, largest t* {worst:.3g}, {self.seconds:.0f} s)")

    def _unsettled(self) -> str:
        bad = [(a, b, t) for a, b, t, _, _ in self.intervals if not settles(t)]
        return ", ".join(f"[{a:.3g}, {b:.3g}]: " + ("the solver failed" if t is None else f"t* {t:.3g}") for a, b, t in bad)


def _exact_end_vertices(model: Any) -> Any | None:
    """The model with only its vertices whose uncertain instants all sit at an end of their range, or None when
    that is every vertex (or none)."""
    keep = tuple(v for v in model.vertices if TANGENTS not in v.label)
    if not keep or len(keep) == len(model.vertices):
        return None
    return replace(model, vertices=keep)


def _accept(lp: Any) -> Callable[[], bool]:
    return lambda: lp.extra["t"].value is not None and math.isfinite(float(lp.extra["t"].value))


def _t_stars(lps: list[Any], intervals: list[tuple[float, float]], solver: str) -> list[tuple[float | None, str]]:
    """t* of each interval, on its own copy of the problem (``lps``, one per interval), solved at once
    (:func:`~.solve.solve_all`: two copies on two cores take the time of one); a copy whose solver failed is solved
    again with the other Clarabel (its retry)."""
    for lp, (lo, hi) in zip(lps, intervals):
        lp.params["one_minus_alpha"].value = 1.0 - lo
        lp.params["alpha"].value = hi
    outs = solve_all([lp.problem for lp in lps], solver, [_accept(lp) for lp in lps])
    res = []
    for lp, out in zip(lps, outs):
        if out.kind != "ok":
            out = solve(lp.problem, solver, _accept(lp), fallback=False, retry=True, skip_first=True)
        res.append((float(lp.extra["t"].value), out.record.status) if out.kind == "ok" else (None, out.record.status))
    return res


def prove_no_set(model: Any, s: Any, motor: bool, alpha_range: tuple[float, float],
                 say: Callable[[str], None] = lambda _m: None, intervals: int = INTERVALS) -> Phase1:
    """Phase-1 problems of the invariance LMIs of ``model`` (settings ``s``: multiplier, weights, Lyapunov kind,
    solver) over ``intervals`` log-spaced intervals of ``alpha_range``, PARALLEL at a time: on the vertices with their
    instants at the ends of their ranges, an interval they leave unsettled halved once, and a half still unsettled
    solved again with every vertex.  Stops at the first interval left unsettled (no proof can come out any more)."""
    t0 = time.perf_counter()
    lo, hi = alpha_range
    edges = np.exp(np.linspace(math.log(lo), math.log(hi), intervals + 1))
    w = np.array([s.weights.e_x, s.weights.e_y, s.weights.e_theta])
    build = lambda m: build_invariance(m, s.multiplier, s.margin, w, motor, s.lyapunov, symmetry=False,  # noqa: E731
                                       phase1=PHASE1_BOX)
    sub = _exact_end_vertices(model)
    kinds = [sub, model] if sub is not None else [model]  # the fewer vertices first
    copies: list[list[Any]] = [[] for _ in kinds]  # per kind, its compiled copies (one per interval solved at once)
    result = Phase1(float(lo), float(hi))

    def run(i: int, ivs: list[tuple[float, float]]) -> list[tuple[float | None, str]]:
        while len(copies[i]) < len(ivs):
            copies[i].append(build(kinds[i]))
        ts = _t_stars(copies[i][: len(ivs)], ivs, s.solver)
        for (a, b), (t, status) in zip(ivs, ts):
            say(f"  phase-1 on alpha in [{a:.4g}, {b:.4g}] ({len(kinds[i].vertices)} vertices): "
                + ("the solver failed" if t is None else f"t* = {t:.3g}") + f" ({status})")
        return ts

    def settle(ivs: list[tuple[float, float]], depth: int) -> bool:
        """Settle ``ivs`` (PARALLEL at a time) on the fewer vertices, halving what they leave, and what is left
        then on every vertex; False at the first interval left unsettled (no proof can come out any more)."""
        for k in range(0, len(ivs), PARALLEL):
            chunk = ivs[k : k + PARALLEL]
            for (a, b), (t, status) in zip(chunk, run(0, chunk)):
                n = len(kinds[0].vertices)
                if not settles(t) and depth > 0:
                    mid = math.sqrt(a * b)
                    if not settle([(a, mid), (mid, b)], depth - 1):
                        return False
                    continue
                if not settles(t) and len(kinds) > 1:
                    (t, status), = run(1, [(a, b)])
                    n = len(kinds[1].vertices)
                result.intervals.append((a, b, t, n, status))
                if not settles(t):
                    return False
        return True

    settle([(float(a), float(b)) for a, b in zip(edges[:-1], edges[1:])], 1)
    result.seconds = time.perf_counter() - t0
    return result
