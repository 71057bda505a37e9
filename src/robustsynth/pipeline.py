"""Stages that write files: build-model, synthesize, verify, and ``run`` chaining them.

Each stage is a function from frozen inputs to a frozen result; no printing, no click.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from .artifacts.files import SCHEMA_VERSION, remove_files, set_aside
from .artifacts.results_dir import RUN_FILES, SYNTHESIS_FILES, VERIFICATION_FILES, clear_foreign, figure_files
from .config import Config, plant_kind_of
from .model import Model, build_model, coverage_check
from .objectives import objective

__all__ = [
    "ModelStage",
    "model_stage",
    "SynthesisStage",
    "synthesis_stage",
    "VerificationStage",
    "verification_stage",
    "RunResult",
    "run",
    "default_outdir",
    "clear_foreign",
    "MarginStage",
    "margin_stage",
]

def default_outdir(config: Config) -> Path:
    return Path("results") / config.name


def plant_of(config: Any, config_path: str | Path | None = None) -> Any:
    """The plant a config describes, as the stages take it: the tracked robot's :class:`~robustsynth.model.Model`
    (:func:`~robustsynth.model.build_model`), or a linear plant's :class:`~robustsynth.plants.linear.LinearPlant`
    (``plant: kind: lti``; its ``plant.file`` read beside ``config_path``, default the working directory)."""
    return _RECORDS[plant_kind_of(config)].plant(config, config_path)


@dataclass(frozen=True)
class ModelStage:
    model: Any  # the plant: the robot's Model, or a LinearPlant
    coverage: dict[str, Any]
    files: tuple[Path, ...]
    cleared: tuple[str, ...] = ()  # files of another config removed from the output directory


def model_stage(config: Any, outdir: str | Path, config_path: str | Path | None = None) -> ModelStage:
    """Build the config's plant (:func:`plant_of`), check its vertex description's coverage, write model.json (and
    the robot's model.md)."""
    from .artifacts.files import commit_files, make_dir

    make_dir(outdir)  # an output place that cannot be made fails before any work
    plant = plant_of(config, config_path)
    cleared = clear_foreign(outdir, config)
    cov, files = _records(plant).model(plant)
    written = commit_files(outdir, files, primary="model.json")
    return ModelStage(plant, cov, tuple(written), tuple(cleared))


@dataclass(frozen=True)
class SynthesisStage:
    model: Any  # the robot's Model, or a LinearPlant
    result: Any  # robustsynth.synthesis.SynthesisResult
    gains: dict[str, Any]
    files: tuple[Path, ...]
    comparison: dict[str, Any] | None = None
    cleared: tuple[str, ...] = ()  # files of another config removed from the output directory
    diagnosis: list[Any] | None = None  # synthesis.diagnose.Relaxation, most effective first


def synthesis_stage(model: Any, outdir: str | Path, compare: bool = True,
                    on_step: Callable[[str], None] | None = None, diagnose: bool | None = None,
                    **overrides: Any) -> SynthesisStage:
    """Synthesize and certify a gain for any plant (``model``: the robot's Model or a LinearPlant); write
    gains.json (last), gains.mat, synthesis.md (the robot's: with the paper-vs-slip-aware comparison unless
    ``compare`` is False, and the diagnosis; a linear plant's: with the gain's delay margin).

    Files that depend on the gain (verification, report) are removed first.  When no certified
    gain is found, the old gain files are removed too, so nothing stale looks current."""
    from .errors import Interrupted, OutputError, RobustSynthError
    from .artifacts.files import commit_files, make_dir
    from .synthesis import synthesize

    records = _records(model)
    records.refuse(diagnose=diagnose, **overrides)
    outdir = make_dir(outdir)
    config = model.user_config
    cleared = clear_foreign(outdir, config)
    try:
        result = synthesize(model, on_step=on_step, **overrides)
    except RobustSynthError as exc:
        if outdir.is_dir() and not isinstance(exc, (Interrupted, OutputError)):
            set_aside(outdir, SYNTHESIS_FILES + VERIFICATION_FILES + RUN_FILES + figure_files(outdir),
                      f"synthesize found no certified gain for '{config.name}' as configured now (exit "
                      f"{getattr(exc, 'exit_code', '?')}); these are of the gain before")
        raise
    gd, files, cmp, diagnosis = records.synthesis(model, result, compare, diagnose, on_step, overrides)
    written = commit_files(outdir, files, primary="gains.json", invalidate=VERIFICATION_FILES + RUN_FILES + figure_files(outdir),
                           reason="they verified and reported the gain that synthesize replaced")
    return SynthesisStage(model, result, gd, tuple(written), cmp, tuple(cleared), diagnosis)


ProgressFn = Callable[[int, int], None]


@dataclass(frozen=True)
class VerificationStage:
    model: Any  # the robot's Model, or a LinearPlant
    result: Any  # robustsynth.robot_verification.VerificationResult (a linear plant's: results.Verdict)
    data: dict[str, Any]
    figures: dict[str, Path]
    files: tuple[Path, ...]


def verification_stage(
    model: Any,
    outdir: str | Path,
    gains_path: str | Path | None = None,
    runs: int | None = None,
    seed: int | None = None,
    fmt: str = "png",
    plots: bool = True,
    progress: ProgressFn | None = None,
) -> VerificationStage:
    """Verify a gains file (default ``outdir/gains.json``) on any plant (``model``: the robot's Model or a
    LinearPlant); write figures, verification.md and verification.json (last).  The run's report and summary are
    removed first; the output directory is made once the inputs are checked (a refusal leaves none behind)."""
    from .artifacts.files import commit_files, json_bytes, make_dir
    from .artifacts.gains import load_gains

    records = _records(model)
    gp = Path(gains_path) if gains_path is not None else Path(outdir) / "gains.json"
    gains = load_gains(gp)
    res, searched = records.verify(model, gains, gp, runs, seed, progress)
    outdir = make_dir(outdir)
    remove_files(outdir, ("verification.json",))
    set_aside(outdir, RUN_FILES, "they reported the verification that verify replaced")
    figures: dict[str, Path] = records.figures(res, model, outdir, fmt) if plots else {}
    # an earlier verification's figures (another gain, format, or before --no-plots) would read as this one's (review)
    rel = {k: str(v.relative_to(outdir)) for k, v in figures.items()}
    set_aside(outdir, tuple(n for n in figure_files(outdir) if n not in rel.values()),
              "they were figures of an earlier verification (another gain, format, or before --no-plots)")
    vd = records.verification_record(model, res, gp, outdir, gains, searched)
    files = {
        "verification.md": records.verification_markdown(model, res, vd, rel).encode("utf-8"),
        "verification.json": json_bytes(vd),
    }
    written = commit_files(outdir, files, primary="verification.json", invalidate=RUN_FILES)
    return VerificationStage(model, res, vd, figures, tuple(list(figures.values()) + written))


def validation_stage(model: Model, gains_path: str | Path, outdir: str | Path, episodes: int = 4, seed: int = 0,
                     progress: ProgressFn | None = None, plots: bool = True, workers: int = 1,
                     engine: str = "physics", inject: Any = None) -> dict[str, Any]:
    """``robustsynth validate``: the deployed law on the physics robot (:mod:`.robot_verification.physics`);
    writes the episodes as robot logs under ``outdir/logs/`` and ``validation.json`` (last).  ``inject``: a
    violation of one of the certificate's assumptions in every episode (:class:`.robot_verification.physics.Injection`)."""
    import numpy as np

    from .artifacts.files import commit_files, json_bytes, make_dir
    from .artifacts.gains import gains_id, load_gains
    from .certificate import recheck_gains
    from .errors import InputError
    from .robot_verification.physics import validate_physics

    if engine == "physics":
        _require_physics()
    gains = load_gains(gains_path)
    if gains.get("kind") == "lti":
        raise InputError(f"{gains_path}: a linear plant's gains (kind: lti); validate runs the tracked robot")
    K = np.atleast_2d(np.asarray(gains["K"], dtype=float))  # a list (gains.json) or an array (gains.mat)
    size = K.shape if K.size else (0, 0)
    if size != (model.n_u, model.n_s):  # no law to run (a traceback before)
        raise InputError(f"{gains_path}: K has {size[0]} x {size[1]} entries; this config's controller "
                         f"needs {model.n_u} x {model.n_s} (d_hi = {model.d_hi})")
    if inject is not None:
        inject.check(model, engine)
    outdir = make_dir(outdir)  # after the inputs are checked: a refusal leaves no directory behind
    rechecked = recheck_gains(model, gains)
    # the bounds the episodes are judged against: the certificate's own, re-checked for this config (a
    # gains file's "certified" figures are what it says, not what holds: an edited K or another config's
    # gain would pass against them)
    gains = dict(gains, certified={"ultimate_bound": rechecked.figures.get("ultimate_bound"),
                                   "ultimate_bound_between_samples": rechecked.figures.get("ultimate_bound_between_samples"),
                                   "turns": (gains.get("certificate") or {}).get("turns")} if rechecked.passed else {})
    res = validate_physics(model, gains, episodes=episodes, seed=seed, progress=progress if workers == 1 else None,
                           workers=workers, engine=engine, inject=inject)
    _write_logs(res["logs"], outdir / "logs")
    vd = dict(res["validation"], gains_id=gains_id(gains), config=model.config.name)
    # the slip the certificate has to cover: on the straight segments it certifies; the turns' (ICR
    # effects: the per-track factors grow with the turn rate) reported beside it
    vd["slip"] = _observed_slip(model, _pieces(res["logs"], res["straight"]))
    vd["slip"]["where"] = "straight segments (the steps the certificate covers)"
    vd["slip_whole_episodes"] = _observed_slip(model, res["logs"])
    vd["certificate"] = {"passed": rechecked.passed,
                         "detail": "re-checked in numpy for this config" if rechecked.passed else rechecked.reason,
                         # what the bounds are a claim about (review: a paper-model gain was said to be covered)
                         "model": (gains.get("certificate") or {}).get("model"),
                         "error_bounds": bool(rechecked.passed and rechecked.figures.get("ultimate_bound"))}
    vd["passed"] = bool(vd["passed"] and vd["slip"].get("inside_box", True) and rechecked.passed)
    if plots:
        from .report.plots import validation_figure

        res["validation"]["passed"] = vd["passed"]
        validation_figure(res, model.config.reference.path, outdir / "validation.png")
        vd["figure"] = "validation.png"
    elif (outdir / "validation.png").exists():  # an earlier run's figure would read as this one's (review)
        remove_files(outdir, ("validation.png",))
    commit_files(outdir, {"validation.json": json_bytes(vd)}, primary="validation.json")
    return vd


def excitation_stage(model: Model, outdir: str | Path, episodes: int = 4, seed: int = 0,
                     engine: str = "physics") -> list[Path]:
    """``robustsynth validate --excite``: open-loop excitation of the robot (turns at several rates,
    speed changes; :func:`.robot_verification.physics.excite`) written as robot logs under
    ``outdir/logs/`` for ``identify``; ``engine='kinematic'``: the model's own robot, no MuJoCo."""
    from .robot_verification.physics import excite

    if engine == "physics":
        _require_physics()
    return _write_logs(excite(model, episodes=episodes, seed=seed, engine=engine), Path(outdir) / "logs")


def _pieces(logs: list, keep: Any) -> list:
    """The contiguous runs of kept rows of each log as logs of their own (at least 3 rows)."""
    import dataclasses

    import numpy as np

    out = []
    for log, k in zip(logs, keep):
        k = np.asarray(k, dtype=bool)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], k.astype(int), [0]])))
        for a, b in zip(edges[::2], edges[1::2]):
            if b - a >= 3:
                out.append(dataclasses.replace(log, path=f"{log.path}[{a}:{b}]", **{
                    f: getattr(log, f)[a:b] for f in ("t", "x", "y", "theta", "seq", "rho_r", "rho_l", "sent", "applied")},
                    estimate=None if log.estimate is None else log.estimate[a:b]))
    return out


