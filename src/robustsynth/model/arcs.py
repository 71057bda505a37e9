"""A reference that turns along arcs: the vertices for a reference yaw rate ``|w_k| <= w_bar``
(docs/theory.md §10, "Turning along arcs").

The reference moves at V^D with a yaw rate ``w_k`` that is constant on each sampling period and
changes by at most ``step`` from one period to the next; the law measures the error in the
reference's frame at t_k and sends the turning feedforward ``(V^D, w_k) + du_k``.  Over one period,
in the frame F_k of the reference at t_k, the robot moves as on a straight segment (its own
kinematics do not know about the reference).  Linearized about the nominal arc (heading ``w s``
in F_k, s the time since t_k), with ``eta(s)`` the heading's deviation from it and ``a`` the
forward-speed deviation, the error before the change of frame is exactly

    e~_x+ = [straight map]_x - V int sin(w s) eta ds + int a (cos(w s) - 1) ds
    e~_y+ = [straight map]_y - V w Ts^2/2 + V int (cos(w s) - 1) eta ds + int a sin(w s) ds
    e~_theta+ = [straight map]_theta - w Ts,

where the straight map is the vertex's own (A, B, E) with every command's feedforward
``(0, w_{k-j})`` added (it reaches the robot as a command does, through the slip).  At t_{k+1} the
law measures in F_{k+1}, turned by ``phi = w_k Ts``: ``e+ = R(phi) e~+`` on (e_x, e_y).

Everything the arc adds is bounded in the form the kinematic channels use (model/nonlinear.py):

- the feedforward and the reference's turn: disturbance columns ``w_k / w_bar`` and, per older
  command j, ``(w_k - w_{k-j}) / b_j`` with ``b_j = min(j step, 2 w_bar)``, each in [-1, 1];
- ``int f(s) eta(s) ds`` and ``int f(s) a(s) ds`` with ``f`` one of ``cos(w s) - 1`` (in
  [cos phi_bar - 1, 0]) or ``sin(w s)`` (in [-sin phi_bar, sin phi_bar]), ``phi_bar = w_bar Ts``:
  ``eta(s) = e_theta0 + sum_j (omega_j - w_k) l_j(s)`` with weights ``1, l_j >= 0`` and ``a``
  piecewise constant, so each term is a channel of the kinematic module (``Ts e_theta0``,
  ``W_j (omega_j - w_k)``, ``len_j a_j``) times the factor's average, which lies in its range;
- the rotation: ``R(phi) = I + (cos phi - 1) I + sin phi [[0, 1], [-1, 0]]``, so two channels per
  row with ``q`` the rows of the map before the rotation, ``cos phi - 1`` in [cos phi_bar - 1, 0]
  and ``sin phi`` in [-sin phi_bar, sin phi_bar].  A channel's own contribution ``b delta`` into
  one row turns into ``(cos phi b delta, -sin phi b delta)``: it keeps its column (|cos| <= 1) and
  gains a twin of weight ``sin phi_bar b`` into the other row.

All factors are independent scalars in [-1, 1] (a diagonal Delta), which contains the correlated
truth (the same ``w_k`` in several places): sound, conservative.  The channels' centres move into
(A, B, E); B_p is common to every vertex, so per-vertex multipliers stay valid on the hull.

**The nonlinear robot** (``theta_bar``: |eta(t)| <= theta_bar on the period, proven by the certificate
on its own set from the heading rows).  With ``psi = w s``, exactly (no linearization anywhere):

    e~_x+ = [straight map]_x + int eta F_tx ds + int a F_sx ds,   F_tx = -V (cos psi c(eta) + sin psi sinc eta)
    e~_y+ = [straight map]_y - V w Ts^2/2 + int eta F_ty ds + int a F_sy ds,
            F_ty = V (cos psi sinc eta - sin psi c(eta) - 1),  F_sx = cos(psi + eta) - 1,  F_sy = sin(psi + eta)

(c(eta) = (1 - cos eta) / eta), the same four channel families with wider factor ranges
(:func:`arc_ranges`): F_tx in +-V (c(theta_bar) + sin phi_bar), F_ty in V [cos phi_bar sinc theta_bar - 1 -
sin phi_bar c(theta_bar), sin phi_bar c(theta_bar)], F_sx in [cos(phi_bar + theta_bar) - 1, 0], F_sy in
+-sin(phi_bar + theta_bar).  theta_bar = 0 gives the linearized ranges above, phi_bar = 0 the straight
kinematic channels of docs/theory.md §9.  The rotation is exact either way.

**Slip that changes within a period** (``within_period``): the channels are the delay vertex's covering
ones (model/nonlinear.covering_channels, at the slip box's centre), plus one deviation channel per track
and command (its forward speed per unit of slip, the feedforward included) whose weight is the largest
|factor| of each family; the vertices of a delay vertex and its within-period vertices share one
multiplier.  What remains assumed: with theta_bar = 0, the kinematic terms of second order in the errors
(docs/theory.md §2); without ``within_period``, slip constant within a period.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .nonlinear import KinematicChannels
from .vertices import Vertex

__all__ = ["Turns", "turning_vertices", "turning_heading", "heading_yaw_columns", "straight_delta", "arc_ranges", "FEEDFORWARD",
           "linearized_arc_period"]

FEEDFORWARD = np.array([0.0, 1.0])  # the command (dV, omega) of one rad/s of reference yaw rate


@dataclass(frozen=True)
class Turns:
    """The reference yaw rates a certificate covers: ``|w_k| <= max_yaw_rate`` [rad/s], constant on
    each sampling period, ``|w_k - w_{k-1}| <= max_step`` [rad/s]."""

    max_yaw_rate: float
    max_step: float
    # one arc channel per (channel row, error row): a family's factor and the other family's turned twin
    # merged (the same set of values, half the channels); False: the layout of certificates made before
    # (docs/theory.md §10), kept to re-check them
    merged: bool = True

    def next_yaw_rates(self, w: np.ndarray) -> np.ndarray:
        """The yaw rates the reference may take on the period after one at ``w`` (...): w and a step of max_step
        either way, within +-max_yaw_rate, (..., 3) (clipped ones repeat)."""
        return np.clip(np.asarray(w, dtype=float)[..., None] + self.max_step * np.array([-1.0, 0.0, 1.0]),
                       -self.max_yaw_rate, self.max_yaw_rate)

    def step_bounds(self, n_cmd: int) -> np.ndarray:
        """b_j = max |w_k - w_{k-j}| for j = 1..n_cmd-1."""
        return np.array([min(j * self.max_step, 2.0 * self.max_yaw_rate) for j in range(1, n_cmd)])


def _slot_coef(C: np.ndarray, D: np.ndarray, j: int, n_e: int, n_u: int) -> np.ndarray:
    """The coefficients (rows of C, D) on command j (0: the new command, else stored slot j - 1)."""
    return D if j == 0 else C[:, n_e + (j - 1) * n_u : n_e + j * n_u]


def arc_ranges(phi_bar: float, theta_bar: float = 0.0) -> dict[str, tuple[float, float]]:
    """Centre and half-width of each family's factor for |w s| <= phi_bar and |eta| <= theta_bar (the
    module's docstring; 0: the linearization): turn_y and turn_x per unit of V^D, and the rotation's
    ``rot_cos`` (cos phi - 1) and ``rot_sin`` (sin phi)."""
    p, t = float(phi_bar), float(theta_bar)
    if not (0.0 <= p <= np.pi / 2.0 and 0.0 <= t <= 1.0):
        raise ValueError(f"arc factor ranges: w_bar Ts = {p:g} rad must be in [0, pi/2] and theta_bar = {t:g} in [0, 1]")
    one_minus_cos_p = 2.0 * np.sin(p / 2.0) ** 2  # 1 - cos phi_bar without cancellation
    sin_p = float(np.sin(p))
    sinc_t = float(np.sin(t) / t) if t > 0.0 else 1.0
    c_t = 2.0 * float(np.sin(t / 2.0)) ** 2 / t if t > 0.0 else 0.0  # (1 - cos t) / t
    gap = one_minus_cos_p + float(np.cos(p)) * (1.0 - sinc_t)  # 1 - cos phi_bar sinc theta_bar
    s = min(p + t, np.pi / 2.0)
    one_minus_cos_s = 2.0 * float(np.sin(min(p + t, np.pi) / 2.0)) ** 2
    return {
        "turn_y": (-gap / 2.0, gap / 2.0 + sin_p * c_t),
        "turn_x": (0.0, sin_p + c_t),
        "speed_y": (0.0, float(np.sin(s))),
        "speed_x": (-one_minus_cos_s / 2.0, one_minus_cos_s / 2.0),
        "rot_cos": (-one_minus_cos_p / 2.0, one_minus_cos_p / 2.0),
        "rot_sin": (0.0, sin_p),
    }


def _row_families(r: int, n_turn: int, n_lat_from: int | None = None) -> tuple[str, str]:
    """The arc factor families of channel row ``r`` into e_y and e_x: the turn rows' (``r < n_turn``, per
    unit of V^D), the speed rows', or (``r >= n_lat_from``) the icr model's lateral rows': ``v_y (cos(psi + eta)
    - 1)`` into e_y has speed_x's range, ``-v_y sin(psi + eta)`` into e_x speed_y's."""
    if r < n_turn:
        return ("turn_y", "turn_x")
    if n_lat_from is not None and r >= n_lat_from:
        return ("speed_x", "speed_y")
    return ("speed_y", "speed_x")


def _with_twins(wy: float, wx: float, s_half: float) -> dict[int, float]:
    """One channel's weight into e_y (1) and e_x (0): its own factor's into that row plus the turned twin
    (``s_half`` times) of the other row's (independent factors in [-1, 1]: the sum is the same set)."""
    return {1: wy + s_half * wx, 0: wx + s_half * wy}


