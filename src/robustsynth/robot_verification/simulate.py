"""The robot in closed loop with the deployed controller, vectorized across Monte Carlo runs, and
the adversary that searches for the history taking it furthest out.

The controller is the deployed :class:`~robustsynth.law.Law` (bit for bit); the robot and
its network are a :class:`~robustsynth.plants.kinematic.KinematicRobot`; what the world does (slip,
delays, losses, starts) is a :class:`~robustsynth.scenarios.Scenario`.  Sensors sample at
``t_k = k Ts``; the controller computes ``du_k = K xi_k`` from the measured pose in the current
segment's frame L (eq. 13, 16, 17).  The only Python loop is over time steps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..certificate.lyapunov import rows_times
from ..errors import check_interrupt
from ..plants.kinematic import KinematicRobot
from ..plants.path import PathGeometry, arc_frame_error, frame_error, make_path, path_from_yaw_rates, pose_from_error
from ..law import Law, tangent_length, turn_shape
from ..scenarios import Scenario, slip_candidates, split_state, track_changes

__all__ = [
    "SimResult",
    "simulate",
    "control_law",
    "adversarial_nonlinear",
    "adversary_start",
    "adversary_course",
    "adversary_courses",
    "ADVERSARY_OBJECTIVES",
    "FREE_YAW",
    "run_logs",
    "applied_times",
    "simulate_compensated",
    "CompensatedRuns",
    "EstimatorLoop",
]


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


def control_law(model, K: np.ndarray, path: PathGeometry, scen: Scenario) -> Law:
    """The deployed controller's :class:`~robustsynth.law.Law` for the N runs of ``scen``:
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
    return _closed_loop(model, K, path, scen, transient, progress)


def _closed_loop(model, K: np.ndarray, path: PathGeometry, scen: Scenario, transient: float = 0.0,
                 progress: Callable[[int, int], None] | None = None, loop: "EstimatorLoop | None" = None) -> SimResult:
    """:func:`simulate`, and with ``loop`` the slip-compensated law's (:func:`simulate_compensated`): the law's
    command of each period passes through ``loop.command`` before it is sent."""
    K = np.asarray(K, dtype=float)
    Ts, V = model.Ts, model.V
    N, steps = scen.runs, scen.steps
    robot = KinematicRobot.of(model)
    J_inv = robot.J_inv
    S = model.s_tilde(scen.taus)  # (N, steps, d_hi)
    uD = np.array([V, 0.0])
    U = robot.memory(scen.du0, N)
    q = scen.q0.copy()
    t = np.arange(steps + 1) * Ts
    seg = np.array([path.segment(tk) for tk in t])
    Q = np.empty((N, steps + 1, 3))
    E = np.empty((N, steps + 1, 3))
    XI = np.empty((N, steps, model.n_s))
    DU = np.empty((N, steps, 2))
    FF = np.zeros(steps)
    g = model.turn_feedforward  # the command per rad/s of the reference's yaw rate
    Q[:, 0] = q
    law = control_law(model, K, path, scen)  # the deployed controller, one memory per run
    for k in range(steps):
        check_interrupt()
        E[:, k] = frame_error(path, seg[k], q, t[k])
        meas = q + scen.noise[:, k]
        dv, dw = law.correction(t[k], meas[:, 0], meas[:, 1], meas[:, 2])  # also z_{k+1} = z_k + Ts (e_x, e_y)_k
        du = np.stack([dv, dw], axis=1)
        FF[k] = law.feedforward(t[k])  # a turning reference's yaw rate w_k (0 on a polyline)
        u = uD + du + FF[k] * g  # the law's command, as Controller.step forms it
        XI[:, k], DU[:, k] = _xi(law), du
        U = robot.send(U, u if loop is None else loop.command(k, float(t[k]), meas, XI[:, k], u))
        mu_k, change = scen.slip_in_period(k)
        q = robot.period(q, U, S[:, k], mu_k, switch=change)
        Q[:, k + 1] = q
        if progress is not None and (k % 50 == 0 or k == steps - 1):
            progress(k + 1, steps)
    E[:, steps] = frame_error(path, seg[steps], q, t[steps])
    rho = (uD + DU + FF[:, None] * g) @ J_inv.T if loop is None else loop.sent @ J_inv.T
    since_switch = t - path.t_start[seg]
    settled = (t >= transient) & (since_switch >= transient)
    return SimResult(t, Q, E, XI, DU, rho, seg, settled)


