"""synthesis.md, the report of ``robustsynth synthesize`` (gains.json and gains.mat are
:mod:`robustsynth.artifacts.gains`)."""

from __future__ import annotations

import math

from typing import Any

import numpy as np

from ..artifacts.gains import LAW
from ..objectives import labelled_figures, objective
from .markdown import LINEAR_READING, conditions_text, fmt, margin_table, matrix_table, table

__all__ = ["synthesis_markdown", "diagnosis_markdown", "certificate_check_markdown", "lti_synthesis_markdown"]

MULTIPLIER_TEXT = {  # synthesis.runner.multiplier_used
    "structured": "one block per Delta block",
    "full": "mu I, the paper’s |Delta| <= 1",
    "diagonal": ("one scalar per channel of independent factors: the kinematic channels of docs/theory.md §9, the arc "
                 "channels of §10; synthesis.multiplier applies to norm-bounded delays only"),
    "none": "the delay vertices have no Delta; synthesis.multiplier applies to norm-bounded delays only",
}


def diagnosis_markdown(model: Any, result: Any, diagnosis: list[Any] | None) -> str:
    """Where the design is stuck: one re-synthesis per relaxed constraint (synthesis.diagnose)."""
    if not diagnosis:
        return ""
    e_y = result.certified["ultimate_bound"]["e_y"]
    rows = [[r.constraint, r.status, fmt(100 * r.e_y) if r.e_y is not None else "—",
             f"{100 * r.change:+.0f} %" if r.change is not None else "—", f"{r.time_s:.1f}"] for r in diagnosis]
    best = diagnosis[0]
    lead = (f"The certified |e_y| <= {100 * e_y:.2f} cm responds most to the **{best.name}**: "
            f"{best.constraint} gives {100 * best.e_y:.2f} cm ({100 * best.change:+.0f} %)."
            if best.change is not None else "No relaxation tried gave a certified design.")
    return ("\n## Where the design is stuck\n\n" + lead + " Each row re-solves with one constraint relaxed and "
            "everything else as configured; the relaxed designs certify their own problem, not this one.\n\n"
            + table(["relaxed", "status", "certified |e_y| [cm]", "change", "time [s]"], rows))