def _arc_weights(r: int, n_turn: int, V: float, rng: dict[str, tuple[float, float]], s_half: float,
                 n_lat_from: int | None = None) -> dict[int, float]:
    """The weight of channel row ``r``'s arc factors into e_x (0) and e_y (1): its families' half-widths
    with their turned twins (:func:`_with_twins`); turn rows per unit of V^D."""
    y, x = _row_families(r, n_turn, n_lat_from)
    k = V if r < n_turn else 1.0
    return {row: k * w for row, w in _with_twins(rng[y][1], rng[x][1], s_half).items()}


def _max_abs(rng: dict[str, tuple[float, float]], name: str) -> float:
    """The largest |factor| of a family: |centre| + half-width."""
    centre, half = rng[name]
    return abs(centre) + half


def _parts(v: Vertex, ch: KinematicChannels, M11: float, turns: Turns, Ts: float, V: float, n_e: int, n_u: int,
           d_hi: int, theta_bar: float = 0.0, g: np.ndarray = FEEDFORWARD):
    """The unscaled augmented data of one vertex: (A, B, E, C_q, D_q, F_q, B_p).  ``ch``: the channels, built
    at a slip whose ``M(mu)[1, 1] = M11`` (> 0): the vertex's own slip corner, or the box's centre for the
    channels that cover slip changing within a period (``ch.n_dev`` > 0: their deviation channels, one
    per track and command, come after the rotation's, each into e_y and e_x with the other's turned twin);
    ``theta_bar`` > 0: for the nonlinear robot with |eta(t)| <= theta_bar."""
    n_s = v.A.shape[0]
    n_cmd = d_hi + 1
    wbar = float(turns.max_yaw_rate)
    b = turns.step_bounds(n_cmd)
    rng = arc_ranges(wbar * Ts, theta_bar)
    c_mid, c_half = rng["rot_cos"]
    s_half = rng["rot_sin"][1]
    g = np.asarray(g, dtype=float)  # the feedforward command per rad/s of reference yaw rate
    A, B = np.array(v.A, dtype=float), np.array(v.B, dtype=float)
    # the feedforward of command j reaches the error rows as a command does (not the stored commands)
    ff = [np.concatenate([_slot_coef(A, B, j, n_e, n_u)[:n_e] @ g, np.zeros(n_s - n_e)]) for j in range(n_cmd)]
    ref = np.zeros(n_s)
    ref[1], ref[2] = V * Ts**2 / 2.0, Ts
    cols = [wbar * (sum(ff) - ref)] + [-b[j - 1] * ff[j] for j in range(1, n_cmd)]
    E = np.column_stack([np.asarray(v.E, dtype=float)] + cols)
    # the kinematic channels' rows (and the deviation ones'), with the feedforward in their disturbance
    # columns: turn rows W_j (omega_j - w_k) (W_j from the row's own coefficient on command j: W_j M(mu)[1],
    # M[1, 1] > 0), speed rows len_j a_j, deviation rows f_ij (track i's forward speed per unit of slip)
    n_dev, n_lin = ch.n_dev, ch.n_lin
    Cc = np.vstack([ch.C] + ([ch.C_dev] if n_dev else []) + ([ch.C_lin] if n_lin else [])).astype(float)
    Dc = np.vstack([ch.D] + ([ch.D_dev] if n_dev else []) + ([ch.D_lin] if n_lin else [])).astype(float)
    n_f = ch.F.shape[1]
    Fc = np.zeros((Cc.shape[0], E.shape[1]))
    Fc[:, :n_f] = np.vstack([ch.F] + ([ch.F_dev] if n_dev else []) + ([ch.F_lin] if n_lin else []))
    for j in range(n_cmd):
        coef = _slot_coef(Cc, Dc, j, n_e, n_u)  # (rows, n_u)
        resp = coef @ g
        Fc[:, n_f] += wbar * resp
        if j:
            Fc[:, n_f + j] += -b[j - 1] * resp
    n_main = ch.C.shape[0]
    lat_from = ch.n_turn + ch.n_speed
    turn, speed, lat = slice(0, ch.n_turn), slice(ch.n_turn, lat_from), slice(lat_from, n_main)
    for j in range(n_cmd):  # - W_j w_k, with W_j = (W_j M[1, 1]) / M[1, 1]
        row = 1 + j
        Fc[row, n_f] -= wbar * _slot_coef(Cc, Dc, j, n_e, n_u)[row, 1] / M11
    # the families: channel rows, the error row they enter, the factor's scale (V^D on the turn rows), its range
    fams = ((turn, 1, V, rng["turn_y"]), (turn, 0, V, rng["turn_x"]), (speed, 1, 1.0, rng["speed_y"]),
            (speed, 0, 1.0, rng["speed_x"]), (lat, 1, 1.0, rng["speed_x"]), (lat, 0, 1.0, rng["speed_y"]))
    # the factors' centres into the map before the rotation
    A_in, B_in, E_in = A.copy(), B.copy(), E.copy()
    for rows, row, k, (centre, _) in fams:
        if centre:
            A_in[row] += k * centre * Cc[rows].sum(axis=0)
            B_in[row] += k * centre * Dc[rows].sum(axis=0)
            E_in[row] += k * centre * Fc[rows].sum(axis=0)
    # channels: q = (C, D, F) rows, p into one row of e with a weight
    chans: list[tuple[np.ndarray, np.ndarray, np.ndarray, int, float]] = []
    # the arc's (before the rotation): each family's factor into its row, and its turned twin into the other
    # (weight sin phi_bar); the contributions of one channel row into one error row, all with independent
    # factors in [-1, 1], are one channel whose weight is their sum (the same set of values, half the channels)
    if turns.merged:
        for r in range(n_main):
            into_w = _arc_weights(r, ch.n_turn, V, rng, s_half, lat_from)
            chans += [(Cc[r], Dc[r], Fc[r], 1, into_w[1]), (Cc[r], Dc[r], Fc[r], 0, into_w[0])]
    else:  # per family, each channel and its twin apart
        for rows, into, k, (_, half) in fams:
            for r in range(n_main)[rows]:
                chans += [(Cc[r], Dc[r], Fc[r], into, k * half), (Cc[r], Dc[r], Fc[r], 1 - into, k * half * s_half)]
    # the rotation: q = the map's (e_x, e_y) rows before it (centres included)
    for src in (0, 1):
        chans += [(A_in[src], B_in[src], E_in[src], src, c_half), (A_in[src], B_in[src], E_in[src], 1 - src, s_half)]
    # slip changing within the period (docs/theory.md §10, "Slip that changes within a period"): track i's
    # deviation dmu_i(t) from the centre slip, |dmu_i| <= half_i, under command j moves the robot by f_ij dmu_i
    # and turns it by kappa_i f_ij dmu_i; its share of int a F_s is at most half_i max|F_s| len_j |f_ij|, of
    # int eta F_t at most half_i max|F_t| |kappa_i| W_j |f_ij|: the weights on q (with the turned twin of the
    # other row's, as above), half_i on p
    lat_dev = ch.lat_dev_or_zero()
    for r in range(n_dev):
        row = n_main + r
        wy, wx = (float(ch.len_dev[r]) * _max_abs(rng, sp) + float(ch.W_dev[r]) * V * _max_abs(rng, tn)
                  + float(lat_dev[r]) * _max_abs(rng, lt)
                  for sp, tn, lt in (("speed_y", "turn_y", "speed_x"), ("speed_x", "turn_x", "speed_y")))
        half = float(ch.half_dev[r])
        weights = _with_twins(wy, wx, s_half)
        for into in (1, 0):
            wq = weights[into]
            chans.append((wq * Cc[row], wq * Dc[row], wq * Fc[row], into, half))
    # the icr model's linear deviation channels (slip changing within the period, docs/theory.md §12): into the
    # map before the rotation, e_x and e_y each with its turned twin, e_theta as it is
    for r in range(n_lin):
        row = n_main + n_dev + r
        into, wgt = int(ch.lin_target[r]), float(ch.lin_weight[r])
        chans.append((Cc[row], Dc[row], Fc[row], into, wgt))
        if into in (0, 1):
            chans.append((Cc[row], Dc[row], Fc[row], 1 - into, s_half * wgt))
    Bp = np.zeros((n_s, len(chans)))
    for k, (_, _, _, target, wgt) in enumerate(chans):
        Bp[target, k] = wgt
    Cq, Dq, Fq = (np.array([ch[i] for ch in chans]) for i in range(3))
    A_out, B_out, E_out = A_in.copy(), B_in.copy(), E_in.copy()
    for X in (A_out, B_out, E_out):
        X[:2] *= 1.0 + c_mid
    return A_out, B_out, E_out, Cq, Dq, Fq, Bp


