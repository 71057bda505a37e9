"""What a gains file certifies, in the lines the CLI prints (synthesize, run, and :meth:`SynthesisResult.lines`): the
tracked robot's certified figures in cm and rad (with the nonlinear proof's heading bound and the compensated law's
condition), a linear plant's in its outputs' units with its delay margin."""

from __future__ import annotations

from typing import Any, Mapping

from ..objectives import labelled_figures
from ..results import Margin

__all__ = ["certified_lines", "robot_certified", "lti_gain_lines"]


def certified_lines(gains: Mapping[str, Any]) -> list[str]:
    """The certified figures of a gains mapping, any plant (a linear plant's has its ``lifting``)."""
    return lti_gain_lines(gains) if "lifting" in gains else [robot_certified(gains)]


def robot_certified(gains: Mapping[str, Any]) -> str:
    """The robot's certified figures, one line."""
    c = gains["certified"]
    parts = [f"certified ({gains['objective']}):"]
    if c.get("decay_rate") is not None:
        parts.append(f"decay rate {c['decay_rate']:.4f}")
    ub = c.get("ultimate_bound")
    if ub:
        part = (f"|e_x| <= {ub['e_x'] * 100:.2f} cm, |e_y| <= {ub['e_y'] * 100:.2f} cm, "
                f"|e_theta| <= {ub['e_theta']:.4f} rad")
        every_t = c.get("ultimate_bound_between_samples")
        if every_t:  # the samples' figures, then those for every instant (between the samples too, through the turns)
            part += (f" at the samples (for all t: |e_x| <= {every_t['e_x'] * 100:.2f} cm, "
                     f"|e_y| <= {every_t['e_y'] * 100:.2f} cm)")
        parts.append(part)
    if c.get("motor_speed_bound") is not None:
        parts.append(f"|rho| <= {c['motor_speed_bound']:.3f} rad/s")
    for key, label in labelled_figures():  # an objective's own figure (hinf's l2 gain, ...)
        if c.get(key) is not None:
            parts.append(f"{label} {c[key]:.4g}")
    if gains.get("certificate", {}).get("kinematics") == "nonlinear":
        parts.append(f"for the nonlinear robot (|e_theta(t)| <= {gains['certificate']['heading_bound']:g} rad)")
    line = " ".join(parts[:1]) + " " + ", ".join(parts[1:])
    comp = gains.get("compensation")
    if comp:  # the slip-compensated law: a conditional claim (docs/theory.md §18)
        line += (f"; slip-compensated law, while each track's traction is within {comp['error']:.4g} of the estimate "
                 f"(ratio box [{comp['ratio_right'][0]:.4f}, {comp['ratio_right'][1]:.4f}], motors at "
                 f"{comp['certificate_max_motor_speed']:.3g} rad/s before compensation)")
    return line


def _lti_certified(gd: Mapping[str, Any]) -> str:
    c = gd["certified"]
    if c.get("hinf_gain") is not None:
        parts = [f"l2 gain {c['hinf_gain']:.4g} from the disturbance (per-period peak) to "
                 + ", ".join(o["name"] for o in c["outputs"])]
    elif c.get("disturbance_step_bound") is not None:
        parts = [f"V+ <= {c['alpha']:.4f} V + {1 - c['alpha']:.4f} (invariant, attracting set)"]
    else:
        parts = [f"decay {c['decay']:.4f} per period"]
    for o in c.get("outputs") or ():
        if o.get("bound") is not None:
            parts.append(f"|{o['name']}| <= {o['bound']:.4g} {o['unit']}")
    if c.get("rest_radius") is not None:
        parts.append(f"from rest within |x| <= {c['rest_radius']:.4g}")
    if c.get("inputs"):
        parts.append("inputs within " + ", ".join(f"|{u['name']}| <= {u['limit']:g}" for u in c["inputs"]))
    return f"certified ({gd['objective']}, d = {gd['lifting']['d']}): " + ", ".join(parts)


def lti_gain_lines(gd: Mapping[str, Any]) -> list[str]:
    """A linear plant's certified gain: its figures and its delay margin."""
    if gd.get("delay_margin") is None:  # a result not yet written: synthesize adds the margin beside it
        return [_lti_certified(gd)]
    margin = Margin.from_record("delay_max", gd["delay_margin"], gd["network"]["delay"][0])  # as `margin` prints it
    return [_lti_certified(gd), "robust stability of this gain, " + margin.line()]
