"""The certificate of ``stability``: the decay LMIs (6a) at every vertex condition, and the decay rate."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ...verified import round_up
from ..check import CertificateCheck, _fail, _Family
from ..lmis import lmi_stability

__all__ = ["rows"]


def rows(cert: Mapping[str, Any], family: _Family, K: np.ndarray, X: np.ndarray, lyap: str, mats: list[np.ndarray],
         checks: list, figures: dict) -> CertificateCheck | None:
    """The decay LMIs (6a) and the decay rate; a failure, or None."""
    aX = np.abs(X)
    r2 = float(cert["r2"])
    if not 0 < r2 < 1:
        return _fail("r2 must be in (0, 1)", checks, figures)
    checks.extend(family.items("decay LMI (6a)", lambda v, M, lf, rt, y, mag: lmi_stability(
        v, aX if mag else X, lf, rt, y, M, r2, mag)))
    figures["decay_rate"] = round_up(np.sqrt(r2), 2)
    return None
