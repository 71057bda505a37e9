"""The kinematic terms the linearization drops, as bounded channels of the vertices (docs/theory.md §9).

Over one period the robot follows exact arcs: command ``j`` (``du_{k-j}``, j = 0 the newest) acts
on ``[s~_j, s~_{j-1})`` (``s~_{-1} = Ts``, ``s~_{d_hi} = 0``) with forward speed ``v_j = V + a_j`` and
turn rate ``omega_j``, both affine in the command and in the slip (``(v_j, omega_j) = M(mu)(u^D + du)``),
so ``e_theta(t)`` is piecewise linear.  Exactly, with ``e_theta(t)`` in ``[-theta_bar, theta_bar]``:

    e_y+ - [linear map]_y = int a sin e_theta dt + V int (sinc e_theta - 1) e_theta dt
    e_x+ - [linear map]_x = -V int c(e_theta) e_theta dt - int a (1 - cos e_theta) dt,  c = (1 - cos)/.

Write ``e_theta(t) = e_theta0 + sum_j omega_j l_j(t)`` with ``l_j(t) >= 0`` the time command j has
acted by t.  Every integral of a bounded factor against a non-negative weight is the weight's
integral times the factor's average, which lies in the factor's range.  So each term is a
*channel* ``q`` (linear in the lifted state, the command and the constant column) times an unknown
number in a known interval, independent of every other:

- ``Ts e_theta0`` and ``W_j omega_j`` (``W_j = int l_j = (h_j^2 - h_{j-1}^2) / 2``, ``h_j = Ts - s~_j``)
  times ``V (sinc - 1)`` in ``[V (sinc theta_bar - 1), 0]`` (e_y) and ``V c`` in ``[-V c(theta_bar), V c(theta_bar)]`` (e_x);
- ``len_j a_j`` (``len_j = h_j - h_{j-1}``) times ``sin`` in ``[-sin theta_bar, sin theta_bar]`` (e_y) and
  ``1 - cos`` in ``[0, 1 - cos theta_bar]`` (e_x).

The centre of each interval moves into the vertex (A, B, E); the half-width is a diagonal Delta
(|delta_i| <= 1) with ``p = Delta q``, ``q = C_q xi + D_q du + F_q w``.  W_j and len_j are affine in a
delay vertex's ``(h_j, h_j^2/2)`` and the channels in the slip, so the vertices cover every admissible
delay and slip exactly as the linear parts do.  The certificate must also prove
``|e_theta(t)| <= theta_bar`` on its own set: ``e_theta`` at the period's break points (the
``heading`` rows, affine in the same vertex data) is bounded there.

Slip that changes within the period (:func:`covering_channels`): the channels are built at the slip
box's centre, and each track and command adds one channel for its slip's deviation from it; they are
then the same at every slip of a delay vertex, whose vertices share one multiplier (``group``).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from .vertices import Vertex, interval_coordinates

__all__ = ["KinematicChannels", "vertex_channels", "covering_channels", "factor_ranges", "channel_scales", "augment",
           "linearization_delta"]


@dataclass(frozen=True)
class KinematicChannels:
    """One vertex's channels ``q = C xi + D du + F w`` (rows: Ts e_theta0, W_j omega_j for j = 0..d_hi,
    len_j a_j for j = 0..d_hi) and its heading rows: e_theta at t_k and after each command's interval
    (``C_h xi + D_h du + g_h``, in time order)."""

    C: np.ndarray
    D: np.ndarray
    F: np.ndarray
    n_turn: int  # the first n_turn rows are the turn channels (e_theta0 and omega_j), the rest speed
    C_h: np.ndarray
    D_h: np.ndarray
    g_h: np.ndarray
    # slip changing within the period (covering_channels): per track i and command j the track's own
    # forward speed per unit of slip, ``f_ij = N_i[0] (u^D + du_{k-j})`` (rows ``C_dev xi + D_dev du + F_dev``),
    # its interval's length ``len_j`` and ``|kappa_i| W_j`` (N_i[1] = kappa_i N_i[0]), and the track's slip
    # half-width; empty without
    C_dev: np.ndarray | None = None
    D_dev: np.ndarray | None = None
    F_dev: np.ndarray | None = None
    len_dev: np.ndarray | None = None
    W_dev: np.ndarray | None = None
    half_dev: np.ndarray | None = None
    # a turning reference (model/arcs.py): the heading rows' coefficients on the reference's yaw-rate
    # coordinates (w_k / w_bar, (w_k - w_{k-j}) / b_j, each in [-1, 1]); None on straight segments
    F_h: np.ndarray | None = None
    # per heading row, the time since t_k of its break point [s]
    elapsed_h: np.ndarray | None = None

    @property
    def heading_offsets(self) -> np.ndarray:
        """Per heading row, the largest |e_theta| its constant part can give: ``|g_h|``, plus ``sum |F_h|`` over
        a turning reference's yaw-rate box (its coordinates each in [-1, 1])."""
        out = np.abs(np.asarray(self.g_h, dtype=float))
        return out if self.F_h is None else out + np.abs(self.F_h).sum(axis=1)

    @property
    def n_dev(self) -> int:
        return 0 if self.C_dev is None else self.C_dev.shape[0]

    @property
    def n_rows(self) -> int:
        """Channels per error row (e_x, e_y): the turn and speed channels, then the deviation ones."""
        return self.C.shape[0] + self.n_dev