def _observed_slip(model: Model, logs: list) -> dict[str, Any]:
    """The slip box ``identify`` estimates from the validation's episodes, and whether the config's box
    holds it (a certificate for a box the physics leaves does not apply to that robot)."""
    from .errors import InputError
    from .identification import identify

    cfg = model.user_config
    if cfg.slip.model == "icr":  # closed-loop episodes turn little: the icr fit needs excitation (and a noise model)
        return {"estimated": None, "reason": "slip.model icr: the closed-loop episodes say little about the yaw factor "
                "and x_icr; run validate --excite and identify --model icr on its logs"}
    try:
        ident = identify(logs, cfg.robot.gear_radius, cfg.robot.track_distance, max_motor_speed=cfg.robot.max_motor_speed)
    except InputError as exc:
        return {"estimated": None, "reason": str(exc)}
    box = {k: [float(a), float(b)] for k, (a, b) in ident.box.items()}
    conf = {"right": (cfg.slip.right.min, cfg.slip.right.max), "left": (cfg.slip.left.min, cfg.slip.left.max)}
    inside = all(conf[s][0] <= box[s][0] and box[s][1] <= conf[s][1] for s in box)
    return {"estimated": box, "config": {k: list(v) for k, v in conf.items()}, "inside_box": bool(inside),
            "periods": int(ident.slip.mu.shape[0])}


