"""Robust stability of a given gain on any linear plant over the network (``plant: kind: lti``,
docs/theory.md §14): one quadratic Lyapunov function for every admissible delay sequence.

With the over-approximation of :func:`robustsynth.core.delays.over_approximation` the closed loop is
``xi+ = M(t) xi + sum_j E w_j``, M affine in the instants' positions t and ``|w_j| <= rho_j |F_j xi|``.
``V = xi' P xi`` decreases by the factor ``decay^2`` for every such step when, at every vertex of the
in-order instants' polytope (V(M(t) xi + E w) is convex in t, so the vertices suffice) and with
S-procedure multipliers ``eps_j >= 0``,

    [[M' P M - decay^2 P + sum_j eps_j rho_j^2 F_j' F_j,  M' P E~], [E~' P M,  E~' P E~ - diag(eps_j I)]] < 0

(the synthesis' form; :func:`analyze_lti` adds a multiplier per direction of the remainder, and gives
instants on equal ranges one channel: their remainders enter as one sum).

A point is accepted only after :func:`robustsynth.certificate.lti.check_lti_certificate` proved it in
verified arithmetic.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..core.delays import YOUNG_DELTA, channel_groups, kept_directions, vertex_combinations
from ..results import AnalysisResult
from .lmis import _sym_basis
from .result import SynthesisResult
from .solve import auto_threads

__all__ = ["analyze_lti", "vertex_combinations", "LinearJob", "line_search_design",
           "synthesize_lti", "auto_threads", "DECAY", "STRICT"]

DECAY = 1.0 - 1e-6  # V shrinks by at least this factor per period: asymptotic stability with a margin
STRICT = 1e-7  # the LMIs' strictness (P >= I fixes the scale)
ALPHA_FAR = 0.9  # ultimate-bound: the line search's grid of 1 - alpha starts here
REFINE_ROUNDS = 2  # then rounds of two solves around the best alpha (halving the bracket in log(1 - alpha))
INPUT_BACKOFF = 1e-6  # synthesis: the input limits are posed this much (relative) tighter than proven


def _vertex_matrices(pw, verts: tuple) -> np.ndarray:
    """Every vertex's closed-loop matrix M (n_v, n_s, n_s) (``verts`` = (combos, owner, fractions))."""
    combos, owner, frac = verts
    return np.array([pw.vertex(combos[c], end) for c, end in zip(owner, frac)])


def channel_layout(pw, merge: bool = True) -> tuple:
    """The analysis LMIs' remainder channels: (kept directions and the dropped ones' bounds per instant
    (:func:`robustsynth.core.delays.kept_directions`), the instants with dropped directions, the decay's factor
    for them (Young's inequality, as in :func:`robustsynth.certificate.lti.lti_vertex_blocks`), the groups of
    instants sharing a channel (:func:`robustsynth.core.delays.channel_groups`; ``merge=False``: one per
    instant), each group's kept directions, and the channels E~ (n_s, their total width))."""
    n = pw.E.shape[1]
    kept, dropped = kept_directions(pw)
    n_drop = sum(len(kj) < n for kj in kept)
    shrink = 1.0 / (1.0 + YOUNG_DELTA) if n_drop else 1.0
    groups = channel_groups(pw, kept) if merge else [[j] for j in range(pw.d_hi) if len(kept[j])]
    dirs = [kept[g[0]] for g in groups]  # a group's kept directions (its instants' are equal)
    Et = np.hstack([pw.channels(g[0])[:, u] for g, u in zip(groups, dirs)])
    return kept, dropped, n_drop, shrink, groups, dirs, Et


