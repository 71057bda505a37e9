"""cvxpy builders of the synthesis LMIs over the model's vertices (docs/theory.md §6), one compiled
problem per objective.

Every LMI is written in the form ``L >= margin * I`` (explicit identity) and is affine in the
vertex data (A_i, B_i, E_i, C_q_i, D_q_i), so holding at every vertex it holds on their hull.
With a **common** Lyapunov matrix ``Q = P^-1`` and ``Y = K Q``, vertex i reads

    [[(1-alpha) Q, 0,      (A_i Q + B_i Y)',  (C_qi Q + D_qi Y)'],
     [0,           diag b, E_i',              0                ],
     [A_i Q + B_i Y, E_i,  Q - B_p M_i B_p',  0                ],
     [C_qi Q + D_qi Y, 0,  0,                 M_i              ]]  >=  margin I,

(M_i = Lambda_i^-1 the S-procedure multiplier of vertex i, with Delta's block structure).  With
**slip-dependent** matrices S_m (one per slip corner) and a slack G (``Y = K G``,
de Oliveira-Bernussou-Geromel 1999; Daafouz-Bernussou 2001) the (1,1) block becomes
``(1-alpha)(G + G' - S_m)`` for the vertex's corner m, ``Q`` in the products becomes ``G`` and the
(3,3) block ``S_next - B_p M B_p'`` for every slip that may follow: every corner n when slip may
jump, or, under ``slip.max_rate``, the bilinear interpolation of the S_n at ``corner_m +- max_rate Ts``
(the LMI is multi-affine in (mu_k, mu_{k+1} - mu_k), so these vertices cover every admissible pair).
**Delay-dependent**: one S per slip corner and delay vertex, with the next period's at every next
delay vertex as well; **path-dependent**: one per slip corner, previous and current delay vertex
(``Model.lyapunov_conditions``).  ``Parameter`` s (``alpha``, ``r2``) change
between solves, so line search and bisection reuse one compiled problem (DPP).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import cvxpy as cp
import numpy as np

__all__ = ["LMIProblem", "build_stability", "build_invariance", "multiplier", "motor_constraints",
           "heading_constraints", "heading_row_key", "heading_rows", "heading_row_table", "rows_broken"]


@dataclass
class LMIProblem:
    problem: cp.Problem
    Y: cp.Variable
    lyapunov: str  # 'common' or 'slip-dependent'
    Q: cp.Variable | None = None
    G: cp.Variable | None = None
    S: list[cp.Variable] = field(default_factory=list)
    M: list[Any] = field(default_factory=list)  # per vertex (cvxpy expressions)
    params: dict[str, cp.Parameter] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)  # its extra variables (and a phase-1 problem's posed rows)
    mirrored: bool = False  # posed mirror-invariant (docs/theory.md §6h)
    images: tuple[int, ...] = ()  # posed mirror-invariant: each vertex's mirror image (its LMIs stand for both)
    # per vertex of the model its invariance LMIs (none for a vertex its mirror image's stand for): their duals say
    # which vertices bind (:mod:`.phase1`)
    vertex_lmis: list[list[Any]] = field(default_factory=list)

    def values(self) -> dict[str, Any]:
        """Symmetrized values of the certificate's variables (numpy)."""
        sym = lambda X: (np.asarray(X) + np.asarray(X).T) / 2.0  # noqa: E731
        out: dict[str, Any] = {"Y": np.asarray(self.Y.value), "lyapunov": self.lyapunov}
        if self.lyapunov == "common":
            out["Q"] = sym(self.Q.value)
        else:
            out["G"] = np.asarray(self.G.value)
            out["S"] = [sym(S.value) for S in self.S]
        Ms = []
        for M in self.M:
            v = M.value if hasattr(M, "value") else M
            v = np.zeros((0, 0)) if v is None else np.asarray(v, dtype=float).reshape(M.shape)
            Ms.append(sym(v))
        out["M"] = Ms
        for k, v in self.extra.items():  # the extra variables (not the posed rows' keys and constraints)
            if isinstance(v, cp.Variable):
                out[k] = np.asarray(v.value)
        return out


ANALYSIS_KAPPA = 1e4  # analysis of a given gain: Lyapunov matrices with I <= X <= kappa I, first;
ANALYSIS_KAPPA_WIDE = 1e7  # then, where none is found, this wider box (a synthesized gain's Q may need 5e4)


def multiplier(n_blocks: int, kind: str, tag: str = "") -> tuple[Any, list[cp.Variable]]:
    """M = Lambda^-1 with the structure of Delta = blockdiag(d1 I2, d2, ...).

    ``structured``: a 2x2 symmetric block per repeated scalar d1 I2 (a D-scaling) and a scalar
    for d2; ``full``: mu I (the paper's single scalar for |Delta| <= 1)."""
    n = 3 * n_blocks
    if n == 0:
        return cp.Constant(np.zeros((0, 0))), []
    if kind == "full":
        mu = cp.Variable(name=f"mu{tag}")
        return mu * np.eye(n), [mu]
    terms, variables = [], []
    for b in range(n_blocks):
        S = cp.Variable((2, 2), symmetric=True, name=f"S{tag}_{b}")
        m = cp.Variable(name=f"m{tag}_{b}")
        E = np.zeros((n, 2))
        E[3 * b : 3 * b + 2] = np.eye(2)
        f = np.zeros((n, 1))
        f[3 * b + 2] = 1.0
        terms += [E @ S @ E.T, m * (f @ f.T)]
        variables += [S, m]
    return sum(terms[1:], terms[0]), variables


def _selector(n: int, idx: np.ndarray) -> np.ndarray:
    """The n x len(idx) matrix whose columns are the unit vectors of ``idx``."""
    P = np.zeros((n, idx.size))
    P[idx, np.arange(idx.size)] = 1.0
    return P