def synthesis_markdown(model: Any, result: Any, gd: dict[str, Any], comparison: dict[str, Any] | None = None,
                       diagnosis: list[Any] | None = None) -> str:
    cfg = model.config
    figs = result.certified
    c = gd["certificate"]
    out = [f"# Synthesis for `{cfg.name}`\n\n"]
    out.append(f"**Objective `{result.objective}`**: {objective(result.objective).text}.\n\n")
    out.append(f"Written with `gains.json` whose `gains_id` is `{gd['gains_id']}`.\n\n")
    out.append(
        f"Control law `{LAW}` on the lifted state ({', '.join(model.state_names)}); applied command "
        + ("`u_hat = [V^D, w_k] + du` (w_k: the turning reference's yaw rate, up to "
           f"{model.turns.max_yaw_rate:.3g} rad/s, which the certificate covers)" if getattr(model, "turns", None) is not None
           else "`u_hat = [V^D, 0] + du`")
        + f". Multiplier: `{result.multiplier}` ({MULTIPLIER_TEXT[result.multiplier]}).\n\n"
    )
    out.append("## Assumptions\n\n")
    rate = cfg.slip.max_rate
    out.append(
        f"- delays tau in [{cfg.network.delay.min:g}, {cfg.network.delay.max:g}] s, sampling Ts = {cfg.network.sampling_time:g} s,"
        f" d_lo = {model.d_lo}, d_hi = {model.d_hi}, in-order delivery, "
        + ("no packet loss;\n" if not model.dropouts else
           f"at most {model.dropouts} commands lost in a row (the actuator holds the last one received; covered as an "
           f"effective delay of up to {cfg.network.delay.max + model.dropouts * cfg.network.sampling_time:g} s);\n")
        + f"- slip mu_r in [{cfg.slip.right.min:g}, {cfg.slip.right.max:g}], mu_l in [{cfg.slip.left.min:g}, {cfg.slip.left.max:g}], "
        + (f"yaw factor in [{cfg.slip.yaw.min:g}, {cfg.slip.yaw.max:g}], x_icr in [{cfg.slip.icr_offset.min:g}, "
           f"{cfg.slip.icr_offset.max:g}] m (slip.model icr: lateral sliding, docs/theory.md §12), "
           if cfg.slip.model == "icr" else "")
        + _within_text(result.certified.get("slip_within_period"), len(model.covering_vertices or model.varying),
                       model.icr and len(model.covering_vertices) == len(model.vertices))
        + ("free to jump anywhere in its range every period" if rate is None else
        f"changing at most {rate:g} /s (" + (f"the {cfg.synthesis.lyapunov} certificate uses the rate bound"
                                              if cfg.synthesis.lyapunov != "common" else
                                              "a common Lyapunov matrix does not use the rate bound")
        + "; verification's profiles respect it)")
        + ";\n"
    )
    out.append(_model_text(model, result))
    out.append("## Certified figures\n\n")
    ub = figs.get("ultimate_bound") or {}
    rows = [
        ["robust stability", fmt(figs.get("robust_stability")), "—"],
        ["decay rate r (V(xi[k+1]) <= r² V(xi[k]) without slip)", fmt(figs.get("decay_rate")), "per step"],
        ["bound on |e_x|", fmt(ub.get("e_x")) if ub else "—", "m"],
        ["bound on |e_y|", fmt(ub.get("e_y")) if ub else "—", "m"],
        ["bound on |e_theta|", fmt(ub.get("e_theta")) if ub else "—", "rad"],
        ["bound on |e_x(t)| for all t (between samples too)", fmt((figs.get("ultimate_bound_between_samples") or {}).get("e_x")), "m"],
        ["bound on |e_y(t)| for all t (between samples too)", fmt((figs.get("ultimate_bound_between_samples") or {}).get("e_y")), "m"],
        ["bound on |e_theta(t)| for all t (between samples too)", fmt(figs.get("heading_within_period")), "rad"],
        ["bound on |rho_r|, |rho_l| on the ellipsoid", fmt(figs.get("motor_speed_bound")), "rad/s"],
    ] + [[label, fmt(figs.get(key)), "—"] for key, label in labelled_figures()]
    out.append(table(["quantity", "value", "unit"], rows))
    if ub:
        out.append(
            f"\nThe bounds hold on the set `xi' P xi <= {c['ellipsoid_level']:.6g}`"
            + (" (P = S(mu)^-1, one matrix per slip corner; the bounds are the largest over the corners)"
               if c.get("lyapunov") == "slip-dependent" else
               " (for every delay vertex d, P = S(mu, d)^-1, one matrix per slip corner and delay vertex: the set is the"
               " intersection over d, so it needs no knowledge of the delay; the bounds are the largest over the matrices)"
               if c.get("lyapunov") == "delay-dependent" else
               " (P = S(mu, prev, b)^-1 for the previous period's delay weights prev and every delay vertex b, one matrix"
               " per slip corner and pair of delay vertices; the bounds are the largest over the matrices)"
               if c.get("lyapunov") == "path-dependent" else "")
            + f", which every trajectory enters (V decays at least as `(1-alpha)^k`, alpha = {c['alpha']:.4g}) and never leaves."
            f" In centimetres: |e_y| <= {100 * ub['e_y']:.2f} cm, |e_x| <= {100 * ub['e_x']:.2f} cm.\n"
        )
    if cfg.robot.max_motor_speed is not None:
        out.append(
            f"\nMotor-speed limit rho_max = {cfg.robot.max_motor_speed:g} rad/s "
            f"{'enforced as an LMI on the ellipsoid' if c['motor_limits_enforced'] else 'not enforced by this objective'}.\n"
        )
    out.append("\n## Gain\n\n" + matrix_table(np.asarray(result.K), model.input_names, model.state_names))
    out.append(certificate_check_markdown(c))
    out.append(_search_markdown(result))
    s = gd["solver"]
    out.append(
        f"\n## Solver\n\n{s['name']} {s['version']}, status `{s['status']}`, {s['iterations']} iterations in the final"
        f" solve, {result.solver['solves']} solves in all, {s['solve_time_s']:.3f} s solving;"
        f" fallback used: {'yes' if s['fallback_used'] else 'no'}.\n"
    )
    if result.notes:
        out.append("\nNotes: " + "; ".join(result.notes) + ".\n")
    from .comparison import comparison_markdown

    out.append(comparison_markdown(comparison))
    out.append(diagnosis_markdown(model, result, diagnosis))
    return "".join(out)


