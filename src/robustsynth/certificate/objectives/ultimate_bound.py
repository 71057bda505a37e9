"""The certificate of ``ultimate-bound``: the invariance LMIs (6b) at every vertex condition, and the figures
on the invariant set (the errors at and between the samples, the motor speeds, the heading within a period)."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ...verified import gamma, round_up
from ..bounds import between_samples, heading_within_period, set_max
from ..check import CertificateCheck, _arr, _fail, _Family
from ..lmis import lmi_invariance

__all__ = ["rows"]


def rows(cert: Mapping[str, Any], family: _Family, K: np.ndarray, X: np.ndarray, lyap: str, mats: list[np.ndarray],
         checks: list, figures: dict) -> CertificateCheck | None:
    """The invariance LMIs (6b) and the figures on the invariant set; a failure, or None."""
    model, aX = family.model, np.abs(X)
    alpha = float(cert["alpha"])
    beta = _arr(cert["beta"], "beta").reshape(-1)
    if beta.shape != (model.n_w,):
        return _fail(f"beta has {beta.size} entries, expected {model.n_w}", checks, figures)
    if not 0 < alpha < 1:
        return _fail("alpha must be in (0, 1)", checks, figures)
    if np.any(beta <= 0):
        return _fail("beta must be > 0", checks, figures)
    checks.extend(family.items("invariance LMI (6b)", lambda v, M, lf, rt, y, mag: lmi_invariance(
        v, aX if mag else X, lf, rt, y, M, np.abs(beta) if mag else beta, alpha, mag)))
    # the figures are claimed as bounds: rounded outwards (any level >= sum beta / alpha is invariant)
    level = round_up(float(np.sum(beta) / alpha), beta.size + 1)  # {xi' P xi <= level}: invariant, attracting
    figures["decay_rate"] = round_up(np.sqrt(1.0 - alpha), 2)
    figures["ellipsoid_level"] = level
    _set_figures(model, K, lyap, mats, level, bool(family.varying), figures)
    checks.extend(_set_checks(model, cert, figures))
    return None


def _set_figures(model: Any, K: np.ndarray, lyap: str, mats: list[np.ndarray], level: float, varying: bool,
                 figures: dict) -> None:
    """The bounds on the set {V <= level}: the errors at the samples, the motor speeds, |e_theta(t)| and
    the errors between the samples (into ``figures``)."""
    n_u, n_s = K.shape
    # per bounded figure the largest value the set allows over every slip (and previous delay), the
    # smallest over the delay vertices V takes its maximum over (set_max; docs/theory.md §6i)
    inner = model.delay_vertex_count if lyap in ("delay-dependent", "path-dependent") else 1
    diags = np.array([np.diag(Sm) for Sm in mats])
    figures["ultimate_bound"] = {
        name: round_up(np.sqrt(level * set_max(diags[:, k], inner)), 2)
        for k, name in enumerate(("e_x", "e_y", "e_theta"))
    }
    J_inv = np.asarray(model.J_inv)
    # c S c' with c = J^-1 K, bounded above with its rounding: + gamma |c| |S| |c|'
    g = gamma(2 * n_s + 2 * n_u + 4)
    aJK = np.abs(J_inv) @ np.abs(K)
    devs = np.array([np.einsum("ij,jk,ik->i", J_inv, K @ Sm @ K.T, J_inv)
                     + g * (1 + g) * np.einsum("ij,jk,ik->i", aJK, np.abs(Sm), aJK) for Sm in mats])
    dev = max(set_max(devs[:, i], inner) for i in range(devs.shape[1]))
    figures["motor_speed_bound"] = round_up(model.feedforward_motor_speed + np.sqrt(max(round_up(level * dev), 0.0)), 3)
    # |e_theta(t)| on the set and the errors between samples (docs/theory.md §9; on arcs against the
    # turning reference, §10)
    if model.channels:
        figures["heading_within_period"] = heading_within_period(model, K, mats, level, inner)
    chord: dict[str, float] = {}  # what the chord terms add, each at its worst: the most an error rises in a period
    figures["ultimate_bound_between_samples"] = between_samples(
        model, K, mats, level, figures["ultimate_bound"], figures.get("heading_within_period"), inner,
        within_period=varying, chord=chord)
    figures["between_samples_rise"] = chord


def _set_checks(model: Any, cert: Mapping[str, Any], figures: dict) -> list[dict[str, Any]]:
    """The conditions on the set's figures: |e_theta(t)| within a nonlinear certificate's heading bound,
    the motor speeds within their limit where the certificate enforces it."""
    checks = []
    if model.heading_bound is not None:
        figures["heading_bound"] = model.heading_bound
        checks.append({
            "name": "|e_theta(t)| within every period on the set <= heading bound [rad]",
            "max_eig": None,
            "threshold": float(model.heading_bound),
            "margin_found": None,
            "value": figures["heading_within_period"],
            "passed": bool(figures["heading_within_period"] <= model.heading_bound),
        })
    rho_max = model.config.robot.max_motor_speed
    if rho_max is not None and cert.get("motor_limits_enforced", False):
        checks.append({
            "name": "motor speed on the invariant set (6c) [rad/s]",
            "max_eig": None,
            "threshold": float(rho_max),
            "margin_found": None,
            "value": figures["motor_speed_bound"],
            "passed": bool(figures["motor_speed_bound"] <= rho_max),
        })
    return checks