def analyze_lti(pw, decay: float = DECAY, solver: str = "clarabel", merge: bool = True) -> AnalysisResult:
    """Search P and the multipliers for the LMIs of the module docstring; the verdict is the numpy check's.

    Per instant j the remainder enters through the channels E U_j (U_j = ``pw.dirs[j]``) with two kinds of
    multiplier: one on the full block (|w_j| <= rho_j |F_j xi|) and one per direction (|w_jl| <= rho_jl |F_j
    xi|); the LMIs hold when the sum of the S-procedure terms does, so either kind alone, or both, may
    carry the proof (a remainder along one direction: the directional ones are far tighter; an isotropic
    one: the full block).  Instants with equal channels (:func:`robustsynth.core.delays.channel_groups`: equal
    ranges) share one channel and one set of multipliers per combination (``merge=False``: a channel and
    multipliers per instant): their remainders enter as one sum W, and with a multiplier a on each of the
    group's g instants every split of W costs at least a |W|^2 / g, so the channel's diagonal is -a / g,
    linear (docs/theory.md §14).  Every vertex's block is linear in the unknowns y = (P's upper triangle,
    multipliers): its coefficient matrices are computed in numpy, and enter as parameters of a problem
    compiled once per structure."""
    from ..certificate.lti import check_lti_certificate, lti_check
    from .solve import solve

    verts = vertex_combinations(pw)
    combos, owner, _ = verts
    n_s, n = pw.E.shape
    d = pw.d_hi
    kept, dropped, n_drop, shrink, groups, dirs, Et = channel_layout(pw, merge)
    k = n_s + Et.shape[1]
    # the multipliers, per group: the full block, then one per kept direction (flat index; the numpy check
    # reads them per instant in a (d, 1 + n) layout, every instant of a group with the group's values)
    slots = [(g, 0) for g in range(len(groups))] + [(g, 1 + int(l)) for g in range(len(groups)) for l in dirs[g]]
    q = len(slots)
    Ms = _vertex_matrices(pw, verts)
    basis = _sym_basis(n_s)  # P = sum_i p_i S_i
    n_p = len(basis)
    # the P-part of every vertex block, per basis matrix: [[M' S M - decay^2 S, M' S E~], [E~' S M, E~' S E~]]
    MtS = np.einsum("vab,ibc->viac", Ms.transpose(0, 2, 1), basis)  # (n_v, n_p, n_s, n_s)
    top = MtS @ Ms[:, None] - decay**2 * shrink * basis[None]
    off = MtS @ Et
    low = np.broadcast_to(Et.T @ basis @ Et, (len(Ms),) + (n_p, k - n_s, k - n_s))
    CP = np.concatenate([np.concatenate([top, off], axis=-1),
                         np.concatenate([off.transpose(0, 1, 3, 2), low], axis=-1)], axis=-2)  # (n_v, n_p, k, k)
    FF = [pw.F[j].T @ pw.F[j] for j in range(d)]
    # pbar >= lambda_max(P) carries the dropped directions' term pbar n_drop / delta rho_D^2 F_j' F_j
    CB = np.zeros((len(Ms), k, k))
    if n_drop:
        for j in range(d):
            CB[:, :n_s, :n_s] += (n_drop / YOUNG_DELTA * dropped[j][combos[owner, j]] ** 2)[:, None, None] * FF[j]
    # the multipliers' part: sum over the group's instants of (eps_0 rho_j^2 + eps_l rho_jl^2) F_j' F_j in the
    # top block, and -eps_0 / g on the group's channel, -eps_l / g at its direction l, in the low one
    CE = np.zeros((len(Ms), q, k, k))
    start = np.cumsum([n_s] + [len(u) for u in dirs])
    for e, (g, slot) in enumerate(slots):
        for j in groups[g]:
            piece = combos[owner, j]
            bound = pw.rho[j][piece] if slot == 0 else pw.rho_dir[j][piece, slot - 1]
            CE[:, e, :n_s, :n_s] += (bound**2)[:, None, None] * FF[j]
        idx = (np.arange(start[g], start[g + 1]) if slot == 0 else
               start[g] + int(np.flatnonzero(dirs[g] == slot - 1)[0]))
        CE[:, e, idx, idx] = -1.0 / len(groups[g])
    with _PROBLEMS_LOCK:  # the cached problem's parameters and values belong to one solve at a time
        prob, p, eps, pbar, CPp, CEp, CBp = _analysis_problem(len(Ms), n_p, k, q, len(combos), n_s,
                                                               tuple(owner.tolist()), basis)
        for v in range(len(Ms)):  # the vertices' coefficients: parameters of a problem compiled once per structure
            CPp[v].value = CP[v].reshape(n_p, k * k).T
            CEp[v].value = CE[v].reshape(q, k * k).T
            CBp[v].value = CB[v].reshape(k * k)
        held: dict = {}

        def P_value() -> np.ndarray:
            return np.einsum("i,iab->ab", np.asarray(p.value, dtype=float), basis)

        def eps_value() -> np.ndarray:
            flat = np.maximum(np.asarray(eps.value, dtype=float), 0.0)
            out = np.zeros((len(combos), d, 1 + n))
            for e, (g, slot) in enumerate(slots):
                out[:, groups[g], slot] = flat[:, e, None]
            return out

        def accept() -> bool:
            if p.value is None or eps.value is None:
                return False
            held["check"] = check_lti_certificate(pw, P_value(), eps_value(), decay, verts)
            return bool(held["check"]["ok"])

        t0 = time.perf_counter()
        # no first-order fallback: SCS at 1e-8 took 31 s on a 150-vertex problem and rescued nothing
        # (measured: margin on configs/zbp.yaml with 6 pieces); a failed solve is "not certified here"
        out = solve(prob, solver, accept, fallback=False)
        dt = time.perf_counter() - t0
        vertices = len(Ms)
        check = lti_check(held["check"], {"decay": decay}) if "check" in held else None
        if out.kind == "ok":
            return AnalysisResult(True, "certified", "common", {"P": P_value(), "multipliers": eps_value(),
                                                                "vertices": vertices}, check, dt)
        status = "infeasible" if out.kind == "infeasible" else ("rejected" if "check" in held else "failed")
        return AnalysisResult(False, status, "common", None, check, dt)


_PROBLEMS: dict = {}  # the analysis LMIs per structure, compiled once by cvxpy (its parameters: the coefficients)
_PROBLEMS_KEPT = 4
_PROBLEMS_LOCK = threading.RLock()


def _analysis_problem(n_v: int, n_p: int, k: int, q: int, n_c: int, n_s: int, owner: tuple, basis: np.ndarray):
    """(problem, p, eps, coefficient parameters per vertex) of a structure: the margins' bisections solve
    the same structure many times with new coefficients, and cvxpy then reuses its compilation (DPP),
    which took two thirds of a solve's time (measured: profile of `robustsynth margin configs/zbp.yaml`)."""
    import cvxpy as cp

    key = (n_v, n_p, k, q, n_c, n_s, owner)
    if key in _PROBLEMS:
        return _PROBLEMS[key]
    p = cp.Variable(n_p)
    eps = cp.Variable((n_c, q), nonneg=True)
    pbar = cp.Variable(nonneg=True)  # >= lambda_max(P): the dropped directions' term
    CPp = [cp.Parameter((k * k, n_p)) for _ in range(n_v)]
    CEp = [cp.Parameter((k * k, q)) for _ in range(n_v)]
    CBp = [cp.Parameter(k * k) for _ in range(n_v)]
    P = cp.reshape(basis.reshape(n_p, -1).T @ p, (n_s, n_s), order="C")
    cons = [P >> np.eye(n_s), P << pbar * np.eye(n_s)]
    for v in range(n_v):
        X = cp.reshape(CPp[v] @ p + CEp[v] @ eps[owner[v]] + CBp[v] * pbar, (k, k), order="C")
        cons.append((X + X.T) / 2 << -STRICT * np.eye(k))
    entry = (cp.Problem(cp.Minimize(0), cons), p, eps, pbar, CPp, CEp, CBp)
    while len(_PROBLEMS) >= _PROBLEMS_KEPT:
        _PROBLEMS.pop(next(iter(_PROBLEMS)))
    _PROBLEMS[key] = entry
    return entry


