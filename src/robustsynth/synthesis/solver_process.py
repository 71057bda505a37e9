"""Clarabel in a process of its own, for the problems whose setup holds Python's lock for seconds.

``clarabel.DefaultSolver(...)`` builds its KKT system in native code without releasing the GIL: on a
219-LMI problem (139 260 rows) that took 5-6 s idle and 8-10 s with both cores busy, and no thread of
the process, the one that waits for SIGINT / SIGTERM included, ran meanwhile (issue 50; py-spy showed it).
A problem at least :data:`CHILD_ROWS` rows tall is therefore solved by a child process: the parent keeps
its lock free, hears a signal at once and kills the child.  The child gets the very arrays cvxpy would
have passed to Clarabel in this process and sends back every field cvxpy reads, so the result is the
same to the last bit (tests/synthesis/test_solver_process.py compares them).

The file is both sides: imported, it is the parent's (stdlib only); run as a script, the child's loop
(numpy, scipy, clarabel; neither cvxpy nor robustsynth is imported there).  Frames on the pipes are
an 8-byte length and a pickle.
"""

from __future__ import annotations

import os
import pickle
import signal
import struct
import subprocess
import sys
import threading
from typing import Any, BinaryIO

__all__ = ["CHILD_ROWS", "ChildFailed", "ChildSolver", "ChildSolution", "SolverPanic", "forget_inherited", "kill_all",
           "kill_given_up", "serialize_cones", "serialize_settings", "trim_heap"]

# rows of A from which a problem goes to a child: the setup of the largest problems seen in the straight
# syntheses (icr default, 75 763 rows) took 0.85 s idle, of 10 552 rows 0.1 s; the spawn costs ~0.3 s once
CHILD_ROWS = 20_000

_HEADER = struct.Struct("<Q")
_FIELDS = ("status", "x", "z", "s", "obj_val", "obj_val_dual", "solve_time", "iterations", "r_prim", "r_dual")


def trim_heap() -> None:
    """Give the heap's freed memory back to the system (glibc's ``malloc_trim``; elsewhere nothing).  glibc keeps
    what a process freed for its next allocations: a solver child idle after the d_hi = 3 robot's full solve still
    held 750 MB, and held it beside the next problems' children; a solve's own data freed this way leaves it at its
    baseline (tests/synthesis/test_solver_process.py)."""
    import ctypes

    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):  # not glibc: its allocator returns memory by its own rules
        pass


class SolverPanic(Exception):
    """The solver's native code panicked in the child (Clarabel's Rust ``PanicException`` in-process)."""


class ChildFailed(RuntimeError):
    """The child ended or broke its protocol (a crash, a kill, an unexpected frame)."""


def _send(fp: BinaryIO, obj: Any) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    fp.write(_HEADER.pack(len(data)))
    fp.write(data)
    fp.flush()


def _read_exactly(fp: BinaryIO, n: int) -> bytes | None:
    chunks, left = [], n
    while left:
        chunk = fp.read(left)
        if not chunk:
            return None
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _recv(fp: BinaryIO) -> Any:
    head = _read_exactly(fp, _HEADER.size)
    if head is None:
        raise EOFError
    body = _read_exactly(fp, _HEADER.unpack(head)[0])
    if body is None:
        raise EOFError
    return pickle.loads(body)


# -- the parent's side -----------------------------------------------------------------------------------

def serialize_cones(cones: list[Any]) -> list[tuple[str, int]] | None:
    """Clarabel's cone objects (not picklable) as (class name, dim); None for a cone this cannot carry."""
    out = []
    for c in cones:
        name = type(c).__name__
        if name not in ("ZeroConeT", "NonnegativeConeT", "SecondOrderConeT", "PSDTriangleConeT"):
            return None
        out.append((name, int(c.dim)))
    return out


def serialize_settings(settings: Any) -> dict[str, Any]:
    """The settings that differ from Clarabel's defaults (``DefaultSettings`` is not picklable)."""
    import clarabel

    fresh = clarabel.DefaultSettings()
    out = {}
    for key in dir(settings):
        if key.startswith("_"):
            continue
        value = getattr(settings, key)
        if callable(value):
            continue
        if value != getattr(fresh, key):
            out[key] = value
    return out


class ChildSolution:
    """What cvxpy reads of a ``clarabel.DefaultSolution``; ``status`` is its name (cvxpy maps ``str(status)``)."""

    def __init__(self, fields: dict[str, Any]) -> None:
        for key in _FIELDS:
            setattr(self, key, fields.get(key))


