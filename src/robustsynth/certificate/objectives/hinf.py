"""The certificate of ``hinf``: the bounded-real LMIs (6d) at every vertex, and the l2 gain."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ...verified import round_up
from ..check import CertificateCheck, _fail, _Family
from ..lmis import _T, _block, _minus, _sym

__all__ = ["rows", "lmi_hinf"]


def rows(cert: Mapping[str, Any], family: _Family, K: np.ndarray, X: np.ndarray, lyap: str, mats: list[np.ndarray],
         checks: list, figures: dict) -> CertificateCheck | None:
    """The bounded-real LMIs (6d) and the l2 gain; a failure, or None."""
    if lyap != "common":
        return _fail("hinf certificates use a common Lyapunov matrix")
    model, aX = family.model, np.abs(X)
    g = float(cert["gamma2"])
    w = model.config.synthesis.weights
    Cz = np.zeros((3, X.shape[0]))
    Cz[:3, :3] = np.diag([w.e_x, w.e_y, w.e_theta])
    Bd = np.asarray(model.B_d)
    checks.extend(family.items("bounded-real LMI (6d)", lambda v, M, lf, rt, y, mag: lmi_hinf(
        v, np.abs(Bd) if mag else Bd, np.abs(Cz) if mag else Cz, aX if mag else X, y, M, g, mag)))
    figures["hinf_gain"] = round_up(np.sqrt(g), 2)
    return None


def lmi_hinf(v, Bd, Cz, Q, Y, M, gamma2, mag: bool = False):
    """Bounded-real LMI at vertex v (docs/theory.md §6d):
    [[Q, 0, (AQ+BY)', (Cz Q)', (C_qQ+D_qY)'], [0, g I, Bd', 0, 0],
     [AQ+BY, Bd, Q - B_p M B_p', 0, 0], [Cz Q, 0, 0, I, 0], [C_qQ+D_qY, 0, 0, 0, M]] >= 0."""
    AQ = v.A @ Q + v.B @ Y
    CzQ = Cz @ Q
    n_s, n_q, n_d, n_z = Q.shape[0], v.B_p.shape[-1], Bd.shape[1], Cz.shape[0]
    Z = np.zeros
    rows = [
        [Q, Z((n_s, n_d)), _T(AQ), CzQ.T],
        [Z((n_d, n_s)), gamma2 * np.eye(n_d), Bd.T, Z((n_d, n_z))],
        [AQ, Bd, _minus(Q, v.B_p @ M @ v.B_p.T, mag) if n_q else Q, Z((n_s, n_z))],
        [CzQ, Z((n_z, n_d)), Z((n_z, n_s)), np.eye(n_z)],
    ]
    if n_q:
        CQ = v.C_q @ Q + v.D_q @ Y
        rows[0].append(CQ.T)
        rows[1].append(Z((n_d, n_q)))
        rows[2].append(Z((n_s, n_q)))
        rows[3].append(Z((n_z, n_q)))
        rows.append([CQ, Z((n_q, n_d)), Z((n_q, n_s)), Z((n_q, n_z)), M])
    return _sym(_block(rows))
