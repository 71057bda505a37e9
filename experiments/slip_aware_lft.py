"""Experiment: a certificate that also covers slip's multiplicative effect (docs/theory.md §2).

Linearized in e and du but exact in the slip mu (constant over a period), the error obeys
``e_dot = s A e + B M du + B_D d`` with ``s = (mu_r + mu_l)/2`` and ``M = J H J^-1 = s I + d N``,
``d = mu_r - mu_l``, ``N = [[0, D/4], [1/D, 0]]``: the paper's model (eq. lineare) has s = 1, M = I.
Discretized with the delays, every command of the period is multiplied by the same M, and s enters
Phi and the h^2/2 term.  This builds the LFT

    xi+ = A xi + B du + B_p p + B_w w,  q = C_q xi + D_q du + D_qp p,  p = Delta q

with Delta = blockdiag(delta_s I (shared by M, Phi and Gamma(Ts)), delta_d I, [delay blocks]),
checks its coverage against the exact slip-aware lifted matrices (explicit Delta, closure
(I - Delta D_qp)^-1), and solves the invariance LMI with the p-row kept (feedthrough):

    [[-(1-a)Q, 0, 0, (AQ+BY)', (CQ+DY)'], [0, -M, 0, M B_p', M D_qp'], [0, 0, -diag b, B_w', 0],
     [AQ+BY, B_p M, B_w, -Q, 0], [CQ+DY, D_qp M, 0, 0, -M]] <= 0

    .venv/bin/python experiments/slip_aware_lft.py
"""

from __future__ import annotations

import cvxpy as cp
import numpy as np

from _common import config, motor_lmis, solve_optimal
from robustsynth.model import build_model
from robustsynth.plants.path import make_path
from robustsynth.scenarios import draw_scenario
from robustsynth.robot_verification.simulate import simulate


def slip_ranges(m):
    c = m.config.slip
    s_lo, s_hi = (c.right.min + c.left.min) / 2, (c.right.max + c.left.max) / 2
    d_lo, d_hi = c.right.min - c.left.max, c.right.max - c.left.min
    return s_lo, s_hi, d_lo, d_hi


def build(m):
    """The LFT matrices and its block list [(kind, size)]."""
    cfg = m.config
    V, D, Ts, d_hi = m.V, cfg.robot.track_distance, m.Ts, m.d_hi
    A, B, BD = np.asarray(m.A_c), np.asarray(m.B_c), np.asarray(m.B_D_c)
    AB = A @ B
    n_e, n_u, n_s = 3, 2, m.n_s
    s_lo, s_hi, dl, dh = slip_ranges(m)
    s_c, s_r, d_c, d_r = (s_lo + s_hi) / 2, (s_hi - s_lo) / 2, (dl + dh) / 2, (dh - dl) / 2
    N = np.array([[0.0, D / 4], [1 / D, 0.0]])
    nU = 2 * (d_hi + 1)  # U = [du_k; du_{k-1}; ...; du_{k-d_hi}]
    S_xi, S_u = np.zeros((nU, n_s)), np.zeros((nU, n_u))
    S_u[:2] = np.eye(2)
    for i in range(1, d_hi + 1):
        S_xi[2 * i : 2 * i + 2, n_e + 2 * (i - 1) : n_e + 2 * i] = np.eye(2)
    IM = np.kron(np.eye(d_hi + 1), s_c * np.eye(2) + d_c * N)
    IN = np.kron(np.eye(d_hi + 1), N)
    blocks = [("repeated", nU + 2), ("repeated", nU)] + [("delay", 3)] * d_hi
    off = np.cumsum([0] + [b[1] for b in blocks])
    n_p = int(off[-1])
    Ae, Be, Bpe = np.zeros((n_e, n_s)), np.zeros((n_e, n_u)), np.zeros((n_e, n_p))
    Cq, Dq, Dqp = np.zeros((n_p, n_s)), np.zeros((n_p, n_u)), np.zeros((n_p, n_p))

    def ubar(i):  # the effective command M du_{k-i} as rows on [xi, du, p]
        E = np.zeros((2, nU))
        E[:, 2 * i : 2 * i + 2] = np.eye(2)
        P = np.zeros((2, n_p))
        P[:, off[0] : off[0] + nU] = s_r * E
        P[:, off[1] : off[2]] = d_r * E
        return E @ IM @ S_xi, E @ IM @ S_u, P

    Cq[off[0] : off[0] + nU], Dq[off[0] : off[0] + nU] = S_xi, S_u  # delta_s acts on U
    Cq[off[1] : off[2]], Dq[off[1] : off[2]] = IN @ S_xi, IN @ S_u  # delta_d acts on N U
    Ae[:, :n_e] = np.eye(3) + s_c * A * Ts  # Phi_s = I + s A Ts
    k = off[0] + nU
    Bpe[1, k], Cq[k, 2] = s_r * V * Ts, 1.0
    sel = np.vstack([np.eye(2), [0.0, 1.0]])
    ranges = m.instant_ranges
    for j in range(d_hi):
        hmin, hmax = Ts - ranges[j, 1], Ts - ranges[j, 0]
        gmin, gmax = s_lo * hmin**2 / 2, s_hi * hmax**2 / 2  # g = s h^2/2: the delay box widened by s
        hc, gc, a1, a2 = (hmin + hmax) / 2, (gmin + gmax) / 2, (hmax - hmin) / 2, (gmax - gmin) / 2
        X1, U1, P1 = ubar(j)
        X2, U2, P2 = ubar(j + 1)
        xX, xU, xP = X1 - X2, U1 - U2, P1 - P2
        G0 = hc * B + gc * AB
        Ae += G0 @ xX
        Be += G0 @ xU
        Bpe += G0 @ xP
        o = off[2 + j]
        Bpe[:, o : o + 2] += -a1 * B
        Bpe[:, o + 2] += -a2 * AB[:, 1]
        Cq[o : o + 3], Dq[o : o + 3], Dqp[o : o + 3] = sel @ xX, sel @ xU, sel @ xP
    GT = Ts * B + Ts**2 / 2 * s_c * AB  # Gamma_s(Ts) on the oldest command
    X, Uu, P = ubar(d_hi)
    Ae += GT @ X
    Be += GT @ Uu
    Bpe += GT @ P
    k = off[0] + nU + 1
    Bpe[1, k] = s_r * Ts**2 / 2 * V
    Cq[k], Dq[k], Dqp[k] = X[1], Uu[1], P[1]
    Al, Bl, Bpl = np.zeros((n_s, n_s)), np.zeros((n_s, n_u)), np.zeros((n_s, n_p))
    Al[:n_e], Bl[:n_e], Bpl[:n_e] = Ae, Be, Bpe
    Bl[n_e : n_e + 2] = np.eye(2)
    for j in range(1, d_hi):
        Al[n_e + 2 * j : n_e + 2 * j + 2, n_e + 2 * (j - 1) : n_e + 2 * j] = np.eye(2)
    # slip as a disturbance: Gamma_D(s) d; the centre part s_c into B_w, the rest one more component
    W = np.asarray(m.slip.W)
    Bw = np.zeros((n_s, W.shape[1] + 1))
    Bw[:n_e, : W.shape[1]] = (Ts * BD + Ts**2 / 2 * s_c * (A @ BD)) @ W
    Bw[1, -1] = Ts**2 / 2 * s_r * V * V / D * max(abs(dl), abs(dh))
    params = {"s_c": s_c, "s_r": s_r, "d_c": d_c, "d_r": d_r, "nU": nU}
    return (Al, Bl, Bpl, Cq, Dq, Dqp, Bw, blocks, params)


