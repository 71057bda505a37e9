"""The only place that calls a cvxpy solver: explicit tolerances, status mapping, SCS fallback."""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator

import cvxpy as cp

from ..errors import check_interrupt, pending_interrupt
from . import solver_process

MAX_THREADS = 4  # auto_threads' cap

__all__ = ["SolveRecord", "Outcome", "solve", "solve_all", "auto_threads", "SOLVER_OPTIONS", "solver_options", "solver_version"]

SOLVER_OPTIONS: dict[str, dict[str, Any]] = {
    "clarabel": {
        "solver": cp.CLARABEL,
        "tol_gap_abs": 1e-9,
        "tol_gap_rel": 1e-9,
        "tol_feas": 1e-9,
        "tol_infeas_abs": 1e-9,
        "tol_infeas_rel": 1e-9,
        "max_iter": 500,
        # one thread: the KKT factors here are small and many; the solver's thread pool spent ~15 %
        # of a path-dependent solve waiting (measured: bench_synthesis_profile), and make test and sweeps
        # already run one solve per core
        "max_threads": 1,  # (dropped below for a Clarabel without the setting)
        # every solve from scratch: a problem solved again with new parameter values must give what a
        # fresh copy gives (solve_all's results may not depend on which copy solved which point); today's
        # Clarabel interface never updates data in place, so this changes nothing yet
        "warm_start": False,
    },
    # SCS is first-order: 1e-8 is tight for it; the iteration cap bounds a fallback to ~1 s here
    "scs": {"solver": cp.SCS, "eps_abs": 1e-8, "eps_rel": 1e-8, "max_iters": 20_000},
}
# Clarabel again, without its equilibration (the row and column scaling of the data): where the scaled
# problem stalls near infeasibility and ends in a numerical error, the unscaled one often concludes, as
# fast as a first solve (measured on the default robot's kinematic channels, docs/theory.md §9: every
# solve 'solver_error' in ~0.3 s scaled, 'infeasible' in ~0.3 s unscaled, where SCS takes 1-29 s to say
# the same; on certified points both give the same optimum)
SOLVER_OPTIONS["clarabel-unscaled"] = {**SOLVER_OPTIONS["clarabel"], "equilibrate_enable": False}
# the cheap retry: after its solver, before the fallback solver (each Clarabel the other: the kinematic channels'
# problems start unscaled, synthesis.heading_search.KINEMATIC_PRIMARY)
RETRY = {"clarabel": "clarabel-unscaled", "clarabel-unscaled": "clarabel"}
FALLBACK = {"clarabel": "scs", "clarabel-unscaled": "scs", "scs": "clarabel"}


def solver_options(name: str) -> dict[str, Any]:
    opts = dict(SOLVER_OPTIONS[name])
    if opts["solver"] == cp.CLARABEL:
        try:
            import clarabel

            if not hasattr(clarabel.DefaultSettings(), "max_threads"):
                opts.pop("max_threads", None)
        except (ImportError, AttributeError):
            opts.pop("max_threads", None)
    return opts


def solver_version(name: str) -> str:
    try:
        mod = __import__(name.split("-")[0])  # clarabel-unscaled is Clarabel
        return str(getattr(mod, "__version__", "unknown"))
    except ImportError:
        return "not installed"


@dataclass
class SolveRecord:
    """What one solver attempt did."""

    name: str
    status: str
    iterations: int | None
    solve_time_s: float  # the whole call: cvxpy's canonicalization and unpacking, and the solver
    error: str = ""
    solver_time_s: float | None = None  # the solver's own time (its report), when it gave one


@dataclass
class Outcome:
    """Result of :func:`solve`: ``kind`` is 'ok', 'infeasible' or 'failed'."""

    kind: str
    record: SolveRecord
    attempts: list[SolveRecord] = field(default_factory=list)
    skipped: int = 0  # solvers of the chain not run again: they had failed on this very problem before

    @property
    def fallback_used(self) -> bool:
        """More than one solver was needed (counting one that failed before and was skipped)."""
        return len(self.attempts) + self.skipped > 1


_HELD_SIGNALS = {signal.SIGINT, signal.SIGTERM}
POLL_S = 0.05  # [s]: how often the waiting thread looks for a held signal while solves run


_POOLED = threading.local()  # .active: this thread is one of solve_all's workers
_CANCEL = threading.local()  # .event: set once the thread that waits for this solve has given it up


