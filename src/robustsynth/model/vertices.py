"""Vertex descriptions of the uncertain lifted model (docs/theory.md §4-5).

Every model of the family hands synthesis and verification the same thing: a tuple of
:class:`Vertex` es, each an LFT in the delay ``(A_i, B_i, E_i, B_p, C_q_i, D_q_i)`` that may have
no Delta at all, such that for every admissible slip and delay history the exact lifted matrices
are a convex combination of the vertices' (with one Delta, |Delta| <= 1, shared by all of them).
An LMI that is affine in (A, B, E, C_q, D_q) and holds at every vertex (each with its own
multiplier) therefore holds everywhere.

- ``paper``: one vertex, the norm-bounded form of eqs. 31-33, slip as the additive box ``B_w w``.
- ``slip-aware``: per slip corner m the command columns are multiplied by ``M(mu_m)`` and the
  constant column ``c_m = B~_d (mu_m - 1)`` is tied to the vertex (E_m = c_m, w = 1); delays either
  by the norm-bounded embedding (same Delta for every corner) or by a covering triangle: the curve
  (h, h^2/2) lies in the triangle of its end points and the crossing of its end tangents, which
  contains its convex hull (strictly: it is not the hull itself), so each uncertain instant
  contributes 3 vertices: every combination (``product``, 4 * 3^n_b in all), or only the combinations
  in-order delivery needs (:func:`in_order_combinations`: (n+1)(n+2)/2 when the instants' triangles
  share one range).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

__all__ = ["Vertex", "apply_slip", "add_lateral", "icr_constant", "augment_integral", "triangle", "triangle_coordinates", "delay_vertex_gammas",
           "DELAY_COVERS", "TANGENTS", "in_order_combinations", "in_order_weights", "delay_cover_ranges"]


@dataclass(frozen=True)
class Vertex:
    """One vertex: ``xi+ = A xi + B du + E w + B_p p``, ``p = Delta q``, ``q = C_q xi + D_q du + F_q w``.

    ``corner`` indexes the slip corner (the Lyapunov matrix of a slip-dependent certificate);
    ``label`` names the vertex in reports.  ``diagonal``: Delta is diagonal with independent
    scalars (the kinematic channels of :mod:`.nonlinear`, a diagonal multiplier); otherwise it has
    the delay embedding's blocks (d1 I2, d2) per instant.  ``F_q`` None: no disturbance in q.
    ``group`` >= 0: every vertex of the group has the same channels and one multiplier (the kinematic
    channels for slip changing within a period: one group per delay vertex, whose slip vertices
    differ only in (A, B, E), so the LMI with that multiplier holds on their hull)."""

    A: np.ndarray
    B: np.ndarray
    E: np.ndarray
    B_p: np.ndarray
    C_q: np.ndarray
    D_q: np.ndarray
    corner: int
    label: str
    F_q: np.ndarray | None = None
    diagonal: bool = False
    group: int = -1  # vertices of one group (>= 0) share their S-procedure multiplier
    # the delay vertex's h_j (the time each command interval j acts on its triangle's (h, h^2/2) coordinates), one per
    # instant, on the polytopic delay descriptions' vertices; () elsewhere
    instants: tuple[float, ...] = ()

    @property
    def tangent(self) -> bool:
        """A vertex of the tangent cuts of a delay's exponential (its label says ``tangents``; phase 1 leaves
        them out)."""
        return TANGENTS in self.label

    @property
    def n_q(self) -> int:
        return self.B_p.shape[1]

    @property
    def F(self) -> np.ndarray:
        """F_q, zeros when the vertex has none: shape (n_q, n_w)."""
        return np.zeros((self.n_q, self.E.shape[1])) if self.F_q is None else self.F_q


def apply_slip(A: np.ndarray, B: np.ndarray, M: np.ndarray, n_e: int, n_u: int, d_hi: int):
    """Multiply every command entering the error rows by the slip matrix M (..., 2, 2).

    In the lifted map the error rows hold ``Gamma(h) (du_{k-j} - du_{k-j-1})``; the robot receives
    ``M du``, so exactly these blocks (and B's error rows) are right-multiplied by M.  The shift
    register rows (stored commands) are what the controller sent and stay as they are."""
    A = np.array(A, dtype=float, copy=True)
    B = np.array(B, dtype=float, copy=True)
    M = np.asarray(M, dtype=float)
    shape = np.broadcast_shapes(A.shape[:-2], M.shape[:-2])
    A = np.broadcast_to(A, shape + A.shape[-2:]).copy()
    B = np.broadcast_to(B, shape + B.shape[-2:]).copy()
    for j in range(d_hi):
        cols = slice(n_e + j * n_u, n_e + (j + 1) * n_u)
        A[..., :n_e, cols] = A[..., :n_e, cols] @ M
    B[..., :n_e, :] = B[..., :n_e, :] @ M
    return A, B


def add_lateral(A: np.ndarray, B: np.ndarray, lengths: np.ndarray, row: np.ndarray, n_e: int, n_u: int):
    """Add the lateral velocity of the icr slip model (docs/theory.md §12) to the lifted map: command
    interval i (du_{k-i}, of length ``lengths[..., i]``) moves e_y by ``L_i v_y``, ``v_y = row @ u``
    (A e_y = 0: nothing else).  A (..., n_s, n_s), B (..., n_s, n_u), lengths (..., d_hi + 1)."""
    A = np.array(A, dtype=float, copy=True)
    B = np.array(B, dtype=float, copy=True)
    L = np.asarray(lengths, dtype=float)
    row = np.asarray(row, dtype=float)
    B[..., 1, :] += L[..., 0, None] * row
    for i in range(1, L.shape[-1]):
        A[..., 1, n_e + (i - 1) * n_u : n_e + i * n_u] += L[..., i, None] * row
    return A, B


def icr_constant(A_c: np.ndarray, B_c: np.ndarray, Ts: float, V: float, mu: np.ndarray, D: float, n_s: int) -> np.ndarray:
    """The constant column of the icr slip model's lifted map (..., n_s) for slips ``mu`` (..., 4): the
    period's error under the reference command alone, ``Gamma(Ts) (M u^D - u^D) + Ts e_y v_y(u^D)``
    (the tracks model's ``B~_d (mu - 1)``, which it reproduces for yaw = 1, x_icr = 0)."""
    from .linearize import Gamma
    from .slip import lateral_row, slip_matrix

    mu = np.asarray(mu, dtype=float)
    uD = np.array([V, 0.0])
    out = np.zeros(mu.shape[:-1] + (n_s,))
    out[..., : B_c.shape[0]] = (slip_matrix(mu, D) @ uD - uD) @ Gamma(A_c, B_c, Ts).T
    out[..., 1] += Ts * (lateral_row(mu, D) @ uD)
    return out


def augment_integral(A: np.ndarray, B: np.ndarray, Ts: float, n_e: int = 3):
    """Append the integrator states z = (int_e_x, int_e_y), ``z+ = z + Ts (e_x, e_y)``, last to xi."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    n = A.shape[-1]
    Aa = np.zeros(A.shape[:-2] + (n + 2, n + 2))
    Aa[..., :n, :n] = A
    Aa[..., n, 0] = Ts
    Aa[..., n + 1, 1] = Ts
    Aa[..., n:, n:] = np.eye(2)
    Ba = np.zeros(B.shape[:-2] + (n + 2, B.shape[-1]))
    Ba[..., :n, :] = B
    return Aa, Ba


def triangle(h_min: float, h_max: float) -> np.ndarray:
    """Vertices (h, h^2/2) of the triangle that contains the curve (h, h^2/2) on [h_min, h_max]:
    the two end points and the crossing of the end tangents ((h_min+h_max)/2, h_min h_max/2)."""
    return np.array([[h_min, h_min**2 / 2.0], [h_max, h_max**2 / 2.0], [(h_min + h_max) / 2.0, h_min * h_max / 2.0]])


def triangle_coordinates(h: np.ndarray, h_min: float, h_max: float) -> np.ndarray:
    """Barycentric coordinates (..., 3) of (h, h^2/2) in :func:`triangle`; all in [0, 1] for h in range.

    With t = (h - h_min)/(h_max - h_min): weights (1-t)^2, t^2, 2 t (1-t) (a quadratic Bezier curve
    whose control point is the tangents' crossing)."""
    t = (np.asarray(h, dtype=float) - h_min) / (h_max - h_min)
    return np.stack([(1.0 - t) ** 2, t**2, 2.0 * t * (1.0 - t)], axis=-1)


DELAY_COVERS = ("product", "in-order", "in-order-common")
# the name of a triangle's third vertex (the crossing of its end tangents) in vertex labels; a vertex without it has
# every uncertain instant at an end of its range
TANGENTS = "tangents"

# the triangle vertices of one instant (:func:`triangle`'s rows) and where the in-order coupling puts them on
# [0, 1] (:func:`in_order_weights`): h_max ("high", weight t^2) first, then the tangents' crossing, then h_min
LOW, HIGH, MID = 0, 1, 2
# the pairs (newer instant i, older instant j) no in-order point needs when both triangles share one range
_OUT_OF_ORDER = {(HIGH, MID), (MID, LOW), (HIGH, LOW)}


def in_order_combinations(cover: np.ndarray, tol: float) -> list[tuple[int, ...]]:
    """The combinations of triangle vertices (one per uncertain instant, in the order of
    ``itertools.product``) that in-order delivery can need, for triangles on the ranges ``cover``
    (n, 2) of h_j = Ts - s~_j (h_0 <= h_1 <= ...: a newer command switches no earlier than an older one).

    Theorem (docs/theory.md §5, "in-order delay vertices"): couple the instants' barycentric weights
    ((1-t)^2, t^2, 2t(1-t)) through one uniform U on [0, 1] (:func:`in_order_weights`).  At every
    admissible h the combinations of positive mass reproduce (h_j, h_j^2/2) for every j, and none has a
    pair of instants with one range and states (i, j) in ``_OUT_OF_ORDER`` (they would need t_i > t_j, or
    t_i > sqrt(t_j (2 - t_j)) >= t_j, where h_i <= h_j gives t_i <= t_j).  Instants on different ranges
    are left free (every pair of states is reachable there), so the result is the product when no two
    instants share a range, and (n+1)(n+2)/2 combinations (patterns low..., tangents..., high...) when
    all do."""
    n = len(cover)
    same = [[abs(cover[i][0] - cover[j][0]) <= tol and abs(cover[i][1] - cover[j][1]) <= tol for j in range(n)]
            for i in range(n)]
    out: list[tuple[int, ...]] = []

    def extend(prefix: tuple[int, ...]) -> None:
        j = len(prefix)
        if j == n:
            out.append(prefix)
            return
        for c in (LOW, HIGH, MID):
            if all(not same[i][j] or (prefix[i], c) not in _OUT_OF_ORDER for i in range(j)):
                extend(prefix + (c,))

    extend(())
    return out


def in_order_weights(h: np.ndarray, cover: np.ndarray, combos: list[tuple[int, ...]], tol: float = 1e-12) -> np.ndarray:
    """Convex weights (..., len(combos)) of instants ``h`` (..., n) (in order, each within its cover range)
    over the combinations of :func:`in_order_combinations`: the mass of {U : every instant j is in state
    c_j}, where instant j is HIGH on [0, t_j^2), MID on [t_j^2, 1-(1-t_j)^2), LOW on the rest.  Their
    marginals are the triangle coordinates of every instant (:func:`triangle_coordinates`); raises
    ValueError when the combinations miss mass (instants out of order or out of their ranges)."""
    h = np.asarray(h, dtype=float)
    cover = np.asarray(cover, dtype=float)
    t = (h - cover[:, 0]) / (cover[:, 1] - cover[:, 0])
    if np.any(t < -tol) or np.any(t > 1 + tol):
        raise ValueError("switching instants outside the ranges of their delay vertices")
    t = np.clip(t, 0.0, 1.0)
    e1, e2 = t * t, 1.0 - (1.0 - t) ** 2
    lo = np.stack([e2, np.zeros_like(t), e1], axis=-1)  # (..., n, 3): per state its interval of U
    hi = np.stack([np.ones_like(t), e1, e2], axis=-1)
    idx = np.arange(h.shape[-1])
    out = np.empty(h.shape[:-1] + (len(combos),))
    for k, c in enumerate(combos):
        c = np.asarray(c)
        out[..., k] = np.maximum(0.0, hi[..., idx, c].min(axis=-1) - lo[..., idx, c].max(axis=-1))
    missing = np.abs(out.sum(axis=-1) - 1.0)
    if np.any(missing > 1e-9):
        raise ValueError(f"switching instants not in order: the in-order delay vertices miss {float(missing.max()):.3g} "
                         "of their weight")
    return out


def delay_cover_ranges(Ts: float, ranges: np.ndarray, width_tol: float, cover: str) -> tuple[list[int], np.ndarray]:
    """The uncertain instants and the h-ranges (n, 2) of their triangles: their own, or with
    ``in-order-common`` all the envelope of them (more delays than the config's: sound, looser)."""
    unc = [j for j, (lo, hi) in enumerate(np.asarray(ranges)) if (Ts - lo) - (Ts - hi) > width_tol]
    own = np.array([[Ts - ranges[j][1], Ts - ranges[j][0]] for j in unc]).reshape(-1, 2)
    if cover == "in-order-common" and len(unc):
        own = np.tile([own[:, 0].min(), own[:, 1].max()], (len(unc), 1))
    return unc, own


def delay_vertex_gammas(A_c: np.ndarray, B_c: np.ndarray, Ts: float, ranges: np.ndarray, width_tol: float,
                        cover: str = "product"):
    """Per-instant Gammas of every delay vertex: (list of labels, array (n_v, d_hi, n_e, n_u), list of
    uncertain instant indices, the combinations of triangle vertices used (one tuple per delay vertex)).
    A fixed instant contributes its exact Gamma.  ``cover``: every combination of the instants' triangles
    (``product``, 3^n), or only those in-order delivery needs (:func:`in_order_combinations`), on each
    instant's own range (``in-order``) or on their common range (``in-order-common``)."""
    if cover not in DELAY_COVERS:
        raise ValueError(f"unknown delay cover {cover!r}")
    AB = A_c @ B_c
    unc, tri_ranges = delay_cover_ranges(Ts, ranges, width_tol, cover)
    per = []
    for j, (lo, hi) in enumerate(np.asarray(ranges)):
        if j not in unc:
            h_max = Ts - lo
            per.append([(f"s{j}={lo:g}", h_max * B_c + h_max**2 / 2.0 * AB)])
            continue
        h_min, h_max = tri_ranges[unc.index(j)]
        tri = triangle(h_min, h_max)
        names = (f"s{j}={Ts - h_min:g}", f"s{j}={Ts - h_max:g}", f"s{j}:{TANGENTS}")
        per.append([(names[v], tri[v, 0] * B_c + tri[v, 1] * AB) for v in range(3)])
    if cover == "product":
        combos = list(itertools.product(range(3), repeat=len(unc)))
    else:
        combos = in_order_combinations(tri_ranges, width_tol)
    labels, gammas = [], []
    for combo in combos:
        pick = [per[j][0] if j not in unc else per[j][combo[unc.index(j)]] for j in range(len(per))]
        labels.append(", ".join(c[0] for c in pick))
        gammas.append(np.stack([c[1] for c in pick]))
    return labels, np.array(gammas), unc, combos


def loss_pieces(Ts: float, tau_min: float, tau_max: float, m: int, d_hi: int) -> list[tuple[str, int]]:
    """The pieces of the reachable switching instants on a link that loses at most m commands in a
    row, for tau_max <= Ts (docs/theory.md §3): ``('R', g)``: the newest command arrives after
    tau in [tau_min, tau_max] and the g before it were lost, s~ = (tau x (g+1), 0, ...);
    ``('L', g)``: the newest g commands are lost, s~ = (Ts x g, 0, ...)."""
    pieces = [("R", g) for g in range(0, min(m, d_hi - 1) + 1)]
    pieces += [("L", g) for g in range(1, min(m, d_hi) + 1)]
    return pieces


def loss_vertex_gammas(A_c: np.ndarray, B_c: np.ndarray, Ts: float, tau_min: float, tau_max: float, m: int,
                       d_hi: int, width_tol: float):
    """Delay vertices of the exact reachable set under loss (:func:`loss_pieces`): labels and
    per-instant Gammas (n_v, d_hi, n_e, n_u).  A piece R_g ties instants 0..g to one delay, so its
    vertices are the three triangle vertices of (h, h^2/2), h = Ts - tau, applied to all of them."""
    AB = A_c @ B_c
    G = lambda h, q: h * B_c + q * AB  # noqa: E731
    zero = G(Ts, Ts**2 / 2.0)  # s~ = 0: the command was in force for the whole period
    h_min, h_max = Ts - tau_max, Ts - tau_min
    tri = triangle(h_min, h_max) if h_max - h_min > width_tol else np.array([[h_max, h_max**2 / 2.0]])
    labels, gammas = [], []
    for kind, g in loss_pieces(Ts, tau_min, tau_max, m, d_hi):
        if kind == "R":
            for v, (h, q) in enumerate(tri):
                name = ("tau=max", "tau=min", TANGENTS)[v] if len(tri) == 3 else "tau"
                labels.append(f"received after {g} lost, {name}")
                gammas.append(np.stack([G(h, q) if j <= g else zero for j in range(d_hi)]))
        else:
            labels.append(f"newest {g} lost")
            gammas.append(np.stack([G(0.0, 0.0) if j < g else zero for j in range(d_hi)]))
    return labels, np.array(gammas)


def loss_hull_coordinates(s_tilde: np.ndarray, Ts: float, tau_min: float, tau_max: float, m: int, d_hi: int,
                          width_tol: float, tol: float = 1e-12) -> np.ndarray:
    """Convex weights (..., n_v) over :func:`loss_vertex_gammas` for reachable instants ``s_tilde``
    (..., d_hi); raises ValueError for instants outside the reachable set."""
    s = np.asarray(s_tilde, dtype=float)
    pieces = loss_pieces(Ts, tau_min, tau_max, m, d_hi)
    h_min, h_max = Ts - tau_max, Ts - tau_min
    n_tri = 3 if h_max - h_min > width_tol else 1
    sizes = [n_tri if k == "R" else 1 for k, _ in pieces]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    flat = s.reshape(-1, d_hi)
    out = np.zeros((flat.shape[0], int(offsets[-1])))
    for n, row in enumerate(flat):
        lead = int(np.argmax(np.abs(row - row[0]) > tol)) if np.any(np.abs(row - row[0]) > tol) else d_hi
        rest_zero = np.all(np.abs(row[lead:]) <= tol)
        if abs(row[0] - Ts) <= tol and ("L", lead) in pieces and rest_zero:
            out[n, offsets[pieces.index(("L", lead))]] = 1.0
            continue
        g = min(lead - 1, min(m, d_hi - 1))
        ok = rest_zero or np.all(np.abs(row[g + 1:]) <= tol)
        if not ok or not (tau_min - tol <= row[0] <= tau_max + tol) or np.any(np.abs(row[: g + 1] - row[0]) > tol):
            raise ValueError(f"switching instants {row.tolist()} are not reachable on this lossy link")
        i = offsets[pieces.index(("R", g))]
        if n_tri == 3:
            out[n, i : i + 3] = triangle_coordinates(Ts - row[0], h_min, h_max)
        else:
            out[n, i] = 1.0
    return out.reshape(s.shape[:-1] + (int(offsets[-1]),))


def loss_instant_grid(Ts: float, tau_min: float, tau_max: float, m: int, d_hi: int, n: int) -> np.ndarray:
    """Reachable switching-instant vectors (rows, (n_rows, d_hi)) on a lossy link (tau_max <= Ts):
    every piece of :func:`loss_pieces`, the delay on an n-point grid."""
    taus = np.linspace(tau_min, tau_max, max(n, 1)) if tau_max > tau_min else np.array([tau_min])
    rows = []
    for kind, g in loss_pieces(Ts, tau_min, tau_max, m, d_hi):
        if kind == "R":
            for t in taus:
                rows.append([t if j <= g else 0.0 for j in range(d_hi)])
        else:
            rows.append([Ts if j < g else 0.0 for j in range(d_hi)])
    return np.array(rows)


# ---------------------------------------------------------------------------------------------------
# slip that changes within a period (docs/theory.md §11)

# per track and command interval, the (uniform, (Ts - t)-weighted) averages of the slip in normalized
# coordinates ((mu - lo) / (hi - lo)) lie in this parallelogram: it contains every pair a measurable
# slip in [lo, hi] can produce on any interval of the period (theory.md §11, the lens lemma)
SLIP_AVERAGE_PARALLELOGRAM = ((0.0, 0.0), (0.5, 1.0), (1.0, 1.0), (0.5, 0.0))


def interval_coordinates(h: np.ndarray, q: np.ndarray, Ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Per command interval i = 0..d_hi (du_{k-i} acts on [s~_i, s~_{i-1}), s~_{-1} = Ts, s~_{d_hi} = 0)
    its length L_i and weight W_i = int (Ts - t) dt over it, from the instants' delay coordinates
    ``h_j = Ts - s~_j`` and ``q_j = h_j^2 / 2`` (..., d_hi); affine in (h, q), so a delay vertex's
    coordinates give its own.  Returns (L, W), each (..., d_hi + 1)."""
    h = np.asarray(h, dtype=float)
    q = np.asarray(q, dtype=float)
    zero = np.zeros(h.shape[:-1] + (1,))
    hh = np.concatenate([zero, h, np.full_like(zero, Ts)], axis=-1)
    qq = np.concatenate([zero, q, np.full_like(zero, Ts**2 / 2.0)], axis=-1)
    return np.diff(hh, axis=-1), np.diff(qq, axis=-1)


def interval_slip_averages(S: np.ndarray, Ts: float, t_switch: np.ndarray, mu_before: np.ndarray,
                           mu_after: np.ndarray, per_track: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The slip averages of every command interval when the slip jumps from ``mu_before`` to ``mu_after``
    (..., 2) within the period: (uniform, (Ts - t)-weighted), each (..., d_hi + 1, 2).  ``t_switch`` is
    one time for every slip parameter (...), or with ``per_track`` each track's own time (..., 2).
    An interval of zero length gets mu_before (it carries no weight)."""
    S = np.asarray(S, dtype=float)
    mb0 = np.asarray(mu_before, dtype=float)
    ts = np.asarray(t_switch, dtype=float)
    if per_track and ts.shape[-1:] != mb0.shape[-1:]:
        raise ValueError(f"per-track switch times {ts.shape} do not match the slip {mb0.shape}")
    ts = ts[..., None, :] if per_track else ts[..., None, None]  # (..., 1, 2 or 1)
    ends = np.concatenate([np.full(S.shape[:-1] + (1,), Ts), S, np.zeros(S.shape[:-1] + (1,))], axis=-1)
    b, a = ends[..., :-1, None], ends[..., 1:, None]  # interval i: [a_i, b_i)
    F = lambda t: Ts * t - t * t / 2.0  # noqa: E731  (antiderivative of Ts - t)
    cut = np.clip(ts, a, b)
    L, W = b - a, F(b) - F(a)
    l_before, w_before = cut - a, F(cut) - F(a)
    with np.errstate(invalid="ignore", divide="ignore"):
        f_l = np.where(L > 0, l_before / np.where(L > 0, L, 1.0), 1.0)
        f_w = np.where(W > 0, w_before / np.where(W > 0, W, 1.0), 1.0)
    mb, ma = mb0[..., None, :], np.asarray(mu_after, dtype=float)[..., None, :]
    return f_l * mb + (1.0 - f_l) * ma, f_w * mb + (1.0 - f_w) * ma


def varying_slip_maps(Phi: np.ndarray, A_c: np.ndarray, B_c: np.ndarray, Ts: float, V: float, L: np.ndarray,
                      W: np.ndarray, M_bar: np.ndarray, M_til: np.ndarray, lat_bar: np.ndarray | None = None):
    """The lifted map (A, B, E) when command interval i has slip matrix ``M_bar[..., i]`` on average and
    ``M_til[..., i]`` on its (Ts - t)-weighted average (..., d_hi + 1, 2, 2); L, W (..., d_hi + 1) from
    :func:`interval_coordinates`.  Exact for any slip history (§11): the error rows are
    ``Phi e + sum_i G_i (u^D + du_{k-i}) - Gamma(Ts) u^D`` with ``G_i = L_i B M_bar_i + W_i A B M_til_i``."""
    from .linearize import Gamma

    n_e, n_u = B_c.shape
    d_hi = L.shape[-1] - 1
    G = L[..., None, None] * (B_c @ M_bar) + W[..., None, None] * ((A_c @ B_c) @ M_til)  # (..., d_hi + 1, n_e, n_u)
    if lat_bar is not None:  # the icr model's lateral velocity (its uniform average) into e_y
        G = G.copy()
        G[..., 1, :] += L[..., None] * lat_bar
    batch = G.shape[:-3]
    n_s = n_e + d_hi * n_u
    # lift()'s layout, with each command's block G_i itself (not a difference of Gammas: switched_exact
    # without a jump is then robot_exact bit for bit)
    A = np.zeros(batch + (n_s, n_s))
    B = np.zeros(batch + (n_s, n_u))
    A[..., :n_e, :n_e] = Phi
    B[..., :n_e, :] = G[..., 0, :, :]
    for i in range(1, d_hi + 1):
        A[..., :n_e, n_e + (i - 1) * n_u : n_e + i * n_u] = G[..., i, :, :]
    B[..., n_e : n_e + n_u, :] = np.eye(n_u)
    for j in range(1, d_hi):
        A[..., n_e + j * n_u : n_e + (j + 1) * n_u, n_e + (j - 1) * n_u : n_e + j * n_u] = np.eye(n_u)
    E = np.zeros(batch + (n_s,))
    uD = np.array([V, 0.0])
    E[..., :n_e] = G.sum(axis=-3) @ uD - Gamma(A_c, B_c, Ts) @ uD
    return A, B, E


def piecewise_twist_averages(S: np.ndarray, Ts: float, mu0: np.ndarray, changes: list, D: float):
    """Per command interval (i = 0..d_hi, du_{k-i} on [s~_i, s~_{i-1})) the uniform and (Ts - t)-weighted averages of
    the twist matrix (v_x, v_y, omega per command; :func:`~.slip.twist_matrix`) when the slip parameters are
    ``mu0`` (..., n_p) from t_k and take the values of ``changes`` = [(t, mu), ...] (time order) within the period:
    exact for any slip model (the averages of the twist over each piece of constant slip).  Returns (bar, til),
    each (..., d_hi + 1, 3, 2)."""
    from .slip import twist_matrix

    S = np.asarray(S, dtype=float)
    lead = S.shape[:-1]
    ends = np.concatenate([np.full(lead + (1,), Ts), S, np.zeros(lead + (1,))], axis=-1)
    F = lambda t: Ts * t - t * t / 2.0  # noqa: E731  (antiderivative of Ts - t)
    pieces = [(np.zeros(lead), np.asarray(mu0, dtype=float))] + [(np.asarray(t, dtype=float), np.asarray(m, dtype=float))
                                                                 for t, m in changes]
    n_i = S.shape[-1] + 1
    bar = np.zeros(lead + (n_i, 3, 2))
    til = np.zeros(lead + (n_i, 3, 2))
    for i in range(n_i):
        b, a = ends[..., i], ends[..., i + 1]  # interval i: [a, b)
        L, W = b - a, F(b) - F(a)
        for k, (t0, m) in enumerate(pieces):
            t1 = pieces[k + 1][0] if k + 1 < len(pieces) else np.full(lead, Ts)
            lo_, hi_ = np.clip(t0, a, b), np.clip(np.maximum(t1, t0), a, b)
            T = twist_matrix(m, D)
            with np.errstate(invalid="ignore", divide="ignore"):
                wl = np.where(L > 0, (hi_ - lo_) / np.where(L > 0, L, 1.0), 1.0 if k == 0 else 0.0)
                ww = np.where(W > 0, (F(hi_) - F(lo_)) / np.where(W > 0, W, 1.0), 1.0 if k == 0 else 0.0)
            bar[..., i, :, :] += wl[..., None, None] * T
            til[..., i, :, :] += ww[..., None, None] * T
    return bar, til


def varying_slip_vertices(Phi: np.ndarray, A_c: np.ndarray, B_c: np.ndarray, Ts: float, V: float, D: float,
                          mu_r: tuple[float, float], mu_l: tuple[float, float], h: np.ndarray, q: np.ndarray,
                          labels: list[str], integral: bool, limit: int, tol: float = 1e-12):
    """Vertices that contain the lifted map for every slip history within the box, slip free to change
    at any time (docs/theory.md §11): per delay vertex (coordinates ``h``, ``q`` (n_v, d_hi)), every
    combination of :data:`SLIP_AVERAGE_PARALLELOGRAM` points per track and command interval (an interval
    of zero length at the vertex gets one point).  Returns a list of Vertex (no uncertainty channels,
    ``corner`` -1: they belong to no slip corner) and the delay vertex of each, or None when there would
    be more than ``limit`` or a delay vertex has more than two command intervals of nonzero length."""
    from .slip import slip_matrix

    L_all, W_all = interval_coordinates(h, q, Ts)
    para = np.array(SLIP_AVERAGE_PARALLELOGRAM)
    (rl, rh), (ll, lh) = mu_r, mu_l
    per_track = [(rl, rh), (ll, lh)]
    # the (mu_bar, mu_til) values per track of each parallelogram point; a zero-width range has one
    track_pts = []
    for lo, hi in per_track:
        pts = {(lo + (hi - lo) * u, lo + (hi - lo) * v) for u, v in para} if hi - lo > tol else {(lo, lo)}
        track_pts.append(sorted(pts))
    interval_pts = [(r, lft) for r in track_pts[0] for lft in track_pts[1]]  # (right (bar, til), left (bar, til))
    counts = []
    for L, W in zip(L_all, W_all):
        live = (np.abs(L) > tol * Ts) | (np.abs(W) > tol * Ts * Ts)
        if np.count_nonzero(live) > 2:
            # the heading within the period (certificate.bounds.heading_within_period) takes one slip corner for
            # the commands before a switching instant: exact with at most two command intervals
            return None
        counts.append(len(interval_pts) ** int(np.count_nonzero(live)))
    if sum(counts) > limit:
        return None
    n_e, n_u = B_c.shape
    out, delay = [], []
    for t, (L, W) in enumerate(zip(L_all, W_all)):
        live = (np.abs(L) > tol * Ts) | (np.abs(W) > tol * Ts * Ts)
        choices = [interval_pts if lv else [interval_pts[-1]] for lv in live]
        combos = list(itertools.product(*choices))
        bar = np.array([[[r[0], lft[0]] for r, lft in c] for c in combos])  # (n, d_hi + 1, 2)
        til = np.array([[[r[1], lft[1]] for r, lft in c] for c in combos])
        maps = varying_slip_maps(Phi, A_c, B_c, Ts, V, L, W, slip_matrix(bar, D), slip_matrix(til, D))
        out += _within_period_vertices(maps, integral, Ts, n_e, n_u, f"{labels[t]}; slip averages")
        delay += [t] * len(combos)
    return out, delay


def _within_period_vertices(maps: tuple, integral: bool, Ts: float, n_e: int, n_u: int, label: str) -> list[Vertex]:
    """Vertices without uncertainty channels (``corner`` -1: of no slip corner) of the maps (A, B, E) of a stack, with
    the integrators where the model has them, labelled ``label #k``."""
    A, B, E = maps
    if integral:
        A, B = augment_integral(A, B, Ts, n_e)
        E = np.concatenate([E, np.zeros(E.shape[:-1] + (2,))], axis=-1)
    n_s = A.shape[-1]
    return [Vertex(A[k], B[k], E[k][:, None], np.zeros((n_s, 0)), np.zeros((0, n_s)), np.zeros((0, n_u)), -1,
                   f"{label} #{k}") for k in range(A.shape[0])]


def icr_varying_vertices(Phi: np.ndarray, A_c: np.ndarray, B_c: np.ndarray, Ts: float, V: float, D: float,
                         ranges: tuple[tuple[float, float], ...], h: np.ndarray, q: np.ndarray, labels: list[str],
                         integral: bool, limit: int, tol: float = 1e-12):
    """Vertices whose hull holds the icr slip model's linearized lifted map for every history of its parameters within
    the box, changing at any time within the period (docs/theory.md §12): per delay vertex (coordinates ``h``, ``q``
    (n_v, d_hi)), every combination of the box corners' twist matrices, one per command interval (an interval of zero
    length at the vertex gets one).  The map is affine in each interval's average twist (:func:`varying_slip_maps`,
    ``G_i = L_i B M_bar_i + W_i A B M_til_i``) and the twist is multi-affine in the parameters, so every interval's
    uniform average is a convex combination of the corners' twists, independently of the other intervals'.  The
    vertices take the (Ts - t)-weighted average of omega equal to the uniform one; their difference is a channel
    (:func:`~.nonlinear.icr_covering_channels` with ``by_vertices``), so these vertices serve the certificates whose
    vertices carry the kinematic channels only.  Returns a list of Vertex (``corner`` -1) and the delay vertex of each,
    or None when there would be more than ``limit``."""
    from .slip import slip_corners, twist_matrix

    T = np.unique(np.round(twist_matrix(slip_corners(*ranges), D), 15), axis=0)  # (n, 3, 2): v_x, v_y, omega rows
    L_all, W_all = interval_coordinates(h, q, Ts)
    live_all = (np.abs(L_all) > tol * Ts) | (np.abs(W_all) > tol * Ts * Ts)
    if sum(len(T) ** int(np.count_nonzero(lv)) for lv in live_all) > limit:
        return None
    n_u = B_c.shape[1]
    out, delay = [], []
    for t, (L, W, live) in enumerate(zip(L_all, W_all, live_all)):
        combos = np.array(list(itertools.product(*[range(len(T)) if lv else (0,) for lv in live])), dtype=int)
        tw = T[combos]  # (n, d_hi + 1, 3, 2)
        M = tw[..., [0, 2], :]
        maps = varying_slip_maps(Phi, A_c, B_c, Ts, V, L, W, M, M, lat_bar=tw[..., 1, :])
        out += _within_period_vertices(maps, integral, Ts, B_c.shape[0], n_u, f"{labels[t]}; twists")
        delay += [t] * len(combos)
    return out, delay