class _Child:
    """One child process, solving one problem at a time."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen([sys.executable, os.path.abspath(__file__), str(os.getpid())],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                     close_fds=True)

    def solve(self, request: dict[str, Any]) -> dict[str, Any]:
        stdin, stdout = self.proc.stdin, self.proc.stdout  # both pipes: Popen was given PIPE for them
        if stdin is None or stdout is None:
            raise ChildFailed("the solver's process has no pipes")
        try:
            _send(stdin, request)
            kind, payload = _recv(stdout)
        except (EOFError, OSError, pickle.UnpicklingError) as exc:
            try:
                code = self.proc.wait(timeout=2.0)  # a pipe closed by its death: reap it for its exit code
            except subprocess.TimeoutExpired:
                code = None
            raise ChildFailed(f"the solver's process ended (exit code {code})" if code is not None
                              else f"the solver's process broke its pipe ({type(exc).__name__})") from None
        if kind == "panic":
            raise SolverPanic(payload)
        if kind == "error":
            raise ChildFailed(payload)
        return payload

    def kill(self) -> None:
        try:
            self.proc.kill()
        except OSError:
            pass
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            pass


_LOCK = threading.Lock()
_IDLE: list[_Child] = []
_BUSY: dict[int, tuple[_Child, threading.Event | None]] = {}  # id -> (child, the cancel event of its solve)


def _take() -> _Child:
    with _LOCK:
        while _IDLE:
            child = _IDLE.pop()
            if child.proc.poll() is None:
                return child
    return _Child()


class ChildSolver:
    """Stands for ``clarabel.DefaultSolver(P, q, A, b, cones, settings)``: ``solve()`` runs it in a child."""

    def __init__(self, P: Any, q: Any, A: Any, b: Any, cones: list[tuple[str, int]], settings: dict[str, Any],
                 cancel: threading.Event | None = None) -> None:
        self.request = {"P": P, "q": q, "A": A, "b": b, "cones": cones, "settings": settings}
        self.cancel = cancel

    def solve(self) -> ChildSolution:
        child = _take()
        with _LOCK:
            _BUSY[id(child)] = (child, self.cancel)
        ok = False
        try:
            if self.cancel is not None and self.cancel.is_set():
                raise ChildFailed("the solve was given up before it started")
            out = ChildSolution(child.solve(self.request))
            ok = True
            return out
        finally:
            with _LOCK:
                _BUSY.pop(id(child), None)
                if ok and child.proc.poll() is None:
                    _IDLE.append(child)
            if not ok:
                child.kill()


def kill_given_up(cancel: threading.Event) -> None:
    """Kill the children whose solve ``cancel`` gave up (their waiting thread then ends at once)."""
    with _LOCK:
        victims = [child for child, ev in _BUSY.values() if ev is cancel]
    for child in victims:
        child.kill()


def forget_inherited() -> None:
    """In a forked child (:mod:`.forked`): the solver processes in the lists are the parent's; this process starts
    with none (its own are started as it needs them).  The lock is made afresh: another thread of the parent may
    have held it at the fork."""
    global _LOCK
    _LOCK = threading.Lock()
    _IDLE.clear()
    _BUSY.clear()


def kill_all() -> None:
    """Kill every child, busy or idle (at exit)."""
    with _LOCK:
        victims = list(_IDLE) + [child for child, _ in _BUSY.values()]
        _IDLE.clear()
    for child in victims:
        child.kill()


# -- the child's side ------------------------------------------------------------------------------------

def _watch_parent(parent: int) -> None:
    """End this process once its parent is gone (it may be killed with -9): checked every 0.5 s while the
    solver runs outside the GIL."""
    import time

    while True:
        time.sleep(0.5)
        if os.getppid() != parent:
            os._exit(0)


def _child_main(parent: int) -> None:
    # the parent decides about SIGINT / SIGTERM (a Ctrl-C reaches the whole process group) and kills us
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # anything printed goes where stderr goes (the parent's /dev/null), not into the frames
    inp = os.fdopen(os.dup(0), "rb")
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()

    import clarabel

    while True:
        try:
            req = _recv(inp)
        except EOFError:
            return
        try:
            settings = clarabel.DefaultSettings()
            for key, value in req["settings"].items():
                setattr(settings, key, value)
            cones = [getattr(clarabel, name)(dim) for name, dim in req["cones"]]
            sol = clarabel.DefaultSolver(req["P"], req["q"], req["A"], req["b"], cones, settings).solve()
            fields = {key: getattr(sol, key, None) for key in _FIELDS}
            fields["status"] = str(sol.status)
            reply: tuple[str, Any] = ("ok", fields)
            del sol
        except BaseException as exc:  # noqa: BLE001 - every failure goes back to the parent
            first = (str(exc).splitlines() or [type(exc).__name__])[0][:200]
            reply = ("panic" if type(exc).__name__ == "PanicException" else "error", first)
        del req  # an idle child keeps no problem's data,
        trim_heap()  # nor the memory that held it: before the reply, so that the parent goes on with the child small
        _send(out, reply)
        del reply


if __name__ == "__main__":
    _child_main(int(sys.argv[1]))
else:  # imported (the parent's side): a forked child forgets this process's solvers and kills its own at its end
    from .. import forked as _forked

    _forked.in_children(forget_inherited, kill_all)