def _stop_on_held_signal(_info: Any) -> bool:
    """Clarabel's termination callback (every iteration): stop the solve in flight once SIGINT or SIGTERM
    is pending (held by :func:`_in_threads`), was delivered through another thread (the CLI's handler
    recorded it, or raises in here), or the waiting thread gave the solve up."""
    event = getattr(_CANCEL, "event", None)
    if event is not None and event.is_set():
        return True
    try:
        return bool(signal.sigpending() & _HELD_SIGNALS) or pending_interrupt() is not None
    except BaseException:  # noqa: BLE001 - the CLI's handler raised Interrupted while this ran
        return True


def _clarabel_stops_on_signals() -> None:
    """Every Clarabel solver cvxpy makes is built here (cvxpy builds it inside its interface and has no hook
    for it: ``clarabel.DefaultSolver`` is wrapped once).  A problem of at least ``solver_process.CHILD_ROWS``
    rows is solved in a child process (its setup would hold the GIL for seconds: no signal heard meanwhile);
    any other gets :func:`_stop_on_held_signal` as its termination callback (a Clarabel build without
    callbacks: its solve is given up by :func:`_in_threads` instead)."""
    import clarabel

    real = clarabel.DefaultSolver
    if getattr(real, "_stops_on_held_signals", False):
        return
    callbacks = hasattr(real, "set_termination_callback")

    def DefaultSolver(P: Any, q: Any, A: Any, b: Any, cones: Any, settings: Any) -> Any:  # noqa: N802, N803
        if A.shape[0] >= solver_process.CHILD_ROWS:
            carried = solver_process.serialize_cones(cones)
            if carried is not None:
                return solver_process.ChildSolver(P, q, A, b, carried, solver_process.serialize_settings(settings),
                                                  getattr(_CANCEL, "event", None))
        solver = real(P, q, A, b, cones, settings)
        if callbacks:
            solver.set_termination_callback(_stop_on_held_signal)
        return solver

    DefaultSolver._stops_on_held_signals = True  # type: ignore[attr-defined]
    clarabel.DefaultSolver = DefaultSolver


def _give_up(cancel: threading.Event) -> None:
    """The solves of this wait are given up: their callbacks see it, their child processes are killed."""
    cancel.set()
    solver_process.kill_given_up(cancel)


def _take_held_signal(cancel: threading.Event) -> None:
    """While solves run: a SIGINT / SIGTERM held pending is taken here and its handler run in this (the
    waiting) thread; when it raises (the CLI's: Interrupted, Python's: KeyboardInterrupt) the solves are given
    up.  Taken with ``sigtimedwait``, not by unblocking it: a solver that installs its own SIGINT handler for
    the solve (SCS, Clarabel) would otherwise swallow it.  Without a Python handler the signal's own action
    (SIGTERM: the process ends) is what happens."""
    if pending_interrupt() is not None:  # the CLI's handler saw a signal another thread took
        _give_up(cancel)
        check_interrupt()
    info = signal.sigtimedwait(_HELD_SIGNALS, 0)
    if info is None:
        return
    signo = info.si_signo
    handler = signal.getsignal(signo)
    try:
        if callable(handler):
            handler(signo, None)
        elif handler != signal.SIG_IGN:  # SIG_DFL, or a handler not set from Python: the default action
            signal.signal(signo, signal.SIG_DFL)
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signo})
            signal.raise_signal(signo)
    except BaseException:
        _give_up(cancel)
        raise


def _in_threads(fns: list[Callable[[], Any]]) -> list[Any]:
    """Run each of ``fns`` (solver calls) in a daemon thread of its own and wait for them: their results in
    order, or the first one's exception.  The solvers' native code runs outside the GIL, so two solves on two
    cores take the time of one.  SIGINT and SIGTERM are held in every thread meanwhile (Clarabel catches SIGINT
    in its native code and carries on; SCS takes it for its own) and the waiting thread looks for them every
    POLL_S: a signal ends the wait at once, whatever the solver (issue 50: SIGTERM during SCS fallback retries
    went unheard for minutes).  A solve given up runs on in its thread (Clarabel stops at its next iteration:
    its termination callback sees the cancel; SCS has none and ends by its iteration cap); nothing waits
    for it, and the process may exit meanwhile."""
    cancel = threading.Event()
    results: list[Any] = [None] * len(fns)
    errors: list[BaseException | None] = [None] * len(fns)

    def target(i: int, fn: Callable[[], Any]) -> None:
        _CANCEL.event = cancel
        try:
            results[i] = fn()
        except BaseException as exc:  # noqa: BLE001 - handed to the waiting thread
            errors[i] = exc

    check_interrupt()
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD_SIGNALS)  # the threads inherit the mask
    try:
        threads = [threading.Thread(target=target, args=(i, fn), daemon=True, name=f"robustsynth-solve-{i}")
                   for i, fn in enumerate(fns)]
        for t in threads:
            t.start()
        for t in threads:
            while t.is_alive():
                t.join(POLL_S)
                if t.is_alive():
                    _take_held_signal(cancel)
    except BaseException:  # the handler ran here, e.g. for a signal a thread that does not hold it took
        _give_up(cancel)
        raise
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
    check_interrupt()  # a solve the callback ended: the interrupt, not its "solver error"
    for exc in errors:
        if exc is not None:
            raise exc
    return results