def _model_text(model: Any, result: Any) -> str:
    """The assumption the model makes: the paper's linearization, the nonlinear kinematics' channels, or the
    slip-aware linearization."""
    cfg = model.config
    out = []
    if model.kind == "paper":
        out.append(
            "- model `paper`: the seed paper's linearization at mu = 1 (slip only as the additive box `B_d W w`); the"
            " robot does not follow it under slip (see model.md), so these guarantees are for the paper's model only;\n\n"
        )
    elif result.certificate.get("kinematics") == "nonlinear":
        hb = result.certificate["heading_bound"]
        out.append(
            f"- model `slip-aware` with **nonlinear kinematics**: exact in slip and delay, and the terms the linearization"
            f" drops (docs/theory.md §2) are covered over the exact arcs of each period as bounded channels, valid while"
            f" |e_theta(t)| <= {hb:g} rad — which the certificate proves on its own set (docs/theory.md §9). Assumed:"
            + (" the kinematic model itself (the icr model: per-track traction, a yaw factor, the body sliding sideways"
               " at v_y = -x_icr omega; slip as an instantaneous map of the commands, no dynamics), " if model.icr else
               " the kinematic model itself (tracks as the paper's slip factors), ")
            + ("slip free to change within a period (covered, above)" if result.certified.get("slip_within_period") == "covered"
               else "slip constant within a period")
            + f", {_path_text(model)}, in-order delivery. LMIs at {len(model.vertices)}"
            f" vertices ({model.corners.shape[0]} slip corners, delays {model.delay_description},"
            f" {model.vertices[0].n_q} kinematic channels each), Lyapunov matrix `{cfg.synthesis.lyapunov}`"
            + (", integral action on e_x, e_y" if model.integral else "") + ".\n\n"
        )
    else:
        out.append(
            f"- model `slip-aware`: exact in slip and delay, linearized at the slip-compensated operating point; the"
            f" neglected terms (model.md) are of second order in (e_theta, speed deviation) — the forward-speed factor"
            f" sigma is taken as 1 (synthesis.kinematics: nonlinear covers them); {_path_text(model)}."
            f" LMIs at {len(model.vertices)} vertices ({model.corners.shape[0]} slip corners,"
            f" delays {model.delay_description}), Lyapunov matrix `{cfg.synthesis.lyapunov}`"
            + (", integral action on e_x, e_y" if model.integral else "") + ".\n\n"
        )
    return "".join(out)


def _search_markdown(result: Any) -> str:
    """The search's section: the alpha line search or the decay-rate bisection, point by point ('' without one)."""
    out = []
    if result.search:
        out.append("\n## Search\n\n")
        if "alpha" in result.search[0] or "alpha_interval" in result.search[0]:
            rows = [[_alpha_cell(p), _result_cell(p), fmt(p["objective"]) if p.get("objective") is not None else "—"]
                    for p in sorted(result.search, key=_alpha_key)]
            out.append("Line search over alpha (objective: sum of weight x bound² over e_x, e_y, e_theta; an interval: "
                       "a phase-1 problem over it, docs/theory.md §6j):\n\n")
            out.append(table(["alpha", "result", "objective"], rows))
        elif "r" in result.search[0]:
            rows = [[fmt(p["r"], 6), p["status"]] for p in result.search]
            out.append("Bisection on the decay rate r (in the order solved):\n\n")
            out.append(table(["r", "result"], rows))
    return "".join(out)


