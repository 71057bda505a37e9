"""The bounds a certificate rests on, read from the robot's own logs (`identify`), and a check that a
robot stays inside a config's assumptions (`check-log`).

From logs in the format of :mod:`robustsynth.artifacts.logs`:

- **delay**: ``applied - sent`` of every received command; the range covers all of them.
- **losses**: the longest run of consecutive commands that never acted.
- **slip** (the paper's per-track factors, ``slip.model: tracks``): one estimate of (mu_r, mu_l) per
  sampling period. The commands that acted in the period, and for how long, follow from the
  applied times, with in-order delivery. The robot is moved from the measured pose at t_k through
  exact arcs under ``u = J H(mu) rho``, and mu is fitted (Gauss-Newton, 2 unknowns, 3 equations) to
  the measured pose at t_{k+1}. The slip box covers ``coverage`` of the estimates (central
  quantiles) and is widened by twice the estimates' standard uncertainty. That uncertainty comes
  from the fit's residual: the pose noise seen in the data. Estimates more than POOR_SIGMA times as
  uncertain as the median (a period in which one track barely turns) are left out of the box.
- **slip** (``slip.model: icr``, :mod:`robustsynth.identification_icr`): per period a line of
  (mu_r, mu_l, 1/yaw) and x_icr; the box of traction and yaw is the stated gauge (the least box that
  explains every period), x_icr's the central quantiles; the pose noise is given, not estimated.

Periods are skipped when the command acting at t_k is unknown (before the first applied command),
when the robot barely moves, or when a command exceeds the motor limit (if one is given): saturated
motors do not turn at the commanded speed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from .artifacts.logs import RobotLog
from .errors import InputError
from .core.network import longest_burst
from .identification_icr import S_WEIGHT
from .plants.kinematic import arc_step, wrap_angle

__all__ = ["SlipEstimates", "Identification", "estimate_slip", "estimate_icr", "identify", "fragment_yaml",
           "report_markdown", "check_log", "check_pose_noise", "config_pose_noise", "MODELS"]

MODELS = ("tracks", "icr")
KEYS = {"tracks": ("right", "left"), "icr": ("right", "left", "yaw", "icr_offset")}  # config keys of the slip box
ICR_NAMES = ("mu_r", "mu_l", "yaw", "x_icr")
UNITS = {"mu_r": "-", "mu_l": "-", "yaw": "-", "x_icr": "m"}
MIN_TURNING = 10  # icr: fewer turning periods say nothing about the yaw factor and x_icr
GAUGE_FALSE_ALARM = 0.05  # icr: the gauge's z is set so that any period's noise exceeds z sigma with these odds
WIDEN_SIGMA = 2.0  # the box is widened by this many standard uncertainties of an estimate
FIT_TOL = 1e-9  # the fit's own numerical error on mu (noise-free logs): the least widening
MIN_TRAVEL_M = 1e-3  # a period in which the commands move the robot less than this says little about slip
GN_STEPS = 6
POOR_SIGMA = 3.0  # an estimate whose uncertainty exceeds this many times the median is left out of the box
CHECK_SIGMA = 3.0  # check-log: an estimate is outside a range when beyond it by more than this many uncertainties


@dataclass(frozen=True)
class SlipEstimates:
    """Per-period estimates over all logs (only the periods used)."""

    mu: np.ndarray  # (n, n_p): (mu_r, mu_l), with the icr model also (yaw, x_icr) (NaN: not seen in that period)
    sigma: np.ndarray  # (n, n_p): standard uncertainty of each estimate (inf: the period says nothing about it)
    turn_rate: np.ndarray  # (n,): commanded omega / V over the period (rad/m), for the report
    where: list[tuple[str, int]]  # (file, row of t_k) of each estimate
    skipped: dict[str, int] = field(default_factory=dict)
    names: tuple[str, ...] = ("mu_r", "mu_l")  # the columns of mu and sigma


@dataclass(frozen=True)
class Identification:
    logs: int
    instants: int
    sampling_time: float
    delays: np.ndarray
    delay_range: tuple[float, float]
    lost: int
    longest_burst: int
    slip: SlipEstimates
    coverage: float
    box: dict[str, tuple[float, float]]  # config key ("right", "left"; icr: also "yaw", "icr_offset") -> (min, max)
    widening: dict[str, float]
    model: str = "tracks"
    pose_noise: tuple[float, float] | None = None  # icr: the pose noise the uncertainties assume [m], [rad]
    gauge: np.ndarray | None = None  # icr: the gauge box [[mu_r], [mu_l], [1/yaw]] (lo, hi) before widening


def _received(log: RobotLog) -> tuple[np.ndarray, np.ndarray]:
    """(rows of the commands that act, rows of those overtaken): with in-order delivery a command
    applied after a newer one (higher seq) was applied never acts."""
    rec = np.flatnonzero(np.isfinite(log.applied))
    if not rec.size:
        return rec, rec
    later_min = np.minimum.accumulate(log.applied[rec][::-1])[::-1]  # earliest application from i on
    acts = log.applied[rec] <= later_min
    return rec[acts], rec[~acts]


def _segments(log: RobotLog) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per period k (t_k -> t_{k+1}): the indices of the acting commands (-1: padding) and how long
    each acts (n-1, S), and whether the period's commands are all known (n-1,)."""
    rec, _ = _received(log)
    app = log.applied[rec]
    t0, t1 = log.t[:-1], log.t[1:]
    lo = np.searchsorted(app, t0, side="right")  # first switch after t_k
    hi = np.searchsorted(app, t1, side="left")  # switches strictly inside (t_k, t_{k+1})
    known = lo >= 1
    S = int(np.max(hi - lo, initial=0)) + 1
    P = t0.size
    idx = np.full((P, S), -1)
    dur = np.zeros((P, S))
    for j in range(S):
        i = lo - 1 + j  # the command acting in segment j
        valid = known & (i < hi)
        start = np.where(j == 0, t0, app[np.clip(i, 0, app.size - 1)])
        nxt = np.where(i + 1 < hi, app[np.clip(i + 1, 0, app.size - 1)], t1)
        idx[:, j] = np.where(valid, rec[np.clip(i, 0, rec.size - 1)], -1)
        dur[:, j] = np.where(valid, nxt - start, 0.0)
    return idx, dur, known


