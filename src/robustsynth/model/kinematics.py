"""Robot kinematics (paper section 1, eqs. 2, U_t, eq.9-eq.12)."""

from __future__ import annotations

import numpy as np

__all__ = ["J_matrix", "J_inverse", "H_matrix", "G_matrix", "JHJinv", "motor_speeds"]


def J_matrix(R: float, D: float) -> np.ndarray:
    """J = [[R/2, R/2], [R/D, -R/D]]: motor speeds rho -> body velocities u (eq. U_t with H = I)."""
    return np.array([[R / 2.0, R / 2.0], [R / D, -R / D]])


def J_inverse(R: float, D: float) -> np.ndarray:
    """J^-1 = [[1/R, D/(2R)], [1/R, -D/(2R)]]: commanded velocities -> nominal motor speeds (eq. 9)."""
    return np.array([[1.0 / R, D / (2.0 * R)], [1.0 / R, -D / (2.0 * R)]])


def H_matrix(mu_r: float, mu_l: float) -> np.ndarray:
    """H = diag(mu_r, mu_l): slip coefficients (eq. H_mu)."""
    return np.diag([mu_r, mu_l])


def G_matrix(theta: float) -> np.ndarray:
    """G(theta): body velocities -> pose rates (eq. 2)."""
    return np.array([[np.cos(theta), 0.0], [np.sin(theta), 0.0], [0.0, 1.0]])


def JHJinv(mu_r: np.ndarray | float, mu_l: np.ndarray | float, D: float) -> np.ndarray:
    """J H J^-1 in closed form (affine in mu); broadcasts over arrays of mu, shape (..., 2, 2).

    ``u_eff = J H J^-1 u_hat`` is the velocity the robot really gets (eq. 12).
    """
    mu_r = np.asarray(mu_r, dtype=float)
    mu_l = np.asarray(mu_l, dtype=float)
    s = (mu_r + mu_l) / 2.0
    d = mu_r - mu_l
    out = np.empty(np.broadcast(mu_r, mu_l).shape + (2, 2))
    out[..., 0, 0] = s
    out[..., 0, 1] = d * D / 4.0
    out[..., 1, 0] = d / D
    out[..., 1, 1] = s
    return out


def motor_speeds(u_hat: np.ndarray, R: float, D: float) -> np.ndarray:
    """Nominal motor speeds rho_hat = J^-1 u_hat (eq. 9); ``u_hat`` has shape (..., 2)."""
    return np.asarray(u_hat) @ J_inverse(R, D).T