def _alpha_key(p: dict[str, Any]) -> float:
    """Where a search point sits on the alpha axis: its alpha, or the middle (in log alpha) of a phase-1 interval."""
    if "alpha" in p:
        return float(p["alpha"])
    a, b = p["alpha_interval"]
    return math.sqrt(a * b)


def _alpha_cell(p: dict[str, Any]) -> str:
    return fmt(p["alpha"]) if "alpha" in p else f"[{fmt(p['alpha_interval'][0])}, {fmt(p['alpha_interval'][1])}]"


def _result_cell(p: dict[str, Any]) -> str:
    """The point's outcome; a phase-1 interval's with its t* (below 0: no set in the interval)."""
    if "alpha_interval" not in p:
        return p["status"]
    t = p.get("t")
    return f"{p['status']} ({p['by']}, " + ("the solver failed" if t is None else f"t* = {t:.3g}") + ")"


def certificate_check_markdown(c: dict[str, Any]) -> str:
    """The certificate check: each family of conditions re-checked in numpy, and in all how many LMIs
    (markdown.conditions_text, the count verification.md gives for the same re-check)."""
    out = ["\n## Certificate check (numpy, independent of the solver)\n\n"]
    out.append(
        f"Each LMI L was rebuilt in numpy from the written values (`Q`, `M`, `Y = K Q`) and must satisfy"
        f" L >= {0.5 * c['margin']:.3g} I (half the solve margin {c['margin']:.3g}). This is **proven in verified"
        " arithmetic**: L minus that threshold, minus a bound on the rounding of L's own assembly, passes Rump's"
        " floating-point Cholesky test (BIT 46, 2006; docs/theory.md §7). The smallest eigenvalue (eigvalsh) is shown"
        " beside it; the rounding allowance is the part of the margin the proof sets aside for rounding.\n\n"
    )
    crow = []
    for ch in c["checks"]:
        val = ch.get("margin_found")
        if ch["passed"]:
            verdict = "proven" if ch.get("verified") else "pass"
        else:
            verdict = "**not proven (rounding)**" if ch.get("status") == "not proven (rounding)" else "**FAIL**"
        crow.append([
            ch["name"],
            f"{val:.3e}" if val is not None else fmt(ch.get("value")),
            f">= {-ch['threshold']:.3e}" if val is not None else f"<= {fmt(ch['threshold'])}",
            f"{ch['rounding_allowance']:.1e}" if ch.get("rounding_allowance") is not None else "—",
            verdict,
        ])
    out.append(table(["check", "smallest eigenvalue / value", "required", "rounding allowance", "result"], crow))
    # the same count verification.md gives for its re-check (issue 50: "5 conditions" there, "108" here)
    out.append(f"\nIn all: {conditions_text(c['checks'], 'this table')}; verification.md counts its re-check the same way.\n")
    return "".join(out)


def _path_text(model: Any) -> str:
    """What the certificate assumes of the path: straight segments, or the arcs of a turning reference."""
    turns = getattr(model, "turns", None)
    if turns is None:
        return "straight segments (the turns at waypoints are not covered)"
    return (f"a reference along arcs with yaw rate |w| <= {turns.max_yaw_rate:.4g} rad/s, steps <= {turns.max_step:.4g} "
            "rad/s between periods (reference.turn_radius: the rounded corners are covered, docs/theory.md §10)")


def _within_text(within: str | None, n: int, icr_channels: bool = False) -> str:
    """How the certificate treats slip that changes between sampling instants (docs/theory.md §11, §12); ``n``: the
    within-period vertices, ``icr_channels``: the icr model's channels alone cover it."""
    if within == "covered" and icr_channels:
        return ("free to change at any time, also within a sampling period (covered: channels bound the map's deviation "
                "from the constant-slip vertices' hull, docs/theory.md §12), ")
    if within == "covered":
        return (f"free to change at any time, also within a sampling period (covered: the LMI holds at {n} vertices of"
                " the slip's averages over each command interval, docs/theory.md §11, §12), ")
    if within:
        return f"**assumed constant within a sampling period** ({within.removeprefix('assumed constant: ')}), "
    return "constant within a sampling period, "