def _end_pose(q0: np.ndarray, rho: np.ndarray, dur: np.ndarray, mu: np.ndarray, R: float, D: float) -> np.ndarray:
    """Poses after the segments: rho (P, S, 2) motor speeds, dur (P, S), mu (P, 2)."""
    q = q0
    for j in range(dur.shape[1]):
        wr, wl = mu[:, 0] * rho[:, j, 0], mu[:, 1] * rho[:, j, 1]
        q = arc_step(q, R / 2.0 * (wr + wl), R / D * (wr - wl), dur[:, j])
    return q


def _residual(q0, q1, rho, dur, mu, R, D) -> np.ndarray:
    qe = _end_pose(q0, rho, dur, mu, R, D)
    c, s = np.cos(q0[:, 2]), np.sin(q0[:, 2])
    dx, dy = qe[:, 0] - q1[:, 0], qe[:, 1] - q1[:, 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(qe[:, 2] - q1[:, 2])], axis=1)


@dataclass(frozen=True)
class _Periods:
    """One log's usable periods: poses at t_k and t_{k+1} (P, 3), the acting commands' motor speeds
    (P, S, 2) and durations (P, S), the commanded travel [m] and turn [rad], and the log rows of t_k."""

    q0: np.ndarray
    q1: np.ndarray
    rho: np.ndarray
    dur: np.ndarray
    travel: np.ndarray
    turn: np.ndarray
    where: list[tuple[str, int]]


def _settling(log: RobotLog, settle: float) -> np.ndarray:
    """Per period (len(log) - 1,), whether a command that differs from its predecessor was applied within
    ``settle`` seconds before the period or during it: a robot with dynamics (a physics engine, a real one) is
    still settling there, and the kinematic slip models describe its steady motion only."""
    n = len(log) - 1
    if settle <= 0.0 or n <= 0:
        return np.zeros(max(n, 0), dtype=bool)
    rho = np.stack([log.rho_r, log.rho_l], axis=1)
    changed = np.r_[True, np.any(rho[1:] != rho[:-1], axis=1)]
    at = np.asarray(log.applied, dtype=float)[changed & np.isfinite(log.applied)]
    t0, t1 = np.asarray(log.t[:-1], dtype=float), np.asarray(log.t[1:], dtype=float)
    out = np.zeros(n, dtype=bool)
    for a in at:
        out |= (a > t0 - settle) & (a < t1)
    return out


