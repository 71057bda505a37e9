"""Helpers shared by the synthesis tests."""

from __future__ import annotations

from robustsynth.synthesis.runner import _cert_common, _Runner, _weights
from robustsynth.synthesis.lmis import build_invariance


def invariance_runner(model, lyapunov: str, alpha: float, symmetry: bool = True):
    """The invariance LMIs at a fixed alpha and the product's runner for them (its solver settings, a
    point accepted only when the numpy re-check of every vertex condition passes, and the problem
    without the mirror to retry on, as synthesis builds it).  Returns the LMI problem and the runner."""
    s = model.config.synthesis

    def build(sym: bool, mdl=model):
        return build_invariance(mdl, s.multiplier, s.margin, _weights(s), True, lyapunov, symmetry=sym)

    lp = build(symmetry)
    lp.params["alpha"].value = alpha
    lp.params["one_minus_alpha"].value = 1.0 - alpha

    def make_cert(vals: dict) -> dict:
        cert = _cert_common(model, vals, s.multiplier, s.margin, "ultimate-bound")
        cert.update(alpha=alpha, beta=vals["beta"], motor_limits_enforced=True)
        return cert

    return lp, _Runner(model, lp, "clarabel", make_cert, full=lambda mdl: build(False, mdl))


def invariance_at(model, lyapunov: str, alpha: float, symmetry: bool = True):
    """One invariance solve at a fixed alpha through the product's runner; Clarabel only, no fallback.
    Returns the LMI problem, K, the certificate and its check."""
    lp, runner = invariance_runner(model, lyapunov, alpha, symmetry)
    out, cert, K, chk = runner.run(fallback=False)
    assert out.kind == "ok", (out.record, chk)
    return lp, K, cert, chk
