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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .vertices import Vertex

__all__ = ["KinematicChannels", "vertex_channels", "factor_ranges", "channel_scales", "augment", "linearization_delta"]


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


def vertex_channels(mu: np.ndarray, coords: np.ndarray, V: float, Ts: float, M: np.ndarray, n_s: int,
                    n_e: int, n_u: int, d_hi: int) -> KinematicChannels:
    """Channels of the vertex with slip matrix ``M = M(mu)`` and delay coordinates ``coords[j] = (h_j,
    h_j^2/2)`` of instants j = 0..d_hi-1 (a delay vertex's; for a triangle's third vertex the second
    coordinate is not h^2/2, which is the point: everything below is affine in them)."""
    coords = np.asarray(coords, dtype=float).reshape(d_hi, 2)
    h = np.concatenate([[0.0], coords[:, 0], [Ts]])  # h_{-1} .. h_{d_hi}
    hq = np.concatenate([[0.0], coords[:, 1], [Ts * Ts / 2.0]])
    uD = np.array([V, 0.0])
    n_cmd = d_hi + 1
    C = np.zeros((1 + 2 * n_cmd, n_s))
    Dm = np.zeros((1 + 2 * n_cmd, n_u))
    F = np.zeros((1 + 2 * n_cmd, 1))
    C[0, 2] = Ts

    def put(row: int, j: int, coef: np.ndarray, const: float) -> None:
        if j == 0:
            Dm[row] = coef
        else:
            C[row, n_e + (j - 1) * n_u : n_e + j * n_u] = coef
        F[row, 0] = const

    lens = []
    for j in range(n_cmd):
        W = hq[j + 1] - hq[j]
        ln = h[j + 1] - h[j]
        lens.append(ln)
        put(1 + j, j, W * M[1], W * float(M[1] @ uD))
        put(1 + n_cmd + j, j, ln * M[0], ln * (float(M[0] @ uD) - V))
    # heading at the break points: t_k, then after the oldest command's interval, ..., after the newest's
    C_h = [np.eye(n_s)[2]]
    D_h = [np.zeros(n_u)]
    g_h = [0.0]
    c, d, g = C_h[0].copy(), D_h[0].copy(), 0.0
    for j in range(d_hi, -1, -1):
        if j == 0:
            d = d + lens[j] * M[1]
        else:
            c = c.copy()
            c[n_e + (j - 1) * n_u : n_e + j * n_u] += lens[j] * M[1]
        g += lens[j] * float(M[1] @ uD)
        C_h.append(c.copy())
        D_h.append(d.copy())
        g_h.append(g)
    return KinematicChannels(C, Dm, F, 1 + n_cmd, np.array(C_h), np.array(D_h), np.array(g_h))


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


def channel_scales(channels: list[KinematicChannels], theta_bar: float, V: float) -> np.ndarray:
    """One factor per augmented channel, common to every vertex: B_p's column is multiplied and q's
    row divided by it, which leaves the LFT unchanged and gives the solver comparable sizes.  It must
    be common: B_p enters the LMIs quadratically (B_p M B_p'), so it may not differ between vertices."""
    rows = np.max([np.max(np.abs(np.hstack([ch.C, ch.D, ch.F])), axis=1) for ch in channels], axis=0)
    n_t = channels[0].n_turn
    r = factor_ranges(theta_bar)
    sel = list(range(n_t)) * 2 + list(range(n_t, rows.size)) * 2
    n_v = rows.size - n_t
    cols = np.concatenate([np.full(n_t, V * r["sinc"][1]), np.full(n_t, V * r["c"][1]),
                           np.full(n_v, r["sin"][1]), np.full(n_v, r["cos"][1])])
    rn = rows[sel]
    return np.where((rn > 0) & (cols > 0), np.sqrt(np.where(rn > 0, rn, 1.0) / np.where(cols > 0, cols, 1.0)), 1.0)


def augment(v: Vertex, ch: KinematicChannels, theta_bar: float, V: float, scales: np.ndarray) -> Vertex:
    """The vertex with the kinematic channels for |e_theta(t)| <= theta_bar: the factors' centres in
    (A, B, E), their half-widths as the diagonal Delta.  Rows: e_y via sinc (turn channels), e_x via c
    (turn channels), e_y via sin (speed channels), e_x via 1 - cos (speed channels)."""
    r = factor_ranges(theta_bar)
    A, B, E = (np.array(x, dtype=float, copy=True) for x in (v.A, v.B, v.E))
    turn, speed = slice(0, ch.n_turn), slice(ch.n_turn, ch.C.shape[0])
    for row, centre, rows in ((1, V * r["sinc"][0], turn), (0, -r["cos"][0], speed)):
        A[row] += centre * ch.C[rows].sum(axis=0)
        B[row] += centre * ch.D[rows].sum(axis=0)
        E[row] += centre * ch.F[rows].sum(axis=0)
    sel = list(range(ch.n_turn)) * 2 + list(range(ch.n_turn, ch.C.shape[0])) * 2
    Cq, Dq, Fq = ch.C[sel].copy(), ch.D[sel].copy(), ch.F[sel].copy()
    n_t, n_v = ch.n_turn, ch.C.shape[0] - ch.n_turn
    Bp = np.zeros((A.shape[0], len(sel)))
    Bp[1, :n_t] = V * r["sinc"][1]
    Bp[0, n_t : 2 * n_t] = V * r["c"][1]
    Bp[1, 2 * n_t : 2 * n_t + n_v] = r["sin"][1]
    Bp[0, 2 * n_t + n_v :] = r["cos"][1]
    Bp *= scales
    Cq, Dq, Fq = Cq / scales[:, None], Dq / scales[:, None], Fq / scales[:, None]
    return Vertex(A, B, E, Bp, Cq, Dq, v.corner, v.label, Fq, True)


def linearization_delta(ch: KinematicChannels) -> np.ndarray:
    """diag(Delta) at which an augmented vertex is the linearization again (every factor 0): +1 on the
    sinc and 1 - cos channels (their centres are minus their half-widths), 0 on the others."""
    n_t, n_v = ch.n_turn, ch.C.shape[0] - ch.n_turn
    return np.concatenate([np.ones(n_t), np.zeros(n_t), np.zeros(n_v), np.ones(n_v)])
