"""The only place that calls a cvxpy solver: explicit tolerances, status mapping, SCS fallback."""

from __future__ import annotations

import signal
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import cvxpy as cp

from ..errors import check_interrupt

__all__ = ["SolveRecord", "Outcome", "solve", "SOLVER_OPTIONS", "solver_version"]

SOLVER_OPTIONS: dict[str, dict[str, Any]] = {
    "clarabel": {
        "solver": cp.CLARABEL,
        "tol_gap_abs": 1e-9,
        "tol_gap_rel": 1e-9,
        "tol_feas": 1e-9,
        "tol_infeas_abs": 1e-9,
        "tol_infeas_rel": 1e-9,
        "max_iter": 500,
    },
    # SCS is first-order: 1e-8 is tight for it; the iteration cap bounds a fallback to ~1 s here
    "scs": {"solver": cp.SCS, "eps_abs": 1e-8, "eps_rel": 1e-8, "max_iters": 20_000},
}
FALLBACK = {"clarabel": "scs", "scs": "clarabel"}


def solver_version(name: str) -> str:
    try:
        mod = __import__(name)
        return str(getattr(mod, "__version__", "unknown"))
    except ImportError:
        return "not installed"


@dataclass
class SolveRecord:
    """What one solver attempt did."""

    name: str
    status: str
    iterations: int | None
    solve_time_s: float
    error: str = ""


@dataclass
class Outcome:
    """Result of :func:`solve`: ``kind`` is 'ok', 'infeasible' or 'failed'."""

    kind: str
    record: SolveRecord
    attempts: list[SolveRecord] = field(default_factory=list)

    @property
    def fallback_used(self) -> bool:
        return len(self.attempts) > 1


_HELD_SIGNALS = {signal.SIGINT, signal.SIGTERM}


def _call_solver(problem: cp.Problem, name: str) -> None:
    """One solver call (a seam for fault-injection tests).

    Clarabel catches SIGINT inside its native code and carries on (Ctrl-C was swallowed and the
    run completed).  SIGINT and SIGTERM are therefore held pending while the solver runs: the
    signal is delivered, and the run stops, as soon as the solve returns."""
    import warnings

    opts = dict(SOLVER_OPTIONS[name])
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD_SIGNALS)
    try:
        with warnings.catch_warnings():
            # an inaccurate solution is reported through the status and handled by the caller
            warnings.simplefilter("ignore", UserWarning)
            problem.solve(**opts)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _attempt(problem: cp.Problem, name: str) -> SolveRecord:
    t0 = time.perf_counter()
    try:
        _call_solver(problem, name)
    except (cp.error.SolverError, ValueError, ArithmeticError) as exc:
        return SolveRecord(name, "solver_error", None, time.perf_counter() - t0, str(exc).splitlines()[0][:200])
    stats = problem.solver_stats
    iters = getattr(stats, "num_iters", None)
    return SolveRecord(name, str(problem.status), int(iters) if iters is not None else None, time.perf_counter() - t0)


def solve(problem: cp.Problem, primary: str, accept: Callable[[], bool], fallback: bool = True) -> Outcome:
    """Solve with ``primary``; on a solver error, an inaccurate status or a point that ``accept``
    rejects (the numpy certificate check), retry once with the other solver.

    A clean 'infeasible' from the solver is final (no retry).  An 'optimal_inaccurate' point (of
    either solver) is still offered to ``accept``: the numpy check, not the status, decides."""
    attempts: list[SolveRecord] = []
    for name in (primary, FALLBACK[primary]) if fallback else (primary,):
        check_interrupt()
        rec = _attempt(problem, name)
        check_interrupt()  # an interrupt is never a failed or infeasible point
        attempts.append(rec)
        if rec.status == cp.INFEASIBLE:
            return Outcome("infeasible", rec, attempts)
        if rec.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
            if accept():
                return Outcome("ok", rec, attempts)
            rec.error = rec.error or "returned point failed the numpy certificate check"
    return Outcome("failed", attempts[-1], attempts)