@dataclass(frozen=True)
class CompensatedRuns:
    """:func:`simulate_compensated`'s runs: the closed loop (``sim``: ``du`` the law's corrections, ``rho`` the
    compensated motor speeds sent) and per run and period the estimate each command was compensated with
    (``mu_hat``), the command sent (``sent``: (V_hat, omega_hat), compensated), whether the certificate's condition
    was sure to hold for it (``holds``), its margin (error less half-width + lag; NaN without an estimate) and the
    monitor's status word (``status``)."""

    sim: SimResult
    sent: np.ndarray  # (N, steps, 2)
    mu_hat: np.ndarray  # (N, steps, 2)
    holds: np.ndarray  # (N, steps) bool
    margin: np.ndarray  # (N, steps)
    status: np.ndarray  # (N, steps) int
    model: object = None  # the robot driven (its true slip), and the scenario (for the logs)
    scen: object = None

    def logs(self, name: str = "run") -> list:
        """The runs as robot logs (:func:`run_logs`) with the estimate's columns: mu_hat_r, mu_hat_l, condition."""
        est = np.concatenate([self.mu_hat, self.holds[..., None].astype(float)], axis=2)
        return run_logs(self.model, self.sim, self.scen, name, estimate=est)


def applied_times(model, taus: np.ndarray, steps: int) -> np.ndarray:
    """(N, steps): the instant each command sent at t_k (k >= 0) started acting, NaN when lost, for packets with the
    delays ``taus`` (N, d_hi + steps; the d_hi sent before t_0 first).  That instant is the simulator's
    (``s_tilde_sequence``): a command that arrives before an older one waits for it, so it acts from
    max(t_k + tau_k, the older commands' arrivals)."""
    d_hi = model.d_hi
    n = d_hi + steps
    sent = (np.arange(n) - d_hi) * model.Ts
    arrival = sent + np.asarray(taus)[:, :n]
    acts_from = np.maximum.accumulate(np.where(np.isfinite(arrival), arrival, -np.inf), axis=1)[:, d_hi:]
    return np.where(np.isfinite(arrival[:, d_hi:]), acts_from, np.nan)


