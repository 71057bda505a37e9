"""The nonlinear networked robot in closed loop, vectorized across Monte Carlo runs.

Unicycle kinematics with slip, ``q_dot = G(theta) J H J^-1 u_hat`` (eq. 12), integrated exactly
between actuation events (constant V, omega: arcs).  Sensors sample at ``t_k = k Ts``; the
controller computes ``du_k = K xi_k`` from the measured pose in the current segment's frame L
(eq. 13, 16, 17); the command acts from ``t_k + tau_k`` on, delivered in order.  Slip is
piecewise constant on the sampling grid.  The only Python loop is over time steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import check_interrupt
from ..model.network import gilbert_elliott, with_losses
from ..model.kinematics import JHJinv
from ..runtime.law import Law, PathTable, segment_at
from ..runtime.law import frame_error as law_frame_error
from ..runtime.law import wrap_angle as law_wrap_angle

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
    "period",
    "control_law",
    "steady_state_start",
    "adversarial_nonlinear",
    "adversary_start",
    "ADVERSARY_OBJECTIVES",
    "slip_profiles",
    "SLIP_PROFILES",
]

SLIP_PROFILES = ("constant", "random-walk", "steps", "corners")


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angle in [-pi, pi) (the deployed controller's wrap)."""
    return law_wrap_angle(np.asarray(a, dtype=float))


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
    """Polyline path followed at speed V^D; segment i is the frame L_i (origin, heading).  The
    numbers are those of the deployed controller's :class:`~robustsynth.runtime.law.PathTable`."""

    waypoints: np.ndarray  # (n+1, 2)
    headings: np.ndarray  # (n,)
    lengths: np.ndarray  # (n,)
    t_start: np.ndarray  # (n,) time the desired point leaves waypoint i
    duration: float
    speed: float
    table: PathTable = field(repr=False, compare=False)

    def segment(self, t: float) -> int:
        return segment_at(self.table.t_start, t)

    def desired_pose(self, t: float) -> np.ndarray:
        i = self.segment(t)
        s = self.speed * (t - self.t_start[i])
        c, sn = self.table.cos[i], self.table.sin[i]
        return np.array([self.waypoints[i, 0] + s * c, self.waypoints[i, 1] + s * sn, self.headings[i]])


def make_path(waypoints, speed: float) -> PathGeometry:
    tab = PathTable(np.asarray(waypoints, dtype=float).tolist(), speed)
    return PathGeometry(np.array(tab.waypoints), np.array(tab.heading), np.array(tab.length), np.array(tab.t_start),
                        tab.duration, tab.speed, tab)


def frame_error(path: PathGeometry, seg: int, q: np.ndarray, t: float) -> np.ndarray:
    """e = R(theta_0)(q - q_0) - [V^D (t - t_seg), 0, 0] in frame L of segment ``seg`` (eqs. 13, 16,
    17): the deployed controller's :func:`~robustsynth.runtime.law.frame_error` on arrays."""
    q = np.asarray(q, dtype=float)
    return np.stack(law_frame_error(path.table, seg, t, q[..., 0], q[..., 1], q[..., 2]), axis=-1)


@dataclass(frozen=True)
class Scenario:
    """Everything random about N runs, drawn up front (so any implementation can replay it)."""

    taus: np.ndarray  # (N, steps + d_hi): delay of the packet sent at t_{i - d_hi}
    mu: np.ndarray  # (N, steps, 2): (mu_r, mu_l) on [t_k, t_k+1)
    noise: np.ndarray  # (N, steps, 3): measurement noise on (x, y, theta)
    q0: np.ndarray  # (N, 3): initial pose
    profiles: tuple[str, ...]  # slip profile of each run
    du0: np.ndarray | None = None  # (N, d_hi, 2): stored commands du_{-1}, ..., du_{-d_hi} (None: zero)
    z0: np.ndarray | None = None  # (N, 2): integrator states at t_0 (None: zero)

    @property
    def runs(self) -> int:
        return self.taus.shape[0]

    @property
    def steps(self) -> int:
        return self.mu.shape[1]