def _sym(L: Any) -> Any:
    return (L + L.T) / 2.0


class _Lyap:
    """The Lyapunov variables: X (what multiplies A and C_q), and per vertex the (left, right) blocks
    of its conditions (``Model.lyapunov_conditions``).

    With ``mirror`` (the model's left/right symmetry, ``Model.mirror``) the certificate is taken
    mirror-invariant, at no loss (docs/theory.md §6h): G, Q, Y and the Lyapunov matrices of symmetric
    slip corners have no entries between even and odd states, a mirrored corner's matrix is
    ``T S T`` of its partner's, and of each mirrored pair of conditions only one is posed."""

    def __init__(self, model: Any, kind: str, K: np.ndarray | None = None, mirror: Any = None):
        n_s = model.n_s
        self.kind = kind
        self._conds = model.lyapunov_conditions(kind, model.slip_step)
        if mirror is not None and K is not None:
            Kf = np.asarray(K, dtype=float)
            tol = 1e-12 * max(1.0, float(np.abs(Kf).max()))
            if not np.allclose(mirror.tu[:, None] * Kf * mirror.t, Kf, rtol=0.0, atol=tol):
                mirror = None  # a gain that is not mirror-symmetric: its certificate need not be
        self.mirror = mirror
        if kind == "common":
            self.Q = self._var(n_s, "Q", symmetric=True, structured=mirror is not None)
            self.X = self.Q
            self.G = None
            self.S: list[Any] = []
            self.own = [0]
        else:
            self.Q = None
            self.G = self._var(n_s, "G", symmetric=False, structured=mirror is not None)
            self.X = self.G
            count = model.lyapunov_count(kind)
            sig = mirror.lyapunov if mirror is not None else tuple(range(count))
            self.own = [j for j in range(count) if j <= sig[j]]  # the matrices that are variables
            S: dict[int, Any] = {}
            for j in self.own:
                S[j] = self._var(n_s, f"S{j}", symmetric=True, structured=mirror is not None and sig[j] == j)
            for j in range(count):
                if j not in S:  # a mirrored corner's matrix: T S T of its partner's
                    S[j] = cp.multiply(np.outer(mirror.t, mirror.t), S[sig[j]])
            self.S = [S[j] for j in range(count)]
        # synthesis: Y = K X is the variable; analysis of a given K: Y = K X is affine in X
        if K is not None:
            self.Y = np.asarray(K, dtype=float) @ self.X
        elif mirror is None:
            self.Y = cp.Variable((model.n_u, n_s), name="Y")
        else:  # row r of Y only on the states of the command's parity (T_u Y T = Y)
            rows = []
            for r, sign in enumerate(mirror.tu):
                cols = np.flatnonzero(mirror.t == sign)
                Er = np.zeros((model.n_u, 1))
                Er[r, 0] = 1.0
                rows.append(Er @ cp.Variable((1, cols.size), name=f"Y{r}") @ _selector(n_s, cols).T)
            self.Y = sum(rows[1:], rows[0])
        self._keep = self._kept_conditions(model)

    def _var(self, n: int, name: str, symmetric: bool, structured: bool) -> Any:
        if not structured:
            return cp.Variable((n, n), symmetric=symmetric, name=name)
        parts = []
        for sign, tag in ((1.0, "even"), (-1.0, "odd")):
            idx = np.flatnonzero(self.mirror.t == sign)
            if idx.size:
                P = _selector(n, idx)
                parts.append(P @ cp.Variable((idx.size, idx.size), symmetric=symmetric, name=f"{name}_{tag}") @ P.T)
        return sum(parts[1:], parts[0])

    def _kept_conditions(self, model: Any) -> list[list[bool]]:
        """Per vertex, which conditions are posed: all without a mirror; with one, of a condition and
        its mirror image (the congruence by T of each other) the one with the smaller key."""
        keep = [[True] * len(c) for c in self._conds]
        if self.mirror is None:
            return keep
        sv, sl = self.mirror.vertex, self.mirror.lyapunov

        def key(i: int, j: int, right: list, v: tuple, l: tuple) -> tuple:
            return (v[i], l[j], tuple(sorted((l[n], round(w, 12)) for w, n in right)))

        ident = tuple(range(max(len(sv), len(sl))))
        keys = {key(i, j, r, ident, ident) for i, cs in enumerate(self._conds) for j, r, _ in cs}
        for i, cs in enumerate(self._conds):
            for c, (j, right, _) in enumerate(cs):
                k, mk = key(i, j, right, ident, ident), key(i, j, right, sv, sl)
                keep[i][c] = k <= mk or mk not in keys
        return keep

    @property
    def mats(self) -> list[Any]:
        return [self.Q] if self.kind == "common" else self.S

    def left(self, j: int) -> Any:
        return self.Q if self.kind == "common" else self.G + self.G.T - self.S[j]

    def _next(self, right: list[tuple[float, int]]) -> Any:
        (w0, n0), *rest = right
        expr = self.mats[n0] if w0 == 1.0 else w0 * self.mats[n0]
        for w, n in rest:
            expr = expr + w * self.mats[n]
        return expr

    def conditions(self, i: int) -> list[tuple[Any, Any]]:
        """(left, right) blocks of vertex i's conditions: this period's Lyapunov matrix and the next's."""
        return [(self.left(j), self._next(right)) for (j, right, _), k in zip(self._conds[i], self._keep[i]) if k]

    def grouped(self, i: int) -> tuple[list[tuple[Any, Any]], list[Any]]:
        """Vertex i's conditions with one ``right`` per left matrix: a variable Z_ij below every next
        period's matrix that may follow (``right - Z_ij >= 0``, the second list).  Exact, not a
        relaxation: the next period's matrix enters its LMI only as ``+ right`` in one diagonal block,
        so the LMI holds for every right exactly when it holds for the Schur complement W_ij of the
        other blocks, and Z_ij = W_ij satisfies both (docs/theory.md §6h).  The big LMI is written once
        per left matrix instead of once per (left, next) pair; the pairs keep small n_s x n_s LMIs."""
        groups: dict[int, list[Any]] = {}
        for (j, right, _), k in zip(self._conds[i], self._keep[i]):
            if k:
                groups.setdefault(j, []).append(self._next(right))
        pairs, below = [], []
        n_s = self.X.shape[0]
        for j, rights in groups.items():
            if len(rights) == 1:
                pairs.append((self.left(j), rights[0]))
                continue
            Z = cp.Variable((n_s, n_s), symmetric=True, name=f"Z{i}_{j}")
            pairs.append((self.left(j), Z))
            below += [R - Z >> 0 for R in rights]
        return pairs, below

    def motor_rows(self, model: Any, j: int) -> list[int] | None:
        """Rows of J^-1 whose motor LMI matrix j needs: all, except for a mirror-invariant matrix, whose
        left-track LMI is the congruence of its right-track one (J^-1's rows are mirror images)."""
        J_inv = np.asarray(model.J_inv)
        if self.mirror is None or self.mirror.lyapunov[j] != j or not np.allclose(J_inv[1], J_inv[0] * self.mirror.tu):
            return None
        return [0]

    def scale(self, floor: float) -> list[Any]:
        return [self.mats[j] >> floor * np.eye(self.X.shape[0]) for j in self.own]

    def diag_bound(self, i: int) -> tuple[Any, list[Any]]:
        """An expression >= every Lyapunov matrix's (i, i) entry (epigraph for several matrices)."""
        if self.kind == "common":
            return self.Q[i, i], []
        t = cp.Variable(name=f"t{i}")
        return t, [t >= self.S[j][i, i] for j in self.own]  # a mirrored matrix has its partner's diagonal

    def problem_kwargs(self) -> dict[str, Any]:
        return {"Y": self.Y, "lyapunov": self.kind, "Q": self.Q, "G": self.G, "S": self.S,
                "mirrored": self.mirror is not None, "images": tuple(self.mirror.vertex) if self.mirror is not None else ()}