def abandoned_solves_ended(timeout: float) -> bool:
    """Wait up to ``timeout`` [s] in all for the solves :func:`_in_threads` gave up; whether none still runs."""
    deadline = time.monotonic() + timeout
    for t in threading.enumerate():
        if t.name.startswith("robustsynth-solve-") and t.is_alive():
            t.join(max(0.0, deadline - time.monotonic()))
    return not any(t.name.startswith("robustsynth-solve-") and t.is_alive() for t in threading.enumerate())


def _call_solver(problem: cp.Problem, name: str) -> None:
    """One solver call (a seam for fault-injection tests), in a thread of its own that this one waits for
    while it looks for SIGINT / SIGTERM (:func:`_in_threads`); within :func:`solve_all`'s threads, directly."""
    opts = solver_options(name)
    if opts["solver"] == cp.CLARABEL:
        _clarabel_stops_on_signals()
    if getattr(_POOLED, "active", False):
        problem.solve(**opts)  # solve_all's caller waits, holds the signals and the warning filter
        return
    with _quiet():  # (catch_warnings is process-wide: entered here, it holds for the solve's thread)
        _in_threads([lambda: problem.solve(**opts)])


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """cvxpy's UserWarning about an inaccurate solution is held back: the status reports it and the
    caller handles it; so are numpy's RuntimeWarnings from cvxpy's unpacking of a failed solve (an overflow in
    its PSD utilities reached the terminal after a solver error: the status says it).  ``warnings.catch_warnings``
    saves and restores the process-wide filter list, so it must not be entered by threads that overlap
    (solve_all enters it once around its pool)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        warnings.filterwarnings("ignore", category=RuntimeWarning, module=r"cvxpy\.")
        yield


class _NativeStderr:
    """Hold what native code writes to file descriptor 2 during a solve, so that a solver panic's
    report (Rust prints it, with a backtrace under RUST_BACKTRACE=1) does not reach the user's
    terminal; anything else written is passed on afterwards."""

    def __enter__(self) -> "_NativeStderr":
        import os
        import sys
        import tempfile

        self.saved = None
        try:
            sys.stderr.flush()
            self.buf = tempfile.TemporaryFile()
            self.saved = os.dup(2)
            os.dup2(self.buf.fileno(), 2)
        except (OSError, ValueError, AttributeError):  # no usable fd 2 (embedded): leave it alone
            self.saved = None
        return self

    def release(self, keep: bool) -> None:
        import os

        if self.saved is None:
            return
        os.dup2(self.saved, 2)
        os.close(self.saved)
        self.saved = None
        if keep:
            self.buf.seek(0)
            data = self.buf.read()
            if data:
                try:
                    os.write(2, data)
                except OSError:
                    pass
        self.buf.close()

    def __exit__(self, *exc: Any) -> None:
        self.release(keep=True)


def _attempt(problem: cp.Problem, name: str) -> SolveRecord:
    with _NativeStderr() as err:
        rec, panicked = _run(problem, name)
        if panicked:
            err.release(keep=False)
    return rec


def _run(problem: cp.Problem, name: str) -> tuple[SolveRecord, bool]:
    """One solver attempt and whether the solver's native code panicked (its report then belongs to
    no one: the caller drops what was captured on fd 2)."""
    t0 = time.perf_counter()
    try:
        _call_solver(problem, name)
    except (cp.error.SolverError, ValueError, ArithmeticError, solver_process.ChildFailed) as exc:
        return SolveRecord(name, "solver_error", None, time.perf_counter() - t0, str(exc).splitlines()[0][:200]), False
    except BaseException as exc:  # noqa: BLE001
        # a panic in a solver's native code (Clarabel's Rust: pyo3_runtime.PanicException derives
        # from BaseException, e.g. "Eigval error" in a PSD cone step) is a failed attempt, not a crash
        if type(exc).__name__ != "PanicException" and not isinstance(exc, solver_process.SolverPanic):
            raise
        msg = (str(exc).splitlines() or ["panic"])[0][:200]
        return SolveRecord(name, "solver_error", None, time.perf_counter() - t0, f"solver panicked: {msg}"), True
    stats = problem.solver_stats
    iters = getattr(stats, "num_iters", None)
    own = getattr(stats, "solve_time", None)
    return SolveRecord(name, str(problem.status), int(iters) if iters is not None else None, time.perf_counter() - t0,
                       solver_time_s=float(own) if own is not None else None), False


class Rejected(Exception):
    """Raised by the ``accept`` of :func:`solve` to end it at once, without the fallback solver: the
    point is refused for a reason another solver cannot fix.  :func:`solve` sets ``attempts``."""

    attempts: list[SolveRecord] = []


def solve(problem: cp.Problem, primary: str, accept: Callable[[], bool], fallback: bool = True,
          retry: bool | None = None, skip_first: bool = False) -> Outcome:
    """Solve with ``primary``; on a solver error, an inaccurate status or a point that ``accept``
    rejects (the numpy certificate check), retry with the same solver unscaled (``RETRY``; ``retry``,
    by default whenever ``fallback``), then, with ``fallback``, with the other solver (and its retry).

    A clean 'infeasible' from the solver is final (no retry).  An 'optimal_inaccurate' point (of
    either solver) is still offered to ``accept``: the numpy check, not the status, decides.
    ``skip_first``: the caller solved this problem with ``primary`` before and it failed; start past it."""
    retry = fallback if retry is None else retry
    attempts: list[SolveRecord] = []
    names = _chain(primary, retry) + (_chain(FALLBACK[primary], retry) if fallback else ())
    skipped = 1 if skip_first else 0
    for name in names[skipped:]:
        check_interrupt()
        rec = _attempt(problem, name)
        check_interrupt()  # an interrupt is never a failed or infeasible point
        attempts.append(rec)
        done = _decide(rec, accept, attempts)
        if done is not None:
            done.skipped = skipped
            return done
    if not attempts:  # nothing past the first solver to try
        return Outcome("failed", SolveRecord(primary, "failed before", None, 0.0), attempts, skipped)
    return Outcome("failed", attempts[-1], attempts, skipped)


def _chain(name: str, retry: bool = True) -> tuple[str, ...]:
    return (name, RETRY[name]) if retry and name in RETRY else (name,)


def _decide(rec: SolveRecord, accept: Callable[[], bool], attempts: list[SolveRecord]) -> Outcome | None:
    """The outcome of one attempt, or None when it neither proved nor refuted anything (the caller
    may retry with another solver)."""
    if rec.status == cp.INFEASIBLE:
        return Outcome("infeasible", rec, attempts)
    if rec.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE):
        try:
            ok = accept()
        except Rejected as exc:
            rec.error = str(exc)
            exc.attempts = attempts
            raise
        if ok:
            return Outcome("ok", rec, attempts)
        rec.error = rec.error or "returned point failed the numpy certificate check"
    return None


def auto_threads() -> int:
    """How many solves :func:`solve_all` runs at once by default (a linear plant's line search): the CPUs this
    process may use, at most ``MAX_THREADS``."""
    from ..forked import cores

    return max(1, min(MAX_THREADS, cores()))


def solve_all(problems: list[cp.Problem], primary: str, accepts: list[Callable[[], bool]]) -> list[Outcome]:
    """:func:`solve` (without the fallback solver) of independent problems at once, one thread each:
    the solvers' native code runs outside the GIL, so two problems on two cores take the time of
    one.  Each problem must be its own cvxpy object (a problem's parameters are not shared between
    threads).  ``accept`` runs afterwards in the calling thread, in the problems' order, so the outcomes
    do not depend on how many ran at once.  SIGINT and SIGTERM end the wait at once, as for one solve
    (:func:`_in_threads`); a solver's output on fd 2 is captured, and cvxpy's inaccuracy warning filtered,
    once around all of them (both are process-wide)."""
    if len(problems) == 1:
        return [solve(problems[0], primary, accepts[0], fallback=False)]

    def work(problem: cp.Problem) -> tuple[SolveRecord, bool]:
        _POOLED.active = True
        try:
            return _run(problem, primary)
        finally:
            _POOLED.active = False

    with _NativeStderr() as err, _quiet():
        runs = _in_threads([lambda p=p: work(p) for p in problems])
        if any(panicked for _, panicked in runs):
            err.release(keep=False)
    out = []
    for (rec, _), accept in zip(runs, accepts):
        done = _decide(rec, accept, [rec])
        out.append(done if done is not None else Outcome("failed", rec, [rec]))
    return out