def _command_row(j: int, coef: np.ndarray, n_s: int, n_e: int, n_u: int) -> tuple[np.ndarray, np.ndarray]:
    """``coef`` on command j's slot: the new command's (D, j = 0) or the stored one's (C, its state slot)."""
    c, d = np.zeros(n_s), np.zeros(n_u)
    if j == 0:
        d[:] = coef
    else:
        c[n_e + (j - 1) * n_u : n_e + j * n_u] = coef
    return c, d


def _break_points(lens: np.ndarray, yaw: list[np.ndarray], uD: np.ndarray, n_s: int, n_e: int, n_u: int,
                  d_hi: int) -> list[tuple[np.ndarray, np.ndarray, float, float]]:
    """e_theta at the period's break points, ``(c, d, g, t)`` with e_theta = c xi + d du + g at time t
    since t_k: at t_k, then after the oldest command's interval, ..., after the newest's; command j turns
    at ``yaw[j] (u^D + du)``."""
    c, d, g, t = np.eye(n_s)[2], np.zeros(n_u), 0.0, 0.0
    out = [(c, d, g, t)]
    for j in range(d_hi, -1, -1):
        dc, dd = _command_row(j, lens[j] * yaw[j], n_s, n_e, n_u)
        c, d, g, t = c + dc, d + dd, g + lens[j] * float(yaw[j] @ uD), t + float(lens[j])
        out.append((c, d, g, t))
    return out


def vertex_channels(mu: np.ndarray, coords: np.ndarray, V: float, Ts: float, M: np.ndarray, n_s: int,
                    n_e: int, n_u: int, d_hi: int) -> KinematicChannels:
    """Channels of the vertex with slip matrix ``M = M(mu)`` and delay coordinates ``coords[j] = (h_j,
    h_j^2/2)`` of instants j = 0..d_hi-1 (a delay vertex's; for a triangle's third vertex the second
    coordinate is not h^2/2, which is the point: everything below is affine in them)."""
    coords = np.asarray(coords, dtype=float).reshape(d_hi, 2)
    lens, Ws = interval_coordinates(coords[:, 0], coords[:, 1], Ts)
    uD = np.array([V, 0.0])
    n_cmd = d_hi + 1
    rows = [(np.eye(n_s)[2] * Ts, np.zeros(n_u), 0.0)]  # Ts e_theta0
    rows += [(*_command_row(j, Ws[j] * M[1], n_s, n_e, n_u), Ws[j] * float(M[1] @ uD)) for j in range(n_cmd)]
    rows += [(*_command_row(j, lens[j] * M[0], n_s, n_e, n_u), lens[j] * (float(M[0] @ uD) - V)) for j in range(n_cmd)]
    C, Dm, F = (np.array([r[k] for r in rows]) for k in range(3))
    C_h, D_h, g_h, t_h = (np.array(x) for x in zip(*_break_points(lens, [M[1]] * n_cmd, uD, n_s, n_e, n_u, d_hi)))
    return KinematicChannels(C, Dm, F[:, None], 1 + n_cmd, C_h, D_h, g_h, elapsed_h=t_h)


