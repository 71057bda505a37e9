"""The CLI's console and exits: where a command's lines go (:class:`_Ctx`, the ``commands.Console`` the jobs print
through), and how its errors, signals and closed pipes become one stderr line and the documented exit code
(:func:`_guard` around each command body, :func:`run_main` around the whole program)."""

from __future__ import annotations

import sys
from typing import Any, Callable

import click

from ..artifacts.inputs import NewDirs
from ..errors import (EXIT_INTERRUPTED, EXIT_OK, Interrupted, RobustSynthError, check_interrupt, exit_broken_pipe,
                      exit_leaving_solves, install_signal_handlers, pending_interrupt)
from ..report.progress import stage_lines, stop_heartbeats


class _Ctx:
    """The command's console (``commands.Console``): -q / -v decide what is printed where."""

    def __init__(self, quiet: bool, verbose: bool) -> None:
        self.quiet = quiet
        self.verbose = verbose

    def say(self, msg: str) -> None:
        if not self.quiet:
            click.echo(msg)

    def detail(self, msg: str) -> None:
        if self.verbose and not self.quiet:
            click.echo(msg, err=True)

    def stages(self) -> Callable[[str], None]:
        """The stage lines of a long command (report.progress.stage_lines)."""
        return stage_lines(self.quiet, self.detail)

    def show(self, lines: list[str]) -> None:
        """A command's summary (report.console): an Err line on stderr (also under --quiet), the others on stdout."""
        from ..results import Err

        for line in lines:
            if isinstance(line, Err):
                click.echo(line, err=True)
            else:
                self.say(line)


def _exit_interrupted(exc: Interrupted) -> None:
    _NEW_DIRS.remove_empty()
    click.echo(f"{exc}", err=True)
    exit_leaving_solves(exc.exit_code)


def _exit_if_signalled() -> None:
    """After a signal, whatever broke is its consequence (e.g. an import it interrupted): report the
    interrupt instead (``errors.pending_interrupt``)."""
    pending = pending_interrupt()
    if pending is not None:
        _exit_interrupted(pending)


def _guard(fn: Callable[..., int | None]) -> Callable[..., None]:
    """Run a command body; a RobustSynthError becomes one stderr line and its exit code; an
    interrupt (SIGINT, SIGTERM) the line 'interrupted' and 130 / 143; a closed pipe 141."""

    def wrapper(*args: Any, **kwargs: Any) -> None:
        _NEW_DIRS.clear()  # this command's own (one process may run several: tests, scripts)
        try:
            try:
                code = fn(*args, **kwargs)
            finally:
                stop_heartbeats()  # none speaks after the command's last line ('interrupted', an error)
            sys.stdout.flush()
            check_interrupt()  # a signal whose exception Python swallowed (see errors.on_signal)
        except Interrupted as exc:
            _exit_interrupted(exc)
        except KeyboardInterrupt:
            _NEW_DIRS.remove_empty()
            click.echo("interrupted", err=True)
            exit_leaving_solves(EXIT_INTERRUPTED)
        except BrokenPipeError:
            exit_broken_pipe()
        except Exception as exc:
            _exit_if_signalled()
            if not isinstance(exc, RobustSynthError):
                raise
            _NEW_DIRS.remove_empty()
            click.echo(f"error: {exc}", err=True)
            sys.exit(exc.exit_code)
        sys.exit(EXIT_OK if code is None else code)

    wrapper.__name__ = fn.__name__
    wrapper.__doc__ = fn.__doc__
    return wrapper


_NEW_DIRS = NewDirs()  # output directories this command creates: removed again if it fails and leaves them empty


def run_main(main: click.Group) -> None:
    """The console script: ``main`` with interrupts and closed pipes handled also outside the
    command bodies (start-up, argument parsing), where click would print 'Aborted!' and exit 1.
    The handlers go in before click parses anything, so that the window in which a signal meets
    the interpreter's defaults is only the interpreter's own start-up."""
    install_signal_handlers()
    try:
        main.main(standalone_mode=False)
        check_interrupt()
    except click.exceptions.Exit as exc:  # --help, --version
        sys.exit(exc.exit_code)
    except (KeyboardInterrupt, click.exceptions.Abort):
        click.echo("interrupted", err=True)
        sys.exit(EXIT_INTERRUPTED)
    except Interrupted as exc:
        _exit_interrupted(exc)
    except BrokenPipeError:
        exit_broken_pipe()
    except click.ClickException as exc:  # usage errors: one line with click's message, exit 2
        if type(exc).__name__ == "NoArgsIsHelpError":  # bare `robustsynth`: the help itself, as click shows it
            exc.show()
            sys.exit(exc.exit_code)
        ctx = getattr(exc, "ctx", None)
        where = f"{ctx.command_path}: " if ctx is not None else ""
        click.echo(f"error: {where}{exc.format_message()}" + (" (--help for usage)" if ctx is not None else ""), err=True)
        sys.exit(exc.exit_code)
    except Exception:
        _exit_if_signalled()
        raise
    sys.exit(EXIT_OK)
