"""The console's summaries: the lines each command prints about its results, made from the result mappings
and stage records, as plain text (the CLI prints them in order; nothing here prints or knows the CLI).

A line for stderr (a warning, a failed check: shown also under --quiet) is an :class:`Err`; every other line
goes to stdout."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from ..artifacts.certified import certified_lines
from ..monitor import CAUSES
from ..results import Err

__all__ = ["Err", "wrote", "cleared", "model_summary", "lti_model_summary", "synthesis_summary", "verification_summary",
           "run_summary", "logs_line", "physics_line", "run_export_lines", "margin_summary", "check_log_summary",
           "violated", "monitor_summary", "excitation_summary", "validation_summary", "export_summary", "sweep_summary",
           "identified_line"]


def wrote(files: Iterable[Any]) -> str:
    return f"wrote {', '.join(str(p) for p in files)}"


def cleared(out: Path, names: Sequence[str]) -> list[str]:
    """The files of another config a stage set aside (artifacts.results_dir.clear_foreign: moved, not deleted)."""
    if not names:
        return []
    where = Path(names[0]).parts[:2]
    listed = ", ".join(str(Path(*Path(c).parts[2:])) for c in names)
    return [f"set aside {len(names)} file(s) another config had left in {out}, under {out / Path(*where)}/ "
            f"(nothing deleted): {listed}"]


def _uncontrollable(controllable: bool) -> list[str]:
    from ..model.lti import UNCONTROLLABLE_WARNING

    return [] if controllable else [Err(UNCONTROLLABLE_WARNING)]


# -- build-model ---------------------------------------------------------------------------------------------------

def model_summary(name: str, out: Path, stage: Any) -> list[str]:
    """The robot's lifted model (a pipeline.ModelStage): its sizes and the coverage check."""
    m, cov = stage.model, stage.coverage
    return cleared(out, stage.cleared) + [
        f"model '{name}': d_lo={m.d_lo} d_hi={m.d_hi} n_s={m.n_s} uncertain instants={len(m.instants)} "
        f"coverage={'ok' if cov['passed'] else 'FAILED'} "
        f"(max|Delta|={cov['max_abs_delta']:.4f}, residual={cov['max_residual']:.1e})",
        wrote(stage.files)]


def lti_model_summary(name: str, out: Path, stage: Any) -> list[str]:
    """A linear plant's lifted model (a pipeline.ModelStage): its sizes and the coverage check."""
    p, cov = stage.model, stage.coverage
    return cleared(out, stage.cleared) + [
        f"model '{name}' (linear plant): n={p.n_x} m={p.n_u} d_hi={p.d_hi} n_s={p.n_s} pieces={p.pieces} "
        f"coverage={'ok' if cov['remainder_ratio'] <= 1 else 'FAILED'} "
        f"(worst remainder / bound {cov['remainder_ratio']:.3f} on {int(cov['samples'])} instants, residual "
        f"{cov['reconstruction']:.1e})"] + _uncontrollable(p.arrays["controllable"]) + [wrote(stage.files)]


# -- synthesize ----------------------------------------------------------------------------------------------------

def _diagnosis(diagnosis: Sequence[Any] | None) -> list[str]:
    """Where the design is stuck, one line per relaxed constraint, the most effective first."""
    if not diagnosis:
        return []
    return ["where the design is stuck (one re-synthesis per relaxed constraint; see synthesis.md):"] + [
        f"  {r.constraint}: " + (f"|e_y| <= {100 * r.e_y:.2f} cm ({100 * r.change:+.0f} %)"
                                 if r.e_y is not None and r.change is not None else r.status) for r in diagnosis]


def synthesis_summary(out: Path, stage: Any) -> list[str]:
    """A synthesis, any plant (a pipeline.SynthesisStage): the certified figures (a linear plant's with its delay
    margin), the notes, the diagnosis (the robot's), the files."""
    return (cleared(out, stage.cleared) + certified_lines(stage.gains)
            + [f"note: {note}" for note in stage.gains.get("notes") or ()] + _diagnosis(stage.diagnosis)
            + [wrote(stage.files)])