def turning_vertices(model, turns: Turns, theta_bar: float | None = None, within_period: bool = False,
                     icr_channels: bool = False) -> tuple[tuple[Vertex, ...], tuple[Vertex, ...]]:
    """The linearized model's vertices (``model.base_vertices``, with their kinematic channels
    ``model.channels``) augmented for ``turns``, for the nonlinear robot with |eta(t)| <= ``theta_bar``
    (None: the linearization); one scale per channel, common to every vertex (B_p enters the LMIs
    quadratically and must be the same at every vertex).  And ``()``, or with ``within_period`` (the model
    must have ``covering``): every vertex with its delay vertex's channels for slip changing within a
    period (``model.covering``, built at the box's centre, one multiplier per delay vertex: ``group``), and
    the within-period vertices (``model.varying``) augmented alike (docs/theory.md §10); for the icr model with a
    ``theta_bar`` its own (``Model.within_period_cover``, ``icr_channels`` as there)."""
    if not model.channels or len(model.channels) != len(model.base_vertices):
        raise ValueError("turning references need the delay vertices and their kinematic channels")
    if within_period and not model.covering:
        raise ValueError("slip changing within a period on arcs needs the model's covering channels")
    tb = float(theta_bar or 0.0)
    covering, varying, varying_delay = model.within_period_cover(theta_bar is not None, icr_channels)
    n_d = len(covering)
    if within_period:
        lo, hi = (np.array([r[k] for r in model.slip_ranges[:2]], dtype=float) for k in (0, 1))
        # the covering channels are built at the box's centre (the icr model's: at its centre twist)
        M11 = covering[0].turn_gain or _turn_gain(model, (lo + hi) / 2.0)
        jobs = [(v, covering[i % n_d], M11, i % n_d) for i, v in enumerate(model.base_vertices)]
        jobs += [(v, covering[t], M11, t) for v, t in zip(varying, varying_delay)]
    else:
        jobs = [(v, ch, _turn_gain(model, model.corners[v.corner]), -1)
                for v, ch in zip(model.base_vertices, model.channels)]
    parts = []
    for v, ch, M11, _ in jobs:
        if v.n_q:
            raise ValueError("turning references need vertices without uncertainty channels")
        if ch.F.shape[1] != np.asarray(v.E).shape[1]:
            raise ValueError("the channels' constant column does not match the vertex's")
        parts.append(_parts(v, ch, M11, turns, model.Ts, model.V, model.n_e, model.n_u, model.d_hi, tb,
                            model.turn_feedforward))
    Bp = parts[0][6]
    if any(not np.array_equal(p[6], Bp) for p in parts):
        raise ValueError("B_p differs between vertices")
    n_base = len(model.base_vertices)
    rows = np.max([np.max(np.abs(np.hstack(p[3:6])), axis=1) for p in parts[:n_base]], axis=0)
    cols = np.max(np.abs(Bp), axis=0)
    ok = (rows > 0) & (cols > 0)
    scale = np.where(ok, np.sqrt(np.where(ok, rows, 1.0) / np.where(ok, cols, 1.0)), 1.0)
    out = []
    for (v, _, _, group), (A, B, E, Cq, Dq, Fq, Bp_v) in zip(jobs, parts):
        out.append(Vertex(A, B, E, Bp_v * scale, Cq / scale[:, None], Dq / scale[:, None], v.corner, v.label,
                          Fq / scale[:, None], True, group, v.instants))
    if within_period and model.icr and not varying:  # the icr channels cover every slip history on the constant-slip vertices
        return tuple(out[:n_base]), tuple(out[:n_base])
    return tuple(out[:n_base]), tuple(out[n_base:])


