"""The icr slip model's parameters from robot logs (``identify --model icr``, docs/theory.md §13).

Per sampling period the measured poses at t_k and t_{k+1} give three numbers, the body's mean
twist (v_x, v_y, omega); the icr model (§12) has four parameters p = (mu_r, mu_l, yaw, x_icr):

    v_x = R (mu_r rho_r + mu_l rho_l) / 2,   omega = yaw R (mu_r rho_r - mu_l rho_l) / D,   v_y = -x_icr omega.

x_icr = -v_y / omega follows in every turning period.  The other three are one equation short:
with s = 1 / yaw,

    mu_r rho_r = v_x / R + s omega D / (2 R),   mu_l rho_l = v_x / R - s omega D / (2 R),

so the traction factors consistent with a period lie on a *line* in (mu_r, mu_l, s): a robot whose
tracks differ in traction and one that loses yaw rate move alike under one command.  Which box of
(mu_r, mu_l, yaw) the logs show is therefore a convention, and identify states the one it uses
(the *gauge*): the box of least traction widths plus S_WEIGHT times its width in s that every
period's line meets (one linear program; with the small S_WEIGHT the traction comes nearly first).
Periods at different commands pin the box: on logs whose slip visits its box's corners under turns
of both signs the gauge returns the true box (tests/test_identification.py).  The physical reading:
what the straight driving shows is traction, and turning slip beyond it is lost yaw rate (the
physics study of §12).  The relaxation: a period's line needs to meet the box only within
CHECK_SIGMA of its own noise.

The linear programs (HiGHS) run on cutting planes: a subset of periods (the extreme ones and a
random sample), then every period is checked against the box in closed form (the interval of s in
which its line lies in the box) and the violators are added, until none is left.

Per period the estimate is then the point of its line whose traction lies nearest the middle of the
box's (clipped to the period's own feasible interval), refined through exact arcs (Gauss-Newton on
(mu_r, mu_l, x_icr) at s_k: the mean twist is exact for one command per period and first-order
when a delayed command switches within it).  The uncertainties are first-order propagations of the
pose noise, which the caller gives: with as many unknowns as equations per period the fit's residual
says nothing about the noise (the tracks model estimates it from its residual).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .plants.kinematic import arc_step, wrap_angle

__all__ = ["IcrLines", "icr_lines", "gauge_box", "feasible_s", "icr_estimates", "check_icr", "track_at_rest", "S_RANGE",
           "S_WEIGHT", "CHECK_SIGMA"]

S_RANGE = (1.0 / 10.0, 1.0 / 0.05)  # s = 1 / yaw searched in [0.1, 20]: yaw in [0.05, 10] (the config's yaw <= 10)
S_WEIGHT = 0.05  # the gauge's price of one unit of s = 1/yaw, against one unit of traction width
CHECK_SIGMA = 3.0  # a period's line meets the box when within this many of its standard uncertainties
MIN_TURN = 1e-3  # rad/s: below this measured yaw rate (or 3 sigma of its noise) a period says nothing about yaw, x_icr
AT_REST = 1e-6  # a track whose mean motor speed is below this share of the other's is at rest: its mu is not seen
MODEL_FLOOR = 1e-9  # the lines' own numerical error (mu, x_icr): the least uncertainty
FIT_POINTS = (0.25, 0.5, 1.0, 2.0, 4.0)  # x s_ref: where the lines are fitted through the exact arcs
BEND = 2.0  # a two-command period's curve: its largest deviation from the line at FIT_POINTS, times this
GN_STEPS = 4
CUT_SEED_RANDOM = 400  # cutting planes: random periods in the first subset
CUTS_PER_ROUND = 400  # cutting planes: at most this many violators added per round
MAX_ROUNDS = 40
_TOL = 1e-9


@dataclass(frozen=True)
class IcrLines:
    """Per period: mu_r(s) = ar + br s, mu_l(s) = al + bl s, x_icr(s) = ax + bx s (s = 1 / yaw; x_icr
    NaN where the period does not turn), their standard uncertainties (sig_r, sig_l: of mu at fixed s,
    with the pose noise and the model's error; sig_x), the measured yaw rate, whether the period
    turns (beyond MIN_TURN and 3 sigma of its noise), and the pieces the exact refinement needs."""

    ar: np.ndarray
    br: np.ndarray
    al: np.ndarray
    bl: np.ndarray
    ax: np.ndarray
    bx: np.ndarray
    sig_r: np.ndarray
    sig_l: np.ndarray
    sig_x: np.ndarray
    omega: np.ndarray
    turning: np.ndarray
    q0: np.ndarray
    q1: np.ndarray
    rho: np.ndarray
    dur: np.ndarray

    def __len__(self) -> int:
        return int(self.ar.size)

    def take(self, idx: np.ndarray) -> "IcrLines":
        return IcrLines(*(getattr(self, f)[idx] for f in self.__dataclass_fields__))

    def x_at(self, s: np.ndarray) -> np.ndarray:
        return self.ax + self.bx * s

    @property
    def sig_s(self) -> np.ndarray:
        """The uncertainty of s = 1/yaw a period pins: its traction's uncertainty over the line's slope,
        of the better-determined track (inf for a flat line)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.minimum(self.sig_r / np.abs(self.br), self.sig_l / np.abs(self.bl))


def track_at_rest(rho: np.ndarray, dur: np.ndarray) -> np.ndarray:
    """Periods (P,) in which a track's mean motor speed is (nearly) zero: its traction factor is not
    seen, so the period's line is not defined (the callers skip them)."""
    rbar = np.abs(np.einsum("ps,psi->pi", dur, rho))
    return np.min(rbar, axis=1) <= AT_REST * np.maximum(np.max(rbar, axis=1), 1e-300)


def _mean_twist(q0: np.ndarray, q1: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The constant body twist (v_x, v_y, omega) that moves q0 to q1 in time T along an arc (the
    inverse of :func:`~robustsynth.plants.kinematic.arc_step`)."""
    c, s = np.cos(q0[:, 2]), np.sin(q0[:, 2])
    dx, dy = q1[:, 0] - q0[:, 0], q1[:, 1] - q0[:, 1]
    bx, by = c * dx + s * dy, -s * dx + c * dy
    w = wrap_angle(q1[:, 2] - q0[:, 2]) / T
    h = w * T / 2.0
    sc = T * np.sinc(h / np.pi)
    return (np.cos(h) * bx + np.sin(h) * by) / sc, (-np.sin(h) * bx + np.cos(h) * by) / sc, w


def _end_pose(q0, rho, dur, p, s, R, D):
    """Poses after the period's command segments under (mu_r, mu_l, x_icr) = p (P, 3) and s = 1/yaw."""
    q = q0
    for j in range(dur.shape[1]):
        wr, wl = p[:, 0] * rho[:, j, 0], p[:, 1] * rho[:, j, 1]
        w = R / D * (wr - wl) / s
        q = arc_step(q, R / 2.0 * (wr + wl), w, dur[:, j], -p[:, 2] * w)
    return q


def _residual(q0, q1, rho, dur, p, s, R, D):
    qe = _end_pose(q0, rho, dur, p, s, R, D)
    c, sn = np.cos(q0[:, 2]), np.sin(q0[:, 2])
    dx, dy = qe[:, 0] - q1[:, 0], qe[:, 1] - q1[:, 1]
    return np.stack([c * dx + sn * dy, -sn * dx + c * dy, wrap_angle(qe[:, 2] - q1[:, 2])], axis=1)


def _refine(q0, q1, rho, dur, p, s, R, D) -> np.ndarray:
    """Gauss-Newton on (mu_r, mu_l, x_icr) at fixed s through the exact arcs of the period's commands,
    from the mean-twist estimate p.  Damped on the diagonal: x_icr stays put where omega ~ 0."""
    p = p.copy()
    Jm = np.empty((p.shape[0], 3, 3))
    for _ in range(GN_STEPS):
        r = _residual(q0, q1, rho, dur, p, s, R, D)
        for i in range(3):
            step = p.copy()
            step[:, i] += 1e-7
            Jm[:, :, i] = (_residual(q0, q1, rho, dur, step, s, R, D) - r) / 1e-7
        JtJ = np.einsum("pki,pkj->pij", Jm, Jm)
        JtJ = JtJ + (1e-10 * np.einsum("pii->pi", JtJ) + 1e-30)[:, :, None] * np.eye(3)
        p = p - np.linalg.solve(JtJ, np.einsum("pki,pk->pi", Jm, r)[..., None])[..., 0]
    return p


def icr_lines(q0: np.ndarray, q1: np.ndarray, rho: np.ndarray, dur: np.ndarray, R: float, D: float,
              noise: tuple[float, float]) -> IcrLines:
    """The per-period lines from poses q0 -> q1 (P, 3), the commands' motor speeds rho (P, S, 2)
    acting for dur (P, S), and the pose noise (position [m], heading [rad], one std per sample).
    No track may be at rest (:func:`track_at_rest`)."""
    T = dur.sum(axis=1)
    rbar = np.einsum("ps,psi->pi", dur, rho) / T[:, None]  # mean motor speeds over the period
    vx, vy, w = _mean_twist(q0, q1, T)
    # first order in the pose noise (two poses per period, iid): the displacement is seen in the frame
    # of the mean heading (theta_0 + theta_1) / 2, whose error sh / sqrt(2) turns it sideways
    sp, sh = float(noise[0]), float(noise[1])
    L = np.hypot(q1[:, 0] - q0[:, 0], q1[:, 1] - q0[:, 1])
    s_vx = np.sqrt(2.0) * sp / T
    s_vy = np.sqrt(2.0 * sp**2 + (L * sh) ** 2 / 2.0) / T
    s_w = np.sqrt(2.0) * sh / T
    turning = np.abs(w) >= np.maximum(MIN_TURN, 3.0 * s_w)
    with np.errstate(divide="ignore", invalid="ignore"):
        ar, br = vx / (R * rbar[:, 0]), w * D / (2.0 * R * rbar[:, 0])
        al, bl = vx / (R * rbar[:, 1]), -w * D / (2.0 * R * rbar[:, 1])
        x = np.where(turning, -vy / w, 0.0)
        # the omega term's share of sig_r, sig_l depends on s: evaluated at the lumped s of the turning
        # periods (commanded over measured yaw rate with mu = 1), one value for the whole log set
        w_cmd = R / D * (rbar[:, 0] - rbar[:, 1])
        s_ref = float(np.clip(np.median(w_cmd[turning] / w[turning]), *S_RANGE)) if np.any(turning) else 1.0
        sig_r = np.hypot(s_vx, s_ref * D / 2.0 * s_w) / np.abs(R * rbar[:, 0])
        sig_l = np.hypot(s_vx, s_ref * D / 2.0 * s_w) / np.abs(R * rbar[:, 1])
        sig_x = np.where(turning, np.hypot(s_vy, x * s_w) / np.abs(w), np.inf)
    # the exact lines: (mu_r, mu_l, x_icr) fitted through the exact arcs at FIT_POINTS x s_ref and the
    # least-squares line through them: exact for one command per period; when a delayed command switches
    # within it the points lie on a slightly bent curve, and BEND x the largest deviation from the line
    # at the points joins the uncertainty (for s within FIT_POINTS' span: yaw within [1/4, 4] x the
    # lumped yaw of the logs)
    pts = np.asarray(FIT_POINTS) * s_ref
    fits = np.stack([_refine(q0, q1, rho, dur, np.stack([ar + br * si, al + bl * si, x], axis=1), si, R, D)
                     for si in pts], axis=0)  # (k, P, 3)
    sc = pts - pts.mean()
    slope = np.einsum("k,kpi->pi", sc, fits - fits.mean(axis=0)) / float(sc @ sc)
    icpt = fits.mean(axis=0) - slope * pts.mean()
    bend = BEND * np.max(np.abs(fits - (icpt[None] + slope[None] * pts[:, None, None])), axis=0)
    ar, al, ax = icpt[:, 0], icpt[:, 1], icpt[:, 2]
    sig_r = np.sqrt(sig_r**2 + bend[:, 0] ** 2) + MODEL_FLOOR
    sig_l = np.sqrt(sig_l**2 + bend[:, 1] ** 2) + MODEL_FLOOR
    sig_x = np.sqrt(sig_x**2 + bend[:, 2] ** 2) + MODEL_FLOOR
    ax = np.where(turning, ax, np.nan)
    return IcrLines(ar, slope[:, 0], al, slope[:, 1], ax, np.where(turning, slope[:, 2], 0.0), sig_r, sig_l, sig_x, w,
                    turning, q0, q1, rho, dur)


def feasible_s(lines: IcrLines, box: np.ndarray, z: float = CHECK_SIGMA) -> tuple[np.ndarray, np.ndarray]:
    """Per period the interval [lo, hi] of s in which its line lies in ``box`` = [[mu_r lo, hi],
    [mu_l lo, hi], [s lo, hi]] within z of its uncertainties (empty: lo > hi)."""
    lo = np.full(len(lines), box[2, 0])
    hi = np.full(len(lines), box[2, 1])
    for a, b, sg, (blo, bhi) in ((lines.ar, lines.br, lines.sig_r, box[0]), (lines.al, lines.bl, lines.sig_l, box[1])):
        slack = z * sg
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (blo - slack - a) / b, (bhi + slack - a) / b
        flat = np.abs(b) < 1e-14
        inside = (a >= blo - slack - _TOL) & (a <= bhi + slack + _TOL)
        lo = np.maximum(lo, np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2)))
        hi = np.minimum(hi, np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2)))
    return lo, hi