def write_run_logs(model: Model, result: Any, logdir: str | Path) -> list[Path]:
    """The verification's Monte Carlo runs as robot logs (one CSV per run, the format `identify` and
    `check-log` read) in ``logdir``; for a slip-compensated law, its runs with the estimator in the loop on the true
    slip (with the estimate's columns)."""
    from .robot_verification.simulate import run_logs

    if result.compensated is not None:  # a slip-compensated law: the runs of the law as deployed, on the true slip
        return _write_logs(result.compensated.logs(), logdir)
    return _write_logs(run_logs(model, result.sim, result.scenario), logdir)


def _write_logs(logs: list, logdir: str | Path) -> list[Path]:
    """Robot logs as CSV files in ``logdir`` (created), each under its own name.  Logs an earlier run left
    under the same naming (``episode_NNN.csv``, ``excite_NNN.csv``, ``run_NNN.csv``) that this one does not
    write are removed first: identify read them with the new ones (review); other files stay."""
    import re

    from .artifacts.files import make_dir
    from .artifacts.logs import write_log

    logdir = make_dir(logdir)
    names = {log.path for log in logs}
    numbered = re.compile(r"(.+)_\d{3,}\.csv")
    prefixes = {m.group(1) for m in map(numbered.fullmatch, names) if m}
    stale = [p.name for p in sorted(logdir.iterdir()) if p.is_file() and p.name not in names
             and (m := numbered.fullmatch(p.name)) and m.group(1) in prefixes]
    remove_files(logdir, tuple(stale))
    paths = []
    for log in logs:
        write_log(logdir / log.path, log)
        paths.append(logdir / log.path)
    return paths