def _periods(logs: Sequence[RobotLog], R: float, D: float, max_motor_speed: float | None, settle: float = 0.0
             ) -> tuple[list[_Periods], dict[str, int]]:
    """Every log's usable periods, and how many were skipped and why (``settle``: :func:`_settling`)."""
    skipped = {"unknown command": 0, "too little motion": 0, "motor limit": 0}
    if settle > 0.0:
        skipped["settling after a command change"] = 0
    out = []
    for log in logs:
        idx, dur, known = _segments(log)
        rho_all = np.stack([log.rho_r, log.rho_l], axis=1)
        rho = np.where(idx[..., None] >= 0, rho_all[np.clip(idx, 0, None)], 0.0)
        travel = np.sum(dur * np.abs(R / 2.0 * (rho[..., 0] + rho[..., 1])), axis=1)
        turn = np.sum(dur * np.abs(R / D * (rho[..., 0] - rho[..., 1])), axis=1)
        ok = known.copy()
        skipped["unknown command"] += int(np.sum(~known))
        if settle > 0.0:
            unsettled = ok & _settling(log, settle)
            skipped["settling after a command change"] += int(np.sum(unsettled))
            ok &= ~unsettled
        little = ok & (travel < MIN_TRAVEL_M) & (turn * D < MIN_TRAVEL_M)
        skipped["too little motion"] += int(np.sum(little))
        ok &= ~little
        if max_motor_speed is not None:
            sat = ok & np.any((np.abs(rho) > max_motor_speed) & (idx[..., None] >= 0), axis=(1, 2))
            skipped["motor limit"] += int(np.sum(sat))
            ok &= ~sat
        q = np.stack([log.x, log.y, log.theta], axis=1)
        rows = np.flatnonzero(ok) + 2
        out.append(_Periods(q[:-1][ok], q[1:][ok], rho[ok], dur[ok], travel[ok], turn[ok],
                            [(log.path, int(rw)) for rw in rows]))
    return out, skipped


def estimate_slip(logs: Sequence[RobotLog], gear_radius: float, track_distance: float,
                  max_motor_speed: float | None = None, settle: float = 0.0) -> SlipEstimates:
    """One (mu_r, mu_l) per usable period of every log (the tracks model)."""
    R, D = float(gear_radius), float(track_distance)
    mus, sigmas, turns, where = [], [], [], []
    res_sq, dof = 0.0, 0
    per_log = []
    periods, skipped = _periods(logs, R, D, max_motor_speed, settle)
    for pr in periods:
        q0, q1, rho, dur = pr.q0, pr.q1, pr.rho, pr.dur
        mu = np.ones((q0.shape[0], 2))
        Jm = np.zeros((q0.shape[0], 3, 2))
        JtJ = np.zeros((q0.shape[0], 2, 2))
        for _ in range(GN_STEPS):
            r = _residual(q0, q1, rho, dur, mu, R, D)
            for i in range(2):
                h = 1e-6
                step = mu.copy()
                step[:, i] += h
                Jm[:, :, i] = (_residual(q0, q1, rho, dur, step, R, D) - r) / h
            JtJ = np.einsum("pki,pkj->pij", Jm, Jm)
            Jtr = np.einsum("pki,pk->pi", Jm, r)
            mu = mu - np.linalg.solve(JtJ + 1e-18 * np.eye(2), Jtr[..., None])[..., 0]
        r = _residual(q0, q1, rho, dur, mu, R, D)
        res_sq += float(np.sum(r**2))  # one variance for the three equations: a rough, not a rigorous, uncertainty
        dof += r.shape[0]  # three equations, two unknowns per period
        per_log.append((mu, np.linalg.inv(JtJ + 1e-18 * np.eye(2)), pr.turn / np.maximum(pr.travel, 1e-12), pr.where))
    var = res_sq / dof if dof else 0.0  # residual variance per equation (positions dominate)
    for mu, cov, tr, wh in per_log:
        mus.append(mu)
        sigmas.append(np.sqrt(np.maximum(var * np.diagonal(cov, axis1=1, axis2=2), 0.0)))
        turns.append(tr)
        where += wh
    cat = (lambda xs, shape: np.concatenate(xs) if xs else np.zeros(shape))  # noqa: E731
    return SlipEstimates(cat(mus, (0, 2)), cat(sigmas, (0, 2)), cat(turns, (0,)), where, skipped)


def _icr_lines(logs: Sequence[RobotLog], R: float, D: float, pose_noise: tuple[float, float],
               max_motor_speed: float | None, settle: float = 0.0):
    """The icr model's per-period lines over all logs, the periods behind them (None: no usable
    period; a period with a track at rest is skipped: its traction factor is not seen) and the
    skip counts."""
    from .identification_icr import icr_lines, track_at_rest

    periods, skipped = _periods(logs, R, D, max_motor_speed, settle)
    skipped["a track at rest"] = 0
    kept = []
    for p in periods:
        rest = track_at_rest(p.rho, p.dur)
        skipped["a track at rest"] += int(np.sum(rest))
        keep = ~rest
        kept.append(_Periods(p.q0[keep], p.q1[keep], p.rho[keep], p.dur[keep], p.travel[keep], p.turn[keep],
                             [w for w, k in zip(p.where, keep) if k]))
    periods = kept
    if not sum(p.q0.shape[0] for p in periods):
        return None, periods, skipped
    S = max(p.dur.shape[1] for p in periods)

    def pad(a: np.ndarray) -> np.ndarray:  # every log's periods with S command segments (zero-length padding)
        return np.concatenate([a, np.zeros(a.shape[:1] + (S - a.shape[1],) + a.shape[2:])], axis=1)

    cat = np.concatenate
    lines = icr_lines(cat([p.q0 for p in periods]), cat([p.q1 for p in periods]), cat([pad(p.rho) for p in periods]),
                      cat([pad(p.dur) for p in periods]), R, D, pose_noise)
    return lines, periods, skipped


