"""A call run in a forked child process, its result read back through a pipe: work beside this process's own.

The remedies' quick tries (:mod:`robustsynth.synthesis.remedies`) are searches of their own, each on a changed config;
on two cores two of them run at once.  Threads cannot carry them: a search enters ``warnings.catch_warnings`` and
points file descriptor 2 at a pipe around each solve (:mod:`robustsynth.synthesis.solve`), both process-wide.  A fork
can: the child has the parent's memory (the imported modules, the model, the callable), runs the call, and sends back
its pickled result; nothing is imported or pickled on the way in.  The robot's verification runs its single-threaded
checks the same way beside the adversary's threads, and the report half its figures (:func:`beside`).

The child takes no signal: SIGINT and SIGTERM are ignored there (the parent decides; a Ctrl-C reaches the whole
process group), and it gets SIGKILL when the thread that forked it ends (``PR_SET_PDEATHSIG``; the main thread: when
the parent dies).  It never unwinds into the parent's frames: whatever the call does, the child ends with
``os._exit`` after its end hooks (below).  The parent kills the children it no longer waits for (:meth:`Forked.kill`;
:func:`beside`'s also when the wait for one is interrupted).  Linux only (``AVAILABLE``; elsewhere the callers run
the call in this process).

A room above that keeps processes of its own registers what a child does with them (:func:`in_children`: the
synthesis' solver processes are the parent's, and the child kills its own before it ends).  Standard library only."""

from __future__ import annotations

import os
import pickle
import select
import signal
import sys
import time
from typing import Any, Callable

__all__ = ["AVAILABLE", "ChildError", "Forked", "Raised", "beside", "cores", "in_children", "wait_any"]

AVAILABLE = hasattr(os, "fork") and sys.platform.startswith("linux")
BESIDE = True  # False: beside() forks nothing (a sweep's worker processes share the cores already)
POLL_S = 0.2  # [s] the parent's wait wakes this often (a signal's handler runs at once anyway)

# what a child does first and last (in_children): (at its start, at its end) pairs
_CHILD_HOOKS: list[tuple[Callable[[], None], Callable[[], None]]] = []


def in_children(start: Callable[[], None], end: Callable[[], None]) -> None:
    """Have every child call ``start()`` before its call and ``end()`` after it (before it exits, whatever the call
    did): how a room forgets the processes it inherited and kills the ones it started."""
    _CHILD_HOOKS.append((start, end))


class ChildError(RuntimeError):
    """The child ended without a result (a crash, a kill), or its call raised something other than the expected."""


