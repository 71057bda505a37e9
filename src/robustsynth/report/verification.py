"""verification.json, verification.md and the run's report.md."""

from __future__ import annotations

import math
from typing import Any

from ..config import config_to_dict
from .. import __version__
from ..artifacts.files import SCHEMA_VERSION
from ..certificate.turns import TURN_REENTRY
from ..objectives import labelled_figures
from ..robot_verification.lines import robot_leaves
from ..results import failed_names
from .markdown import conditions_text, fmt, table

__all__ = ["verification_dict", "verification_markdown", "report_markdown", "summary_dict", "lti_verification_markdown"]


def verification_dict(model: Any, res: Any, gains_file: str, gid: str) -> dict[str, Any]:
    fr = dict(res.frozen)
    fr.pop("tau", None)
    fr.pop("spectral_radius_vs_tau", None)
    return {
        "schema_version": SCHEMA_VERSION,
        "robustsynth_version": __version__,
        "passed": res.passed,
        "gains_file": gains_file,
        "gains_id": gid,
        "config": config_to_dict(model.user_config),
        "certified": res.certificate.figures if res.certificate.passed else None,
        "checks": list(res.checks),
        "frozen": fr,
        "lifted": res.lifted,
        "monte_carlo": res.monte_carlo,
    }


def _val(v: Any) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        return fmt(v, 5)
    return str(v)


def verification_markdown(model: Any, res: Any, vd: dict[str, Any], figures: dict[str, str] | None = None) -> str:
    cfg = model.config
    out = [f"# Verification for `{cfg.name}`: {'PASSED' if res.passed else 'FAILED'}\n\n"]
    leaves = robot_leaves(res.monte_carlo, cfg)
    if leaves:
        out.append(f"> Note: {leaves}.\n\n")
    out.append(
        f"Gain file `{vd['gains_file']}` (gains_id `{vd['gains_id'][:16]}…`), checked independently of how it was made."
        " Pass/fail rules are in docs/reference/verification.md (*Verification rules*).\n\n"
    )
    out.append(checks_markdown(res))
    mc = res.monte_carlo
    out.append(nonlinear_markdown(cfg, mc))
    if figures:
        out.append(figures_markdown(figures))
    return "".join(out)


RECHECK = "certificate: LMIs re-checked in numpy"


def checks_markdown(res: Any) -> str:
    """The table of checks.  The re-check's detail counts its conditions as synthesis.md does
    (markdown.conditions_text): the verifier writes the number of families of conditions ("4 conditions"),
    synthesis.md their LMIs ("at 768 vertex conditions"), and the two read as contradicting each other
    (issue 50)."""
    cert_checks = list(getattr(getattr(res, "certificate", None), "checks", ()) or ())

    def detail(c: dict[str, Any]) -> str:
        d = str(c["detail"])
        prefix = f"{len(cert_checks)} conditions, "
        if c["name"] == RECHECK and cert_checks and d.startswith(prefix):
            d = conditions_text(cert_checks) + ", " + d[len(prefix):]
        return d

    return checks_table(res.checks, detail)


def checks_table(checks: Any, detail: Any = lambda c: str(c["detail"])) -> str:
    """The Markdown table of a verdict's checks (:class:`robustsynth.results.Check` form), any plant's."""
    rows = [[c["name"], "pass" if c["passed"] else "**FAIL**", _val(c["value"]), _val(c["threshold"]), detail(c)]
            for c in checks]
    return table(["check", "result", "value", "threshold", "detail"], rows)


def figures_markdown(figures: dict[str, str]) -> str:
    """The figures, each once: a heading, the image, and its caption where it has one."""
    from .plots import FIGURE_CAPTIONS, FIGURES

    out = ["\n## Figures\n\n"]
    for name, rel in figures.items():
        out.append(f"### {FIGURES[name]}\n\n![{FIGURES[name]}]({rel})\n\n")
        if FIGURE_CAPTIONS.get(name):
            out.append(f"{FIGURE_CAPTIONS[name]}\n\n")
    return "".join(out)


def nonlinear_markdown(cfg: Any, mc: dict[str, Any]) -> str:
    """The nonlinear robot's section: how the runs were made, what is excluded, maxima vs certificate."""
    vl = mc.get("V_over_level")
    out = [_runs_text(cfg, mc), _maxima_markdown(mc), _adversarial_text(mc.get("adversarial")), _lyapunov_markdown(vl)]
    if mc.get("turns"):
        out.append(_turns_markdown(cfg, mc["turns"], vl))
    if mc.get("boundary_probe"):
        out.append(_boundary_text(mc["boundary_probe"]))
    out += [_dropouts_text(mc.get("dropouts")), _beyond_cap_text(mc.get("beyond_cap"), cfg),
            _steady_state_text(mc.get("steady_state")), _whole_runs_text(mc, cfg), _exceeds_text(mc),
            monitor_markdown(mc.get("monitor")), compensated_markdown(mc.get("compensated"))]
    return "".join(out)


