"""The certified figures on the invariant set of an ultimate-bound certificate, beyond the sampled
ellipsoid bounds: the largest value a row of the state takes on the set (:func:`set_max`,
:func:`sup_on_set`), |e_theta(t)| within every period (:func:`heading_within_period`) and the errors
between the samples (:func:`between_samples`; docs/theory.md §6i, §9-§12).  Every figure is rounded
outwards."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..verified import gamma, round_up

__all__ = ["heading_within_period", "set_max", "sup_on_set", "between_samples"]


def heading_within_period(model: Any, K: np.ndarray, mats: list[np.ndarray], level: float, inner: int = 1) -> float:
    """An upper bound on |e_theta(t)| for t in every period, over the set {V <= level}: e_theta is
    piecewise linear in t, so its extremes are at the break points, ``r xi + g`` (r = C_h + D_h K) at
    each vertex; the supremum over the set is ``|g| + sqrt(level r S r')`` (its rounding bound added),
    convex in (r, g), so the vertices' largest covers every delay and slip.  On a turning model the rows
    also carry the reference's yaw-rate coordinates (``F_h``, each in [-1, 1]: model/arcs.turning_heading),
    which add ``sum |F_h|``, convex in them too."""
    n = K.shape[0] + 2 * model.n_s + 4
    g = gamma(n)
    out = 0.0
    for ch in model.heading_channels:
        R = ch.C_h + ch.D_h @ K
        aR = np.abs(ch.C_h) + np.abs(ch.D_h) @ np.abs(K)
        q = np.array([_form_upper(R, aR, S, g) for S in mats])  # (n_mats, n_rows)
        off = ch.heading_offsets  # |g|, plus a turning reference's sum |F_h|
        for i in range(q.shape[1]):
            val = float(off[i]) * (1 + g) + np.sqrt(max(level * set_max(q[:, i], inner), 0.0))
            out = max(out, float(val))
    return round_up(out, 8)  # the product with level, the square root and the sum


def _form_upper(R: np.ndarray, aR: np.ndarray, S: np.ndarray, g: float) -> np.ndarray:
    """r S r' for every row r of R, plus its rounding bound g (1 + g) |r| |S| |r|' (aR: the rows'
    magnitudes, which bound their own rounding when they were computed)."""
    return np.einsum("ij,jk,ik->i", R, S, R) + g * (1 + g) * np.einsum("ij,jk,ik->i", aR, np.abs(S), aR)


def set_max(q: np.ndarray, inner: int = 1) -> float:
    """An upper bound on ``max c S(mu, ...) c'`` that the set {V <= level} allows, from ``q[j]`` >= c S_j c'
    (one per Lyapunov matrix, in the certificate's order), ``|c xi|^2 <= level * set_max(q)`` on it
    (docs/theory.md §6i).

    ``inner``: how many consecutive matrices V takes its maximum over (the delay vertices d of a
    delay- or path-dependent certificate, 1 otherwise).  On the set, ``xi' S(mu, d)^-1 xi <= level`` for
    every d, so ``|c xi|^2 <= level sum_d theta_d c S(mu, d) c'`` for any convex weights theta, and
    ``c S(mu, d) c'`` is a convex combination of the corners' (and previous delay vertices') values: the
    bound is ``min_theta max_outer sum_d theta_d q[outer, d]`` (a small linear program), never above
    ``min_d max_outer q`` nor the largest q.  Any theta gives a valid bound, so the program's accuracy
    only decides how tight it is; the value is evaluated at its theta and rounded up."""
    q = np.maximum(np.asarray(q, dtype=float).reshape(-1, inner), 0.0)
    best = float(np.min(np.max(q, axis=0)))  # theta a unit vector: min over d of max over the rest
    if inner > 1 and q.shape[0] > 1:
        from scipy.optimize import linprog

        n_o = q.shape[0]
        # min s  s.t.  q theta - s <= 0, sum theta = 1, theta >= 0
        res = linprog(np.r_[np.zeros(inner), 1.0], A_ub=np.c_[q, -np.ones(n_o)], b_ub=np.zeros(n_o),
                      A_eq=np.r_[np.ones(inner), 0.0][None, :], b_eq=[1.0],
                      bounds=[(0, None)] * inner + [(None, None)], method="highs")
        if res.status == 0:
            theta = np.maximum(res.x[:inner], 0.0)
            total = float(np.sum(theta))
            if total > 0:
                # sum(theta q) / sum(theta): weights that sum to one whatever the rounding of theta
                val = round_up(float(np.max(q @ theta)) / total, 2 * inner + 2)  # dot products, sum, division
                best = min(best, val)
    return best


def sup_on_set(rows: np.ndarray, mats: list[np.ndarray], level: float, inner: int = 1) -> float:
    """max over the rows r of the largest |r xi| on the set, sqrt(level * set_max(r S r')), with the
    rounding of r S r' added (``inner``: :func:`set_max`)."""
    g = gamma(2 * rows.shape[1] + 4)
    q = np.array([_form_upper(rows, np.abs(rows), S, g) for S in mats])  # (n_mats, n_rows)
    top = max(set_max(q[:, i], inner) for i in range(q.shape[1]))
    return float(np.sqrt(max(round_up(level * top), 0.0)))


def between_samples(model: Any, K: np.ndarray, mats: list[np.ndarray], level: float, sampled: dict[str, float],
                    heading: float | None, inner: int = 1, within_period: bool = False,
                    chord: dict[str, float] | None = None) -> dict[str, float | None]:
    """Bounds on |e_x(t)|, |e_y(t)|, |e_theta(t)| for every t, not only at the sampling instants
    (docs/theory.md §9).  Both ends of a period lie in the set, so within it each error is at most
    its sampled bound plus its distance from the chord between the ends, which is at most
    ``Ts^2/8 sup|f''| + Ts/4 sum |jumps of f'|`` (the Green's function of f'' on [0, Ts] lies in
    [0, Ts/4] and integrates to at most Ts^2/8).  On the exact arcs ``e_y' = v sin e_theta`` and
    ``e_x' = v cos e_theta - V`` (``f'' = +-v omega cos/sin``, jumps ``|dv|`` times sin / cos at the d_hi
    switching instants); on the linearization ``e_y' = V e_theta`` (``f'' = V omega``, no jumps) and
    ``e_x' = a`` (only jumps); with the icr slip model e_y' also holds v_y, whose jumps add to e_y's (where
    it may jump at any time, its oscillation over the period: :func:`_lateral_oscillation`).
    v, omega and the jumps dv of the commands in flight are bounded on the set at every slip corner
    (multi-affine in the slip).  e_theta(t): :func:`heading_within_period`.

    ``chord`` (a dict, filled): what the chord terms add to the sampled bounds, each at its own worst (on e_x and
    e_y): the most any error rises above the larger end of its period.  Where the terms are joined to the start
    (:func:`_chord_joined`) the bounds for all t are smaller than the sampled ones plus these.

    ``within_period``: slip may also change within the period (docs/theory.md §11).  Then e_x' = a(t)
    jumps wherever the slip does, and the chord distance is bounded by ``Ts/4 (sup a - inf a)`` over
    the period instead (for f' in [m, M]: |f(t) - chord(t)| <= t (Ts - t) / Ts (M - m)): the largest
    difference of a between any two slip corners and any two commands in flight, on the set.  e_y'' =
    V omega(t) is bounded pointwise, whatever the slip does.  On the exact arcs (a nonlinear
    certificate) e_y' = V sin e_theta + a sin e_theta: the first part has a bounded f'', the second
    (a jumps with the slip) is bounded by its range; e_x' likewise."""
    n_s, n_e, n_u, d_hi = model.n_s, model.n_e, model.n_u, model.d_hi
    Ts, V = model.Ts, model.V
    cmds = [np.asarray(K, dtype=float)]
    for j in range(1, d_hi + 1):
        E = np.zeros((n_u, n_s))
        E[:, n_e + (j - 1) * n_u : n_e + j * n_u] = np.eye(n_u)
        cmds.append(E)
    if getattr(model, "turns", None) is not None:
        return _between_samples_on_arcs(model, cmds, mats, level, sampled, heading, inner, within_period, chord)
    vbar, wbar, dvbar, abar = _speeds_on_set(model, cmds, mats, level, inner)
    h = min(float(heading if heading is not None else 0.0), np.pi / 2)
    one_minus_cos, vy = 2.0 * float(np.sin(h / 2.0)) ** 2, 0.0  # (vy: the largest |v_y| where the icr model has it)
    if model.heading_bound is not None:
        s = float(np.sin(h))
        ey = Ts * Ts / 8 * vbar * wbar + Ts / 4 * d_hi * dvbar * s
        ex = Ts * Ts / 8 * vbar * wbar * s + Ts / 4 * d_hi * dvbar
    else:
        ey = Ts * Ts / 8 * V * wbar
        ex = Ts / 4 * d_hi * dvbar
    if within_period:
        osc = _forward_oscillation(model, cmds, mats, level, inner)
        ex = Ts / 4 * osc
        if model.heading_bound is not None:
            # the exact arcs, split so that only the parts in which a = v - V (which jumps with the slip)
            # appears are bounded by their ranges: e_y' = V sin e_theta + a sin e_theta, the first with
            # |f''| = |V cos e_theta omega| <= V wbar, the second in +-abar s; e_x' = a - V (1 - cos e_theta)
            # - a (1 - cos e_theta): a ranges over osc, the second has |f''| <= V s wbar, the third is in
            # +-abar (1 - cos)
            ey = Ts * Ts / 8 * V * wbar + Ts / 4 * 2.0 * abar * s
            ex = Ts / 4 * osc + Ts * Ts / 8 * V * s * wbar + Ts / 4 * 2.0 * abar * one_minus_cos
    if model.icr and (within_period or model.heading_bound is not None):
        # the lateral velocity v_y = row(p) u (docs/theory.md §12): e_y' gets v_y cos e_theta, e_x' -v_y sin e_theta;
        # slip changing within the period (or a heading that turns it) makes it jump at any time, so each part is
        # bounded by its range: |f - chord| <= Ts/4 (sup f' - inf f') <= Ts/4 2 vy_bar (times sin for e_x)
        # (for e_y its oscillation plus what cos e_theta takes off its size: |v1 c1 - v2 c2| <= |v1 - v2| + |v2| (1 -
        # cos); the sign of v_y is the command's, so where x_icr = 0 is in the box that is about half of 2 vy_bar)
        vy, range_y = _lateral_ranges(model, cmds, mats, level, inner, 0.0, one_minus_cos)
        ey += Ts / 4 * range_y
        ex += Ts / 4 * 2.0 * vy * float(np.sin(h))
    elif model.icr:  # e_y' also holds the lateral velocity v_y = row(p) u: its jumps at the switching instants
        dvy = max(sup_on_set(np.array([model.lateral_row(mu) @ (cmds[j] - cmds[j + 1]) for j in range(d_hi)]), mats,
                             level, inner) for mu in np.asarray(model.corners))
        ey += Ts / 4 * d_hi * dvy
    if chord is not None:  # the chord terms each at its worst
        chord.update(e_x=round_up(ex, 4), e_y=round_up(ey, 4))
    if within_period:  # the same terms joined to the start's errors (:func:`_chord_joined`): the smaller bounds
        s = float(np.sin(h)) if model.heading_bound is not None else 0.0
        a_cos = Ts / 4 * 2.0 * abar * one_minus_cos if model.heading_bound is not None else 0.0
        fy, fx = chord_families(model, cmds, 0.0, "e_y"), chord_families(model, cmds, 0.0, "e_x")
        wy, wx = (Ts, Ts * 2.0 * s, Ts * Ts / 2.0 * V), (Ts, Ts * Ts / 2.0 * V * s, Ts * 2.0 * s)
        By, Bx = sampled["e_y"], sampled["e_x"]
        ey = min(ey, _chord_joined(model, fy, wy, mats, level, inner, 1, Ts / 4 * vy * one_minus_cos, By) - By)
        ex = min(ex, _chord_joined(model, fx, wx, mats, level, inner, 0, a_cos, Bx) - Bx)
    return {"e_x": round_up(sampled["e_x"] + ex, 12), "e_y": round_up(sampled["e_y"] + ey, 12),
            "e_theta": heading}


CHORD_INTERVALS = 64  # the intervals of lambda = t / Ts on which _chord_joined bounds |e_x(t)|, |e_y(t)|
CHORD_COARSE = 8  # the points of lambda at which it evaluates J first (J is convex: their chords bound it between)
CHORD_ROWS = (256, 32, 32)  # the most rows of each family (chord_families) _chord_joined joins at once
CHORD_BUDGET = 1_000_000  # the most quadratic forms per sign it evaluates at once (rows fewer with many matrices)


def _chord_joined(model: Any, fams: list[tuple[np.ndarray, np.ndarray]], weights: tuple[float, float, float],
                  mats: list[np.ndarray], level: float, inner: int, row: int, const: float, end: float) -> float:
    """A bound on |f(t)| over the period for f an error component (e_x or e_y: ``row`` of xi; on arcs its part of p -
    p_r in the frame of the reference at t_k) where the slip changes within the period, with the chord terms joined
    to f(0) = xi[row] at t_k rather than added to the larger end (docs/theory.md §12, "the chord terms joined").

    With lambda = t / Ts, ``|f(t)| <= (1 - lambda) |f(0)| + lambda |f(Ts)| + lambda (1 - lambda) X``, where
    ``|f(Ts)| <= end`` (the end lies in the set) and X bounds the chord terms of :func:`between_samples`: X = sum_i
    ``weights[i]`` (max over the rows r of family i of ``|r xi| + c``) + 4 ``const`` (``fams``: :func:`chord_families`;
    ``const``: the terms without a row, at their lambda = 1/2 value).  So ``|f(t)| <= (1 - lambda) J(lambda) + lambda
    end + 4 lambda (1 - lambda) const`` with ``J(lambda) = sup over the set of |f(0)| + lambda (X - 4 const)``: the
    largest over every triple of rows and signs of ``sqrt(level r S r')`` plus the constants, for r = f(0)'s row +- the
    three rows (at most the sum of the separate bounds, smaller where the rows do not align).  J is nondecreasing and
    convex in lambda: it is evaluated at CHORD_COARSE points, their chords bound it between, and each of CHORD_INTERVALS
    intervals is bounded by its affine majorant's larger end with J (or its chord) at the right end; J itself is
    evaluated only where an interval can still be the largest.  Rows beyond ``CHORD_ROWS`` (ranked by their own bound)
    are covered by the sum of the separate bounds.  Rounded outwards."""
    n_s = model.n_s
    rows, consts = zip(*fams)
    e = np.zeros(n_s)
    e[row] = 1.0
    # each row's own bound, to rank them and to cover those left out: sqrt(level r S r') + constant
    own = [np.sqrt(level * _rows_set_max(R, mats, inner)) + c for R, c in zip(rows, consts)]
    sizes = [min(k, o.size) for o, k in zip(own, CHORD_ROWS)]
    while len(mats) * int(np.prod(sizes)) > CHORD_BUDGET and max(sizes) > 1:  # many Lyapunov matrices: fewer rows
        i = int(np.argmax(sizes))
        sizes[i] = max(1, sizes[i] // 2)
    keep = [np.argsort(-o)[:k] for o, k in zip(own, sizes)]
    top = [float(np.max(o)) for o in own]
    rest = [float(np.max(np.delete(o, k))) if o.size > k.size else None for o, k in zip(own, keep)]
    R = np.vstack([e[None]] + [r[k] for r, k in zip(rows, keep)])
    idx = np.cumsum([1] + sizes)
    blocks = [np.arange(idx[i], idx[i + 1]) for i in range(3)]
    kept_c = [c[k] for c, k in zip(consts, keep)]
    e_own = float(np.sqrt(level * _rows_set_max(e[None], mats, inner))[0])
    Gs = np.array([R @ S @ R.T for S in mats])
    Ga = np.array([np.abs(R) @ np.abs(S) @ np.abs(R).T for S in mats])
    gq = 2.0 * gamma(2 * n_s + 16)  # the rounding of G and of the combination below (on |c| |R| |S| |R|' |c|')

    def joined(lam: float) -> float:
        w = [lam * x for x in weights]  # each family's weight in J(lam)
        best = 0.0
        q_round = gq * _triple_form(Ga, blocks, w)  # (n_mats, n0, n1, n2)
        for signs in np.ndindex(2, 2, 2):
            c = [w[i] * (1.0 - 2.0 * signs[i]) for i in range(3)]
            q_up = _triple_form(Gs, blocks, c) + q_round
            val = (np.sqrt(level * np.maximum(_set_max_rows(q_up.reshape(len(mats), -1), inner), 0.0))
                   .reshape(q_up.shape[1:]) + w[0] * kept_c[0][:, None, None] + w[1] * kept_c[1][None, :, None]
                   + w[2] * kept_c[2][None, None, :])
            best = max(best, float(np.max(val)))
        # a triple with a row left out: at most the sum of the separate bounds
        for i in range(3):
            if rest[i] is not None:
                best = max(best, e_own + sum(w[j] * (rest[j] if j == i else top[j]) for j in range(3)))
        return round_up(best, 12)

    def on(lo: float, hi: float, J: float) -> float:  # the bound on [lo, hi] with J >= J(hi)
        peak = 0.25 if lo <= 0.5 <= hi else max(lo * (1 - lo), hi * (1 - hi))
        return max((1 - lo) * J + lo * end, (1 - hi) * J + hi * end) + 4.0 * peak * const

    # J is convex in lambda (a supremum of functions affine in it), so between the points of a coarse grid it is at
    # most their chord: every interval first gets that bound, and J itself is evaluated at the right ends of the
    # intervals whose bound is largest, until the largest left is below the largest evaluated one
    coarse = np.arange(CHORD_COARSE + 1) / CHORD_COARSE
    J_coarse = [joined(float(x)) for x in coarse]
    lams = np.arange(CHORD_INTERVALS + 1) / CHORD_INTERVALS
    J_chord = [round_up(float(np.interp(x, coarse, J_coarse)), 4) for x in lams[1:]]
    left = sorted(((on(float(lams[i]), float(lams[i + 1]), J_chord[i]), i) for i in range(CHORD_INTERVALS)),
                  reverse=True)
    out = 0.0
    for bound, i in left:
        if bound <= out:
            break  # this and every one after it: their chord bounds are below an evaluated one
        out = max(out, on(float(lams[i]), float(lams[i + 1]), min(J_chord[i], joined(float(lams[i + 1])))))
    return round_up(out, 8)


def chord_families(model: Any, cmds: list[np.ndarray], yaw_rate: float, component: str = "e_y"
                   ) -> list[tuple[np.ndarray, np.ndarray]]:
    """The three families of rows and constants whose ``max |r xi| + c`` bound, on a state xi, the chord terms
    :func:`_chord_joined` joins to ``component`` (each with its distinct rows, :func:`_distinct`), with the commands in
    flight ``cmds`` and a turning feedforward |w| <= ``yaw_rate`` in each.  For e_y: the oscillation of v_y (every pair
    of slip corners and of commands in flight), the forward-speed deviation |a| = |v - V^D| and |omega| + ``yaw_rate``
    (the reference's own turn, psi''), at every slip corner and command.  For e_x: the oscillation of a (pairs, as for
    v_y), |omega| and |v_y| at every slip corner and command."""
    V, uD, g = model.V, np.array([model.V, 0.0]), model.turn_feedforward
    corners = np.asarray(model.corners)
    lat = [model.lateral_row(mu) for mu in corners] if model.icr else [np.zeros(model.n_u)]  # (tracks: no v_y)
    fwd = [model.slip_matrix(mu)[0] for mu in corners]
    fam: list[tuple[list, list]] = [([], []), ([], []), ([], [])]
    for ra in (lat if component == "e_y" else fwd):
        for rb in (lat if component == "e_y" else fwd):
            const = abs(float((ra - rb) @ uD)) + (abs(float(ra @ g)) + abs(float(rb @ g))) * yaw_rate
            for ca in cmds:
                for cb in cmds:
                    fam[0][0].append(ra @ ca - rb @ cb)
                    fam[0][1].append(const)
    for mu in corners:
        M = model.slip_matrix(mu)
        for c in cmds:
            omega = (M[1] @ c, abs(float(M[1] @ uD)) + abs(float(M[1] @ g)) * yaw_rate)
            if component == "e_y":
                a = (M[0] @ c, abs(float(M[0] @ uD) - V) + abs(float(M[0] @ g)) * yaw_rate)
                parts = (a, (omega[0], omega[1] + yaw_rate))
            else:
                r = model.lateral_row(mu) if model.icr else np.zeros(model.n_u)
                parts = (omega, (r @ c, abs(float(r @ uD)) + abs(float(r @ g)) * yaw_rate))
            for k, (rw, cst) in enumerate(parts, start=1):
                fam[k][0].append(rw)
                fam[k][1].append(cst)
    return [_distinct(np.array(r, dtype=float), np.array(c, dtype=float)) for r, c in fam]


def _distinct(rows: np.ndarray, consts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct (row, constant) pairs of a family that enters as ``|r xi| + c``: r and -r alike (each row's
    first nonzero entry made positive, which is exact), exact duplicates dropped."""
    first = np.argmax(rows != 0.0, axis=1)
    sign = np.where(rows[np.arange(rows.shape[0]), first] < 0.0, -1.0, 1.0)
    both = np.unique(np.c_[rows * sign[:, None], consts], axis=0)
    return both[:, :-1], both[:, -1]


def _triple_form(G: np.ndarray, blocks: list[np.ndarray], c: list[float]) -> np.ndarray:
    """``(e + c0 r0 + c1 r1 + c2 r2) S (...)'`` for every triple of rows (r0, r1, r2) of the three ``blocks``, from
    their Gram matrices ``G`` (n_mats, n_rows, n_rows) under each S (row 0: e); shape (n_mats, n0, n1, n2)."""
    b0, b1, b2 = blocks
    d = np.diagonal(G, axis1=1, axis2=2)
    x, y, z = (slice(None), None, None), (None, slice(None), None), (None, None, slice(None))

    def one(v: np.ndarray, at: tuple) -> np.ndarray:  # (n_mats, k) placed on its axis
        return v[(slice(None),) + at]

    out = (G[:, 0, 0][:, None, None, None] + c[0] ** 2 * one(d[:, b0], x) + c[1] ** 2 * one(d[:, b1], y)
           + c[2] ** 2 * one(d[:, b2], z) + 2 * c[0] * one(G[:, 0, b0], x) + 2 * c[1] * one(G[:, 0, b1], y)
           + 2 * c[2] * one(G[:, 0, b2], z))
    out += 2 * c[0] * c[1] * G[:, b0][:, :, b1][:, :, :, None]
    out += 2 * c[0] * c[2] * G[:, b0][:, :, b2][:, :, None, :]
    out += 2 * c[1] * c[2] * G[:, b1][:, :, b2][:, None, :, :]
    return out


def _rows_set_max(R: np.ndarray, mats: list[np.ndarray], inner: int) -> np.ndarray:
    """Per row r of R an upper bound of max r S r' on the set (:func:`set_max`'s bound at a unit theta, without its
    linear program), its rounding added."""
    g = gamma(2 * R.shape[1] + 4)
    aR = np.abs(R)
    q = np.array([_form_upper(R, aR, S, g) for S in mats])
    return _set_max_rows(q, inner)


def _set_max_rows(q: np.ndarray, inner: int) -> np.ndarray:
    """:func:`set_max` at the best unit theta, for every column of q (n_mats, n): ``min_d max_outer q``."""
    q = np.maximum(q, 0.0)
    return np.min(np.max(q.reshape(-1, inner, q.shape[-1]), axis=0), axis=0)


def _lateral_on_set(model: Any, cmds: list[np.ndarray], mats: list[np.ndarray], level: float, inner: int,
                    yaw_rate: float = 0.0) -> float:
    """The largest |v_y| of the icr slip model on the set, over every slip corner (v_y is multi-affine in the
    parameters: its extremes over the box, and over any average of slips, are at the corners) and every
    command in flight, with a turning reference's feedforward (0, w), |w| <= ``yaw_rate``."""
    uD = np.array([model.V, 0.0])
    out = 0.0
    for mu in np.asarray(model.corners):
        row = model.lateral_row(mu)
        out = max(out, abs(float(row @ uD)) + abs(float(row @ model.turn_feedforward)) * yaw_rate
                  + sup_on_set(np.array([row @ c for c in cmds]), mats, level, inner))
    return out


def _forward_oscillation(model: Any, cmds: list[np.ndarray], mats: list[np.ndarray], level: float, inner: int,
                         yaw_rate: float = 0.0) -> float:
    """The largest difference of the forward speed a = v - V^D between any two instants of a period on the
    set, slip changing at any time: between any two slip corners and any two commands in flight (``cmds``),
    with a turning reference's feedforward (0, w), |w| <= ``yaw_rate``, in each."""
    return _oscillation(model, [model.slip_matrix(mu)[0] for mu in np.asarray(model.corners)], cmds, mats, level,
                        inner, yaw_rate)


def _lateral_ranges(model: Any, cmds: list[np.ndarray], mats: list[np.ndarray], level: float, inner: int,
                    yaw_rate: float, one_minus_cos: float) -> tuple[float, float]:
    """The largest |v_y| on the set (:func:`_lateral_on_set`) and the range of ``v_y cos theta`` over a period, with
    ``1 - cos theta <= one_minus_cos``: ``|v1 c1 - v2 c2| <= |v1 - v2| + |v2| (1 - cos)``, the first v_y's oscillation
    (:func:`_lateral_oscillation`, never taken above twice the largest |v_y|)."""
    vy = _lateral_on_set(model, cmds, mats, level, inner, yaw_rate)
    return vy, min(_lateral_oscillation(model, cmds, mats, level, inner, yaw_rate), 2.0 * vy) + vy * one_minus_cos


def _lateral_oscillation(model: Any, cmds: list[np.ndarray], mats: list[np.ndarray], level: float, inner: int,
                         yaw_rate: float = 0.0) -> float:
    """The largest difference of the icr model's lateral velocity v_y = row(p) u between any two instants of a
    period on the set, slip changing at any time (docs/theory.md §12): as :func:`_forward_oscillation`, with
    the lateral rows.  At most twice :func:`_lateral_on_set`, and about once where the box holds x_icr = 0 (a
    corner whose v_y is 0 against one whose v_y is largest): v_y keeps its sign for a fixed command."""
    return _oscillation(model, [model.lateral_row(mu) for mu in np.asarray(model.corners)], cmds, mats, level,
                        inner, yaw_rate)


def _oscillation(model: Any, rows: list[np.ndarray], cmds: list[np.ndarray], mats: list[np.ndarray], level: float,
                 inner: int, yaw_rate: float) -> float:
    """The largest |r_a u_a - r_b u_b| on the set over every pair of rows (``rows``: a speed's row at each slip
    corner; the speed is multi-affine in the slip, so its extremes over the box, and the extremes of a difference
    of two such, are at corner pairs) and every pair of commands in flight u = u^D + w g + c xi (``cmds``: the
    c), each with its own feedforward w, |w| <= ``yaw_rate``."""
    uD = np.array([model.V, 0.0])
    g = model.turn_feedforward  # the feedforward command per rad/s of yaw rate ((0, 1): M[0, 1])
    osc = 0.0
    for ra in rows:
        for rb in rows:
            const = abs(float((ra - rb) @ uD)) + (abs(float(ra @ g)) + abs(float(rb @ g))) * yaw_rate
            for ca in cmds:
                diffs = np.array([ra @ ca - rb @ cb for cb in cmds])
                osc = max(osc, const + sup_on_set(diffs, mats, level, inner))
    return osc


def _speeds_on_set(model: Any, cmds: list[np.ndarray], mats: list[np.ndarray], level: float, inner: int,
                   yaw_rate: float = 0.0, yaw_step: float = 0.0) -> tuple[float, float, float, float]:
    """Bounds on the set, over every slip corner and command in flight (``cmds``: the rows that give
    each command from xi), on the forward speed |v|, the turn rate |omega|, the jump |dv| between
    consecutive commands and the forward-speed deviation |a| = |v - V^D|; with a turning reference's
    feedforward (0, w), |w| <= ``yaw_rate`` and steps <= ``yaw_step``, in every command."""
    uD = np.array([model.V, 0.0])
    g = model.turn_feedforward  # the feedforward command per rad/s of yaw rate ((0, 1): M[., 1])
    vbar = wbar = dvbar = abar = 0.0
    for mu in np.asarray(model.corners):
        M = model.slip_matrix(mu)
        forward = sup_on_set(np.array([M[0] @ c for c in cmds]), mats, level, inner)
        ff_v = abs(float(M[0] @ g)) * yaw_rate  # the feedforward's share of v (asymmetric slip)
        vbar = max(vbar, abs(float(M[0] @ uD)) + ff_v + forward)
        abar = max(abar, abs(float(M[0] @ uD) - model.V) + ff_v + forward)
        wbar = max(wbar, abs(float(M[1] @ uD)) + abs(float(M[1] @ g)) * yaw_rate
                   + sup_on_set(np.array([M[1] @ c for c in cmds]), mats, level, inner))
        dvbar = max(dvbar, abs(float(M[0] @ g)) * yaw_step
                    + sup_on_set(np.array([M[0] @ (cmds[j] - cmds[j + 1]) for j in range(model.d_hi)]), mats, level,
                                 inner))
    return vbar, wbar, dvbar, abar


def _between_samples_on_arcs(model: Any, cmds: list[np.ndarray], mats: list[np.ndarray], level: float,
                              sampled: dict[str, float], heading: float, inner: int,
                              within_period: bool = False, chord: dict[str, float] | None = None
                              ) -> dict[str, float | None]:
    """:func:`between_samples` for a reference turning along arcs (docs/theory.md §10), on the exact arcs
    (for either kinematics: the linearization's own flow is not the robot's).  In the frame F_k of the
    reference at t_k, with p the robot's position and p_r the reference's (heading psi = w_k s), the error
    at time s is ``R(-psi) (p - p_r)`` and ``e_theta = eta``.  Each component f of ``p - p_r`` is within
    ``max(|f(0)|, |f(Ts)|)`` of its chord plus ``Ts^2/8 sup|f''| + Ts/4 sum|jumps of f'|``: ``f(0)`` is
    e(t_k), ``f(Ts)`` is ``R(-phi) e(t_{k+1})`` (both in the set: ``|p_y - p_ry| <= B_y + sin phi_bar B_x`` at
    the ends); ``(p_y - p_ry)'' = v omega cos theta - V w cos psi``, ``(p_x - p_rx)'' = -v omega sin theta + V w
    sin psi`` (theta = psi + eta, |theta| <= phi_bar + |eta|), jumps ``|dv|`` (times sin theta for y) at
    the d_hi switching instants.  v, omega (the turning feedforward (0, w_{k-j}) included) and the jumps
    dv (steps of w included) are bounded on the set at every slip corner.  Then ``|e_y| <= P_y + sin phi_bar
    P_x`` and ``|e_x| <= P_x + sin phi_bar P_y``, P the bounds on |p - p_r| over the period.

    ``within_period``: slip may also change within the period, so v jumps wherever it does.  As on straight
    segments (:func:`between_samples`) only the parts in which a = v - V^D appears are bounded by their
    ranges: ``(p_y - p_ry)' = V (sin theta - sin psi) + a sin theta``, the first with ``|f''| <= V (omega_bar +
    w_bar)``, the second in ``+-abar sin theta_hat``; ``(p_x - p_rx)' = a + V (cos theta - cos psi) + a (cos theta
    - 1)``: a ranges over its oscillation, the second has ``|f''| <= V (omega_bar sin theta_hat + w_bar sin
    phi_bar)``, the third is in ``+-abar (1 - cos theta_hat)`` (theta_hat = phi_bar + |eta|)."""
    turns = model.turns
    Ts, V, d_hi = model.Ts, model.V, model.d_hi
    w_r = float(turns.max_yaw_rate)
    phi = w_r * Ts
    sp = float(np.sin(phi))
    vbar, wbar, dvbar, abar = _speeds_on_set(model, cmds, mats, level, inner, w_r, float(turns.max_step))
    top = phi + float(heading)  # |theta| <= phi_bar + |eta|: sin grows up to pi/2, 1 - cos up to pi
    s, one_minus_cos = float(np.sin(min(top, np.pi / 2))), 2.0 * float(np.sin(min(top, np.pi) / 2.0)) ** 2
    Bx, By = float(sampled["e_x"]), float(sampled["e_y"])
    if within_period:
        osc = _forward_oscillation(model, cmds, mats, level, inner, w_r)
        Py = By + sp * Bx + Ts * Ts / 8 * V * (wbar + w_r) + Ts / 4 * 2.0 * abar * s
        Px = (Bx + sp * By + Ts / 4 * osc + Ts * Ts / 8 * V * (wbar * s + w_r * sp)
              + Ts / 4 * 2.0 * abar * one_minus_cos)
    else:
        Py = By + sp * Bx + Ts * Ts / 8 * (vbar * wbar + V * w_r) + Ts / 4 * d_hi * dvbar * s
        Px = Bx + sp * By + Ts * Ts / 8 * (vbar * wbar * s + V * w_r * sp) + Ts / 4 * d_hi * dvbar
    if model.icr:  # the lateral velocity: (p_y - p_ry)' gets v_y cos theta, (p_x - p_rx)' -v_y sin theta, each
        # bounded by its range (it jumps wherever the slip or a command does): Ts/4 2 vy_bar (times sin theta_hat)
        # (for y its oscillation plus vy_bar (1 - cos theta_hat), as on straight segments)
        vy, range_y = _lateral_ranges(model, cmds, mats, level, inner, w_r, one_minus_cos)
        Py += Ts / 4 * range_y
        Px += Ts / 4 * 2.0 * vy * s
    if chord is not None:  # the chord terms each at its worst: the separate sums' bounds, less the sampled ones
        chord.update(e_x=round_up(Px + sp * Py - Bx, 16), e_y=round_up(Py + sp * Px - By, 16))
    if within_period:  # the terms of Py and Px joined to the start's errors (:func:`_chord_joined`): the smaller
        vy = vy if model.icr else 0.0  # (the tracks model: no lateral velocity, its family a zero row)
        fy, fx = chord_families(model, cmds, w_r, "e_y"), chord_families(model, cmds, w_r, "e_x")
        wy, wx = (Ts, Ts * 2.0 * s, Ts * Ts / 2.0 * V), (Ts, Ts * Ts / 2.0 * V * s, Ts * 2.0 * s)
        cx = Ts * Ts / 8 * V * w_r * sp + Ts / 4 * 2.0 * abar * one_minus_cos  # the terms of Px without a row
        Py = min(Py, _chord_joined(model, fy, wy, mats, level, inner, 1, Ts / 4 * vy * one_minus_cos, By + sp * Bx))
        Px = min(Px, _chord_joined(model, fx, wx, mats, level, inner, 0, cx, Bx + sp * By))
    return {"e_x": round_up(Px + sp * Py, 16), "e_y": round_up(Py + sp * Px, 16), "e_theta": heading}