def _rate_limit(target: np.ndarray, start: np.ndarray, max_step: float | None) -> np.ndarray:
    """Follow ``target`` (N, steps, 2) from ``start`` (N, 2) with |mu_{k+1} - mu_k| <= max_step."""
    if max_step is None:
        return target
    out = np.empty_like(target)
    cur = start.copy()
    for k in range(target.shape[1]):
        cur = cur + np.clip(target[:, k] - cur, -max_step, max_step)
        out[:, k] = cur
    return out


def slip_profiles(rng: np.random.Generator, kinds: list[str], steps: int, lo: np.ndarray, hi: np.ndarray, Ts: float,
                   max_rate: float | None = None):
    """Slip (N, steps, 2) per profile: constant; random walk (std 5 % of the range per sqrt(s),
    reflected at the bounds); steps (a new random level every ~3 s); corners (a random corner of
    the box held 1-5 periods).  With ``max_rate`` every profile moves at most max_rate * Ts per
    period (steps and corners become ramps at the largest rate)."""
    N = len(kinds)
    mu = np.empty((N, steps, 2))
    kinds_arr = np.array(kinds)
    width = hi - lo
    max_step = None if max_rate is None else max_rate * Ts
    # constant
    start = lo + width * rng.random((N, 2))
    mu[:] = start[:, None, :]
    # random walk: std 5% of the range per sqrt(s), reflected at the bounds
    scale = 0.05 * math.sqrt(Ts) * width
    inc = rng.normal(size=(N, steps, 2)) * scale
    if max_step is not None:
        inc = np.clip(inc, -max_step, max_step)
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
    stepped[:, 0] = start
    sel = kinds_arr == "steps"
    mu[sel] = _rate_limit(stepped, start, max_step)[sel]
    # corners: a random corner held for 1-5 periods (the switching the certificate allows)
    hold = rng.integers(1, 6, size=(N, steps))
    switch = np.zeros((N, steps), dtype=bool)
    nxt = np.zeros(N, dtype=int)
    for k in range(steps):
        on = nxt == k
        switch[on, k] = True
        nxt[on] = k + hold[on, k]
    pick = rng.integers(0, 2, size=(N, steps, 2))
    corner = np.where(pick == 0, lo, hi)
    idx = np.maximum.accumulate(np.where(switch, np.arange(steps)[None, :], 0), axis=1)
    cornered = np.take_along_axis(corner, idx[:, :, None].repeat(2, axis=2), axis=1)
    sel = kinds_arr == "corners"
    c0 = cornered[:, 0].copy()
    mu[sel] = _rate_limit(cornered, c0, max_step)[sel]
    start = np.where((kinds_arr == "corners")[:, None], c0, start)
    return mu