# ------------------------------------------------------------------ synthesis (docs/theory.md §15)


@dataclass(frozen=True)
class _Candidate:
    """What an objective's linear design ended with: a gain u_k = K xi_k and its proven ``figures`` (certified only
    when ``check_lti_certificate`` and ``lti_within`` proved it in numpy), or how it failed (``status``, ``message``);
    :func:`synthesize_lti` makes a certified one a SynthesisResult and raises for the rest."""

    certified: bool
    status: str  # certified | infeasible | rejected | failed
    objective: str
    K: np.ndarray | None
    P: np.ndarray | None  # the certified set is {xi' P xi <= 1}
    eps: np.ndarray | None
    alpha: float | None  # V+ <= alpha V (+ (1 - alpha) with the disturbance)
    figures: dict
    check: dict  # check_lti_certificate's record: ok, failing, vertices, min_eig
    d_hi: int
    vertices: int
    solves: int
    solve_time_s: float
    message: str = ""
    search: tuple = ()  # each alpha tried and how its last solve ended


class _Vertices:
    """The open loop at every vertex of the over-approximation: ``M = A_v + B_v K`` and the remainder
    rows ``F_j = Fa_j (+ K for j = 0)`` (docs/theory.md §15)."""

    def __init__(self, plant: dict, Ts: float, tau_min: float, tau_hi: float, d: int, pieces: int) -> None:
        from ..core.delays import over_approximation

        A, B = plant["A"], plant["B"]
        n, m = B.shape
        self.n, self.m, self.d = n, m, d
        self.n_s = n + d * m
        pw0 = over_approximation(A, B, np.zeros((m, self.n_s)), Ts, tau_min, tau_hi, d, pieces)
        self.pw0 = pw0
        self.verts = vertex_combinations(pw0)
        self.combos, self.owner, frac = self.verts
        B0 = np.zeros((self.n_s, m))
        B0[n : n + m] = np.eye(m)  # u_k enters the shift register; the plant's rows through G_0 only
        Av, Bv, rho = [], [], []
        for c, end in zip(self.owner, frac):
            combo = self.combos[c]
            Av.append(pw0.vertex(combo, end))
            i = combo[0]
            G0 = pw0.base[0][i] + end[0] * pw0.width[0][i] * pw0.slope[0][i]
            Bv.append(B0 + pw0.E @ G0)
            rho.append([float(pw0.rho[j][combo[j]]) for j in range(d)])
        self.Av, self.Bv = np.array(Av), np.array(Bv)
        self.rho = np.array(rho)
        self.Fa = pw0.F  # with K = 0: the past commands' differences


def _dual_blocks(V: _Vertices, Q: np.ndarray, Y: np.ndarray, eps_v: np.ndarray, alpha: float,
                 c_dist: float | None, C_out: np.ndarray | None = None) -> np.ndarray:
    """The synthesis LMI's blocks, batched over the vertices (affine in Q, Y, eps and 1/c):

        [[-alpha Q,    (M Q)',                            (rho_j F_j Q)'  ],
         [M Q,         -Q + (sum_j eps_j + 1/c) E E',     0               ],
         [rho_j F_j Q,  0,                                -diag(eps_j I_m)]]  <= 0,

    M Q = A_v Q + B_v Y, F_0 Q = Fa_0 Q + Y, F_j Q = Fa_j Q; the 1/c term (the disturbance's, c =
    ``c_dist``) is the Schur complement of its row [0, -c I, E', 0] (docs/theory.md §15).  With
    ``C_out`` (hinf) a last block row [C Q, 0, 0, -I] carries the output's |z|^2."""
    nv = len(V.Av)
    m, d, n_s = V.m, V.d, V.n_s
    E = V.pw0.E
    MQ = V.Av @ Q + V.Bv @ Y  # (nv, n_s, n_s)
    FQ = np.concatenate([(V.Fa[j] @ Q + (Y if j == 0 else 0.0))[None].repeat(nv, 0) * V.rho[:, j, None, None]
                         for j in range(d)], axis=1)  # (nv, d m, n_s)
    p = 0 if C_out is None else C_out.shape[0]
    k = 2 * n_s + d * m + p
    X = np.zeros((nv, k, k))
    a, c = n_s, 2 * n_s
    X[:, :a, :a] = -alpha * Q
    X[:, a:c, :a] = MQ
    X[:, :a, a:c] = MQ.transpose(0, 2, 1)
    X[:, c : c + d * m, :a] = FQ
    X[:, :a, c : c + d * m] = FQ.transpose(0, 2, 1)
    inv_c = 0.0 if not c_dist else 1.0 / c_dist
    X[:, a:c, a:c] = -Q + (np.sum(eps_v, axis=1) + inv_c)[:, None, None] * (E @ E.T)
    e = c + d * m
    X[:, c:e, c:e] = _eps_diag(eps_v, m)
    if p:
        X[:, e:, :a] = C_out @ Q
        X[:, :a, e:] = (C_out @ Q).T
        X[:, e:, e:] = -np.eye(p)
    return X