class EstimatorLoop:
    """The slip-compensated law's runtime part for N robots at once (docs/theory.md §18): per robot the deployed
    :class:`~robustsynth.monitor.Monitor` and :class:`~robustsynth.law.Compensator` of ``description``, fed each
    period as :meth:`~robustsynth.law.Compensator.step` feeds them (the fallback left out: the law is what is
    judged), the command divided by the estimate vectorized (:func:`~robustsynth.law.compensate`, the runtime's
    operations).  ``applied``: (N, steps) the instant each command started acting (:func:`applied_times`), reported
    at the first sampling instant at or after it.  Records per robot and period the estimate used (``mu_hat``), the
    command sent, the condition (``holds``), its margin and the monitor's status word."""

    def __init__(self, description: dict, applied: np.ndarray) -> None:
        from ..law import Compensator
        from ..monitor import Monitor

        N, steps = applied.shape
        self.mons = [Monitor(description) for _ in range(N)]
        self.comps = [Compensator(description) for _ in range(N)]
        self.order = [sorted((float(applied[n, j]), j) for j in range(steps) if np.isfinite(applied[n, j]))
                      for n in range(N)]
        self.next = [0] * N
        self.mu_hat, self.sent = np.empty((N, steps, 2)), np.empty((N, steps, 2))
        self.holds, self.margin = np.zeros((N, steps), dtype=bool), np.full((N, steps), np.nan)
        self.status = np.zeros((N, steps), dtype=int)

    def command(self, k: int, t: float, meas: np.ndarray, xi: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The commands (N, 2) to send at period k for the law's ``u`` (N, 2), the poses measured ``meas`` (N, 3) and
        the lifted states ``xi`` (N, n_s) the law used."""
        from ..law import compensate

        for n, (mon, c) in enumerate(zip(self.mons, self.comps)):
            reports, o = [], self.order[n]
            while self.next[n] < len(o) and o[self.next[n]][0] <= t + 1e-12:
                reports.append((o[self.next[n]][1], o[self.next[n]][0]))
                self.next[n] += 1
            self.status[n, k] = mon.check(t, float(meas[n, 0]), float(meas[n, 1]), float(meas[n, 2]), xi[n].tolist(),
                                          (float(u[n, 0]), float(u[n, 1])), reports)
            c.take(mon)  # as Compensator.step
            self.holds[n, k], self.mu_hat[n, k] = c.holds, c.mu
            if c.margin is not None:
                self.margin[n, k] = c.margin
        self.sent[:, k] = np.stack(compensate(u[:, 0], u[:, 1], self.mu_hat[:, k, 0], self.mu_hat[:, k, 1],
                                              self.comps[0].half_D), axis=1)
        for n, mon in enumerate(self.mons):
            mon.sent(k, t, (float(self.sent[n, k, 0]), float(self.sent[n, k, 1])))
        return self.sent[:, k]


def simulate_compensated(model, K: np.ndarray, path: PathGeometry, scen: Scenario, description: dict,
                         progress: Callable[[int, int], None] | None = None) -> CompensatedRuns:
    """The slip-compensated law in closed loop (docs/theory.md §18): :func:`simulate` with, per run, the deployed
    monitor and compensator of ``description`` in the loop (:class:`EstimatorLoop`).  The robot is ``model``'s with
    the scenario's true slip.  The fallback is not engaged (as in ``verify``'s runs: the law is what is judged)."""
    loop = EstimatorLoop(description, applied_times(model, scen.taus, scen.steps))
    sim = _closed_loop(model, K, path, scen, 0.0, progress, loop)
    return CompensatedRuns(sim, loop.sent, loop.mu_hat, loop.holds, loop.margin, loop.status, model, scen)


ADVERSARY_OBJECTIVES = ("V", "e_x", "e_y", "e_theta", "motor_speed")
WITHIN_PERIOD_TIMES = (0.0, 0.5)  # the adversary's times of a slip change, in periods, each track on its own
# the adversary's courses along arcs (a turning model), "arcs-A-G": from t = 0 on, arcs of A periods at the largest
# yaw rate the model covers, alternating left and right, G periods straight between them (a review found short
# arcs and gaps push harder than long ones: 1.13 against 0.98 cm of |e_y| on configs/turns.yaml)
ARC_COURSES = ("arcs-10-3", "arcs-2-1", "arcs-1-1")
# the adversary's course along which it also picks the reference's yaw rate each period (a turning model): w_{k-1} and
# its steps of max_step either way, within +-max_yaw_rate
FREE_YAW = "free-yaw"


def _top_distinct(score: np.ndarray, width: int) -> np.ndarray:
    """Indices of the ``width`` largest finite scores, distinct values first (equal scores are
    almost always the same state reached twice); short of distinct ones, the next best repeated.
    Ties are broken by index, so the search is deterministic.

    Only the best few are sorted: every score at or above the ``TOP_PREFIX * width``-th largest (ties
    with it included) is a prefix of the full order, and whether a score counts as distinct depends
    only on its predecessor in that order; when the prefix holds ``width`` distinct scores the pick
    is the full sort's, else the whole array is sorted."""
    finite = np.flatnonzero(np.isfinite(score))
    vals = score[finite]
    m = TOP_PREFIX * width
    if vals.size > 2 * m:
        cut = np.partition(vals, vals.size - m)[vals.size - m]  # the m-th largest
        head = finite[vals >= cut]  # every score >= it, in index order (as the stable sort keeps ties)
        picked = _distinct_first(head, score, width)
        if picked is not None:
            return picked
    return _distinct_first(finite, score, width, full=True)


TOP_PREFIX = 8  # _top_distinct sorts the largest TOP_PREFIX * width scores first


def _distinct_first(idx: np.ndarray, score: np.ndarray, width: int, full: bool = False) -> np.ndarray | None:
    """:func:`_top_distinct` on the candidates ``idx`` (ascending): None when they are a prefix of the
    order (not ``full``) that holds fewer than ``width`` distinct scores."""
    order = idx[np.argsort(-score[idx], kind="stable")]
    s = score[order]
    new = np.ones(s.size, dtype=bool)
    new[1:] = np.abs(np.diff(s)) > 1e-12 * np.maximum(1.0, np.abs(s[1:]))
    if not full and np.count_nonzero(new) < width:
        return None
    picked = np.concatenate([order[new], order[~new]])[:width]
    return np.resize(picked, width)  # fewer admissible candidates than width: cycle through them


