"""The lines the CLI prints of the tracked robot's verdict (:meth:`VerificationResult.lines`): each failed check, the
verdict with the worst Monte Carlo ratios, where the robot leaves its certified set and whom that blames, the
slip-compensated law's runs and its slip jump, the waypoint turns.  Plain text from the verdict's records; the
verification report (report/verification.py) says the same sentences in Markdown."""

from __future__ import annotations

from typing import Any, Mapping

from ..objectives import listed, objective
from ..results import failed_lines

__all__ = ["verdict_lines", "robot_leaves", "compensated_line", "jump_line", "turns_line"]


def verdict_lines(result: Any, config: Any | None) -> list[str]:
    """The robot's verdict (a VerificationResult; ``config``: the config it was verified against, whose synthesis
    settings the blame of :func:`robot_leaves` reads; None: no blame said)."""
    mc = result.monte_carlo
    ratios = ", ".join(f"{k} {v:.3f}" for k, v in mc["ratio_to_certified"].items())
    lines = failed_lines(result.checks) + [
        f"verification {'passed' if result.passed else 'FAILED'}: {len(result.checks)} checks, {mc['runs']} Monte Carlo "
        "runs" + (f"; worst/certified: {ratios}" if ratios else "")]
    leaves = robot_leaves(mc, config) if config is not None else ""
    if leaves:
        lines.append(leaves)
    comp = compensated_line(mc.get("compensated"))
    if comp:
        lines.append(comp)
        jump = jump_line((mc.get("compensated") or {}).get("jump"))
        if jump:
            lines.append(jump)
    turns = turns_line(mc.get("turns") or [])
    return lines + ([turns] if turns else [])


def turns_line(turns: list[Mapping[str, Any]]) -> str | None:
    """The waypoint turns: all along arcs the certificate covers, or how many a corner's check certified."""
    if not turns:
        return None
    bad = [t for t in turns if not t["certified"]]
    if all(t.get("note", "").startswith("along an arc") for t in turns):  # reference.turn_radius
        return (f"waypoint turns: {len(turns)} of {len(turns)} certified (arcs the certificate covers; the Monte Carlo "
                "maxima include them)")
    return (f"waypoint turns (not in the verdict): {len(turns) - len(bad)} of {len(turns)} certified"
            + (f"; waypoint {bad[0]['waypoint']}: {bad[0]['reason']} (reference.turn_radius rounds the corners into "
               "arcs the certificate can cover: docs/theory.md §10)" if bad else ""))


def robot_leaves(mc: dict[str, Any], cfg: Any) -> str:
    """One sentence when the robot leaves the certified set from its boundary (the probe, on arcs too, or the
    adversary from the boundary above 1: the verdict fails on it), else '': whom it blames and what to do.
    The blame follows the exact lifted map on the same states: at most 1, the linearization (a certificate made
    with synthesis.kinematics: linearized); above, the certificate's model itself (the paper's, which leaves slip
    out of the commands).  It points to nonlinear kinematics only where the config can have them."""
    from ..verification.verdict import LEVEL_TOL

    bp = mc.get("boundary_probe") or {}
    if not bp:
        return ""
    robot = max([bp.get("max_V_over_level_nonlinear", 0.0), (bp.get("arcs") or {}).get("max_V_over_level_nonlinear", 0.0),
                 (bp.get("adversary") or {}).get("max_V_over_level", 0.0)])
    if robot <= 1.0 + LEVEL_TOL:
        return ""
    exact = bp.get("max_V_over_level_linear", 0.0)  # on straight segments (the probe runs no exact map on arcs)
    syn = cfg.synthesis
    if exact > 1.0 + LEVEL_TOL:  # above round-off: the model itself is left
        return (f"the certificate's model is not the robot's: from the boundary of its set the exact lifted map reaches "
                f"V/level {exact:.3f} and the nonlinear robot {robot:.3f}, so the verdict fails"
                + ("; the paper's model leaves slip out of the commands, synthesis.model: slip-aware keeps it"
                   if syn.model == "paper" else "") + " (docs/theory.md §7)")
    if syn.kinematics == "nonlinear":
        return (f"the robot leaves a set proven for it (V/level {robot:.3f}): the proof or its checker has a defect, or an "
                "assumption it states does not hold here; please report it with the files of this run")
    if syn.model != "slip-aware":
        hint = ("; synthesis.kinematics: nonlinear, which proves the set for the robot, needs synthesis.model: "
                "slip-aware: docs/theory.md §9")
    else:
        needs = [w for w, cond in ((f"objective {listed(lambda o: o.nonlinear_kinematics)}",
                                    not objective(syn.objective).nonlinear_kinematics),
                                   ("delay vertices (delay_description auto, polytopic or lossy-polytopic)",
                                    syn.delay_description == "norm-bounded")) if cond]
        hint = ("; synthesis.kinematics: nonlinear"
                + (f" ({', '.join(needs)})" if needs else "")
                + " proves the set for the robot, where one exists: docs/theory.md §9")
    return (f"the proof is for the robot's linearization: from the boundary of its set the nonlinear robot reaches "
            f"V/level {robot:.3f}, so the verdict fails{hint}")


def jump_line(j: Mapping[str, Any] | None) -> str | None:
    """The slip-jump experiment of the compensated law (robot_verification/compensated.jump_recovery), one line."""
    if not j:
        return None
    rec, back, lost = j["recovery_periods"], j["back_in_the_set_periods"], j["condition_lost_after"]

    def n(d: Mapping[str, Any]) -> str:
        return "never" if d["median"] is None else f"{d['median']:g} (max {d['max']}" + (
            f", never in {d['runs_never']} runs)" if d["runs_never"] else ")")

    return (f"a slip jump (not certified: the certificate assumes the rate bound; {j['runs']} runs, each track jumping by "
            f">= {j['jump_size_min']:.2f}): the condition failed {n(lost)} periods after it, held again after {n(rec)}, "
            f"the state back in its set after {n(back)}; in between V/level up to {j['max_V_over_level_in_recovery']:.1f}, "
            f"|e_x| {100 * j['max_in_recovery']['e_x']:.2f} cm, |e_y| {100 * j['max_in_recovery']['e_y']:.2f} cm")


def compensated_line(rec: Mapping[str, Any] | None) -> str | None:
    """verify's record of the slip-compensated law on the true robot (robot_verification/compensated.py), one line."""
    if not rec or rec.get("skipped"):
        return None
    first = rec["condition_first_period"]
    ratios = ", ".join(f"{k} {v:.3f}" for k, v in rec["ratio_to_certified"].items())
    box = ", ".join(f"{k} [{lo:g}, {hi:g}]" for k, (lo, hi) in zip(("mu_r", "mu_l"), rec["true_box"]))
    return (f"slip compensation, estimator in the loop ({rec['runs']} runs, true slip {box} moving at "
            f"{rec['max_rate']:g} /s): the condition (half-width + lag <= {rec['error']:.4g}) held in "
            f"{100 * rec['condition_held_share']:.1f} % of the periods (first at period {first['median']:g}, median); "
            f"where it held the robot left its set on {rec['steps_leaving_the_set']} of {rec['steps_judged']} steps "
            f"(max V/level {rec['max_V_over_level_judged']:.3f}), observed / certified {ratios}; where it did not "
            f"(mostly the estimator's first periods) it reached V/level {rec['max_V_over_level_all']:.2f}, |e_x| "
            f"{100 * rec['max_all']['e_x']:.2f} cm, |e_y| {100 * rec['max_all']['e_y']:.2f} cm")