def exact(m, s_tilde, mu_r, mu_l):
    """Slip-aware exact lifted (A, B) at switching instants s_tilde and constant slip."""
    V, D, Ts, d_hi = m.V, m.config.robot.track_distance, m.Ts, m.d_hi
    A, B = np.asarray(m.A_c), np.asarray(m.B_c)
    s, d = (mu_r + mu_l) / 2, mu_r - mu_l
    M = s * np.eye(2) + d * np.array([[0.0, D / 4], [1 / D, 0.0]])
    G = lambda h: (h * B + h * h / 2 * s * (A @ B)) @ M  # noqa: E731
    n_e, n_s = 3, m.n_s
    Al, Bl = np.zeros((n_s, n_s)), np.zeros((n_s, 2))
    Al[:n_e, :n_e] = np.eye(3) + s * A * Ts
    Gs = [G(Ts - s_tilde[j]) for j in range(d_hi)] + [G(Ts)]
    Bl[:n_e] = Gs[0]
    for j in range(1, d_hi + 1):
        Al[:n_e, n_e + 2 * (j - 1) : n_e + 2 * j] = Gs[j] - Gs[j - 1]
    Bl[n_e : n_e + 2] = np.eye(2)
    for j in range(1, d_hi):
        Al[n_e + 2 * j : n_e + 2 * j + 2, n_e + 2 * (j - 1) : n_e + 2 * j] = np.eye(2)
    return Al, Bl