def _lp(lines: IcrLines, z: float) -> np.ndarray:
    """The gauge LP on the given periods: variables (lo_r, hi_r, lo_l, hi_l, lo_s, hi_s, s_1..s_m);
    minimize the traction widths plus S_WEIGHT times the s width."""
    from scipy import sparse
    from scipy.optimize import linprog

    from .errors import SolverFailure

    m = len(lines)
    J = np.arange(m)

    def bound(col: int, v: float):
        return sparse.csr_matrix((np.full(m, v), (J, np.full(m, col))), shape=(m, 6))

    rows, rhs = [], []
    for c_lo, a, b, sg in ((0, lines.ar, lines.br, lines.sig_r), (2, lines.al, lines.bl, lines.sig_l)):
        rows += [sparse.hstack([bound(c_lo + 1, -1.0), sparse.diags(b)]), sparse.hstack([bound(c_lo, 1.0), sparse.diags(-b)])]
        rhs += [z * sg - a, a + z * sg]
    rows += [sparse.hstack([bound(5, -1.0), sparse.eye(m)]), sparse.hstack([bound(4, 1.0), -sparse.eye(m)])]
    rhs += [np.zeros(m), np.zeros(m)]
    order = sparse.csr_matrix(([1.0, -1.0] * 3, ([0, 0, 1, 1, 2, 2], [0, 1, 2, 3, 4, 5])), shape=(3, 6 + m))
    rows.append(order)  # lo <= hi: the slack must not buy an inverted box
    rhs.append(np.zeros(3))
    cost = np.zeros(6 + m)
    cost[:6] = (-1.0, 1.0, -1.0, 1.0, -S_WEIGHT, S_WEIGHT)
    bounds = [(None, None)] * 4 + [S_RANGE] * (2 + m)
    res = linprog(cost, A_ub=sparse.vstack(rows).tocsr(), b_ub=np.concatenate(rhs), bounds=bounds, method="highs")
    if res.status != 0:
        raise SolverFailure(f"identify --model icr: the gauge LP failed ({res.message})")
    return res.x[:6].reshape(3, 2)


