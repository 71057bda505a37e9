"""Vectorized simulation of the lifted linear model (eq. 25) in closed loop, ``du_k = K xi_k``,
under the delay sequences of :mod:`robustsynth.core.network` (random, extreme switching), a greedy
worst-case search, and frozen delays; and the spectral radii of the lifted closed loop of any
:class:`~robustsynth.core.plant.Plant` at frozen instants and over periodic delay sequences, which
the robot's and the linear plant's checks and instability searches share."""

from __future__ import annotations

import numpy as np

from ..core.network import s_tilde_sequence
from ..core.plant import Plant
from ..errors import check_interrupt
from ..scenarios import slip_candidates

__all__ = [
    "closed_loop_run",
    "arc_closed_loop_run",
    "random_yaw_rates",
    "yaw_windows",
    "greedy_worst_case",
    "frozen_spectral_radius",
    "periodic_spectral_radius",
    "frozen_instant_grid",
]


def closed_loop_run(model, K: np.ndarray, taus: np.ndarray, mu: np.ndarray, xi0: np.ndarray,
                    affine: bool = True) -> np.ndarray:
    """xi[n, k] for runs n of the model's exact lifted map ``xi+ = (A + B K) xi + c(mu)``;
    ``taus`` (N, steps + d_hi) packet delays, ``mu`` (N, steps, 2) slip, ``xi0`` (N, n_s).
    Returns (N, steps + 1, n_s); ``affine=False`` drops c (the homogeneous part, which governs the
    deviation from the steady state of a constant slip)."""
    s = model.s_tilde(taus)  # (N, steps, d_hi)
    A, B = model.exact(s, mu)
    Acl = A + B @ K  # (N, steps, n_s, n_s)
    c = model.constant(mu) if affine else np.zeros(mu.shape[:-1] + (model.n_s,))  # (N, steps, n_s)
    N, steps = s.shape[:2]
    xi = np.empty((N, steps + 1, model.n_s))
    xi[:, 0] = xi0
    for k in range(steps):
        check_interrupt()
        xi[:, k + 1] = np.einsum("nij,nj->ni", Acl[:, k], xi[:, k]) + c[:, k]
    return xi


def arc_closed_loop_run(model, K: np.ndarray, taus: np.ndarray, mu: np.ndarray, w: np.ndarray,
                        xi0: np.ndarray, affine: bool = True) -> np.ndarray:
    """As :func:`closed_loop_run` along arcs, for a turning model: the kinematics linearized about the reference's
    arc (:func:`~robustsynth.model.arcs.linearized_arc_period`), ``w`` (N, steps + d_hi) the reference's yaw
    rates w_{-d_hi}, ..., w_{steps-1} (the commands in memory at the start carry the first d_hi).  Returns
    (N, steps + 1, n_s).  ``affine=False``: the homogeneous part only (the map less its value at xi = 0 for the
    same delays, slip and yaw rates: the difference of two runs under one history)."""
    S = model.s_tilde(taus)  # (N, steps, d_hi)
    N, steps = S.shape[:2]
    n_e, d_hi = model.n_e, model.d_hi
    K = np.asarray(K, dtype=float)
    yaw = yaw_windows(w, d_hi)
    xi = np.empty((N, steps + 1, model.n_s))
    xi[:, 0] = xi0
    for k in range(steps):
        check_interrupt()
        x = xi[:, k]
        du = x @ K.T
        xi[:, k + 1, :n_e] = model.linearized_arc_period(x, du, S[:, k], mu[:, k], yaw[:, k], homogeneous=not affine)
        xi[:, k + 1, n_e:] = _memory_after(model, x, du)
    return xi


def _memory_after(model, x: np.ndarray, du: np.ndarray) -> np.ndarray:
    """The lifted state at t_{k+1} after its errors, from ``x`` at t_k and the correction ``du`` sent then: du,
    the stored corrections shifted by one, and the integrators advanced, z + Ts (e_x, e_y)."""
    n_e, n_u, d_hi = model.n_e, model.n_u, model.d_hi
    parts = [du, x[..., n_e : n_e + (d_hi - 1) * n_u]]
    if model.n_z:
        parts.append(x[..., n_e + d_hi * n_u :] + model.Ts * x[..., :2])
    return np.concatenate(parts, axis=-1)


def yaw_windows(w: np.ndarray, d_hi: int) -> np.ndarray:
    """(N, steps, d_hi + 1): for each period k the yaw rates (w_k, w_{k-1}, ..., w_{k-d_hi}) its commands carry, from
    ``w`` (N, steps + d_hi) = (w_{-d_hi}, ..., w_{steps-1})."""
    w = np.asarray(w, dtype=float)
    steps = w.shape[1] - d_hi
    return np.stack([w[:, d_hi - j : d_hi - j + steps] for j in range(d_hi + 1)], axis=-1)