def compensated_markdown(rec: dict[str, Any] | None) -> str:
    """The slip-compensated law on the true robot (robot_verification/compensated.py, docs/theory.md §18)."""
    if not rec:
        return ""
    if rec.get("skipped"):
        return f"\n## The slip-compensated law on the true slip\n\nNot run: {rec['skipped']}.\n"
    box = ", ".join(f"{k} in [{lo:g}, {hi:g}]" for k, (lo, hi) in zip(("mu_r", "mu_l"), rec["true_box"]))
    first = rec["condition_first_period"]
    rows = [[k, fmt(100 * rec["max_on_set"][k] if k != "e_theta" else rec["max_on_set"][k]),
             fmt(rec["ratio_to_certified"][k], 3),
             fmt(100 * rec["max_all"][k] if k != "e_theta" else rec["max_all"][k])] for k in ("e_x", "e_y", "e_theta")]
    return ("\n## The slip-compensated law on the true slip\n\n"
            "The runs above are the robot under the certificate's condition: their slip is the ratio mu / mu_hat, in "
            f"[{rec['ratio_box'][0][0]:.4f}, {rec['ratio_box'][0][1]:.4f}] per track. These "
            f"{rec['runs']} runs (seed {rec['seed']}, {rec['steps']} steps) close the loop on the true slip ({box}, "
            f"moving at {rec['max_rate']:g} /s, each track changing at its own time within the period) with each run's "
            "monitor estimating it and the law dividing each track's command by the estimate (docs/theory.md §18). "
            f"They start {rec['start']}.\n\n"
            f"The condition (each track's half-width + lag {rec['lag']:.4g} <= error {rec['error']:.4g}) held in "
            f"{100 * rec['condition_held_share']:.1f} % of the periods; it first held at period {first['median']:g} "
            f"(median; latest {first['max']}; runs in which it never held: {first['runs_never']}); median margin "
            f"{fmt(rec['margin_median'])}. Steps judged (the state in the set at t_k and the condition held for every "
            f"command that can act in the period): {rec['steps_judged']}; the robot left its set on "
            f"{rec['steps_leaving_the_set']} of them (largest V/level after a judged step "
            f"{rec['max_V_over_level_judged']:.3f}). Periods in which the condition held but a command met a traction "
            f"farther than the error from its estimate: {rec['estimate_unsound_steps']}.\n\n"
            + table(["tracking error", "max on the covered samples (cm; rad)", "observed / certified",
                     "max over every sample, warm-up included (cm; rad)"], rows)
            + f"\nLargest V/level over every sample: {rec['max_V_over_level_all']:.3f} (where the condition did not "
            "hold the theorem claims nothing). Monitor alarm periods over these runs: "
            + ", ".join(f"{k} {v}" for k, v in rec["monitor_alarm_periods"].items()) + ".\n"
            + _jump_markdown(rec.get("jump")))


def _jump_markdown(j: dict[str, Any] | None) -> str:
    if not j:
        return ""

    def n(d: dict[str, Any]) -> str:
        return "never" if d["median"] is None else f"{d['median']:g} (median; largest {d['max']}; never in {d['runs_never']} runs)"

    return ("\n**A slip jump** (measured, not certified: the certificate assumes the rate bound only). "
            f"{j['runs']} runs with each track's traction constant, jumping at period {j['jump_period']} by at least "
            f"{j['jump_size_min']:.3f} (to the box's far half) and constant again: the condition failed {n(j['condition_lost_after'])} "
            f"periods after the jump, held again for every command that can act after {n(j['recovery_periods'])}, and "
            f"the state was back in the set under it after {n(j['back_in_the_set_periods'])}. Periods in which the "
            f"condition was claimed while a command met a traction farther than the error (before the monitor could "
            f"see the jump): {j['periods_claimed_wrongly']}. Until back in the set: V/level up to "
            f"{j['max_V_over_level_in_recovery']:.2f}, |e_x| {100 * j['max_in_recovery']['e_x']:.2f} cm, |e_y| "
            f"{100 * j['max_in_recovery']['e_y']:.2f} cm, |e_theta| {j['max_in_recovery']['e_theta']:.3f} rad.\n")


def _runs_text(cfg: Any, mc: dict[str, Any]) -> str:
    """The section's heading and how the Monte Carlo runs were made: their number, seed and length, the path,
    the delays and slip profiles, where they start and which steps the maxima leave out."""
    return (f"\n## The nonlinear robot\n\n{mc['runs']} Monte Carlo runs (seed {mc['seed']}), {mc['steps']} steps of "
            f"{cfg.network.sampling_time:g} s along the path {list(map(list, cfg.reference.path))}; delays {mc['delays']};"
            f" slip profiles {mc['slip_profiles']}"
            + (f", slip rate at most {mc['slip_max_rate']:g} /s" if mc.get("slip_max_rate") else ", slip may jump every period")
            + (f", changes {mc['slip_changes']}" if mc.get("slip_changes") else "")
            + f". Runs start at the {mc['start']}. Maxima are taken over the steps in the {mc['excluded']}.\n\n")