# -- verify, run -----------------------------------------------------------------------------------------------------

def verification_summary(out: Path, stage: Any) -> list[str]:
    """A verification, any plant (a pipeline.VerificationStage): the verdict's lines and the files it wrote."""
    n = len(stage.figures)
    return stage.result.lines() + [f"wrote {out / 'verification.json'}, {out / 'verification.md'}"
                                   + (f" and {n} figure{'s' if n > 1 else ''}" if n else "")]


def run_summary(out: Path, res: Any) -> list[str]:
    """`run`, any plant (a pipeline.RunResult): the certified figures, the diagnosis, the verdict."""
    return (cleared(out, res.model.cleared) + certified_lines(res.synthesis.gains) + _diagnosis(res.synthesis.diagnosis)
            + res.verification.result.lines())


def logs_line(logs: Sequence[Any], logdir: Path) -> str:
    """verify --log: the run logs written."""
    return f"wrote {len(logs)} run logs to {logdir}/"


def physics_line(vd: Mapping[str, Any], episodes: int) -> str:
    """`run --physics`: the physics robot's errors against the certified bounds, one line."""
    ratios = ", ".join(f"{k} {v:.2f}" for k, v in vd["ratio_to_certified"].items() if v is not None)
    return (f"physics robot (MuJoCo, {episodes} episodes, {vd['straight_rule'].split(' (')[0]}): observed/certified "
            + (ratios or "(no certified bounds)") + f"; validation {'passed' if vd['passed'] else 'FAILED'}")


def run_export_lines(target: str, gains: Path, exported: tuple[Mapping[str, Any], Sequence[Any]] | None) -> list[str]:
    """`run --export`: what was exported, or why not (``exported`` None: the verification failed)."""
    if exported is None:
        return [f"export skipped: verification failed, so the gain is not exported as a controller (robustsynth "
                f"export {gains} --to {target} --allow-unverified exports it marked UNVERIFIED)"]
    d, files = exported
    return [f"exported ({target}; proven: {d['proof']['proven']}; verification: {d['proof']['verified']}): "
            f"{', '.join(str(p) for p in files)}"]


# -- margin ----------------------------------------------------------------------------------------------------------

def margin_summary(stage: Any, as_json: bool = False) -> list[str]:
    """A gain's margins, any plant (a pipeline.MarginStage): its warnings (stderr), then, unless the JSON is what
    is printed, a line per margin, its notes and the files written."""
    warnings = [Err(w) for w in stage.report.warnings]
    return warnings if as_json else warnings + stage.report.lines() + [wrote(stage.files)]


# -- check-log, monitor ----------------------------------------------------------------------------------------------

def violated(row: Mapping[str, Any], tolerance: float) -> bool:
    """A checked assumption (check-log) broken by more than ``tolerance`` of its samples."""
    return bool(row["samples"]) and row["fraction_outside"] > tolerance


def check_log_summary(rows: Sequence[Mapping[str, Any]], tolerance: float) -> list[str]:
    """One line per assumption of the config (held, violated, not checked), then the count."""
    lines = []
    for r in rows:
        rng = f"{r['assumption']} in [{r['range'][0]:g}, {r['range'][1]:g}] ({r['unit']})"
        if not r["samples"]:
            lines.append(f"{'n/a':8s} {rng}: not checked (no period of the logs says anything about it)")
            continue
        worst = "" if r["worst"] is None else f", worst {r['worst']:.4g}" + (f" at {r['where']}" if r["where"] else "")
        lines.append(f"{'VIOLATED' if violated(r, tolerance) else 'ok':8s} {rng}: {r['outside']} of {r['samples']} "
                     f"outside ({100 * r['fraction_outside']:.2f} %){worst}")
    bad = sum(violated(r, tolerance) for r in rows)
    unchecked = sum(not r["samples"] for r in rows)
    lines.append(f"check-log: {len(rows) - bad - unchecked} of {len(rows)} assumptions hold"
                 + (f", {unchecked} not checked" if unchecked else "") + f" (tolerance {100 * tolerance:g} %)"
                 + (f"; pose noise assumed {rows[-1]['pose_noise'][0]:g} m, {rows[-1]['pose_noise'][1]:g} rad"
                    if rows and rows[-1].get("pose_noise") else ""))
    return lines


