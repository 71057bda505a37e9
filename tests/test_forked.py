"""robustsynth.forked.beside: a call computed in a forked child beside this process, its value the call's own; a
child that fails has the call run again here (its exception raised as itself); kill() stops a child; where nothing
is forked, the call runs here when its value is asked for."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

from robustsynth import forked

WAIT_S = 30.0  # [s] the longest a test waits for a child to be gone (a loaded machine is slow to reap)

needs_fork = pytest.mark.skipif(not (forked.AVAILABLE and forked.cores() > 1),
                                reason="beside forks only where there is a fork and two cores")


@needs_fork
def test_beside_computes_in_another_process_and_returns_the_value():
    here = os.getpid()
    job = forked.beside(lambda: (os.getpid(), [1.5, float("inf")], {"a": (2, None)}))
    pid, values, nested = job.result()
    assert pid != here
    assert values == [1.5, float("inf")] and nested == {"a": (2, None)}


@needs_fork
def test_a_child_that_raises_has_the_call_run_here_and_its_exception_raised_as_itself():
    here = os.getpid()
    calls = []

    def fn():
        calls.append(os.getpid())  # the child's append stays in the child
        raise KeyError(f"raised in {'this' if os.getpid() == here else 'a child'} process")

    job = forked.beside(fn)
    with pytest.raises(KeyError, match="raised in this process"):
        job.result()
    assert calls == [here]  # run once here, after the child failed


@needs_fork
def test_a_child_that_dies_has_the_call_run_here():
    here = os.getpid()

    def fn():
        if os.getpid() != here:
            os._exit(3)  # the child dies without a result
        return "computed here"

    assert forked.beside(fn).result() == "computed here"


def _sleeping_child(tmp_path):
    """A child that writes its pid and sleeps; (the job, the pid)."""
    mark = tmp_path / "pid"

    def fn():
        (tmp_path / "pid.part").write_text(str(os.getpid()))
        os.replace(tmp_path / "pid.part", mark)  # whole when it appears
        time.sleep(10 * WAIT_S)
        return "never"

    job = forked.beside(fn)
    t0 = time.perf_counter()
    while not mark.exists() and time.perf_counter() - t0 < WAIT_S:
        time.sleep(0.05)
    return job, int(mark.read_text())


@needs_fork
def test_kill_stops_the_child(tmp_path):
    job, pid = _sleeping_child(tmp_path)
    job.kill()
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # reaped by kill(): no such process
    job.kill()  # a second kill is nothing


def test_without_a_fork_the_call_runs_here_when_its_value_is_asked(monkeypatch):
    monkeypatch.setattr(forked, "AVAILABLE", False)
    calls = []
    job = forked.beside(lambda: calls.append(os.getpid()) or "value")
    assert calls == []  # not before it is asked for
    assert job.result() == "value" and calls == [os.getpid()]
    job.kill()


@needs_fork
def test_the_result_is_asked_for_once():
    job = forked.beside(lambda: 1)
    assert job.result() == 1
    with pytest.raises(RuntimeError, match="asked for twice"):
        job.result()


def test_where_the_fork_fails_the_call_runs_here(monkeypatch):
    def no_fork():
        raise BlockingIOError(11, "Resource temporarily unavailable")  # fork's EAGAIN at a process limit

    monkeypatch.setattr(forked.os, "fork", no_fork)
    monkeypatch.setattr(forked, "cores", lambda: 2)
    monkeypatch.setattr(forked, "AVAILABLE", True)
    assert forked.beside(lambda: os.getpid()).result() == os.getpid()


class _Alarm(Exception):
    pass


@needs_fork
def test_an_interrupted_wait_stops_the_child(tmp_path):
    """A signal's handler that raises while result() waits (the CLI's on Ctrl-C): the child is killed and reaped
    there, not left computing (it ignores SIGINT) for a kill() that would no longer find it."""
    job, pid = _sleeping_child(tmp_path)

    def alarm(_signo, _frame):
        raise _Alarm

    old = signal.signal(signal.SIGALRM, alarm)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.3)
        with pytest.raises(_Alarm):
            job.result()
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, old)
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # killed and reaped
    job.kill()


def test_another_thread_or_beside_off_computes_here(monkeypatch):
    """Only the main thread forks (another thread's fork could copy a lock some thread holds into the child), and
    nothing forks with BESIDE off (a sweep's workers)."""
    got = []
    t = threading.Thread(target=lambda: got.append(forked.beside(os.getpid).result()))
    t.start()
    t.join()
    assert got == [os.getpid()]
    monkeypatch.setattr(forked, "BESIDE", False)
    assert forked.beside(os.getpid).result() == os.getpid()