def _require_physics() -> None:
    """InputError (exit 2) naming how to install MuJoCo when it cannot be imported."""
    from .errors import InputError
    from .plants.physics import available

    why = available()
    if why:
        raise InputError(f"validate: {why}")


def identification_stage(log_paths: list[Path], cfg: Any, out: Path | None, coverage: float, model: str,
                         max_motor_speed: float | None, plots: bool = True,
                         pose_noise: tuple[float, float] | None = None, settle: float = 0.0) -> tuple[Any, str, list[Path]]:
    """`robustsynth identify`: the identification, its config fragment, and (with ``out``) the files
    written: the fragment, ``<stem>.md`` (the data behind it) and ``<stem>.png`` (histograms).  The icr
    model's pose noise defaults to the config's ``verification.noise``."""
    from .artifacts.files import atomic_write, make_dir
    from .artifacts.logs import read_log
    from .identification import fragment_yaml, identify, report_markdown

    logs = [read_log(p) for p in log_paths]
    if model == "icr" and pose_noise is None:
        from .identification import config_pose_noise

        pose_noise = config_pose_noise(cfg)
    ident = identify(logs, cfg.robot.gear_radius, cfg.robot.track_distance, coverage, model, max_motor_speed, pose_noise,
                     settle)
    text = fragment_yaml(ident)
    written: list[Path] = []
    if out is not None:
        make_dir(out.parent)
        fig = None
        if plots:
            from .report.plots import identification_figure

            fig = identification_figure(ident, out.with_suffix(".png"))
            written.append(fig)
        md = out.with_suffix(".md")
        atomic_write(md, report_markdown(ident, text, fig.name if fig else None).encode("utf-8"))
        written.append(md)
        atomic_write(out, text.encode("utf-8"))  # last: a fragment exists only with its report
        written.append(out)
    return ident, text, written


@dataclass(frozen=True)
class RunResult:
    model: ModelStage
    synthesis: SynthesisStage
    verification: VerificationStage
    files: tuple[Path, ...]

    @property
    def passed(self) -> bool:
        return bool(self.verification.result.passed)


