"""The certificate of ``hinf``: the bounded-real LMIs (6d) at every vertex, and the l2 gain."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ...verified import round_up
from ..check import CertificateCheck, _fail, _Family
from ..lmis import lmi_hinf

__all__ = ["rows"]


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