def _maxima_markdown(mc: dict[str, Any]) -> str:
    """The table of each bounded figure's maxima (Monte Carlo mean, p95 and max, the extreme switching runs,
    the adversary) beside the certified bound and the worst run's ratio to it."""
    rows = []
    units = {"e_x": ("cm", 100), "e_y": ("cm", 100), "e_theta": ("rad", 1), "motor_speed": ("rad/s", 1)}
    adv = mc.get("adversarial")
    for k, (u, sc) in units.items():
        m = mc["maxima"][k]
        cert = mc["certified"].get(k)
        ratio = mc["ratio_to_certified"].get(k)
        rows.append([f"max |{k}| [{u}]", fmt(m["mean"] * sc), fmt(m["p95"] * sc), fmt(m["max"] * sc),
                     fmt(mc["extreme_maxima"][k] * sc), fmt(adv["max"][k] * sc) if adv else "—",
                     fmt(cert * sc) if cert is not None else "—", fmt(ratio, 3) if ratio is not None else "—"])
    return table(["quantity", "mean", "p95", "max", "extreme switching", "adversarial", "certified",
                  "worst / certified"], rows)


def _adversarial_text(adv: dict[str, Any] | None) -> str:
    """The adversarial search from the steady states: its length and kind, the largest V/level it reached and
    how many of its states lie outside the set ("" without one)."""
    if not adv:
        return ""
    return (f"\nAdversarial search over {adv['steps']} periods: {adv['search']}; "
            f"max V/level = {adv['max_V_over_level']:.4f}, "
            f"{100 * adv['fraction_of_steps_outside']:.2f} % of the states it kept lie outside the certified set.\n")


def _lyapunov_markdown(vl: dict[str, Any] | None) -> str:
    """V/level of the robot's true lifted state on the certified steps, and the waypoints after which the
    steps are excluded until the robot is back in the set (a table; "" without the record)."""
    if not vl:
        return ""
    out = [f"\nLyapunov function of the robot's true lifted state on the certified steps: max V/level ="
           f" {vl['max_in_certified_steps']:.4f}; {100 * vl['fraction_of_certified_steps_outside']:.3f} % of them lie"
           " outside the certified set (V/level > 1).\n"]
    if vl["waypoints"]:
        out.append("\nAfter each waypoint the segment's frame changes, the state starts outside the set, and the"
                   " certificate promises only attraction; these steps are excluded until the robot is back:\n\n")
        out.append(table(["waypoint at [s]", "max V/level at the switch", "longest time to re-enter [s]",
                          "runs not back before the next waypoint"],
                         [[fmt(w["t_switch_s"]), fmt(w["max_V_over_level_at_switch"], 4),
                           fmt(w["max_time_to_reenter_s"]), str(w["runs_not_reentered"])] for w in vl["waypoints"]]))
    return "".join(out)


def _turns_markdown(cfg: Any, turns: list[dict[str, Any]], vl: dict[str, Any] | None) -> str:
    """The waypoint turns' certified bounds: on arcs (reference.turn_radius) part of the certified set's claims,
    at sharp corners beside what the Monte Carlo runs measured at the nearest switch (not part of the verdict)."""
    measured = {round(w["t_switch_s"], 6): w for w in (vl.get("waypoints") or [])} if vl else {}

    def _measured(t: dict) -> dict:  # the simulated switch nearest to the certified one (one period apart)
        near = [w for k, w in measured.items() if abs(k - t["t_switch_s"]) <= 1.0]
        return min(near, key=lambda w: abs(w["t_switch_s"] - t["t_switch_s"])) if near else {}

    n_ok = sum(1 for t in turns if t["certified"])
    if cfg.reference.turn_radius is not None:  # arcs: no switch, no re-entry
        cells = [turn_bound_cells(t, cfg) for t in turns]
        return (f"\n**Waypoint turns** (docs/theory.md §10, \"Turning along arcs\"): {n_ok} of {len(turns)} turns"
                f" certified. Every corner is rounded by an arc of radius {cfg.reference.turn_radius:g} m: the"
                " reference does not jump, and the certificate covers its yaw rate, so the certified set and its"
                " bounds hold through the turns (the Monte Carlo maxima above include them):\n\n"
                + table(["waypoint", "turn [rad]", "arc starts at [s]", "certified |e_y| for all t [cm]",
                         "certified |e_theta| for all t [rad]", "certified peak |rho| [rad/s]", "status"],
                        [[str(t["waypoint"]), fmt(t["turn_rad"], 3), fmt(t["t_switch_s"]), *c, "certified"]
                         for t, c in zip(turns, cells)])
                + _no_bound_text(cells, cfg))
    rows, cells = [], []
    for t in turns:
        m = _measured(t)
        ey, th, rho = turn_bound_cells(t, cfg)
        cells.append((ey, th, rho))
        rows.append([str(t["waypoint"]), fmt(t["turn_rad"], 3), fmt(t["V_over_level_at_switch"], 3),
                     fmt(m.get("max_V_over_level_at_switch"), 3), ey, th, rho, fmt(t["time_to_reenter_s"]),
                     fmt(m.get("max_time_to_reenter_s")),
                     "certified" + (f" ({t['note']})" if t["note"] else "") if t["certified"]
                     else "not certified: " + t["reason"]])
    return (f"\n**Waypoint turns** (not part of the verdict; docs/theory.md §10): {n_ok} of {len(turns)} turns"
            " certified. From the certified set, the frame change bounds V/level at the switch; the decay then"
            f" bounds the errors through the turn and the time until V <= {TURN_REENTRY:g} level. Beside them,"
            " what the Monte Carlo runs measured:\n\n"
            + table(["waypoint", "turn [rad]", "certified V/level at the switch", "measured max",
                     "certified peak |e_y| at the samples [cm]", "certified peak |e_theta| at the samples [rad]",
                     "certified peak |rho| [rad/s]", f"certified time to V <= {TURN_REENTRY:g} level [s]",
                     "measured time to V <= level [s]", "status"], rows)
            + _no_bound_text(cells, cfg))