def adversarial_nonlinear(model, K: np.ndarray, V_fn: Callable[..., np.ndarray], mu0: np.ndarray, steps: int,
                          width: int = 1, objectives: tuple[str, ...] = ("V",), n_tau: int = 9,
                          with_delay: bool = False, starts: np.ndarray | None = None,
                          within_period: bool = False, course: str = "straight", slip_free: bool = False) -> dict:
    """Beam search for the slip and delay history that takes the nonlinear robot furthest out, along
    a straight line (``course`` "straight") or, for a turning model, along one of :func:`adversary_course`'s
    courses of arcs (the turning feedforward in the commands) or (FREE_YAW) along references whose yaw rate the
    search picks each period too (w_{k-1} and its steps of ``max_step`` either way, within +-``max_yaw_rate``;
    w_{-1} = 0), from the steady states of the slips ``mu0`` (N, 2).

    The search runs in the frame of each history's reference at t_k, where the pose is the error: the law
    (:class:`~robustsynth.law.Law`, the deployed one) measures a pose at the origin of that frame, and
    :func:`~robustsynth.plants.path.arc_frame_error` moves the pose into the next reference's frame.  Its commands are the deployed law's
    up to the round-off of that change of frame (a replay in the world frame agrees to 1e-9 or better).

    Every period each kept history is continued with every slip the adversary may pick
    (:func:`~robustsynth.scenarios.slip_candidates`: the corners, or with ``slip.max_rate``
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
    "value": float, "mu_next": (2,), "course": str, "yaw": (T + 1,)}`` (the first d_hi delays are the start's;
    ``mu_next``: the slip V was evaluated with; ``yaw``: the reference's yaw rate on each period and on the next
    one, for |rho| the one that makes it largest), to replay with :func:`simulate` from
    :func:`adversary_start` (``yaw`` builds the reference of the FREE_YAW course).

    ``starts`` (N, n_s): lifted states to start from instead of the steady states (the boundary of
    the certified set, :func:`~robustsynth.robot_verification.probe.boundary_states`), with slips ``mu0``.

    ``within_period`` (slip that may jump at any time, docs/theory.md §11): from the second period on
    the adversary also picks *when* within the period each track's slip takes its new value, at
    :data:`WITHIN_PERIOD_TIMES` of the period (0: at the sampling instant), every pair of times for the
    two tracks; each worst history then has ``t_switch`` (T, 2), to replay as ``Scenario.mu_switch``.

    ``slip_free``: ``V_fn`` does not depend on the slip (a common Lyapunov matrix), so it is evaluated once
    per candidate instead of once per next slip (the same values; the slip it reports is the first)."""
    unknown = set(objectives) - set(ADVERSARY_OBJECTIVES)
    if unknown or not objectives or width < 1:
        raise ValueError(f"objectives must be a non-empty subset of {ADVERSARY_OBJECTIVES} and width >= 1")
    K = np.asarray(K, dtype=float)
    Ts, V = model.Ts, model.V
    robot = KinematicRobot.of(model)
    J_inv = robot.J_inv
    taus = model.network.candidates(n_tau)  # with a lossy link also inf: the newest packet is lost
    n_tau = taus.size
    path, scen = adversary_start(model, K, mu0, steps, starts, course)
    N = scen.runs
    U = robot.memory(scen.du0, N)
    # each history's pose in the frame of its reference at t_k, i.e. its error: the histories of the free course
    # each have their own reference, and the law measures the error of a pose at the origin of that frame
    q = frame_error(path, 0, scen.q0, 0.0)
    law = control_law(model, K, _LOCAL_FRAME, scen)
    free = course == FREE_YAW
    if free:
        w_prev = np.zeros(N)  # the starts' commands carry no feedforward
    uD = np.array([V, 0.0])
    hist = scen.taus.copy()  # delays of the last d_hi packets
    mu_prev = np.array(mu0, dtype=float)
    best = {o: (-np.inf, -1, -1, None, 0.0) for o in objectives}  # objective -> (score, step, kept index, V's slip, w_{k+1})
    maxima = {"e_x": 0.0, "e_y": 0.0, "e_theta": 0.0, "motor_speed": 0.0}
    max_V = -np.inf
    parents, MU, TAU, VK, SW, YAW = [], [], [], [], [], []
    jumps = within_period and model.slip_step is None
    for k in range(steps):
        check_interrupt()
        tk = k * Ts
        P = q.shape[0]
        if free:  # the reference's yaw rate on this period: the adversary's pick
            W = model.turns.next_yaw_rates(w_prev)  # (P, n_y)
        else:
            W = np.full((P, 1), path.feedforward(tk))
        n_y = W.shape[1]
        dv, dw = law.correction(0.0, q[:, 0], q[:, 1], q[:, 2])
        U = robot.send(np.broadcast_to(U[:, None], (P, n_y) + U.shape[1:]),
                       (uD + np.stack([dv, dw], axis=1))[:, None] + W[..., None] * model.turn_feedforward)  # (P, n_y, d_hi + 1, 2)
        if k == 0:  # the starts' own commands
            maxima["motor_speed"] = float(np.max(np.abs(U[:, :, 0] @ J_inv.T)))
        cand_mu, S, sw, shape, e_next, xi_next = _one_period(model, robot, law, q, U, hist, taus, mu_prev, W,
                                                             jumps and k > 0)
        n_c, n_w = cand_mu.shape[1], sw.shape[0]
        v, v_arg, nxt_mu = _next_V(model, V_fn, xi_next, cand_mu, S, shape, slip_free, with_delay)
        W1, w1_arg, rho = _next_motor_speeds(model, path, free, W, shape, xi_next, K, J_inv, tk + Ts)
        flat = _scores(model, v, e_next, rho, taus, hist)
        for o in maxima:
            maxima[o] = max(maxima[o], float(np.max(flat[o])))
        max_V = max(max_V, float(np.max(flat["V"])))
        keep = _kept(flat, N, P, n_c * n_w * n_tau * n_y, objectives, width)
        pi, ci, wi, ti, yi = np.unravel_index(keep, shape)
        _update_best(best, objectives, flat, keep, (pi, ci, wi, ti, yi), N, width, k, W1, w1_arg, nxt_mu, v_arg)
        q = e_next[pi, ci, wi, ti, yi]
        U = U[pi, yi]
        law.past = [x[pi] for x in law.past]
        law.z = [x[pi] for x in law.z]
        mu_prev = cand_mu[pi, ci]
        if free:
            w_prev = W[pi, yi]
        hist = np.concatenate([hist[pi, 1:], taus[ti][:, None]], axis=1)
        parents.append(pi)
        MU.append(mu_prev)
        SW.append(sw[wi])
        TAU.append(taus[ti])
        YAW.append(W[pi, yi])
        VK.append(flat["V"][keep])
    worst = _worst_histories(best, parents, MU, TAU, SW, YAW, scen.taus, model.n_p, course)
    return {"max": maxima, "max_V": max_V, "V": np.array(VK), "tau": np.array(TAU), "worst": worst,
            "switch_times": tuple(WITHIN_PERIOD_TIMES) if jumps and steps > 1 else (0.0,)}


