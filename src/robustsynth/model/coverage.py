"""The coverage test of a model's vertex description: the exact lifted maps of random admissible
(slip, delay history) samples, the delay extremes and the slip corners rebuilt from the vertices with
explicit hull weights and Delta (docs/theory.md §5)."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["coverage_check"]


def coverage_check(model: Any, n_sequences: int = 1000, steps: int = 20, seed: int = 0) -> dict:
    """Coverage of the vertex description on random admissible (slip, delay history) samples, the
    delay extremes and the slip corners: the exact lifted matrices of the model's kind and its
    constant term are rebuilt from the vertices with explicit hull weights (>= 0, summing to 1) and
    Delta (|Delta_ii| <= 1).  Returns the sample count, the extremes of the coordinates and the
    largest residual."""
    net = model.network
    rng = np.random.default_rng(seed)
    taus = net.uniform(rng, (n_sequences, steps + model.d_hi))
    extremes = np.vstack([net.pattern(kind, (1, taus.shape[1]), shifted=False)
                          for kind in ("constant-min", "constant-max", "alternating")])
    taus = net.lose(taus, rng, 0.3, max(1.0, net.max_lost))  # bursts of up to m lost commands (inf) ...
    taus[:3] = extremes  # ... on all but the extremes
    s = model.s_tilde(taus).reshape(-1, model.d_hi)
    if model.delay_description == "lossy-polytopic":  # only the instants a lossy link produces
        corners = model.reachable_instants(5)
    else:
        corners = np.array(np.meshgrid(*[r for r in model.instant_ranges], indexing="ij")).reshape(model.d_hi, -1).T
        if model.delay_cover != "product":  # the corners delivery in order can produce (s~_0 >= s~_1 >= ...)
            corners = corners[np.all(np.diff(corners, axis=1) <= 0.0, axis=1)]
    s = np.vstack([s, corners])
    ranges = model.slip_ranges
    mu = np.stack([rng.uniform(lo, hi, s.shape[0]) for lo, hi in ranges], axis=1)
    mu[: model.corners.shape[0]] = model.corners  # every slip corner at least once
    mu[-1] = [hi for _, hi in ranges]
    A_ex, B_ex = model.exact(s, mu)
    c_ex = model.constant(mu)
    lam, dlt = model.hull_coordinates(s, mu)
    A_h, B_h, c_h = model.from_hull(lam, dlt, model.disturbance_coordinates(mu))
    res = max(float(np.max(np.abs(A_ex - A_h), initial=0.0)), float(np.max(np.abs(B_ex - B_h), initial=0.0)),
              float(np.max(np.abs(c_ex - c_h), initial=0.0)))
    max_delta = float(np.max(np.abs(dlt), initial=0.0))
    min_weight = float(np.min(lam))
    sum_err = float(np.max(np.abs(lam.sum(axis=-1) - 1.0)))
    return {
        "samples": int(s.shape[0]),
        "vertices": len(model.vertices),
        "max_abs_delta": max_delta,
        "min_weight": min_weight,
        "max_weight_sum_error": sum_err,
        "max_residual": res,
        "passed": bool(max_delta <= 1.0 + 1e-12 and min_weight >= -1e-12 and sum_err <= 1e-12 and res <= 1e-12),
    }