def _vertices_of(plant: dict, Ts: float, tau_min: float, tau_hi: float, d: int, pieces: int
                 ) -> tuple[_Vertices, np.ndarray]:
    """The vertices (an over-approximation that overflows is bad input, exit 2) and the outputs' rows
    on the lifted state."""
    from ..errors import InputError

    try:
        V = _Vertices(plant, Ts, tau_min, tau_hi, d, pieces)
    except ValueError as exc:
        raise InputError(f"plant: {exc} (delays up to {tau_hi:g} s)") from None
    from ..core.delays import lifted_rows

    return V, lifted_rows(plant["C"], V.n_s)


def _eps_diag(eps_v: np.ndarray, m: int) -> np.ndarray:
    """-diag(eps_j I_m) per vertex, (nv, d m, d m)."""
    nv, d = eps_v.shape
    out = np.zeros((nv, d * m, d * m))
    for j in range(d):
        out[:, j * m : (j + 1) * m, j * m : (j + 1) * m] = -eps_v[:, j, None, None] * np.eye(m)
    return out


def _coefficients(V: _Vertices, dist: bool, C_out: np.ndarray | None = None):
    """The blocks of :func:`_dual_blocks` as ``X_v = C0_v + Cc / c + sum_i q_i (CQ_vi + alpha SQ_i) +
    sum_l y_l CY_vl + sum_j eps_j CE_vj`` (q: Q's upper triangle, y: Y's entries), in numpy."""
    n_s, m, d = V.n_s, V.m, V.d
    zQ, zY = np.zeros((n_s, n_s)), np.zeros((m, n_s))
    ze = np.zeros((len(V.Av), d))
    C0 = _dual_blocks(V, zQ, zY, ze, 0.0, None, C_out)
    Cc = _dual_blocks(V, zQ, zY, ze, 0.0, 1.0, C_out)[0] - C0[0] if dist else np.zeros(C0.shape[1:])  # per unit of 1/c
    basis = _sym_basis(n_s)
    CQ = np.stack([_dual_blocks(V, S, zY, ze, 0.0, None, C_out) - C0 for S in basis], axis=1)
    k = C0.shape[-1]
    SQ = np.zeros((len(basis), k, k))
    SQ[:, :n_s, :n_s] = -basis  # the -alpha Q corner
    CY = []
    for a in range(m):
        for b in range(n_s):
            U = zY.copy()
            U[a, b] = 1.0
            CY.append(_dual_blocks(V, zQ, U, ze, 0.0, None, C_out) - C0)
    CE = []
    for j in range(d):
        e = ze.copy()
        e[:, j] = 1.0
        CE.append(_dual_blocks(V, zQ, zY, e, 0.0, None, C_out) - C0)
    return C0, Cc, basis, CQ, SQ, np.stack(CY, axis=1), np.stack(CE, axis=1)


def _vertex_lmis(V: _Vertices, dist: bool, c_coef, alpha_coef, C_out: np.ndarray | None = None):
    """The cvxpy unknowns (q, y, eps), Q and Y, the symmetric basis and one LMI per vertex of
    :func:`_dual_blocks`; ``c_coef`` multiplies the disturbance's 1/c term and ``alpha_coef`` the -Q
    corner (parameters, a variable, or constants)."""
    import cvxpy as cp

    C0, Cc, basis, CQ, SQ, CY, CE = _coefficients(V, dist, C_out)
    nv, k = C0.shape[0], C0.shape[-1]
    n_q, n_s, m = len(basis), V.n_s, V.m
    q = cp.Variable(n_q)
    y = cp.Variable(m * n_s)
    eps = cp.Variable((len(V.combos), V.d), nonneg=True)
    SQf = SQ.reshape(n_q, k * k).T
    cons = []
    for v in range(nv):
        lin = (C0[v].reshape(-1) + c_coef * Cc.reshape(-1) + CQ[v].reshape(n_q, -1).T @ q + alpha_coef * (SQf @ q)
               + CY[v].reshape(m * n_s, -1).T @ y + CE[v].reshape(V.d, -1).T @ eps[V.owner[v]])
        X = cp.reshape(lin, (k, k), order="C")
        cons.append((X + X.T) / 2 << -STRICT * np.eye(k))
    Q = cp.reshape(basis.reshape(n_q, -1).T @ q, (n_s, n_s), order="C")
    Y = cp.reshape(y, (m, n_s), order="C")
    return q, y, eps, Q, Y, basis, cons


def _prove(plant: dict, V: _Vertices, Ts: float, tau_min: float, tau_hi: float, pieces: int, Q: np.ndarray,
           Y: np.ndarray, eps: np.ndarray, alpha: float, c_dist: float | None, C_out: np.ndarray | None = None
           ) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray]:
    """The gain K = Y Q^-1 and its certificate P = Q^-1, eta = 1/eps, re-checked in the primal form on
    the over-approximation built for K itself (:func:`robustsynth.certificate.lti.check_lti_certificate`)."""
    from ..certificate.lti import check_lti_scaled
    from ..core.delays import over_approximation

    Q = (Q + Q.T) / 2.0
    K = np.linalg.solve(Q, Y.T).T
    P = np.linalg.inv(Q)
    P = (P + P.T) / 2.0
    with np.errstate(divide="ignore"):
        eta = np.where(eps > 0, 1.0 / np.maximum(eps, 0.0), np.inf)
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(eta))):
        return {"ok": False, "failing": -1, "vertices": 0, "min_eig": float("nan")}, K, P, eta
    pw = over_approximation(plant["A"], plant["B"], K, Ts, tau_min, tau_hi, V.d, pieces)
    return check_lti_scaled(pw, P, eta, float(np.sqrt(alpha)), V.verts, c_dist, C_out), K, P, eta