def random_yaw_rates(model, rng: np.random.Generator, N: int, steps: int) -> np.ndarray:
    """Reference yaw rates a turning certificate covers, (N, steps + d_hi): 0 for the commands in memory at the
    start (w_{-d_hi}, ..., w_{-1}), then in even runs each period w_{k-1} or a step of max_step either way (a
    third each), in odd runs a step of max_step towards the extreme ahead, turning back there (from one extreme
    to the other as fast as the steps allow); always within +-max_yaw_rate."""
    t = model.turns
    d_hi = model.d_hi
    w = np.zeros((N, steps + d_hi))
    ahead = np.ones(N)
    odd = np.arange(N) % 2 == 1
    rows = np.arange(N)
    for k in range(d_hi, w.shape[1]):
        ahead = np.where(w[:, k - 1] >= t.max_yaw_rate, -1.0, np.where(w[:, k - 1] <= -t.max_yaw_rate, 1.0, ahead))
        move = np.where(odd, ahead, rng.integers(-1, 2, size=N))  # -1, 0, 1
        w[:, k] = t.next_yaw_rates(w[:, k - 1])[rows, move.astype(int) + 1]
    return w


def greedy_worst_case(model, K, V_fn, xi0: np.ndarray, steps: int, n_tau: int = 9, slip: bool = True,
                      mu0: np.ndarray | None = None, with_delay: bool = False, yaw: bool = False):
    """Greedy search for large V: each step, over a grid of the new packet's delay and the slips the
    adversary may pick (:func:`slip_candidates`), take the choice that maximizes
    ``V_fn(xi_{k+1}, mu)`` (``V_fn(xi_{k+1}, mu, prev=...)`` with the period's delay weights when
    ``with_delay``: a path-dependent Lyapunov function).  Returns (xi, taus, mu).

    ``yaw`` (a turning model, the tracks slip model): along arcs, on the kinematics linearized about them
    (:func:`~robustsynth.model.arcs.linearized_arc_period`), the search also picks the reference's yaw rate each
    period, w_{k-1} or a step of max_step either way within +-max_yaw_rate (0 before the start); returns (xi,
    taus, mu, w) with w (N, steps + d_hi) as :func:`arc_closed_loop_run` takes it."""
    net = model.network
    tau_grid = net.candidates(n_tau)
    n_tau = tau_grid.size
    N = xi0.shape[0]
    d_hi, n_u = model.d_hi, model.n_u
    K = np.asarray(K, dtype=float)
    hist = np.full((N, d_hi), (net.delay_min + net.delay_max) / 2.0)  # delays of the last d_hi packets (inf: lost)
    xi = np.empty((N, steps + 1, model.n_s))
    xi[:, 0] = xi0
    taus_out = np.empty((N, steps + d_hi))
    taus_out[:, :d_hi] = hist
    n_p = model.n_p
    mu_out = np.empty((N, steps, n_p))
    mu_prev = np.tile(model.nominal_slip, (N, 1)) if mu0 is None else np.array(mu0, dtype=float)
    w_out = np.zeros((N, steps + d_hi))  # the reference's yaw rates, w_{-d_hi}, ..., w_{steps-1}
    for k in range(steps):
        check_interrupt()
        x = xi[:, k]
        mu_cands = slip_candidates(model, mu_prev) if slip else np.tile(model.nominal_slip, (N, 1, 1))
        n_m = mu_cands.shape[1]
        # candidate delay of packet k (the newest): s~ depends on it and on the history
        cand = np.concatenate([np.repeat(hist[:, None, :], n_tau, axis=1), np.broadcast_to(tau_grid[None, :, None], (N, n_tau, 1))], axis=2)
        s = model.s_tilde(cand)[:, :, 0, :]  # (N, n_tau, d_hi)
        if yaw:
            W = model.turns.next_yaw_rates(w_out[:, k + d_hi - 1])  # (N, n_y)
            n_y = W.shape[1]
            shape = (N, n_tau, n_m, n_y)
            memory = w_out[:, k : k + d_hi][:, ::-1]  # w_{k-1}, ..., w_{k-d_hi}
            yaws = np.concatenate([np.broadcast_to(W[:, None, None, :, None], shape + (1,)),
                                   np.broadcast_to(memory[:, None, None, None, :], shape + (d_hi,))], axis=-1)
            du = x @ K.T
            e = model.linearized_arc_period(np.broadcast_to(x[:, None, None, None], shape + x.shape[1:]),
                                            np.broadcast_to(du[:, None, None, None], shape + (n_u,)),
                                            np.broadcast_to(s[:, :, None, None], shape + (d_hi,)),
                                            np.broadcast_to(mu_cands[:, None, :, None], shape + (n_p,)), yaws)
            rest = _memory_after(model, x, du)
            nxt = np.concatenate([e, np.broadcast_to(rest[:, None, None, None], shape + rest.shape[1:])], axis=-1)
        else:
            A, B = model.exact(s[:, :, None, :], mu_cands[:, None, :, :])  # (N, n_tau, n_m, ...)
            nxt = (np.einsum("ntmij,nj->ntmi", A + B @ K, x) + model.constant(mu_cands)[:, None])[:, :, :, None]
            n_y = 1
        mus = np.broadcast_to(mu_cands[:, None, :, None], nxt.shape[:-1] + (n_p,))
        if with_delay:
            dw = model.delay_weights(s)  # (N, n_tau, n_d): this period's delay, the next state's "previous"
            V = V_fn(nxt, mus, prev=np.broadcast_to(dw[:, :, None, None], nxt.shape[:-1] + dw.shape[-1:]))
        else:
            V = V_fn(nxt, mus)  # (N, n_tau, n_m, n_y)
        if net.max_lost:  # losing the newest packet only while the burst is below the cap
            V = np.where(np.isinf(tau_grid)[None, :, None, None] & ~net.loss_allowed(hist)[:, None, None, None], -np.inf, V)
        flat = V.reshape(N, -1).argmax(axis=1)
        ti, di, yi = np.unravel_index(flat, (n_tau, n_m, n_y))
        xi[:, k + 1] = nxt[np.arange(N), ti, di, yi]
        mu_out[:, k] = mu_cands[np.arange(N), di]
        mu_prev = mu_out[:, k]
        taus_out[:, k + d_hi] = tau_grid[ti]
        hist = np.concatenate([hist[:, 1:], tau_grid[ti][:, None]], axis=1)
        if yaw:
            w_out[:, k + d_hi] = W[np.arange(N), yi]
    return (xi, taus_out, mu_out, w_out) if yaw else (xi, taus_out, mu_out)