def motor_constraints(model: Any, Q: Any, Y: Any, rows: Any = None, u2: Any = None) -> list[Any]:
    """[[u^2, c_i' Y], [Y' c_i, Q]] >= 0 with u = rho_max - V^D / R (docs/theory.md §6c; minus the
    turning feedforward's share, §10), for each row c_i
    of J^-1 (or those in ``rows``); ``Q`` may be any expression standing for the Lyapunov matrix
    (G + G' - S_m).  ``u2``: a variable standing for u^2 instead (the least motor bound, §6c)."""
    if u2 is None:
        rho_max = model.config.robot.max_motor_speed
        ubar = rho_max - model.feedforward_motor_speed  # V^D / R (and a turning reference's feedforward)
        # solve against a bound a hair tighter than the limit so that the numpy check has headroom
        top = np.array([[(ubar * (1.0 - 1e-6)) ** 2]])
    else:
        top = cp.reshape(u2, (1, 1), order="C")
    cons = []
    J_inv = np.asarray(model.J_inv)
    for c in J_inv if rows is None else J_inv[list(rows)]:
        row = c @ Y  # (n_s,)
        blk = cp.bmat([[top, cp.reshape(row, (1, model.n_s), order="C")],
                       [cp.reshape(row, (model.n_s, 1), order="C"), Q]])
        cons.append(_sym(blk) >> 0)
    return cons


def heading_constraints(model: Any, lv: _Lyap, only: frozenset[bytes] | None = None,
                        extra: dict[str, Any] | None = None) -> list[Any]:
    """|e_theta(t)| <= theta_bar within every period on the set {V <= 1} (docs/theory.md §9): for each
    vertex's heading rows r xi + d du + g (``KinematicChannels``) and each Lyapunov matrix,
    ``[[(theta_bar - |g| - sum|F_h|)^2, r X + d Y], [., left]] >= 0``; the kinematic channels assume it.
    ``F_h``: a turning model's yaw-rate columns of the rows (model/arcs.heading_yaw_columns, docs/theory.md
    §10), whose box coordinates add ``sum|F_h|`` as :func:`~robustsynth.certificate.bounds.heading_within_period` does.
    Up to LIFT_ROWS distinct rows, those the others imply are left out (:func:`implied_rows_left_out`); beyond, every
    row is a linear row on a lifted matrix (:func:`_lifted_heading_rows`).  Both exact.

    ``only`` (a relaxation, not the certificate's LMIs: row generation, :func:`rows_broken`): in the lifted form, just
    the rows whose key (:func:`heading_row_key`) is in it, all of them where it names none of this model's.  ``extra``
    receives, in the lifted form, ``heading_keys`` (the rows posed, in order) and ``heading_rows`` (their linear
    constraints, one per Lyapunov matrix: their duals rank the rows, :mod:`.phase1`)."""
    table = heading_row_table(model)
    rooms = table.rooms(model)
    V = table.V
    cons = []
    if len(table) > LIFT_ROWS:  # linear rows cost less than the LPs that would leave some out
        pick = table.indices(only) if only else np.zeros(0, dtype=int)
        pick = pick if len(pick) else np.arange(len(table))
        cons = _lifted_heading_rows(model, lv, V[pick], rooms[pick])
        if extra is not None:
            extra["heading_keys"] = table.keys(pick)
            extra["heading_rows"] = cons[1::2]
        return cons
    # the rows are the model's, not the vertex subset's: phase-1 builds several copies on one model (one pruning)
    key = (V.tobytes(), rooms.tobytes(), V.shape)
    if key not in _KEPT:
        _KEPT.clear()  # the last model's only: a search builds its problems one heading bound after another
        _KEPT[key] = implied_rows_left_out(list(V), list(rooms))
    n_s = model.n_s
    for i in _KEPT[key]:
        c, d, room = V[i, :n_s], V[i, n_s:], float(rooms[i])
        row = c @ lv.X + d @ lv.Y
        for j in range(len(lv.mats)):
            blk = cp.bmat([[np.array([[room**2 * (1.0 - 1e-6)]]), cp.reshape(row, (1, model.n_s), order="C")],
                           [cp.reshape(row, (model.n_s, 1), order="C"), lv.left(j)]])
            cons.append(_sym(blk) >> 0)
    return cons


