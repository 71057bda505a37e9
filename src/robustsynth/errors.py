"""Exceptions of robustsynth and the exit codes the CLI maps them to (one table, here); the signals that
become exceptions, and how the process ends after one."""

from __future__ import annotations

import os
import sys
from typing import Any

__all__ = [
    "EXIT_OK",
    "EXIT_VERIFICATION_FAILED",
    "EXIT_BAD_INPUT",
    "EXIT_INFEASIBLE",
    "EXIT_SOLVER_FAILURE",
    "RobustSynthError",
    "ConfigError",
    "InputError",
    "InfeasibleError",
    "SolverFailure",
    "VerificationFailed",
    "OutputError",
    "Interrupted",
    "EXIT_INTERRUPTED",
    "EXIT_TERMINATED",
    "EXIT_BROKEN_PIPE",
    "on_signal",
    "check_interrupt",
    "install_signal_handlers",
    "exit_leaving_solves",
    "exit_broken_pipe",
]

EXIT_OK = 0
EXIT_VERIFICATION_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INFEASIBLE = 3
EXIT_SOLVER_FAILURE = 4
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it
EXIT_TERMINATED = 143  # 128 + SIGTERM
EXIT_BROKEN_PIPE = 141  # 128 + SIGPIPE: the reader went away (e.g. `| head`)


class RobustSynthError(Exception):
    """Base class. ``str(err)`` is the one line shown to the user."""

    exit_code = EXIT_BAD_INPUT


class ConfigError(RobustSynthError, ValueError):
    """The configuration file is unreadable or invalid (message names the key path)."""

    exit_code = EXIT_BAD_INPUT


class InputError(RobustSynthError, ValueError):
    """Any other bad input: a gains file, an option value."""

    exit_code = EXIT_BAD_INPUT


class InfeasibleError(RobustSynthError):
    """The LMIs have no solution: no gain meets the requested guarantee."""

    exit_code = EXIT_INFEASIBLE


class SolverFailure(RobustSynthError):
    """Every solver tried failed numerically, or no returned point passed the certificate check."""

    exit_code = EXIT_SOLVER_FAILURE


class VerificationFailed(RobustSynthError):
    """At least one verification check failed."""

    exit_code = EXIT_VERIFICATION_FAILED


class OutputError(RobustSynthError, OSError):
    """An output place cannot be created or written (message: the path and the OS reason)."""

    exit_code = EXIT_BAD_INPUT


class Interrupted(RobustSynthError):
    """SIGINT or SIGTERM arrived: the command stops; files already committed stay as they were."""

    def __init__(self, signum: int = 2) -> None:
        import signal

        super().__init__("interrupted")
        self.exit_code = EXIT_TERMINATED if signum == signal.SIGTERM else EXIT_INTERRUPTED


# Signals the CLI's handler has seen.  Raising from a signal handler is not enough: Python
# swallows an exception raised while it runs a weakref callback or a finalizer ("Exception
# ignored in ..."), e.g. during an import.  So the handler also records the signal, and
# check_interrupt() (called at every solve, simulation step, figure and stage) raises it again.
_PENDING: list[int] = []


def on_signal(signum: int, _frame: object = None) -> None:
    """Signal handler installed by the CLI for SIGINT and SIGTERM."""
    _PENDING.append(signum)
    raise Interrupted(signum)


def pending_interrupt() -> "Interrupted | None":
    """The interrupt of a signal that arrived, if any: an exception raised after it (say an
    extension module whose initialization the signal broke: 'ImportError: initialization failed')
    is its consequence and is reported as the interrupt."""
    return Interrupted(_PENDING[0]) if _PENDING else None


def check_interrupt() -> None:
    """Raise :class:`Interrupted` if a signal arrived (a no-op for library users: nothing is
    recorded unless the CLI's handler is installed)."""
    if _PENDING:
        raise Interrupted(_PENDING[0])


def _unraisable(info: Any) -> None:
    """An interrupt raised where Python cannot propagate it (a weakref callback during an import)
    is not printed: it was recorded, and the next checkpoint raises it (:func:`on_signal`)."""
    if isinstance(info.exc_value, Interrupted):
        return
    _DEFAULT_UNRAISABLE(info)


_DEFAULT_UNRAISABLE = sys.unraisablehook


def install_signal_handlers() -> None:
    """SIGINT and SIGTERM stop the command (exit 130 / 143, see :func:`on_signal`); a file-size
    limit makes a write fail (EFBIG, exit 2) instead of killing the process."""
    import signal

    try:
        signal.signal(signal.SIGINT, on_signal)
        signal.signal(signal.SIGTERM, on_signal)
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        sys.unraisablehook = _unraisable
    except ValueError:  # not the main thread (e.g. an embedding application)
        pass


SOLVE_GRACE_S = 2.0


def exit_leaving_solves(code: int) -> None:
    """Exit with ``code``.  A solve the interrupt gave up may still run in its thread (synthesis.solve._in_threads);
    the interpreter's shutdown would unwind that thread through the solver's native frames (Clarabel's Rust then
    aborts: 'FATAL: exception not rethrown', exit -6, measured in bench_interrupts).  Such a thread is given
    SOLVE_GRACE_S to end (Clarabel's stops at its next iteration); one still running is left to the OS:
    the process ends without the interpreter's shutdown (every file is committed or removed by now)."""
    solve = sys.modules.get("robustsynth.synthesis.solve")
    if solve is not None and not solve.abandoned_solves_ended(SOLVE_GRACE_S):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def exit_broken_pipe() -> None:
    """Exit 141 after a broken pipe, stdout pointed at /dev/null first so the interpreter's final flush is silent."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    sys.exit(EXIT_BROKEN_PIPE)
