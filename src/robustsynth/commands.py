"""The commands' jobs per plant kind: what build-model, synthesize, verify, run and margin do with a config, and
the lines they print, so that the CLI only parses options, calls one job and prints (issue 52: no plant branches
in the CLI).

A plant kind registers one :class:`Jobs` in :data:`JOBS` (the commands it offers, how its model is described, the
options it refuses; the five jobs are the base's, one implementation for every kind); :func:`jobs_for` picks it
from the config, :func:`require` refuses a command the kind does not offer (one line, exit 2).  A job takes a
:class:`Console` (where lines go, how progress shows) and returns an :class:`Outcome`: the exit code and the
result's data.  Options of another plant kind are refused before any work, by name.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Protocol

from .errors import EXIT_OK, EXIT_VERIFICATION_FAILED, InputError

__all__ = ["Console", "Outcome", "Jobs", "RobotJobs", "LinearJobs", "JOBS", "jobs_for", "require", "kind_of"]


class Console(Protocol):
    """Where a job's lines go (the CLI's context): ``say`` a line on stdout (not under --quiet), ``detail`` a step
    (stderr, under --verbose), ``show`` a summary (report.console lines; an Err on stderr), ``stages()`` the
    callable that prints a long command's stages, ``quiet``: whether progress bars stay hidden."""

    quiet: bool

    def say(self, msg: str) -> None: ...

    def detail(self, msg: str) -> None: ...

    def show(self, lines: list[str]) -> None: ...

    def stages(self) -> Callable[[str], None]: ...


@dataclass(frozen=True)
class Outcome:
    """A job's exit code and its result (``data``: what ``--json`` prints, where a command has it)."""

    code: int = EXIT_OK
    data: Any = None


def _refuse(**options: Any) -> None:
    """One line, exit 2, for the first option given (not None) that this plant kind does not take, with its reason."""
    for name, (value, why) in options.items():
        if value is not None:
            raise InputError(f"--{name.replace('_', '-')}: {why}")