def compensation_replay_line(c: Mapping[str, Any]) -> str:
    """A slip-compensated law's condition over replayed logs (runtime.replay.monitor_logs), one line."""
    logged = c["logs_with_the_estimate"]
    return (f"slip compensation: the condition held in {100.0 * c['condition_held_share']:.1f} % of {c['periods']} "
            "periods" + (f"; the logged estimate and condition are the replay's in every period of {logged} logs"
                         if logged and not c["periods_the_logged_estimate_differs"] else
                         f"; the logged estimate or condition differs from the replay's in "
                         f"{c['periods_the_logged_estimate_differs']} periods (not this gain's compensated law?)"
                         if logged else " (the logs carry no estimate columns)"))


def slip_estimate_line(est: Mapping[str, Any]) -> str:
    """One line of the slip estimates over logs (runtime.replay.estimate_summary)."""
    parts = [f"{name} within +-{p['median_half']:.3f} (median; largest {p['max_half']:.3f}), narrower than the box in "
             f"{100.0 * p['observed_share']:.0f} % of them" for name, p in est["parameters"].items()
             if name in ("mu_r", "mu_l", "traction")]
    return (f"slip estimate over {est['periods']} periods: " + "; ".join(parts or ["none"])
            + (f"; {est['inconsistent']} periods no traction in the box explains" if est["inconsistent"] else ""))


def monitor_summary(res: Mapping[str, Any], outdir: Path | None) -> list[str]:
    """The monitor replayed over logs (runtime.replay.monitor_files): every alarm, the fallback, the count."""
    lines = []
    for run in res["runs"]:
        for a in run["alarms"]:
            by = ", ".join(f"{c} by {a['by'][c]:.4g}" for c in a["causes"].split(", ") if c in a["by"])
            lines.append(f"{run['log']}: period {a['period']} (t = {a['t']:.3f} s): {by}")
        if run["fallback_engaged_at"] is not None:
            lines.append(f"{run['log']}: the fallback ({run['fallback']}) would have engaged at period "
                         f"{run['fallback_engaged_at']}")
    counts = ", ".join(f"{n} {res['alarm_periods'][n]}" for n, _ in CAUSES if res["alarm_periods"][n])
    if res.get("slip_estimate"):
        lines.append(slip_estimate_line(res["slip_estimate"]))
    if res.get("compensation"):
        lines.append(compensation_replay_line(res["compensation"]))
    lines.append(f"monitor: {res['runs_with_alarms']} of {res['logs']} logs with alarms"
                 + (f" (periods: {counts})" if counts else "")
                 + (f"; wrote {outdir / 'monitor.json'}" if outdir is not None else ""))
    return lines


# -- validate --------------------------------------------------------------------------------------------------------

def excitation_summary(cfg: Any, config_path: Path, engine: str, out: Path, episodes: int,
                       physics: str | None) -> list[str]:
    """validate --excite: the logs written, and the identify command that reads them (``physics``: the summary of
    the robot the engine drove, None for the kinematic one)."""
    nz = cfg.verification.noise  # the excitation puts exactly this noise on the logged poses
    icr = f" --model icr --pose-noise {nz.position:g} {nz.heading:g}" if cfg.slip.model == "icr" else ""
    settle = " --settle 1" if engine == "physics" else ""  # the engine's robot has dynamics: skip its transients
    return ([] if physics is None else [f"physics robot (MuJoCo): {physics}"]) + [
        f"excitation ({engine}): {episodes} episodes written to {out / 'logs'}; next: robustsynth identify "
        f"{out / 'logs'}/*.csv --config {config_path}{icr}{settle} --max-motor-speed "
        f"{cfg.robot.max_motor_speed or 'R'} -o FRAGMENT.yaml"]


