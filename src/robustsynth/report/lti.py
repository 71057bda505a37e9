"""Markdown reports of a linear plant (``plant: kind: lti``): synthesis, verification, margins."""

from __future__ import annotations

from typing import Any

import numpy as np

from .markdown import margin_table
from .verification import checks_table

__all__ = ["lti_synthesis_markdown", "lti_verification_markdown", "LINEAR_READING"]

# what a linear plant's certified and exhibited margins are (margin.md, and the synthesis report's delay margin)
LINEAR_READING = ("Certified: a common quadratic Lyapunov function of the guaranteed over-approximation (docs/theory.md "
                  "§14), proven in numpy. Exhibited: a destabilizing periodic delay/loss sequence of the exactly lifted "
                  "closed loop.")


def _mat(M: Any, digits: int = 6) -> str:
    M = np.atleast_2d(np.asarray(M, dtype=float))
    return "[" + "; ".join(", ".join(f"{x:.{digits}g}" for x in row) for row in M) + "]"


def lti_synthesis_markdown(gd: dict[str, Any]) -> str:
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


def lti_verification_markdown(data: dict[str, Any]) -> str:
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