def _gauge_z(n: int) -> float:
    """The gauge's z: the chance that the noise of any of n periods' two traction factors exceeds z
    sigma (either side) is at most GAUGE_FALSE_ALARM."""
    from scipy.stats import norm

    return float(norm.isf(GAUGE_FALSE_ALARM / (4.0 * max(n, 1))))


def config_pose_noise(cfg: Any) -> tuple[float, float]:
    """The icr model's default pose noise: the config's ``verification.noise``; refused when it is zero
    (the default), which would claim exact poses for a real robot's log."""
    nz = cfg.verification.noise
    if nz.position == 0 and nz.heading == 0:
        raise InputError("--pose-noise: the icr model needs the logged poses' noise and the config's "
                         "verification.noise is 0; give --pose-noise POSITION HEADING [m] [rad] (0 0 for exact poses)")
    return float(nz.position), float(nz.heading)


def check_pose_noise(pose_noise: Any, source: str = "--pose-noise") -> tuple[float, float]:
    """The icr model's pose noise (position [m], heading [rad]): two finite numbers >= 0 (InputError)."""
    try:
        pn = tuple(float(x) for x in pose_noise)
    except (TypeError, ValueError):
        pn = ()
    if len(pn) != 2 or not all(np.isfinite(pn)) or min(pn) < 0:
        raise InputError(f"{source}: the icr model needs the pose noise as two finite numbers >= 0 (position [m], "
                         f"heading [rad]); got {pose_noise}")
    return pn


def estimate_icr(logs: Sequence[RobotLog], gear_radius: float, track_distance: float, pose_noise: tuple[float, float],
                 max_motor_speed: float | None = None, settle: float = 0.0) -> tuple[SlipEstimates, np.ndarray]:
    """One (mu_r, mu_l, yaw, x_icr) per usable period of every log (the icr model, in the gauge of
    :mod:`robustsynth.identification_icr`), and the gauge box [[mu_r], [mu_l], [s = 1/yaw]] (lo, hi)."""
    from .identification_icr import S_RANGE, gauge_box, icr_estimates

    R, D = float(gear_radius), float(track_distance)
    lines, periods, skipped = _icr_lines(logs, R, D, pose_noise, max_motor_speed, settle)
    if lines is None:
        return SlipEstimates(np.zeros((0, 4)), np.zeros((0, 4)), np.zeros(0), [], skipped, ICR_NAMES), np.zeros((3, 2))
    where = logs[0].path if logs else "identify"
    if int(np.sum(lines.turning)) < MIN_TURNING:
        raise InputError(f"{where}: the logs hardly turn ({int(np.sum(lines.turning))} turning periods): the icr model's "
                         "yaw factor and x_icr need turns (record some: validate --excite)")
    z = _gauge_z(len(lines))
    box = gauge_box(lines, z)
    tol = 1e-6 * (S_RANGE[1] - S_RANGE[0])
    if box[2, 0] <= S_RANGE[0] + tol or box[2, 1] >= S_RANGE[1] - tol:
        raise InputError(f"{where}: the logs do not determine the yaw factor (the least box that explains them needs "
                         f"yaw at the search's bound {1 / S_RANGE[1]:g} or {1 / S_RANGE[0]:g}): drive turns at several "
                         "rates and speeds, forwards (validate --excite)")
    est, sig = icr_estimates(lines, box, R, D, z)
    turn = np.concatenate([p.turn / np.maximum(p.travel, 1e-12) for p in periods])
    return SlipEstimates(est, sig, turn, [w for p in periods for w in p.where], skipped, ICR_NAMES), box


def _longest_burst(log: RobotLog) -> int:
    return int(longest_burst(~np.isfinite(log.applied))[0])


def _good(sg: np.ndarray) -> np.ndarray:
    """The estimates that say something: finite, and at most POOR_SIGMA times as uncertain as the
    median of those (a period in which one track barely turns, or a straight one for yaw and x_icr)."""
    fin = np.isfinite(sg)
    if not np.any(fin):
        return fin
    return fin & (sg <= POOR_SIGMA * float(np.median(sg[fin])) + FIT_TOL)


def _median_sigma(sg: np.ndarray) -> float:
    fin = np.isfinite(sg)
    return float(np.median(sg[fin])) if np.any(fin) else 0.0


