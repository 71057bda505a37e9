"""Command-line interface: parses options, calls one library function, prints the summary lines
:mod:`.report.console` makes of its result, maps errors to exit codes.

No mathematics and no formatting of results here; heavy modules are imported inside the commands.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any, Callable

import click

from . import __version__
from .artifacts.inputs import NewDirs
from .errors import (EXIT_INTERRUPTED, EXIT_OK, Interrupted, RobustSynthError, check_interrupt, exit_broken_pipe,
                     exit_leaving_solves, install_signal_handlers, pending_interrupt)
from .report.progress import Heartbeat, progress_bar, stage_lines, stop_heartbeats, sweep_counts

FILE = click.Path(dir_okay=False, path_type=Path)
DIR = click.Path(file_okay=False, path_type=Path)
CONFIG_ARG = click.argument("config", required=False, type=FILE)
LOGS_ARG = click.argument("logs", nargs=-1, required=True, type=FILE)
OUTDIR_OPT = click.option("-o", "--outdir", type=DIR, default=None,
                          help="Output directory [default: results/<config name>/].")
GAINS_OUTDIR_OPT = click.option("-o", "--outdir", type=DIR, default=None,
                                help="Output directory [default: the directory of --gains, else results/<config name>/].")
NO_FIGURE_OPT = click.option("--no-plots", is_flag=True, help="Skip the figure.")


class _Ctx:
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
        from .report.console import Err

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


class _FiniteNonNeg(click.ParamType):
    """A finite number >= 0 (click's FloatRange lets nan through: a review found --pose-noise nan nan taken)."""

    name = "float"

    def convert(self, value: Any, param: Any, ctx: Any) -> float:
        try:
            x = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not (math.isfinite(x) and x >= 0.0):
            self.fail(f"{value!r} is not a finite number >= 0", param, ctx)
        return x


_FINITE_NONNEG = _FiniteNonNeg()


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


def _load(config: Path | None, lti_ok: bool = False):
    from .config import is_lti, load_config
    from .errors import ConfigError

    try:
        cfg = load_config(config)
    except ConfigError:
        if config is not None:  # a file robustsynth wrote, given as CONFIG: one line saying so (issue 50)
            _not_a_config(config)
        raise
    if is_lti(cfg) and not lti_ok:
        from .errors import InputError

        cmd = click.get_current_context().info_name
        raise InputError(f"plant.kind: lti: `robustsynth {cmd}` is not available for a linear plant yet "
                         "(available: build-model, synthesize, verify, run, margin, sweep, export)")
    return cfg


def _not_a_config(path: Path, option: str | None = None) -> None:
    """One line when a file robustsynth wrote is given as a config (artifacts.inputs.not_a_config)."""
    from .artifacts.inputs import not_a_config

    ctx = click.get_current_context(silent=True)
    not_a_config(path, option, None if ctx is None else ctx.info_name,
                 ctx is not None and any(p.name == "gains" for p in ctx.command.params))


_NEW_DIRS = NewDirs()  # output directories this command creates: removed again if it fails and leaves them empty


def _outdir(cfg: Any, outdir: Path | None, gains: Path | None = None) -> Path:
    """-o if given, else beside --gains (the files belong to that gain), else results/<name>/."""
    from .pipeline import default_outdir

    return _NEW_DIRS.note(outdir if outdir is not None else gains.parent if gains is not None else default_outdir(cfg))


def _gains_config(obj: _Ctx, config: Path | None, gains: Path | None, said: str) -> Any:
    """CONFIG, else the config stored in --gains when it is another than the default one, ``said`` in one line."""
    from .artifacts.inputs import gains_own_config, needs_its_config

    needs_its_config(config, gains, click.get_current_context().info_name)
    cfg = _load(config, lti_ok=True)
    if config is not None or gains is None:
        return cfg
    stored = gains_own_config(cfg, gains)
    if stored is not cfg:
        obj.say(f"config: the one stored in {gains} ({stored.name!r}){said}")
    return stored


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="robustsynth")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing but errors.")
@click.option("-v", "--verbose", is_flag=True, help="Print the steps as they run (stderr).")
@click.pass_context
def main(ctx: click.Context, quiet: bool, verbose: bool) -> None:
    """Certified robust state feedback for a skid-slip tracked robot over a delaying network.

    CONFIG is a YAML scenario file; without it the embedded default is used.  A config with
    `plant: {kind: lti, A: ..., B: ...}` is any linear plant instead of the robot: build-model,
    synthesize, verify, run, margin, sweep and export (c, python) work on it too (docs/tutorials/linear-plant.md).
    Exit codes: 0 ok, 1 verification failed, 2 bad input or usage, 3 infeasible, 4 solver failure,
    130 interrupted (Ctrl-C), 143 terminated (SIGTERM).
    """
    ctx.obj = _Ctx(quiet, verbose)
    install_signal_handlers()


