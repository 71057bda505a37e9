"""Time-varying network delay and the lifted discrete model (eq. LTI_error2, eq. 25, docs/theory.md §3).

Within ``[t_k, t_k+1)`` the actuator holds ``du_{k-j}`` from ``t_k + s~_j`` on, with
``Ts >= s~_0 >= ... >= s~_{d_hi} = 0`` (in-order delivery).  Summation by parts gives

    e_{k+1} = Phi e_k + sum_{j<d_hi} Gamma(Ts - s~_j) (du_{k-j} - du_{k-j-1}) + Gamma(Ts) du_{k-d_hi} + Gamma_D d_k

and with the lifted state ``xi_k = [e_k; du_{k-1}; ...; du_{k-d_hi}]``:
``xi_{k+1} = A~(s~) xi_k + B~(s~) du_k + B~_d d_k`` (eq. 25).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["delay_indices", "instant_ranges", "lift"]

_INT_TOL = 1e-9


def _near_int(x: float) -> int | None:
    n = round(x)
    return int(n) if abs(x - n) <= _INT_TOL * max(1.0, abs(x)) else None


def delay_indices(tau_min: float, tau_max: float, Ts: float) -> tuple[int, int]:
    """(d_lo, d_hi) = (floor(tau_min/Ts), max(1, ceil(tau_max/Ts))), robust to float round-off."""
    lo_x, hi_x = tau_min / Ts, tau_max / Ts
    n = _near_int(lo_x)
    d_lo = n if n is not None else math.floor(lo_x)
    n = _near_int(hi_x)
    d_hi = n if n is not None else math.ceil(hi_x)
    return d_lo, max(1, d_hi)


def instant_ranges(tau_min: float, tau_max: float, Ts: float, d_hi: int) -> np.ndarray:
    """Range [lo_j, hi_j] of each switching instant s~_j, j = 0..d_hi-1; shape (d_hi, 2)."""
    j = np.arange(d_hi)
    lo = np.clip(tau_min - j * Ts, 0.0, Ts)
    hi = np.clip(tau_max - j * Ts, 0.0, Ts)
    return np.stack([lo, hi], axis=1)


def lift(Phi: np.ndarray, Gammas: np.ndarray, Gamma_Ts: np.ndarray, Gamma_D: np.ndarray):
    """Lifted (A~, B~, B~_d) from the per-instant Gamma_j = Gamma(Ts - s~_j).

    ``Gammas`` has shape (..., d_hi, n_e, n_u); the result broadcasts over the leading axes.
    """
    Gammas = np.asarray(Gammas)
    batch = Gammas.shape[:-3]
    d_hi, n_e, n_u = Gammas.shape[-3:]
    n_s = n_e + d_hi * n_u
    A = np.zeros(batch + (n_s, n_s))
    B = np.zeros(batch + (n_s, n_u))
    A[..., :n_e, :n_e] = Phi
    B[..., :n_e, :] = Gammas[..., 0, :, :]
    for j in range(1, d_hi + 1):  # coefficient of du_{k-j}
        nxt = Gammas[..., j, :, :] if j < d_hi else Gamma_Ts
        cols = slice(n_e + (j - 1) * n_u, n_e + j * n_u)
        A[..., :n_e, cols] = nxt - Gammas[..., j - 1, :, :]
    B[..., n_e : n_e + n_u, :] = np.eye(n_u)  # du_k becomes du_{(k+1)-1}
    for j in range(1, d_hi):  # shift register: du_{k-j} -> slot j+1
        A[..., n_e + j * n_u : n_e + (j + 1) * n_u, n_e + (j - 1) * n_u : n_e + j * n_u] = np.eye(n_u)
    Bd = np.zeros((n_s, Gamma_D.shape[1]))
    Bd[:n_e] = Gamma_D
    return A, B, np.broadcast_to(Bd, batch + Bd.shape).copy()
