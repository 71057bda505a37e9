"""The console's heartbeat across a fork (robustsynth.report.progress, the remedies' tries of robustsynth/forked.py)."""

from __future__ import annotations

import threading
import time

import pytest

HELD_S = 0.5  # [s] another thread holds the heartbeat's lock this long around the fork
WAIT_S = 20.0  # [s] a child that can print answers in well under this; one whose lock copy is held never does


def test_a_forked_child_prints_through_a_heartbeat_another_thread_was_holding() -> None:
    """A thread holds the heartbeat's lock (as its own thread does while it prints "still working") when the main
    thread forks: the fork waits for it, so the child's copy of the lock is free and the child's line goes out; the
    parent's heartbeat works on after the fork."""
    from robustsynth.report import progress
    from robustsynth import forked

    if not forked.AVAILABLE:
        pytest.skip("no fork here")
    beat = progress.Heartbeat()
    try:
        taken = threading.Event()

        def hold() -> None:
            with beat.lock:
                taken.set()
                time.sleep(HELD_S)

        threading.Thread(target=hold, daemon=True).start()
        taken.wait()
        child = forked.Forked(lambda: beat("a line from the child") or "printed")
        done = forked.wait_any([child], until=time.perf_counter() + WAIT_S)
        if done is None:
            child.kill()
        assert done is child and child.result() == "printed"
        assert beat.lock.acquire(timeout=WAIT_S)  # the parent's lock was released after the fork
        beat.lock.release()
    finally:
        progress.stop_heartbeats()