def _boundary_text(bp: dict[str, Any]) -> str:
    """The boundary probe's paragraph: whether it is part of the verdict, what it ran, V(xi+)/level on the
    exact lifted map and on the nonlinear robot (with its local search), the runs with slip jumps, on arcs
    and between the samples, the adversary from the boundary, and what a value above 1 means for this
    certificate's kind."""
    judged = bp.get("in_verdict", False)
    # files written before the verdict judged every kind: in_verdict was the certificate's kind
    nonlinear = bp["kinematics"] == "nonlinear" if "kinematics" in bp else judged
    return (
        f"\n**From the boundary of the certified set** ({'part of the verdict' if judged else 'not part of the verdict'}):"
        f" {bp['samples']} states on"
        f" V = level, spread over the set and at the maximizers of each bounded figure, with stored commands"
        f" within the motor limit, a slip corner and admissible delays, run for one period. On the exact lifted"
        f" map the certificate is about, max V(xi+)/level = {bp['max_V_over_level_linear']:.4f}. On the nonlinear"
        f" robot (exact arcs) it is {bp['max_V_over_level_nonlinear']:.4f}"
        + (f" ({bp['refinement']['max_V_over_level_before']:.4f} on these states; a local search from the"
           f" {bp['refinement']['starts']} worst along the boundary, {bp['refinement']['runs']} more periods, reached"
           f" {bp['refinement']['max_V_over_level_after']:.4f})" if bp.get("refinement") else "")
        + f", and {100 * bp['fraction_outside_nonlinear']:.2f} % of these states leave the set. The two differ by up to"
        f" {1000 * bp['max_period_gap']['e_x']:.1f} mm in e_x and {1000 * bp['max_period_gap']['e_y']:.1f} mm in e_y"
        " per period. "
        + _mid_period_text(bp.get("mid_period") or {})
        + (_arcs_text(bp["arcs"]) if bp.get("arcs") else "")
        + _between_text(bp.get("between_samples") or {}, judged)
        + _boundary_adversary_text(bp.get("adversary"))
        + ("The certificate covers these terms (nonlinear kinematics, docs/theory.md §9"
           + (", on arcs §10" if bp.get("arcs") else "") + "): a value above 1 would contradict it.\n" if nonlinear else
           "The certificate proves the bounds for the robot's linearization; the kinematic terms it drops"
           " (docs/theory.md §2, §7) are not part of this proof (synthesis.kinematics: nonlinear covers them).\n")
    )


def _boundary_adversary_text(adv: dict[str, Any] | None) -> str:
    """The adversary's beam search from the boundary: its starts (and those the probe's local search found),
    its periods and courses, the largest V/level it reached ("" without one)."""
    if not adv:
        return ""
    return (f"The adversary's beam search from {adv['starts']} of these states (each figure's maximizer"
            " at every slip corner" + (f", and the {adv['searched_starts']} worst the local search found"
                                       if adv.get("searched_starts") else "")
            + f") over {adv['steps']} periods"
            + (" (on a straight line and along arcs, fixed ones and ones whose yaw rates it picks)"
               if len(adv.get("courses", ())) > 1 else "")
            + " reaches max V/level ="
            f" {adv['max_V_over_level']:.4f}. ")


def _dropouts_text(dr: dict[str, Any] | None) -> str:
    """The lossy link the runs went through: its channel, the cap on bursts, what was lost ("" without one)."""
    if not dr:
        return ""
    ch = dr["channel"]
    return (f"\nLossy link: {ch['model']} channel (loss probability {ch['probability']:g}, mean burst "
            f"{ch['mean_burst']:g} packets), bursts cut at {dr['max_consecutive']}: {dr['lost_packets']} commands "
            f"lost ({100 * dr['lost_fraction']:.1f} %), longest burst {dr['longest_burst']}"
            + (f"; the adversary dropped {100 * dr['adversary_lost_fraction']:.1f} % of its packets"
               if "adversary_lost_fraction" in dr else "") + ".\n")