def coverage(m, lft, samples=300, seed=0):
    """Largest |exact - LFT closure| and largest |delta| over random slip and delay samples."""
    A, B, Bp, Cq, Dq, Dqp, _, blocks, prm = lft
    rng = np.random.default_rng(seed)
    c = m.config.slip
    taus = rng.uniform(m.config.network.delay.min, m.config.network.delay.max, size=(samples, 1 + m.d_hi))
    S = m.s_tilde(taus)[:, 0, :]
    worst, dmax = 0.0, 0.0
    for n in range(samples):
        mr, ml = rng.uniform(c.right.min, c.right.max), rng.uniform(c.left.min, c.left.max)
        s, d = (mr + ml) / 2, mr - ml
        diag = [np.full(prm["nU"] + 2, (s - prm["s_c"]) / prm["s_r"] if prm["s_r"] else 0.0),
                np.full(prm["nU"], (d - prm["d_c"]) / prm["d_r"] if prm["d_r"] else 0.0)]
        s_lo, s_hi, _, _ = slip_ranges(m)
        for j in range(m.d_hi):
            hmin, hmax = m.Ts - m.instant_ranges[j, 1], m.Ts - m.instant_ranges[j, 0]
            gmin, gmax = s_lo * hmin**2 / 2, s_hi * hmax**2 / 2
            h = m.Ts - S[n, j]
            d1 = ((hmin + hmax) / 2 - h) / ((hmax - hmin) / 2) if hmax > hmin else 0.0
            d2 = ((gmin + gmax) / 2 - s * h * h / 2) / ((gmax - gmin) / 2) if gmax > gmin else 0.0
            diag.append(np.array([d1, d1, d2]))
        Dl = np.diag(np.concatenate(diag))
        dmax = max(dmax, float(np.max(np.abs(Dl))))
        F = np.linalg.solve(np.eye(Dl.shape[0]) - Dl @ Dqp, Dl)
        Ae, Be = exact(m, S[n], mr, ml)
        worst = max(worst, float(np.max(np.abs(A + Bp @ F @ Cq - Ae))), float(np.max(np.abs(B + Bp @ F @ Dq - Be))))
    return worst, dmax


def solve(m, alpha, lft, motor):
    A, B, Bp, Cq, Dq, Dqp, Bw, blocks, _ = lft
    n_s, n_u, n_p, n_w = m.n_s, m.n_u, Bp.shape[1], Bw.shape[1]
    Q, Y, beta = cp.Variable((n_s, n_s), symmetric=True), cp.Variable((n_u, n_s)), cp.Variable(n_w)
    terms, o = [], 0
    for kind, size in blocks:  # M = Lambda^-1 with the structure of Delta (D-scalings)
        E = np.zeros((n_p, size))
        E[o : o + size] = np.eye(size)
        if kind == "delay":
            S, mm = cp.Variable((2, 2), symmetric=True), cp.Variable()
            terms += [E[:, :2] @ S @ E[:, :2].T, mm * np.outer(E[:, 2], E[:, 2])]
        else:
            S = cp.Variable((size, size), symmetric=True)
            terms.append(E @ S @ E.T)
        o += size
    M = sum(terms[1:], terms[0])
    AQ, CQ, Z = A @ Q + B @ Y, Cq @ Q + Dq @ Y, np.zeros
    L = cp.bmat([
        [-(1 - alpha) * Q, Z((n_s, n_p)), Z((n_s, n_w)), AQ.T, CQ.T],
        [Z((n_p, n_s)), -M, Z((n_p, n_w)), M @ Bp.T, M @ Dqp.T],
        [Z((n_w, n_s)), Z((n_w, n_p)), -cp.diag(beta), Bw.T, Z((n_w, n_p))],
        [AQ, Bp @ M, Bw, -Q, Z((n_s, n_p))],
        [CQ, Dqp @ M, Z((n_p, n_w)), Z((n_p, n_s)), -M]])
    cons = [(L + L.T) / 2 << -1e-7 * np.eye(L.shape[0]), cp.sum(beta) <= alpha]
    if motor:
        cons += motor_lmis(m, Q, Y)
    p = cp.Problem(cp.Minimize(0.1 * Q[0, 0] + Q[1, 1] + 0.1 * Q[2, 2]), cons)
    if not solve_optimal(p):
        return None
    return Y.value @ np.linalg.inv(Q.value), np.sqrt(beta.value.sum() / alpha * np.diag(Q.value)[:3])


if __name__ == "__main__":
    cases = [("default", {}), ("default, no motor limit", {"robot.max_motor_speed": None}),
             ("heavy slip, no motor limit", {"slip.right.min": 0.4, "slip.left.min": 0.4, "robot.max_motor_speed": None}),
             ("narrow slip [0.9, 1]", {"slip.right.min": 0.9, "slip.left.min": 0.9})]
    for name, over in cases:
        m = build_model(config(**over))
        lft = build(m)
        res, dmax = coverage(m, lft)
        motor = m.config.robot.max_motor_speed is not None
        sols = [r for r in (solve(m, a, lft, motor) for a in np.linspace(0.05, 0.5, 10)) if r is not None]
        head = f"{name:28s} coverage residual {res:.1e} (max|delta| {dmax:.3f}): "
        if not sols:
            print(head + "infeasible")
            continue
        K, ub = min(sols, key=lambda r: r[1][1])
        vc = m.config.verification
        path = make_path(m.config.reference.path, m.V)
        sim = simulate(m, K, path, draw_scenario(m, 200, 0, int(path.duration / m.Ts), path), vc.transient)
        mc = np.abs(sim.e[:, sim.settled]).max(axis=(0, 1))
        print(head + f"certified |e_y| <= {100 * ub[1]:.2f} cm; nonlinear MC max {100 * mc[1]:.2f} cm")
