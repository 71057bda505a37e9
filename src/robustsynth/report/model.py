"""model.json and model.md (the files of ``robustsynth build-model``)."""

from __future__ import annotations

from typing import Any

from ..config import config_to_dict
from ..model import ERROR_NAMES, SLIP_NAMES, Model
from .. import __version__
from ..artifacts.files import SCHEMA_VERSION
from .markdown import fmt, matrix_table, table

__all__ = ["model_dict", "model_markdown", "q_names", "p_names"]


def q_names(model: Model) -> list[str]:
    names = []
    for inst in model.instants:
        j = inst.j
        names += [f"q{j}.dV", f"q{j}.omega", f"q{j}.omega'"]
    return names


def p_names(model: Model) -> list[str]:
    return [n.replace("q", "p", 1) for n in q_names(model)]


def uncertainty_dict(model: Model) -> dict[str, Any]:
    blocks = []
    for b, inst in enumerate(model.instants):
        blocks.append(
            {
                "instant": inst.j,
                "structure": "diag(delta1*I2, delta2)",
                "q_rows": [3 * b, 3 * b + 1, 3 * b + 2],
                "bound": 1.0,
                "s_range": list(inst.s_range),
                "h_range": list(inst.h_range),
                "nominal": {"s": inst.s_nominal, "h": inst.h_c, "h2_half": inst.g_c},
                "scaling": {"alpha1": inst.alpha1, "alpha2": inst.alpha2},
            }
        )
    fixed = [
        {"instant": j, "s": float(model.instant_ranges[j, 0])}
        for j in range(model.d_hi)
        if j not in {i.j for i in model.instants}
    ]
    return {
        "norm_bound": 1.0,
        "blocks": blocks,
        "fixed_instants": fixed,
        "slip": {
            "d_min": list(model.slip.d_min),
            "d_max": list(model.slip.d_max),
            "W": model.slip.W,
            "w_labels": list(model.slip.labels),
            "note": "d = mu - 1 = W w, |w_i| <= 1; a non-zero centre is the column 'centre' (w = 1)",
        },
    }


def model_dict(model: Model, coverage: dict[str, Any]) -> dict[str, Any]:
    return {
        "schema_version": SCHEMA_VERSION,
        "robustsynth_version": __version__,
        "config": config_to_dict(model.user_config),
        "dimensions": {"n_e": model.n_e, "n_u": model.n_u, "n_s": model.n_s, "d_lo": model.d_lo, "d_hi": model.d_hi},
        "state_names": list(model.state_names),
        "input_names": list(model.input_names),
        "slip_names": list(SLIP_NAMES),
        "continuous": {"A": model.A_c, "B": model.B_c, "B_D": model.B_D_c},
        "lifted": {
            "A": model.A,
            "B": model.B,
            "B_d": model.B_d,
            "B_p": model.B_p,
            "C_q": model.C_q,
            "D_q": model.D_q,
        },
        "uncertainty": uncertainty_dict(model),
        "coverage_check": coverage,
    }