class Jobs(ABC):
    """A plant kind's commands, one implementation for every kind: ``commands`` the ones it offers (the CLI refuses
    the others by name), ``model_summary`` how its model is described, and the hooks that refuse another kind's
    options (:meth:`refuse_synthesis`, :meth:`refuse_verify`, :meth:`refuse_run`) before any work."""

    kind = ""
    noun = ""  # what the plant is called in a message: "a linear plant"
    commands: frozenset[str] = frozenset()
    progress = True  # whether its verification reports the runs done (a progress bar)

    @staticmethod
    @abstractmethod
    def model_summary(name: str, out: Path, stage: Any) -> list[str]:
        """The lines that describe the kind's model (build-model)."""

    def refuse_synthesis(self, multiplier: str | None, diagnose: bool | None) -> None:
        """The synthesis options this kind does not take (one line, exit 2)."""

    def refuse_verify(self, logdir: Path | None) -> None:
        """The verification options this kind does not take."""

    def refuse_run(self, physics: int, export_to: str | None) -> None:
        """The run options this kind does not take."""

    def model(self, cfg: Any, out: Path, con: Console, config_path: Path | None) -> Outcome:
        """build-model: the model files and their summary."""
        from .pipeline import model_stage

        con.show(self.model_summary(cfg.name, out, model_stage(cfg, out, config_path)))
        return Outcome()

    def synthesize(self, cfg: Any, out: Path, con: Console, config_path: Path | None, *, objective: str | None,
                   solver: str | None, multiplier: str | None, diagnose: bool | None) -> Outcome:
        """synthesize: the certified gain (``multiplier``, ``diagnose``: the robot's options)."""
        from .pipeline import plant_of, synthesis_stage
        from .report import console

        self.refuse_synthesis(multiplier, diagnose)
        con.detail(f"building the model of '{cfg.name}'")
        st = synthesis_stage(plant_of(cfg, config_path), out, on_step=con.stages(), diagnose=diagnose,
                             objective=objective, solver=solver, multiplier=multiplier)
        con.show(console.synthesis_summary(out, st))
        return Outcome(data=st)

    def verify(self, cfg: Any, out: Path, con: Console, config_path: Path | None, *, gains: Path | None,
               runs: int | None, seed: int | None, fmt: str, plots: bool, logdir: Path | None) -> Outcome:
        """verify: the gain's checks; exit 1 when one fails (``logdir``: the robot's run logs)."""
        from .artifacts.files import writable_dir
        from .pipeline import plant_of, verification_stage, write_run_logs
        from .report import console
        from .report.progress import progress_bar

        self.refuse_verify(logdir)
        # the log place is proven writable before the work (a review found exit 2 at the end), and removed
        # again if the work fails before any log is in it
        with writable_dir(logdir) if logdir is not None else nullcontext():
            plant = plant_of(cfg, config_path)
            with progress_bar(con.quiet) if self.progress else nullcontext() as cb:
                st = verification_stage(plant, out, gains, runs, seed, fmt, plots, cb)
            con.show(console.verification_summary(out, st))
            if logdir is not None:
                con.say(console.logs_line(write_run_logs(st.model, st.result, logdir), logdir))
        return Outcome(EXIT_OK if st.result.passed else EXIT_VERIFICATION_FAILED, st)

    def run(self, cfg: Any, out: Path, con: Console, config_path: Path | None, *, objective: str | None,
            solver: str | None, multiplier: str | None, diagnose: bool | None, runs: int | None, seed: int | None,
            fmt: str, plots: bool, physics: int, export_to: str | None) -> Outcome:
        """run: synthesize and verify (``physics``: then the MuJoCo robot; ``export_to``: then the controller)."""
        from .pipeline import run, validation_stage
        from .report import console
        from .report.progress import Heartbeat, progress_bar

        self.refuse_synthesis(multiplier, diagnose)
        self.refuse_run(physics, export_to)
        stage = con.stages()  # the stages and each step of the synthesis (a heartbeat between them, on a terminal)
        with (progress_bar(con.quiet, stage if isinstance(stage, Heartbeat) else None) if self.progress
              else nullcontext()) as cb:
            res = run(cfg, out, runs, seed, fmt, plots, cb, on_stage=lambda s: stage(f"[{s}]"), on_step=stage,
                      diagnose=diagnose, config_path=config_path, objective=objective, solver=solver, multiplier=multiplier)
        con.show(console.run_summary(out, res))
        passed = res.passed
        if physics:
            con.say("[validate on the physics robot]")
            from .forked import cores

            # the episodes on the cores there are (each has its own random stream: the same results on any number)
            vd = validation_stage(res.verification.model, out / "gains.json", out / "validation", episodes=physics,
                                  plots=plots, workers=min(physics, cores()))
            con.say(console.physics_line(vd, physics))
            passed = passed and vd["passed"]
        _export_verified(out, con, export_to, res.passed)
        con.say(f"report: {out / 'report.md'}")
        return Outcome(EXIT_OK if passed else EXIT_VERIFICATION_FAILED, res)

    def margin(self, cfg: Any, out: Path, con: Console, config_path: Path | None, *, gains: Path | None,
               lyapunov: str | None, as_json: bool) -> Outcome:
        """margin: how far the delay (and slip) bounds can be pushed for the gain (``data``: margin.json)."""
        return _margin(cfg, out, con, config_path, gains, lyapunov, as_json)


class RobotJobs(Jobs):
    """The tracked robot: every command."""

    kind = "tracked-robot"
    noun = "the tracked robot"
    commands = frozenset({"build-model", "synthesize", "verify", "run", "margin", "identify", "check-log", "monitor",
                          "validate", "export", "sweep"})

    @staticmethod
    def model_summary(name: str, out: Path, stage: Any) -> list[str]:
        from .report.console import model_summary

        return model_summary(name, out, stage)

    def excite(self, cfg, out, con, config_path, *, episodes, seed, engine):
        """``validate --excite``: open-loop excitation episodes written as robot logs for ``identify``."""
        from .model import build_model
        from .pipeline import excitation_stage
        from .report import console

        paths = excitation_stage(build_model(cfg), out, episodes=episodes, seed=seed, engine=engine)
        physics = None
        if engine == "physics":  # which robot the engine drove (issue 50: the default chassis had been used silently)
            from .robot_verification.physics import physics_config

            physics = physics_config(cfg)[1]["summary"]
        con.show(console.excitation_summary(cfg, config_path, engine, out, len(paths), physics))
        return Outcome(data=paths)

    def validate(self, cfg, out, con, config_path, *, gains, episodes, seed, workers, engine, plots, inject):
        """``validate --gains``: the deployed law on the physics (or kinematic) robot; ``inject`` (kind, period,
        size) breaks one of the certificate's assumptions on purpose."""
        from .model import build_model
        from .pipeline import validation_stage
        from .report import console
        from .report.progress import progress_bar

        injection = None
        if inject is not None:
            from .robot_verification.physics import Injection

            injection = Injection(*inject)
        with progress_bar(con.quiet) as cb:
            vd = validation_stage(build_model(cfg), gains, out, episodes=episodes, seed=seed, progress=cb, plots=plots,
                                  workers=workers, engine=engine, inject=injection)
        con.show(console.validation_summary(vd, episodes, out, None if injection is None else injection.describe()))
        return Outcome(EXIT_OK if vd["passed"] else EXIT_VERIFICATION_FAILED, vd)


