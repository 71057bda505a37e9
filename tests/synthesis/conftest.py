"""Helpers shared by the synthesis tests."""

from __future__ import annotations

from robustsynth.synthesis.design import _cert_common, _Runner, _weights
from robustsynth.synthesis.lmis import build_invariance


def invariance_at(model, lyapunov: str, alpha: float, symmetry: bool = True):
    """One invariance solve at a fixed alpha through the product's runner (its solver settings, and a
    point accepted only when the numpy re-check of every vertex condition passes); Clarabel only, no
    fallback.  Returns the LMI problem, K, the certificate and its check."""
    s = model.config.synthesis
    lp = build_invariance(model, s.multiplier, s.margin, _weights(s), True, lyapunov, symmetry=symmetry)
    lp.params["alpha"].value = alpha
    lp.params["one_minus_alpha"].value = 1.0 - alpha

    def make_cert(vals: dict) -> dict:
        cert = _cert_common(model, vals, s.multiplier, s.margin, "ultimate-bound")
        cert.update(alpha=alpha, beta=vals["beta"], motor_limits_enforced=True)
        return cert

    out, cert, K, chk = _Runner(model, lp, "clarabel", make_cert).run(fallback=False)
    assert out.kind == "ok", (out.record, chk)
    return lp, K, cert, chk