def _beyond_cap_text(bc: dict[str, Any] | None, cfg: Any) -> str:
    """The runs outside the model (verification.dropouts.exceed_cap): bursts longer than the cap, and how far
    the robot went in them ("" without them)."""
    if not bc:
        return ""
    out = [f"\n**Outside the model** (`verification.dropouts.exceed_cap`, not part of the verdict): {bc['runs']} runs "
           f"on the same channel with bursts not cut; {bc['runs_outside_model']} of them have a burst longer than "
           f"{cfg.network.dropouts.max_consecutive} (longest {bc['longest_burst']}), "
           f"{100 * bc['lost_fraction']:.1f} % lost."]
    mo = bc.get("max_outside")
    if mo:
        out.append(f" Over whole runs they reach |e_x| = {100 * mo['e_x']:.2f} cm, |e_y| = {100 * mo['e_y']:.2f} cm, "
                   f"|e_theta| = {mo['e_theta']:.4f} rad, |rho| = {mo['motor_speed']:.3f} rad/s")
        if "max_V_over_level_outside" in bc:
            r = bc["ratio_to_certified_outside"]
            out.append(f"; max V/level {bc['max_V_over_level_outside']:.3f}, |e_y| {r['e_y']:.2f} x certified")
        out.append(".")
    out.append("\n")
    return "".join(out)


def _steady_state_text(ss: dict[str, Any] | None) -> str:
    """The steady state under constant slip at the slip box's corners ("" without the record)."""
    if not ss:
        return ""
    return (f"\nSteady state under constant slip (each corner of the slip box): |e_x*| <= "
            f"{100 * ss['max_abs']['e_x']:.3f} cm, |e_y*| <= {100 * ss['max_abs']['e_y']:.3f} cm.\n")


def _whole_runs_text(mc: dict[str, Any], cfg: Any) -> str:
    """The commanded motor speed over whole Monte Carlo runs (turns included) against robot.max_motor_speed
    ("" without a motor limit)."""
    m_all = mc["maxima"]["motor_speed_all"]["max"]
    if cfg.robot.max_motor_speed is None:
        return ""
    note = "exceeds" if m_all > cfg.robot.max_motor_speed else "stays within"
    if cfg.reference.turn_radius is not None:
        return (f"\nOver whole Monte Carlo runs (the adversary's aside), arcs included, the commanded motor speed (the turning feedforward with it) reaches "
                f"{m_all:.3f} rad/s, which {note} rho_max = {cfg.robot.max_motor_speed:g} rad/s.\n")
    return (f"\nOver whole Monte Carlo runs (the adversary's aside), waypoint transients included, the commanded motor speed reaches {m_all:.3f} rad/s, which"
            f" {note} rho_max = {cfg.robot.max_motor_speed:g} rad/s: the certificate covers the invariant set, and the"
            " waypoint turns start each segment outside it.\n")


def _exceeds_text(mc: dict[str, Any]) -> str:
    """How far the nonlinear robot exceeds the certificate, beside the slack allowed ("" where it does not)."""
    ratios = [r for r in mc["ratio_to_certified"].values() if r is not None]
    if not (ratios and max(ratios) > 1):
        return ""
    return (f"\nThe nonlinear robot exceeds the certificate by up to {100 * (max(ratios) - 1):.1f} % (allowed: "
            f"{100 * (mc['nonlinear_slack'] - 1):.0f} %).\n")


def monitor_markdown(mon: dict[str, Any] | None) -> str:
    """The runtime monitor over the runs (recorded, not in the verdict): alarms per cause, what it is sure to see."""
    if not mon:
        return ""
    det = mon["detects"]
    counts = ", ".join(f"{k} {v}" for k, v in mon["alarm_periods"].items() if v)
    return ("\n### The runtime monitor over these runs\n\n"
            f"Replayed over the {mon['logs']} Monte Carlo runs (they keep every assumption): {mon['runs_with_alarms']} runs "
            "raised an alarm" + (f" (alarm periods: {counts}; a false alarm unless the robot left its set)" if counts else "")
            + f". Once the state was seen inside its set, a departure to V/level above {det['set_ratio']:.3g} is always "
            f"flagged; a traction {det['traction']:.3g} or more outside the box, within {det['window_s']:g} s "
            "(docs/howto/runtime-monitor.md).\n" + _estimate_markdown(mon.get("slip_estimate")))


