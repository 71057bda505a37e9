"""Continuous linearized tracking error (eq. lineare) and its exact sampled pieces.

``A`` is nilpotent (A^2 = 0), so every matrix exponential below is a polynomial in the interval
length; :func:`van_loan` computes the same integrals generically with ``scipy.linalg.expm`` for
cross-checks and for plants whose ``A`` is not nilpotent.
"""

from __future__ import annotations

import numpy as np

__all__ = ["continuous_matrices", "Phi", "Gamma", "Gamma_D", "van_loan", "lifted_exact"]


def continuous_matrices(V: float, D: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, B_D) of e_dot = A e + B du + B_D d (eq. lineare), linearized at e = 0, du = 0, d = 0."""
    A = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, V], [0.0, 0.0, 0.0]])
    B = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
    B_D = np.array([[V / 2.0, V / 2.0], [0.0, 0.0], [V / D, -V / D]])
    return A, B, B_D


def Phi(A: np.ndarray, h: float) -> np.ndarray:
    """e^{A h} = I + A h (exact because A^2 = 0)."""
    return np.eye(A.shape[0]) + A * h


def Gamma(A: np.ndarray, B: np.ndarray, h: np.ndarray | float) -> np.ndarray:
    """Gamma(h) = int_0^h e^{A s} ds B = h B + (h^2/2) A B; broadcasts over h, shape (..., n, m)."""
    h = np.asarray(h, dtype=float)[..., None, None]
    return h * B + (h * h / 2.0) * (A @ B)


def Gamma_D(A: np.ndarray, B_D: np.ndarray, Ts: float) -> np.ndarray:
    """Gamma_D = int_0^Ts e^{A s} ds B_D."""
    return Gamma(A, B_D, Ts)


def van_loan(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{A h}, int_0^h e^{A s} ds B) from one block matrix exponential (Van Loan)."""
    from scipy.linalg import expm

    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    E = expm(M * h)
    return E[:n, :n], E[:n, n:]


def lifted_exact(A: np.ndarray, B: np.ndarray, B_D: np.ndarray, Ts: float, s_tilde: np.ndarray):
    """The robot's exact (A~(s~), B~(s~), B~_d) (:func:`robustsynth.core.lifting.lift`) for switching instants ``s_tilde[..., j]``, j = 0..d_hi-1."""
    from ..core.lifting import lift

    s_tilde = np.asarray(s_tilde, dtype=float)
    Gammas = Gamma(A, B, Ts - s_tilde)
    return lift(Phi(A, Ts), Gammas, Gamma(A, B, Ts), Gamma_D(A, B_D, Ts))