def identify(logs: Sequence[RobotLog], gear_radius: float, track_distance: float, coverage: float = 0.995,
             model: str = "tracks", max_motor_speed: float | None = None,
             pose_noise: tuple[float, float] | None = None, settle: float = 0.0) -> Identification:
    """The delay range, the longest loss burst and the slip box that cover the logs.

    ``model='icr'`` needs ``pose_noise`` = (position [m], heading [rad]), the std of the logged
    poses: with as many unknowns as equations per period its fit cannot estimate the noise.  ``settle``
    [s]: skip the periods within that long after a command change (a robot with dynamics, e.g. the excitation
    logs of the physics robot, is still settling there)."""
    if not (np.isfinite(settle) and settle >= 0.0):
        raise InputError(f"--settle: must be a finite number of seconds >= 0 (got {settle!r})")
    if model not in MODELS:
        raise InputError(f"--model: {model!r} is not one of {', '.join(MODELS)}")
    if not 0.5 <= coverage <= 1.0:
        raise InputError(f"--coverage: must be in [0.5, 1] (got {coverage:g})")
    if not logs:
        raise InputError("identify: no log given")
    if model == "icr":
        pose_noise = check_pose_noise(pose_noise)
    delays = np.concatenate([lg.delays[np.isfinite(lg.delays)] for lg in logs])
    if delays.size == 0:
        raise InputError(f"{logs[0].path}: column 'applied': no command was ever applied")
    gauge = None
    if model == "icr":
        est, gauge = estimate_icr(logs, gear_radius, track_distance, pose_noise, max_motor_speed, settle)
    else:
        est = estimate_slip(logs, gear_radius, track_distance, max_motor_speed, settle)
    if est.mu.shape[0] < 10:
        raise InputError(f"{logs[0].path}: only {est.mu.shape[0]} periods could be used to estimate slip "
                         f"(skipped: {est.skipped}); a log needs the robot moving under known commands")
    q = (1.0 - coverage) / 2.0
    box, widen = {}, {}
    for i, key in enumerate(KEYS[model]):
        sg = est.sigma[:, i]
        if gauge is not None and key == "yaw":  # the gauge's range of s = 1/yaw, widened in s
            from .identification_icr import S_RANGE

            sg_s = sg / est.mu[:, 2] ** 2  # the uncertainty in s of the periods that say something about it
            w = WIDEN_SIGMA * float(np.median(sg_s[_good(sg_s)])) + FIT_TOL
            if gauge[2, 0] - w <= S_RANGE[0] or gauge[2, 1] + w >= S_RANGE[1]:
                raise InputError(f"{logs[0].path}: the logs do not determine the yaw factor (its range, widened by its "
                                 f"uncertainty, reaches the search's bound {1 / S_RANGE[1]:g} or {1 / S_RANGE[0]:g}): "
                                 "drive turns at several rates and speeds, forwards (validate --excite), or check --pose-noise")
            box[key], widen[key] = (1.0 / (gauge[2, 1] + w), 1.0 / (gauge[2, 0] - w)), w
            continue
        w = WIDEN_SIGMA * _median_sigma(sg) + FIT_TOL
        if gauge is not None and i < 2:  # the gauge's traction box: it explains every period (within z sigma, of
            from .identification_icr import MODEL_FLOOR  # which z times the lines' numerical floor is not noise)

            w += _gauge_z(est.mu.shape[0]) * MODEL_FLOOR
            lo, hi = gauge[i, 0] - w, gauge[i, 1] + w
        else:  # the central quantiles of the estimates (tracks; x_icr)
            good = _good(sg)
            if not np.any(good):
                raise InputError(f"{logs[0].path}: no period turns enough to estimate {est.names[i]} (the icr model needs "
                                 "turns; see validate --excite)")
            lo = float(np.quantile(est.mu[good, i], q)) - w
            hi = float(np.quantile(est.mu[good, i], 1.0 - q)) + w
        box[key] = (max(lo, 1e-3), hi) if key != "icr_offset" else (lo, hi)
        widen[key] = w
    steps = np.concatenate([np.diff(lg.t) for lg in logs])
    return Identification(
        logs=len(logs), instants=int(sum(len(lg) for lg in logs)), sampling_time=float(np.median(steps)),
        delays=delays, delay_range=(float(np.min(delays)), float(np.max(delays))),
        lost=int(sum(int(np.sum(~np.isfinite(lg.applied))) for lg in logs)), longest_burst=max(map(_longest_burst, logs)),
        slip=est, coverage=coverage, box=box, widening=widen, model=model,
        pose_noise=None if pose_noise is None else (float(pose_noise[0]), float(pose_noise[1])), gauge=gauge)


def _g(x: float) -> str:
    return f"{x:.4g}"


def _num(x: float) -> str:
    """x to 4 significant digits as a YAML number (no exponent: PyYAML reads '2e-05' as a string)."""
    return np.format_float_positional(float(f"{x:.4g}"), trim="-")