def _estimate_markdown(est: dict[str, Any] | None) -> str:
    """The slip estimate over the runs (with slip.max_rate; docs/theory/17-the-slip-estimate.md)."""
    if not est or not est["parameters"]:
        return ""
    rows = "".join(f"| {name} | {p['median_half']:.4f} | {p['max_half']:.4f} | {100.0 * p['observed_share']:.0f} % |\n"
                   for name, p in est["parameters"].items())
    return ("\nThe slip estimate over the same runs (each period: the tracks' traction now, sure to contain it under the "
            f"stated rate, box and noise; {est['periods']} periods, {est['inconsistent']} that no traction in the box "
            "explains):\n\n| parameter | median half-width | largest | narrower than the box |\n|---|---|---|---|\n" + rows)


NO_HEADING_BOUND = "no bound (>= pi)"


def turn_bound_cells(turn: dict[str, Any], cfg: Any) -> tuple[str, str, str]:
    """The cells of a waypoint turn's bounds (certificate.turns.turn_bounds: peak |e_y| [cm], peak |e_theta| [rad],
    peak |rho| [rad/s]), with a bound that says nothing printed as "no bound" and why, not as a number
    (issue 50: |e_theta| 6.51 rad, |e_y| 61.3 cm, |rho| 150 rad/s read as certified figures):

    - a heading bound >= pi rad says nothing: every heading error is within pi after wrapping, so the cell
      reads ``no bound (>= pi)``;
    - a position bound (|e_y|) larger than half the shortest segment of ``reference.path`` says nothing
      about which segment the robot follows: ``no bound (> half the shortest segment, X m)``;
    - a motor-speed bound beyond ``robot.max_motor_speed`` is not a certificate of the limit (the commands
      saturate there, outside the model): the number stays, marked ``(exceeds the L rad/s limit)``."""
    peak = turn.get("peak") or {}
    ey, th = peak.get("e_y"), peak.get("e_theta")
    half = half_shortest_segment(cfg)
    if ey is not None and half is not None and float(ey) > half:
        ey_cell = f"no bound (> half the shortest segment, {half:.3g} m)"
    else:
        ey_cell = fmt(None if ey is None else 100 * float(ey), 3)
    th_cell = NO_HEADING_BOUND if th is not None and float(th) >= math.pi else fmt(th, 3)
    rho, lim = turn.get("motor_speed_peak"), cfg.robot.max_motor_speed
    rho_cell = fmt(rho, 3)
    if rho is not None and lim is not None and float(rho) > float(lim):
        rho_cell += f" (exceeds the {lim:g} rad/s limit)"
    return ey_cell, th_cell, rho_cell


def half_shortest_segment(cfg: Any) -> float | None:
    """Half the length of the shortest segment of reference.path [m] (None: fewer than two waypoints)."""
    wp = [tuple(map(float, w)) for w in cfg.reference.path]
    lengths = [d for a, b in zip(wp, wp[1:]) if (d := math.hypot(b[0] - a[0], b[1] - a[1])) > 0.0]
    return 0.5 * min(lengths) if lengths else None


def _no_bound_text(cells: list[tuple[str, str, str]], cfg: Any) -> str:
    """One line under the turn table when a cell says "no bound" or marks a motor peak: why."""
    flat = [c for row in cells for c in row]
    why = []
    if NO_HEADING_BOUND in flat:
        why.append("a heading bound of pi rad or more says nothing (every heading error is within pi after wrapping)")
    if any(c.startswith("no bound (> half") for c in flat):
        why.append(f"a cross-track bound above half the shortest segment ({half_shortest_segment(cfg):.3g} m) says nothing"
                   " about which segment the robot follows")
    if any("rad/s limit)" in c for c in flat):
        why.append("a motor peak above robot.max_motor_speed is no certificate of the limit: the commands saturate"
                   " there, outside the model")
    return ("\nIn the table above, " + "; ".join(why) + ".\n") if why else ""


def transients_markdown(mc: dict[str, Any]) -> str:
    """The waypoint turns: what the verdict excludes, said in report.md rather than hidden."""
    tr = mc.get("transients")
    if not tr or not tr.get("excluded_steps_fraction"):  # nothing excluded (e.g. a path rounded by arcs)
        return ""
    mx = tr["max"]
    out = [f"\n**Turns and other excluded steps** ({100 * tr['excluded_steps_fraction']:.1f} % of the steps, "
           f"rule: {mc['excluded']}): the robot reaches |e_x| = {100 * mx['e_x']:.2f} cm, |e_y| = {100 * mx['e_y']:.2f} cm, "
           f"|e_theta| = {mx['e_theta']:.3f} rad there."]
    lim = tr.get("motor_limit")
    if lim is not None:
        peak = tr["max_commanded_motor_speed"]
        if peak > lim:
            out.append(f" The controller asks for up to {peak:.2f} rad/s against rho_max = {lim:g} rad/s "
                       f"({100 * tr['steps_above_limit_fraction']:.2f} % of all steps, at most "
                       f"{tr['longest_above_limit_s']:.1f} s in a row); "
                       + ("the simulated motors saturate there, as real ones do." if tr["saturated"] else
                          "**the simulation does not saturate the motors** (`verification.motor_saturation: false`): "
                          "a real robot would not follow these runs."))
        else:
            out.append(f" The commanded motor speed stays within rho_max = {lim:g} rad/s throughout (peak {peak:.2f}).")
    return "".join(out) + "\n"


