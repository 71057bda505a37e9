"""The nonlinear networked robot in closed loop, vectorized across Monte Carlo runs.

Unicycle kinematics with slip, ``q_dot = G(theta) J H J^-1 u_hat`` (eq. 12), integrated exactly
between actuation events (constant V, omega: arcs).  Sensors sample at ``t_k = k Ts``; the
controller computes ``du_k = K xi_k`` from the measured pose in the current segment's frame L
(eq. 13, 16, 17); the command acts from ``t_k + tau_k`` on, delivered in order.  Slip is
piecewise constant on the sampling grid.  The only Python loop is over time steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..model.kinematics import JHJinv

__all__ = [
    "PathGeometry",
    "make_path",
    "Scenario",
    "draw_scenario",
    "SimResult",
    "simulate",
    "arc_step",
    "frame_error",
    "wrap_angle",
    "saturate",
    "SLIP_PROFILES",
]

SLIP_PROFILES = ("constant", "random-walk", "steps")


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angle in [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def arc_step(q: np.ndarray, v: np.ndarray, w: np.ndarray, h: np.ndarray | float) -> np.ndarray:
    """Exact pose after moving with constant (v, w) for time h: an arc (a line when w = 0).

    dx = v h sinc(w h / 2) cos(theta + w h / 2), dy likewise with sin; stable for w -> 0."""
    th = q[..., 2]
    half = w * h / 2.0
    chord = v * h * np.sinc(half / np.pi)  # np.sinc(x) = sin(pi x)/(pi x)
    out = np.empty_like(q)
    out[..., 0] = q[..., 0] + chord * np.cos(th + half)
    out[..., 1] = q[..., 1] + chord * np.sin(th + half)
    out[..., 2] = th + w * h
    return out


def saturate(u_hat: np.ndarray, J: np.ndarray, J_inv: np.ndarray, rho_max: float | None) -> np.ndarray:
    """The command the actuator can apply: motor speeds rho = J^-1 u_hat clipped to +-rho_max,
    mapped back, u = J rho (identity when rho_max is None)."""
    if rho_max is None:
        return u_hat
    rho = np.clip(u_hat @ J_inv.T, -rho_max, rho_max)
    return rho @ J.T


@dataclass(frozen=True)
class PathGeometry:
    """Polyline path followed at speed V^D; segment i is the frame L_i (origin, heading)."""

    waypoints: np.ndarray  # (n+1, 2)
    headings: np.ndarray  # (n,)
    lengths: np.ndarray  # (n,)
    t_start: np.ndarray  # (n,) time the desired point leaves waypoint i
    duration: float
    speed: float

    def segment(self, t: float) -> int:
        i = int(np.searchsorted(self.t_start, t + 1e-12, side="right") - 1)
        return min(max(i, 0), len(self.lengths) - 1)

    def desired_pose(self, t: float) -> np.ndarray:
        i = self.segment(t)
        s = self.speed * (t - self.t_start[i])
        c, sn = math.cos(self.headings[i]), math.sin(self.headings[i])
        return np.array([self.waypoints[i, 0] + s * c, self.waypoints[i, 1] + s * sn, self.headings[i]])


def make_path(waypoints, speed: float) -> PathGeometry:
    W = np.asarray(waypoints, dtype=float)
    d = np.diff(W, axis=0)
    lengths = np.hypot(d[:, 0], d[:, 1])
    headings = np.arctan2(d[:, 1], d[:, 0])
    t_start = np.concatenate([[0.0], np.cumsum(lengths)[:-1]]) / speed
    return PathGeometry(W, headings, lengths, t_start, float(np.sum(lengths) / speed), speed)


def frame_error(path: PathGeometry, seg: int, q: np.ndarray, t: float) -> np.ndarray:
    """e = R(theta_0)(q - q_0) - [V^D (t - t_seg), 0, 0] in frame L of segment ``seg`` (eqs. 13, 16, 17)."""
    th0 = path.headings[seg]
    c, s = math.cos(th0), math.sin(th0)
    dx = q[..., 0] - path.waypoints[seg, 0]
    dy = q[..., 1] - path.waypoints[seg, 1]
    e = np.empty_like(q)
    e[..., 0] = c * dx + s * dy - path.speed * (t - path.t_start[seg])
    e[..., 1] = -s * dx + c * dy
    e[..., 2] = wrap_angle(q[..., 2] - th0)
    return e


@dataclass(frozen=True)
class Scenario:
    """Everything random about N runs, drawn up front (so any implementation can replay it)."""

    taus: np.ndarray  # (N, steps + d_hi): delay of the packet sent at t_{i - d_hi}
    mu: np.ndarray  # (N, steps, 2): (mu_r, mu_l) on [t_k, t_k+1)
    noise: np.ndarray  # (N, steps, 3): measurement noise on (x, y, theta)
    q0: np.ndarray  # (N, 3): initial pose
    profiles: tuple[str, ...]  # slip profile of each run

    @property
    def runs(self) -> int:
        return self.taus.shape[0]

    @property
    def steps(self) -> int:
        return self.mu.shape[1]


def _slip_profiles(rng: np.random.Generator, kinds: list[str], steps: int, lo: np.ndarray, hi: np.ndarray, Ts: float):
    N = len(kinds)
    mu = np.empty((N, steps, 2))
    kinds_arr = np.array(kinds)
    width = hi - lo
    # constant
    start = lo + width * rng.random((N, 2))
    mu[:] = start[:, None, :]
    # random walk: std 5% of the range per sqrt(s), reflected at the bounds
    inc = rng.normal(scale=0.05 * math.sqrt(Ts), size=(N, steps, 2)) * width
    walk = start[:, None, :] + np.cumsum(inc, axis=1)
    span = np.where(width > 0, width, 1.0)
    x = np.mod(walk - lo, 2 * span)
    walk = lo + np.where(x > span, 2 * span - x, x)
    walk = np.where(width > 0, walk, lo)
    sel = kinds_arr == "random-walk"
    mu[sel] = walk[sel]
    # steps: a new random level every ~3 s (geometric holding times)
    p = min(1.0, Ts / 3.0)
    jumps = rng.random((N, steps)) < p
    jumps[:, 0] = True
    levels = lo + width * rng.random((N, steps, 2))
    idx = np.maximum.accumulate(np.where(jumps, np.arange(steps)[None, :], 0), axis=1)
    stepped = np.take_along_axis(levels, idx[:, :, None].repeat(2, axis=2), axis=1)
    sel = kinds_arr == "steps"
    mu[sel] = stepped[sel]
    return mu


def draw_scenario(model, runs: int, seed: int, steps: int, path: PathGeometry, delays: str = "random",
                  slip: str | None = None) -> Scenario:
    """Seeded random scenario. ``delays``: 'random' (uniform iid), 'alternating' (min/max),
    'constant-min', 'constant-max'.  ``slip``: a profile for every run, or None to cycle through
    SLIP_PROFILES; 'none' for mu = 1."""
    cfg = model.config
    vc = cfg.verification
    rng = np.random.default_rng(seed)
    dl = cfg.network.delay
    n_pk = steps + model.d_hi
    if delays == "random":
        taus = rng.uniform(dl.min, dl.max, size=(runs, n_pk))
    elif delays == "alternating":
        taus = np.where((np.arange(n_pk)[None, :] + np.arange(runs)[:, None]) % 2 == 0, dl.min, dl.max) * np.ones((runs, 1))
    elif delays in ("constant-min", "constant-max"):
        taus = np.full((runs, n_pk), dl.min if delays == "constant-min" else dl.max)
    else:
        raise ValueError(f"unknown delay pattern {delays!r}")
    lo = np.array([cfg.slip.right.min, cfg.slip.left.min])
    hi = np.array([cfg.slip.right.max, cfg.slip.left.max])
    if slip == "none":
        kinds = ["none"] * runs
        mu = np.ones((runs, steps, 2))
    else:
        kinds = [slip] * runs if slip else [SLIP_PROFILES[n % 3] for n in range(runs)]
        mu = _slip_profiles(rng, kinds, steps, lo, hi, model.Ts)
    sd = np.array([vc.noise.position, vc.noise.position, vc.noise.heading])
    noise = rng.normal(size=(runs, steps, 3)) * sd if np.any(sd > 0) else np.zeros((runs, steps, 3))
    off = vc.initial_offset
    th0 = path.headings[0]
    c, s = math.cos(th0), math.sin(th0)
    q0 = np.array([path.waypoints[0, 0] + c * off.x - s * off.y, path.waypoints[0, 1] + s * off.x + c * off.y, th0 + off.theta])
    return Scenario(taus, mu, noise, np.tile(q0, (runs, 1)), tuple(kinds))


@dataclass(frozen=True)
class SimResult:
    t: np.ndarray  # (steps + 1,)
    q: np.ndarray  # (N, steps + 1, 3) pose at t_k
    e: np.ndarray  # (N, steps + 1, 3) true error at t_k in the segment frame active at t_k
    xi: np.ndarray  # (N, steps, n_s) lifted state the controller used (measured error)
    du: np.ndarray  # (N, steps, 2)
    rho: np.ndarray  # (N, steps, 2) commanded motor speeds J^-1 u_hat_k
    segment: np.ndarray  # (steps + 1,) segment index at t_k
    settled: np.ndarray  # (steps + 1,) bool: outside the transients


def simulate(model, K: np.ndarray, path: PathGeometry, scen: Scenario, transient: float = 0.0,
             progress: Callable[[int, int], None] | None = None) -> SimResult:
    """Vectorized closed-loop simulation of ``scen`` (all runs at once)."""
    K = np.asarray(K, dtype=float)
    cfg = model.config
    Ts, d_hi, V = model.Ts, model.d_hi, model.V
    D = cfg.robot.track_distance
    N, steps = scen.runs, scen.steps
    J_inv = np.asarray(model.J_inv)
    J = np.asarray(model.J)
    rho_sat = cfg.robot.max_motor_speed if cfg.verification.motor_saturation else None
    S = model.s_tilde(scen.taus)  # (N, steps, d_hi)
    uD = np.array([V, 0.0])
    U = np.tile(uD, (N, d_hi + 1, 1))  # U[:, j] = u_hat_{k-j}
    q = scen.q0.copy()
    t = np.arange(steps + 1) * Ts
    seg = np.array([path.segment(tk) for tk in t])
    Q = np.empty((N, steps + 1, 3))
    E = np.empty((N, steps + 1, 3))
    XI = np.empty((N, steps, model.n_s))
    DU = np.empty((N, steps, 2))
    Q[:, 0] = q
    for k in range(steps):
        E[:, k] = frame_error(path, seg[k], q, t[k])
        e_meas = frame_error(path, seg[k], q + scen.noise[:, k], t[k])
        xi = np.concatenate([e_meas, (U[:, :d_hi] - uD).reshape(N, -1)], axis=1)
        du = xi @ K.T
        U[:, 1:] = U[:, :-1]
        U[:, 0] = uD + du
        XI[:, k], DU[:, k] = xi, du
        M = JHJinv(scen.mu[:, k, 0], scen.mu[:, k, 1], D)  # (N, 2, 2)
        start = np.zeros(N)
        for j in range(d_hi, -1, -1):  # u_hat_{k-j} acts on [s~_j, s~_{j-1}), s~_{d_hi} = 0, s~_{-1} = Ts
            end = S[:, k, j - 1] if j > 0 else np.full(N, Ts)
            h = end - start
            u_eff = np.einsum("nij,nj->ni", M, saturate(U[:, j], J, J_inv, rho_sat))
            q = arc_step(q, u_eff[:, 0], u_eff[:, 1], h)
            start = end
        Q[:, k + 1] = q
        if progress is not None and (k % 50 == 0 or k == steps - 1):
            progress(k + 1, steps)
    E[:, steps] = frame_error(path, seg[steps], q, t[steps])
    rho = (uD + DU) @ J_inv.T
    since_switch = t - path.t_start[seg]
    settled = (t >= transient) & (since_switch >= transient)
    return SimResult(t, Q, E, XI, DU, rho, seg, settled)