def frozen_instant_grid(model, n: int) -> np.ndarray:
    """Admissible frozen switching-instant vectors s~ (rows): every uncertain instant on an
    n-point grid of its range, combined monotonically (s~_0 >= s~_1 >= ...); fixed ones fixed.  On a
    lossy link described exactly (lossy-polytopic): the vectors the link can produce."""
    reach = model.reachable_instants(n)
    if reach is not None:
        return reach
    axes = []
    for j in range(model.d_hi):
        lo, hi = model.instant_ranges[j]
        axes.append(np.linspace(lo, hi, n) if hi > lo else np.array([lo]))
    if len(axes) == 1:
        return axes[0][:, None]
    # keep the product manageable: thin each axis so the product stays <= ~ n^2 points
    n_unc = sum(a.size > 1 for a in axes)
    if n_unc > 2:
        m = max(3, int(round(n ** (2.0 / n_unc))))
        axes = [np.linspace(a[0], a[-1], m) if a.size > 1 else a for a in axes]
    grid = np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(axes), -1).T
    mono = np.all(np.diff(grid, axis=1) <= 1e-15, axis=1)
    return grid[mono]


def periodic_spectral_radius(plant: Plant, K: np.ndarray, dseq: np.ndarray, thetas: np.ndarray | None = None
                             ) -> np.ndarray:
    """rho(product over one period)^(1/p) of the lifted closed loop A~ + B~ K of any
    :class:`~robustsynth.core.plant.Plant` for periodic packet delays ``dseq`` (n, p) (``inf``: lost,
    at most the network's cap in a row) and, per period, the parameters ``thetas`` (n_t, p, n_theta)
    (None: a plant without one); shape (n, n_t) (n_t = 1 without).  The commands K keeps set the
    lifting's depth (a gain may keep more than the plant's d_hi); the packets before the period and, after
    a burst, its successor are the periodic sequence's own."""
    dseq = np.atleast_2d(np.asarray(dseq, dtype=float))
    p = dseq.shape[1]
    net = plant.network
    d = (K.shape[-1] - (plant.n_s - plant.d_hi * plant.n_u)) // plant.n_u
    if d < plant.d_hi:
        raise ValueError(f"K keeps {d} commands, the plant's network needs {plant.d_hi} (pad the gain)")
    cols = np.arange(-d, p + net.max_lost + 1) % p
    s = s_tilde_sequence(dseq[:, cols], net.sampling_time, d)[:, :p]  # (n, p, d)
    A, B = plant.lifted(s[:, None], None if thetas is None else np.asarray(thetas, dtype=float)[None])
    Acl = A + B @ K  # (n, n_t, p, n_s, n_s)
    prod = Acl[..., 0, :, :]
    for k in range(1, p):
        prod = Acl[..., k, :, :] @ prod
    return np.max(np.abs(np.linalg.eigvals(prod)), axis=-1) ** (1.0 / p)


def frozen_spectral_radius(plant: Plant, K: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Spectral radius of A~(s~, theta) + B~(s~, theta) K for each frozen instant vector (row of ``s``),
    the largest over the plant's parameter corners (the robot's slip; a linear plant has none), for any
    :class:`~robustsynth.core.plant.Plant`."""
    corners = np.asarray(plant.parameter_corners(), dtype=float)
    A, B = plant.lifted(s[:, None, :], None if corners.shape[-1] == 0 else corners[None, :, :])
    return np.max(np.abs(np.linalg.eigvals(A + B @ K)), axis=(-1, -2))
