"""The slip-compensated law's certificate model (docs/theory.md §18): the config the certificate is built on.

A law that divides each track's command by the estimate mu_hat_i of its traction makes the track move at
``mu_i / mu_hat_i`` times the uncompensated command.  While ``|mu_i(t) - mu_hat_i| <= e`` (``slip.compensation.error``)
and ``mu_hat_i`` lies in the box (the estimate is clamped to it), that ratio lies in ``[1 - e / lo_i, 1 + e / lo_i]``,
lo_i the track's smallest traction; and the motors turn at most ``rho_max`` when the uncompensated command needs at
most ``rho_max lo_i``.  So the compensated law's certificate is the ordinary one (any kinematics) on a config whose
slip box is that ratio box, free to jump every period (the estimate moves each period; the ratio inherits no rate
bound), and whose motor limit is ``rho_max min(lo_r, lo_l)``: :func:`certificate_config`.  The assumption on e is
the theorem's condition, which the runtime monitor checks each period from the estimate's own enclosure.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["Compensation", "certificate_config", "compensation_of", "estimate_description", "AUTO_HEADROOM"]

# ``error: auto`` is this many times the estimate's a-priori bound at action (monitor.slip_estimate_bound): that bound
# is for straight driving with constant commands, and the closed loop's corrections and turns widen the estimate —
# on configs/harsh-compensated.yaml's 200 verification runs the largest half-width + lag was 1.46 times it
# (docs/theory.md §18).  A design choice, not an allowance: the condition it sets is checked every period.
AUTO_HEADROOM = 1.5


@dataclass(frozen=True)
class Compensation:
    """What a compensated model was built from: the user's ``config`` (true slip box and rate), the estimate error
    ``error`` the certificate assumes (``auto``: AUTO_HEADROOM times the a-priori ``bound["at_action"]``), the ratio box per track and
    the motor limit the certificate uses for the uncompensated command."""

    config: Any
    error: float
    error_auto: bool
    ratio: tuple[tuple[float, float], tuple[float, float]]
    max_motor_speed: float | None
    bound: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        return {"error": self.error, "error_auto": self.error_auto, "ratio_right": list(self.ratio[0]),
                "ratio_left": list(self.ratio[1]), "certificate_max_motor_speed": self.max_motor_speed,
                "a_priori": {"half": dict(self.bound["half"]), "lag": self.bound["lag"],
                             "at_action": dict(self.bound["at_action"])}}


def estimate_description(config: Any) -> dict[str, Any]:
    """The parts of a controller description (:func:`robustsynth.artifacts.gains.controller_description`) the slip
    estimate's a-priori bound reads (:func:`robustsynth.monitor.slip_estimate_bound`), from the config alone."""
    from .slip import slip_parameter_ranges

    mon, net, noise = config.monitor, config.network, config.verification.noise
    return {"sampling_time": float(net.sampling_time), "reference_speed": float(config.reference.speed),
            "track_distance": float(config.robot.track_distance),
            "monitor": {"max_rate": config.slip.max_rate, "slip_model": config.slip.model,
                        "slip_ranges": [list(r) for r in slip_parameter_ranges(config.slip)],
                        "position_noise": float(mon.noise_sigmas * noise.position),
                        "heading_noise": float(mon.noise_sigmas * noise.heading), "model_tol": float(mon.model_tol),
                        "window": int(mon.window), "tau_max": float(net.delay.max),
                        "max_lost": int(net.dropouts.max_consecutive)}}


def compensation_of(config: Any) -> Compensation | None:
    """The compensation ``config`` asks for (None without ``slip.compensation``).  ConfigError when its error
    (given, or the a-priori bound with ``auto``) leaves no positive ratio."""
    from ..errors import ConfigError
    from ..monitor import slip_estimate_bound

    comp = config.slip.compensation
    if comp is None:
        return None
    bound = slip_estimate_bound(estimate_description(config))
    auto = comp.error == "auto"
    e = AUTO_HEADROOM * max(bound["at_action"].values()) if auto else float(comp.error)
    lo_r, lo_l = float(config.slip.right.min), float(config.slip.left.min)
    if e >= min(lo_r, lo_l):
        raise ConfigError(f"slip.compensation.error: {'auto gives ' if auto else ''}{e:.3g} (auto: {AUTO_HEADROOM:g} x the "
                          "estimate's a-priori bound at action), not "
                          f"below the smallest traction {min(lo_r, lo_l):g}: compensation cannot be certified here "
                          "(less pose noise, a lower slip.max_rate or a shorter delay narrow it)")
    rho = config.robot.max_motor_speed
    return Compensation(config=config, error=e, error_auto=auto,
                        ratio=((1.0 - e / lo_r, 1.0 + e / lo_r), (1.0 - e / lo_l, 1.0 + e / lo_l)),
                        max_motor_speed=None if rho is None else float(rho) * min(lo_r, lo_l), bound=bound)


def certificate_config(config: Any, comp: Compensation) -> Any:
    """The config the compensated law's certificate is built on: the slip box replaced by the ratio box (no rate
    bound, no compensation), the motor limit by ``rho_max min(lo_r, lo_l)``; everything else as ``config``."""
    from ..config import config_from_dict, config_to_dict

    d = config_to_dict(config)
    (r_lo, r_hi), (l_lo, l_hi) = comp.ratio
    d["slip"] = {"model": "tracks", "right": {"min": r_lo, "max": r_hi}, "left": {"min": l_lo, "max": l_hi},
                 "max_rate": None, "compensation": None}
    d["robot"]["max_motor_speed"] = comp.max_motor_speed
    return config_from_dict(d)