def heading_yaw_columns(ch: KinematicChannels, turns: Turns, n_e: int, n_u: int, d_hi: int,
                        g: np.ndarray = FEEDFORWARD) -> np.ndarray:
    """The heading rows' coefficients on the reference's yaw-rate coordinates (columns w_k / w_bar and
    (w_k - w_{k-j}) / b_j): eta = e_theta - w_k s at a break point is the straight row plus
    ``sum_j l_j M11_j w_{k-j} - t w_k``, l_j the time command j has acted by then (the row's coefficient on
    the command's turn rate is ``l_j M11_j``, M11_j = M(mu)[1, 1] at the slip of its interval) and t the
    time elapsed (``ch.elapsed_h``)."""
    wbar = float(turns.max_yaw_rate)
    b = turns.step_bounds(d_hi + 1)
    resp = np.stack([_slot_coef(ch.C_h, ch.D_h, j, n_e, n_u) @ np.asarray(g, dtype=float) for j in range(d_hi + 1)],
                    axis=1)
    elapsed = np.asarray(ch.elapsed_h, dtype=float)  # (rows,)
    F_h = np.zeros((resp.shape[0], d_hi + 1))
    F_h[:, 0] = wbar * (resp.sum(axis=1) - elapsed)  # w_{k-j} = w_k - (w_k - w_{k-j})
    F_h[:, 1:] = -b * resp[:, 1:]
    return F_h