class HeadingRowTable:
    """The distinct heading rows of a model's heading channels, in the order :func:`heading_constraints` poses them
    (each at its first occurrence, channel by channel), as arrays: ``V`` (rows, n_s + n_u) the coefficients
    ``[c, d]``, ``offsets`` their constant parts' reach (``KinematicChannels.heading_offsets``), and ``raw`` (rows,
    n_s + n_u + 1) whose rows' bytes are the rows' keys (:func:`heading_row_key`).  Built with numpy, not row by row:
    the default robot at d_hi = 5 has 2.2 million rows, whose enumeration as Python tuples took 6 s."""

    def __init__(self, channels: tuple) -> None:
        raw = np.concatenate([np.column_stack([np.asarray(ch.C_h, dtype=float), np.asarray(ch.D_h, dtype=float),
                                               np.asarray(ch.heading_offsets, dtype=float)]) for ch in channels])
        self._key = np.dtype((np.void, raw.itemsize * raw.shape[1]))  # a row's bytes: its key
        distinct, first = np.unique(np.ascontiguousarray(raw).view(self._key).ravel(), return_index=True)
        keep = np.sort(first)
        self.raw = raw[keep]
        self.V, self.offsets = self.raw[:, :-1], self.raw[:, -1]
        # the keys sorted (np.unique's order) and each one's row here: indices() looks keys up in them
        self._sorted, self._row = distinct, np.searchsorted(keep, first)

    def __len__(self) -> int:
        return len(self.raw)

    def keys(self, idx: Any = None) -> list[bytes]:
        rows = self.raw if idx is None else self.raw[np.asarray(idx, dtype=int)]
        return [r.tobytes() for r in rows]

    def indices(self, keys: Any) -> np.ndarray:
        """The rows (sorted indices) whose key is one of ``keys`` (keys of other widths, or of no row here, name
        none)."""
        keys = [k for k in keys if len(k) == self._key.itemsize]
        if not keys or not len(self.raw):
            return np.zeros(0, dtype=int)
        want = np.frombuffer(b"".join(keys), dtype=self._key)
        at = np.minimum(np.searchsorted(self._sorted, want), len(self._sorted) - 1)
        return np.unique(self._row[at[self._sorted[at] == want]])

    def rooms(self, model: Any) -> np.ndarray:
        """theta_bar - offset per row.  Raises InfeasibleError where a row has no room (the slip's own turn within a
        period reaches the bound)."""
        from ..errors import InfeasibleError

        theta_bar = float(model.heading_bound)
        rooms = theta_bar - self.offsets
        bad = np.flatnonzero(rooms <= 0)
        if len(bad):
            turning = any(getattr(ch, "F_h", None) is not None for ch in model.heading_channels)
            raise InfeasibleError(
                f"synthesis.heading_bound: {theta_bar:g} rad is smaller than the turn the slip alone causes within "
                f"one period ({float(self.offsets[bad[0]]):.3g} rad" + (", the turning reference's yaw rates included"
                                                                         if turning else "")
                + "): no set can keep |e_theta(t)| below it")
        return rooms


_TABLE: dict[int, tuple[tuple, HeadingRowTable]] = {}  # the last channels' table (its tuple held: the id stays theirs)


def heading_row_table(model: Any) -> HeadingRowTable:
    """The :class:`HeadingRowTable` of ``model``'s heading channels, kept for the last channels asked (a search asks
    it of one model's heading bounds and vertex subsets, which share their channels)."""
    channels = model.heading_channels
    got = _TABLE.get(id(channels))
    if got is None or got[0] is not channels:
        _TABLE.clear()
        got = _TABLE[id(channels)] = (channels, HeadingRowTable(channels))
    return got[1]


def heading_rows(model: Any) -> tuple[list[tuple[np.ndarray, np.ndarray, float]], list[bytes]]:
    """The distinct heading rows of ``model`` (one with a heading bound), in the order :func:`heading_constraints`
    poses them: (state coefficients c, command coefficients d, room theta_bar - offset) each, and their keys
    (:func:`heading_row_key`).  Raises InfeasibleError where a row has no room (the slip's own turn within a period
    reaches the bound).  (Row by row: :func:`heading_row_table` holds them as arrays.)"""
    table = heading_row_table(model)
    rooms = table.rooms(model)
    n_s = model.n_s
    rows = [(v[:n_s].copy(), v[n_s:].copy(), float(r)) for v, r in zip(table.V, rooms)]
    return rows, table.keys()


def set_weight(Q: np.ndarray, K: np.ndarray) -> np.ndarray:
    """``W = [I; K] Q [I; K]'``: on the set {xi' Q^-1 xi <= 1} of the gain K, a row z = [c, d] (on xi and du = K xi)
    reaches ``sqrt(z W z')``."""
    IK = np.vstack([np.eye(Q.shape[0]), K])
    return IK @ Q @ IK.T