def synthesize_lti(plant: dict, Ts: float, tau_min: float, tau_max: float, m_lost: int, objective: str,
                   decay: float = 0.98, pieces: int = 2, alpha_points: int = 6, solver: str = "clarabel",
                   say=lambda s: None, threads: int | None = None, name: str | None = None) -> SynthesisResult:
    """A gain u_k = K xi_k on the lifted state with a common quadratic certificate for every delay in
    [tau_min, tau_max] and up to m_lost losses in a row (docs/theory.md §15):

    - ``stability``: V+ <= decay^2 V; with input limits, the largest ball of states at rest (past
      commands zero) inside {V <= 1} where |u_i| <= u_max,i;
    - ``ultimate-bound``: V+ <= alpha V + (1 - alpha) for every disturbance with ||w(t)|| <= w_max: the
      set {V <= 1} is invariant and attracts every trajectory; minimizes the largest output bound /
      scale over it (alpha searched), with |u_i| <= u_max,i on it.

    The lifted system is linear: the LMIs are posed for xi beta / delta, delta the disturbance's bound
    per period and beta = 1 - sqrt(alpha) (which keeps Q of order one), and every figure is scaled back.

    The line search solves ``threads`` alphas at once (None: :func:`auto_threads`); it visits the same
    alphas whatever that number, so the gain does not depend on the machine.

    Parameters
    ----------
    plant : dict
        The plant's arrays (:func:`~robustsynth.model.lti.lti_plant`).
    Ts, tau_min, tau_max : float
        Sampling period and delay bounds [s].
    m_lost : int
        Commands lost in a row at most.
    objective : str
        ``stability``, ``ultimate-bound``, ``hinf`` or ``auto``.
    decay : float
        ``stability``: the decay per period.
    pieces : int
        Pieces per switching instant's range in the over-approximation.
    alpha_points : int
        ``ultimate-bound``: the line search's grid.
    solver : str
        ``clarabel`` or ``scs``.
    say : callable
        Receives progress lines.
    threads : int or None
        Solves run at once (above).
    name : str or None
        The plant's name, for the messages of a failure.

    Returns
    -------
    SynthesisResult
        The gain (``plant_kind`` "lti"), its certificate (P, alpha, the multipliers, the vertices, the pieces and
        the numpy proof's record) and the figures proven in numpy (``certified``).

    Raises
    ------
    InfeasibleError
        The LMIs have no solution (the message says what may bind).
    SolverFailure
        The solver failed, or no point it returned was proven in numpy.
    """
    from ..errors import InputError
    from ..core.delays import lti_depth

    from ..objectives import objective as descriptor
    from .objectives import design_of

    objective = _resolved_objective(plant, objective)
    d = lti_depth(tau_max, m_lost, Ts)
    tau_hi = tau_max + m_lost * Ts
    if descriptor(objective).needs_disturbance and plant.get("E") is None:
        raise InputError(f"synthesis.objective: {objective} needs plant.disturbance (E and its bound)")
    t0 = time.perf_counter()
    V, C = _vertices_of(plant, Ts, tau_min, tau_hi, d, pieces)
    job = LinearJob(plant, V, C, Ts, tau_min, tau_hi, pieces, objective, decay, alpha_points, threads, solver, say, t0)
    return _proven(design_of(objective, "lti")(job), name, pieces, solver)


@dataclass(frozen=True)
class LinearJob:
    """What an objective's design for a linear plant starts from (``linear(job)`` of a module of
    :mod:`robustsynth.synthesis.objectives`): the plant's arrays, its lifted vertices and outputs, the network's
    bounds, the lifting's depth, the settings, and when the synthesis started (``t0``, for its duration)."""

    plant: dict
    V: "_Vertices"
    C: np.ndarray
    Ts: float
    tau_min: float
    tau_hi: float
    pieces: int
    objective: str
    decay: float
    alpha_points: int
    threads: int | None
    solver: str
    say: Any
    t0: float

    @property
    def d(self) -> int:
        """The lifting's depth (the vertices')."""
        return self.V.d

    @property
    def nv(self) -> int:
        """The over-approximation's vertices."""
        return len(self.V.Av)

    def per_period_gain(self) -> float:
        """g = int_0^Ts ||e^{A r} E|| dr: a disturbance of sup-norm 1 over a period moves the state by at most g."""
        from ..core.delays import disturbance_bound

        return disturbance_bound(self.plant["A"], self.plant["E"], 1.0, self.Ts)


def line_search_design(job: LinearJob, dist: bool) -> _Candidate:
    """The line search over alpha (:class:`_LineSearch`) for ``job``: with the disturbance (``dist``: the
    invariant set, ultimate-bound) or without it (the decay, stability); the design at the best proven alpha."""
    search = _LineSearch(job.plant, job.V, job.C, job.Ts, job.tau_min, job.tau_hi, job.pieces, dist, job.decay,
                         job.alpha_points, job.threads, job.solver, job.say)
    best = search.run()
    solves = search.held.get("solves", 0)
    dt = time.perf_counter() - job.t0
    if best is None:
        design = _uncertified(job.plant, job.objective, search, job.decay, job.d, job.nv, solves, dt)
    else:
        design = _certified_design(job.plant, job.objective, search, best, job.d, job.nv, solves, dt)
    tried = tuple({"alpha": a, "status": kind} for a, kind in search.held["ended"].items())
    return replace(design, search=tried)


