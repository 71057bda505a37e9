"""Vectorized simulation of the lifted linear model (eq. 25) in closed loop, ``du_k = K xi_k``:
random, extreme-switching and greedy worst-case delay/slip sequences, and frozen delays."""

from __future__ import annotations

import itertools

import numpy as np

__all__ = [
    "closed_loop_run",
    "random_delays",
    "alternating_delays",
    "slip_vertices",
    "greedy_worst_case",
    "frozen_spectral_radius",
    "frozen_instant_grid",
]


def closed_loop_run(model, K: np.ndarray, taus: np.ndarray, d: np.ndarray, xi0: np.ndarray) -> np.ndarray:
    """xi[n, k] for runs n; ``taus`` (N, steps + d_hi) packet delays, ``d`` (N, steps, 2) slip
    deviation, ``xi0`` (N, n_s).  Returns (N, steps + 1, n_s)."""
    s = model.s_tilde(taus)  # (N, steps, d_hi)
    A, B = model.exact(s)
    Acl = A + B @ K  # (N, steps, n_s, n_s)
    Bd = np.asarray(model.B_d)
    N, steps = s.shape[:2]
    xi = np.empty((N, steps + 1, model.n_s))
    xi[:, 0] = xi0
    for k in range(steps):
        xi[:, k + 1] = np.einsum("nij,nj->ni", Acl[:, k], xi[:, k]) + d[:, k] @ Bd.T
    return xi


def random_delays(model, rng: np.random.Generator, N: int, steps: int) -> np.ndarray:
    dl = model.config.network.delay
    return rng.uniform(dl.min, dl.max, size=(N, steps + model.d_hi))


def alternating_delays(model, N: int, steps: int, period: int = 1) -> np.ndarray:
    """min/max switching with a given period (in packets), phase shifted across runs."""
    dl = model.config.network.delay
    i = np.arange(steps + model.d_hi)[None, :] + np.arange(N)[:, None]
    return np.where((i // period) % 2 == 0, dl.min, dl.max)


def slip_vertices(model) -> np.ndarray:
    """The 4 corners of the slip-deviation box, shape (4, 2)."""
    sl = model.slip
    return np.array(list(itertools.product((sl.d_min[0], sl.d_max[0]), (sl.d_min[1], sl.d_max[1]))))


def greedy_worst_case(model, K, P, xi0: np.ndarray, steps: int, n_tau: int = 9, slip: bool = True):
    """Greedy search for large V = xi' P xi: each step, over a grid of the new packet's delay and
    the slip-box corners, take the choice that maximizes V(xi_{k+1}).  Returns (xi, taus, d)."""
    dl = model.config.network.delay
    tau_grid = np.linspace(dl.min, dl.max, n_tau)
    d_cands = slip_vertices(model) if slip else np.zeros((1, 2))
    N = xi0.shape[0]
    d_hi = model.d_hi
    hist = np.full((N, d_hi), (dl.min + dl.max) / 2.0)  # delays of the last d_hi packets
    xi = np.empty((N, steps + 1, model.n_s))
    xi[:, 0] = xi0
    taus_out = np.empty((N, steps + d_hi))
    taus_out[:, :d_hi] = hist
    d_out = np.empty((N, steps, 2))
    Bd = np.asarray(model.B_d)
    for k in range(steps):
        # candidate delay of packet k (the newest): s~ depends on it and on the history
        cand = np.concatenate([np.repeat(hist[:, None, :], n_tau, axis=1), np.broadcast_to(tau_grid[None, :, None], (N, n_tau, 1))], axis=2)
        s = model.s_tilde(cand)[:, :, 0, :]  # (N, n_tau, d_hi)
        A, B = model.exact(s)
        nxt = np.einsum("ntij,nj->nti", A + B @ K, xi[:, k])  # (N, n_tau, n_s)
        nxt = nxt[:, :, None, :] + (d_cands @ Bd.T)[None, None, :, :]  # (N, n_tau, n_d, n_s)
        V = np.einsum("ntdi,ij,ntdj->ntd", nxt, P, nxt)
        flat = V.reshape(N, -1).argmax(axis=1)
        ti, di = np.unravel_index(flat, V.shape[1:])
        xi[:, k + 1] = nxt[np.arange(N), ti, di]
        d_out[:, k] = d_cands[di]
        taus_out[:, k + d_hi] = tau_grid[ti]
        hist = np.concatenate([hist[:, 1:], tau_grid[ti][:, None]], axis=1)
    return xi, taus_out, d_out


def frozen_instant_grid(model, n: int) -> np.ndarray:
    """Admissible frozen switching-instant vectors s~ (rows): every uncertain instant on an
    n-point grid of its range, combined monotonically (s~_0 >= s~_1 >= ...); fixed ones fixed."""
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


def frozen_spectral_radius(model, K: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Spectral radius of A~(s~) + B~(s~) K for each frozen instant vector (row of ``s``)."""
    A, B = model.exact(s)
    return np.max(np.abs(np.linalg.eigvals(A + B @ K)), axis=-1)
