"""Issue 53: instants on equal ranges share one remainder channel (core.delays.channel_groups); their remainders
w_j enter as one sum W, and every split of W costs at least W' H W, H the parallel sum of the instants'
multipliers.  Which form of that bound should the analysis LMIs take?

- per-instant: a channel per instant (the LMIs before the grouping; exactly as tight as the exact form);
- exact: the shared channel with h <= H(a) as [[a_j, h], [h, s_j]] >= 0 and sum_j s_j <= h (2 x 2 PSD cones;
  a rotated-cone SOC in the DPP-compiled problem made cvxpy allocate 33 GiB formatting it);
- equal: the shared channel with equal multipliers a for the group's g instants, diagonal -a / g (linear),
  what synthesis.lti.analyze_lti solves.

For each, the largest delay bound certified at fixed pieces (bisection to 1e-5 s; every verdict is the package's
numpy check, certificate.lti.check_lti_certificate, which accepts any multipliers) and the solve times (the package's
solve, parameters and Clarabel, for per-instant and equal; Clarabel alone on a problem compiled beforehand for
exact: not comparable to the digit).  Found: exact and per-instant certify the same bound to 3e-5 s, as they
must (the two blocks are negative definite together); equal is within 3e-5 s of them (servo and fast-current, 1 and 2 pieces)
and needs no cone and no variable beyond the multipliers:

    .venv/bin/python experiments/lti_channel_grouping.py tests/data/dc-servo.yaml 0.1701 0.1799 1
    KSCALE=3 .venv/bin/python experiments/lti_channel_grouping.py tests/data/fast-current.yaml 0.02 0.0705 2

(KSCALE multiplies the configured gain: a shorter margin, where 2 pieces are affordable.)
"""

from __future__ import annotations

import os
import sys
import time
import warnings

import cvxpy as cp
import numpy as np

from robustsynth.certificate.lti import check_lti_certificate
from robustsynth.config import load_config
from robustsynth.core.delays import YOUNG_DELTA, lti_depth, over_approximation, pad_lti_gain, vertex_combinations
from robustsynth.model.lti import lti_plant
from robustsynth.synthesis.lti import DECAY, STRICT, _vertex_matrices, analyze_lti, channel_layout

TOL = 1e-5  # s: the bisection's end


def analyze_exact(pw, decay: float = DECAY) -> tuple[bool, float]:
    """The shared channels with the exact parallel sum (2 x 2 PSD cones), per-instant multipliers; (proven, time)."""
    verts = vertex_combinations(pw)
    combos, owner, _ = verts
    n_s, n = pw.E.shape
    d = pw.d_hi
    kept, dropped, n_drop, shrink, groups, dirs, Et = channel_layout(pw)
    k = n_s + Et.shape[1]
    Ms = _vertex_matrices(pw, verts)
    n_c = len(combos)
    P = cp.Variable((n_s, n_s), symmetric=True)
    pbar = cp.Variable(nonneg=True)
    eps = cp.Variable((n_c, d * (1 + n)), nonneg=True)  # per instant: the full block, then per direction

    def at(c, j, slot):
        return eps[c, j * (1 + n) + slot]

    cons = [P >> np.eye(n_s), P << pbar * np.eye(n_s)]
    h = {}
    for g, grp in enumerate(groups):
        for a, l in enumerate(dirs[g]):
            if len(grp) == 1:
                h[g, a] = [at(c, grp[0], 0) + at(c, grp[0], 1 + l) for c in range(n_c)]
                continue
            hv = cp.Variable(n_c, nonneg=True)
            s = cp.Variable((n_c, len(grp)), nonneg=True)
            h[g, a] = [hv[c] for c in range(n_c)]
            cons.append(cp.sum(s, axis=1) <= hv)
            for c in range(n_c):
                for q, j in enumerate(grp):
                    cons.append(cp.bmat([[at(c, j, 0) + at(c, j, 1 + l), hv[c]], [hv[c], s[c, q]]]) >> 0)
    FF = [pw.F[j].T @ pw.F[j] for j in range(d)]
    for v, c in enumerate(owner):
        M = Ms[v]
        top = M.T @ P @ M - decay**2 * shrink * P
        for j in range(d):
            i = combos[c][j]
            r2 = at(c, j, 0) * pw.rho[j][i] ** 2
            for l in kept[j]:
                r2 = r2 + at(c, j, 1 + l) * pw.rho_dir[j][i, l] ** 2
            if n_drop:
                r2 = r2 + pbar * n_drop / YOUNG_DELTA * dropped[j][i] ** 2
            top = top + r2 * FF[j]
        diag = cp.hstack([h[g, a][c] for g in range(len(groups)) for a in range(len(dirs[g]))])
        low = Et.T @ P @ Et - cp.diag(diag)
        off = M.T @ P @ Et
        X = cp.bmat([[top, off], [off.T, low]])
        cons.append((X + X.T) / 2 << -STRICT * np.eye(k))
    prob = cp.Problem(cp.Minimize(0), cons)
    data = prob.get_problem_data(cp.CLARABEL)  # compile outside the timing (the package compiles once per structure)
    del data
    t = time.perf_counter()
    try:
        prob.solve(solver=cp.CLARABEL)
    except cp.error.SolverError:
        return False, time.perf_counter() - t
    dt = time.perf_counter() - t
    if P.value is None:
        return False, dt
    ev = np.maximum(eps.value, 0.0).reshape(n_c, d, 1 + n)
    return bool(check_lti_certificate(pw, P.value, ev, decay, verts)["ok"]), dt


def main() -> None:
    warnings.filterwarnings("ignore")
    cfg = load_config(sys.argv[1])
    plant = lti_plant(cfg)
    A, B, K = plant["A"], plant["B"], plant["K"] * float(os.environ.get("KSCALE", "1"))
    Ts = cfg.network.sampling_time
    lo, hi, N = float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
    n, m = B.shape

    def build(tau: float):
        d = lti_depth(tau, 0, Ts)
        return over_approximation(A, B, pad_lti_gain(K, n, m, d), Ts, 0.0, tau, d, N)

    def package(merge: bool):
        def run(pw):
            r = analyze_lti(pw, merge=merge)
            return r.certified, r.solve_time_s
        return run

    for name, f in (("per-instant", package(False)), ("exact", analyze_exact), ("equal", package(True))):
        a, b, times = lo, hi, []
        for x, want in ((a, True), (b, False)):
            ok, t = f(build(x))
            times.append(t)
            if ok != want:
                raise SystemExit(f"{name}: {x} is {'' if ok else 'not '}certified; choose another bracket")
        while b - a > TOL:
            x = 0.5 * (a + b)
            ok, t = f(build(x))
            times.append(t)
            a, b = (x, b) if ok else (a, x)
        print(f"{sys.argv[1]} pieces {N}: {name:12s} largest certified {a:.5f} s ({len(times)} solves, "
              f"mean {np.mean(times):.2f} s, max {max(times):.2f} s)", flush=True)


if __name__ == "__main__":
    main()