def _export_verified(out: Path, con: Console, target: str | None, verified: bool) -> None:
    """``run --export``: the gain ``run`` wrote and verified, exported into OUTDIR/export; a failed verification is
    not exported as a controller (issue 50; the exit code stays 1)."""
    if not target:
        return
    from .report import console
    from .runtime.export import export_controller

    # export_controller reads the verification.json this run wrote beside gains.json
    exported = export_controller(out / "gains.json", target, out / "export", None) if verified else None
    con.show(console.run_export_lines(target, out / "gains.json", exported))


class LinearJobs(Jobs):
    """A linear plant (``plant: kind: lti``): the generic law over the network (docs/tutorials/linear-plant.md)."""

    kind = "lti"
    noun = "a linear plant"
    commands = frozenset({"build-model", "synthesize", "verify", "run", "margin", "sweep", "export"})
    progress = False

    @staticmethod
    def model_summary(name: str, out: Path, stage: Any) -> list[str]:
        from .report.console import lti_model_summary

        return lti_model_summary(name, out, stage)

    def refuse_synthesis(self, multiplier: str | None, diagnose: bool | None) -> None:
        why = "a robot synthesis option, not available for a linear plant"
        _refuse(multiplier=(multiplier, why), diagnose=(diagnose, why))

    def refuse_verify(self, logdir: Path | None) -> None:
        _refuse(log=(logdir, "robot logs are for the tracked robot, not a linear plant"))

    def refuse_run(self, physics: int, export_to: str | None) -> None:
        from .runtime.linear_law import foreign_target

        why = foreign_target(export_to)  # the export command's refusal, said of run's option
        _refuse(physics=(physics or None, "the MuJoCo robot validates the tracked robot's gain, not a linear plant's"),
                export=(export_to if why else None, why))

    def margin(self, cfg, out, con, config_path, *, gains, lyapunov, as_json):
        _refuse(lyapunov=(lyapunov, "a linear plant's certificate is one common quadratic function"))
        return _margin(cfg, out, con, config_path, gains, lyapunov, as_json)


def _margin(cfg: Any, out: Path, con: Console, config_path: Path | None, gains: Path | None, lyapunov: str | None,
            as_json: bool) -> Outcome:
    """margin, any plant: the stage, then its lines (under --json only its warnings: stdout is the JSON)."""
    from .pipeline import margin_stage
    from .report import console

    st = margin_stage(cfg, out, gains, lyapunov, on_step=con.stages(), config_path=config_path)
    con.show(console.margin_summary(st, as_json))
    return Outcome(data=st.data)


JOBS: dict[str, Jobs] = {j.kind: j for j in (RobotJobs(), LinearJobs())}


def kind_of(cfg: Any) -> str:
    """The plant kind of a loaded config: ``lti`` for ``plant: kind: lti``, else the tracked robot."""
    from .config import plant_kind_of

    return plant_kind_of(cfg)


def jobs_for(cfg: Any) -> Jobs:
    return JOBS[kind_of(cfg)]


def require(cfg: Any, command: str) -> None:
    """Refuse ``command`` on a config whose plant kind does not offer it (one line naming the kind, exit 2)."""
    jobs = jobs_for(cfg)
    if command not in jobs.commands:
        order = [c for c in ("build-model", "synthesize", "verify", "run", "margin", "sweep", "export") if c in jobs.commands]
        raise InputError(f"plant.kind: {jobs.kind}: `robustsynth {command}` is not available for {jobs.noun} yet "
                         f"(available: {', '.join(order)})")
