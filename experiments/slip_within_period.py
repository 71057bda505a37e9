"""Experiment (issue 22, item 2): what does covering slip that changes *within* a period cost the
default robot's certificate, with the simplest description?

Description: the vertices keep the slip mu_k at the sampling instant; the slip's deviation
delta(t) = mu(t) - mu_k, |delta| <= w per track, enters as independent diagonal channels (the
kinematic-channel machinery of model/nonlinear.py): for each command interval j and track t,
``len_j N_t[0] (u^D + du_j)`` into e_x, ``len_j N_t[1] (u^D + du_j)`` into e_theta (the interval's
average of delta) and ``V W_j N_t[1] (u^D + du_j)`` into e_y (its (Ts - s)-weighted average), each
times a number in [-w, w] (M(mu) = mu_r N_r + mu_l N_l is linear in the slip).  w = max_rate * Ts
under slip.max_rate, the range's width without a rate bound.  Common Lyapunov matrix, linearized
kinematics.

    .venv/bin/python experiments/slip_within_period.py W [ALPHA ...]

Measured 2026-11-28 (default robot, common Q, alpha 0.1 / 0.15 / 0.2 / 0.25):

- w = 0: 6.87 / 4.99 / 4.46 / 4.50 cm -- the committed certificate's figures (the description is exact
  at w = 0; the optimum over alpha is 4.40 cm);
- w = 0.01 (slip.max_rate 0.1/s): 9.08 / 6.37 / 5.57 cm / a point that fails the numpy check
  (Clarabel 'optimal_inaccurate' throughout);
- w = 0.05 (slip.max_rate 0.5/s) and w = 0.4 (no rate bound): Clarabel fails at every alpha.

So this description is far too conservative for the default class: the three averages and the two
tracks are treated as independent, and the u^D part of each channel acts like a disturbance.  Not
in the product.  What the product does instead (docs/theory.md §11): the two averages of each
(interval, track) as *vertices* of the parallelogram that contains every pair a slip history can
produce, times the delay vertices; on the default robot the certificate then costs nothing (4.40 cm,
the same smallest eigenvalue as the constant-slip vertices).
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np

import robustsynth.model.build as MB
from robustsynth import default_config
from robustsynth.model.nonlinear import vertex_channels
from robustsynth.model.slip import slip_matrix
from robustsynth.model.vertices import Vertex
from robustsynth.synthesis.runner import _cert_common, _Runner, _weights
from robustsynth.synthesis.lmis import build_invariance

_COORDS: list[np.ndarray] = []


def _capture(mu, coords, V, Ts, M, n_s, n_e, n_u, d_hi):
    """build_model's call of vertex_channels, recording each vertex's delay coordinates."""
    _COORDS.append(np.array(coords))
    return vertex_channels(mu, coords, V, Ts, M, n_s, n_e, n_u, d_hi)


def slip_variation_vertices(model, w: float) -> list[Vertex]:
    cfg = model.config
    D, V, Ts = cfg.robot.track_distance, model.V, model.Ts
    n_s, n_e, n_u, d_hi = model.n_s, model.n_e, model.n_u, model.d_hi
    n_cmd = d_hi + 1
    speed, turn = slice(1 + n_cmd, 1 + 2 * n_cmd), slice(1, 1 + n_cmd)
    out = []
    for v, coords in zip(model.vertices, _COORDS):
        Cs, Ds, Fs, cols = [], [], [], []
        for t in range(2):
            unit = np.zeros(2)
            unit[t] = 1.0
            N = slip_matrix(unit, D)
            # vertex_channels' speed rows carry len_j (M[0] (u^D + du) - V): the V is taken back off
            zero = vertex_channels(unit, coords, V, Ts, np.zeros((2, 2)), n_s, n_e, n_u, d_hi)
            for rows, target, M, scale in ((speed, 0, N, 1.0), (speed, 2, np.array([N[1], [0.0, 0.0]]), 1.0),
                                           (turn, 1, N, V)):
                ch = vertex_channels(unit, coords, V, Ts, M, n_s, n_e, n_u, d_hi)
                F = ch.F[rows] - (zero.F[rows] if rows is speed else 0.0)
                for k in range(F.shape[0]):
                    Cs.append(ch.C[rows][k])
                    Ds.append(ch.D[rows][k])
                    Fs.append(F[k])
                    b = np.zeros(n_s)
                    b[target] = scale * w
                    cols.append(b)
        Cq, Dq, Fq, Bp = np.array(Cs), np.array(Ds), np.array(Fs), np.array(cols).T
        keep = np.max(np.abs(np.hstack([Cq, Dq, Fq])), axis=1) > 0
        out.append(Vertex(v.A, v.B, v.E, Bp[:, keep], Cq[keep], Dq[keep], v.corner, v.label, Fq[keep], True))
    return out


def main(argv: list[str]) -> None:
    w = float(argv[0])
    alphas = [float(a) for a in argv[1:]] or [0.1, 0.15, 0.2, 0.25]
    MB.vertex_channels = _capture
    model = MB.build_model(default_config())
    m = replace(model, vertices=tuple(slip_variation_vertices(model, w)))
    s = m.config.synthesis
    for a in alphas:
        lp = build_invariance(m, s.multiplier, s.margin, _weights(s), True, "common", symmetry=False)
        lp.params["alpha"].value = a
        lp.params["one_minus_alpha"].value = 1 - a

        def make_cert(vals: dict, a: float = a) -> dict:
            c = _cert_common(m, vals, s.multiplier, s.margin, "ultimate-bound")
            c.update(alpha=a, beta=vals["beta"], motor_limits_enforced=True)
            return c

        out, _, _, chk = _Runner(m, lp, "clarabel", make_cert).run(fallback=False)
        ub = chk.figures["ultimate_bound"] if chk is not None else None
        print(f"w = {w:g}, alpha = {a:g}: {out.kind} ({out.record.status})"
              + (f", |e_y| <= {100 * ub['e_y']:.2f} cm" if ub else ""), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