def model_markdown(model: Model, coverage: dict[str, Any]) -> str:
    c = model.config
    sn, un = model.state_names, model.input_names
    out = [f"# Model of `{c.name}` (kind `{model.kind}`)\n\n"]
    out.append(
        "Lifted norm-bounded model of the networked tracking error (seed paper eqs. 25, 31–33), nominal at mu = 1:\n\n"
        "    xi[k+1] = A xi[k] + B du[k] + B_d d[k] + B_p p[k],  p[k] = Delta[k] q[k],"
        "  q[k] = C_q xi[k] + D_q du[k]\n\n"
        "with `Delta[k] = blockdiag(delta1 I2, delta2, …)`, `|delta| <= 1`.\n"
    )
    out.append(kind_markdown(model))
    out.append("\n## Parameters\n\n")
    out.append(
        table(
            ["quantity", "symbol", "value", "unit"],
            [
                ["gear radius", "R", fmt(c.robot.gear_radius), "m"],
                ["track distance", "D", fmt(c.robot.track_distance), "m"],
                ["max motor speed", "rho_max", fmt(c.robot.max_motor_speed), "rad/s"],
                ["reference speed", "V^D", fmt(c.reference.speed), "m/s"],
                ["sampling time", "Ts", fmt(c.network.sampling_time), "s"],
                ["delay range", "tau", f"[{fmt(c.network.delay.min)}, {fmt(c.network.delay.max)}]", "s"],
                ["lost commands in a row", "m", str(model.dropouts), "packets"],
                ["effective delay range", "tau_eff",
                 f"[{fmt(c.network.delay.min)}, {fmt(c.network.delay.max + model.dropouts * c.network.sampling_time)}]", "s"],
                ["right slip", "mu_r", f"[{fmt(c.slip.right.min)}, {fmt(c.slip.right.max)}]", "—"],
                ["left slip", "mu_l", f"[{fmt(c.slip.left.min)}, {fmt(c.slip.left.max)}]", "—"],
                *([["yaw factor", "yaw", f"[{fmt(c.slip.yaw.min)}, {fmt(c.slip.yaw.max)}]", "—"],
                   ["ICR offset", "x_icr", f"[{fmt(c.slip.icr_offset.min)}, {fmt(c.slip.icr_offset.max)}]", "m"]]
                  if c.slip.model == "icr" else []),
                ["delay indices", "d_lo, d_hi", f"{model.d_lo}, {model.d_hi}", "samples"],
                ["lifted state size", "n_s", str(model.n_s), "—"],
                ["uncertain instants", "d_hi − d_lo", str(len(model.instants)), "—"],
            ],
        )
    )
    out.append("\n## Continuous linearization (eq. `lineare`)\n\n`A`:\n\n")
    out.append(matrix_table(model.A_c, ERROR_NAMES, ERROR_NAMES))
    out.append("\n`B`:\n\n" + matrix_table(model.B_c, ERROR_NAMES, un))
    out.append("\n`B_D`:\n\n" + matrix_table(model.B_D_c, ERROR_NAMES, SLIP_NAMES))
    out.append("\n## Lifted nominal model (eq. 25)\n\n`A`:\n\n" + matrix_table(model.A, sn, sn))
    out.append("\n`B`:\n\n" + matrix_table(model.B, sn, un))
    out.append("\n`B_d`:\n\n" + matrix_table(model.B_d, sn, SLIP_NAMES))
    out.append("\n## Norm-bounded uncertainty (eqs. 31–33)\n\n")
    if model.instants:
        qn, pn = q_names(model), p_names(model)
        out.append("`B_p`:\n\n" + matrix_table(model.B_p, sn, pn))
        out.append("\n`C_q`:\n\n" + matrix_table(model.C_q, qn, sn))
        out.append("\n`D_q`:\n\n" + matrix_table(model.D_q, qn, un))
        rows = [
            [
                inst.j,
                f"[{fmt(inst.s_range[0])}, {fmt(inst.s_range[1])}]",
                f"[{fmt(inst.h_range[0])}, {fmt(inst.h_range[1])}]",
                fmt(inst.h_c),
                fmt(inst.g_c),
                fmt(inst.alpha1),
                fmt(inst.alpha2),
            ]
            for inst in model.instants
        ]
        out.append(
            "\nΔ blocks: one `diag(delta1 I2, delta2)` per uncertain switching instant `s~_j`, acting on"
            " `du[k-j] - du[k-j-1]`. Nominal `Gamma_0 = h_c B + g_c A B` at the centre of the (h, h²/2) box.\n\n"
        )
        out.append(table(["j", "s~_j range [s]", "h range [s]", "h_c [s]", "g_c [s²]", "alpha1 [s]", "alpha2 [s²]"], rows))
    else:
        out.append("The delay is constant: no switching instant is uncertain, Δ is empty.\n")
    out.append(
        f"\nSlip deviation `d = mu - 1` in `[{fmt(model.slip.d_min[0])}, {fmt(model.slip.d_max[0])}]` (right),"
        f" `[{fmt(model.slip.d_min[1])}, {fmt(model.slip.d_max[1])}]` (left), written `d = W w`, `|w_i| <= 1`,"
        f" columns: {', '.join(model.slip.labels) or 'none'}.\n"
    )
    if c.slip.model == "icr":
        out.append(
            "\n`B_D` and `B_d` are the paper's additive slip columns, for mu_r and mu_l only. The yaw factor and the"
            " ICR offset x_icr do not appear in them: they enter at the slip-aware vertices (the slip matrix `M(mu)`"
            " and the constant column, lateral velocity included; docs/theory.md §12).\n"
        )
    out.append("\n## Coverage check\n\n")
    out.append(
        f"{coverage['samples']} (slip, switching-instant) samples (random admissible delay sequences, alternating and"
        f" constant extremes, the corners of the instant ranges, every slip corner): the exact lifted matrices of the"
        f" `{model.kind}` model and its constant term rebuilt from the {coverage['vertices']} vertices with explicit"
        f" convex weights (smallest {coverage['min_weight']:.3g}, sums off by at most {coverage['max_weight_sum_error']:.2g})"
        f" and Delta (largest |Delta_ii| = {coverage['max_abs_delta']:.6g}): largest residual"
        f" {coverage['max_residual']:.3g}. **{'passed' if coverage['passed'] else 'FAILED'}**.\n"
    )
    return "".join(out)