def turning_heading(model, turns: Turns) -> tuple[tuple[KinematicChannels, ...], ...]:
    """``model.channels``, ``model.covering`` and ``model.icr_covering`` with their heading rows' yaw-rate
    coefficients (``F_h``: :func:`heading_yaw_columns`)."""
    from dataclasses import replace

    def add(chs):
        return tuple(replace(ch, F_h=heading_yaw_columns(ch, turns, model.n_e, model.n_u, model.d_hi, model.turn_feedforward))
                     for ch in chs)

    return add(model.channels), add(model.covering), add(model.icr_covering)


def _turn_gain(model, mu: np.ndarray) -> float:
    """M(mu)[1, 1] at the slip ``mu`` = (mu_r, mu_l, ...): the turn rate the robot gets per unit of commanded
    turn rate."""
    from .slip import slip_matrix

    # (the icr model's yaw factor included: slip_matrix scales the yaw row by it)
    return float(slip_matrix(np.asarray(mu, dtype=float), float(model.config.robot.track_distance))[1, 1])


def straight_delta(ch: KinematicChannels, phi_bar: float, theta_bar: float = 0.0, merged: bool = True) -> np.ndarray:
    """diag(Delta) at which a turning vertex (for ``phi_bar = w_bar Ts`` and ``theta_bar``) is the
    linearized straight one again (w = 0, every factor 0): on each arc channel minus its family's centre
    over the channel's weight (the twin's share included; ``merged``: :attr:`Turns.merged`), on the
    rotation's minus cos's centre over its half-width (0 for sin), 0 on the deviation channels; in
    :func:`_parts`' order."""
    rng = arc_ranges(phi_bar, theta_bar)
    s_half = rng["rot_sin"][1]

    def at_zero(centre: float, weight: float) -> float:
        return -centre / weight if weight > 0.0 else 0.0

    out = []
    if merged:
        lat_from = ch.n_turn + ch.n_speed
        for r in range(ch.C.shape[0]):
            w = _arc_weights(r, ch.n_turn, 1.0, rng, s_half, lat_from)  # per unit of the row's scale, as the centres
            y, x = _row_families(r, ch.n_turn, lat_from)
            out += [at_zero(rng[y][0], w[1]), at_zero(rng[x][0], w[0])]
    else:
        n_t, n_v = ch.n_turn, ch.C.shape[0] - ch.n_turn
        for n, name in zip((n_t, n_t, n_v, n_v), ("turn_y", "turn_x", "speed_y", "speed_x")):
            out += [at_zero(*rng[name]), 0.0] * n  # each with its twin
    c_mid, c_half = rng["rot_cos"]
    out += [at_zero(c_mid, c_half), 0.0] * 2  # the rotation: cos - 1 and sin per row
    out += [0.0] * (2 * ch.n_dev)  # slip's deviations within the period: none on a straight segment at constant slip
    out += [0.0] * sum(2 if int(t) in (0, 1) else 1 for t in (ch.lin_target if ch.n_lin else ()))
    return np.array(out)


