"""Robust stability of a given gain on any linear plant over the network (``plant: kind: lti``,
docs/theory.md §14): one quadratic Lyapunov function for every admissible delay sequence.

With the over-approximation of :func:`robustsynth.model.lti.over_approximation` the closed loop is
``xi+ = M(t) xi + sum_j E w_j``, M affine in the pieces' positions t and ``|w_j| <= rho_j |F_j xi|``.
``V = xi' P xi`` decreases by the factor ``decay^2`` for every such step when, for every piece
combination and its ends (V(M(t) xi + E w) is convex in t, so the ends suffice) and with
S-procedure multipliers ``eps_j >= 0``,

    [[M' P M - decay^2 P + sum_j eps_j rho_j^2 F_j' F_j,  M' P E~], [E~' P M,  E~' P E~ - diag(eps_j I)]] < 0.

A point is accepted only after :func:`robustsynth.certificate.check_lti_certificate` proved it in
verified arithmetic.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["LtiAnalysis", "analyze_lti", "vertex_combinations", "DECAY", "STRICT"]

DECAY = 1.0 - 1e-6  # V shrinks by at least this factor per period: asymptotic stability with a margin
STRICT = 1e-7  # the LMIs' strictness (P >= I fixes the scale)


@dataclass(frozen=True)
class LtiAnalysis:
    certified: bool
    status: str  # certified | infeasible | rejected (the numpy check failed) | failed
    P: np.ndarray | None
    eps: np.ndarray | None
    vertices: int
    solve_time_s: float
    check: dict


def vertex_combinations(pw) -> tuple[np.ndarray, np.ndarray]:
    """(piece combinations (n_c, d), end combinations (n_e, d)): every piece of every instant, and both
    ends of a piece (one where the instant's range is a point)."""
    combos = np.array(list(itertools.product(*[range(t.size) for t in pw.theta])), dtype=int).reshape(-1, pw.d_hi)
    ends_per = [[0] if float(np.max(w)) == 0.0 else [0, 1] for w in pw.width]
    ends = np.array(list(itertools.product(*ends_per)), dtype=float).reshape(-1, pw.d_hi)
    return combos, ends


def _vertex_matrices(pw, combos: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every vertex's closed-loop matrix M (n_v, n_s, n_s) and the combination it belongs to (n_v,)."""
    Ms, owner = [], []
    for c, combo in enumerate(combos):
        for end in ends:
            Ms.append(pw.vertex(combo, end))
            owner.append(c)
    return np.array(Ms), np.array(owner)


def analyze_lti(pw, decay: float = DECAY, solver: str = "clarabel") -> LtiAnalysis:
    """Search P, eps for the LMIs of the module docstring; the verdict is the numpy check's.

    Every vertex's block is linear in the unknowns y = (P's upper triangle, eps): its coefficient
    matrices are computed in numpy, so cvxpy sees one affine map per vertex (fast to compile)."""
    import cvxpy as cp

    from ..certificate import check_lti_certificate
    from .solve import solve

    combos, ends = vertex_combinations(pw)
    n_s, n = pw.E.shape
    d = pw.d_hi
    k = n_s + d * n
    Et = np.hstack([pw.E] * d)
    Ms, owner = _vertex_matrices(pw, combos, ends)
    iu = np.triu_indices(n_s)
    n_p = iu[0].size
    basis = np.zeros((n_p, n_s, n_s))  # P = sum_i p_i S_i
    basis[np.arange(n_p), iu[0], iu[1]] = 1.0
    basis[np.arange(n_p), iu[1], iu[0]] = 1.0
    # the P-part of every vertex block, per basis matrix: [[M' S M - decay^2 S, M' S E~], [E~' S M, E~' S E~]]
    MtS = np.einsum("vab,ibc->viac", Ms.transpose(0, 2, 1), basis)  # (n_v, n_p, n_s, n_s)
    top = MtS @ Ms[:, None] - decay**2 * basis[None]
    off = MtS @ Et
    low = np.broadcast_to(Et.T @ basis @ Et, (len(Ms),) + (n_p, d * n, d * n))
    CP = np.concatenate([np.concatenate([top, off], axis=-1),
                         np.concatenate([off.transpose(0, 1, 3, 2), low], axis=-1)], axis=-2)  # (n_v, n_p, k, k)
    # the eps part: eps_j rho_j^2 F_j' F_j in the top block, -eps_j I in block j of the low one
    CE = np.zeros((len(Ms), d, k, k))
    for j in range(d):
        rho2 = np.array([float(pw.rho[j][combos[c, j]]) ** 2 for c in owner])
        CE[:, j, :n_s, :n_s] = rho2[:, None, None] * (pw.F[j].T @ pw.F[j])
        CE[:, j, n_s + j * n : n_s + (j + 1) * n, n_s + j * n : n_s + (j + 1) * n] -= np.eye(n)
    p = cp.Variable(n_p)
    eps = cp.Variable((len(combos), d), nonneg=True)
    P = cp.reshape(basis.reshape(n_p, -1).T @ p, (n_s, n_s), order="C")
    cons = [P >> np.eye(n_s)]
    for v in range(len(Ms)):
        lin = CP[v].reshape(n_p, k * k).T @ p + CE[v].reshape(d, k * k).T @ eps[owner[v]]
        X = cp.reshape(lin, (k, k), order="C")
        cons.append((X + X.T) / 2 << -STRICT * np.eye(k))
    prob = cp.Problem(cp.Minimize(0), cons)
    held: dict = {}

    def P_value() -> np.ndarray:
        return np.einsum("i,iab->ab", np.asarray(p.value, dtype=float), basis)

    def accept() -> bool:
        if p.value is None or eps.value is None:
            return False
        held["check"] = check_lti_certificate(pw, P_value(), np.maximum(eps.value, 0.0), decay, combos, ends)
        return bool(held["check"]["ok"])

    t0 = time.perf_counter()
    out = solve(prob, solver, accept)
    dt = time.perf_counter() - t0
    vertices = len(Ms)
    if out.kind == "ok":
        return LtiAnalysis(True, "certified", P_value(), np.maximum(np.array(eps.value), 0.0), vertices, dt,
                           held["check"])
    status = "infeasible" if out.kind == "infeasible" else ("rejected" if "check" in held else "failed")
    return LtiAnalysis(False, status, None, None, vertices, dt, held.get("check", {}))