def draw_scenario(model, runs: int, seed: int, steps: int, path: PathGeometry, delays: str = "random",
                  slip: str | None = None, losses: bool | str = True) -> Scenario:
    """Seeded random scenario. ``delays``: 'random' (uniform iid), 'alternating' (min/max),
    'constant-min', 'constant-max'.  ``slip``: a profile for every run, or None to cycle through
    SLIP_PROFILES; 'none' for mu = 1.  With ``network.dropouts.max_consecutive`` > 0 commands are lost
    on the configured Gilbert-Elliott channel (``verification.dropouts``; delay ``inf``), bursts cut
    at the cap (``losses='uncapped'``: not cut; False: no losses).  Runs start at the pose of the config's initial offset with no
    stored commands; :func:`steady_state_start` moves them to the steady state of their first slip."""
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
    m = cfg.network.dropouts.max_consecutive
    if m and losses:  # bursty losses from their own stream: the other draws do not depend on them
        ch = vc.dropouts
        lost = gilbert_elliott(np.random.default_rng([seed, 1]), (runs, n_pk), ch.probability, ch.mean_burst,
                               None if losses == "uncapped" else m)
        lost[:, : model.d_hi] = False  # commands sent before t_0 arrived (the run starts in their steady state)
        taus = with_losses(taus, lost)
    lo = np.array([cfg.slip.right.min, cfg.slip.left.min])
    hi = np.array([cfg.slip.right.max, cfg.slip.left.max])
    if slip == "none":
        kinds = ["none"] * runs
        mu = np.ones((runs, steps, 2))
    else:
        kinds = [slip] * runs if slip else [SLIP_PROFILES[n % len(SLIP_PROFILES)] for n in range(runs)]
        mu = slip_profiles(rng, kinds, steps, lo, hi, model.Ts, cfg.slip.max_rate)
    sd = np.array([vc.noise.position, vc.noise.position, vc.noise.heading])
    noise = rng.normal(size=(runs, steps, 3)) * sd if np.any(sd > 0) else np.zeros((runs, steps, 3))
    off = vc.initial_offset
    e_off = np.array([off.x, off.y, off.theta])
    q0 = np.tile(_pose_from_error(path, e_off), (runs, 1))
    return Scenario(taus, mu, noise, q0, tuple(kinds))


def _pose_from_error(path: PathGeometry, e: np.ndarray) -> np.ndarray:
    """World pose at t = 0 whose error in the first segment's frame is ``e`` (..., 3)."""
    e = np.asarray(e, dtype=float)
    th0 = path.headings[0]
    c, s = math.cos(th0), math.sin(th0)
    q = np.empty_like(e)
    q[..., 0] = path.waypoints[0, 0] + c * e[..., 0] - s * e[..., 1]
    q[..., 1] = path.waypoints[0, 1] + s * e[..., 0] + c * e[..., 1]
    q[..., 2] = th0 + e[..., 2]
    return q


def steady_state_start(model, K: np.ndarray, path: PathGeometry, scen: Scenario) -> Scenario:
    """The same scenario started at the steady state xi*(mu_0) of each run's first slip (plus the
    config's initial offset): error e*, stored commands du* and integrators z* of the robot's
    slip-aware lifted closed loop under that constant slip.  A gain without a steady state (e.g.
    K = 0) leaves the scenario as it was."""
    from dataclasses import replace

    try:
        xi = model.equilibrium(K, scen.mu[:, 0])  # (N, n_s)
    except np.linalg.LinAlgError:
        return scen  # no steady state for this gain (I - A - B K singular): runs start on the path
    if not np.all(np.isfinite(xi)):
        return scen
    off = model.config.verification.initial_offset
    e, du0, z0 = _split_state(model, xi)
    return replace(scen, q0=_pose_from_error(path, e + np.array([off.x, off.y, off.theta])), du0=du0, z0=z0)


def _split_state(model, xi: np.ndarray):
    """(e, stored commands (N, d_hi, 2), integrators or None) of lifted states xi (N, n_s)."""
    n_e, n_u = model.n_e, model.n_u
    du = xi[:, n_e : n_e + model.d_hi * n_u].reshape(-1, model.d_hi, n_u)
    return xi[:, :n_e], du, (xi[:, model.n_s - model.n_z :] if model.n_z else None)


@dataclass(frozen=True)
class SimResult:
    t: np.ndarray  # (steps + 1,)
    q: np.ndarray  # (N, steps + 1, 3) pose at t_k
    e: np.ndarray  # (N, steps + 1, 3) true error at t_k in the segment frame active at t_k
    xi: np.ndarray  # (N, steps, n_s) lifted state the controller used (measured error)
    du: np.ndarray  # (N, steps, 2)
    rho: np.ndarray  # (N, steps, 2) commanded motor speeds J^-1 u_hat_k
    segment: np.ndarray  # (steps + 1,) segment index at t_k
    settled: np.ndarray  # (steps + 1,) bool: outside the fixed transients (see verify for the certified rule)

    def true_xi(self, n_e: int = 3) -> np.ndarray:
        """The robot's true lifted state at t_0..t_{steps-1}: true error, stored commands, integrators."""
        return np.concatenate([self.e[:, :-1], self.xi[:, :, n_e:]], axis=2)


