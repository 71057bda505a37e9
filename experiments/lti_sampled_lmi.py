"""Issue 53: how far can a common quadratic Lyapunov function reach for the DC servo of
tests/data/dc-servo.yaml?  A necessary condition: P >= I with M' P M - lambda^2 P < 0 on sampled exact
lifted closed loops M (400 random in-order switching instants, plus the frozen delays on a grid).  Infeasible
at tau means no common quadratic V exists for delays up to tau, whatever the over-approximation.

    .venv/bin/python experiments/lti_sampled_lmi.py 0.16 0.18 0.19
"""

from __future__ import annotations

import sys

import cvxpy as cp
import numpy as np

from robustsynth.core.lifting import instant_ranges
from robustsynth.core.delays import exact_closed_loop, lti_depth, pad_lti_gain

A = np.array([[0.0, 1.0], [0.0, -72.5]])
B = np.array([[0.0], [75.3]])
K = -np.array([[7.27, 0.14]])
TS = 0.02
DECAY = 1.0 - 1e-6
SAMPLES = 400


def feasible(tau: float, seed: int = 0) -> str:
    rng = np.random.default_rng(seed)
    d = lti_depth(tau, 0, TS)
    r = instant_ranges(0.0, tau, TS, d)
    s = r[:, 0] + (r[:, 1] - r[:, 0]) * rng.random((SAMPLES, d))
    s = np.maximum.accumulate(s[:, ::-1], axis=1)[:, ::-1]
    frozen = np.array([np.clip(t - np.arange(d) * TS, 0.0, TS) for t in np.linspace(0.0, tau, 41)])
    Ms = exact_closed_loop(A, B, pad_lti_gain(K, 2, 1, d), TS, np.vstack([s, frozen]))
    n_s = Ms.shape[-1]
    P = cp.Variable((n_s, n_s), symmetric=True)
    cons = [P >> np.eye(n_s)] + [M.T @ P @ M - DECAY**2 * P << -1e-7 * np.eye(n_s) for M in Ms]
    prob = cp.Problem(cp.Minimize(0), cons)
    prob.solve(solver=cp.CLARABEL)
    return prob.status


if __name__ == "__main__":
    for tau in map(float, sys.argv[1:] or ["0.16", "0.18", "0.19"]):
        print(f"tau_max {tau:g} s: sampled-loop LMIs {feasible(tau)}", flush=True)
