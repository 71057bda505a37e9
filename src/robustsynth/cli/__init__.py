"""Command-line interface: parses options, calls one library function (a plant kind's job, :mod:`..commands`, or a
stage), prints the summary lines :mod:`..report.console` makes of its result.  Errors become exit codes in
:mod:`._console`; the shared options are in :mod:`._options`.

No mathematics, no formatting of results and no plant branches here; heavy modules are imported inside the commands.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from .. import __version__
from ..commands import JOBS as PLANT_KINDS
from ..commands import jobs_for as _jobs
from ..commands import require
from ..errors import EXIT_OK, install_signal_handlers
from ..report.progress import sweep_counts
from ._console import _NEW_DIRS, _Ctx, _guard, run_main
from ._options import (_FINITE_NONNEG, CONFIG_ARG, DIR, FILE, GAINS_OUTDIR_OPT, LOGS_ARG, NO_FIGURE_OPT, OUTDIR_OPT,
                       _synth_opts, _verbosity, _verify_opts)


def _load(config: Path | None):
    """CONFIG (or the embedded default), refused when its plant kind does not offer this command."""
    from ..config import load_config
    from ..errors import ConfigError

    try:
        cfg = load_config(config)
    except ConfigError:
        if config is not None:  # a file robustsynth wrote, given as CONFIG: one line saying so (issue 50)
            _not_a_config(config)
        raise
    require(cfg, click.get_current_context().info_name)
    return cfg


def _not_a_config(path: Path, option: str | None = None) -> None:
    """One line when a file robustsynth wrote is given as a config (artifacts.inputs.not_a_config)."""
    from ..artifacts.inputs import not_a_config

    ctx = click.get_current_context(silent=True)
    not_a_config(path, option, None if ctx is None else ctx.info_name,
                 ctx is not None and any(p.name == "gains" for p in ctx.command.params))


def _outdir(cfg: Any, outdir: Path | None, gains: Path | None = None) -> Path:
    """-o if given, else beside --gains (the files belong to that gain), else results/<name>/."""
    from ..pipeline import default_outdir

    return _NEW_DIRS.note(outdir if outdir is not None else gains.parent if gains is not None else default_outdir(cfg))


def _gains_config(obj: _Ctx, config: Path | None, gains: Path | None, said: str, stderr: bool = False) -> Any:
    """CONFIG, else the config stored in --gains when it is another than the default one, ``said`` in one line
    (on stderr with ``stderr``: where stdout is JSON)."""
    from ..artifacts.inputs import gains_own_config, needs_its_config

    needs_its_config(config, gains, click.get_current_context().info_name)
    cfg = _load(config)
    if config is not None or gains is None:
        return cfg
    stored = gains_own_config(cfg, gains)
    if stored is not cfg:
        line = f"config: the one stored in {gains} ({stored.name!r}){said}"
        if not stderr:
            obj.say(line)
        elif not obj.quiet:
            click.echo(line, err=True)
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


@main.command()
@_verbosity
@click.option("--plant", type=click.Choice(list(PLANT_KINDS)), default="tracked-robot", show_default=True,
              help="Whose config: the tracked robot's, or a linear plant's (plant: kind: lti).")
@_guard
def schema(plant: str) -> None:
    """Print the JSON Schema of the configuration file."""
    import json

    from ..config import config_schema

    click.echo(json.dumps(config_schema(plant), indent=2))


@main.command("default-config")
@_verbosity
@click.option("--name", "name", default=None,
              help="Set the scenario name (and so the output directory results/NAME/) [default: default].")
@_guard
def default_config(name: str | None) -> None:
    """Print the embedded default configuration (YAML)."""
    from ..config import default_config_text, named_default_config_text

    click.echo(default_config_text() if name is None else named_default_config_text(name), nl=False)


@main.command("build-model")
@_verbosity
@CONFIG_ARG
@OUTDIR_OPT
@click.pass_obj
@_guard
def build_model_cmd(obj: _Ctx, config: Path | None, outdir: Path | None) -> int:
    """Build the lifted model and check its vertex description; write model.json and model.md.

    synthesis.model slip-aware (default): exact in slip and delay, its vertices cover every
    admissible slip and delay; paper: the seed paper's eq. 25 with the uncertainty of eqs. 31-33.
    """
    cfg = _load(config)
    return _jobs(cfg).model(cfg, _outdir(cfg, outdir), obj, config).code


@main.command()
@_verbosity
@CONFIG_ARG
@OUTDIR_OPT
@_synth_opts
@click.pass_obj
@_guard
def synthesize(obj: _Ctx, config: Path | None, outdir: Path | None, objective: str | None, solver: str | None,
               multiplier: str | None, diagnose: bool | None) -> int:
    """Solve the LMIs for a certified robust gain; write gains.json, gains.mat, synthesis.md."""
    cfg = _load(config)
    return _jobs(cfg).synthesize(cfg, _outdir(cfg, outdir), obj, config, objective=objective, solver=solver,
                                 multiplier=multiplier, diagnose=diagnose).code


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
    cfg = _gains_config(obj, config, gains, ", the gain's own; pass CONFIG to verify it on another")  # issue 50
    return _jobs(cfg).verify(cfg, _outdir(cfg, outdir, gains), obj, config, gains=gains, runs=runs, seed=seed,
                             fmt=fmt, plots=not no_plots, logdir=logdir).code


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
    cfg = _load(config)
    return _jobs(cfg).run(cfg, _outdir(cfg, outdir), obj, config, objective=objective, solver=solver,
                          multiplier=multiplier, diagnose=diagnose, runs=runs, seed=seed, fmt=fmt, plots=not no_plots,
                          physics=physics, export_to=export_to).code


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
               as_json: bool) -> int:
    """How far can the delay bound and the slip range be pushed for a given gain?

    For each margin: the furthest certified value (analysis LMIs, K fixed, checked in numpy) and the
    nearest value at which an instability is exhibited (periodic delay/slip sequences of the lifted
    closed loop), with the destabilizing sequence.  Writes OUTDIR/margin.json.
    """
    cfg = _gains_config(obj, config, gains, "; pass CONFIG to take the gain's margins on another", stderr=as_json)
    res = _jobs(cfg).margin(cfg, _outdir(cfg, outdir, gains), obj, config, gains=gains, lyapunov=lyapunov,
                            as_json=as_json)
    if as_json:
        import json

        click.echo(json.dumps(res.data, indent=2))
    return res.code


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
    from ..artifacts.inputs import motor_limit
    from ..pipeline import identification_stage

    cfg = _load(config)
    ident, text, written = identification_stage(list(logs), cfg, out, coverage, model,
                                                motor_limit(max_motor_speed, cfg), not no_plots, pose_noise, settle)
    if out is None:
        click.echo(text, nl=False)
    else:
        from ..report.console import identified_line

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
    from ..artifacts.inputs import check_log_config, motor_limit
    from ..artifacts.logs import read_log
    from ..errors import EXIT_VERIFICATION_FAILED, InputError
    from ..identification import check_log
    from ..report import console

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
    from ..errors import EXIT_VERIFICATION_FAILED
    from ..report.console import monitor_summary
    from ..runtime.replay import monitor_files

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
@click.option("--inject", type=click.Choice(["delay", "losses", "friction", "patch", "push", "command"]), default=None,
              help="Break one of the certificate's assumptions in every episode, to see the runtime monitor flag it: "
                   "delay (a command SIZE s beyond tau_max), losses (SIZE commands beyond the cap in a row), friction "
                   "(a mud patch: ground of friction SIZE that drags the robot back), push (sideways, SIZE x its "
                   "weight for a period), command (SIZE x the motor limit); or change the ground: patch (friction "
                   "SIZE for 100 periods, then back).")
@click.option("--inject-period", type=click.IntRange(min=1), default=150, show_default=True,
              help="The period the injection starts at.")
@click.option("--inject-size", type=float, default=None,
              help="The injection's size [default: delay 0.07 s, losses 1, friction 0.3, patch 0.4, push 3, command 2].")
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
    from ..errors import InputError

    if excite == (gains is not None):
        raise InputError("validate: give exactly one of --gains (validate a gain) and --excite (excitation logs)")
    if excite and inject is not None:
        raise InputError("validate: --inject runs the closed loop (--gains), not the excitation (--excite)")
    if inject is None and inject_size is not None:
        raise InputError("validate: --inject-size without --inject")
    cfg = _load(config)
    out = outdir if outdir is not None else Path("results") / cfg.name / ("excitation" if excite else "validation")
    if excite:
        return _jobs(cfg).excite(cfg, out, obj, config, episodes=episodes, seed=seed, engine=engine).code
    return _jobs(cfg).validate(cfg, out, obj, config, gains=gains, episodes=episodes, seed=seed, workers=workers,
                               engine=engine, plots=not no_plots,
                               inject=None if inject is None else (inject, inject_period, inject_size)).code


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
    from ..errors import ConfigError
    from ..report.console import export_summary
    from ..runtime.export import export_controller

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
    from ..report.console import sweep_summary
    from ..sweeps import load_sweep, sweep

    sp = load_sweep(spec)
    out = outdir if outdir is not None else Path("results") / "sweeps" / spec.stem
    obj.detail(f"{len(sp.points())} points over {', '.join(sp.keys)} ({sp.mode})")
    res = sweep(sp, out, verify_runs=verify_runs, workers=workers, scheduler=scheduler, force=force,
                progress=sweep_counts(obj.quiet))
    obj.show(sweep_summary(res, out))




def entry() -> None:
    """The console script (``_console.run_main``: interrupts and closed pipes handled also outside the commands)."""
    run_main(main)