def summary_dict(model: Any, gains: dict[str, Any] | None, vd: dict[str, Any] | None, status: str) -> dict[str, Any]:
    """results/<name>/summary.json: what the regression compares (certified figures, feasibility,
    verdict, Monte Carlo maxima at the config's seed)."""
    out: dict[str, Any] = {"schema_version": SCHEMA_VERSION, "name": model.config.name, "status": status,
                           "dimensions": {"d_lo": model.d_lo, "d_hi": model.d_hi, "n_s": model.n_s}}
    if vd is not None:
        out["gains_id"] = vd["gains_id"]
    if gains is not None:
        out["objective"] = gains["objective"]
        out["certified"] = gains["certified"]
    if vd is not None:
        out["verification_passed"] = vd["passed"]
        out["failed_checks"] = failed_names(vd["checks"])
        mc = vd["monte_carlo"]
        out["monte_carlo"] = {"runs": mc["runs"], "seed": mc["seed"],
                              "max": {k: v["max"] for k, v in mc["maxima"].items()}}
        comp = mc.get("compensated")
        if comp and not comp.get("skipped"):  # the slip-compensated law on the true slip (docs/theory.md §18)
            out["compensated"] = {k: comp[k] for k in ("error", "condition_held_share", "steps_judged",
                                                       "steps_leaving_the_set", "max_on_set")}
    return out


def report_markdown(model: Any, gains: dict[str, Any], vd: dict[str, Any], figures: dict[str, str],
                    comparison: dict[str, Any] | None = None) -> str:
    cfg = model.config
    c = gains["certified"]
    ub = c.get("ultimate_bound") or {}
    mc = vd["monte_carlo"]
    out = [f"# robustsynth report: `{cfg.name}`\n\n"]
    out.append(
        f"Verdict: **{'PASSED' if vd['passed'] else 'FAILED'}**. Objective `{gains['objective']}`; d_lo = {model.d_lo},"
        f" d_hi = {model.d_hi}, lifted state n_s = {model.n_s}. Details: [model](model.md),"
        f" [synthesis](synthesis.md), [verification](verification.md); gain in `gains.json` / `gains.mat`.\n\n"
    )
    leaves = robot_leaves(mc, cfg)
    if leaves:
        out.append(f"> Note: {leaves}.\n\n")
    out.append("## What is proven, and what the robot did\n\n")
    def worst(k: str) -> float:  # what the verdict uses: Monte Carlo, extreme-switching and adversarial runs
        adv = (mc.get("adversarial") or {}).get("max", {}).get(k, 0.0)
        return max(mc["maxima"][k]["max"], mc["extreme_maxima"][k], adv)

    rows = [["decay rate r per step", fmt(c.get("decay_rate")), "—", "—"]]
    for k, u, sc in (("e_x", "cm", 100), ("e_y", "cm", 100), ("e_theta", "rad", 1)):
        if ub:
            rows.append([f"|{k}| [{u}]", fmt(ub[k] * sc), fmt(worst(k) * sc), fmt(mc["ratio_to_certified"].get(k), 3)])
    if c.get("motor_speed_bound") is not None:
        rows.append(["|rho| [rad/s]", fmt(c["motor_speed_bound"]), fmt(worst("motor_speed")),
                     fmt(mc["ratio_to_certified"].get("motor_speed"), 3)])
    rows += [[label, fmt(c[key]), "—", "—"] for key, label in labelled_figures()
             if c.get(key) is not None]  # an objective's own figure (hinf's l2 gain, ...)
    out.append(table(["quantity", f"certified ({model.kind} model)",
                      f"nonlinear robot, max on certified steps ({mc['runs']} Monte Carlo + 4 extreme runs"
                      + (" + the adversarial search" if mc.get("adversarial") else "") + ")", "ratio"], rows))
    failed = failed_names(vd["checks"])
    if failed:
        out.append("\nFailed checks: " + "; ".join(failed) + ".\n")
    out.append(transients_markdown(mc))
    out.append(nonlinear_markdown(cfg, mc))
    from .comparison import comparison_markdown

    out.append(comparison_markdown(comparison))
    out.append(figures_markdown(figures))  # each once (issue 50: a list of links, then the same figures again)
    return "".join(out)


def _mid_period_text(mid: dict) -> str:
    """The probe's runs with a slip jump within the period (docs/theory.md §11)."""
    if not mid.get("runs"):
        return ""
    return (f"{mid['runs']} more runs had the slip jump to a random corner at a random time within the period"
            + (" (covered by the certificate, so judged with the others): " if mid["covered"] else
               " (**not covered**: this certificate assumes slip constant within a period, so they are reported, not"
               " judged): ")
            + f"max V(xi+)/level = {mid['max_V_over_level_linear']:.4f} on the exact map,"
            f" {mid['max_V_over_level_nonlinear']:.4f} on the nonlinear robot. ")