def _certificate_lines(vd: Mapping[str, Any]) -> list[str]:
    """What the validation judges against: the robot the engine ran, the certificate's bounds and model."""
    vc = vd["certificate"]
    lines = []
    if vd.get("physics"):  # which robot the engine ran (issue 50: the default chassis had been used silently)
        lines.append(f"physics robot (MuJoCo): {vd['physics']['summary']}")
    if not vc["passed"]:
        lines.append(f"no certified bounds: {vc['detail']}")
    elif not vc.get("error_bounds"):  # a stability or H-infinity certificate (review: "passed" with nothing judged)
        lines.append("the certificate states no error bounds (its objective proves no invariant set): the errors "
                     "below are not judged, only the slip")
    if vc.get("model") == "paper":
        lines.append("the certificate is for the paper's model (synthesis.model: paper), whose slip is not this "
                     "robot's: its bounds are the paper model's claims (verify judges them on the robot)")
    return lines


def _error_lines(vd: Mapping[str, Any], arcs: bool) -> list[str]:
    """The largest errors: on the straight segments (or the whole path) against the certified ones, in the turns."""
    sm, c = vd["straight_max"], vd["certified"]
    through = bool(vd.get("through_turns"))
    lines = [("the whole path, turns included (against the bounds for all t): " if through else "straight segments: ")
             + ", ".join(f"|{k}| {v * (100 if k != 'e_theta' else 1):.3g} {'cm' if k != 'e_theta' else 'rad'}"
                         + (f" (certified {c[k] * (100 if k != 'e_theta' else 1):.3g}, ratio {v / c[k]:.2f})"
                            if c.get(k) else "") for k, v in sm.items())]
    tm = vd["turn_max"]
    if through:
        lines.append(f"torque-saturated up to {vd['torque_saturated_s']:.1f} s per episode")
    else:
        what = ("arcs (certified; reported apart from the straight segments)" if arcs else "turns (not certified)")
        lines.append(f"{what}: |e_y| {100 * tm['e_y']:.3g} cm, |e_theta| {tm['e_theta']:.3g} rad; "
                     f"torque-saturated up to {vd['torque_saturated_s']:.1f} s per episode")
    return lines


def _slip_lines(vd: Mapping[str, Any], arcs: bool) -> list[str]:
    """The slip the engine showed (identify's estimate) against the config's box."""
    vc, sl = vd["certificate"], vd["slip"]
    lines = []
    if sl.get("estimated"):
        b = sl["estimated"]
        lines.append(f"slip the engine showed on the straight segments (identify): right [{b['right'][0]:.3f}, "
                     f"{b['right'][1]:.3f}], left [{b['left'][0]:.3f}, {b['left'][1]:.3f}] — "
                     + ("inside" if sl["inside_box"] else "OUTSIDE") + " the config's box"
                     + ("" if not vc["passed"] or vc.get("model") == "paper" else
                        ": the certificate " + ("covers it" if sl["inside_box"] else "does not apply to this robot")))
    whole = vd.get("slip_whole_episodes", {}).get("estimated")
    if whole:
        lines.append(f"  with the turns: right [{whole['right'][0]:.3f}, {whole['right'][1]:.3f}], left "
                     f"[{whole['left'][0]:.3f}, {whole['left'][1]:.3f}]"
                     + (" (with the arcs)" if arcs else " (through the turns the certificate covers)"
                        if vd.get("through_turns") else " (the turns are not certified)"))
    return lines