def heading_weights(lp: LMIProblem) -> list[np.ndarray] | None:
    """Per Lyapunov matrix j of a solved problem, ``W_j = R left_j^-1 R'`` at its values (``R = [X; Y]``, X = Q or G,
    left_j = Q or G + G' - S_j): heading row z = [c, d] holds on the set where ``z W_j z' <= room^2`` for every j, the
    condition its LMI ``[[room^2, z R], [R' z', left_j]] >= 0`` states.  None where the values are missing or a left_j
    is singular."""
    val = lambda x: None if x is None else np.asarray(x.value if hasattr(x, "value") else x, dtype=float)  # noqa: E731
    Y = val(lp.Y)
    try:
        if lp.lyapunov == "common":
            Q = val(lp.Q)
            if Q is None or Y is None or Q.shape == ():
                return None
            Q = (Q + Q.T) / 2.0
            return [set_weight(Q, np.linalg.solve(Q.T, Y.T).T)]  # K = Y Q^-1
        G = val(lp.G)
        if G is None or Y is None or G.shape == ():
            return None
        R = np.vstack([G, Y])
        out = []
        for S in lp.S:
            Sv = val(S)
            if Sv is None or Sv.shape == ():
                return None
            out.append(R @ np.linalg.solve(G + G.T - Sv, R.T))
        return out
    except np.linalg.LinAlgError:
        return None


ROW_CHUNK = 1 << 17  # rows per block of row_ratios: its temporaries stay near 20 MB whatever the rows (2.2 M at d_hi 5)
# a row counts as broken where it would break its posed form (room^2 (1 - 1e-6), _lifted_heading_rows) at the values
ROW_BROKEN = math.sqrt(1.0 - 1e-6)
ROW_BATCH = 500  # the broken rows added per round of row generation (the worst first)
# the heading rows beyond which the problems start on a subset and generate the rest (rows_broken); below, every row is
# posed at once.  On the default robot at d_hi = 2 (2 601 rows) a remedy's probe solved with every row in 24 s, and
# in 22 s + 71 s by generation from 500 rows; at d_hi = 3 (60 281 rows) a problem with every row takes ~20 s and
# ~400 MB to build, at d_hi = 5 (2.2 million) ~4 GB: there the rows are what a problem holds
GENERATE_ROWS = 20_000


def row_ratios(table: HeadingRowTable, rooms: np.ndarray, W: list[np.ndarray]) -> np.ndarray:
    """Per row of ``table``, ``max_j sqrt(z W_j z') / room``: at most 1 where the row holds
    (:func:`heading_weights`)."""
    out = np.zeros(len(table))
    for a in range(0, len(table), ROW_CHUNK):
        V = table.V[a:a + ROW_CHUNK]
        for Wj in W:
            r = np.sqrt(np.maximum(np.einsum("ia,ab,ib->i", V, Wj, V), 0.0)) / rooms[a:a + ROW_CHUNK]
            np.maximum(out[a:a + ROW_CHUNK], r, out=out[a:a + ROW_CHUNK])
    return out


def lifts_rows(model: Any) -> bool:
    """Whether ``model``'s heading rows are posed as linear rows on a lifted matrix (more than LIFT_ROWS): a problem
    posed on a subset of them can be checked against the rest (:func:`rows_broken`)."""
    return model.heading_bound is not None and len(heading_row_table(model)) > LIFT_ROWS


def generates_rows(model: Any) -> bool:
    """Whether problems of ``model`` start on a subset of its heading rows and generate the rest: more than
    GENERATE_ROWS rows (posed as linear rows)."""
    return model.heading_bound is not None and len(heading_row_table(model)) > max(GENERATE_ROWS, LIFT_ROWS)


def rows_broken(model: Any, lp: LMIProblem, posed: frozenset[bytes] | None) -> list[bytes] | None:
    """Row generation for a problem built with ``heading_rows=posed`` (a subset of ``model``'s rows in the lifted form):
    the keys of the rows not posed that its solution breaks, the worst first, at most ROW_BATCH (empty: the solution
    holds every row, so it is one of the problem with every row).  None where nothing can be said (every row was
    posed, the rows are not lifted, or the values are missing): the caller then treats the solution as it is."""
    if posed is None or model.heading_bound is None:
        return None
    table = heading_row_table(model)
    if len(table) <= LIFT_ROWS:
        return None
    W = heading_weights(lp)
    if W is None:
        return None
    held = table.indices(posed)
    if not len(held):
        return None  # heading_constraints posed every row (``posed`` names none of this model's)
    ratio = row_ratios(table, table.rooms(model), W)
    ratio[held] = 0.0  # posed: the solver's (their own tolerance is the certificate checker's)
    bad = np.flatnonzero(ratio > ROW_BROKEN)
    if not len(bad):
        return []
    worst = bad[np.argsort(-ratio[bad], kind="stable")[:ROW_BATCH]]
    return table.keys(worst)


def heading_row_key(c: np.ndarray, d: np.ndarray, offset: float) -> bytes:
    """A heading row's identity across models of one robot (its coefficients and its offset, not its room): the key
    :func:`heading_constraints` takes in ``only`` and returns in ``heading_keys``."""
    return np.concatenate([c, d, [offset]]).tobytes()