def _between_text(between: dict, judged: bool) -> str:
    """The probe's errors between the samples beside the certificate's bounds for all t (docs/theory.md §9)."""
    bound = between.get("bound")
    if not bound or "straight" not in between:
        return ""

    def figs(d: dict) -> str:  # e_theta's bound is None where the certificate states none (no delay vertices)
        th = d.get("e_theta")
        return f"{100 * d['e_x']:.2f} / {100 * d['e_y']:.2f} cm and " + ("(none)" if th is None else f"{th:.3f} rad")

    return (f"Between the samples ({between['instants']} instants of each of these periods, e_x / e_y / e_theta in the"
            f" frame of the reference at t) the errors reach {figs(between['straight'])} on the straight line"
            + (f" and {figs(between['arcs'])} on arcs" if "arcs" in between else "")
            + f", against the bounds for all t of {figs(bound)}"
            + _rise_text(between.get("straight_rise") or {}, bound, between.get("sampled") or {},
                         between.get("rise_bound") or {})
            + (" (judged). " if judged else " (reported: a linearized certificate's sets hold for its linearization). ")
            + (f"The {between['mid_period']['runs']} states whose slip jumps within the period, which this certificate "
               f"does not cover (it assumes slip constant within each), reach {figs(between['mid_period'])} on the straight"
               " line (not judged). " if "mid_period" in between else ""))


def _rise_text(rise: dict, bound: dict, sampled: dict, rise_bound: dict | None = None) -> str:
    """How far the errors rise above the ends of their period, beside the chord terms at their worst (``rise_bound``;
    without it, what the bound for all t adds to the sampled one)."""
    rise_bound = rise_bound or {}
    parts = [f"{name} {100 * rise[name]:.2f} of {100 * rise_bound.get(name, bound[name] - sampled[name]):.2f} cm"
             for name in ("e_x", "e_y") if name in rise and sampled.get(name) is not None]
    return ("; above the larger end of their period they rise by at most " + ", ".join(parts)
            + " (the chord terms, each at its worst)") if parts else ""


def _arcs_text(arcs: dict) -> str:
    """The probe's runs on arcs (docs/theory.md §10): the judged ones, and those with a slip jump."""
    jumps = arcs.get("mid_period_runs", 0)
    judged = (f"{arcs['runs']} of these states, {jumps} of them with the slip jumping within the period" if jumps else
              f"{arcs['runs']} of these states with slip constant in the period")
    dropped = arcs.get("dropped_inadmissible_memory", 0)
    if dropped:
        judged += (f"; {dropped} more dropped: their stored commands with the feedforward exceed the motor limit, a"
                   " memory never reached")
    out = (f"On arcs (the reference turning at up to {arcs['max_yaw_rate']:.3g} rad/s, the feedforward in the commands;"
           f" {judged}) the nonlinear robot reaches max V(xi+)/level = {arcs['max_V_over_level_nonlinear']:.4f}"
           + (f" ({arcs['refinement']['max_V_over_level_before']:.4f} on these states, then the local search from the"
              f" {arcs['refinement']['starts']} worst, their yaw rates kept)" if arcs.get("refinement") else "") + ". ")
    if not jumps and "mid_period_max_V_over_level_nonlinear" in arcs:
        out += (f"With the slip jumping within the period (not covered, reported) it reaches "
                f"{arcs['mid_period_max_V_over_level_nonlinear']:.4f}. ")
    return out


def lti_verification_markdown(data: dict[str, Any]) -> str:
    """verification.md of a linear plant's gain (``plant: kind: lti``), from its verification record."""
    md = [f"# Verification: {'passed' if data['passed'] else 'FAILED'}\n\n",
          (f"{data['starts']} starts on the boundary of the certified set, {data['periods']} periods of the exactly "
           f"lifted loop (lifting d = {data['lifting']}) per family (docs/theory.md §15).\n\n" if data["starts"] else
           f"The l2 gain from rest over {data['periods']} periods of the exactly lifted loop (lifting d = "
           f"{data['lifting']}) for each delay sequence (docs/theory.md §15).\n\n"),
          (f"The gain came without a certificate: one was searched ({data['certificate_searched']['kind']}, "
           f"decay {data['certificate_searched']['decay']:.7g} per period, {data['certificate_searched']['pieces']} "
           "pieces) and proven in numpy; the checks below are against it.\n\n" if data.get("certificate_searched") else ""),
          checks_table(data["checks"])]
    if data["families"]:
        first = next(iter(data["families"].values()))
        md.append("\n| family | " + " | ".join(first.keys()) + " |\n")
        md.append("|---|" + "---|" * len(first) + "\n")
        md += [f"| {name} | " + " | ".join(f"{v:.6g}" for v in f.values()) + " |\n" for name, f in data["families"].items()]
    return "".join(md)
