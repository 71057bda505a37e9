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

__all__ = ["slip_corners", "corner_weights", "next_corner_weights", "slip_matrix", "compensated_command", "required_motor_speeds",
           "check_physical_feasibility"]

_WIDTH_TOL = 1e-12


def _track_values(lo: float, hi: float) -> list[float]:
    return [lo] if hi - lo <= _WIDTH_TOL else [lo, hi]


def slip_corners(mu_r: tuple[float, float], mu_l: tuple[float, float]) -> np.ndarray:
    """Corners (mu_r, mu_l) of the slip box, shape (n_c, 2), n_c in {1, 2, 4}; a zero-width range
    gives one value, so no corner is repeated."""
    return np.array(list(itertools.product(_track_values(*mu_r), _track_values(*mu_l))), dtype=float)


def corner_weights(mu: np.ndarray, mu_r: tuple[float, float], mu_l: tuple[float, float]) -> np.ndarray:
    """Bilinear convex weights lambda (..., n_c) with ``sum_m lambda_m corner_m = mu`` and, since M is
    affine in mu, ``sum_m lambda_m M(corner_m) = M(mu)``; the order is that of :func:`slip_corners`."""
    mu = np.asarray(mu, dtype=float)
    per_track = []
    for i, (lo, hi) in enumerate((mu_r, mu_l)):
        if hi - lo <= _WIDTH_TOL:
            per_track.append([np.ones(mu.shape[:-1])])
        else:
            t = (mu[..., i] - lo) / (hi - lo)
            per_track.append([1.0 - t, t])
    return np.stack([a * b for a, b in itertools.product(*per_track)], axis=-1)


def next_corner_weights(corner: np.ndarray, mu_r: tuple[float, float], mu_l: tuple[float, float],
                        max_step: float | None) -> np.ndarray:
    """Corner weights (n_next, n_c) of the slips that can follow ``corner`` in one period.

    Without a rate bound (or a track whose range is narrower than one period's step) the next slip
    is anywhere in the box: the unit vectors.  With ``max_step`` = max_rate * Ts smaller than a
    track's width, that track's next value is ``corner +- max_step``, whose bilinear weights
    extrapolate beyond [0, 1]: a slip-dependent Lyapunov LMI is multi-affine in (mu_k, dmu), so
    holding at these vertices it holds for every mu_k in the box and |dmu| <= max_step."""
    per_track = []
    for i, (lo, hi) in enumerate((mu_r, mu_l)):
        vals = _track_values(lo, hi)
        if len(vals) == 1 or max_step is None or max_step >= hi - lo:
            per_track.append(vals)
        else:
            per_track.append([corner[i] - max_step, corner[i] + max_step])
    nxt = np.array(list(itertools.product(*per_track)), dtype=float)
    return corner_weights(nxt, mu_r, mu_l)  # at the corners themselves: the unit vectors


def slip_matrix(mu: np.ndarray, D: float) -> np.ndarray:
    """M(mu) = J H J^-1, shape (..., 2, 2), for ``mu[..., (mu_r, mu_l)]``."""
    mu = np.asarray(mu, dtype=float)
    return JHJinv(mu[..., 0], mu[..., 1], D)


def compensated_command(mu: np.ndarray, V: float, D: float) -> np.ndarray:
    """du* = M(mu)^-1 u^D - u^D: the command deviation that makes the robot move at u^D (..., 2)."""
    uD = np.array([V, 0.0])
    return np.linalg.solve(slip_matrix(mu, D), np.broadcast_to(uD, np.shape(mu))[..., None])[..., 0] - uD


def required_motor_speeds(mu: np.ndarray, V: float, R: float) -> np.ndarray:
    """rho* = J^-1 M(mu)^-1 u^D = H^-1 J^-1 u^D = (V/(R mu_r), V/(R mu_l)): what the motors must turn
    to hold the reference speed on straight ground under slip mu (..., 2)."""
    mu = np.asarray(mu, dtype=float)
    return V / (R * mu)


def check_physical_feasibility(config) -> None:
    """Raise :class:`InfeasibleError` (exit 3) when some slip corner cannot hold the reference within
    ``robot.max_motor_speed``: no controller can, whatever the model or the LMIs."""
    rho_max = config.robot.max_motor_speed
    if rho_max is None:
        return
    V, R = config.reference.speed, config.robot.gear_radius
    for track, rng in (("right", config.slip.right), ("left", config.slip.left)):
        need = V / (R * rng.min)
        if need > rho_max:
            raise InfeasibleError(
                f"physically infeasible: on the {track} track with slip mu = {rng.min:g} the motor must turn at "
                f"{need:.3g} rad/s to hold reference.speed = {V:g} m/s (V^D / (R mu)), above robot.max_motor_speed = "
                f"{rho_max:g} rad/s: raise robot.max_motor_speed to at least {need:.3g}, lower reference.speed, or narrow "
                f"slip.{track}.min"
            )