def _lifted_heading_rows(model: Any, lv: _Lyap, V: np.ndarray, rooms: np.ndarray) -> list[Any]:
    """The heading rows ``z_i = [c_i, d_i]`` as *linear* rows on one lifted matrix per Lyapunov matrix j:
    ``[[Z_j, R], [R', left_j]] >= 0`` with ``R = [X; Y]``, and ``z_i Z_j z_i' <= room_i^2``.  Exact, not a relaxation:
    the LMI says ``Z_j >= R left_j^-1 R'``, so each linear row implies the row's own LMI
    ``[[room_i^2, z_i R], [R' z_i', left_j]] >= 0`` (``z_i R left_j^-1 R' z_i' <= room_i^2``), and ``Z_j = R left_j^-1 R'``
    satisfies every row that the LMIs allow.  One LMI of size 2 n_s + n_u per matrix and a linear row per heading
    row, instead of one LMI of size 1 + n_s per row and matrix: the rows of a long delay's covering channels
    (60 281 on the icr default at d_hi = 3, their corner combinations over four command intervals) cost what linear
    rows cost."""
    n_z = model.n_s + model.n_u
    R = cp.vstack([lv.X, lv.Y])
    # z Z z' = sum_ab z_a z_b Z_ab: the rows' coefficients on vec(Z) (column-major, as cp.vec)
    coef = np.einsum("ia,ib->iba", V, V).reshape(len(V), n_z * n_z)
    cons = []
    for j in range(len(lv.mats)):
        Z = cp.Variable((n_z, n_z), symmetric=True, name=f"Zh{j}")
        cons.append(_sym(cp.bmat([[Z, R], [R.T, lv.left(j)]])) >> 0)
        cons.append(coef @ cp.vec(Z, order="F") <= rooms**2 * (1.0 - 1e-6))
    return cons


# a row counts as implied only where its combination of the others is this much inside its room and reproduces it
# to this relative residual (the LP's own tolerances are ~1e-7; the certificate checker bounds every row anyway)
IMPLIED_ROOM, IMPLIED_RESIDUAL = 1e-6, 1e-9
# the rows beyond which none is left out (the LPs cost ~n h, h the rows kept): the default robot at d_hi = 2 has 2 601
# heading rows at 0.1 rad (5.7 s, 205 kept; every solve of its problem ~10x faster with them left out as LMIs: 28 s
# against 309 s at 0.2 rad); at d_hi = 3 it has 60 281 (its covering channels' corner combinations over four
# intervals), where the LPs took over 5 minutes without ending.  heading_constraints asks for at most LIFT_ROWS rows
# (beyond, every row is a linear row on a lifted matrix), so this cap guards only other callers
IMPLIED_MAX_ROWS = 5000
# the heading rows beyond which they are posed as linear rows on one lifted matrix per Lyapunov matrix
# (:func:`_lifted_heading_rows`), all of them, instead of an LMI per row kept (benchmarks/bench_heading_rows.py, side
# by side): the default robot at d_hi = 2 (2 601 rows, 0.2 rad, alpha 0.042) builds its problem in 2.2 s instead of
# 8.7 s (the LPs) and solves it in 21.5 s instead of 24.1 s; at d_hi = 3 (60 281 rows) it builds in 5.4 s instead of
# 36 s.  The committed configs have at most a few hundred rows (default: 217), where the default's synthesis takes
# 16-18 s either way with its figures equal to 1e-8 m, and keep the LMI per row
LIFT_ROWS = 1000
_KEPT: dict[tuple[bytes, bytes, tuple[int, ...]], list[int]] = {}  # the last row set's kept rows (heading_constraints)


def implied_rows_left_out(vecs: list[np.ndarray], rooms: list[float]) -> list[int]:
    """The indices of the rows ``|v_i xi'| <= room_i`` (on the set: ``sqrt(v_i X v_i') <= room_i``) to keep: a row
    that is a signed combination of the kept ones, ``v_i = sum_j l_j v_j`` with ``sum_j |l_j| room_j <= room_i``, holds
    whenever they do (``|v_i xi| <= sum_j |l_j| |v_j xi|``), so its LMI adds nothing and is left out.  Exact: the
    certificate checker still bounds every row.  The heading rows of a vertex set repeat one another's break points:
    217 rows keep 57 on configs/default.yaml at 0.081 rad, 2 601 keep 205 on the default robot at d_hi = 2.

    In the normalized rows ``w_i = v_i / room_i`` a row is left out when ``w_i`` lies inside the symmetric hull of
    the kept ones (shrunk by IMPLIED_ROOM), so the rows kept are the hull's extreme points, found as in Clarkson's
    algorithm: the rows in turn (the loosest first), each tested by one LP against the extreme rows found so far
    (``min sum_j |l_j| room_j`` with ``sum_j l_j v_j = v_i``); where it is not inside, the LP's dual (a direction y with
    ``|y w_j| <= 1`` on them and ``y w_i > 1``; outside their span, the part of w_i orthogonal to it) points to the
    row most extreme along y among those not yet left out, which is kept, and the row is tested again.  One small LP
    per row and per extreme row (~n h, h the rows kept) instead of one over all the others per row (~n^2): 2 601
    rows in 5.7 s against 29 s, the same rows kept on every committed nonlinear config.  Beyond IMPLIED_MAX_ROWS
    rows every one is kept."""
    from scipy.optimize import linprog

    V = np.asarray(vecs, dtype=float)
    room = np.asarray(rooms, dtype=float)
    n = len(V)
    if n < 2 or n > IMPLIED_MAX_ROWS:
        return list(range(n))
    W = V / room[:, None]
    kept: list[int] = []
    is_kept = np.zeros(n, dtype=bool)
    left_out = np.zeros(n, dtype=bool)
    for i in sorted(range(n), key=lambda k: -room[k]):
        while not is_kept[i]:
            if kept:
                A = V[kept].T
                res = linprog(np.concatenate([room[kept], room[kept]]), A_eq=np.hstack([A, -A]), b_eq=V[i],
                              bounds=(0, None), method="highs")
                if res.status == 0:
                    lam = res.x[: len(kept)] - res.x[len(kept):]
                    scale = max(1.0, float(np.max(np.abs(V[i]))))
                    if (float(np.abs(lam) @ room[kept]) <= room[i] * (1.0 - IMPLIED_ROOM)
                            and float(np.max(np.abs(A @ lam - V[i]))) <= IMPLIED_RESIDUAL * scale):
                        left_out[i] = True
                        break
                    y = np.asarray(res.eqlin.marginals, dtype=float)
                else:  # outside the kept rows' span: the part of w_i orthogonal to it separates it
                    B = W[kept].T
                    y = W[i] - B @ np.linalg.lstsq(B, W[i], rcond=None)[0]
            else:
                y = W[i]
            others = ~left_out & ~is_kept
            others[i] = False
            k = i
            if others.any():
                scores = np.abs(W[others] @ y)
                j = int(np.argmax(scores))
                if scores[j] > abs(float(W[i] @ y)) * (1.0 + 1e-9):  # a row further out along y: it is extreme
                    k = int(np.flatnonzero(others)[j])
            kept.append(k)
            is_kept[k] = True
    return sorted(kept)


