"""Bounds through each waypoint turn of the reference path from an ultimate-bound certificate
(docs/theory.md §10): the frame jump at a sharp corner and the periods until the state is back in the
set, or the arcs of a rounded path, which the certificate's own vertices cover."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ..verified import round_up
from .lyapunov import lyapunov_of

__all__ = ["turn_bounds", "TURN_REENTRY", "TURN_LINEARIZATION_HEADING"]


TURN_REENTRY = 1.05  # a turn ends, for the bound, when V is back below this multiple of the level


TURN_LINEARIZATION_HEADING = 0.5  # [rad]: beyond it the linearization's turn bound says little about the robot


def turn_bounds(model: Any, K: np.ndarray, cert: Mapping[str, Any], figures: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Bounds through each waypoint turn of ``reference.path`` from an ultimate-bound certificate
    (docs/theory.md §10).

    The law switches to segment i at the first sample t_k >= t_switch, delta = t_k - t_switch in
    [0, Ts): the errors change frame, ``xi' = J xi + o(delta)``, J rotating (e_x, e_y) by the turn
    angle d, ``o = (R(d) - I) [V^D delta, 0]`` on (e_x, e_y) and ``-d`` on e_theta; the stored commands
    and integrators are unchanged (as the law keeps them).  From {V <= c level} (c = 1 for the first
    turn, then what the previous turn left at this switch), ``V(xi') <= r level`` with
    ``sqrt(r level) = max_(j,k) sqrt(c level lambda_max(L_j' J' P_k J L_j)) + max_delta sqrt(o' P_k o)``
    (the triangle inequality in each P_k-norm, S_j = L_j L_j', every pair of the certificate's matrices:
    V is at most the largest over them; sqrt(o' P o) is convex in delta, so delta = 0 and Ts cover
    every sampling offset).  A straight-through waypoint (d = 0) leaves the state as it is: r = c.
    The decrease ``V+ <= (1 - alpha) V + alpha level`` then gives ``V_k <= level + (1 - alpha)^k (r - 1)
    level``: the errors stay within sqrt(r) times the set's bounds through the turn, and V is back
    below TURN_REENTRY * level after k periods.  Those are statements about the model the
    certificate is for; a turn is reported **not certified**, with the reason, when its motor peak
    exceeds robot.max_motor_speed (the commands saturate, outside every model), when its heading
    peak within a period exceeds a nonlinear certificate's heading bound (outside its channels), or
    when the next waypoint comes before the re-entry.  Floating point, not verified arithmetic."""
    ub = figures.get("ultimate_bound")
    wp = np.asarray(model.config.reference.path, dtype=float)
    if not ub or wp.shape[0] < 3 or "alpha" not in cert:
        return []
    if getattr(model, "turns", None) is not None:
        return _arc_turns(model, figures)
    lyap = lyapunov_of(model, cert)
    level = float(figures["ellipsoid_level"])
    alpha = float(cert["alpha"])
    cfg = model.config
    V, R, Ts = cfg.reference.speed, cfg.robot.gear_radius, model.Ts
    rho_max = cfg.robot.max_motor_speed
    seg = np.diff(wp, axis=0)
    headings = np.arctan2(seg[:, 1], seg[:, 0])
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    t_switch = np.cumsum(lengths)[:-1] / V
    chol = [np.linalg.cholesky(S) for S in lyap.S]
    heading_bound = figures.get("heading_bound")
    heading = float(figures.get("heading_within_period") or ub["e_theta"])  # |e_theta(t)| within a period
    out = []
    c_start = 1.0  # V at the switch <= c_start * level
    for i in range(1, headings.size):
        d = float(np.angle(np.exp(1j * (headings[i] - headings[i - 1]))))
        if d == 0.0:
            r = c_start
        else:
            cd, sd = np.cos(d), np.sin(d)
            Rd = np.array([[cd, sd], [-sd, cd]])
            J = np.eye(model.n_s)
            J[:2, :2] = Rd
            offsets = []
            for delta in (0.0, Ts):
                o = np.zeros(model.n_s)
                o[:2] = (Rd - np.eye(2)) @ np.array([V * delta, 0.0])
                o[2] = -d
                offsets.append(o)
            root = max(np.sqrt(c_start * level * max(float(np.linalg.eigvalsh(L.T @ J.T @ P @ J @ L)[-1]), 0.0))
                       + max(np.sqrt(max(float(o @ P @ o), 0.0)) for o in offsets)
                       for L in chol for P in lyap.P)
            r = round_up(root * root / level, 4)
        scale = float(np.sqrt(max(r, 1.0)))
        peak = {k: round_up(scale * float(ub[k]), 2) for k in ("e_x", "e_y", "e_theta")}
        motor = figures.get("motor_speed_bound")
        motor_peak = None if motor is None else round_up(V / R + scale * (float(motor) - V / R), 3)
        periods = 0 if r <= TURN_REENTRY else int(np.ceil(np.log((TURN_REENTRY - 1.0) / (r - 1.0)) / np.log(1.0 - alpha)))
        reentry = periods * Ts
        next_switch = float(lengths[i] / V)
        why = []
        if motor_peak is not None and rho_max is not None and motor_peak > rho_max:
            why.append(f"its motor peak {motor_peak:.3g} rad/s exceeds robot.max_motor_speed {rho_max:g}: the commands "
                       "saturate, outside the model")
        heading_peak = round_up(scale * heading, 2)
        if heading_bound is not None and heading_peak > float(heading_bound):
            why.append(f"its heading peak {heading_peak:.3g} rad within a period exceeds the certificate's heading bound "
                       f"{float(heading_bound):g} rad")
        if i < headings.size - 1 and reentry > next_switch:
            why.append(f"the next waypoint comes after {next_switch:.3g} s, before the re-entry after {reentry:.3g} s")
        note = ""
        if not why and heading_bound is None and peak["e_theta"] > TURN_LINEARIZATION_HEADING:
            note = (f"its heading peak {peak['e_theta']:.3g} rad lies beyond where the linearization holds "
                    f"(~{TURN_LINEARIZATION_HEADING:g} rad): a bound for the linearization only")
        out.append({"waypoint": i, "t_switch_s": float(t_switch[i - 1]), "turn_rad": d,
                    "V_over_level_at_switch": r, "peak": peak, "motor_speed_peak": motor_peak,
                    "periods_to_reenter": periods, "time_to_reenter_s": reentry, "certified": not why,
                    "reason": "; ".join(why), "note": note})
        # what this turn leaves at the next switch: at least floor(segment / Ts) - 1 periods of decay
        k_next = max(int(np.floor(next_switch / Ts)) - 1, 0)
        c_start = round_up(1.0 + (1.0 - alpha) ** k_next * max(r - 1.0, 0.0), 4)
    return out