def run(
    config: Config,
    outdir: str | Path | None = None,
    runs: int | None = None,
    seed: int | None = None,
    fmt: str = "png",
    plots: bool = True,
    progress: ProgressFn | None = None,
    on_stage: Callable[[str], None] | None = None,
    compare: bool = True,
    on_step: Callable[[str], None] | None = None,
    diagnose: bool | None = None,
    config_path: str | Path | None = None,
    **synthesis_overrides: Any,
) -> RunResult:
    """build-model -> synthesize -> verify, then report.md and summary.json; any plant's config.

    When synthesis finds no gain, summary.json records the status ('infeasible' or
    'solver-failure') and the error is raised again.  ``synthesis_overrides`` (objective, solver,
    multiplier) replace the config's synthesis settings.  A linear plant's config (``plant: kind: lti``) runs the
    same stages (no comparison; the robot's ``diagnose``, ``multiplier`` and ``progress`` refused), its
    verification's result a :class:`~robustsynth.results.Verdict`.

    Parameters
    ----------
    config : Config
        The scenario.
    outdir : str, Path or None
        Output directory (default ``results/<name>/``).
    runs, seed : int or None
        Monte Carlo runs and their seed (default: the config's).
    fmt : str
        Figure format: ``png``, ``pdf`` or ``svg``.
    plots : bool
        Draw the figures.
    progress : callable or None
        Called with (runs done, runs in all) during verification.
    on_stage : callable or None
        Called with each stage's name as it starts.
    compare : bool
        Add the paper-model comparison to the synthesis report.
    on_step : callable or None
        Receives one line per solve.
    diagnose : bool or None
        Re-solve with each constraint relaxed (None: when the certified |e_y| exceeds half the track
        distance).
    config_path : str, Path or None
        The config's file: a linear plant's ``plant.file`` is read beside it (default: the working directory).
    **synthesis_overrides : Any
        ``objective``, ``solver``, ``multiplier``.

    Returns
    -------
    RunResult
        The model, synthesis and verification stages and the files written; ``passed`` is the verdict.
    """
    from .errors import InfeasibleError, Interrupted, OutputError, RobustSynthError, check_interrupt
    from .artifacts.files import atomic_write, commit_files, json_bytes

    outdir = Path(outdir) if outdir is not None else default_outdir(config)

    def say(stage: str) -> None:
        check_interrupt()
        if on_stage is not None:
            on_stage(stage)

    records = _RECORDS[plant_kind_of(config)]
    records.refuse(diagnose=diagnose, progress=progress, **synthesis_overrides)  # before any work
    say("build-model")
    ms = model_stage(config, outdir, config_path)
    say("synthesize")
    try:
        ss = synthesis_stage(ms.model, outdir, compare=compare, on_step=on_step, diagnose=diagnose, **synthesis_overrides)
    except RobustSynthError as exc:
        if isinstance(exc, (Interrupted, OutputError)):
            raise
        status = "infeasible" if isinstance(exc, InfeasibleError) else "solver-failure"
        atomic_write(outdir / "summary.json", json_bytes(records.failed_summary(ms.model, status, str(exc))))
        raise
    say("verify")
    vs = verification_stage(ms.model, outdir, runs=runs, seed=seed, fmt=fmt, plots=plots, progress=progress)
    files = records.run_files(ms, ss, vs, outdir, runs, seed, compare, say)
    written = commit_files(outdir, files, primary="summary.json")
    return RunResult(ms, ss, vs, tuple(ms.files + ss.files + vs.files + tuple(written)))