def fragment_yaml(ident: Identification) -> str:
    """A config fragment (network and slip sections) with the data behind each number as comments."""
    s = ident.slip
    d = ident.delays
    n = s.mu.shape[0]
    lines = [
        f"# identified by robustsynth identify from {ident.logs} log(s): {ident.instants} sampling instants,",
        f"# {n} periods used for slip ({', '.join(f'{k}: {v}' for k, v in s.skipped.items() if v) or 'none skipped'})",
        "network:",
        f"  sampling_time: {_num(ident.sampling_time)}  # median time step of the logs",
        "  delay:",
        f"    min: {_round(ident.delay_range[0], -1)}  # smallest of {d.size} measured delays (applied - sent); "
        f"1st percentile {_g(float(np.quantile(d, 0.01)))}",
        f"    max: {_round(ident.delay_range[1], +1)}  # largest; 99th percentile {_g(float(np.quantile(d, 0.99)))}",
        "  dropouts:",
        f"    max_consecutive: {ident.longest_burst}  # longest run of lost commands; {ident.lost} of "
        f"{ident.instants} lost ({100 * ident.lost / max(ident.instants, 1):.2f} %)",
        "slip:",
    ]
    if ident.model == "icr":
        pn = ident.pose_noise or (0.0, 0.0)
        lines += [
            "  model: icr  # mu_r, mu_l, yaw, x_icr (docs/theory.md §12); per period three numbers for four parameters:",
            f"  # traction and yaw are the gauge box (least traction widths + {S_WEIGHT:g} x the 1/yaw width) that explains",
            f"  # every period within its noise; pose noise assumed {_g(pn[0])} m, {_g(pn[1])} rad",
        ]
    for i, key in enumerate(KEYS[ident.model]):
        lo, hi = ident.box[key]
        name = s.names[i]
        vals = s.mu[:, i][np.isfinite(s.mu[:, i])]
        seen = f"range {_g(float(np.min(vals)))} .. {_g(float(np.max(vals)))}" if vals.size else "none seen"
        how = (f"explains all {vals.size} estimates" if ident.model == "icr" and key != "icr_offset"
               else f"covers {100 * ident.coverage:g} % of {vals.size} estimates")
        unit = " [m]" if UNITS[name] == "m" else ""
        lines.append(f"  {key}:  # {name}{unit}: {how} ({seen}), widened by {WIDEN_SIGMA:g} sigma = "
                     f"{_g(ident.widening[key])}" + (" in 1/yaw" if key == "yaw" else ""))
        lines.append(f"    min: {_round(lo, -1)}")
        lines.append(f"    max: {_round(hi, +1)}")
    return "\n".join(lines) + "\n"


def _round(x: float, direction: int, digits: int = 4) -> str:
    """x rounded to ``digits`` significant digits away from the box's inside (down for a min, up for a
    max), written without an exponent (YAML reads '1e-05' as a string)."""
    if x == 0 or not np.isfinite(x):
        return _g(x)
    scale = 10.0 ** (digits - 1 - int(np.floor(np.log10(abs(x)))))
    r = float((np.floor if direction < 0 else np.ceil)(x * scale) / scale)
    if (direction < 0 and r > x) or (direction > 0 and r < x):  # the division's rounding went inwards
        r = float(np.nextafter(r, -np.inf if direction < 0 else np.inf))
    return np.format_float_positional(r, trim="-")


