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

__all__ = ["KinematicChannels", "vertex_channels", "covering_channels", "icr_covering_channels", "factor_ranges",
           "channel_scales", "augment", "linearization_delta"]


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
    # the icr slip model (docs/theory.md §12, "Nonlinear kinematics"): the last ``n_lat`` rows of C are the
    # lateral channels ``len_j v_y,j`` (v_y = -x_icr omega); the deviation rows' lateral share (per unit of
    # the factor, like ``len_dev``); the turn rate per unit of commanded turn rate at the channels' slip
    n_lat: int = 0
    lat_dev: np.ndarray | None = None
    turn_gain: float | None = None
    # slip changing within a period under the icr model: the linear map's deviation from the hull of the
    # constant-slip vertices, as channels ``q = C_lin xi + D_lin du + F_lin w`` into error row ``lin_target``
    # with factor in +-``lin_weight`` (model/nonlinear.icr_covering_channels)
    C_lin: np.ndarray | None = None
    D_lin: np.ndarray | None = None
    F_lin: np.ndarray | None = None
    lin_target: np.ndarray | None = None
    lin_weight: np.ndarray | None = None

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

    @property
    def n_lin(self) -> int:
        return 0 if self.C_lin is None else self.C_lin.shape[0]

    @property
    def n_speed(self) -> int:
        """The forward-speed rows ``len_j a_j`` (between the turn rows and the lateral ones)."""
        return self.C.shape[0] - self.n_turn - self.n_lat

    def lat_dev_or_zero(self) -> np.ndarray:
        return np.zeros(self.n_dev) if self.lat_dev is None else np.asarray(self.lat_dev, dtype=float)


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


