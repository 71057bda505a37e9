"""Independent, numpy-only re-check of an LMI certificate (math.md §5-6).

The LMIs are rebuilt from the certificate's values (``Q``, the multiplier ``M``, ``beta``,
``alpha`` / ``r2`` / ``gamma2``) and the gain ``K`` *as written* (``Y = K Q``), never from the
solver's internal variables; each must have its largest eigenvalue at most ``-threshold``.
The certified figures (decay rate, ellipsoid bounds in m and rad, motor-speed bound in rad/s,
l2 gain) are computed here from the same values, so every number written as certified has
passed this check.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

__all__ = [
    "CHECK_FRACTION",
    "CertificateCheck",
    "check_certificate",
    "lmi_stability",
    "lmi_invariance",
    "lmi_hinf",
    "multiplier_structure_error",
]

# A certificate passes when every LMI satisfies  lambda_max <= -CHECK_FRACTION * margin,
# i.e. it keeps at least this fraction of the margin it was solved with.
CHECK_FRACTION = 0.5
SYMMETRY_TOL = 1e-9  # relative asymmetry allowed in Q and M read from a file


@dataclass(frozen=True)
class CertificateCheck:
    passed: bool
    checks: tuple[dict[str, Any], ...]
    figures: dict[str, Any] = field(default_factory=dict)
    reason: str = ""

    @property
    def min_eig_margin(self) -> float:
        """Smallest -lambda_max over the LMIs (the margin actually found)."""
        vals = [c["margin_found"] for c in self.checks if c.get("margin_found") is not None]
        return float(min(vals)) if vals else float("nan")


def _sym(X: np.ndarray) -> np.ndarray:
    return (X + X.T) / 2.0


def lmi_stability(A, B, Bp, Cq, Dq, Q, Y, M, r2):
    """[[-r2 Q, (AQ+BY)^T, (CqQ+DqY)^T], [AQ+BY, -Q + Bp M Bp^T, 0], [CqQ+DqY, 0, -M]]  (math.md §5a)."""
    AQ = A @ Q + B @ Y
    n_s, n_q = Q.shape[0], M.shape[0]
    if n_q == 0:
        return _sym(np.block([[-r2 * Q, AQ.T], [AQ, -Q]]))
    CQ = Cq @ Q + Dq @ Y
    Z = np.zeros((n_s, n_q))
    return _sym(np.block([[-r2 * Q, AQ.T, CQ.T], [AQ, -Q + Bp @ M @ Bp.T, Z], [CQ, Z.T, -M]]))


def lmi_invariance(A, B, Bp, Cq, Dq, Bw, Q, Y, M, beta, alpha):
    """V(xi+) <= (1-alpha) V(xi) + sum beta_i w_i^2 for all |Delta| <= 1 (math.md §5b), as

    [[-(1-alpha) Q, 0, (AQ+BY)^T, (CqQ+DqY)^T], [0, -diag(beta), Bw^T, 0],
     [AQ+BY, Bw, -Q + Bp M Bp^T, 0], [CqQ+DqY, 0, 0, -M]]."""
    AQ = A @ Q + B @ Y
    n_s, n_q, n_w = Q.shape[0], M.shape[0], Bw.shape[1]
    Zsw = np.zeros((n_s, n_w))
    rows = [
        [-(1.0 - alpha) * Q, Zsw, AQ.T],
        [Zsw.T, -np.diag(beta), Bw.T],
        [AQ, Bw, -Q + (Bp @ M @ Bp.T if n_q else 0.0)],
    ]
    if n_q:
        CQ = Cq @ Q + Dq @ Y
        rows[0].append(CQ.T)
        rows[1].append(np.zeros((n_w, n_q)))
        rows[2].append(np.zeros((n_s, n_q)))
        rows.append([CQ, np.zeros((n_q, n_w)), np.zeros((n_q, n_s)), -M])
    return _sym(np.block(rows))


def lmi_hinf(A, B, Bp, Cq, Dq, Bd, Cz, Q, Y, M, gamma2):
    """Bounded-real LMI with the uncertainty (math.md §5d):
    [[-Q, 0, (AQ+BY)^T, (Cz Q)^T, (CqQ+DqY)^T], [0, -g I, Bd^T, 0, 0],
     [AQ+BY, Bd, -Q + Bp M Bp^T, 0, 0], [Cz Q, 0, 0, -I, 0], [CqQ+DqY, 0, 0, 0, -M]]."""
    AQ = A @ Q + B @ Y
    CzQ = Cz @ Q
    n_s, n_q, n_d, n_z = Q.shape[0], M.shape[0], Bd.shape[1], Cz.shape[0]
    Z = np.zeros
    rows = [
        [-Q, Z((n_s, n_d)), AQ.T, CzQ.T],
        [Z((n_d, n_s)), -gamma2 * np.eye(n_d), Bd.T, Z((n_d, n_z))],
        [AQ, Bd, -Q + (Bp @ M @ Bp.T if n_q else 0.0), Z((n_s, n_z))],
        [CzQ, Z((n_z, n_d)), Z((n_z, n_s)), -np.eye(n_z)],
    ]
    if n_q:
        CQ = Cq @ Q + Dq @ Y
        rows[0].append(CQ.T)
        rows[1].append(Z((n_d, n_q)))
        rows[2].append(Z((n_s, n_q)))
        rows[3].append(Z((n_z, n_q)))
        rows.append([CQ, Z((n_q, n_d)), Z((n_q, n_s)), Z((n_q, n_z)), -M])
    return _sym(np.block(rows))


def multiplier_structure_error(M: np.ndarray, n_blocks: int, kind: str) -> str:
    """'' when M has the structure the S-procedure needs for Delta = blockdiag(d1 I2, d2, ...)."""
    n = 3 * n_blocks
    if M.shape != (n, n):
        return f"multiplier has shape {M.shape}, expected {(n, n)}"
    allowed = np.zeros((n, n), dtype=bool)
    for b in range(n_blocks):
        allowed[3 * b : 3 * b + 2, 3 * b : 3 * b + 2] = True
        allowed[3 * b + 2, 3 * b + 2] = True
    if np.any(M[~allowed] != 0.0):
        return "multiplier has entries outside the blocks of Delta (the S-procedure would not hold)"
    if kind == "full" and n and not np.allclose(M, M[0, 0] * np.eye(n), rtol=0, atol=0):
        return "a 'full' multiplier must be mu * I"
    return ""


def _arr(x: Any, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"certificate.{name} has non-finite entries")
    return a


def _symmetric(X: np.ndarray, name: str) -> str:
    scale = max(1.0, float(np.max(np.abs(X), initial=0.0)))
    if X.ndim != 2 or X.shape[0] != X.shape[1]:
        return f"{name} is not square"
    if np.max(np.abs(X - X.T), initial=0.0) > SYMMETRY_TOL * scale:
        return f"{name} is not symmetric"
    return ""


def _item(name: str, lam_max: float, threshold: float) -> dict[str, Any]:
    return {
        "name": name,
        "max_eig": float(lam_max),
        "threshold": float(-threshold),
        "margin_found": float(-lam_max),
        "passed": bool(lam_max <= -threshold),
    }


def check_certificate(model: Any, K: np.ndarray, cert: Mapping[str, Any]) -> CertificateCheck:
    """Re-check ``cert`` for gain ``K`` on ``model``; never raises on a bad certificate."""
    try:
        return _check(model, K, cert)
    except (KeyError, ValueError, TypeError, np.linalg.LinAlgError) as exc:
        return CertificateCheck(False, (), {}, f"certificate unreadable: {exc}")


def _check(model: Any, K: np.ndarray, cert: Mapping[str, Any]) -> CertificateCheck:
    objective = cert["objective"]
    K = _arr(K, "K")
    n_s, n_u = model.n_s, model.n_u
    if K.shape != (n_u, n_s):
        return CertificateCheck(False, (), {}, f"K has shape {K.shape}, expected {(n_u, n_s)}")
    Q = _arr(cert["Q"], "Q")
    if Q.shape != (n_s, n_s):
        return CertificateCheck(False, (), {}, f"Q has shape {Q.shape}, expected {(n_s, n_s)}")
    mult = cert["multipliers"]
    M = _arr(mult["M"], "multipliers.M").reshape(model.n_q, model.n_q)
    margin = float(cert["margin"])
    if not margin > 0:
        return CertificateCheck(False, (), {}, "margin must be > 0")
    for X, nm in ((Q, "Q"), (M, "multipliers.M")):
        err = _symmetric(X, nm)
        if err:
            return CertificateCheck(False, (), {}, err)
    err = multiplier_structure_error(M, len(model.instants), mult.get("kind", "structured"))
    if err:
        return CertificateCheck(False, (), {}, err)
    if "P" in cert:
        P = _arr(cert["P"], "P")
        if P.shape != Q.shape or np.max(np.abs(P @ Q - np.eye(n_s))) > 1e-6:
            return CertificateCheck(False, (), {}, "P is not the inverse of Q")
    threshold = CHECK_FRACTION * margin
    Y = K @ Q
    A, B, Bp, Cq, Dq = (np.asarray(x) for x in (model.A, model.B, model.B_p, model.C_q, model.D_q))
    eig = lambda X: float(np.linalg.eigvalsh(X)[-1])  # noqa: E731
    checks = [_item("Q > 0", -float(np.linalg.eigvalsh(Q)[0]), threshold)]
    if model.n_q:
        checks.append(_item("M > 0 (multiplier)", -float(np.linalg.eigvalsh(M)[0]), threshold))
    figures: dict[str, Any] = {"robust_stability": False, "decay_rate": None, "ultimate_bound": None,
                               "motor_speed_bound": None, "hinf_gain": None}
    cfg = model.config
    if objective == "stability":
        r2 = float(cert["r2"])
        if not 0 < r2 < 1:
            return CertificateCheck(False, tuple(checks), figures, "r2 must be in (0, 1)")
        checks.append(_item("decay LMI (5a)", eig(lmi_stability(A, B, Bp, Cq, Dq, Q, Y, M, r2)), threshold))
        figures["decay_rate"] = float(np.sqrt(r2))
    elif objective == "ultimate-bound":
        alpha = float(cert["alpha"])
        beta = _arr(cert["beta"], "beta").reshape(-1)
        Bw = np.asarray(model.B_w)
        if beta.shape != (Bw.shape[1],):
            return CertificateCheck(False, tuple(checks), figures, f"beta has {beta.size} entries, expected {Bw.shape[1]}")
        if not 0 < alpha < 1:
            return CertificateCheck(False, tuple(checks), figures, "alpha must be in (0, 1)")
        if np.any(beta <= 0):
            return CertificateCheck(False, tuple(checks), figures, "beta must be > 0")
        L = lmi_invariance(A, B, Bp, Cq, Dq, Bw, Q, Y, M, beta, alpha)
        checks.append(_item("invariance LMI (5b)", eig(L), threshold))
        level = float(np.sum(beta) / alpha)  # {xi' P xi <= level} is invariant and attracting
        figures["decay_rate"] = float(np.sqrt(1.0 - alpha))
        figures["ellipsoid_level"] = level
        diag = np.maximum(np.diag(Q), 0.0)  # figures are discarded below unless every check passes
        figures["ultimate_bound"] = {
            "e_x": float(np.sqrt(level * diag[0])),
            "e_y": float(np.sqrt(level * diag[1])),
            "e_theta": float(np.sqrt(level * diag[2])),
        }
        R = cfg.robot.gear_radius
        KQK = K @ Q @ K.T
        J_inv = np.asarray(model.J_inv)
        dev = np.sqrt(np.maximum(level * np.einsum("ij,jk,ik->i", J_inv, KQK, J_inv), 0.0))
        figures["motor_speed_bound"] = float(cfg.reference.speed / R + np.max(dev))
        rho_max = cfg.robot.max_motor_speed
        if rho_max is not None and cert.get("motor_limits_enforced", False):
            checks.append({
                "name": "motor speed on the ellipsoid (5c) [rad/s]",
                "max_eig": None,
                "threshold": float(rho_max),
                "margin_found": None,
                "value": figures["motor_speed_bound"],
                "passed": bool(figures["motor_speed_bound"] <= rho_max),
            })
    elif objective == "hinf":
        g = float(cert["gamma2"])
        w = cfg.synthesis.weights
        Cz = np.zeros((3, n_s))
        Cz[:3, :3] = np.diag([w.e_x, w.e_y, w.e_theta])
        L = lmi_hinf(A, B, Bp, Cq, Dq, np.asarray(model.B_d), Cz, Q, Y, M, g)
        checks.append(_item("bounded-real LMI (5d)", eig(L), threshold))
        figures["hinf_gain"] = float(np.sqrt(g))
    else:
        return CertificateCheck(False, (), {}, f"unknown objective {objective!r}")
    passed = all(c["passed"] for c in checks)
    figures["robust_stability"] = passed
    if not passed:
        figures = {k: (False if k == "robust_stability" else None) for k in figures}
    return CertificateCheck(passed, tuple(checks), figures, "" if passed else "an LMI fails the margin check")