def check_log(logs: Sequence[RobotLog], cfg: Any, max_motor_speed: float | None = None,
              pose_noise: tuple[float, float] | None = None) -> list[dict[str, Any]]:
    """Per assumption of ``cfg`` (delay range, in-order delivery, loss cap, each slip range): how many samples lie
    outside, the worst value and where.  A slip estimate counts as outside when it lies beyond the
    range by more than CHECK_SIGMA of its own uncertainty; poorly determined estimates (POOR_SIGMA)
    are not counted.  slip.model icr: each period is explained inside the box if it can be
    (:func:`robustsynth.identification_icr.check_icr`), with ``pose_noise`` (default: the config's
    verification.noise, refused when zero) as the logged poses' noise; a parameter no period says
    anything about has 0 samples (not checked)."""
    out = []
    dl = cfg.network.delay
    d = [(lg.delays, lg.path) for lg in logs]
    vals = np.concatenate([x[np.isfinite(x)] for x, _ in d]) if d else np.zeros(0)
    worst, where = None, ""
    for x, path in d:
        for k in np.flatnonzero(np.isfinite(x) & ((x < dl.min) | (x > dl.max))):
            excess = max(dl.min - x[k], x[k] - dl.max)
            if worst is None or excess > worst[0]:
                worst, where = (excess, float(x[k])), f"{path}, row {k + 2}"
    n_out = int(np.sum((vals < dl.min) | (vals > dl.max)))
    out.append({"assumption": "network.delay", "range": [dl.min, dl.max], "samples": int(vals.size), "outside": n_out,
                "fraction_outside": n_out / max(vals.size, 1), "worst": worst[1] if worst else None, "where": where,
                "unit": "s"})
    overtaken, first = 0, ""
    for lg in logs:
        _, bad = _received(lg)
        overtaken += int(bad.size)
        if bad.size and not first:
            first = f"{lg.path}, row {int(bad[0]) + 2}"
    out.append({"assumption": "in-order delivery", "range": [0, 0], "samples": int(vals.size), "outside": overtaken,
                "fraction_outside": overtaken / max(vals.size, 1), "worst": None, "where": first,
                "unit": "commands applied after a newer one"})
    cap = cfg.network.dropouts.max_consecutive
    bursts = [(_longest_burst(lg), lg.path) for lg in logs]
    b, bp = max(bursts) if bursts else (0, "")
    out.append({"assumption": "network.dropouts.max_consecutive", "range": [0, cap], "samples": len(logs),
                "outside": sum(1 for x, _ in bursts if x > cap), "fraction_outside": sum(1 for x, _ in bursts if x > cap)
                / max(len(logs), 1), "worst": b, "where": bp if b > cap else "", "unit": "commands in a row"})
    out += _compensation_rows(logs, cfg)
    if getattr(cfg.slip, "model", "tracks") == "icr":
        return out + _check_icr(logs, cfg, max_motor_speed, pose_noise)
    est = estimate_slip(logs, cfg.robot.gear_radius, cfg.robot.track_distance, max_motor_speed)
    for i, side in enumerate(("right", "left")):
        rng = getattr(cfg.slip, side)
        good = est.sigma[:, i] <= POOR_SIGMA * float(np.median(est.sigma[:, i])) + FIT_TOL if est.mu.size else []
        m, sg = est.mu[good, i], est.sigma[good, i]
        where_i = [w for w, g in zip(est.where, good) if g]
        beyond = np.maximum(rng.min - m, m - rng.max) - CHECK_SIGMA * sg - FIT_TOL
        bad = np.flatnonzero(beyond > 0)
        k = int(np.argmax(np.maximum(rng.min - m, m - rng.max))) if m.size else -1
        out.append({"assumption": f"slip.{side}", "range": [rng.min, rng.max], "samples": int(m.size), "outside": int(bad.size),
                    "fraction_outside": bad.size / max(m.size, 1), "worst": float(m[k]) if k >= 0 else None,
                    "where": f"{where_i[k][0]}, row {where_i[k][1]}" if k >= 0 and bad.size else "", "unit": "—"})
    return out


def _compensation_rows(logs: Sequence[RobotLog], cfg: Any) -> list[dict[str, Any]]:
    """check-log's row for a slip-compensated law's logs (their mu_hat_r, mu_hat_l, condition columns; docs/theory.md
    §18): the periods its controller found the certificate's condition not sure to hold after it first held (before,
    the estimator has no window yet: the theorem starts there), the first of them, and the logs in which it never
    held (each counted once) — ``slip.compensation`` in ``cfg`` or not: the logs say what their controller did."""
    with_est = [lg for lg in logs if lg.estimate is not None]
    if not with_est:
        return []
    cond, periods = [], 0
    for lg in with_est:
        held = lg.estimate[:, 2] == 1.0
        start = int(np.argmax(held)) if held.any() else len(lg)  # the estimator's first windows: not counted
        cond.append((lg, start + np.flatnonzero(~held[start:])))
        periods += len(lg) - start
    outside = sum(int(bad.size) for _, bad in cond)
    first = next(((lg, bad) for lg, bad in cond if bad.size), None)
    never = sum(1 for lg in with_est if not np.any(lg.estimate[:, 2] == 1.0))
    return [{"assumption": "slip.compensation (the estimate within its error)", "range": [1, 1], "samples": periods,
             "outside": outside + never, "fraction_outside": (outside + never) / max(periods + never, 1), "worst": None,
             "where": f"{first[0].path}, row {int(first[1][0]) + 2}" if first else "",
             "unit": "periods the condition did not hold, after it first held in each log" + (
                 f"; in {never} logs it never held" if never else "")}]