def _monitor_lines(vd: Mapping[str, Any], injected: str | None) -> list[str]:
    """The runtime monitor over the episodes, and when it first flagged an injected violation."""
    mon = vd.get("monitor")
    lines = []
    if mon:
        counts = ", ".join(f"{k} {v}" for k, v in mon["alarm_periods"].items() if v)
        lines.append(f"runtime monitor over the episodes: {mon['runs_with_alarms']} of {mon['logs']} with alarms"
                     + (f" (periods: {counts})" if counts else ""))
        if mon.get("slip_estimate"):
            lines.append("  " + slip_estimate_line(mon["slip_estimate"]))
        if mon.get("compensation"):
            lines.append("  " + compensation_replay_line(mon["compensation"]))
    if injected is not None:
        firsts = (mon or {}).get("first_per_log") or []
        seen = "; ".join(f"episode {i}: " + (f"period {f['period']} ({f['causes']})" if f else "not flagged")
                         for i, f in enumerate(firsts)) or "no monitor (the gain has no certified set)"
        lines.append(f"injected {injected}; the runtime monitor's first alarm: {seen}")
    return lines


def validation_summary(vd: Mapping[str, Any], episodes: int, out: Path, injected: str | None) -> list[str]:
    """validate --gains (pipeline.validation_stage): the robot, the certificate, the errors, the slip, the monitor
    (``injected``: the description of the violation injected, if any), the verdict."""
    arcs = vd.get("straight_rule", "").startswith("between the arcs")
    return (_certificate_lines(vd) + _error_lines(vd, arcs) + _slip_lines(vd, arcs) + _monitor_lines(vd, injected)
            + _compensated_validation_lines(vd.get("compensated"))
            + [f"validation {'passed' if vd['passed'] else 'FAILED'}: {episodes} episodes; wrote {out / 'validation.json'}"])


def _compensated_validation_lines(rec: Mapping[str, Any] | None) -> list[str]:
    """validate of a slip-compensated law (docs/theory.md §18): the estimate in the loop, the condition, the set."""
    if not rec:
        return []
    est = rec.get("estimate_median")
    return [f"slip compensation: the estimate (median {est[0]:.3f}, {est[1]:.3f}) divided the commands; its condition "
            f"held in {100 * rec['condition_held_share']:.1f} % of the periods; {rec['samples_judged']} samples in the set "
            f"under it, {rec['samples_judged_outside_the_set']} of them outside (max V/level "
            f"{rec['max_V_over_level_judged']:.3f}; {rec['max_V_over_level_all']:.2f} over every sample); "
            f"{rec['episodes_not_back_at_the_end']} episodes did not end in the set under it"
            if est is not None else "slip compensation: its condition never held (no sample judged)"]


# -- export, sweep, identify -----------------------------------------------------------------------------------------

def export_summary(gains: Path, d: Mapping[str, Any], files: Sequence[Any]) -> list[str]:
    """An exported controller (runtime.export.export_controller): what it is proven for, its verification."""
    proof = d["proof"]
    lines: list[str] = []
    if proof["verification"]["status"] != "passed":
        lines.append(Err(f"warning: {gains}: {proof['verified']}; exported anyway (--allow-unverified), marked "
                         "UNVERIFIED in the files: not a verified controller, do not deploy it as one"))
    if not d.get("certified"):
        lines.append(f"warning: {gains}: no certificate that holds for this gain (none in the file, or its K, "
                     "certificate or config changed after synthesis): exported as UNCERTIFIED (run `robustsynth verify "
                     "--gains` on it)")
    return lines + [f"proven: {proof['proven']}", f"verification: {proof['verified']}", wrote(files)]


def sweep_summary(res: Any, out: Path) -> list[str]:
    """A sweep (sweeps.SweepResult): the points by status, the engine, the time, the files."""
    counts = ", ".join(f"{n} {s}" for s, n in res.counts.items() if n)
    reused = f", {res.reused} read from {out / 'points'}" if res.reused else ""
    return [f"sweep: {len(res.rows)} points: {counts} ({res.engine['kind']}, {res.time_s:.1f} s{reused})",
            f"{wrote(res.files)} and {out / 'points'}/"]


def identified_line(ident: Any, written: Sequence[Any]) -> str:
    return f"identified from {ident.logs} log(s), {ident.slip.mu.shape[0]} periods: {wrote(written)}"