def _next_motor_speeds(model, path, free: bool, W: np.ndarray, shape: tuple, xi_next: np.ndarray, K: np.ndarray,
                       J_inv: np.ndarray, t_next: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The largest |rho| each candidate's commands at t_{k+1} reach, with the next period's feedforward (on the free
    course the adversary's largest): the next yaw rates W1 (P, n_y, n_y'), the index of the largest and |rho|."""
    P, uD = W.shape[0], np.array([model.V, 0.0])
    W1 = model.turns.next_yaw_rates(W) if free else np.full((P, 1, 1), path.feedforward(t_next))  # (P, n_y, n_y')
    u1 = (uD + np.broadcast_to(W1[:, None, None, None, :, :, None], shape + W1.shape[-1:] + (1,)) * model.turn_feedforward
          + rows_times(xi_next, K.T)[..., None, :])
    # each motor's |rho| = |J_inv u1|, written out (a stacked matmul of 2 x 2 products: ~11x slower), and the larger of
    # the two (np.max over an axis of 2: 25x slower)
    u_v, u_w = u1[..., 0], u1[..., 1]  # (not W1: the command's forward speed and yaw rate)
    rho_all = np.maximum(np.abs(u_v * J_inv[0, 0] + u_w * J_inv[0, 1]), np.abs(u_v * J_inv[1, 0] + u_w * J_inv[1, 1]))
    w1_arg = np.argmax(rho_all, axis=-1)
    rho = np.take_along_axis(rho_all, w1_arg[..., None], axis=-1)[..., 0]
    return W1, w1_arg, rho


def _scores(model, v: np.ndarray, e_next: np.ndarray, rho: np.ndarray, taus: np.ndarray, hist: np.ndarray
            ) -> dict[str, np.ndarray]:
    """Each objective's score of every candidate, flat; -inf for a loss where the burst is at the cap."""
    scores = {"V": v, "e_x": np.abs(e_next[..., 0]), "e_y": np.abs(e_next[..., 1]),
              "e_theta": np.abs(e_next[..., 2]), "motor_speed": rho}
    net = model.network
    if net.max_lost:  # a loss only while the burst is below the cap
        bad = np.isinf(taus)[None, None, None, :, None] & ~net.loss_allowed(hist)[:, None, None, None, None]
        scores = {o: np.where(bad, -np.inf, x) for o, x in scores.items()}
    return {o: x.reshape(-1) for o, x in scores.items()}


def _kept(flat: dict[str, np.ndarray], N: int, P: int, per: int, objectives: tuple[str, ...], width: int) -> np.ndarray:
    """The candidates kept for the next period (flat indices): each start's greedy history, then for each objective
    the ``width`` of the largest distinct scores."""
    # the first N histories are greedy, one per start: each goes on with its largest V
    greedy = np.arange(N) * per + np.argmax(flat["V"].reshape(P, per)[:N], axis=1)
    keep = np.concatenate([greedy] + [_top_distinct(flat[o], width) for o in objectives])
    return keep


def _update_best(best: dict, objectives: tuple[str, ...], flat: dict[str, np.ndarray], keep: np.ndarray, idx: tuple,
                 N: int, width: int, k: int, W1: np.ndarray, w1_arg: np.ndarray, nxt_mu: np.ndarray,
                 v_arg: np.ndarray) -> None:
    """Each objective's best candidate so far (its score, step, kept index, V's next slip and next yaw rate) in
    ``best``, from this period's kept candidates (``idx``: their indices in the candidates' shape)."""
    pi, ci, wi, ti, yi = idx
    for j, o in enumerate(objectives):
        i = N + j * width
        if flat[o][keep[i]] > best[o][0]:
            at = (pi[i], ci[i], wi[i], ti[i], yi[i])
            w1 = W1[pi[i], yi[i], w1_arg[at]] if o == "motor_speed" else W1[pi[i], yi[i], 0]
            best[o] = (float(flat[o][keep[i]]), k, i, nxt_mu[pi[i], ci[i], v_arg[at]], float(w1))


def _one_period(model, robot, law, q: np.ndarray, U: np.ndarray, hist: np.ndarray, taus: np.ndarray,
                mu_prev: np.ndarray, W: np.ndarray, jumps: bool) -> tuple:
    """One period of every kept history (P of them) with every candidate of the adversary: the slips it may pick
    (n_c), the times within the period each track's new slip takes over (n_w; only the instant unless ``jumps``),
    the delays of the newest packet (n_tau) and the reference's yaw rates ``W`` (n_y).  Returns the candidate slips
    (P, n_c, 2), the switching instants S (P, n_tau, d_hi), the switching times (n_w, 2), the candidates' shape
    (P, n_c, n_w, n_tau, n_y), their errors at t_{k+1} and their lifted states xi_{k+1}."""
    Ts, V, d_hi = model.Ts, model.V, model.d_hi
    P, n_tau, n_y = q.shape[0], taus.size, W.shape[1]
    cand_mu = slip_candidates(model, mu_prev)  # (P, n_c, 2)
    n_c = cand_mu.shape[1]
    seq = np.concatenate([np.repeat(hist[:, None, :], n_tau, axis=1),
                          np.broadcast_to(taus[None, :, None], (P, n_tau, 1))], axis=2)
    S = model.s_tilde(seq)[:, :, 0, :]  # (P, n_tau, d_hi)
    # when each track's new slip takes over (n_w, 2): every pair of the times, each track on its own
    times = WITHIN_PERIOD_TIMES if jumps else (0.0,)
    sw = Ts * np.array([(a, b) for a in times for b in times])
    n_w = sw.shape[0]
    shape = (P, n_c, n_w, n_tau, n_y)
    after = np.broadcast_to(cand_mu[:, :, None, None, None, :], shape + cand_mu.shape[-1:])
    args = (np.broadcast_to(q[:, None, None, None, None, :], shape + (3,)),
            np.broadcast_to(U[:, None, None, None], shape + U.shape[2:]),
            np.broadcast_to(S[:, None, None, :, None], shape + (d_hi,)))
    if n_w == 1 and not np.any(sw):
        q_next = robot.period(*args, after)
    else:  # the earlier track's change first (the slip in between: that track new, the other old)
        before = np.broadcast_to(mu_prev[:, None, None, None, None, :], after.shape)
        q_next = robot.period(*args, before,
                              switch=track_changes(before, after, np.broadcast_to(sw[None, None, :, None, None, :], shape + (2,))))
    e_next = arc_frame_error(q_next, W[:, None, None, None, :], Ts, V)
    rest = np.stack(law.past + law.z, axis=1)  # the controller's memory after step k
    xi_next = np.concatenate([e_next, np.broadcast_to(rest[:, None, None, None, None, :], shape + rest.shape[1:])],
                             axis=-1)
    return cand_mu, S, sw, shape, e_next, xi_next


def _next_V(model, V_fn: Callable[..., np.ndarray], xi_next: np.ndarray, cand_mu: np.ndarray, S: np.ndarray,
            shape: tuple, slip_free: bool, with_delay: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """V at each candidate's sample (xi_{k+1}, mu_{k+1}): xi_{k+1} does not depend on the next period's slip, which
    the adversary picks among its candidates to make V largest.  Returns V, the index of that slip and the next
    period's candidate slips (P, n_c, n_c', 2)."""
    nxt_mu = slip_candidates(model, cand_mu)  # (P, n_c, n_c', 2)
    n_n = nxt_mu.shape[2]
    if slip_free and not with_delay:
        v = V_fn(xi_next)
        v_arg = np.zeros(shape, dtype=np.intp)
    else:
        xi_b = np.broadcast_to(xi_next[..., None, :], shape + (n_n, xi_next.shape[-1]))
        mu_b = np.broadcast_to(nxt_mu[:, :, None, None, None], shape + (n_n, nxt_mu.shape[-1]))
        if with_delay:
            dwt = model.delay_weights(S)  # (P, n_tau, n_d): this period's, the next sample's "previous"
            v_all = V_fn(xi_b, mu_b, prev=np.broadcast_to(dwt[:, None, None, :, None, None], shape + (n_n, dwt.shape[-1])))
        else:
            v_all = V_fn(xi_b, mu_b)
        v_arg = np.argmax(v_all, axis=-1)
        v = np.take_along_axis(v_all, v_arg[..., None], axis=-1)[..., 0]
    return v, v_arg, nxt_mu


def _worst_histories(best: dict, parents: list, MU: list, TAU: list, SW: list, YAW: list, start_taus: np.ndarray,
                     n_p: int, course: str) -> dict[str, dict]:
    """For each objective the history of its best candidate, walked back from the step it was found at to its
    start (``start_taus``: the starts' delays)."""
    worst = {}
    for o, (value, k, i, mu_v, w1) in best.items():
        mu_h, tau_h, sw_h, yaw_h = np.empty((k + 1, n_p)), np.empty(k + 1), np.empty((k + 1, 2)), np.empty(k + 1)
        for j in range(k, -1, -1):  # walk the history back to its start
            mu_h[j], tau_h[j], sw_h[j], yaw_h[j] = MU[j][i], TAU[j][i], SW[j][i], YAW[j][i]
            i = parents[j][i]
        worst[o] = {"mu": mu_h, "tau": np.concatenate([start_taus[i], tau_h]), "start": int(i), "value": value,
                    "mu_next": mu_v, "t_switch": sw_h, "course": course, "yaw": np.append(yaw_h, w1)}
    return worst


_LOCAL_FRAME = make_path(((0.0, 0.0), (1.0, 0.0)), 1.0)  # the law measures a pose given in its reference's frame at t_k


def merge_adversaries(a: dict, b: dict) -> dict:
    """The union of two searches' results (:func:`adversarial_nonlinear`): the larger maxima, every kept
    candidate's V, and each objective's larger worst history.  A beam search with more choices per
    period does not always find more (it keeps different histories), so a search that may also pick
    the time of a slip change is taken together with the one that may not."""
    return {"max": {k: max(a["max"][k], b["max"][k]) for k in a["max"]}, "max_V": max(a["max_V"], b["max_V"]),
            "V": np.hstack([a["V"], b["V"]]), "tau": np.hstack([a["tau"], b["tau"]]),
            "worst": {o: max(a["worst"][o], b["worst"][o], key=lambda h: h["value"]) for o in a["worst"]},
            "switch_times": tuple(sorted(set(a["switch_times"]) | set(b["switch_times"])))}


def adversary_courses(model) -> tuple[str, ...]:
    """The courses :func:`adversarial_nonlinear` is run on for ``model``: a straight line, and for a turning
    model (``model.turns``) the ARC_COURSES and the FREE_YAW course."""
    return ("straight",) + ((*ARC_COURSES, FREE_YAW) if getattr(model, "turns", None) is not None else ())


def adversary_course(model, steps: int, course: str = "straight", yaw: np.ndarray | None = None) -> PathGeometry:
    """The adversary's path, at least ``steps`` + 10 periods long: a straight line, or ("arcs-A-G", a
    turning model only) from t = 0 on corners rounded by arcs of radius V^D / w_bar that take A periods each
    at the largest yaw rate the model covers (at least one period's turn), turning left and right in turn
    (steps of w_bar), G periods straight between them.  The starts' stored commands carry no feedforward
    (w = 0 before t = 0): the first step is one of w_bar, which the certificate allows.  FREE_YAW (a turning
    model only): the reference of the yaw rates ``yaw`` (one per period from t = 0, then straight on), a history
    of the adversary that picks them; without ``yaw`` a straight line (``steps`` unused: it goes on straight)."""
    V, Ts = model.V, model.Ts
    length = V * Ts * (steps + 10)
    if course == "straight":
        return make_path(((0.0, 0.0), (length, 0.0)), V)
    turns = getattr(model, "turns", None)
    if course == FREE_YAW and turns is not None:
        return path_from_yaw_rates(() if yaw is None else yaw, V, Ts)
    parts = course.split("-")
    if turns is None or course not in ARC_COURSES or len(parts) != 3:
        raise ValueError(f"course must be 'straight' or, for a turning model, one of {ARC_COURSES + (FREE_YAW,)}; "
                         f"got {course!r}")
    arc, gap = int(parts[1]), int(parts[2])
    wbar = float(turns.max_yaw_rate)
    r = V / wbar
    turn = min(wbar * arc * Ts, max(1.0, wbar * Ts))  # [rad] per corner
    # eased turns where the certificate covers steps smaller than w_bar (reference.turn_ramp): the same ramp
    ramp = wbar * Ts / float(turns.max_step) if float(turns.max_step) < wbar else None
    tangent = tangent_length(turn, *turn_shape(turn, r, V * ramp)) if ramp else r * np.tan(turn / 2.0)
    legs = [tangent]
    while sum(legs) < length + 2 * tangent:
        legs.append(2 * tangent + V * Ts * gap)
    legs.append(tangent + V * Ts * gap)
    heading, wp = 0.0, [np.zeros(2)]
    for i, leg in enumerate(legs):
        wp.append(wp[-1] + leg * np.array([np.cos(heading), np.sin(heading)]))
        heading = turn if i % 2 == 0 else 0.0
    return make_path(np.array(wp), V, r, Ts, ramp)


def adversary_start(model, K: np.ndarray, mu0: np.ndarray, steps: int, starts: np.ndarray | None = None,
                    course: str = "straight", yaw: np.ndarray | None = None) -> tuple[PathGeometry, Scenario]:
    """The path (:func:`adversary_course`) and the starts of :func:`adversarial_nonlinear`: the steady
    states of the slips ``mu0`` (N, 2) (or the lifted states ``starts``), the last d_hi packets delayed by
    the middle of [tau_min, tau_max].  The scenario holds no slip or delays beyond the start (``mu`` is
    ``mu0``, one period)."""
    mu0 = np.asarray(mu0, dtype=float)
    N, d_hi = mu0.shape[0], model.d_hi
    dl = model.config.network.delay
    path = adversary_course(model, steps, course, yaw)
    xi0 = model.equilibrium(np.asarray(K, dtype=float), mu0) if starts is None else np.asarray(starts, dtype=float)
    e0, du0, z0 = split_state(model, xi0)
    scen = Scenario(np.full((N, d_hi), (dl.min + dl.max) / 2.0), mu0[:, None, :], np.zeros((N, 1, 3)),
                    pose_from_error(path, e0), (), du0, z0)
    return path, scen


def run_logs(model, sim: SimResult, scen: Scenario, name: str = "run", estimate: np.ndarray | None = None) -> list:
    """The Monte Carlo runs as robot logs (:mod:`robustsynth.artifacts.logs`): per run and sampling
    instant the measured pose (with the scenario's sensor noise), the command sent then (as motor
    speeds), its send time t_k and the instant it started acting (empty when lost).  That instant is
    the simulator's (``s_tilde_sequence``): a command that arrives before an older one waits for it, so
    it acts from max(t_k + tau_k, the older commands' arrivals).  Writing the raw arrival t_k + tau_k
    instead (as before a review) made the logs of delays wider than a period show commands the
    simulated robot never overtook, and check-log and identify misread them.  ``estimate`` (N, steps, 3): a
    slip-compensated law's estimate and condition per row (the logs' optional columns)."""
    from ..artifacts.logs import RobotLog

    N, steps = scen.runs, scen.steps
    t = sim.t[:steps]
    meas = sim.q[:, :steps] + scen.noise[:, :steps]
    applied = applied_times(model, scen.taus, steps)
    return [RobotLog(f"{name}_{n:03d}.csv", t.copy(), meas[n, :, 0], meas[n, :, 1], meas[n, :, 2],
                     np.arange(steps, dtype=float), sim.rho[n, :, 0], sim.rho[n, :, 1], t.copy(), applied[n],
                     None if estimate is None else estimate[n])
            for n in range(N)]