def _proven(design: _Candidate, name: str | None, pieces: int, solver: str) -> SynthesisResult:
    """The design as the result every plant's synthesis returns if its certificate was proven; else the failure
    raised as the robot's synthesis raises it: InfeasibleError (exit 3) where the LMIs have no solution,
    SolverFailure (exit 4) where the solver failed or its point was not proven in numpy."""
    from ..certificate.lti import lti_check
    from ..errors import InfeasibleError, SolverFailure

    if not design.certified:
        why = design.message or design.status
        what = "no certified gain" + (f" for {name}" if name else "")
        if design.status == "infeasible":
            raise InfeasibleError(f"{what}: {why}")
        raise SolverFailure(f"{what} ({design.status}): {why}")
    certificate = {"P": design.P, "alpha": design.alpha, "multipliers": design.eps, "vertices": design.vertices,
                   "pieces": pieces, "check": design.check}
    return SynthesisResult(K=design.K, objective=design.objective, multiplier="per-channel", certificate=certificate,
                           check=lti_check(design.check, design.figures),
                           solver={"name": solver, "solves": design.solves, "time_s": design.solve_time_s},
                           search=design.search, timings={"total_s": design.solve_time_s}, plant_kind="lti")


_DEPRECATED = {"LtiDesign": SynthesisResult, "LtiAnalysis": AnalysisResult}  # one release: every plant's types