class _RobotRecords:
    """What the tracked robot's stages write: model.json and model.md, the gains with the paper-model comparison and
    the diagnosis, the verification's figures and records, the run's report with the comparison of both models."""

    @staticmethod
    def refuse(**_options: Any) -> None:
        """Every stage option is the robot's."""

    @staticmethod
    def plant(config: Any, config_path: str | Path | None) -> Model:
        return build_model(config)

    @staticmethod
    def margin_gain(config: Any, outdir: Path, gains_path: str | Path | None, config_path: str | Path | None
                    ) -> tuple[Any, Any, Path | None, dict[str, Any] | None]:
        """The config (margin() builds the robot's model per delay and slip range) and its gains file's K."""
        import numpy as np

        from .artifacts.gains import load_gains

        gp = Path(gains_path) if gains_path is not None else outdir / "gains.json"
        gains = load_gains(gp)
        return config, np.asarray(gains["K"], dtype=float), gp, gains

    @staticmethod
    def margin_meta(gains: dict[str, Any]) -> tuple[dict[str, Any], tuple[str, ...]]:
        """The kinematics the gain's own certificate is for (None: no certificate), and what the margins do not say
        of a certificate for the nonlinear robot."""
        cert = gains.get("certificate")
        kin = cert.get("kinematics", "linearized") if cert else None
        notes = (("note: the margins are robust stability of the linearization; the gain's certificate for the "
                  "nonlinear robot (synthesis.kinematics: nonlinear) holds for the configured delay and slip ranges "
                  "only",) if kin == "nonlinear" else ())
        return {"gains_kinematics": kin}, notes

    @staticmethod
    def model(model: Model) -> tuple[dict[str, Any], dict[str, bytes]]:
        from .artifacts.files import json_bytes
        from .report.model import model_dict, model_markdown

        cov = coverage_check(model)
        return cov, {"model.md": model_markdown(model, cov).encode("utf-8"), "model.json": json_bytes(model_dict(model, cov))}

    @staticmethod
    def synthesis(model: Model, result: Any, compare: bool, diagnose: bool | None, on_step: Callable[[str], None] | None,
                  overrides: dict[str, Any]) -> tuple[dict[str, Any], dict[str, bytes], Any, Any]:
        from .artifacts.files import json_bytes, mat_bytes
        from .artifacts.gains import gains_dict, gains_mat_vars
        from .report.synthesis import synthesis_markdown
        from .synthesis.diagnose import diagnose as run_diagnosis
        from .synthesis.diagnose import is_large

        gd = gains_dict(model, result)
        diagnosis = None
        if objective(result.objective).figure == "ultimate_bound" and (diagnose or (diagnose is None and is_large(model.config, result.certified))):
            if on_step is not None:
                on_step("where is the design stuck? one synthesis per relaxed constraint")
            diagnosis = run_diagnosis(model, result.certified, motor=bool(result.certificate.get("motor_limits_enforced")),
                                      on_step=on_step, **{k: v for k, v in overrides.items() if v is not None})
        cmp = None
        if compare:
            from .comparison import compare_models

            cmp = compare_models(model, gd)
        files = {
            "gains.mat": mat_bytes(gains_mat_vars(gd)),
            "synthesis.md": synthesis_markdown(model, result, gd, cmp, diagnosis).encode("utf-8"),
            "gains.json": json_bytes(gd),
        }
        return gd, files, cmp, diagnosis

    @staticmethod
    def verify(model: Model, gains: dict[str, Any], gp: Path, runs: int | None, seed: int | None,
               progress: ProgressFn | None) -> tuple[Any, None]:
        from .verification import verify

        return verify(model, gains, runs=runs, seed=seed, progress=progress), None

    @staticmethod
    def figures(res: Any, model: Model, outdir: Path, fmt: str) -> dict[str, Path]:
        from .report.plots import write_figures

        return write_figures(res, model, outdir, fmt)

    @staticmethod
    def verification_record(model: Model, res: Any, gp: Path, outdir: Path, gains: dict[str, Any], _searched: None
                            ) -> dict[str, Any]:
        from .artifacts.gains import gains_id
        from .report.verification import verification_dict

        try:  # a path relative to OUTDIR keeps verification.json identical across output directories
            shown = str(gp.resolve().relative_to(outdir.resolve()))
        except ValueError:
            shown = str(gp)
        return verification_dict(model, res, shown, gains_id(gains))

    @staticmethod
    def verification_markdown(model: Model, res: Any, vd: dict[str, Any], rel: dict[str, str]) -> str:
        from .report.verification import verification_markdown

        return verification_markdown(model, res, vd, rel)

    @staticmethod
    def failed_summary(model: Model, status: str, message: str) -> dict[str, Any]:
        from .report.verification import summary_dict

        return dict(summary_dict(model, None, None, status), message=message)

    @staticmethod
    def run_files(ms: ModelStage, ss: SynthesisStage, vs: VerificationStage, outdir: Path, runs: int | None,
                  seed: int | None, compare: bool, say: Callable[[str], None]) -> dict[str, bytes]:
        from .artifacts.files import json_bytes
        from .report.verification import report_markdown, summary_dict

        rel = {k: str(v.relative_to(outdir)) for k, v in vs.figures.items()}
        cmp = None
        if compare and ss.comparison:
            from .comparison import compare_models

            say("compare")
            other = next((r.get("gains") for r in ss.comparison["rows"] if r["model"] != ms.model.kind), None)
            cmp = compare_models(ms.model, ss.gains, vs.data, runs, seed, other_gains=other)
        return {"report.md": report_markdown(ms.model, ss.gains, vs.data, rel, cmp).encode("utf-8"),
                "summary.json": json_bytes(summary_dict(ms.model, ss.gains, vs.data, "certified"))}


