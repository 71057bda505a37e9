"""The tracked robot's straightforward per-run reference implementations, for tests and benchmarks only: the
oracle that the vectorized closed loop (:mod:`robustsynth.robot_verification.simulate`) is held to.

:func:`simulate_run` replays one run of a :class:`~robustsynth.scenarios.Scenario` with explicit actuation
events (absolute arrival times, in-order by a running maximum) instead of the vectorized
switching instants; ``integrator='ivp'`` integrates the kinematics with ``solve_ivp`` instead of
the exact arcs.  It reads the scenario's arrays only (the room of scenarios is above this one)."""

from __future__ import annotations

import numpy as np

from ..model.kinematics import G_matrix, JHJinv
from .kinematic import arc_step, saturate
from .path import PathGeometry, frame_error

__all__ = ["simulate_run", "ivp_arc"]


def ivp_arc(q: np.ndarray, v: float, w: float, h: float, rtol: float = 1e-11, atol: float = 1e-12,
            vy: float = 0.0) -> np.ndarray:
    """The pose after time h at body velocity (v, vy) and yaw rate w, by numerical integration of
    x' = v cos th - vy sin th, y' = v sin th + vy cos th, th' = w (G(theta) for vy = 0)."""
    from scipy.integrate import solve_ivp

    if h <= 0:
        return q.copy()

    def rhs(_t, x):
        out = G_matrix(x[2]) @ np.array([v, w])
        return out + vy * np.array([-np.sin(x[2]), np.cos(x[2]), 0.0])

    sol = solve_ivp(rhs, (0.0, h), q, rtol=rtol, atol=atol, method="DOP853")
    return sol.y[:, -1]


def simulate_run(model, K: np.ndarray, path: PathGeometry, scen, n: int, integrator: str = "arc"):
    """Run ``n`` of ``scen`` (a :class:`~robustsynth.scenarios.Scenario`); returns (q (steps+1, 3), e (steps+1, 3),
    du (steps, 2))."""
    Ts, d_hi, V = model.Ts, model.d_hi, model.V
    D = model.config.robot.track_distance
    steps = scen.steps
    taus = scen.taus[n]
    send = (np.arange(steps + d_hi) - d_hi) * Ts
    # in order: a received packet is delivered at the latest arrival among itself and the received
    # packets sent before it; a lost one (delay inf) never arrives
    arrive = np.full(taus.shape, np.inf)
    latest = -np.inf
    for i, tau in enumerate(taus):
        if np.isfinite(tau):
            latest = max(latest, send[i] + tau)
            arrive[i] = latest
    uD = np.array([V, 0.0])
    cfg = model.config
    rho_sat = cfg.robot.max_motor_speed if cfg.verification.motor_saturation else None
    # packets sent before t_0 carry the stored commands (zero unless the run starts at a steady state)
    past = [np.zeros(2) for _ in range(d_hi)] if scen.du0 is None else [scen.du0[n, j].copy() for j in range(d_hi)]
    u_hat = [uD + past[d_hi - 1 - i] for i in range(d_hi)]  # in sending order: du_{-d_hi}, ..., du_{-1}
    z = np.zeros(model.n_z) if scen.z0 is None or not model.n_z else scen.z0[n].copy()
    q = scen.q0[n].copy()
    qs, es, dus = [q.copy()], [], []
    for k in range(steps):
        t0 = k * Ts
        seg = path.segment(t0)
        es.append(frame_error(path, seg, q, t0))
        e_meas = frame_error(path, seg, q + scen.noise[n, k], t0)
        xi = np.concatenate([e_meas] + past + [z])
        du = K @ xi
        if model.n_z:
            z = z + Ts * e_meas[:2]
        dus.append(du)
        past = [du] + past[:-1]
        u_hat.append(uD + du + path.feedforward(t0) * model.turn_feedforward)  # a turning reference's yaw rate
        t1 = t0 + Ts
        # the slip: mu[k] over the period, or each track mu[k-1] until its change within the period and
        # mu[k] after it
        changing = scen.mu_switch is not None and k > 0
        t_sw = t0 + scen.mu_switch[n, k] if changing else np.full(2, t0)
        before = scen.mu[n, k - 1] if changing else scen.mu[n, k]
        events = [t0] + sorted(a for a in list(arrive) + list(t_sw) if t0 < a < t1) + [t1]
        for a, b in zip(events[:-1], events[1:]):
            mu = scen.mu[n, k].copy()
            mu[:2] = np.where(b <= t_sw, before[:2], scen.mu[n, k, :2])
            M = JHJinv(mu[0], mu[1], D)
            if mu.shape[-1] > 2:  # the icr model: yaw factor and lateral velocity (theory §12)
                M = np.diag([1.0, mu[2]]) @ M
                lat = -mu[3] * M[1]
            active = [i for i in range(len(u_hat)) if arrive[i] <= a]
            u = u_hat[active[-1]] if active else uD
            us = saturate(u, np.asarray(model.J), np.asarray(model.J_inv), rho_sat)
            ue = M @ us
            vy = float(lat @ us) if mu.shape[-1] > 2 else None
            if integrator == "arc":
                q = arc_step(q, ue[0], ue[1], b - a, vy)
            else:
                q = ivp_arc(q, ue[0], ue[1], b - a, vy=vy or 0.0)
        qs.append(q.copy())
    es.append(frame_error(path, path.segment(steps * Ts), q, steps * Ts))
    return np.array(qs), np.array(es), np.array(dus)
