"""Slip as the robot really feels it: ``u_eff = M(mu) u_hat`` with ``M = J H J^-1`` (docs/theory.md §2).

The paper linearizes at mu = 1, so slip only adds ``B_D d``.  The robot, however, receives
``M(mu) (u^D + du)``: slip *multiplies* the correction, and under constant slip the controller
settles at the slip-compensated command ``du* = M(mu)^-1 u^D - u^D``.  ``M`` is affine in
(mu_r, mu_l), so over the slip box it is a convex combination of its values at the box's corners
with the bilinear weights of :func:`corner_weights`.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..errors import InfeasibleError
from .kinematics import JHJinv

__all__ = ["slip_changes", "turn_feedforward", "icr_components", "icr_twist", "slip_corners", "corner_weights",
           "next_corner_weights", "slip_matrix", "lateral_row", "twist_matrix", "compensated_command", "required_motor_speeds", "check_physical_feasibility", "SLIP_PARAMETERS",
           "nominal_slip", "slip_parameter_ranges"]

_WIDTH_TOL = 1e-12

# The slip parameters of each slip.model (docs/theory.md §12): ``tracks`` is the paper's one factor
# per track; ``icr`` adds the yaw factor kappa (the robot turns at kappa times the tracks' yaw rate:
# an effective track width D / kappa) and the longitudinal offset x_icr [m] of the instantaneous
# centre of rotation (the body slides sideways at v_y = -x_icr * omega).
SLIP_PARAMETERS = {"tracks": ("mu_r", "mu_l"), "icr": ("mu_r", "mu_l", "yaw", "x_icr")}
_NOMINAL = {"mu_r": 1.0, "mu_l": 1.0, "yaw": 1.0, "x_icr": 0.0}


def slip_changes(before: np.ndarray, after: np.ndarray, t: np.ndarray) -> list:
    """Each track's slip going from ``before`` to ``after`` (..., n_p) at its own time ``t`` (..., 2) within a
    period, as the robot's list of changes in time order: ``[(t1, mu_1), (t2, after)]``, the earlier track changed
    at t1 and both at t2 (``KinematicRobot.period``'s ``switch``).  The icr model's yaw factor changes with the
    right track's time and x_icr with the left's, so its parameters change at two instants, in either order."""
    t = np.asarray(t, dtype=float)
    t1, t2 = np.minimum(t[..., 0], t[..., 1]), np.maximum(t[..., 0], t[..., 1])  # (np.min over an axis of 2: 25x slower)
    n_p = np.shape(before)[-1]
    tp = t if n_p == t.shape[-1] else t[..., [i % 2 for i in range(n_p)]]
    return [(t1, np.where(tp <= t1[..., None], after, before)), (t2, after)]


def turn_feedforward(slip_config, track_distance: float) -> np.ndarray:
    """The command (dV, omega) sent per rad/s of a turning reference's yaw rate (docs/theory.md §10, §12):
    ``(0, 1)`` for the tracks model; for the icr model the command that makes the slip box's centre twist
    turn at one rad/s, ``M_c^-1 (0, 1)`` with M_c the (v_x, omega) rows of the twist whose components (traction,
    yaw x traction, per track) sit at the middle of their ranges: a robot that turns at 0.6 of its command
    gets 1/0.6 of the yaw rate as feedforward, and the feedback corrects only the box's spread around it."""
    if getattr(slip_config, "model", "tracks") != "icr":
        return np.array([0.0, 1.0])
    comp = icr_components(slip_parameter_ranges(slip_config))
    T = icr_twist(comp.mean(axis=1), float(track_distance))
    return np.linalg.solve(T[[0, 2]], np.array([0.0, 1.0]))


def icr_components(ranges: tuple[tuple[float, float], ...]) -> np.ndarray:
    """The icr model's twist as six components (docs/theory.md §12, "Nonlinear kinematics"): per command (v, omega_c),
    ``v_x = s v + d (D/4) omega_c``, ``omega = ys omega_c + yd v / D``, ``v_y = -(xs omega_c + xd v / D)`` with
    ``s = (mu_r + mu_l) / 2``, ``d = mu_r - mu_l``, ``ys = yaw s``, ``yd = yaw d``, ``xs = x_icr yaw s``,
    ``xd = x_icr yaw d``.  Returns each component's range ``[lo, hi]`` over the slip box, shape (6, 2): every twist
    of the box, and every average of twists over time, has its components within these (each component is
    multi-affine in the parameters: its extremes are at the box's corners)."""
    p = slip_corners(*ranges)  # (n, 4)
    s, d = (p[:, 0] + p[:, 1]) / 2.0, p[:, 0] - p[:, 1]
    comp = np.stack([s, d, p[:, 2] * s, p[:, 2] * d, p[:, 3] * p[:, 2] * s, p[:, 3] * p[:, 2] * d], axis=0)
    return np.stack([comp.min(axis=1), comp.max(axis=1)], axis=1)


def icr_twist(c: np.ndarray, D: float) -> np.ndarray:
    """The twist matrix (3, 2), rows (v_x, v_y, omega) per command (v, omega_c), of the components ``c`` (6,)
    (:func:`icr_components`' order)."""
    s, d, ys, yd, xs, xd = (float(x) for x in c)
    return np.array([[s, d * D / 4.0], [-xd / D, -xs], [yd / D, ys]])


def nominal_slip(n_p: int) -> np.ndarray:
    """The parameters of a robot that does not slip: (1, 1) or (1, 1, 1, 0)."""
    names = SLIP_PARAMETERS["tracks" if n_p == 2 else "icr"]
    return np.array([_NOMINAL[n] for n in names])


def slip_parameter_ranges(slip_config) -> tuple[tuple[float, float], ...]:
    """(min, max) of each slip parameter of the config's slip.model, in :data:`SLIP_PARAMETERS` order."""
    out = [(slip_config.right.min, slip_config.right.max), (slip_config.left.min, slip_config.left.max)]
    if getattr(slip_config, "model", "tracks") == "icr":
        out += [(slip_config.yaw.min, slip_config.yaw.max), (slip_config.icr_offset.min, slip_config.icr_offset.max)]
    return tuple(out)


def _track_values(lo: float, hi: float) -> list[float]:
    return [lo] if hi - lo <= _WIDTH_TOL else [lo, hi]


def slip_corners(*ranges: tuple[float, float]) -> np.ndarray:
    """Corners of the slip box, shape (n_c, n_p), n_c = 2^(parameters with a nonzero width); a
    zero-width range gives one value, so no corner is repeated."""
    return np.array(list(itertools.product(*(_track_values(*r) for r in ranges))), dtype=float)


def corner_weights(mu: np.ndarray, *ranges: tuple[float, float]) -> np.ndarray:
    """Multilinear convex weights lambda (..., n_c) with ``sum_m lambda_m corner_m = mu``; every map
    that is affine in each parameter separately (M, the twist, the lifted matrices) is then the same
    combination of its values at the corners; the order is that of :func:`slip_corners`."""
    mu = np.asarray(mu, dtype=float)
    per_track = []
    for i, (lo, hi) in enumerate(ranges):
        if hi - lo <= _WIDTH_TOL:
            per_track.append([np.ones(mu.shape[:-1])])
        else:
            t = (mu[..., i] - lo) / (hi - lo)
            per_track.append([1.0 - t, t])
    out = [np.ones(mu.shape[:-1])]
    for w in per_track:
        out = [a * b for a in out for b in w]
    return np.stack(out, axis=-1)


def next_corner_weights(corner: np.ndarray, ranges: tuple[tuple[float, float], ...],
                        max_step: float | None) -> np.ndarray:
    """Corner weights (n_next, n_c) of the slips that can follow ``corner`` in one period.

    Without a rate bound (or a track whose range is narrower than one period's step) the next slip
    is anywhere in the box: the unit vectors.  With ``max_step`` = max_rate * Ts smaller than a
    track's width, that track's next value is ``corner +- max_step``, whose multilinear weights
    extrapolate beyond [0, 1]: a slip-dependent Lyapunov LMI is multi-affine in (mu_k, dmu), so
    holding at these vertices it holds for every mu_k in the box and |dmu| <= max_step.  The rate
    bound applies to the tracks' factors (the first two parameters); the others may jump."""
    per_track = []
    for i, (lo, hi) in enumerate(ranges):
        vals = _track_values(lo, hi)
        if len(vals) == 1 or max_step is None or max_step >= hi - lo or i >= 2:
            per_track.append(vals)
        else:
            per_track.append([corner[i] - max_step, corner[i] + max_step])
    nxt = np.array(list(itertools.product(*per_track)), dtype=float)
    return corner_weights(nxt, *ranges)  # at the corners themselves: the unit vectors


def slip_matrix(mu: np.ndarray, D: float) -> np.ndarray:
    """M(mu) = J H J^-1, shape (..., 2, 2): the (v, omega) the robot gets for a command (v, omega),
    for ``mu[..., (mu_r, mu_l)]``; with the icr parameters the yaw row is scaled by the yaw factor."""
    mu = np.asarray(mu, dtype=float)
    M = JHJinv(mu[..., 0], mu[..., 1], D)
    if mu.shape[-1] > 2:
        M[..., 1, :] *= mu[..., 2, None]
    return M


def lateral_row(mu: np.ndarray, D: float) -> np.ndarray:
    """The body's lateral velocity per command, v_y = row @ (v, omega), shape (..., 2): zero for the
    tracks model, ``-x_icr`` times the yaw row of :func:`slip_matrix` for the icr model."""
    mu = np.asarray(mu, dtype=float)
    if mu.shape[-1] <= 2:
        return np.zeros(mu.shape[:-1] + (2,))
    return -mu[..., 3, None] * slip_matrix(mu, D)[..., 1, :]


def twist_matrix(mu: np.ndarray, D: float) -> np.ndarray:
    """The body twist (v_x, v_y, omega) per command (v, omega), shape (..., 3, 2)."""
    M = slip_matrix(mu, D)
    return np.stack([M[..., 0, :], lateral_row(mu, D), M[..., 1, :]], axis=-2)


def compensated_command(mu: np.ndarray, V: float, D: float) -> np.ndarray:
    """du* = M(mu)^-1 u^D - u^D: the command deviation that makes the robot move at u^D (..., 2)."""
    uD = np.array([V, 0.0])
    M = slip_matrix(mu, D)
    return np.linalg.solve(M, np.broadcast_to(uD, M.shape[:-1])[..., None])[..., 0] - uD


def required_motor_speeds(mu: np.ndarray, V: float, R: float) -> np.ndarray:
    """rho* = J^-1 M(mu)^-1 u^D = H^-1 J^-1 u^D = (V/(R mu_r), V/(R mu_l)): what the motors must turn
    to hold the reference speed on straight ground under slip mu (..., 2)."""
    mu = np.asarray(mu, dtype=float)[..., :2]
    return V / (R * mu)


def check_physical_feasibility(config) -> None:
    """Raise :class:`InfeasibleError` (exit 3) when some slip corner cannot hold the reference within
    ``robot.max_motor_speed``: no controller can, whatever the model or the LMIs."""
    rho_max = config.robot.max_motor_speed
    if rho_max is None:
        return
    V, R = config.reference.speed, config.robot.gear_radius
    r = getattr(config.reference, "turn_radius", None)
    # on an arc of radius r the outer track runs at V^D (1 + D / (2 r))
    outer = V * (1.0 + config.robot.track_distance / (2.0 * r)) if r is not None else V
    for track, rng in (("right", config.slip.right), ("left", config.slip.left)):
        need = outer / (R * rng.min)
        if need > rho_max:
            what = (f"to hold reference.speed = {V:g} m/s (V^D / (R mu))" if r is None else
                    f"as the outer track of an arc of reference.turn_radius = {r:g} m at reference.speed = {V:g} m/s "
                    "(V^D (1 + D / 2r) / (R mu))")
            raise InfeasibleError(
                f"physically infeasible: on the {track} track with slip mu = {rng.min:g} the motor must turn at "
                f"{need:.3g} rad/s {what}, above robot.max_motor_speed = {rho_max:g} rad/s: raise robot.max_motor_speed "
                f"to at least {need:.3g}, lower reference.speed{', raise reference.turn_radius' if r is not None else ''}, "
                f"or narrow slip.{track}.min"
            )
