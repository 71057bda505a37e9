"""Issue 49: how far the certified |e_y| is from what the robot can reach, measured from below by a second method.

The verification's adversary (a forward beam search on the nonlinear robot) gives the "robot maximum" of the
certified / robot maximum ratio.  Is a ratio near 1.8 the adversary's weakness or the certificate's conservatism?
Here an independent search answers it for d_hi = 1: a *dual* (costate) beam search on the robot's kinematics
linearized about its reference (``Model.linearized_arc_period``, exact arcs, the icr or tracks slip, the turning
feedforward).  For affine maps xi+ = M_s xi + b_s chosen each period from the slip corners x a 9-delay grid x the
reference's yaw rates (a grid of max_step spacing, |w_k - w_{k-1}| <= max_step), e_y after N periods is
sum_j lam_j' b_{s_j} + lam_0' xi_0 with lam_N = e_y's row and lam_j = M_{s_j}' lam_{j+1}: the search runs backwards,
keeping for each yaw rate the ``width`` histories of largest value + the best start's term (the equilibria of
constant histories).
Its best history, from a straight equilibrium, is then replayed forwards on the nonlinear robot (``simulate``
along the reference of its yaw rates), whose largest |e_y| is a reachable value: a lower bound on the robot maximum.

    .venv/bin/python benchmarks/bench_reachable.py [CONFIG [GAINS]]   # default: configs/default.yaml, its baseline
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
WIDTH, STEPS, N_TAU = 60, 150, 9  # WIDTH: histories kept per yaw rate


def _choices(model, K: np.ndarray):
    """Every period's choice (corner, delay, w_k, w_{k-1}) and its affine closed-loop map (M (n, ns, ns), b (n, ns))."""
    turns = model.turns
    ys = np.zeros(1) if turns is None else np.arange(-turns.max_yaw_rate, turns.max_yaw_rate + 1e-12, turns.max_step)
    corners, taus = np.asarray(model.corners), model.network.grid(N_TAU)
    C = np.array([(c, t, i, j) for c in range(len(corners)) for t in range(len(taus)) for i in range(ys.size)
                  for j in range(ys.size) if abs(ys[i] - ys[j]) <= (turns.max_step if turns else 0.0) + 1e-12])
    n, ns = len(C), model.n_s
    mu, S = corners[C[:, 0]], model.s_tilde(np.stack([taus[C[:, 1]]] * 2, -1)).reshape(n, -1)
    w = np.stack([ys[C[:, 2]], ys[C[:, 3]]], -1)

    def step(xi: np.ndarray) -> np.ndarray:
        du = xi @ K.T
        return np.concatenate([model.linearized_arc_period(xi, du, S, mu, w), du], -1)

    b = step(np.zeros((n, ns)))
    M = np.stack([step(np.broadcast_to(np.eye(ns)[k], (n, ns))) - b for k in range(ns)], -1)
    return C, M, b, ys, corners, taus


def dual_beam(model, K: np.ndarray, sign: float, width: int = WIDTH, steps: int = STEPS) -> tuple[float, list]:
    """The largest ``sign`` e_y the backward beam finds from a straight equilibrium, and its history forwards
    [(corner, delay index, w_k index), ...]."""
    C, M, b, ys, _, _ = _choices(model, K)
    ns, zero = model.n_s, int(np.argmin(np.abs(ys)))
    const = C[:, 2] == C[:, 3]
    eq = np.linalg.solve(np.eye(ns)[None] - M[const], b[const][..., None])[..., 0]
    eq_at = [eq[C[const, 2] == i] for i in range(ys.size)]  # equilibria of constant histories, per yaw rate
    start = eq[(C[const, 2] == zero)]  # the replay starts straight
    lam, val, wc = np.zeros((1, ns)), np.zeros(1), np.array([-1])
    lam[0, 1] = sign
    back: list[tuple[np.ndarray, np.ndarray]] = []  # per step: (parent index, choice) of each kept history
    best, hist = -np.inf, []

    def walk(i: int, k: int) -> list:  # the kept history i of step k, from its last choice back to its first
        out = []
        while k >= 0:
            par, ch = back[k]
            out.append(tuple(int(x) for x in C[ch[i]][[0, 1, 2]]))
            i, k = int(par[i]), k - 1
        return out

    for k in range(steps):
        parts = []
        for yi in np.unique(wc):
            rows = np.flatnonzero(wc == yi)
            cs = np.arange(len(C)) if yi < 0 else np.flatnonzero(C[:, 2] == yi)
            parts.append((np.repeat(rows, cs.size), np.tile(cs, rows.size),
                          (val[rows][:, None] + lam[rows] @ b[cs].T).ravel(),
                          np.einsum("bi,nij->bnj", lam[rows], M[cs]).reshape(-1, ns)))
        par, ch, v2, l2 = (np.concatenate([p[i] for p in parts]) for i in range(4))
        w2 = C[ch, 3]
        tail = np.full(v2.shape, -np.inf)
        for yi in range(ys.size):
            s = w2 == yi
            if s.any():
                tail[s] = np.max(l2[s] @ eq_at[yi].T, axis=1)
        straight = np.flatnonzero(w2 == zero)
        if straight.size:  # a history that starts straight, from its best equilibrium: a value reached
            sv = v2[straight] + np.max(l2[straight] @ start.T, axis=1)
            j = int(np.argmax(sv))
            if sv[j] > best:
                i = straight[j]
                best = float(sv[j])
                hist = [tuple(int(x) for x in C[ch[i]][[0, 1, 2]])] + (walk(int(par[i]), k - 1) if k else [])
        order = np.argsort(-(v2 + tail), kind="stable")  # the best ``width`` of each yaw rate w_{k-1}: the
        rank = np.empty_like(order)  # histories that reach a straight start stay beside those on the largest arcs
        ws = w2[order]
        first = np.r_[0, np.flatnonzero(np.diff(np.sort(ws, kind="stable"))) + 1]
        by_w = np.argsort(ws, kind="stable")
        rank[by_w] = np.arange(ws.size) - np.repeat(first, np.diff(np.r_[first, ws.size]))
        keep = order[rank < width]
        back.append((par[keep], ch[keep]))
        val, lam, wc = v2[keep], l2[keep], w2[keep]
        if np.max(np.abs(lam)) < 1e-12:
            break
    return sign * best, hist  # hist: from the earliest period to the last (the one whose e_y it is)