def gauge_box(lines: IcrLines, z: float = CHECK_SIGMA, seed: int = 0) -> np.ndarray:
    """The gauge: [[mu_r lo, hi], [mu_l lo, hi], [s lo, hi]], the box of least traction widths plus
    S_WEIGHT times its s width that every period's line meets (within z sigma).  Cutting planes: an
    LP on a subset, then every period checked in closed form (:func:`feasible_s`), the violators added."""
    n = len(lines)
    rng = np.random.default_rng(seed)
    idx = set(rng.choice(n, size=min(n, CUT_SEED_RANDOM), replace=False).tolist())
    for s in (0.5, 1.0, 1.5, 2.0, 3.0):  # the periods extreme in mu at a few yaw factors
        for v in (lines.ar + lines.br * s, lines.al + lines.bl * s):
            order = np.argsort(v)
            idx.update(order[:20].tolist() + order[-20:].tolist())
    idx = np.array(sorted(idx))
    for _ in range(MAX_ROUNDS):
        box = _lp(lines.take(idx), z)
        lo, hi = feasible_s(lines, box, z)
        gap = lo - hi  # inf for a flat line outside the box
        scale = np.maximum(1.0, np.where(np.isfinite(lo), np.abs(lo), 1.0))
        bad = np.setdiff1d(np.flatnonzero(gap > 1e-9 * scale), idx)
        if not bad.size:
            return box
        idx = np.union1d(idx, bad[np.argsort(gap[bad])[::-1][:CUTS_PER_ROUND]])
    from .errors import SolverFailure

    raise SolverFailure(f"identify --model icr: the gauge LP's cutting planes did not settle in {MAX_ROUNDS} rounds")