NEGLECTED = (
    "Exact in slip and delay; linearized once, around the slip-compensated operating point (e_theta = 0, the robot "
    "moving at u^D), where the error kinematics `e_x' = v cos e_theta - V^D`, `e_y' = v sin e_theta`, "
    "`e_theta' = w` (with `(v, w) = M(mu) u_hat`) become `e_x' = a_1`, `e_y' = V^D e_theta`, `e_theta' = a_2`, "
    "`a = M(mu)(u^D + du) - u^D`. The terms dropped, all of second order in (e_theta, a):\n\n"
    "- in `e_x'`: `-(V^D + a_1)(1 - cos e_theta)`;\n"
    "- in `e_y'`: `V^D (sin e_theta - e_theta) + a_1 sin e_theta` — i.e. the forward-speed factor "
    "`sigma = v sinc(e_theta) / V^D` is taken as 1 (it is 1 at the operating point);\n"
    "- nothing else: slip (constant within a period) multiplies every command that acts in the period exactly "
    "(`M(mu)`), the delays enter exactly through the switching instants, and the constant term "
    "`c(mu) = B~_d (mu - 1)` is exact.\n"
)


def kind_markdown(model: Model) -> str:
    """What the model kind covers, what it neglects, and its vertex description."""
    if model.kind == "paper":
        return ("\n## What this model neglects\n\nThe seed paper's linearization at `(e, du, d) = 0`: slip enters only"
                " as the additive `B_D d`. The robot really receives `M(mu) (u^D + du)` (`M = J H J^-1`), so the"
                " correction is multiplied by the slip, and the forward speed is `V^D (mu_r + mu_l)/2` at `du = 0`."
                " A certificate of this model does not hold for the robot under slip (use `synthesis.model: slip-aware`;"
                " `robustsynth verify` shows the gap). The LMIs use one vertex: the norm-bounded form below with the slip"
                " as a box disturbance `B_d W w`.\n")
    corners = ", ".join("(" + ", ".join(fmt(x) for x in m) + ")" for m in model.corners)
    combos = {"product": "every combination of them",
              "in-order": "the combinations in-order delivery needs (docs/theory.md §5: instants that share a range need "
                          "only the patterns low, tangents, high in order)",
              "in-order-common": "with every triangle on the instants' common range, the combinations in-order delivery "
                                 "needs (covers more delays than configured)"}.get(model.delay_cover, "")
    desc = ("a covering triangle for each uncertain instant: the curve (h, h²/2) lies in the triangle of its end points"
            " and the crossing of its end tangents, which contains the curve's convex hull (3 vertices per instant), "
            f"{combos}: {len(model.delay_combos) or 1} delay vertices" if model.delay_description == "polytopic" else
            "the norm-bounded embedding below (the same Delta at every slip corner, one multiplier per vertex)")
    out = ["\n## Slip-aware model\n\n", NEGLECTED,
           f"\nVertices: the {model.corners.shape[0]} slip corners ({', '.join(model.slip_names)}) = {corners} (the slip"
           f" matrix `M(mu)` is {'multi-affine' if model.icr else 'affine'} in the slip) times the delay description —"
           f" {desc}: {len(model.vertices)} vertices. At vertex i"
           " the command columns of the error rows are multiplied by `M(mu_i)` and the constant column"
           + (" (the period's error under the reference command alone, lateral velocity included: docs/theory.md §12)"
              if model.icr else " `c_i = B~_d (mu_i - 1)`")
           + " is tied to the vertex (`E_i = c_i`, `w = 1`). Treating the instants of successive"
           " periods, and slip and delay, as independent is a relaxation (it covers more than in-order delivery"
           " allows).\n"]
    if model.integral:
        out.append("\nIntegral action: states `int_e_x, int_e_y` appended last, `z[k+1] = z[k] + Ts (e_x, e_y)[k]`.\n")
    return "".join(out)