def replay(model, K: np.ndarray, hist: list) -> float:
    """The largest |e_y| of the nonlinear robot along ``hist`` from the straight equilibrium that starts it best."""
    from robustsynth.scenarios import Scenario, split_state
    from robustsynth.plants.path import pose_from_error
    from robustsynth.robot_verification.simulate import FREE_YAW, adversary_course, simulate

    _, _, _, ys, corners, taus = _choices(model, K)
    T, d_hi = len(hist), model.d_hi
    mu = corners[[h[0] for h in hist]]
    tau = taus[[h[1] for h in hist]]
    yaw = ys[[h[2] for h in hist]]
    course = FREE_YAW if model.turns is not None else "straight"
    path = adversary_course(model, T, course, yaw)
    best = 0.0
    for c in corners:  # every straight steady state as the start
        xi0 = model.equilibrium(K, c[None, :])
        e0, du0, z0 = split_state(model, xi0)
        scen = Scenario(np.concatenate([np.full((1, d_hi), tau[0]), tau[None, :]], 1), mu[None], np.zeros((1, T, 3)),
                        pose_from_error(path, e0), (), du0, z0)
        sim = simulate(model, K, path, scen)
        best = max(best, float(np.max(np.abs(sim.e[0, :, 1]))))
    return best


def main() -> dict[str, float]:
    from robustsynth.config import load_config
    from robustsynth.model import build_model

    args = sys.argv[1:] if __name__ == "__main__" else []
    cfg_path = Path(args[0]) if args else ROOT / "configs" / "default.yaml"
    gains_path = Path(args[1]) if len(args) > 1 else ROOT / "results" / "baselines" / cfg_path.stem / "gains.json"
    model = build_model(load_config(cfg_path))
    g = json.loads(gains_path.read_text())
    K = np.asarray(g["K"], dtype=float)
    c = g["certified"]
    ub, allt = c["ultimate_bound"]["e_y"], (c.get("ultimate_bound_between_samples") or {}).get("e_y")
    if model.d_hi != 1:
        print(f"{cfg_path.stem}: d_hi {model.d_hi}: this search is written for d_hi = 1 (the delay history would be "
              "part of each history's state)")
        return {}
    out = {}
    for sign in (1.0, -1.0):
        t0 = time.perf_counter()
        lin, hist = dual_beam(model, K, sign)
        robot = replay(model, K, hist)
        out[f"e_y {sign:+.0f} linearized"], out[f"e_y {sign:+.0f} robot"] = lin, robot
        print(f"{cfg_path.stem}, e_y {'+' if sign > 0 else '-'}: the dual beam (width {WIDTH}, {len(hist)} periods) "
              f"reaches {100 * abs(lin):.3f} cm on the linearized robot, {100 * robot:.3f} cm replayed on the nonlinear "
              f"robot ({time.perf_counter() - t0:.0f} s); certified {100 * ub:.3f} cm at the samples"
              + (f", {100 * allt:.3f} cm for all t" if allt else "")
              + f": certified / reached {ub / max(robot, 1e-12):.2f}")
    return out


if __name__ == "__main__":
    main()
