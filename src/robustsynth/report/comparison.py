"""Markdown of the paper-vs-slip-aware comparison (:mod:`robustsynth.comparison`)."""

from __future__ import annotations

from typing import Any

from .markdown import fmt, table

__all__ = ["comparison_markdown"]

_WHAT = {
    "paper": "the seed paper's linearization at mu = 1 (slip only adds B_D d)",
    "slip-aware": "exact in slip (it multiplies the command), linearized at the slip-compensated operating point",
}


def comparison_markdown(cmp: dict[str, Any] | None) -> str:
    if not cmp:
        return ""
    out = ["\n## Paper model vs slip-aware model, side by side\n\n"]
    nonlinear = any(r["nonlinear"] for r in cmp["rows"])
    if nonlinear:
        out.append(f"Same robot, same {cmp['runs']} Monte Carlo runs (seed {cmp['seed']}) plus the extreme and "
                   "adversarial runs; each gain is judged against its own certificate.\n\n")
    head = ["model", "status", "certified |e_y| [cm]", "certified |e_x| [cm]", "certified |rho| [rad/s]",
            "steady |e_y*| / |e_x*| under constant slip [cm]"]
    if nonlinear:
        head += ["nonlinear max |e_y| [cm]", "nonlinear max |e_x| [cm]", "max V/level", "verdict"]
    rows = []
    for r in cmp["rows"]:
        c = r["certified"] or {}
        ub = c.get("ultimate_bound") or {}
        ss = r["steady_state"] or {}
        row = [f"`{r['model']}`: {_WHAT[r['model']]}", r["status"] if not r["message"] else f"{r['status']}: {r['message']}",
               fmt(100 * ub["e_y"]) if ub else "—", fmt(100 * ub["e_x"]) if ub else "—",
               fmt(c.get("motor_speed_bound")) if c else "—",
               f"{fmt(100 * ss['e_y'])} / {fmt(100 * ss['e_x'])}" if ss else "—"]
        if nonlinear:
            nl = r["nonlinear"]
            row += [fmt(100 * nl["max"]["e_y"]), fmt(100 * nl["max"]["e_x"]), fmt(nl["max_V_over_level"], 4),
                    "passed" if nl["verification_passed"] else "**FAILED**"] if nl else ["—"] * 4
        rows.append(row)
    out.append(table(head, rows))
    out.append("\nThe paper's certificate is proven for a model the robot does not follow: under slip the robot"
               " receives `M(mu) (u^D + du)`, so the correction is multiplied by the slip, and the controller settles"
               " at a slip-compensated command. The slip-aware certificate covers that; what it still assumes is in"
               " docs/reference/verification.md, *What is proven and what is assumed*.\n")
    return "".join(out)