def _set_flag(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    if value and isinstance(ctx.find_object(_Ctx), _Ctx):
        setattr(ctx.find_object(_Ctx), param.name, True)


def _verbosity(fn):
    """-q/--quiet and -v/--verbose also after the subcommand (robustsynth run -q)."""
    fn = click.option("-v", "--verbose", is_flag=True, expose_value=False, callback=_set_flag,
                      help="Print the steps as they run (stderr).")(fn)
    return click.option("-q", "--quiet", is_flag=True, expose_value=False, callback=_set_flag,
                        help="Print nothing but errors.")(fn)


@main.command()
@_verbosity
@click.option("--plant", type=click.Choice(["tracked-robot", "lti"]), default="tracked-robot", show_default=True,
              help="Whose config: the tracked robot's, or a linear plant's (plant: kind: lti).")
@_guard
def schema(plant: str) -> None:
    """Print the JSON Schema of the configuration file."""
    import json

    from .config import config_schema

    click.echo(json.dumps(config_schema(plant), indent=2))


@main.command("default-config")
@_verbosity
@click.option("--name", "name", default=None,
              help="Set the scenario name (and so the output directory results/NAME/) [default: default].")
@_guard
def default_config(name: str | None) -> None:
    """Print the embedded default configuration (YAML)."""
    from .config import default_config_text, named_default_config_text

    click.echo(default_config_text() if name is None else named_default_config_text(name), nl=False)


@main.command("build-model")
@_verbosity
@CONFIG_ARG
@OUTDIR_OPT
@click.pass_obj
@_guard
def build_model_cmd(obj: _Ctx, config: Path | None, outdir: Path | None) -> None:
    """Build the lifted model and check its vertex description; write model.json and model.md.

    synthesis.model slip-aware (default): exact in slip and delay, its vertices cover every
    admissible slip and delay; paper: the seed paper's eq. 25 with the uncertainty of eqs. 31-33.
    """
    from .config import is_lti
    from .pipeline import model_stage
    from .report import console

    cfg = _load(config, lti_ok=True)
    out = _outdir(cfg, outdir)
    if is_lti(cfg):
        from .pipeline_lti import lti_model_stage

        obj.show(console.lti_model_summary(cfg.name, out, lti_model_stage(cfg, out, config)))
        return
    obj.show(console.model_summary(cfg.name, out, model_stage(cfg, out)))


SYNTH_OPTS = [
    click.option("--objective", type=click.Choice(["ultimate-bound", "stability", "hinf"]), default=None,
                 help="Override synthesis.objective."),
    click.option("--solver", type=click.Choice(["clarabel", "scs"]), default=None, help="Override synthesis.solver."),
    click.option("--multiplier", type=click.Choice(["structured", "full"]), default=None,
                 help="Override synthesis.multiplier."),
    click.option("--diagnose/--no-diagnose", "diagnose", default=None,
                 help="Re-solve with each constraint relaxed (motor limit, slip range, delay, slip rate) to show "
                      "which one binds [default: when the certified |e_y| exceeds half the track distance]."),
]


def _synth_opts(fn):
    for opt in reversed(SYNTH_OPTS):
        fn = opt(fn)
    return fn


@main.command()
@_verbosity
@CONFIG_ARG
@OUTDIR_OPT
@_synth_opts
@click.pass_obj
@_guard
def synthesize(obj: _Ctx, config: Path | None, outdir: Path | None, objective: str | None, solver: str | None,
               multiplier: str | None, diagnose: bool | None) -> None:
    """Solve the LMIs for a certified robust gain; write gains.json, gains.mat, synthesis.md."""
    from .config import is_lti
    from .model import build_model
    from .pipeline import synthesis_stage
    from .report import console

    cfg = _load(config, lti_ok=True)
    out = _outdir(cfg, outdir)
    if is_lti(cfg):
        _lti_only(multiplier=multiplier, diagnose=diagnose)
        from .pipeline_lti import lti_synthesis_stage

        obj.show(console.lti_synthesis_summary(out, lti_synthesis_stage(cfg, out, config, obj.stages(), objective,
                                                                         solver)))
        return
    obj.detail(f"building the model of '{cfg.name}'")
    obj.show(console.synthesis_summary(out, synthesis_stage(build_model(cfg), out, on_step=obj.stages(),
                                                            diagnose=diagnose, objective=objective, solver=solver,
                                                            multiplier=multiplier)))


def _lti_only(**robot_options: Any) -> None:
    """Refuse the robot's synthesis options on a linear plant (one line, exit 2)."""
    given = [k for k, v in robot_options.items() if v is not None]
    if given:
        from .errors import InputError

        raise InputError(f"--{given[0]}: a robot synthesis option, not available for a linear plant")


VERIFY_OPTS = [
    click.option("--runs", type=click.IntRange(min=1, max=100_000), default=None, help="Monte Carlo runs [config]."),
    click.option("--seed", type=click.IntRange(min=0), default=None, help="Random seed [config]."),
    click.option("--format", "fmt", type=click.Choice(["png", "pdf", "svg"]), default="png", show_default=True,
                 help="Figure format."),
    click.option("--no-plots", is_flag=True, help="Skip the figures."),
]


def _verify_opts(fn):
    for opt in reversed(VERIFY_OPTS):
        fn = opt(fn)
    return fn


@main.command("verify")
@_verbosity
@CONFIG_ARG
@click.option("--gains", "gains", type=FILE, default=None, help="Gains file [default: OUTDIR/gains.json].")
@GAINS_OUTDIR_OPT
@_verify_opts
@click.option("--log", "logdir", type=DIR, default=None,
              help="Also write each Monte Carlo run as a robot log (CSV, the format identify and check-log read) here.")
@click.pass_obj
@_guard
def verify_cmd(obj: _Ctx, config: Path | None, gains: Path | None, outdir: Path | None, runs: int | None,
               seed: int | None, fmt: str, no_plots: bool, logdir: Path | None) -> int:
    """Check a gain against the config: certificate, frozen delays, lifted model, nonlinear Monte Carlo.

    Exit 1 when any check fails.
    """
    from .config import is_lti
    from .errors import EXIT_VERIFICATION_FAILED
    from .model import build_model
    from .pipeline import verification_stage
    from .report import console

    cfg = _gains_config(obj, config, gains, ", the gain's own; pass CONFIG to verify it on another")  # issue 50
    out = _outdir(cfg, outdir, gains)
    if is_lti(cfg):
        if logdir is not None:
            from .errors import InputError

            raise InputError("--log: robot logs are for the tracked robot, not a linear plant")
        from .pipeline_lti import lti_verification_stage

        data = lti_verification_stage(cfg, out, gains, config, runs, seed, plots=not no_plots, fmt=fmt)
        obj.show(console.lti_verification_summary(data))
        return EXIT_OK if data["passed"] else EXIT_VERIFICATION_FAILED
    from contextlib import nullcontext

    from .artifacts.files import writable_dir

    # the log place is proven writable before the work (a review found exit 2 at the end), and removed
    # again if the work fails before any log is in it
    with writable_dir(logdir) if logdir is not None else nullcontext():
        with progress_bar(obj.quiet) as cb:
            st = verification_stage(build_model(cfg), out, gains, runs, seed, fmt, not no_plots, cb)
        obj.show(console.verification_summary(out, st))
        if logdir is not None:
            from .pipeline import write_run_logs

            obj.say(console.logs_line(write_run_logs(st.model, st.result, logdir), logdir))
    return EXIT_OK if st.result.passed else EXIT_VERIFICATION_FAILED


@main.command("run")
@_verbosity
@CONFIG_ARG
@OUTDIR_OPT
@_synth_opts
@_verify_opts
@click.option("--physics", "physics", type=click.IntRange(min=0, max=1000), default=0, show_default=True,
              metavar="EPISODES", help="Then validate the gain on the MuJoCo robot with this many episodes (0: skip) -> "
                                        "OUTDIR/validation/.")
@click.option("--export", "export_to", type=click.Choice(["c", "python", "ros2", "json"]), default=None,
              help="Then export the verified controller -> OUTDIR/export/ (refused when verification failed).")
@click.pass_obj
@_guard
def run_cmd(obj: _Ctx, config: Path | None, outdir: Path | None, objective: str | None, solver: str | None,
            multiplier: str | None, diagnose: bool | None, runs: int | None, seed: int | None, fmt: str,
            no_plots: bool, physics: int, export_to: str | None) -> int:
    """build-model, synthesize and verify in one go; write report.md and summary.json (with --physics and
    --export also validate on the physics robot and export the controller)."""
    from .config import is_lti
    from .errors import EXIT_VERIFICATION_FAILED
    from .pipeline import run
    from .report import console

    cfg = _load(config, lti_ok=True)
    out = _outdir(cfg, outdir)
    if is_lti(cfg):
        _lti_only(multiplier=multiplier, diagnose=diagnose)
        from .pipeline_lti import lti_run

        res = lti_run(cfg, out, config, obj.stages(), objective, solver, runs, seed, plots=not no_plots)
        obj.show(console.lti_run_summary(out, res))
        return EXIT_OK if res["verification"]["passed"] else EXIT_VERIFICATION_FAILED
    stage = obj.stages()  # the stages and each step of the synthesis (a heartbeat between them, on a terminal)
    with progress_bar(obj.quiet, stage if isinstance(stage, Heartbeat) else None) as cb:
        res = run(cfg, out, runs, seed, fmt, not no_plots, cb, on_stage=lambda s: stage(f"[{s}]"), on_step=stage,
                  diagnose=diagnose, objective=objective, solver=solver, multiplier=multiplier)
    obj.show(console.run_summary(out, res))
    passed = res.passed
    if physics:
        from .pipeline import validation_stage

        obj.say("[validate on the physics robot]")
        vd = validation_stage(res.verification.model, out / "gains.json", out / "validation", episodes=physics,
                              plots=not no_plots)
        obj.say(console.physics_line(vd, physics))
        passed = passed and vd["passed"]
    if export_to:  # a failed verification is not exported as a controller (issue 50); the exit code stays 1
        from .runtime.export import export_controller

        # export_controller reads the verification.json this run wrote beside gains.json
        exported = export_controller(out / "gains.json", export_to, out / "export", None) if res.passed else None
        obj.show(console.run_export_lines(export_to, out / "gains.json", exported))
    obj.say(f"report: {out / 'report.md'}")
    return EXIT_OK if passed else EXIT_VERIFICATION_FAILED


@main.command("margin")
@_verbosity
@CONFIG_ARG
@click.option("--gains", "gains", type=FILE, default=None,
              help="Gains file [default: OUTDIR/gains.json; for a linear plant the config's controller.gain "
                   "comes first].")
@GAINS_OUTDIR_OPT
@click.option("--lyapunov", type=click.Choice(["common", "slip-dependent", "delay-dependent", "path-dependent", "auto"]), default=None,
              help="Certificates tried at each point [default: synthesis.lyapunov]; auto: common, then "
                   "slip-dependent where it fails (tighter, slower).")
@click.option("--json", "as_json", is_flag=True, help="Print margin.json to stdout instead of one line per margin.")
@click.pass_obj
@_guard
def margin_cmd(obj: _Ctx, config: Path | None, gains: Path | None, outdir: Path | None, lyapunov: str | None,
               as_json: bool) -> None:
    """How far can the delay bound and the slip range be pushed for a given gain?

    For each margin: the furthest certified value (analysis LMIs, K fixed, checked in numpy) and the
    nearest value at which an instability is exhibited (periodic delay/slip sequences of the lifted
    closed loop), with the destabilizing sequence.  Writes OUTDIR/margin.json.
    """
    from .config import is_lti
    from .pipeline import margin_stage
    from .report import console

    cfg = _gains_config(obj, config, gains, "; pass CONFIG to take the gain's margins on another")  # review
    if is_lti(cfg):
        if lyapunov is not None:
            from .errors import InputError

            raise InputError("--lyapunov: a linear plant's certificate is one common quadratic function")
        from .pipeline_lti import lti_margin_stage

        data = lti_margin_stage(cfg, _outdir(cfg, outdir, gains), config, on_step=obj.stages(),
                                gains_path=gains)
        obj.show(console.lti_margin_summary(data, as_json))
    else:
        st = margin_stage(cfg, _outdir(cfg, outdir, gains), gains, lyapunov, on_step=obj.stages())
        data = st.data
        if not as_json:
            obj.show(console.margin_summary(st))
    if as_json:
        import json

        click.echo(json.dumps(data, indent=2))


@main.command("identify")
@_verbosity
@LOGS_ARG
@click.option("-o", "--output", "out", type=FILE, default=None,
              help="Write the config fragment here, with <stem>.md and <stem>.png beside it [default: print it].")
@click.option("--config", "config", type=FILE, default=None,
              help="The robot's config (gear radius, track distance) [default: the embedded default].")
@click.option("--model", type=click.Choice(["tracks", "icr"]), default="tracks", show_default=True,
              help="Slip description to identify (tracks: one traction factor per track; icr: also the yaw factor "
                   "and the ICR offset, from turns).")
@click.option("--coverage", type=click.FloatRange(0.5, 1.0), default=0.995, show_default=True,
              help="Fraction of the per-period slip estimates the box covers (before widening).")
@click.option("--pose-noise", "pose_noise", type=_FINITE_NONNEG, nargs=2, default=None,
              metavar="POSITION HEADING",
              help="--model icr: std of the logged poses [m] [rad] [default: the config's verification.noise].")
@click.option("--max-motor-speed", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Skip periods with a command beyond this motor speed [rad/s] (saturated motors) [default: the "
                   "config's robot.max_motor_speed; inf: skip none].")
@click.option("--settle", type=_FINITE_NONNEG, default=0.0, show_default=True, metavar="SECONDS",
              help="Skip the periods within this long after a command change (a robot with dynamics is still settling "
                   "there: the excitation logs of validate --excite on the physics robot want 1).")
@NO_FIGURE_OPT
@click.pass_obj
@_guard
def identify_cmd(obj: _Ctx, logs: tuple[Path, ...], out: Path | None, config: Path | None, model: str, coverage: float,
                 pose_noise: tuple[float, float] | None, max_motor_speed: float | None, settle: float,
                 no_plots: bool) -> None:
    """Delay range, longest loss burst and slip box from robot logs (CSV, the log format of docs/tutorials/robot-logs.md).

    The result is a config fragment with the data behind each number as comments.
    """
    from .artifacts.inputs import motor_limit
    from .pipeline import identification_stage

    cfg = _load(config)
    ident, text, written = identification_stage(list(logs), cfg, out, coverage, model,
                                                motor_limit(max_motor_speed, cfg), not no_plots, pose_noise, settle)
    if out is None:
        click.echo(text, nl=False)
    else:
        from .report.console import identified_line

        obj.say(identified_line(ident, written))


@main.command("check-log")
@_verbosity
@LOGS_ARG
@click.option("--config", "config", type=FILE, default=None, help="The config whose assumptions are checked.")
@click.option("--gains", "gains", type=FILE, default=None,
              help="Check the assumptions of the config stored in this gains file instead.")
@click.option("--tolerance", type=click.FloatRange(0.0, 1.0), default=0.005, show_default=True,
              help="Fraction of samples allowed outside an assumption before it counts as violated.")
@click.option("--max-motor-speed", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Skip slip estimates of periods with a command beyond this motor speed [rad/s] [default: the "
                   "config's robot.max_motor_speed; inf: skip none].")
@click.option("--pose-noise", "pose_noise", type=_FINITE_NONNEG, nargs=2, default=None,
              metavar="POSITION HEADING",
              help="slip.model icr: std of the logged poses [m] [rad] [default: the config's verification.noise].")
@click.pass_obj
@_guard
def check_log_cmd(obj: _Ctx, logs: tuple[Path, ...], config: Path | None, gains: Path | None, tolerance: float,
                  max_motor_speed: float | None, pose_noise: tuple[float, float] | None) -> int:
    """Does the robot of these logs stay inside the config's assumptions (delay, losses, slip)?

    Exit 1 if any assumption is violated by more than --tolerance of its samples.
    """
    from .artifacts.inputs import check_log_config, motor_limit
    from .artifacts.logs import read_log
    from .errors import EXIT_VERIFICATION_FAILED, InputError
    from .identification import check_log
    from .report import console

    if (config is None) == (gains is None):
        raise InputError("check-log: give exactly one of --config and --gains")
    cfg = check_log_config(gains) if gains is not None else _load(config)
    rows = check_log([read_log(p) for p in logs], cfg, motor_limit(max_motor_speed, cfg), pose_noise)
    obj.show(console.check_log_summary(rows, tolerance))
    return EXIT_VERIFICATION_FAILED if any(console.violated(r, tolerance) for r in rows) else EXIT_OK


@main.command("monitor")
@_verbosity
@LOGS_ARG
@click.option("--gains", "gains", type=FILE, required=True,
              help="The gains file whose certificate the monitor watches.")
@click.option("--config", "config", type=FILE, default=None,
              help="The config (its path, network, slip box, monitor settings) [default: the one stored in --gains].")
@click.option("-o", "--outdir", type=DIR, default=None, help="Also write monitor.json (every alarm, per log) here.")
@click.pass_obj
@_guard
def monitor_cmd(obj: _Ctx, logs: tuple[Path, ...], gains: Path, config: Path | None, outdir: Path | None) -> int:
    """Replay the runtime monitor over robot logs: every alarm, with its period and cause.

    Exit 1 if any period raised an alarm (an assumption of the certificate broken, as far as the monitor sees).
    """
    from .errors import EXIT_VERIFICATION_FAILED
    from .report.console import monitor_summary
    from .runtime.replay import monitor_files

    res = monitor_files(list(logs), gains, _load(config) if config is not None else None, outdir)
    obj.show(monitor_summary(res, outdir))
    return EXIT_VERIFICATION_FAILED if res["runs_with_alarms"] else EXIT_OK


@main.command("validate")
@_verbosity
@click.argument("config", type=FILE)
@click.option("--gains", "gains", type=FILE, default=None, help="The gains file to validate (not with --excite).")
@click.option("--excite", is_flag=True,
              help="Instead: drive the robot open loop (turns at several rates, speed changes) and write the "
                   "episodes as robot logs for identify (with the config's verification.noise on the poses).")
@click.option("--episodes", type=click.IntRange(min=1, max=10_000), default=4, show_default=True,
              help="Closed-loop episodes along the config's path (the first from the path's start, the others perturbed).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the delays and the perturbed starts.")
@click.option("--workers", type=click.IntRange(min=1, max=256), default=1, show_default=True,
              help="Processes to run the episodes on (the results do not depend on it).")
@click.option("--engine", type=click.Choice(["physics", "kinematic"]), default="physics", show_default=True,
              help="physics: MuJoCo (slip from contact); kinematic: the model's own robot, one slip per episode from the "
                   "box (--excite: the simulator's slip profiles, a new slip every period or few).")
@click.option("-o", "--outdir", type=DIR, default=None, help="Output directory (default results/<name>/validation).")
@NO_FIGURE_OPT
@click.option("--inject", type=click.Choice(["delay", "losses", "friction", "push", "command"]), default=None,
              help="Break one of the certificate's assumptions in every episode, to see the runtime monitor flag it: "
                   "delay (a command SIZE s beyond tau_max), losses (SIZE commands beyond the cap in a row), friction "
                   "(a mud patch: ground of friction SIZE that drags the robot back), push (sideways, SIZE x its "
                   "weight for a period), command (SIZE x the motor limit).")
@click.option("--inject-period", type=click.IntRange(min=1), default=150, show_default=True,
              help="The period the injection starts at.")
@click.option("--inject-size", type=float, default=None,
              help="The injection's size [default: delay 0.07 s, losses 1, friction 0.3, push 3, command 2].")
@click.pass_obj
@_guard
def validate_cmd(obj: _Ctx, config: Path, gains: Path | None, excite: bool, episodes: int, seed: int, workers: int,
                 engine: str, outdir: Path | None, no_plots: bool, inject: str | None, inject_period: int,
                 inject_size: float | None) -> int:
    """Run the deployed law on a physics-engine robot (MuJoCo; slip from contact and friction).

    Writes validation.json and the episodes as robot logs (logs/, identify's format).  Exit 1 when
    an error on a straight segment exceeds its certified bound, or when the slip the engine showed
    (estimated by identify) leaves the config's slip box.  With --inject, the episodes leave the certificate's
    assumptions on purpose: the console says when the runtime monitor first flagged it.
    """
    from .errors import EXIT_VERIFICATION_FAILED, InputError
    from .model import build_model
    from .pipeline import excitation_stage, validation_stage
    from .report import console

    if excite == (gains is not None):
        raise InputError("validate: give exactly one of --gains (validate a gain) and --excite (excitation logs)")
    if excite and inject is not None:
        raise InputError("validate: --inject runs the closed loop (--gains), not the excitation (--excite)")
    if inject is None and inject_size is not None:
        raise InputError("validate: --inject-size without --inject")
    injection = None
    if inject is not None:
        from .verification.physics import Injection

        injection = Injection(inject, inject_period, inject_size)
    cfg = _load(config)
    out = outdir if outdir is not None else Path("results") / cfg.name / ("excitation" if excite else "validation")
    if excite:
        paths = excitation_stage(build_model(cfg), out, episodes=episodes, seed=seed, engine=engine)
        physics = None
        if engine == "physics":  # which robot the engine drove (issue 50: the default chassis had been used silently)
            from .verification.physics import physics_config

            physics = physics_config(cfg)[1]["summary"]
        obj.show(console.excitation_summary(cfg, config, engine, out, len(paths), physics))
        return EXIT_OK
    with progress_bar(obj.quiet) as cb:
        vd = validation_stage(build_model(cfg), gains, out, episodes=episodes, seed=seed, progress=cb, plots=not no_plots,
                              workers=workers, engine=engine, inject=injection)
    obj.show(console.validation_summary(vd, episodes, out, None if injection is None else injection.describe()))
    return EXIT_OK if vd["passed"] else EXIT_VERIFICATION_FAILED


@main.command("export")
@_verbosity
@click.argument("gains", type=FILE)
@click.option("--to", "target", type=click.Choice(["c", "python", "ros2", "json"]), required=True,
              help="c: rs_controller.h/.c (C99, no heap) + rs_harness.c; python: rs_controller.py (no numpy); "
                   "ros2: a ros__parameters YAML, rs_node.py (an rclpy node running the law and its monitor) and "
                   "rs_controller.py; json: the controller description.")
@click.option("-o", "--outdir", type=DIR, required=True, help="Directory for the generated files.")
@click.option("--config", "config", type=FILE, default=None,
              help="Take the path from this config [default: the config stored in GAINS].")
@click.option("--verification", "verification", type=FILE, default=None,
              help="The verification record of GAINS [default: verification.json beside GAINS, written by "
                   "`robustsynth verify`; it names the gain it verified].")
@click.option("--allow-unverified", is_flag=True,
              help="Export a gain whose verification failed, is missing or is of another gain (warned on stderr, "
                   "the files marked UNVERIFIED).")
@click.pass_obj
@_guard
def export_cmd(obj: _Ctx, gains: Path, target: str, outdir: Path, config: Path | None, verification: Path | None,
               allow_unverified: bool) -> int:
    """Generate the controller of GAINS (gains.json or .mat) for the robot.

    The generated code implements the law the simulator verified, operation for operation: the
    gain, sampling time, command memory, integrators, path and motor mapping are baked in.  Only a
    gain that passed `robustsynth verify` is exported (exit 1 when its verification failed, 2 when
    there is none of this gain), unless --allow-unverified; the files state what it is proven for.
    """
    from .errors import ConfigError
    from .report.console import export_summary
    from .runtime.export import export_controller

    try:
        d, files = export_controller(gains, target, outdir, config, verification_path=verification,
                                     allow_unverified=allow_unverified)
    except ConfigError:
        if config is not None:  # a gains file (or another output of ours) given as --config: one line
            _not_a_config(config, "--config")
        raise
    obj.show(export_summary(gains, d, files))
    return EXIT_OK


@main.command("sweep")
@_verbosity
@click.argument("spec", type=FILE)
@click.option("-o", "--outdir", type=DIR, default=None,
              help="Output directory [default: results/sweeps/<sweep file name>/].")
@click.option("--verify", "verify_runs", type=click.IntRange(min=1, max=100_000), default=None, metavar="RUNS",
              help="Also verify each certified gain with RUNS Monte Carlo runs.")
@click.option("--workers", type=click.IntRange(min=1, max=1024), default=None,
              help="Local worker processes [default: all cores; 1: in this process].")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run the points on this dask.distributed scheduler (pip install 'robustsynth[dask]').")
@click.option("--force", is_flag=True, help="Recompute points already stored under OUTDIR/points/.")
@click.pass_obj
@_guard
def sweep_cmd(obj: _Ctx, spec: Path, outdir: Path | None, verify_runs: int | None, workers: int | None,
              scheduler: str | None, force: bool) -> None:
    """Synthesize (and verify) a gain at every point of a sweep over config keys.

    SPEC names a base config and axes over dotted config keys (grid or zip).  Writes sweep.csv,
    sweep.json, the figure, and one file per point under points/ (a rerun skips those).
    """
    from .report.console import sweep_summary
    from .sweeps import load_sweep, sweep

    sp = load_sweep(spec)
    out = outdir if outdir is not None else Path("results") / "sweeps" / spec.stem
    obj.detail(f"{len(sp.points())} points over {', '.join(sp.keys)} ({sp.mode})")
    res = sweep(sp, out, verify_runs=verify_runs, workers=workers, scheduler=scheduler, force=force,
                progress=sweep_counts(obj.quiet))
    obj.show(sweep_summary(res, out))


def entry() -> None:
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