# ------------------------------------------------------------------ a linear plant (plant: kind: lti)


def _mat(M: Any, digits: int = 6) -> str:
    M = np.atleast_2d(np.asarray(M, dtype=float))
    return "[" + "; ".join(", ".join(f"{x:.{digits}g}" for x in row) for row in M) + "]"


def lti_synthesis_markdown(gd: dict[str, Any]) -> str:
    """synthesis.md of a linear plant's gain (``plant: kind: lti``), from its gains mapping."""
    c, cert, net, lift = gd["certified"], gd["certificate"], gd["network"], gd["lifting"]
    md = ["# Synthesis: a linear plant over the network\n\n",
          f"Config {gd['config']['name']}: n = {lift['n']}, m = {lift['m']}, Ts = {net['sampling_time']:g} s, delays "
          f"[{net['delay'][0]:g}, {net['delay'][1]:g}] s, up to {net['max_consecutive']} lost commands in a row.\n\n",
          f"**Law.** {gd['law']} with d = {lift['d']}:\n\n    K = {_mat(gd['K'])}\n\n",
          f"**Objective:** {gd['objective']}. **Certified** (docs/theory.md §15), for every admissible delay and loss "
          "sequence:\n\n"]
    if c.get("hinf_gain") is not None:
        md.append(f"- from rest, sum_k |y_k|^2 <= gamma^2 sum_k sup_(period k) ||w(t)||^2 with gamma = "
                  f"{c['hinf_gain']:.6g} (the l2 gain from the disturbance to the outputs "
                  f"{', '.join(o['name'] for o in c['outputs'])}; a disturbance of peak ||w|| over a period moves the "
                  f"state by at most {c['per_period_gain']:.6g} ||w||); input limits are not enforced;\n")
    elif c.get("disturbance_step_bound") is not None:
        md.append(f"- the set {{xi' P xi <= 1}} is invariant and attracts every trajectory: V+ <= alpha V + (1 - alpha) "
                  f"with alpha = {c['alpha']:.6g} (sqrt: {c['decay']:.6g} per period), for every disturbance with "
                  f"||w(t)|| <= the configured bound (per period: ||d_k|| <= {c['disturbance_step_bound']:.6g});\n")
        md.append("- on it, the outputs:\n\n| output | bound |\n|---|---|\n")
        md += [f"| {o['name']} | {o['bound']:.6g} {o['unit']} |\n" for o in c["outputs"]]
        md.append("\n")
    else:
        md.append(f"- V = xi' P xi shrinks by alpha = {c['alpha']:.6g} per period (|xi|_P by {c['decay']:.6g});\n")
        if c.get("rest_radius") is not None:
            md.append(f"- every state at rest (past commands zero) with |x| <= {c['rest_radius']:.6g} lies in "
                      "{xi' P xi <= 1}, which the trajectories never leave;\n")
    if c.get("inputs"):
        md.append("- |u_i| <= its limit for every state of {xi' P xi <= 1}: "
                  + ", ".join(f"{u['name']} <= {u['limit']:g}" for u in c["inputs"]) + ".\n")
    md.append(f"\n**Proof.** A common quadratic Lyapunov function of the guaranteed over-approximation ({cert['pieces']} "
              f"pieces per switching instant, {cert['vertices']} vertices), found by the LMIs and re-checked in numpy in "
              f"verified arithmetic on the primal form with K itself (min eigenvalue of the negated blocks "
              f"{cert['check'].get('min_eig', float('nan')):.3g}). {gd['solver']['solves']} solves, "
              f"{gd['solver']['time_s']:.2f} s.\n\n")
    md.append(f"    P = {_mat(cert['P'])}\n")
    if gd.get("delay_margin"):
        md.append("\n**Delay margin** of this gain (robust stability, V shrinking by a common quadratic function, as "
                  "`robustsynth margin` finds it):\n\n")
        md += margin_table({"delay_max": gd["delay_margin"]}, LINEAR_READING)
    return "".join(md)
