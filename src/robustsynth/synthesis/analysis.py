"""Analysis of a *given* gain: is ``du_k = K xi_k`` robustly stable on a model?

The stability LMI of §6a with ``Y = K Q`` (or ``K G``) fixed by ``K`` is an LMI in the Lyapunov
variables and multipliers only.  As in synthesis, the solver's point counts only after
:func:`robustsynth.certificate.check_certificate` has rebuilt every vertex LMI in numpy
from the values, with the gain as given.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..certificate import CertificateCheck, check_certificate, varying_failures
from ..results import AnalysisResult
from .runner import CUTS_PER_ROUND, MAX_CUT_ROUNDS, _cert_common, _Cuts
from .lmis import ANALYSIS_KAPPA, ANALYSIS_KAPPA_WIDE, build_stability
from .solve import solve

__all__ = ["AnalysisResult", "analyze_stability", "STABILITY_R"]

STABILITY_R = 1.0 - 1e-6  # 'robustly stable' = a certified decay rate r <= this (as in synthesis)


def _one(model: Any, K: np.ndarray, lyapunov: str, multiplier: str, margin: float, solver: str,
         r: float) -> tuple[str, dict | None, CertificateCheck | None]:
    """One Lyapunov class: the box ``I <= X <= ANALYSIS_KAPPA I`` first, then, where it holds no
    certificate, the wider ``ANALYSIS_KAPPA_WIDE`` (a review found a synthesized gain whose own Q has
    condition number 5.2e4 reported uncertifiable).  Whatever is found passes the numpy re-check."""
    status, cert, chk = _one_box(model, K, lyapunov, multiplier, margin, solver, r, ANALYSIS_KAPPA)
    if status == "certified":
        return status, cert, chk
    wide = _one_box(model, K, lyapunov, multiplier, margin, solver, r, ANALYSIS_KAPPA_WIDE)
    return wide if wide[0] == "certified" or status != "infeasible" else (status, cert, chk)


def _one_box(model: Any, K: np.ndarray, lyapunov: str, multiplier: str, margin: float, solver: str,
             r: float, kappa: float) -> tuple[str, dict | None, CertificateCheck | None]:
    model = model.linearized()  # robust stability of a fixed K: a statement about the linearization
    cuts: list[int] = []  # within-period vertices added to the LMIs (constraint generation, as in synthesis)
    for _ in range(MAX_CUT_ROUNDS + 1):
        lmi_model = model.with_cuts(cuts) if cuts else model
        lp = build_stability(lmi_model, multiplier, margin, lyapunov, K=K,
                             symmetry=not cuts and model.config.synthesis.symmetry == "auto", kappa=kappa)
        lp.params["r2"].value = r * r
        held: dict[str, Any] = {}

        def accept(lp: Any = lp, held: dict = held) -> bool:
            vals = lp.values()
            held["t"] = float(vals["t"])
            if not held["t"] >= margin:  # the best point misses the margin: no certificate (not a failure)
                return True
            cert = _cert_common(model, vals, multiplier, margin, "stability")  # as synthesis writes it
            cert["r2"] = r * r
            chk = check_certificate(model, K, cert)
            held.update(cert=cert, check=chk)
            failing = varying_failures(chk)
            if failing:
                raise _Cuts(failing)
            return chk.passed

        try:
            out = solve(lp.problem, solver, accept, fallback=True)
        except _Cuts as c:
            new = [i for i in c.indices if i not in cuts][:CUTS_PER_ROUND]
            if not new:
                return "failed", None, None
            cuts += new
            continue
        if out.kind == "ok":
            if "cert" in held:
                return "certified", held["cert"], held["check"]
            return "infeasible", None, None
        return out.kind, None, None
    return "failed", None, None


def analyze_stability(model: Any, K: np.ndarray, *, lyapunov: str = "auto", multiplier: str = "structured",
                      margin: float = 1e-7, solver: str = "clarabel", r: float = STABILITY_R) -> AnalysisResult:
    """Look for a certificate that ``K`` has decay rate <= ``r`` for every admissible delay and slip
    of ``model``.  ``lyapunov='auto'`` tries a common matrix, then (slip-aware model) one per slip
    corner, which is never more conservative."""
    kinds = ["common", "slip-dependent"] if lyapunov == "auto" else [lyapunov]
    if model.kind != "slip-aware":
        kinds = [k for k in kinds if k == "common"]
    t0 = time.perf_counter()
    tried: list[str] = []
    statuses = []
    for kind in kinds:
        status, cert, chk = _one(model, np.asarray(K, dtype=float), kind, multiplier, margin, solver, r)
        tried.append(f"{kind}: {status}")
        statuses.append(status)
        if status == "certified":
            return AnalysisResult(True, status, kind, cert, chk, time.perf_counter() - t0, tuple(tried))
    status = "infeasible" if "infeasible" in statuses else "failed"
    return AnalysisResult(False, status, None, None, None, time.perf_counter() - t0, tuple(tried))
