"""The console's live feedback while a command works, on stderr and only on a terminal: the stage lines with a
heartbeat line between them, the Monte Carlo progress bar, the sweep's count line.  The summaries printed when
a command is done are :mod:`.console`'s."""

from __future__ import annotations

import os
import sys
import time
from contextlib import contextmanager
from typing import Any, Callable, Iterator

import click

__all__ = ["HEARTBEAT_S", "Heartbeat", "LazyBar", "stop_heartbeats", "stage_lines", "progress_bar", "sweep_counts"]

HEARTBEAT_S = 10.0  # [s]: on a terminal, a line at least this often while a command works
HEARTBEAT_POLL_S = 1.0  # [s]: how often the heartbeat's thread looks at the clock
_HEARTBEATS: list["Heartbeat"] = []  # the running command's (stopped when it ends: cli._guard)


def _on_terminal(quiet: bool) -> bool:
    return not quiet and sys.stderr.isatty()


def stop_heartbeats() -> None:
    while _HEARTBEATS:
        _HEARTBEATS.pop().close()


def _hold_for_fork() -> None:
    """Before a fork (robustsynth/forked.py: the remedies' tries, the verification's checks beside the adversary): no
    heartbeat is mid-line, so the child's copies of its lock and of stderr's are free (a lock another thread held at
    the fork stays held in the child for ever)."""
    for beat in _HEARTBEATS:
        beat.lock.acquire()


def _release_after_fork() -> None:
    for beat in _HEARTBEATS:
        beat.lock.release()


def _fresh_in_child() -> None:
    import threading

    for beat in _HEARTBEATS:  # the child prints the lines it is given; its heartbeat thread was not forked
        beat.lock = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(before=_hold_for_fork, after_in_parent=_release_after_fork, after_in_child=_fresh_in_child)


class Heartbeat:
    """The stage lines of a long command, and a line of its own whenever HEARTBEAT_S pass without one (a solve
    of a nonlinear certificate can take minutes: issue 50 found 12.6 minutes of silence).  A daemon thread that
    only prints; it stops when the command ends (:func:`stop_heartbeats`, called by ``cli._guard``)."""

    def __init__(self) -> None:
        import threading

        self.t0 = self.last = time.monotonic()
        self.lock = threading.Lock()
        self.stopped = threading.Event()
        self.open_line = False  # the last output was a line rewritten in place, without its newline
        _HEARTBEATS.append(self)
        threading.Thread(target=self._beat, daemon=True, name="robustsynth-heartbeat").start()

    def close(self) -> None:
        """No line after this one returns (the lock: a line being written is finished first)."""
        with self.lock:
            self.stopped.set()

    def __call__(self, msg: str) -> None:
        with self.lock:
            self.last = time.monotonic()
            click.echo(msg, err=True)

    def rewrite(self, msg: str, end: bool) -> None:
        """A line rewritten in place (``msg`` starts with a carriage return), finished with its newline at ``end``."""
        with self.lock:
            self.last = time.monotonic()
            self.open_line = not end
            click.echo(msg, nl=end, err=True)

    def touch(self) -> None:
        """Something else (a progress bar) showed progress just now."""
        self.last = time.monotonic()

    def _beat(self) -> None:
        while not self.stopped.wait(HEARTBEAT_POLL_S):
            with self.lock:
                now = time.monotonic()
                if not self.stopped.is_set() and now - self.last >= HEARTBEAT_S:
                    self.last = now
                    if self.open_line:  # a rewritten line (a count) is on the terminal: below it
                        click.echo("", err=True)
                        self.open_line = False
                    m, sec = divmod(int(now - self.t0), 60)
                    click.echo(f"  ... still working ({m}:{sec:02d} since the start; Ctrl-C stops)", err=True)


class LazyBar:
    """A Monte Carlo progress bar on stderr that starts at the first progress report, so that its
    ETA is measured on the simulation alone (not on the model building and synthesis before it)."""

    def __init__(self, heartbeat: Heartbeat | None = None) -> None:
        self.bar: Any = None
        self.last = 0
        self.heartbeat = heartbeat  # told of every update, so that it speaks only between the bar's phases
        self._finished = False

    def __call__(self, done: int, total: int) -> None:
        if self.heartbeat is not None:
            self.heartbeat.touch()
        if self.bar is None:
            self.bar = click.progressbar(length=100, label="Monte Carlo", file=sys.stderr)
        pct = int(100 * done / max(total, 1))
        self.bar.update(pct - self.last)
        self.last = pct
        if done >= total:  # the checks after the runs may take minutes: the heartbeat's lines go below the bar
            self.render_finish()

    def render_finish(self) -> None:
        if self.bar is not None and not self._finished:
            self.bar.render_finish()
            self._finished = True


def stage_lines(quiet: bool, detail: Callable[[str], None]) -> Callable[[str], None]:
    """Where a command can take long: its stages and steps as lines on stderr when that is a terminal
    (and not --quiet), with a line at least every HEARTBEAT_S (:class:`Heartbeat`); otherwise ``detail``
    (the CLI's: only with -v)."""
    return Heartbeat() if _on_terminal(quiet) else detail


@contextmanager
def progress_bar(quiet: bool, heartbeat: Heartbeat | None = None) -> Iterator[LazyBar | None]:
    """A progress bar on stderr when it is a terminal (and not --quiet), with a heartbeat line whenever
    HEARTBEAT_S pass without an update (the checks after the Monte Carlo runs), finished when the block
    ends; else None."""
    if not _on_terminal(quiet):
        yield None
        return
    bar = LazyBar(heartbeat if heartbeat is not None else Heartbeat())
    try:
        yield bar
    finally:
        bar.render_finish()


def sweep_counts(quiet: bool) -> Callable[[int, int, int, float | None], None] | None:
    """points done/total, not certified so far, ETA: one rewritten stderr line on a terminal."""
    if not _on_terminal(quiet):
        return None
    beat = Heartbeat()  # a point can take minutes: a line between the counts

    def cb(done: int, total: int, bad: int, eta: float | None) -> None:
        eta_s = "" if eta is None else f", ETA {int(eta) // 60}:{int(eta) % 60:02d}"
        beat.rewrite(f"\r{done}/{total} points, {bad} not certified{eta_s}   ", done == total)

    return cb