def _arc_turns(model: Any, figures: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Each corner of a path rounded by arcs (reference.turn_radius): no frame jump, the reference
    turns at |w_k| <= V^D / r, which the certificate's vertices cover (model/arcs.py), so the certified
    set and its bounds hold through the turn: peak = the set's bounds for all t (``ultimate_bound_between_samples``,
    e_theta within the period), where the certificate states them (else at the samples), no re-entry."""
    from ..law import PathTable

    cfg = model.config
    r = float(cfg.reference.turn_radius)
    table = PathTable(cfg.reference.path, cfg.reference.speed, r, cfg.network.sampling_time, cfg.reference.turn_ramp)
    ub = dict(figures["ultimate_bound"])
    for k, v in (figures.get("ultimate_bound_between_samples") or {}).items():
        if v is not None and k in ub:  # review, stop 47: the table showed the sampled bound as the turn's peak
            ub[k] = max(float(ub[k]), float(v))
    wbar = float(model.turns.max_yaw_rate)
    out = []
    for i, (d, t_arc) in enumerate(table.arcs, start=1):
        out.append({"waypoint": i, "t_switch_s": t_arc, "turn_rad": d, "V_over_level_at_switch": 1.0,
                    "peak": {k: float(ub[k]) for k in ("e_x", "e_y", "e_theta")},
                    "motor_speed_peak": figures.get("motor_speed_bound"), "periods_to_reenter": 0,
                    "time_to_reenter_s": 0.0, "certified": True, "reason": "",
                    "note": (f"along an arc of radius {r:g} m (reference yaw rate up to {wbar:.3g} rad/s, which the "
                             f"certificate covers): no frame jump, the certified set holds through the turn")})
    return out