def _check_icr(logs: Sequence[RobotLog], cfg: Any, max_motor_speed: float | None,
               pose_noise: tuple[float, float] | None) -> list[dict[str, Any]]:
    """check-log's slip rows for an icr config: one per parameter (see :func:`check_log`)."""
    from .identification_icr import check_icr
    from .model.slip import slip_parameter_ranges

    noise = check_pose_noise(pose_noise if pose_noise is not None else config_pose_noise(cfg))
    lines, periods, _ = _icr_lines(logs, cfg.robot.gear_radius, cfg.robot.track_distance, noise, max_motor_speed)
    ranges = slip_parameter_ranges(cfg.slip)
    where = [w for p in periods for w in p.where]
    if lines is None:
        value, outside, sigma = np.zeros((0, 4)), np.zeros((0, 4), dtype=bool), np.zeros((0, 4))
    else:
        value, outside, sigma = check_icr(lines, ranges, CHECK_SIGMA, _gauge_z(len(lines)))
    rows = []
    for i, key in enumerate(KEYS["icr"]):
        lo, hi = ranges[i]
        seen = np.isfinite(value[:, i])
        bad = np.flatnonzero(outside[:, i])
        excess = np.where(seen, np.maximum(lo - value[:, i], value[:, i] - hi), -np.inf)
        pool = outside[:, i] if bad.size else seen & _good(sigma[:, i])  # the worst of the flagged, else of the sure
        k = int(np.argmax(np.where(pool, excess, -np.inf))) if np.any(pool) else -1
        rows.append({"assumption": f"slip.{key}", "range": [lo, hi], "samples": int(np.sum(seen)), "outside": int(bad.size),
                     "fraction_outside": bad.size / max(int(np.sum(seen)), 1),
                     "worst": float(value[k, i]) if k >= 0 else None,
                     "where": f"{where[k][0]}, row {where[k][1]}" if k >= 0 and bad.size else "",
                     "unit": "m" if key == "icr_offset" else "—", "pose_noise": list(noise)})
    return rows


def report_markdown(ident: Identification, fragment: str, figure: str | None) -> str:
    """The identification report: the fragment, the data behind each number, the skipped periods."""
    s, d = ident.slip, ident.delays
    qs = (0.0, 0.005, 0.5, 0.995, 1.0)
    rows = [f"| delay [s] | {d.size} | " + " | ".join(_g(float(np.quantile(d, q))) for q in qs) + " |"]
    for i, name in enumerate(s.names):
        v = s.mu[:, i][np.isfinite(s.mu[:, i])]
        if v.size:
            rows.append(f"| {name} | {v.size} | " + " | ".join(_g(float(np.quantile(v, q))) for q in qs) + " |")
    if ident.model == "icr":
        pn = ident.pose_noise or (0.0, 0.0)
        sig = {n: _g(float(np.median(s.sigma[:, i][np.isfinite(s.sigma[:, i])]))) if np.isfinite(s.sigma[:, i]).any()
               else "-" for i, n in enumerate(s.names)}
        slip_text = (
            "Slip (the icr model, docs/theory.md §13): per sampling period the measured poses give the body's mean twist "
            "(v_x, v_y, omega), three numbers for four parameters. x_icr = -v_y / omega in every turning period; the "
            "traction factors and the yaw factor consistent with a period lie on a line, and the box of (mu_r, mu_l, "
            f"yaw) is the gauge: the least traction widths plus {S_WEIGHT:g} times the width in 1/yaw that every "
            "period's line meets within its noise. The per-period estimates in the table are the points of those "
            "lines whose traction lies nearest the middle of the box's traction. Uncertainties are propagated from the pose noise "
            f"{_g(pn[0])} m, {_g(pn[1])} rad (given, not estimated: the fit has no residual); median standard "
            "uncertainty of an estimate: " + ", ".join(f"{n} {v}" for n, v in sig.items())
            + f". The traction and yaw ranges explain every period; x_icr's covers {100 * ident.coverage:g} % of its "
            f"estimates; each is widened by {WIDEN_SIGMA:g} uncertainties. Periods skipped: "
            + (", ".join(f"{k} {v}" for k, v in s.skipped.items() if v) or "none") + ".\n")
    else:
        slip_text = (
            f"Slip: one estimate of (mu_r, mu_l) per sampling period, fitted to the measured poses through exact arcs "
            f"under the commands that acted in the period. Median standard uncertainty of an estimate: "
            f"mu_r {_g(float(np.median(s.sigma[:, 0])))}, mu_l {_g(float(np.median(s.sigma[:, 1])))} (from the fit's "
            f"residual, i.e. the pose noise). The box covers {100 * ident.coverage:g} % of the estimates and is widened by "
            f"{WIDEN_SIGMA:g} of those uncertainties. Periods skipped: "
            + (", ".join(f"{k} {v}" for k, v in s.skipped.items() if v) or "none") + ".\n")
    out = [
        "# Identification\n\n",
        f"{ident.logs} log(s), {ident.instants} sampling instants, sampling time {_g(ident.sampling_time)} s.\n\n",
        "## Config fragment\n\n```yaml\n" + fragment + "```\n\n",
        "## The data\n\n| quantity | samples | min | 0.5 % | median | 99.5 % | max |\n|---|---|---|---|---|---|---|\n",
        "\n".join(rows) + "\n\n",
        f"Commands lost: {ident.lost} ({100 * ident.lost / max(ident.instants, 1):.2f} %), longest run "
        f"{ident.longest_burst}.\n\n",
        slip_text,
    ]
    if figure:
        out.append(f"\n![delay and slip estimates against the box]({figure})\n")
    return "".join(out)
