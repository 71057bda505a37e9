"""cvxpy builders of the synthesis LMIs (math.md §5), one compiled problem per objective.

Each builder returns an :class:`LMIProblem` whose ``cvxpy.Parameter`` s (``r2``, ``alpha``) are
changed between solves, so bisection and line search re-use one compiled problem (DPP).
Strict inequalities are written ``L << -margin * I`` with an explicit identity.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import cvxpy as cp
import numpy as np

__all__ = ["LMIProblem", "build_stability", "build_invariance", "build_hinf", "multiplier", "motor_constraints"]


@dataclass
class LMIProblem:
    problem: cp.Problem
    Q: cp.Variable
    Y: cp.Variable
    M: Any  # cvxpy expression (structured) with the shape of Delta
    params: dict[str, cp.Parameter] = field(default_factory=dict)
    extra: dict[str, cp.Variable] = field(default_factory=dict)

    def values(self) -> dict[str, np.ndarray]:
        Q = np.asarray(self.Q.value)
        out = {"Q": (Q + Q.T) / 2.0, "Y": np.asarray(self.Y.value)}
        M = self.M.value if hasattr(self.M, "value") else self.M
        M = np.zeros((0, 0)) if M is None else np.asarray(M, dtype=float).reshape(self.M.shape)
        out["M"] = (M + M.T) / 2.0
        for k, v in self.extra.items():
            out[k] = np.asarray(v.value)
        return out


def multiplier(n_blocks: int, kind: str) -> tuple[Any, list[cp.Variable]]:
    """M = Lambda^-1 with the structure of Delta = blockdiag(d1 I2, d2, ...).

    ``structured``: a 2x2 symmetric block per repeated scalar d1 I2 (a D-scaling) and a scalar
    for d2; ``full``: mu I (the paper's single scalar for |Delta| <= 1)."""
    n = 3 * n_blocks
    if n == 0:
        return cp.Constant(np.zeros((0, 0))), []
    if kind == "full":
        mu = cp.Variable(name="mu")
        return mu * np.eye(n), [mu]
    terms, variables = [], []
    for b in range(n_blocks):
        S = cp.Variable((2, 2), symmetric=True, name=f"S{b}")
        m = cp.Variable(name=f"m{b}")
        E = np.zeros((n, 2))
        E[3 * b : 3 * b + 2] = np.eye(2)
        f = np.zeros((n, 1))
        f[3 * b + 2] = 1.0
        terms += [E @ S @ E.T, m * (f @ f.T)]
        variables += [S, m]
    return sum(terms[1:], terms[0]), variables


def _sym(L: Any) -> Any:
    return (L + L.T) / 2.0


def _common(model: Any, kind: str):
    n_s, n_u, n_q = model.n_s, model.n_u, model.n_q
    Q = cp.Variable((n_s, n_s), symmetric=True, name="Q")
    Y = cp.Variable((n_u, n_s), name="Y")
    M, _ = multiplier(len(model.instants), kind)
    A, B, Bp, Cq, Dq = (np.asarray(x) for x in (model.A, model.B, model.B_p, model.C_q, model.D_q))
    AQ = A @ Q + B @ Y
    CQ = Cq @ Q + Dq @ Y if n_q else None
    return Q, Y, M, AQ, CQ, Bp


def motor_constraints(model: Any, Q: Any, Y: Any) -> list[Any]:
    """[[u_i^2, c_i^T Y], [Y^T c_i, Q]] >= 0 with u_i = rho_max - V^D / R  (math.md §5c)."""
    cfg = model.config
    rho_max = cfg.robot.max_motor_speed
    ubar = rho_max - cfg.reference.speed / cfg.robot.gear_radius
    # solve against a bound a hair tighter than the limit so that the numpy check has headroom
    ubar_solve = ubar * (1.0 - 1e-6)
    cons = []
    for c in np.asarray(model.J_inv):
        row = c @ Y  # (n_s,)
        blk = cp.bmat([[np.array([[ubar_solve**2]]), cp.reshape(row, (1, model.n_s), order="C")],
                       [cp.reshape(row, (model.n_s, 1), order="C"), Q]])
        cons.append(_sym(blk) >> 0)
    return cons


def build_stability(model: Any, kind: str, margin: float) -> LMIProblem:
    """Robust decay rate r (math.md §5a); scale fixed by Q >= I; parameter r2 = r^2."""
    Q, Y, M, AQ, CQ, Bp = _common(model, kind)
    n_s, n_q = model.n_s, model.n_q
    r2 = cp.Parameter(nonneg=True, name="r2", value=0.9)
    if n_q:
        Z = np.zeros((n_s, n_q))
        L = cp.bmat([[-r2 * Q, AQ.T, CQ.T], [AQ, -Q + Bp @ M @ Bp.T, Z], [CQ, Z.T, -M]])
    else:
        L = cp.bmat([[-r2 * Q, AQ.T], [AQ, -Q]])
    cons = [_sym(L) << -margin * np.eye(L.shape[0]), Q >> np.eye(n_s)]
    if n_q:
        cons.append(M >> margin * np.eye(n_q))
    prob = cp.Problem(cp.Minimize(cp.trace(Q) / n_s), cons)
    return LMIProblem(prob, Q, Y, M, {"r2": r2})


def build_invariance(model: Any, kind: str, margin: float, weights: np.ndarray, motor: bool) -> LMIProblem:
    """Invariant, attracting ellipsoid under bounded slip (math.md §5b); parameter alpha.

    Minimizes sum_i weights_i * Q_ii, i.e. the weighted squared bounds on e_x, e_y, e_theta."""
    Q, Y, M, AQ, CQ, Bp = _common(model, kind)
    n_s, n_q = model.n_s, model.n_q
    Bw = np.asarray(model.B_w)
    n_w = Bw.shape[1]
    alpha = cp.Parameter(nonneg=True, name="alpha", value=0.1)
    one_minus = cp.Parameter(nonneg=True, name="one_minus_alpha", value=0.9)
    beta = cp.Variable(n_w, name="beta")
    Zsw = np.zeros((n_s, n_w))
    rows = [[-one_minus * Q, Zsw, AQ.T], [Zsw.T, -cp.diag(beta), Bw.T], [AQ, Bw, -Q + (Bp @ M @ Bp.T if n_q else 0)]]
    if n_q:
        rows[0].append(CQ.T)
        rows[1].append(np.zeros((n_w, n_q)))
        rows[2].append(np.zeros((n_s, n_q)))
        rows.append([CQ, np.zeros((n_q, n_w)), np.zeros((n_q, n_s)), -M])
    L = cp.bmat(rows)
    cons = [_sym(L) << -margin * np.eye(L.shape[0]), cp.sum(beta) <= alpha, Q >> margin * np.eye(n_s)]
    if n_q:
        cons.append(M >> margin * np.eye(n_q))
    if motor:
        cons += motor_constraints(model, Q, Y)
    obj = cp.Minimize(sum(float(weights[i]) * Q[i, i] for i in range(3)))
    prob = cp.Problem(obj, cons)
    return LMIProblem(prob, Q, Y, M, {"alpha": alpha, "one_minus_alpha": one_minus}, {"beta": beta})


def build_hinf(model: Any, kind: str, margin: float, weights: np.ndarray) -> LMIProblem:
    """l2 gain gamma from the slip deviation d to z = diag(weights) e (math.md §5d); minimizes gamma^2."""
    Q, Y, M, AQ, CQ, Bp = _common(model, kind)
    n_s, n_q = model.n_s, model.n_q
    Bd = np.asarray(model.B_d)
    n_d = Bd.shape[1]
    Cz = np.zeros((3, n_s))
    Cz[:, :3] = np.diag(weights)
    n_z = 3
    g = cp.Variable(nonneg=True, name="gamma2")
    CzQ = Cz @ Q
    Z = np.zeros
    rows = [
        [-Q, Z((n_s, n_d)), AQ.T, CzQ.T],
        [Z((n_d, n_s)), -g * np.eye(n_d), Bd.T, Z((n_d, n_z))],
        [AQ, Bd, -Q + (Bp @ M @ Bp.T if n_q else 0), Z((n_s, n_z))],
        [CzQ, Z((n_z, n_d)), Z((n_z, n_s)), -np.eye(n_z)],
    ]
    if n_q:
        rows[0].append(CQ.T)
        rows[1].append(Z((n_d, n_q)))
        rows[2].append(Z((n_s, n_q)))
        rows[3].append(Z((n_z, n_q)))
        rows.append([CQ, Z((n_q, n_d)), Z((n_q, n_s)), Z((n_q, n_z)), -M])
    L = cp.bmat(rows)
    cons = [_sym(L) << -margin * np.eye(L.shape[0]), Q >> margin * np.eye(n_s)]
    if n_q:
        cons.append(M >> margin * np.eye(n_q))
    prob = cp.Problem(cp.Minimize(g), cons)
    return LMIProblem(prob, Q, Y, M, {}, {"gamma2": g})