class _LinearRecords:
    """What a linear plant's stages write (docs/theory.md §14-15): model.json with the over-approximation and its
    coverage, the gains with their delay margin, the verification of the exactly lifted loop and its figure, the
    run's report (the synthesis' and the verification's) and summary."""

    @staticmethod
    def refuse(diagnose: bool | None = None, progress: Any = None, **overrides: Any) -> None:
        """InputError for an option of the tracked robot's (``diagnose``, ``progress``, a synthesis setting other
        than ``objective`` and ``solver``)."""
        from .errors import InputError

        robot = {"diagnose": diagnose or None, "progress": progress,
                 **{k: v for k, v in overrides.items() if k not in ("objective", "solver")}}
        for name, value in robot.items():
            if value is not None:
                raise InputError(f"{name}: a tracked robot's option (of run, synthesize and verify), not a linear plant's")

    @staticmethod
    def plant(config: Any, config_path: str | Path | None) -> Any:
        from .plants.linear import LinearPlant

        return LinearPlant.from_config(config, str(Path(config_path).parent) if config_path is not None else None)

    @staticmethod
    def margin_gain(config: Any, outdir: Path, gains_path: str | Path | None, config_path: str | Path | None
                    ) -> tuple[Any, Any, Path | None, dict[str, Any] | None]:
        """The plant and its gain (:func:`robustsynth.artifacts.gains.lti_gain`: a gains file, else
        controller.gain, else outdir/gains.json)."""
        from .artifacts.gains import lti_gain

        plant = _LinearRecords.plant(config, config_path)
        K, source, gd = lti_gain(config, plant.arrays, gains_path, outdir / "gains.json")
        return plant, K, source, gd

    @staticmethod
    def margin_meta(gains: dict[str, Any] | None) -> tuple[dict[str, Any], tuple[str, ...]]:
        return {}, ()

    @staticmethod
    def model(plant: Any) -> tuple[dict[str, Any], dict[str, bytes]]:
        """The lifted model and its guaranteed over-approximation (open loop, K = 0), with the coverage test on
        10 000 random instants."""
        from .artifacts.files import json_bytes, record_header

        pw = plant.description()
        cov = plant.coverage_figures(pw)
        data = {**record_header(), "kind": "lti", "config": plant.name, "n": plant.n_x, "m": plant.n_u, "lifting": plant.d_hi,
                "lifted_states": plant.n_s, "controllable": plant.arrays["controllable"], "pieces": plant.pieces,
                "instants": [{"theta": th.tolist(), "width": w.tolist(), "remainder_bound": r.tolist(),
                              "directions": U.tolist(), "direction_bounds": rd.tolist()}
                             for th, w, r, U, rd in zip(pw.theta, pw.width, pw.rho, pw.dirs, pw.rho_dir)],
                "coverage": cov, "A": plant.A, "B": plant.B}
        return cov, {"model.json": json_bytes(data)}

    @staticmethod
    def synthesis(plant: Any, result: Any, compare: bool, diagnose: bool | None, on_step: Callable[[str], None] | None,
                  overrides: dict[str, Any]) -> tuple[dict[str, Any], dict[str, bytes], None, None]:
        """The gain's files, with its delay margin (:func:`robustsynth.margins.linear.delay_margin`: certified /
        exhibited, seconds beside the synthesis) in gains.json and synthesis.md."""
        import numpy as np

        from .artifacts.files import json_bytes, mat_bytes
        from .artifacts.gains import lti_gains_dict, lti_gains_mat_vars
        from .margins.linear import delay_margin
        from .report.synthesis import lti_synthesis_markdown

        config = plant.config
        margin = delay_margin(plant.network, plant.margin_settings, dict(plant.arrays, K=np.asarray(result.K, dtype=float)),
                              on_step or (lambda _s: None))
        over = {}  # review, stop 47: nothing in the file said that --objective / --solver were used
        if overrides.get("objective") is not None and overrides["objective"] != config.objective:
            over["synthesis.objective"] = overrides["objective"]
        if overrides.get("solver") is not None and overrides["solver"] != config.synthesis.solver:
            over["synthesis.solver"] = overrides["solver"]
        gd = lti_gains_dict(config, plant.arrays, result, over, margin)
        return gd, {"gains.mat": mat_bytes(lti_gains_mat_vars(gd)),
                    "synthesis.md": lti_synthesis_markdown(gd).encode("utf-8"), "gains.json": json_bytes(gd)}, None, None

    @staticmethod
    def verify(plant: Any, gains: dict[str, Any], gp: Path, runs: int | None, seed: int | None,
               progress: ProgressFn | None) -> tuple[Any, dict[str, Any] | None]:
        """The certified gain's claims on the exactly lifted loop (:func:`robustsynth.verification.lti.verify_plant`,
        the gains file's problems naming it); a gain that came without a certificate (K only) gets one searched
        first (:func:`_searched_certificate`)."""
        from .verification.lti import verify_plant

        _LinearRecords.refuse(progress=progress)
        searched = None
        if gains.get("certificate") is None and gains.get("kind") is None:
            gains, searched = _searched_certificate(plant, gains, gp)
        return verify_plant(plant, gains, runs, seed, where=str(gp)), searched

    @staticmethod
    def figures(res: Any, plant: Any, outdir: Path, fmt: str) -> dict[str, Path]:
        from .report.plots import lti_verification_figure

        return {"verification": lti_verification_figure(res.to_dict(), outdir / f"verification.{fmt}")}

    @staticmethod
    def verification_record(plant: Any, res: Any, gp: Path, outdir: Path, gains: dict[str, Any],
                            searched: dict[str, Any] | None) -> dict[str, Any]:
        from .artifacts.files import record_header
        from .artifacts.gains import gains_id

        return {**record_header(), **res.to_dict(), "gains": str(gp), "gains_id": gains_id(gains),
                "certificate_searched": searched}

    @staticmethod
    def verification_markdown(plant: Any, res: Any, vd: dict[str, Any], rel: dict[str, str]) -> str:
        from .report.verification import lti_verification_markdown

        return lti_verification_markdown(vd)

    @staticmethod
    def failed_summary(plant: Any, status: str, message: str) -> dict[str, Any]:
        return {"schema_version": SCHEMA_VERSION, "config": plant.name, "kind": "lti", "status": status, "message": message}

    @staticmethod
    def run_files(ms: ModelStage, ss: SynthesisStage, vs: VerificationStage, outdir: Path, runs: int | None,
                  seed: int | None, compare: bool, say: Callable[[str], None]) -> dict[str, bytes]:
        from .artifacts.files import json_bytes
        from .report.synthesis import lti_synthesis_markdown
        from .report.verification import lti_verification_markdown

        summary = {"schema_version": SCHEMA_VERSION, "config": ms.model.name, "kind": "lti",
                   "certified": ss.gains["certified"], "verification": {"passed": vs.data["passed"], "checks": vs.data["checks"]}}
        return {"report.md": (lti_synthesis_markdown(ss.gains) + "\n" + lti_verification_markdown(vs.data)).encode("utf-8"),
                "summary.json": json_bytes(summary)}