class Raised(Exception):
    """The child's call raised one of the expected exceptions: its message (``str``), and ``kind``, its type's name."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


def _die_with_parent() -> None:
    import ctypes

    try:  # the process's own symbols hold libc's (no find_library: it runs ldconfig in a subprocess)
        ctypes.CDLL(None).prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


class Forked:
    """``fn()`` in a forked child.  :meth:`result` returns what it returned; where it raised one of ``expected``,
    :meth:`result` raises :class:`Raised` with its message; any other exception comes back as :class:`ChildError`
    naming it."""

    def __init__(self, fn: Callable[[], Any], expected: tuple[type[BaseException], ...] = ()) -> None:
        sys.stdout.flush()
        sys.stderr.flush()  # what is buffered now is the parent's to write, not also the child's
        parent = os.getpid()
        r, w = os.pipe()
        try:
            pid = os.fork()
        except OSError:
            os.close(r)
            os.close(w)
            raise
        if pid == 0:  # the child
            os.close(r)
            _child(fn, expected, w, parent)
        os.close(w)
        self.pid, self.fd = pid, r
        self._data = bytearray()
        self._done = False
        self._reaped = False
        self.started = time.perf_counter()

    def _read(self) -> bool:
        """Read what is there; True once the child closed its end (its result is whole, or it died)."""
        chunk = os.read(self.fd, 1 << 20)
        if chunk:
            self._data += chunk
            return False
        return True

    def result(self) -> Any:
        """Wait for the child's result (raising what it raised, see the class)."""
        while not self._done:
            select.select([self.fd], [], [], POLL_S)
            self._done = self._read() or self._done
        return self._finish()

    def _finish(self) -> Any:
        os.close(self.fd)
        self.fd = -1
        os.waitpid(self.pid, 0)
        self._reaped = True
        try:
            kind, payload = pickle.loads(bytes(self._data))
        except Exception:  # noqa: BLE001 - nothing, or a part: the child died before it wrote it whole
            raise ChildError("the child process ended without its result") from None
        if kind == "ok":
            return payload
        if kind == "expected":
            raise Raised(*payload)
        raise ChildError(payload)

    def kill(self) -> None:
        """Stop the child (if it runs) and reap it."""
        if self._reaped:
            return
        try:
            os.kill(self.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1
        try:
            os.waitpid(self.pid, 0)
        except ChildProcessError:
            pass
        self._reaped = True


class _Here:
    """:func:`beside`'s value where no child is forked: ``fn()`` computed when its result is asked for.  As a context
    manager, :meth:`kill` on the way out (nothing here)."""

    def __init__(self, fn: Callable[[], Any]) -> None:
        self._fn = fn

    def result(self) -> Any:
        return self._fn()

    def kill(self) -> None:
        pass

    def __enter__(self) -> "_Here":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.kill()


class _Beside(_Here):
    """:func:`beside`'s value: ``fn()`` in a forked child; where the child fails, the call again here."""

    def __init__(self, fn: Callable[[], Any]) -> None:
        super().__init__(fn)
        self._child: Forked | None = Forked(fn)

    def result(self) -> Any:
        child, self._child = self._child, None
        if child is None:
            raise RuntimeError("beside: the result was asked for twice")
        try:
            return child.result()
        except (ChildError, Raised):  # what it raised is raised here as itself, with its traceback
            return self._fn()
        except BaseException:  # the wait interrupted (a signal's handler, Ctrl-C): the child is stopped
            child.kill()
            raise

    def kill(self) -> None:
        if self._child is not None:
            self._child.kill()
            self._child = None


def cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def beside(fn: Callable[[], Any]) -> _Beside | _Here:
    """``fn()`` computed beside this process: in a forked child where there are a fork (``AVAILABLE``), two cores or
    more and ``BESIDE``, and the caller is the main thread (another thread's fork could copy a lock some thread holds
    at that moment into the child); else here when it is asked for.  ``.result()`` its value (the call again in this
    process where the child failed, so that an exception is raised as itself), ``.kill()`` stops it when its value is
    no longer wanted (``with beside(fn) as job:`` kills it on the way out).  For a call whose value does not depend on when it runs: it sees this process's memory as it was
    at the fork, and what it changes there stays in the child."""
    import threading

    if AVAILABLE and BESIDE and cores() > 1 and threading.current_thread() is threading.main_thread():
        try:
            return _Beside(fn)
        except OSError:  # no fork now (a process limit, no memory for the page tables): here, when asked for
            pass
    return _Here(fn)


def wait_any(running: list[Forked], until: float = float("inf")) -> Forked | None:
    """Wait until one of ``running`` has its result in (or died): that one; None once ``until`` (time.perf_counter)
    has passed.  A signal's handler runs meanwhile (the CLI's raises :class:`~robustsynth.errors.Interrupted`; the
    caller kills the children)."""
    while True:
        wait = min(POLL_S, until - time.perf_counter())
        if wait <= 0.0:
            return None
        ready, _, _ = select.select([f.fd for f in running], [], [], wait)
        for f in running:
            if f.fd in ready and f._read():
                f._done = True
                return f


def _child(fn: Callable[[], Any], expected: tuple[type[BaseException], ...], w: int, parent: int) -> None:
    code = 0
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        _die_with_parent()
        if os.getppid() != parent:  # the parent died before the line above took effect
            os._exit(1)
        for start, _end in _CHILD_HOOKS:  # e.g. the parent's solver processes are the parent's
            start()
        try:
            out: tuple[str, Any] = ("ok", fn())
        except expected as exc:
            out = ("expected", (type(exc).__name__, str(exc)))
        except BaseException as exc:  # noqa: BLE001 - a bug or a crash of the call: named to the parent
            out = ("error", f"{type(exc).__name__}: {exc}")
        data = pickle.dumps(out, protocol=pickle.HIGHEST_PROTOCOL)
        with os.fdopen(w, "wb") as fp:
            fp.write(data)
    except BaseException:  # noqa: BLE001 - the parent sees a result missing (ChildError)
        code = 1
    finally:
        try:
            for _start, end in _CHILD_HOOKS:
                end()
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)