def covering_channels(mu_r: tuple[float, float], mu_l: tuple[float, float], coords: np.ndarray, V: float, Ts: float,
                      D: float, n_s: int, n_e: int, n_u: int, d_hi: int, tol: float = 1e-12) -> KinematicChannels:
    """Channels of a delay vertex that hold for slip changing at any time within the period
    (docs/theory.md §9, "Slip that changes within a period").  With ``mu(t) = mu_c + dmu(t)`` (mu_c the
    box centre, ``|dmu_i| <= half_i``) and M affine in mu, ``M(mu) = M(mu_c) + sum_i dmu_i N_i`` with N_i of
    rank one (``N_i[1] = kappa_i N_i[0]``): the turn and speed channels are those of :func:`vertex_channels`
    at mu_c, and each track i and command j adds one channel ``f_ij`` (its forward speed per unit of slip)
    whose factor is ``dmu_i``'s share of ``int a sin`` (at most ``half_i sin theta_bar len_j``) and of
    ``V int (sinc - 1) e_theta`` (at most ``half_i V (1 - sinc theta_bar) |kappa_i| W_j``); the e_x row alike.
    Heading rows: e_theta at the break points for every slip corner of each command interval on its own
    (the intervals' slip averages are independent; e_theta is affine in each)."""
    from .slip import slip_matrix

    coords = np.asarray(coords, dtype=float).reshape(d_hi, 2)
    lo = np.array([mu_r[0], mu_l[0]], dtype=float)
    hi = np.array([mu_r[1], mu_l[1]], dtype=float)
    mu_c, half = (lo + hi) / 2.0, (hi - lo) / 2.0
    centre = vertex_channels(mu_c, coords, V, Ts, slip_matrix(mu_c, D), n_s, n_e, n_u, d_hi)
    M0 = slip_matrix(np.zeros(2), D)
    N = [slip_matrix(np.eye(2)[i], D) - M0 for i in range(2)]
    lens, Ws = interval_coordinates(coords[:, 0], coords[:, 1], Ts)
    uD = np.array([V, 0.0])
    rows, ln, wt, hw = [], [], [], []
    for i, Ni in enumerate(N):
        kappa = Ni[1, 0] / Ni[0, 0]
        if not np.allclose(Ni[1], kappa * Ni[0], rtol=0.0, atol=1e-12 * np.abs(Ni).max()):
            raise ValueError("a track's slip matrix is not of rank one")
        if half[i] <= 0.0:
            continue  # a track without slip range has no deviation
        for j in range(d_hi + 1):
            rows.append((*_command_row(j, Ni[0], n_s, n_e, n_u), float(Ni[0] @ uD)))
            ln.append(lens[j])
            wt.append(abs(kappa) * Ws[j])
            hw.append(half[i])
    # the heading at the break points, each command interval at each slip corner of its own
    corners = np.array([[r, lft] for r in (lo[0], hi[0]) for lft in (lo[1], hi[1])])
    Ms = slip_matrix(corners, D)
    seen: dict[bytes, tuple] = {}
    for combo in _corner_combinations(lens, corners, tol * Ts):
        for c, d, g, t in _break_points(lens, [Ms[k][1] for k in combo], uD, n_s, n_e, n_u, d_hi):
            seen.setdefault(np.concatenate([c, d, [g, t]]).tobytes(), (c, d, g, t))
    C_h, D_h, g_h, t_h = (np.array(x) for x in zip(*seen.values()))
    dev = [np.array([r[k] for r in rows]).reshape(len(rows), size) for k, size in enumerate((n_s, n_u, 1))]
    return replace(centre, C_h=C_h, D_h=D_h, g_h=g_h, elapsed_h=t_h, C_dev=dev[0], D_dev=dev[1], F_dev=dev[2],
                   len_dev=np.array(ln), W_dev=np.array(wt), half_dev=np.array(hw))


def _corner_combinations(lens: np.ndarray, corners: np.ndarray, tol: float) -> list[tuple[int, ...]]:
    """Per command interval (j = 0..d_hi) a slip corner index: every combination over the intervals of
    nonzero length, corner 0 for the others (they carry no time)."""
    live = [abs(float(ln)) > tol for ln in lens]
    return list(itertools.product(*[range(len(corners)) if lv else (0,) for lv in live]))


def factor_ranges(theta_bar: float) -> dict[str, tuple[float, float]]:
    """Centre and half-width of each factor for |e_theta| <= theta_bar: ``sinc - 1`` (times V, e_y),
    ``c = (1 - cos)/e_theta`` (times V, e_x), ``sin`` (e_y), ``1 - cos`` (e_x)."""
    t = float(theta_bar)
    sinc = np.sin(t) / t
    one_minus_cos = 2.0 * np.sin(t / 2.0) ** 2  # 1 - cos t without cancellation
    return {
        "sinc": (-(1.0 - sinc) / 2.0, (1.0 - sinc) / 2.0),
        "c": (0.0, one_minus_cos / t),
        "sin": (0.0, float(np.sin(t))),
        "cos": (one_minus_cos / 2.0, one_minus_cos / 2.0),
    }