def icr_estimates(lines: IcrLines, box: np.ndarray, R: float, D: float, z: float = CHECK_SIGMA
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Per period (mu_r, mu_l, yaw, x_icr) and their standard uncertainties (inf, and NaN values, where
    the period says nothing about a parameter: yaw and x_icr in straight periods).

    The point of the period's line is the one whose traction lies nearest the middle of the gauge
    box's traction (in units of its widths), clipped to the s interval in which the line lies in the
    box: with the traction pinned near its typical value, the yaw factor shows how the turn went.
    Refined through exact arcs at that s (Gauss-Newton on mu_r, mu_l, x_icr)."""
    lo, hi = feasible_s(lines, box, z)
    wa, wb = (max(box[i, 1] - box[i, 0], 1e-6) for i in (0, 1))
    ca, cb = 0.5 * (box[0, 0] + box[0, 1]), 0.5 * (box[1, 0] + box[1, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        den = (lines.br / wa) ** 2 + (lines.bl / wb) ** 2
        s_near = -((lines.ar - ca) * lines.br / wa**2 + (lines.al - cb) * lines.bl / wb**2) / den
    s_near = np.where(np.isfinite(s_near) & (den > 1e-18), s_near, 0.5 * (box[2, 0] + box[2, 1]))
    s = np.clip(s_near, np.minimum(lo, hi), np.maximum(lo, hi))
    p0 = np.stack([lines.ar + lines.br * s, lines.al + lines.bl * s, np.nan_to_num(lines.x_at(s))], axis=1)
    p = _refine(lines.q0, lines.q1, lines.rho, lines.dur, p0, s, R, D)
    turning = lines.turning
    sig_s = lines.sig_s
    est = np.stack([p[:, 0], p[:, 1], np.where(turning, 1.0 / s, np.nan), np.where(turning, p[:, 2], np.nan)], axis=1)
    sig = np.stack([lines.sig_r, lines.sig_l, np.where(turning, sig_s / s**2, np.inf), lines.sig_x], axis=1)
    return est, sig


def check_icr(lines: IcrLines, ranges: tuple[tuple[float, float], ...], z: float = CHECK_SIGMA,
              z_gauge: float = CHECK_SIGMA) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``check-log`` on an icr config: per period and parameter (mu_r, mu_l, yaw, x_icr) a value and
    whether it lies outside its range by more than z sigma.

    A period's traction and yaw are one equation short, so which parameter to blame is not in the
    period alone.  A period whose line meets the config's box (within z sigma) is explained: none of
    its traction and yaw values is outside (the values: its point at the middle of the box's range
    of s = 1/yaw, clipped to where the line lies in the box).  Any other period is explained within
    the logs' own gauge box (:func:`gauge_box`, what ``identify`` reports), at the point of its line in
    that box with the fewest parameters outside the config's ranges (beyond z sigma), and among those
    the least sum of excesses in sigmas: a robot whose right track pulls more than the config allows
    is blamed on mu_r, not on a yaw factor and mu_l that could trade for it under one command.  If
    that point lies within z sigma of every range, the parameter farthest out in sigmas is blamed
    (the period is not explained).  x_icr (which moves with s when a delayed command switches within
    the period) is outside only if no s the period allows (its interval in the config's box, or its
    point in the gauge) brings it inside.
    NaN values: the period says nothing about that parameter (yaw and x_icr in straight periods).
    Returns (value, outside, sigma), each (n, 4); sigma: the value's standard uncertainty."""
    (r_lo, r_hi), (l_lo, l_hi), (y_lo, y_hi), (x_lo, x_hi) = ranges
    n = len(lines)
    cfg_box = np.array([[r_lo, r_hi], [l_lo, l_hi], [1.0 / y_hi, 1.0 / y_lo]])
    lo, hi = feasible_s(lines, cfg_box, z)
    explained = lo <= hi
    turning = lines.turning
    s_k = np.clip(0.5 * (cfg_box[2, 0] + cfg_box[2, 1]), np.where(explained, lo, -np.inf), np.where(explained, hi, np.inf))
    s_a, s_b = np.where(explained, lo, s_k), np.where(explained, hi, s_k)  # the s the period allows, for x_icr
    sig_s = lines.sig_s
    if not np.all(explained):
        gauge = gauge_box(lines, z_gauge)
        g_lo, g_hi = feasible_s(lines, gauge, z_gauge)
        empty = g_lo > g_hi + 1e-9 * np.maximum(1.0, np.abs(np.nan_to_num(g_lo, posinf=1.0, neginf=1.0)))
        mid = 0.5 * (gauge[2, 0] + gauge[2, 1])
        g_lo, g_hi = np.where(empty, mid, g_lo), np.where(empty, mid, g_hi)
        with np.errstate(divide="ignore", invalid="ignore"):
            zi = z * (1.0 - 1e-6)  # the candidates where a parameter reaches z sigma, just inside
            zs = zi * sig_s
            cands = [g_lo, g_hi] + [np.full(n, c) for c in cfg_box[2]] + [cfg_box[2, 0] - zs, cfg_box[2, 1] + zs]
            for a, b, sg, bounds in ((lines.ar, lines.br, lines.sig_r, (r_lo, r_hi)),
                                     (lines.al, lines.bl, lines.sig_l, (l_lo, l_hi))):
                cands += [(v + d - a) / b for v in bounds for d in (-zi * sg, 0.0, zi * sg)]
            S = np.clip(np.nan_to_num(np.stack(cands, axis=1), nan=mid, posinf=mid, neginf=mid),
                        g_lo[:, None], g_hi[:, None])
            A = lines.ar[:, None] + lines.br[:, None] * S
            B = lines.al[:, None] + lines.bl[:, None] * S
            ex = [np.maximum(0.0, np.maximum(r_lo - A, A - r_hi)) / lines.sig_r[:, None],
                  np.maximum(0.0, np.maximum(l_lo - B, B - l_hi)) / lines.sig_l[:, None],
                  np.where(turning, 1.0, 0.0)[:, None] * np.maximum(0.0, np.maximum(cfg_box[2, 0] - S, S - cfg_box[2, 1]))
                  / sig_s[:, None]]
            # the fewest parameters out (beyond z sigma), then the least excess in sigmas
            cost = sum((e > z) * 1e9 + e for e in ex)
        best = S[np.arange(n), np.argmin(np.nan_to_num(cost, nan=np.inf), axis=1)]
        s_k = np.where(explained, s_k, best)
        s_a, s_b = np.where(explained, s_a, best), np.where(explained, s_b, best)
    value = np.stack([lines.ar + lines.br * s_k, lines.al + lines.bl * s_k, np.where(turning, 1.0 / s_k, np.nan),
                      lines.x_at(s_k)], axis=1)
    sig = np.stack([lines.sig_r, lines.sig_l, np.where(turning, sig_s / s_k**2, np.inf), lines.sig_x], axis=1)
    out = np.zeros(value.shape, dtype=bool)
    with np.errstate(invalid="ignore", divide="ignore"):
        excess = np.stack([np.maximum(lo_ - value[:, i], value[:, i] - hi_) for i, (lo_, hi_) in enumerate(ranges)], axis=1)
        norm = np.where(np.isfinite(value), excess / sig, -np.inf)
        xa, xb = lines.x_at(s_a), lines.x_at(s_b)  # x_icr over the s the period allows: its nearest to the range
        x_excess = np.maximum(x_lo - np.maximum(xa, xb), np.minimum(xa, xb) - x_hi)
        value[:, 3] = np.where(x_excess > 0, np.where(np.minimum(xa, xb) > x_hi, np.minimum(xa, xb), np.maximum(xa, xb)),
                               np.clip(value[:, 3], x_lo, x_hi))
        value[:, 3] = np.where(turning, value[:, 3], np.nan)
        norm[:, 3] = np.where(turning, x_excess / lines.sig_x, -np.inf)
    for i in range(3):
        out[:, i] = ~explained & (norm[:, i] > z)
    nearest = np.flatnonzero(~explained & ~out[:, :3].any(axis=1))
    out[nearest, np.argmax(norm[nearest, :3], axis=1)] = True
    out[:, 3] = norm[:, 3] > z
    return value, out, sig