def period(q: np.ndarray, U: np.ndarray, S: np.ndarray, M: np.ndarray, Ts: float, J: np.ndarray,
           J_inv: np.ndarray, rho_sat: float | None) -> np.ndarray:
    """Move the robot through one sampling period: ``U[..., j]`` = u_hat_{k-j} acts on
    [s~_j, s~_{j-1}) (s~_{d_hi} = 0, s~_{-1} = Ts), the robot receives M u_hat (exact arcs)."""
    d_hi = S.shape[-1]
    start = np.zeros(q.shape[:-1])
    for j in range(d_hi, -1, -1):
        end = S[..., j - 1] if j > 0 else np.full(q.shape[:-1], Ts)
        u_eff = np.einsum("...ij,...j->...i", M, saturate(U[..., j, :], J, J_inv, rho_sat))
        q = arc_step(q, u_eff[..., 0], u_eff[..., 1], end - start)
        start = end
    return q


def _initial_memory(model, scen: Scenario):
    N = scen.runs
    uD = np.array([model.V, 0.0])
    U = np.tile(uD, (N, model.d_hi + 1, 1))  # before step k: U[:, j] = u_hat_{k-1-j}
    if scen.du0 is not None:
        U[:, : model.d_hi] = uD + scen.du0
        U[:, model.d_hi] = uD + scen.du0[:, -1]  # shifted out before it could act
    return U


def control_law(model, K: np.ndarray, path: PathGeometry, scen: Scenario) -> Law:
    """The deployed controller's :class:`~robustsynth.runtime.law.Law` for the N runs of ``scen``:
    its memory holds one value per run (numpy arrays), started from ``scen.du0`` and ``scen.z0``."""
    N = scen.runs
    law = Law(np.asarray(K, dtype=float).tolist(), model.Ts, bool(model.n_z), path.table)
    if law.d_hi != model.d_hi:
        raise ValueError(f"K has columns for {law.d_hi} past inputs, the model keeps {model.d_hi}")
    du0 = np.zeros((N, model.d_hi, 2)) if scen.du0 is None else np.asarray(scen.du0, dtype=float)
    z0 = np.zeros((N, model.n_z)) if scen.z0 is None or not model.n_z else np.asarray(scen.z0, dtype=float)
    law.reset(past=[du0[:, j, i].copy() for j in range(model.d_hi) for i in range(2)],
              z=[z0[:, i].copy() for i in range(model.n_z)])
    return law


def _xi(law: Law) -> np.ndarray:
    return np.stack(law.xi, axis=1)


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
    U = _initial_memory(model, scen)
    q = scen.q0.copy()
    t = np.arange(steps + 1) * Ts
    seg = np.array([path.segment(tk) for tk in t])
    Q = np.empty((N, steps + 1, 3))
    E = np.empty((N, steps + 1, 3))
    XI = np.empty((N, steps, model.n_s))
    DU = np.empty((N, steps, 2))
    Q[:, 0] = q
    law = control_law(model, K, path, scen)  # the deployed controller, one memory per run
    for k in range(steps):
        check_interrupt()
        E[:, k] = frame_error(path, seg[k], q, t[k])
        meas = q + scen.noise[:, k]
        dv, dw = law.correction(t[k], meas[:, 0], meas[:, 1], meas[:, 2])  # also z_{k+1} = z_k + Ts (e_x, e_y)_k
        du = np.stack([dv, dw], axis=1)
        U[:, 1:] = U[:, :-1]
        U[:, 0] = uD + du
        XI[:, k], DU[:, k] = _xi(law), du
        M = JHJinv(scen.mu[:, k, 0], scen.mu[:, k, 1], D)  # (N, 2, 2)
        q = period(q, U, S[:, k], M, Ts, J, J_inv, rho_sat)
        Q[:, k + 1] = q
        if progress is not None and (k % 50 == 0 or k == steps - 1):
            progress(k + 1, steps)
    E[:, steps] = frame_error(path, seg[steps], q, t[steps])
    rho = (uD + DU) @ J_inv.T
    since_switch = t - path.t_start[seg]
    settled = (t >= transient) & (since_switch >= transient)
    return SimResult(t, Q, E, XI, DU, rho, seg, settled)


