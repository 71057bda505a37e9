"""A common certificate of a vertex subset carried to every vertex, where the vertices carry channels (issue 51).

A relaxation's certificate (the same invariance LMIs on a subset of the vertices, :func:`.heading_search._on_subset`)
fixes Q, Y = K Q, alpha and beta.  At a vertex outside the subset the LMI of docs/theory.md §6b is then affine in
that vertex's S-procedure multiplier M alone (``-B_p M B_p'`` and ``M`` on the diagonal), and the vertices of one
``Vertex.group`` (a delay vertex: its slip corners and its within-period vertices) share theirs.  So each group the
subset lacks asks only a small problem: a diagonal M >= margin I that makes its vertices' LMIs >= t I with t as large
as possible, a few LMIs of one vertex's size in ``n_q`` scalars, instead of the whole problem (on the default robot's
linearized turning model at d_hi = 3: 432 vertices of 80 channels, 2.2 GB and about 150 s a solve).

Nothing here proves anything: the multipliers found are candidates, and the certificate with them counts only where
the numpy re-check (:func:`robustsynth.certificate.check_certificate`) proves it at every vertex, as for any solve.
"""

from __future__ import annotations

from typing import Any, Callable

import cvxpy as cp
import numpy as np

from ..certificate.lmis import lmi_invariance
from .phase1 import PARALLEL
from .solve import solve_all

__all__ = ["extend_multipliers"]


def _group_of(i: int, v: Any) -> tuple[str, int]:
    """The key of the multiplier vertex i shares: its group's, or its own (Vertex.group < 0)."""
    return ("group", v.group) if v.group >= 0 else ("vertex", i)


def _members(model: Any) -> dict[tuple[str, int], list[Any]]:
    """Per multiplier key, the vertices whose LMIs it enters: the model's own and its within-period vertices."""
    out: dict[tuple[str, int], list[Any]] = {}
    for i, v in enumerate(model.vertices):
        out.setdefault(_group_of(i, v), []).append(v)
    for v in model.covering_vertices:
        if v.group >= 0:
            out.setdefault(("group", v.group), []).append(v)
    return out


def _lmis(verts: list[Any], Q: np.ndarray, Y: np.ndarray, beta: np.ndarray, alpha: float
          ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per vertex, its invariance LMI without the multiplier (M = 0) and its B_p."""
    n_q = verts[0].n_q
    return [(lmi_invariance(v, Q, Q, Q, Y, np.zeros((n_q, n_q)), beta, alpha), np.asarray(v.B_p)) for v in verts]


def _fits(lmis: list[tuple[np.ndarray, np.ndarray]], M: np.ndarray, margin: float) -> bool:
    """Whether the LMIs (:func:`_lmis`) with the multiplier ``M`` are >= margin I (floating point: a candidate
    only, the certificate's re-check proves)."""
    n_q = M.shape[0]
    for L0, Bp in lmis:
        L = L0.copy()
        a = L.shape[0] - n_q
        L[a - Bp.shape[0]: a, a - Bp.shape[0]: a] -= Bp @ M @ Bp.T
        L[a:, a:] += M
        if np.linalg.eigvalsh((L + L.T) / 2.0)[0] < margin:
            return False
    return True


def _problem(lmis: list[tuple[np.ndarray, np.ndarray]], n_q: int, margin: float) -> tuple[cp.Problem, Any, Any]:
    """The diagonal multiplier (>= margin) that maximizes the least eigenvalue t of the LMIs (:func:`_lmis`)."""
    d = cp.Variable(n_q, name="d")
    t = cp.Variable(name="t")
    D = cp.diag(d)
    cons = [d >= margin]
    for L0, Bp in lmis:
        n, n_s = L0.shape[0], Bp.shape[0]
        a = n - n_q - n_s  # rows: xi, w, then xi+ (where -B_p M B_p' enters) and q (where M does)
        BDB = Bp @ D @ Bp.T
        shift = cp.bmat([[np.zeros((a, a)), np.zeros((a, n_s)), np.zeros((a, n_q))],
                         [np.zeros((n_s, a)), -(BDB + BDB.T) / 2.0, np.zeros((n_s, n_q))],
                         [np.zeros((n_q, a + n_s)), D]])
        cons.append(L0 + shift >> t * np.eye(n))
    return cp.Problem(cp.Maximize(t), cons), d, t


def extend_multipliers(model: Any, cert: dict[str, Any], K: np.ndarray, index: tuple[int, ...], solver: str,
                       say: Callable[[str], None] = lambda _m: None) -> list[np.ndarray] | None:
    """The multipliers of every vertex of ``model`` for the common invariance certificate ``cert`` of its vertices
    ``index`` (``cert['multipliers']['M']`` one per vertex of the subset, in that order): a group the subset holds
    keeps its multiplier, each other group's is found by :func:`_least_margin`.  None where the certificate is not
    a common one, a vertex's channels need a multiplier that is not diagonal (the kinematic channels' are), or a
    group has none with the certificate's margin (the relaxation's set does not fit there: a solve of all it is)."""
    if cert.get("lyapunov", "common") != "common" or "Q" not in cert:
        return None
    if any(v.n_q and not v.diagonal for v in model.vertices):
        return None
    Q = np.asarray(cert["Q"], dtype=float)
    Q = (Q + Q.T) / 2.0
    Y = np.asarray(K, dtype=float) @ Q
    beta, alpha, margin = np.asarray(cert["beta"], dtype=float), float(cert["alpha"]), float(cert["margin"])
    have: dict[tuple[str, int], np.ndarray] = {}
    for j, i in enumerate(index):
        have.setdefault(_group_of(i, model.vertices[i]), np.asarray(cert["multipliers"]["M"][j], dtype=float))
    members = _members(model)
    todo = [key for key in members if key not in have and members[key][0].n_q]
    if todo:
        say(f"  {len(todo)} groups of vertices outside the relaxation: a multiplier for each, their LMIs at the "
            "relaxation's Q, Y, alpha and beta (one of the relaxation's where it fits)")
    lmis = {key: _lmis(members[key], Q, Y, beta, alpha) for key in todo}
    known = list({id(M): M for M in have.values()}.values())
    # a multiplier of the subset's fits another group's vertices often (the same channels, nearby delays): the
    # numpy check of each is cheap against a solve
    left = []
    for key in todo:
        fit = next((M for M in known if M.shape[0] == members[key][0].n_q and _fits(lmis[key], M, margin)), None)
        if fit is None:
            left.append(key)
        else:
            have[key] = fit
    if left:
        say(f"  {len(left)} of them need a multiplier of their own (one small problem each, {PARALLEL} at a time)")
    for k in range(0, len(left), PARALLEL):
        keys = left[k: k + PARALLEL]
        posed = [_problem(lmis[key], members[key][0].n_q, margin) for key in keys]
        outs = solve_all([p for p, _, _ in posed], solver, [lambda t=t: t.value is not None for _, _, t in posed])
        for key, (_, d, t), out in zip(keys, posed, outs):
            if out.kind != "ok" or not float(t.value) >= margin:
                say(f"  none for the vertices of {key[0]} {key[1]} with margin {margin:g}: a solve of all")
                return None
            have[key] = np.diag(np.maximum(np.asarray(d.value, dtype=float), margin))
    return [have[_group_of(i, v)] if v.n_q else np.zeros((0, 0)) for i, v in enumerate(model.vertices)]