def _searched_certificate(plant: Any, gains: dict[str, Any], gp: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """A certificate for a linear plant's gain that came without one (a hand-tuned K): the analysis LMIs of
    ``robustsynth margin`` (:func:`robustsynth.margins.linear.lti_certificate`: a common quadratic function, V
    shrinking by DECAY per period for every delay and loss pattern, margin.pieces), proven in numpy.  Returns the
    gains mapping with it (K padded to the lifting) and what was searched; InfeasibleError (exit 3) when there is
    none."""
    from .errors import InfeasibleError
    from .margins.linear import lti_certificate
    from .synthesis.lti import DECAY
    from .verification.lti import checked_gain

    K = checked_gain(plant, gains, str(gp))
    net = plant.network
    an, K, pieces = lti_certificate(dict(plant.arrays, K=K), net.sampling_time, net.delay_min, net.delay_max,
                                    net.max_lost, int(plant.margin_settings.pieces))
    if not an.certified:
        raise InfeasibleError(f"{gp}: no certificate found for this gain on this network (a common quadratic "
                              f"Lyapunov function, {pieces} pieces per switching instant: {an.status}); "
                              "`robustsynth margin` shows how far the gain is from one")
    certified = {"kind": "lti", "K": K, "certified": {"alpha": DECAY**2, "decay": DECAY},
                 "certificate": {"P": an.P, "multipliers": an.certificate["multipliers"], "pieces": pieces}}
    return certified, {"kind": "common quadratic Lyapunov function, every delay and loss pattern", "pieces": pieces,
                       "decay": DECAY}


_RECORDS = {"tracked-robot": _RobotRecords, "lti": _LinearRecords}  # plant_kind -> what its stages write


def _records(plant: Any) -> Any:
    return _RECORDS[plant.plant_kind]


@dataclass(frozen=True)
class MarginStage:
    report: Any  # robustsynth.margin.MarginReport
    data: dict[str, Any]
    files: tuple[Path, ...]


def margin_stage(config: Any, outdir: str | Path, gains_path: str | Path | None = None,
                 lyapunov: str | None = None, on_step: Callable[[str], None] | None = None,
                 config_path: str | Path | None = None) -> MarginStage:
    """The margins of a gain on the config's plant (:func:`robustsynth.margins.margin`): the gain of a gains
    file, by default ``outdir/gains.json`` (a linear plant's config's ``controller.gain`` comes before that
    default); writes margin.json (:meth:`~robustsynth.margins.MarginReport.to_dict` with the gain's source) and
    margin.md.  ``config_path``: where a linear plant's ``plant.file`` is read from."""
    from dataclasses import replace

    from .artifacts.files import commit_files, json_bytes, make_dir
    from .artifacts.gains import gains_id
    from .margins import margin
    from .report.markdown import margin_markdown

    outdir = make_dir(outdir)
    records = _RECORDS[plant_kind_of(config)]
    plant, K, gp, gains = records.margin_gain(config, outdir, gains_path, config_path)
    rep = margin(plant, K, lyapunov=lyapunov, on_step=on_step)
    meta = {"gains": None if gp is None else str(gp), "gains_id": None if gains is None else gains_id(gains),
            "config": config.name}
    more, notes = records.margin_meta(gains)
    rep = replace(rep, notes=rep.notes + notes, meta={**rep.meta, **meta, **more})
    data = rep.to_dict()
    written = commit_files(outdir, {"margin.json": json_bytes(data), "margin.md": margin_markdown(data).encode("utf-8")},
                           primary="margin.json")
    return MarginStage(rep, data, tuple(written))