ADVERSARY_OBJECTIVES = ("V", "e_x", "e_y", "e_theta", "motor_speed")


def _top_distinct(score: np.ndarray, width: int) -> np.ndarray:
    """Indices of the ``width`` largest finite scores, distinct values first (equal scores are
    almost always the same state reached twice); short of distinct ones, the next best repeated.
    Ties are broken by index, so the search is deterministic."""
    finite = np.flatnonzero(np.isfinite(score))
    order = finite[np.argsort(-score[finite], kind="stable")]
    s = score[order]
    new = np.ones(s.size, dtype=bool)
    new[1:] = np.abs(np.diff(s)) > 1e-12 * np.maximum(1.0, np.abs(s[1:]))
    picked = np.concatenate([order[new], order[~new]])[:width]
    return np.resize(picked, width)  # fewer admissible candidates than width: cycle through them


def adversarial_nonlinear(model, K: np.ndarray, V_fn: Callable[..., np.ndarray], mu0: np.ndarray, steps: int,
                          width: int = 1, objectives: tuple[str, ...] = ("V",), n_tau: int = 9,
                          with_delay: bool = False) -> dict:
    """Beam search for the slip and delay history that takes the nonlinear robot furthest out, along
    a straight line from the steady states of the slips ``mu0`` (N, 2).

    Every period each kept history is continued with every slip the adversary may pick
    (:func:`~robustsynth.verification.lifted.slip_candidates`: the corners, or with ``slip.max_rate``
    the largest moves towards them) and ``n_tau`` delays of the newest packet (and its loss, on a
    lossy link below the burst cap); the robot moves one period (exact arcs, saturating motors).
    Each candidate is a sample of an admissible history: the next true lifted state xi_{k+1} with,
    for V, the next period's slip mu_{k+1} the adversary may pick that makes V largest (xi_{k+1} does
    not depend on it) and, for a path-dependent ``V_fn``, the period's delay weights.  Kept each
    period: for each start its greedy history (its candidate of largest V), and for each objective
    the ``width`` candidates with the largest score (distinct scores first); so the search finds at
    least the V of the greedy adversary from the same starts.

    Objectives (:data:`ADVERSARY_OBJECTIVES`): ``"V"``, ``max V_fn(xi_{k+1}, mu_{k+1}[, prev])`` (out
    of the certified set); ``"e_x"``, ``"e_y"``, ``"e_theta"``, the absolute error; ``"motor_speed"``, the
    largest |rho| the controller commands at t_{k+1}.

    Returns ``max`` (the largest |e_x|, |e_y|, |e_theta|, |rho| over every candidate), ``max_V``,
    ``V`` and ``tau`` (steps, P) of the kept candidates, and ``worst``: for each objective the
    history of its best candidate, ``{"mu": (T, 2), "tau": (d_hi + T,), "start": index into mu0,
    "value": float, "mu_next": (2,)}`` (the first d_hi delays are the start's; ``mu_next``: the slip V
    was evaluated with), to replay with :func:`simulate` from :func:`adversary_start`."""
    from .lifted import delay_candidates, loss_allowed, slip_candidates

    unknown = set(objectives) - set(ADVERSARY_OBJECTIVES)
    if unknown or not objectives or width < 1:
        raise ValueError(f"objectives must be a non-empty subset of {ADVERSARY_OBJECTIVES} and width >= 1")
    K = np.asarray(K, dtype=float)
    cfg = model.config
    Ts, d_hi, V = model.Ts, model.d_hi, model.V
    D = cfg.robot.track_distance
    J_inv, J = np.asarray(model.J_inv), np.asarray(model.J)
    rho_sat = cfg.robot.max_motor_speed if cfg.verification.motor_saturation else None
    taus = delay_candidates(model, n_tau)  # with a lossy link also inf: the newest packet is lost
    n_tau = taus.size
    path, scen = adversary_start(model, K, mu0, steps)
    N = scen.runs
    U = _initial_memory(model, scen)
    q = scen.q0.copy()
    uD = np.array([V, 0.0])
    hist = scen.taus.copy()  # delays of the last d_hi packets
    mu_prev = np.array(mu0, dtype=float)
    law = control_law(model, K, path, scen)
    best = {o: (-np.inf, -1, -1, None) for o in objectives}  # objective -> (score, step, kept index, V's slip)
    maxima = {"e_x": 0.0, "e_y": 0.0, "e_theta": 0.0, "motor_speed": 0.0}
    max_V = -np.inf
    parents, MU, TAU, VK = [], [], [], []
    for k in range(steps):
        check_interrupt()
        tk = k * Ts
        dv, dw = law.correction(tk, q[:, 0], q[:, 1], q[:, 2])
        U = U.copy()
        U[:, 1:] = U[:, :-1]
        U[:, 0] = uD + np.stack([dv, dw], axis=1)
        if k == 0:  # the starts' own commands
            maxima["motor_speed"] = float(np.max(np.abs(U[:, 0] @ J_inv.T)))
        P = q.shape[0]
        cand_mu = slip_candidates(model, mu_prev)  # (P, n_c, 2)
        n_c = cand_mu.shape[1]
        seq = np.concatenate([np.repeat(hist[:, None, :], n_tau, axis=1),
                              np.broadcast_to(taus[None, :, None], (P, n_tau, 1))], axis=2)
        S = model.s_tilde(seq)[:, :, 0, :]  # (P, n_tau, d_hi)
        shape = (P, n_c, n_tau)
        q_next = period(np.broadcast_to(q[:, None, None, :], shape + (3,)),
                        np.broadcast_to(U[:, None, None], shape + U.shape[1:]),
                        np.broadcast_to(S[:, None], shape + (d_hi,)),
                        np.broadcast_to(JHJinv(cand_mu[..., 0], cand_mu[..., 1], D)[:, :, None], shape + (2, 2)),
                        Ts, J, J_inv, rho_sat)
        e_next = frame_error(path, 0, q_next, tk + Ts)
        rest = np.stack(law.past + law.z, axis=1)  # the controller's memory after step k
        xi_next = np.concatenate([e_next, np.broadcast_to(rest[:, None, None, :], shape + rest.shape[1:])], axis=-1)
        # the sample (xi_{k+1}, mu_{k+1}): xi_{k+1} does not depend on the next period's slip, which the
        # adversary picks among its candidates to make V largest
        nxt_mu = slip_candidates(model, cand_mu)  # (P, n_c, n_c', 2)
        n_n = nxt_mu.shape[2]
        xi_b = np.broadcast_to(xi_next[:, :, :, None, :], shape + (n_n, xi_next.shape[-1]))
        mu_b = np.broadcast_to(nxt_mu[:, :, None], shape + (n_n, 2))
        if with_delay:
            dwt = model.delay_weights(S)  # (P, n_tau, n_d): this period's, the next sample's "previous"
            v_all = V_fn(xi_b, mu_b, prev=np.broadcast_to(dwt[:, None, :, None], shape + (n_n, dwt.shape[-1])))
        else:
            v_all = V_fn(xi_b, mu_b)
        v_arg = np.argmax(v_all, axis=-1)
        v = np.take_along_axis(v_all, v_arg[..., None], axis=-1)[..., 0]
        rho = np.max(np.abs((uD + xi_next @ K.T) @ J_inv.T), axis=-1)
        scores = {"V": v, "e_x": np.abs(e_next[..., 0]), "e_y": np.abs(e_next[..., 1]),
                  "e_theta": np.abs(e_next[..., 2]), "motor_speed": rho}
        if model.dropouts:  # a loss only while the burst is below the cap
            bad = np.isinf(taus)[None, None, :] & ~loss_allowed(model, hist)[:, None, None]
            scores = {o: np.where(bad, -np.inf, x) for o, x in scores.items()}
        flat = {o: x.reshape(-1) for o, x in scores.items()}
        for o in maxima:
            maxima[o] = max(maxima[o], float(np.max(flat[o])))
        max_V = max(max_V, float(np.max(flat["V"])))
        per = n_c * n_tau  # the first N histories are greedy, one per start: each goes on with its largest V
        greedy = np.arange(N) * per + np.argmax(flat["V"].reshape(P, per)[:N], axis=1)
        keep = np.concatenate([greedy] + [_top_distinct(flat[o], width) for o in objectives])
        pi, ci, ti = np.unravel_index(keep, shape)
        for j, o in enumerate(objectives):
            i = N + j * width
            if flat[o][keep[i]] > best[o][0]:
                best[o] = (float(flat[o][keep[i]]), k, i, nxt_mu[pi[i], ci[i], v_arg[pi[i], ci[i], ti[i]]])
        q = q_next[pi, ci, ti]
        U = U[pi]
        law.past = [x[pi] for x in law.past]
        law.z = [x[pi] for x in law.z]
        mu_prev = cand_mu[pi, ci]
        hist = np.concatenate([hist[pi, 1:], taus[ti][:, None]], axis=1)
        parents.append(pi)
        MU.append(mu_prev)
        TAU.append(taus[ti])
        VK.append(flat["V"][keep])
    worst = {}
    for o, (value, k, i, mu_v) in best.items():
        mu_h, tau_h = np.empty((k + 1, 2)), np.empty(k + 1)
        for j in range(k, -1, -1):  # walk the history back to its start
            mu_h[j], tau_h[j] = MU[j][i], TAU[j][i]
            i = parents[j][i]
        worst[o] = {"mu": mu_h, "tau": np.concatenate([scen.taus[i], tau_h]), "start": int(i), "value": value,
                    "mu_next": mu_v}
    return {"max": maxima, "max_V": max_V, "V": np.array(VK), "tau": np.array(TAU), "worst": worst}


def adversary_start(model, K: np.ndarray, mu0: np.ndarray, steps: int) -> tuple[PathGeometry, Scenario]:
    """The straight line and the starts of :func:`adversarial_nonlinear`: the steady states of the
    slips ``mu0`` (N, 2), the last d_hi packets delayed by the middle of [tau_min, tau_max].  The
    scenario holds no slip or delays beyond the start (``mu`` is ``mu0``, one period)."""
    mu0 = np.asarray(mu0, dtype=float)
    N, d_hi, V = mu0.shape[0], model.d_hi, model.V
    dl = model.config.network.delay
    path = make_path(((0.0, 0.0), (V * model.Ts * (steps + 10), 0.0)), V)
    e0, du0, z0 = _split_state(model, model.equilibrium(np.asarray(K, dtype=float), mu0))
    scen = Scenario(np.full((N, d_hi), (dl.min + dl.max) / 2.0), mu0[:, None, :], np.zeros((N, 1, 3)),
                    _pose_from_error(path, e0), (), du0, z0)
    return path, scen
