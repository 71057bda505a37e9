"""Experiment: the exact-hull polytopic delay model (docs/theory.md §5, the exact-hull delay vertices).

The curve (h, h^2/2) lies in the triangle spanned by its ends and the crossing of the end
tangents; the lifted matrices are affine in each instant's (h, g), so one invariance LMI per vertex
combination (3^n_uncertain) with a common Q certifies every delay sequence.  Prints the |e_y|
bound next to the norm-bounded one of `robustsynth synthesize`.

    .venv/bin/python experiments/polytopic.py
"""

from __future__ import annotations

import itertools
import time

import cvxpy as cp
import numpy as np

from _common import config, motor_lmis, solve_optimal
from robustsynth.model import build_model
from robustsynth.core.lifting import lift
from robustsynth.model.linearize import Gamma, Gamma_D, Phi
from robustsynth.synthesis import synthesize


def vertices(m):
    Ts = m.Ts
    A, B = np.asarray(m.A_c), np.asarray(m.B_c)
    AB = A @ B
    per = []
    for j in range(m.d_hi):
        lo, hi = m.instant_ranges[j]
        hmin, hmax = Ts - hi, Ts - lo
        if hmax - hmin < 1e-12:
            per.append([(hmin, hmin**2 / 2)])
        else:
            per.append([(hmin, hmin**2 / 2), (hmax, hmax**2 / 2), ((hmin + hmax) / 2, hmin * hmax / 2)])
    for combo in itertools.product(*per):
        G = np.array([h * B + g * AB for h, g in combo])
        Av, Bv, _ = lift(Phi(A, Ts), G, Gamma(A, B, Ts), Gamma_D(A, np.asarray(m.B_D_c), Ts))
        yield Av, Bv


def solve(m, alpha):
    n_s, n_u = m.n_s, m.n_u
    Bw = np.asarray(m.B_w)
    n_w = Bw.shape[1]
    Q = cp.Variable((n_s, n_s), symmetric=True)
    Y = cp.Variable((n_u, n_s))
    beta = cp.Variable(n_w)
    cons = [cp.sum(beta) <= alpha] + motor_lmis(m, Q, Y)
    for Av, Bv in vertices(m):
        AQ = Av @ Q + Bv @ Y
        L = cp.bmat([[-(1 - alpha) * Q, np.zeros((n_s, n_w)), AQ.T], [np.zeros((n_w, n_s)), -cp.diag(beta), Bw.T],
                     [AQ, Bw, -Q]])
        cons.append((L + L.T) / 2 << -1e-7 * np.eye(L.shape[0]))
    p = cp.Problem(cp.Minimize(0.1 * Q[0, 0] + Q[1, 1] + 0.1 * Q[2, 2]), cons)
    if not solve_optimal(p):
        return None
    return float(np.sqrt(beta.value.sum() / alpha * Q.value[1, 1]))


if __name__ == "__main__":
    for name, over in [("default", {}), ("delay-full-period", {"network.delay.min": 0.0, "network.delay.max": 0.1}),
                       ("delay-multi-period", {"network.delay.max": 0.25})]:
        m = build_model(config(**over))
        t0 = time.perf_counter()
        ey = min(v for v in (solve(m, a) for a in np.linspace(0.1, 0.4, 13)) if v is not None)
        t_poly = time.perf_counter() - t0
        nb = synthesize(m).certified["ultimate_bound"]["e_y"]
        print(f"{name:20s} |e_y| polytopic {100 * ey:.2f} cm ({t_poly:.1f} s, 13 alphas)   "
              f"norm-bounded {100 * nb:.2f} cm   ratio {ey / nb:.3f}")