def __getattr__(name: str) -> Any:
    if name in _DEPRECATED:
        import warnings
        warnings.warn(f"robustsynth.synthesis.lti.{name} is deprecated: it is {_DEPRECATED[name].__name__}, every "
                      "plant's type (the figures are .certified, the multipliers .certificate['multipliers'])",
                      DeprecationWarning, stacklevel=2)
        return _DEPRECATED[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _resolved_objective(plant: dict, objective: str) -> str:
    """The objective ``auto`` stands for (as the config's auto: ultimate-bound with a disturbance, else
    stability); InputError for one that is none of them."""
    from ..errors import InputError

    if objective == "auto":
        objective = "ultimate-bound" if plant.get("E") is not None else "stability"
    from ..objectives import names

    if objective not in names("lti"):
        raise InputError(f"synthesis.objective: {objective!r} is not one of auto, {', '.join(names('lti'))}")
    return objective


class _LineSearch:
    """The line search over alpha (ultimate-bound: a grid of 1 - alpha from ALPHA_FAR, then REFINE_ROUNDS
    rounds around the best; stability: the one alpha decay^2), ``n_threads`` solves at once, each on a
    :class:`_LinePoint` of its own (cvxpy's parameters are per problem).  ``held``: "ended" (each alpha tried, in
    order, and how its last solve ended: ok, infeasible or failed), "solves", "last" (the last solve's proof, if its
    point reached one) and "ok"[alpha] = (the bound
    in the plant's units, min over scale, or the rest ball; then the proof's check, K, P, eta, Q) for every
    proven alpha."""

    def __init__(self, plant: dict, V: _Vertices, C: np.ndarray, Ts: float, tau_min: float, tau_hi: float, pieces: int,
                 dist: bool, decay: float, alpha_points: int, threads: int | None, solver: str, say) -> None:
        from ..core.delays import disturbance_bound

        self.plant, self.V, self.C, self.Ts, self.tau_min, self.tau_hi, self.pieces = plant, V, C, Ts, tau_min, tau_hi, pieces
        self.dist, self.solver, self.say = dist, solver, say
        self.n = plant["B"].shape[0]
        # xi beta / delta in the LMIs: delta the disturbance's bound per period
        self.delta = disturbance_bound(plant["A"], plant["E"], plant["w_max"], Ts) if dist else 1.0
        self.u_max = plant.get("u_max")
        self.scale = np.asarray(plant["scale"], dtype=float)
        self.grid = 1.0 - np.geomspace(ALPHA_FAR, 0.002, alpha_points) if dist else np.array([decay**2])
        self.n_threads = max(1, int(threads)) if threads is not None else auto_threads()
        self.points: list[_LinePoint] = []
        self.held: dict = {"ended": {}}

    def beta(self, a: float) -> float:
        """1 - sqrt(alpha), which keeps Q of order one (1 without the disturbance)."""
        return 1.0 - float(np.sqrt(a)) if self.dist else 1.0

    def run(self) -> float | None:
        """The grid, then (ultimate-bound) the refinement around the best alpha, two solves a round on
        either side of it: the best proven alpha, or None (after :meth:`fallback` at the alphas that failed)."""
        self.attempts([float(a) for a in self.grid])
        best = _best(self.held, self.dist)
        if best is None:
            self.fallback()
            best = _best(self.held, self.dist)
        if self.dist and best is not None:
            for _ in range(REFINE_ROUNDS):
                self.attempts(_midpoints(list(self.held["ended"]), best))
                best = _best(self.held, self.dist)
        return best

    def _arm(self, pt: _LinePoint, a: float):
        """``pt`` set to alpha ``a``; its acceptor, which proves the solver's values in numpy (:func:`_prove`)."""
        b = self.beta(a)
        c_dist = (1.0 - a) / b**2 if self.dist else None
        # the limits with a relative back-off, so that the numpy proof on P = Q^-1 has room for rounding
        u2 = (((1.0 - INPUT_BACKOFF) * np.asarray(self.u_max, dtype=float) * b / self.delta) ** 2
              if self.u_max is not None else None)
        pt.set(a, 1.0 / c_dist if self.dist else 0.0, u2)
        return pt.acceptor(lambda Qv, Yv, ev, a=a, c=c_dist: _prove(
            self.plant, self.V, self.Ts, self.tau_min, self.tau_hi, self.pieces, Qv, Yv, ev, a, c))

    def attempts(self, alphas: list[float]) -> None:
        """Solve at each alpha, ``n_threads`` at once; what they gave (each point proven in numpy) into ``held``."""
        from .solve import solve_all

        points = self.points
        for i0 in range(0, len(alphas), self.n_threads):
            chunk = alphas[i0 : i0 + self.n_threads]
            while len(points) < len(chunk):
                points.append(_LinePoint(self.V, self.C, self.dist, self.scale, self.n, self.u_max is not None))
            accepts = [self._arm(pt, a) for pt, a in zip(points, chunk)]
            for pt, a, out in zip(points, chunk, solve_all([p.prob for p in points[: len(chunk)]], self.solver, accepts)):
                self._record(pt, a, out)

    def fallback(self) -> None:
        """No alpha proven: each one whose solve failed is solved again as the robot's are (the primary unscaled,
        then the other solver), so that "infeasible" is said only on a solver's word.  A search that proves a
        gain runs no more solves than it did."""
        from .solve import solve

        for a in [a for a, kind in self.held["ended"].items() if kind == "failed"]:
            pt = self.points[0]  # a failed alpha was solved on a point: there is one
            self.say(f"alpha {a:.4f}: the fallback solver")
            self._record(pt, a, solve(pt.prob, self.solver, self._arm(pt, a), fallback=True, skip_first=True))

    def _record(self, pt: _LinePoint, a: float, out: Any) -> None:
        """What the solve at alpha ``a`` gave, into ``held`` (a second solve at an alpha replaces how it ended)."""
        held, dist = self.held, self.dist
        held["solves"] = held.get("solves", 0) + 1
        held["ended"][float(a)] = out.kind
        # the last solve's proof, if its point reached one (not a point a solver rejected before one said infeasible)
        held["last"] = (pt.proof or None) if out.kind != "infeasible" else None
        if out.kind != "ok":
            why = "; the numpy proof rejected its point" if pt.proof and not pt.proof[0]["ok"] else ""
            self.say(f"alpha {a:.4f}: {out.kind}" + (f" ({out.record.status}{why})" if out.kind == "failed" else ""))
            return
        val = float(np.sqrt(max(float(pt.t.value), 0.0))) * (self.delta / self.beta(a) if dist else 1.0)
        self.say(f"alpha {a:.4f}: {'largest bound / scale' if dist else 'ball at rest'} {val:.6g} (proven)")
        held.setdefault("ok", {})[a] = (val,) + pt.proof


def _uncertified(plant: dict, objective: str, search: _LineSearch, decay: float, d: int, nv: int, solves: int,
                 dt: float) -> _Candidate:
    """The design when no alpha gave a proven certificate: rejected where the last solve's proof failed, failed where
    a solve failed, else infeasible; with what may bind (uncontrollable modes, input limits, the decay, the delays)."""
    from collections import Counter

    dist, held = search.dist, search.held
    last = held.get("last")
    kinds = Counter(held["ended"].values())  # a solve that failed, also with the fallback, proves nothing (exit 4)
    status = ("rejected" if last is not None and not last[0]["ok"] else "failed" if kinds.get("failed") else
              "infeasible")
    why = "no alpha of the line search gave a proven certificate" if dist else f"no certificate with decay {decay:g} per period"
    if kinds.get("failed"):
        why += (f" (at {kinds['failed']} of {len(held['ended'])} alphas the solves failed, also with the fallback solver: "
                "an error, an inaccurate status or a point the numpy proof rejected, which shows neither a gain nor "
                "that none exists" + (f"; {kinds['infeasible']} infeasible" if kinds.get("infeasible") else "") + ")")
    hints = []
    if not plant.get("controllable", True):
        hints.append("the plant is not controllable (rank [B, AB, ...] < n): its uncontrollable modes must decay "
                     "by themselves" + ("" if dist else f", at least by {decay:g} per period"))
    if dist and search.u_max is not None:  # (stability is homogeneous: its limits shrink the rest ball, never bind)
        hints.append("the input limits may be what binds: try larger plant.input_limits or a smaller disturbance bound")
    if not dist:
        hints.append("try a decay closer to 1 (synthesis.decay asks sqrt(V) to shrink by it per period) or a "
                     "shorter delay range")
    return _Candidate(False, status, objective, None, None, None, None, {}, last[0] if last else {}, d, nv,
                     solves, dt, why + ("; " + "; ".join(hints) if hints else ""))


def _certified_design(plant: dict, objective: str, search: _LineSearch, a: float, d: int, nv: int, solves: int,
                      dt: float) -> _Candidate:
    """The design at the best alpha ``a``, its figures proven in numpy in the plant's units (xi = unit * the
    LMIs' xi, unit = delta / beta): the output bounds on the set (ultimate-bound) or the ball at rest inside
    it (stability with input limits), the input limits on it; rejected where a proof fails or the set's
    matrix is not finite in the plant's units."""
    from ..certificate.lti import lti_within
    from ..verified import assembly_radius, proves_at_least, round_up

    n, m = plant["B"].shape
    dist, u_max, delta, C = search.dist, search.u_max, search.delta, search.C
    val, chk, K, P, eta, Qv = search.held["ok"][a]
    unit = delta / search.beta(a)  # xi = unit * (the LMIs' xi)
    figures: dict = {"alpha": a, "decay": round_up(float(np.sqrt(a)), 2)}

    def refuse(why: str) -> _Candidate:
        return _Candidate(False, "rejected", objective, K, None, None, a, {}, chk, d, nv, solves, dt, why)

    if dist:
        figures["disturbance_step_bound"] = delta
        z = np.sqrt(np.maximum(np.einsum("ia,ab,ib->i", C, Qv, C), 0.0)) * (1.0 + 1e-7)
        if not lti_within(P, C, z).all():
            return refuse("the output bounds were not proven on the set")
        figures["outputs"] = [{"name": nm, "unit": un, "bound": round_up(float(zi * unit), 2)}
                              for nm, un, zi in zip(plant["outputs"], plant["output_units"], z)]
    elif u_max is not None:
        Pxx = P[:n, :n]
        r = 1.0 / np.sqrt(float(np.max(np.linalg.eigvalsh(Pxx)))) * (1.0 - 1e-7)
        R = np.eye(n) / (r * r)
        if not proves_at_least(R - Pxx, 0.0, assembly_radius(np.abs(R) + np.abs(Pxx), 2)):
            return refuse("the ball at rest was not proven inside the set")
        figures["rest_radius"] = r
    if u_max is not None:
        if not lti_within(P, K, np.asarray(u_max, dtype=float) / unit).all():
            return refuse("the input limits were not proven on the set")
        figures["inputs"] = [{"name": f"u{i + 1}", "limit": float(u_max[i])} for i in range(m)]
    # (P, eps) in the plant's units: V = xi' P xi, the multipliers scale like P
    if not (np.all(np.isfinite(P / (unit * unit))) and np.all(np.isfinite(eta / (unit * unit))) and unit > 0):
        return refuse(f"the set's matrix is not finite in the plant's units (disturbance step bound {delta:.3g}): "
                      "rescale the units")
    return _Candidate(True, "certified", objective, K, P / (unit * unit), eta / (unit * unit), a, figures, chk, d, nv,
                     solves, dt)


class _LinePoint:
    """One copy of the line search's problem (the invariance LMIs at a parametric alpha, with the
    output bounds or the rest ball and the input limits): solves that run at once each need their own."""

    def __init__(self, V: _Vertices, C: np.ndarray, dist: bool, scale: np.ndarray, n: int, limits: bool) -> None:
        import cvxpy as cp

        m, n_s = V.m, V.n_s
        self.m, self.n_s = m, n_s
        self.t = cp.Variable()
        self.al = cp.Parameter(nonneg=True)
        self.icd = cp.Parameter(nonneg=True)  # 1/c of the disturbance: beta^2 / (1 - alpha)
        self.u2 = cp.Parameter(m, nonneg=True)  # the input limits squared, in the LMIs' units
        self.q, self.y, self.eps, Q, Y, self.basis, cons = _vertex_lmis(V, dist, self.icd, self.al)
        if limits:
            for i in range(m):
                cons.append(cp.bmat([[cp.reshape(self.u2[i], (1, 1), order="C"), Y[i : i + 1, :]],
                                     [Y[i : i + 1, :].T, Q]]) >> 0)
        if dist:
            cons += [C[i] @ Q @ C[i] <= self.t * scale[i] ** 2 for i in range(C.shape[0])]
            self.prob = cp.Problem(cp.Minimize(self.t), cons)
        else:
            W = np.zeros((n_s, n_s))
            W[:n, :n] = np.eye(n)
            cons += [Q << np.eye(n_s), Q >> self.t * W, self.t >= 0]
            self.prob = cp.Problem(cp.Maximize(self.t), cons)
        self.proof: tuple = ()

    def set(self, alpha: float, inv_c: float, u2: np.ndarray | None) -> None:
        self.al.value = float(alpha)
        self.icd.value = float(inv_c)
        self.u2.value = u2 if u2 is not None else np.ones(self.m)
        self.proof = ()

    def acceptor(self, prove):
        """The ``accept`` of :func:`robustsynth.synthesis.solve.solve`: ``prove(Q, Y, eps)`` -> (check,
        K, P, eta) on the solver's values; the proof is kept (``self.proof``)."""

        def accept() -> bool:
            if self.q.value is None or self.y.value is None or self.eps.value is None:
                return False
            Qv = np.einsum("i,iab->ab", np.asarray(self.q.value, dtype=float), self.basis)
            chk, K, P, eta = prove(Qv, np.asarray(self.y.value).reshape(self.m, self.n_s),
                                   np.maximum(np.asarray(self.eps.value), 0.0))
            self.proof = (chk, K, P, eta, Qv)
            return bool(chk["ok"])

        return accept


def _midpoints(tried: list[float], best: float) -> list[float]:
    """The points halfway (in log(1 - alpha)) between ``best`` and its nearest tried neighbour on
    either side (one side only at the grid's ends)."""
    x = sorted(set(np.log(1.0 - np.asarray(tried))))
    xb = float(np.log(1.0 - best))
    lower = [v for v in x if v < xb]
    upper = [v for v in x if v > xb]
    out = []
    if lower:
        out.append(1.0 - float(np.exp((lower[-1] + xb) / 2.0)))
    if upper:
        out.append(1.0 - float(np.exp((upper[0] + xb) / 2.0)))
    return out


def _best(held: dict, dist: bool) -> float | None:
    ok = held.get("ok", {})
    if not ok:
        return None
    return (min if dist else max)(ok, key=lambda a: ok[a][0])