def _break_rows(lens: np.ndarray, yaw_rows: np.ndarray, live: list[bool], uD: np.ndarray, n_s: int, n_e: int, n_u: int,
                d_hi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The distinct heading rows of :func:`_break_points` over every choice of a yaw row per live command interval
    (``yaw_rows``; a dead one takes the first), in the order of the choices (``itertools.product``, the newest command
    slowest) and of the break points within each, each row at its first occurrence: (C_h, D_h, g_h, t_h).  The same
    additions in the same order as :func:`_break_points`, a level of the break points at a time over every choice at
    once (the default robot at d_hi = 5: ~22 000 choices per delay vertex, 2 million calls of it took 69 s)."""
    choices = [range(len(yaw_rows)) if lv else (0,) for lv in live]
    combos = np.array(list(itertools.product(*choices)), dtype=int).reshape(-1, d_hi + 1)
    n = len(combos)
    c = np.broadcast_to(np.eye(n_s)[2], (n, n_s)).copy()
    d = np.zeros((n, n_u))
    g = np.zeros(n)
    t = 0.0
    levels = [np.column_stack([c, d, g, np.full(n, t)])]
    gains = np.array([float(y @ uD) for y in yaw_rows])  # (as _break_points: the 1-D products)
    for j in range(d_hi, -1, -1):
        k = combos[:, j]
        dc = np.zeros((len(yaw_rows), n_s))
        dd = np.zeros((len(yaw_rows), n_u))
        for r, y in enumerate(yaw_rows):
            dc[r], dd[r] = _command_row(j, lens[j] * y, n_s, n_e, n_u)
        c, d, g, t = c + dc[k], d + dd[k], g + lens[j] * gains[k], t + float(lens[j])
        levels.append(np.column_stack([c, d, g, np.full(n, t)]))
    rows = np.ascontiguousarray(np.stack(levels, axis=1).reshape(n * (d_hi + 2), n_s + n_u + 2))
    _, first = np.unique(rows.view(np.dtype((np.void, rows.itemsize * rows.shape[1]))).ravel(), return_index=True)
    rows = rows[np.sort(first)]
    return tuple(np.ascontiguousarray(x) for x in (rows[:, :n_s], rows[:, n_s:n_s + n_u], rows[:, n_s + n_u],
                                                    rows[:, n_s + n_u + 1]))  # type: ignore[return-value]


def vertex_channels(mu: np.ndarray, coords: np.ndarray, V: float, Ts: float, M: np.ndarray, n_s: int,
                    n_e: int, n_u: int, d_hi: int, lateral: np.ndarray | None = None) -> KinematicChannels:
    """Channels of the vertex with slip matrix ``M = M(mu)`` and delay coordinates ``coords[j] = (h_j,
    h_j^2/2)`` of instants j = 0..d_hi-1 (a delay vertex's; for a triangle's third vertex the second
    coordinate is not h^2/2, which is the point: everything below is affine in them).  ``lateral``: the icr
    model's lateral velocity per command (``v_y = lateral @ u``, :func:`~.slip.lateral_row`), which adds the
    rows ``len_j v_y,j`` (the lateral channels; ``-v_y sin e_theta`` into e_x, ``v_y (cos e_theta - 1)`` into
    e_y)."""
    coords = np.asarray(coords, dtype=float).reshape(d_hi, 2)
    lens, Ws = interval_coordinates(coords[:, 0], coords[:, 1], Ts)
    uD = np.array([V, 0.0])
    n_cmd = d_hi + 1
    rows = [(np.eye(n_s)[2] * Ts, np.zeros(n_u), 0.0)]  # Ts e_theta0
    rows += [(*_command_row(j, Ws[j] * M[1], n_s, n_e, n_u), Ws[j] * float(M[1] @ uD)) for j in range(n_cmd)]
    rows += [(*_command_row(j, lens[j] * M[0], n_s, n_e, n_u), lens[j] * (float(M[0] @ uD) - V)) for j in range(n_cmd)]
    n_lat = 0
    if lateral is not None:
        lat = np.asarray(lateral, dtype=float)
        rows += [(*_command_row(j, lens[j] * lat, n_s, n_e, n_u), lens[j] * float(lat @ uD)) for j in range(n_cmd)]
        n_lat = n_cmd
    C, Dm, F = (np.array([r[k] for r in rows]) for k in range(3))
    C_h, D_h, g_h, t_h = (np.array(x) for x in zip(*_break_points(lens, [M[1]] * n_cmd, uD, n_s, n_e, n_u, d_hi)))
    return KinematicChannels(C, Dm, F[:, None], 1 + n_cmd, C_h, D_h, g_h, elapsed_h=t_h, n_lat=n_lat,
                             turn_gain=float(M[1, 1]) if lateral is not None else None)


def icr_covering_channels(ranges: tuple[tuple[float, float], ...], coords: np.ndarray, V: float, Ts: float, D: float,
                          n_s: int, n_e: int, n_u: int, d_hi: int, tol: float = 1e-12,
                          by_vertices: bool = False) -> KinematicChannels:
    """Channels of a delay vertex that hold for the icr slip model's parameters changing at any time within
    the period (docs/theory.md §12, "Slip that changes within a period").  The vertices are the constant-slip
    ones (every corner of the box, slip constant over the period).  The twist a command (v, omega_c) gets is
    linear in six components (:func:`~.slip.icr_components`): ``v_x = s v + d (D/4) omega_c``, ``omega = ys omega_c
    + yd v / D``, ``v_y = -(xs omega_c + xd v / D)``, with s, d the tracks' mean and difference of traction and
    ys, yd, xs, xd those times the yaw factor (and x_icr): the yaw factor is one for both tracks, so a straight
    command's yaw rate depends on the spread of yd only.  Three families of channels bound what a slip history
    adds, each the same at every corner:

    - the kinematic channels of :func:`vertex_channels` at the centre twist (every component at the middle of
      its range), with its lateral rows;
    - per command j, ``q = v_j`` and ``q = omega_c,j`` (its forward speed and commanded turn rate) for the
      components' deviations from that centre inside the dropped terms (``half_dev`` 1, the halves in the
      weights: ``len_dev`` on the speed factors, ``W_dev`` on the turn factors, ``lat_dev`` on the lateral ones);
    - the linear map's deviation from the hull of the constant-slip vertices.  With ``u_j = u_0 + du_j'`` (u_0
      the newest command), the exact map is the constant-slip map at the period's average twist (a point of
      the corners' hull) plus ``V (Ts^2/2) (weighted - uniform average of omega's twist) u_0`` in e_y (a component's
      two averages differ by at most a quarter of its range) and, per older command j,
      ``(L_j (interval average - period average) + V W_j (weighted interval average - period average)) du_j'``
      (at most the component's range times ``share_j`` = L_j (1 - L_j / Ts) where it is affine in the delay
      coordinates, d_hi = 1, else L_j): into e_x, e_theta and e_y.

    ``by_vertices``: the third family for the vertices of :func:`~.vertices.icr_varying_vertices` instead, whose hull
    holds the linear map at every command interval's own average twist (exact, where the channels above lose the
    components' correlation): what is left is, per interval i, omega's (Ts - t)-weighted average against its uniform
    one (the vertices take them equal), at most a quarter of the component's range, into e_y through ``V W_i``.

    Heading rows: e_theta at the break points with each command interval's average yaw row at any of the images
    of the box's corners, independently per interval (e_theta is affine in each)."""
    from .slip import icr_components, icr_twist, slip_corners, slip_matrix

    coords = np.asarray(coords, dtype=float).reshape(d_hi, 2)
    comp = icr_components(ranges)  # (6, 2): s, d, ys, yd, xs, xd
    c, h = comp.mean(axis=1), (comp[:, 1] - comp[:, 0]) / 2.0
    hs, hd, hys, hyd, hxs, hxd = h
    T = icr_twist(c, D)  # the centre twist: (v_x, v_y, omega) per (v, omega_c)
    ch = vertex_channels(None, coords, V, Ts, T[[0, 2]], n_s, n_e, n_u, d_hi, lateral=T[1])
    lens, Ws = interval_coordinates(coords[:, 0], coords[:, 1], Ts)
    uD = np.array([V, 0.0])
    ev, ew = np.array([1.0, 0.0]), np.array([0.0, 1.0])  # a command's forward speed and commanded turn rate
    # per q base (v, omega_c): the components' half-widths on the speed (v_x), turn (omega) and lateral (v_y) factors
    bases = ((ev, hs, hyd / D, hxd / D), (ew, hd * D / 4.0, hys, hxs))
    dev, ln, wt, lt = [], [], [], []
    for e, k_speed, k_turn, k_lat in bases:
        if k_speed <= 0.0 and k_turn <= 0.0 and k_lat <= 0.0:
            continue
        for j in range(d_hi + 1):
            dev.append((*_command_row(j, e, n_s, n_e, n_u), float(e @ uD)))
            ln.append(k_speed * lens[j])
            wt.append(k_turn * Ws[j])
            lt.append(k_lat * lens[j])
    # (interval average - period average) = sum over the other intervals of L_i / Ts (interval j's - interval i's):
    # at most (1 - L_j / Ts) times the range; L_j (1 - L_j / Ts) is affine in the delay coordinates where one
    # instant is uncertain (d_hi = 1: L_1 = Ts - h_0, 1 - L_1 / Ts = h_0 / Ts, the product h_0 - 2 q_0 / Ts), else L_j
    if d_hi == 1:
        share = np.array([0.0, coords[0, 0] - 2.0 * coords[0, 1] / Ts])
    else:
        share = np.asarray(lens, dtype=float)
    lin, target, weight = [], [], []

    def add(c_row, d_row, f, row, w):
        if w > 0.0:
            lin.append((c_row, d_row, f))
            target.append(row)
            weight.append(w)

    if by_vertices:  # each interval's uniform average twist is a vertex coordinate (vertices.icr_varying_vertices);
        # what is left is omega's (Ts - t)-weighted average against its uniform one over each interval (the vertices
        # take them equal): at most a quarter of the range 2 h, into e_y through V W_i (W_i in q: one B_p everywhere)
        for j in range(d_hi + 1):
            for e, k in ((ew, hys), (ev, hyd / D)):
                c_j, d_j = _command_row(j, e, n_s, n_e, n_u)  # (W_j in q: B_p is one for every vertex)
                add(float(Ws[j]) * c_j, float(Ws[j]) * d_j, float(Ws[j]) * float(e @ uD), 1, V * k / 2.0)
    # omega's weighted and uniform period averages on the newest command: into e_y
    for e, k in (() if by_vertices else ((ew, hys), (ev, hyd / D))):
        add(*_command_row(0, e, n_s, n_e, n_u), float(e @ uD), 1, V * Ts * Ts / 2.0 * k / 2.0)
    for j in range(1, 1 if by_vertices else d_hi + 1):  # the older commands' difference from the newest: du_{k-j} - du_k
        rows = {}
        for name, e in (("v", ev), ("w", ew)):
            c_j, d_j = _command_row(j, e, n_s, n_e, n_u)
            c_0, d_0 = _command_row(0, e, n_s, n_e, n_u)
            rows[name] = (c_j - c_0, d_j - d_0)
        (cv, dv), (cw, dw) = rows["v"], rows["w"]
        sh = share[j]
        # e_x: v_x's interval average against the period's (s on v, d on (D/4) omega_c); e_theta: omega's (ys on
        # omega_c, yd on v / D); e_y: the lateral twist's and omega's weighted one on one factor per q base: V W_j
        # (weighted interval average - period average) is at most V (W_j / 4 + Ts share_j) times the range (the
        # weighted and uniform averages over one interval differ by at most a quarter of it, W_j <= Ts L_j)
        add(sh * cv, sh * dv, 0.0, 0, 2.0 * hs)
        add(sh * D / 4.0 * cw, sh * D / 4.0 * dw, 0.0, 0, 2.0 * hd)
        add(sh * cw, sh * dw, 0.0, 2, 2.0 * hys)
        add(sh / D * cv, sh / D * dv, 0.0, 2, 2.0 * hyd)
        ky_w = 2.0 * hxs * sh + V * 2.0 * hys * (Ws[j] / 4.0 + Ts * sh)
        ky_v = (2.0 * hxd * sh + V * 2.0 * hyd * (Ws[j] / 4.0 + Ts * sh)) / D
        if hxs > 0.0 or hys > 0.0:
            add(ky_w * cw, ky_w * dw, 0.0, 1, 1.0)
        if hxd > 0.0 or hyd > 0.0:
            add(ky_v * cv, ky_v * dv, 0.0, 1, 1.0)
    # the heading: each live command interval's yaw row at an image of a corner of (mu_r, mu_l, yaw)
    pts = slip_corners(*ranges[:3])  # (n, 3): mu_r, mu_l, yaw
    yaw_rows = np.unique(np.round(slip_matrix(pts, D)[:, 1, :], 15), axis=0)
    live = [abs(float(x)) > tol * Ts for x in lens]
    C_h, D_h, g_h, t_h = _break_rows(lens, yaw_rows, live, uD, n_s, n_e, n_u, d_hi)

    def stack(rows, k, size):
        return np.array([r[k] for r in rows], dtype=float).reshape(len(rows), size)

    return replace(ch, C_h=C_h, D_h=D_h, g_h=g_h, elapsed_h=t_h,
                   C_dev=stack(dev, 0, n_s), D_dev=stack(dev, 1, n_u), F_dev=stack(dev, 2, 1),
                   len_dev=np.array(ln), W_dev=np.array(wt), half_dev=np.ones(len(dev)), lat_dev=np.array(lt),
                   C_lin=stack(lin, 0, n_s), D_lin=stack(lin, 1, n_u), F_lin=stack(lin, 2, 1),
                   lin_target=np.array(target, dtype=int), lin_weight=np.array(weight))


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
    channels), e_x via 1 - cos (speed channels), e_x via sin and e_y via 1 - cos (the icr model's lateral
    channels), then e_y and e_x via each deviation channel, then the icr model's linear deviation channels."""
    r = factor_ranges(theta_bar)
    n_t, n_v, n_l, n_d = ch.n_turn, ch.n_speed, ch.n_lat, ch.n_dev
    lat = list(range(n_t + n_v, n_t + n_v + n_l))
    sel = list(range(n_t)) * 2 + list(range(n_t, n_t + n_v)) * 2 + lat * 2
    Cq, Dq, Fq = ch.C[sel], ch.D[sel], ch.F[sel]
    n_main = len(sel)
    Bp = np.zeros((n_x, n_main + 2 * n_d + ch.n_lin))
    Bp[1, :n_t] = V * r["sinc"][1]
    Bp[0, n_t : 2 * n_t] = V * r["c"][1]
    Bp[1, 2 * n_t : 2 * n_t + n_v] = r["sin"][1]
    Bp[0, 2 * n_t + n_v : 2 * n_t + 2 * n_v] = r["cos"][1]
    Bp[0, 2 * n_t + 2 * n_v : 2 * n_t + 2 * n_v + n_l] = r["sin"][1]  # -v_y sin e_theta into e_x
    Bp[1, 2 * n_t + 2 * n_v + n_l : n_main] = r["cos"][1]  # v_y (cos e_theta - 1) into e_y
    if n_d:
        t = float(theta_bar)
        one_minus_cos = 2.0 * np.sin(t / 2.0) ** 2
        # e_y: int dmu_i f_ij sin e_theta over the interval and V int (sinc - 1) e_theta's share of dmu_i;
        # e_x: int dmu_i f_ij (1 - cos e_theta) and V int c e_theta's share (docs/theory.md §9); the icr model's
        # lateral share: v_y (cos - 1) into e_y, -v_y sin into e_x (§12)
        lat_dev = ch.lat_dev_or_zero()
        wy = ch.len_dev * np.sin(t) + ch.W_dev * V * (1.0 - np.sin(t) / t) + lat_dev * one_minus_cos
        wx = ch.len_dev * one_minus_cos + ch.W_dev * V * one_minus_cos / t + lat_dev * np.sin(t)
        w = np.concatenate([wy, wx])[:, None]
        Cq = np.vstack([Cq, w * np.vstack([ch.C_dev, ch.C_dev])])
        Dq = np.vstack([Dq, w * np.vstack([ch.D_dev, ch.D_dev])])
        Fq = np.vstack([Fq, w * np.vstack([ch.F_dev, ch.F_dev])])
        Bp[1, n_main : n_main + n_d] = ch.half_dev
        Bp[0, n_main + n_d : n_main + 2 * n_d] = ch.half_dev
    if ch.n_lin:
        Cq, Dq, Fq = np.vstack([Cq, ch.C_lin]), np.vstack([Dq, ch.D_lin]), np.vstack([Fq, ch.F_lin])
        cols = n_main + 2 * n_d + np.arange(ch.n_lin)
        Bp[np.asarray(ch.lin_target, dtype=int), cols] = ch.lin_weight
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
    n_sp = ch.n_turn + ch.n_speed
    turn, speed, lat = slice(0, ch.n_turn), slice(ch.n_turn, n_sp), slice(n_sp, n_sp + ch.n_lat)
    for row, centre, rows in ((1, V * r["sinc"][0], turn), (0, -r["cos"][0], speed), (1, -r["cos"][0], lat)):
        A[row] += centre * ch.C[rows].sum(axis=0)
        B[row] += centre * ch.D[rows].sum(axis=0)
        E[row] += centre * ch.F[rows].sum(axis=0)
    Cq, Dq, Fq, Bp = _unscaled(ch, theta_bar, V, A.shape[0])
    Bp = Bp * scales
    Cq, Dq, Fq = Cq / scales[:, None], Dq / scales[:, None], Fq / scales[:, None]
    return Vertex(A, B, E, Bp, Cq, Dq, v.corner, v.label, Fq, True, group, v.instants)


def linearization_delta(ch: KinematicChannels) -> np.ndarray:
    """diag(Delta) at which an augmented vertex is the linearization again (every factor 0): +1 on the
    sinc and 1 - cos channels (their centres are minus their half-widths), 0 on the others."""
    n_t, n_v, n_l = ch.n_turn, ch.n_speed, ch.n_lat
    return np.concatenate([np.ones(n_t), np.zeros(n_t), np.zeros(n_v), np.ones(n_v), np.zeros(n_l), np.ones(n_l),
                           np.zeros(2 * ch.n_dev + ch.n_lin)])