def _unscaled(ch: KinematicChannels, theta_bar: float, V: float, n_x: int):
    """The channels' rows (q = C xi + D du + F w) and B_p's columns for |e_theta| <= theta_bar, before
    scaling.  Columns: e_y via sinc (turn channels), e_x via c (turn channels), e_y via sin (speed
    channels), e_x via 1 - cos (speed channels), then e_y and e_x via each deviation channel."""
    r = factor_ranges(theta_bar)
    n_t, n_v, n_d = ch.n_turn, ch.C.shape[0] - ch.n_turn, ch.n_dev
    sel = list(range(n_t)) * 2 + list(range(n_t, n_t + n_v)) * 2
    Cq, Dq, Fq = ch.C[sel], ch.D[sel], ch.F[sel]
    Bp = np.zeros((n_x, len(sel) + 2 * n_d))
    Bp[1, :n_t] = V * r["sinc"][1]
    Bp[0, n_t : 2 * n_t] = V * r["c"][1]
    Bp[1, 2 * n_t : 2 * n_t + n_v] = r["sin"][1]
    Bp[0, 2 * n_t + n_v : len(sel)] = r["cos"][1]
    if n_d:
        t = float(theta_bar)
        one_minus_cos = 2.0 * np.sin(t / 2.0) ** 2
        # e_y: int dmu_i f_ij sin e_theta over the interval and V int (sinc - 1) e_theta's share of dmu_i;
        # e_x: int dmu_i f_ij (1 - cos e_theta) and V int c e_theta's share (docs/theory.md §9)
        wy = ch.len_dev * np.sin(t) + ch.W_dev * V * (1.0 - np.sin(t) / t)
        wx = ch.len_dev * one_minus_cos + ch.W_dev * V * one_minus_cos / t
        w = np.concatenate([wy, wx])[:, None]
        Cq = np.vstack([Cq, w * np.vstack([ch.C_dev, ch.C_dev])])
        Dq = np.vstack([Dq, w * np.vstack([ch.D_dev, ch.D_dev])])
        Fq = np.vstack([Fq, w * np.vstack([ch.F_dev, ch.F_dev])])
        Bp[1, len(sel) : len(sel) + n_d] = ch.half_dev
        Bp[0, len(sel) + n_d :] = ch.half_dev
    return Cq, Dq, Fq, Bp


def channel_scales(channels: list[KinematicChannels], theta_bar: float, V: float) -> np.ndarray:
    """One factor per augmented channel, common to every vertex: B_p's column is multiplied and q's
    row divided by it, which leaves the LFT unchanged and gives the solver comparable sizes.  It must
    be common: B_p enters the LMIs quadratically (B_p M B_p'), so it may not differ between vertices."""
    parts = [_unscaled(ch, theta_bar, V, 3) for ch in channels]
    rows = np.max([np.max(np.abs(np.hstack([C, D, F])), axis=1) for C, D, F, _ in parts], axis=0)
    cols = np.max(np.abs(parts[0][3]), axis=0)
    ok = (rows > 0) & (cols > 0)
    return np.where(ok, np.sqrt(np.where(ok, rows, 1.0) / np.where(ok, cols, 1.0)), 1.0)


def augment(v: Vertex, ch: KinematicChannels, theta_bar: float, V: float, scales: np.ndarray, group: int = -1) -> Vertex:
    """The vertex with the kinematic channels for |e_theta(t)| <= theta_bar: the factors' centres in
    (A, B, E), their half-widths as the diagonal Delta (columns as :func:`_unscaled`; the deviation
    channels' factors are centred at 0).  ``group``: vertices of one group share their multiplier."""
    r = factor_ranges(theta_bar)
    A, B, E = (np.array(x, dtype=float, copy=True) for x in (v.A, v.B, v.E))
    turn, speed = slice(0, ch.n_turn), slice(ch.n_turn, ch.C.shape[0])
    for row, centre, rows in ((1, V * r["sinc"][0], turn), (0, -r["cos"][0], speed)):
        A[row] += centre * ch.C[rows].sum(axis=0)
        B[row] += centre * ch.D[rows].sum(axis=0)
        E[row] += centre * ch.F[rows].sum(axis=0)
    Cq, Dq, Fq, Bp = _unscaled(ch, theta_bar, V, A.shape[0])
    Bp = Bp * scales
    Cq, Dq, Fq = Cq / scales[:, None], Dq / scales[:, None], Fq / scales[:, None]
    return Vertex(A, B, E, Bp, Cq, Dq, v.corner, v.label, Fq, True, group)


def linearization_delta(ch: KinematicChannels) -> np.ndarray:
    """diag(Delta) at which an augmented vertex is the linearization again (every factor 0): +1 on the
    sinc and 1 - cos channels (their centres are minus their half-widths), 0 on the others."""
    n_t, n_v = ch.n_turn, ch.C.shape[0] - ch.n_turn
    return np.concatenate([np.ones(n_t), np.zeros(n_t), np.zeros(n_v), np.ones(n_v), np.zeros(2 * ch.n_dev)])