GAUSS_NODES = 8  # Gauss-Legendre nodes per command interval: cos/sin(w s) times an affine function, exact to round-off


def linearized_arc_period(model, xi: np.ndarray, du: np.ndarray, S: np.ndarray, mu: np.ndarray,
                          w: np.ndarray, homogeneous: bool = False) -> np.ndarray:
    """The error at t_{k+1}, in the frame of the reference at t_{k+1}, of the kinematics linearized about the
    reference's arc (docs/theory.md §10, "One period, exactly"), evaluated directly rather than bounded: the
    model a linearized turning certificate is for.  ``xi`` (..., n_s) the lifted state at t_k, ``du`` (..., 2) the
    new correction, ``S`` (..., d_hi) the switching instants, ``mu`` (..., 2) the slip (the tracks model; (..., 4) the
    icr model's parameters), ``w`` (..., d_hi + 1) the reference's yaw rates w_k, w_{k-1}, ..., w_{k-d_hi} (command j
    carries the feedforward w_{k-j} g, ``Model.turn_feedforward``).  Returns (..., 3).

    In the frame F_k of the reference at t_k (origin, heading 0, moving at V^D and yaw rate w_k) the robot's
    heading is ``w_k s + eta(s)``, its speed ``V^D + a`` and (icr) its lateral velocity v_y; to first order in
    (eta, a, v_y)

        d/ds (x - x_ref) = a cos(w_k s) - V^D sin(w_k s) eta - v_y sin(w_k s),
        d/ds (y - y_ref) = a sin(w_k s) + V^D cos(w_k s) eta + v_y cos(w_k s),

    with ``eta`` piecewise linear (slope omega_j - w_k on command j's interval) and ``a``, ``omega_j`` exact in the
    slip, (a_j, omega_j) = M(mu)(u^D + du_{k-j} + (0, w_{k-j})) - (V^D, 0).  The integrals are taken by
    Gauss-Legendre quadrature on each command's interval; the change of frame to F_{k+1} (turned by w_k Ts) is
    exact.  With w = 0 this is the straight lifted map (:meth:`~.model.Model.robot_exact` and the constant).
    ``homogeneous``: the map's linear part only, the same operator (it depends on w_k, the slip and the delays)
    without the nominal commands, the feedforward and the reference's turn: the map less its value at xi = 0,
    du = 0, without the cancellation that subtracting them would cost near 0."""
    from .slip import twist_matrix

    n_e, n_u, d_hi, V, Ts = model.n_e, model.n_u, model.d_hi, model.V, model.Ts
    mu = np.asarray(mu, dtype=float)
    if mu.shape[-1] not in (2, 4):
        raise ValueError("linearized_arc_period: mu holds the tracks model's (mu_r, mu_l) or the icr model's four parameters")
    xi, du, S, w = (np.asarray(a, dtype=float) for a in (xi, du, S, w))
    if w.shape[-1] != d_hi + 1:
        raise ValueError(f"linearized_arc_period: w holds w_k, ..., w_(k-d_hi): {d_hi + 1} yaw rates, got {w.shape[-1]}")
    lead = xi.shape[:-1]
    past = xi[..., n_e : n_e + d_hi * n_u].reshape(lead + (d_hi, n_u))
    u = np.concatenate([du[..., None, :], past], axis=-2)
    if not homogeneous:
        u = np.array([V, 0.0]) + u + w[..., :, None] * model.turn_feedforward
    # (v_x, v_y, omega) of each command (v_y = 0 for the tracks model; the icr model's lateral slide, §12)
    vel = np.einsum("...ij,...kj->...ki", twist_matrix(mu, model.config.robot.track_distance), u)
    wk = w[..., 0]
    # each command's a_j, v_y,j and omega_j - w_k, (..., d_hi + 1); their linear parts only when homogeneous
    a, vy = (vel[..., 0], vel[..., 1]) if homogeneous else (vel[..., 0] - V, vel[..., 1])
    turn = vel[..., 2] if homogeneous else vel[..., 2] - wk[..., None]
    x_gl, w_gl = np.polynomial.legendre.leggauss(GAUSS_NODES)
    ex, ey, eta = xi[..., 0], xi[..., 1], xi[..., 2]
    start = np.zeros(lead)
    for j in range(d_hi, -1, -1):  # command j acts on [s~_j, s~_{j-1}), s~_{d_hi} = 0, s~_{-1} = Ts
        end = S[..., j - 1] if j > 0 else np.full(lead, Ts)
        h = end - start
        s = start[..., None] + h[..., None] * (x_gl + 1.0) / 2.0
        slope = turn[..., j, None]
        et = eta[..., None] + slope * (s - start[..., None])
        c, sn = np.cos(wk[..., None] * s), np.sin(wk[..., None] * s)
        weight = h[..., None] / 2.0 * w_gl
        ex = ex + np.sum(weight * (a[..., j, None] * c - V * sn * et - vy[..., j, None] * sn), axis=-1)
        ey = ey + np.sum(weight * (a[..., j, None] * sn + V * c * et + vy[..., j, None] * c), axis=-1)
        eta = eta + slope[..., 0] * h
        start = end
    phi = wk * Ts
    cp, sp = np.cos(phi), np.sin(phi)
    return np.stack([cp * ex + sp * ey, -sp * ex + cp * ey, eta], axis=-1)