def _vertex_parts(v: Any, lv: _Lyap):
    AX = np.asarray(v.A) @ lv.X + np.asarray(v.B) @ lv.Y
    CX = np.asarray(v.C_q) @ lv.X + np.asarray(v.D_q) @ lv.Y if v.n_q else None
    return AX, CX


def _multipliers(model: Any, kind: str, margin: float, mirror: Any = None) -> tuple[list[Any], list[Any]]:
    """Per vertex the S-procedure multiplier M_i (and M_i >= margin I); the vertices of one
    ``Vertex.group`` share theirs (the channels for slip changing within a period).  With a mirror, a mirrored
    vertex's multiplier is ``S M S`` of its partner's (S its channels' signs, ``Model.mirror``) and a
    self-mirrored vertex's is S-invariant: the mirror image of a certificate is one (§6h)."""
    Ms: list[Any] = []
    cons = []
    shared: dict[int, Any] = {}  # group -> its multiplier (Vertex.group: one per delay vertex, §9)
    for i, v in enumerate(model.vertices):
        if v.group >= 0 and v.group in shared:
            Ms.append(shared[v.group])
            continue
        partner = i if mirror is None else mirror.vertex[i]
        if partner < i:
            s = np.asarray(mirror.q_signs[partner], dtype=float)
            Ms.append(cp.multiply(np.outer(s, s), Ms[partner]) if v.n_q else Ms[partner])
            continue
        diag = None
        if v.diagonal:  # independent scalars (the kinematic channels): a diagonal multiplier
            diag = cp.Variable(v.n_q, name=f"d{i}")
            M = cp.diag(diag)
        else:
            M, _ = multiplier(v.n_q // 3, kind, tag=str(i))
            if mirror is not None and partner == i and v.n_q:  # self-mirrored: S M S = M
                s = np.asarray(mirror.q_signs[i], dtype=float)
                if np.any(s < 0):
                    M = cp.multiply((np.outer(s, s) > 0).astype(float), M)
        Ms.append(M)
        if v.group >= 0:
            shared[v.group] = M
        if v.n_q:  # M >= margin I; a diagonal one's entries each (the same, without a PSD cone of n_q (n_q + 1) / 2 rows)
            cons.append(diag >= margin if diag is not None else M >> margin * np.eye(v.n_q))
    return Ms, cons


def build_stability(model: Any, kind: str, margin: float, lyapunov: str = "common",
                    K: np.ndarray | None = None, symmetry: bool = True, kappa: float = ANALYSIS_KAPPA) -> LMIProblem:
    """Robust decay rate r (docs/theory.md §6a); scale fixed by Q >= I (S_m >= I); parameter r2 = r^2.

    With ``K`` given the gain is fixed (analysis): ``Y = K Q`` (``K G``) is then an expression and the
    problem asks for a Lyapunov certificate of that gain only, with ``I <= X <= kappa I``."""
    model = model.linearized()  # no constant column here: the stability LMI is about the linearization
    lv = _Lyap(model, lyapunov, K, model.mirror(lyapunov) if symmetry else None)
    n_s = model.n_s
    r2 = cp.Parameter(nonneg=True, name="r2", value=0.9)
    Ms, cons = _multipliers(model, kind, margin, lv.mirror)
    # analysis: maximize the smallest eigenvalue t of the LMIs with I <= X <= kappa I, so the point
    # returned sits as far inside the feasible set as it can (a feasibility problem minimizing
    # trace(Q) would land on its boundary, where the numpy check cannot confirm it)
    t = cp.Variable(name="t") if K is not None else None
    floor = margin if t is None else t
    for i, (v, M) in enumerate(zip(model.vertices, Ms)):
        AX, CX = _vertex_parts(v, lv)
        Bp = np.asarray(v.B_p)
        pairs, below = lv.grouped(i)
        cons += below
        for left, right in pairs:
            if v.n_q:
                Z = np.zeros((n_s, v.n_q))
                L = cp.bmat([[r2 * left, AX.T, CX.T], [AX, right - Bp @ M @ Bp.T, Z], [CX, Z.T, M]])
            else:
                L = cp.bmat([[r2 * left, AX.T], [AX, right]])
            cons.append(_sym(L) >> floor * np.eye(L.shape[0]))
    cons += lv.scale(1.0)
    mats = lv.mats
    if t is not None:
        cons += [X << kappa * np.eye(n_s) for X in mats]
        return LMIProblem(cp.Problem(cp.Maximize(t), cons), M=Ms, params={"r2": r2}, extra={"t": t},
                          **lv.problem_kwargs())
    prob = cp.Problem(cp.Minimize(sum(cp.trace(X) for X in mats) / (n_s * len(mats))), cons)
    return LMIProblem(prob, M=Ms, params={"r2": r2}, **lv.problem_kwargs())


def build_invariance(model: Any, kind: str, margin: float, weights: np.ndarray, motor: bool,
                     lyapunov: str = "common", symmetry: bool = True, least_motor: bool = False,
                     phase1: float | None = None, heading_rows: frozenset[bytes] | None = None,
                     mirror: Any = None) -> LMIProblem:
    """Invariant, attracting ellipsoid under every admissible delay and slip (docs/theory.md §6b);
    parameter alpha.  Minimizes sum_i weights_i * (bound on state i)^2 / level over e_x, e_y, e_theta.
    ``symmetry``: use the model's mirror symmetry when it has one (the same optimum, fewer LMIs).
    ``least_motor``: minimize instead the squared bound u^2 of the motor LMIs (§6c) on the commanded
    deviation, ``extra['u2']`` (``motor`` is then ignored).

    ``phase1`` (kappa > 0): the same LMIs as a problem that always has a solution: maximize t (``extra['t']``) with
    the vertex LMIs and X >= t I instead of >= margin I, and the set's position extents X_00, X_11 <= kappa (the
    other constraints as they are).  A solution of the LMIs above with X_00, X_11 <= kappa is one with t = margin >= 0,
    so a maximum t* < 0 says that none exists whose set keeps |e_x|, |e_y| <= sqrt(kappa).  Its parameters may differ from (alpha, 1 - alpha):
    ``one_minus_alpha`` = 1 - alpha_lo and ``alpha`` = alpha_hi make it a relaxation of every alpha in
    [alpha_lo, alpha_hi] ((1 - alpha) X and sum beta <= alpha loosen as alpha falls and rises): t* < 0 then holds for
    the whole interval (docs/theory.md §6j).  ``heading_rows``: pose just those heading rows
    (:func:`heading_constraints`' ``only``), a relaxation: its solution is a certificate only where every row holds at
    its values (row generation, :func:`rows_broken`); a phase-1 problem's ``extra`` then says which rows were posed.
    ``mirror``: with ``symmetry``, the symmetry to pose with instead of the model's own (a vertex subset's, closed under
    its images: ``robustsynth.model.mirror.restrict``)."""
    lv = _Lyap(model, lyapunov, mirror=(mirror if mirror is not None else model.mirror(lyapunov)) if symmetry else None)
    n_s, n_w = model.n_s, model.n_w
    alpha = cp.Parameter(nonneg=True, name="alpha", value=0.1)
    one_minus = cp.Parameter(nonneg=True, name="one_minus_alpha", value=0.9)
    beta = cp.Variable(n_w, name="beta")
    Ms, cons = _multipliers(model, kind, margin, lv.mirror)
    t = cp.Variable(name="t") if phase1 is not None else None
    floor = margin if t is None else t
    Zsw = np.zeros((n_s, n_w))
    vertex_lmis: list[list[Any]] = []  # per vertex its LMIs (phase-1: their duals rank the vertices)
    for i, (v, M) in enumerate(zip(model.vertices, Ms)):
        AX, CX = _vertex_parts(v, lv)
        E = np.asarray(v.E)
        Bp = np.asarray(v.B_p)
        pairs, below = lv.grouped(i)
        cons += below
        vertex_lmis.append([])
        for left, right in pairs:
            rows = [[one_minus * left, Zsw, AX.T], [Zsw.T, cp.diag(beta), E.T],
                    [AX, E, right - (Bp @ M @ Bp.T if v.n_q else 0)]]
            if v.n_q:
                rows[0].append(CX.T)
                rows[1].append(np.asarray(v.F).T)  # q = C_q xi + D_q du + F_q w
                rows[2].append(np.zeros((n_s, v.n_q)))
                rows.append([CX, np.asarray(v.F), np.zeros((v.n_q, n_s)), M])
            L = cp.bmat(rows)
            cons.append(_sym(L) >> floor * np.eye(L.shape[0]))
            vertex_lmis[-1].append(cons[-1])
    cons += [cp.sum(beta) <= alpha] + lv.scale(floor)
    u2 = cp.Variable(nonneg=True, name="u2") if least_motor else None
    if motor or least_motor:
        for j in lv.own:
            cons += motor_constraints(model, lv.left(j), lv.Y, rows=lv.motor_rows(model, j), u2=u2)
    extra: dict[str, Any] = {"beta": beta}
    if model.heading_bound is not None:
        cons += heading_constraints(model, lv, only=heading_rows, extra=extra if t is not None else None)
    if t is not None:
        cons += [lv.mats[j][i, i] <= float(phase1) for j in lv.own for i in (0, 1)]
        extra["t"] = t
        return LMIProblem(cp.Problem(cp.Maximize(t), cons), M=Ms, params={"alpha": alpha, "one_minus_alpha": one_minus},
                          extra=extra, vertex_lmis=vertex_lmis, **lv.problem_kwargs())
    if least_motor:
        objective = u2
        extra["u2"] = u2
    else:
        terms = []
        for i in range(3):
            t, c = lv.diag_bound(i)
            terms.append(float(weights[i]) * t)
            cons += c
        objective = sum(terms)
    prob = cp.Problem(cp.Minimize(objective), cons)
    return LMIProblem(prob, M=Ms, params={"alpha": alpha, "one_minus_alpha": one_minus}, extra=extra,
                      vertex_lmis=vertex_lmis, **lv.problem_kwargs())


def _sym_basis(n: int) -> np.ndarray:
    """The symmetric n x n matrices S_i with ones at (a, b) and (b, a), one per upper-triangle entry."""
    iu = np.triu_indices(n)
    basis = np.zeros((iu[0].size, n, n))
    basis[np.arange(iu[0].size), iu[0], iu[1]] = 1.0
    basis[np.arange(iu[0].size), iu[1], iu[0]] = 1.0
    return basis
