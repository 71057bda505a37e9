"""Verified positive definiteness in floating point (Rump, "Verification of positive definiteness",
BIT Numerical Mathematics 46:433-452, 2006), and rigorous bounds on how far a matrix assembled in
floating point lies from the matrix its formula defines.

The test is sufficient and rigorous in IEEE 754 double precision with rounding to nearest, and it
allows for underflow.  Let ``A`` be symmetric with positive diagonal.  With ``u = 2^-53`` and
``eta = 2^-1074``, set ``alpha_k = (k + 2) u`` (for a dense matrix, column k, 1-based) and

    c = sum_k alpha_k a_kk + 6 n (n + max_k a_kk) eta.

If the floating-point Cholesky factorization of ``A - c I`` runs to completion, then A is positive
definite.  (The diagonal of ``A - c I`` is rounded downwards, and c upwards.)  This is INTLAB's
``isspd`` for point matrices.  The constants cover any order of summation in the factorization, so
LAPACK's ``potrf`` may be used as it is.  Before the test the matrix is scaled by powers of two, which
is exact, so that its diagonal lies in [1/4, 1).

To prove ``L >= t I`` for a matrix L that is only known up to a rounding radius ``r`` (``L = L^ + D``,
``|D_ij| <= R_ij``, ``r >= ||R||_2``), apply the test to ``L^ - (t + r) I``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["UNIT_ROUNDOFF", "gamma", "rump_shift", "is_pd", "proves_at_least", "round_up", "assembly_radius",
           "round_up_array", "round_down_array", "rump_shift_batch", "is_pd_batch", "proves_at_least_batch", "assembly_radius_batch"]

UNIT_ROUNDOFF = 2.0**-53  # u: rounding to nearest in double precision
_ETA = 2.0**-1074  # the smallest positive subnormal


def gamma(k: int) -> float:
    """gamma_k = k u / (1 - k u), the classic bound on k successive roundings, rounded up."""
    ku = k * UNIT_ROUNDOFF
    return round_up(ku / (1.0 - ku), 2)


def round_up(x: float, ops: int = 1) -> float:
    """An upper bound of the exact result of a computation whose float result is ``x`` after at most
    ``ops`` roundings (relative error at most ``ops`` u; the inflation below is rounded up itself)."""
    x = float(x)
    if not math.isfinite(x):
        return x
    grown = x + abs(x) * (ops + 1) * UNIT_ROUNDOFF * 2.0
    return math.nextafter(grown, math.inf)


def rump_shift(diag: np.ndarray) -> float:
    """The shift c of Rump's criterion for a dense n x n matrix with diagonal ``diag`` (> 0), rounded up."""
    d = np.asarray(diag, dtype=float)
    n = d.size
    alpha = (np.arange(1, n + 1) + 2) * UNIT_ROUNDOFF
    c = float(np.sum(alpha * d)) + 6.0 * n * (n + float(np.max(d))) * _ETA
    return round_up(c, n + 2)


def _pow2_scaling(diag: np.ndarray) -> np.ndarray:
    """Powers of two s_k with s_k^2 a_kk in [1/4, 1): D A D is exact in floating point."""
    return np.exp2(-np.ceil(0.5 * np.log2(diag)))


def is_pd(A: np.ndarray) -> bool:
    """True only if the symmetric float matrix ``A`` is proven positive definite (Rump 2006)."""
    A = np.asarray(A, dtype=float)
    if A.shape == (0, 0):
        return True
    if not np.all(np.isfinite(A)) or np.any(A != A.T):
        return False
    d = np.diag(A).copy()
    if np.any(d <= 0.0):
        return False
    s = _pow2_scaling(d)
    As = A * s[:, None] * s[None, :]  # exact when nothing under- or overflows: powers of two
    if not np.all(np.isfinite(As)) or np.any(As / s[:, None] / s[None, :] != A):
        return False  # the scaling was not exact: no proof
    c = rump_shift(np.diag(As))
    B = As.copy()
    # diagonal of As - c I, rounded downwards
    B[np.diag_indices_from(B)] = np.nextafter(np.diag(As) - c, -np.inf)
    try:
        np.linalg.cholesky(B)
    except np.linalg.LinAlgError:
        return False
    return True


def proves_at_least(L_hat: np.ndarray, threshold: float, radius: float = 0.0) -> bool:
    """True only if every symmetric L with ``||L - L_hat||_2 <= radius`` satisfies ``L >= threshold I``:
    Rump's test on ``L_hat - (threshold + radius) I`` (diagonal rounded downwards)."""
    L = np.asarray(L_hat, dtype=float)
    shift = round_up(float(threshold) + float(radius), 1)
    B = L.copy()
    B[np.diag_indices_from(B)] = np.nextafter(np.diag(L) - shift, -np.inf)
    return is_pd(B)


def assembly_radius(magnitude: np.ndarray, terms: int) -> float:
    """An upper bound of ||L - L_hat||_2 for a symmetric matrix L_hat computed in floating point from a
    formula whose entries are sums of at most ``terms`` products (of up to three factors each), given
    ``magnitude``: the same formula evaluated on the absolute values of every input, with every
    subtraction turned into an addition.  Each entry's error is at most gamma_{terms + 4} times its
    magnitude (Higham, Accuracy and Stability of Numerical Algorithms, §3.5).  The magnitude is
    itself computed in floating point, hence the factor (1 + gamma).  The norm is bounded by the
    largest row sum, which for a symmetric matrix is an upper bound of its spectral norm."""
    g = gamma(terms + 4)
    row = float(np.max(np.sum(np.abs(magnitude), axis=1), initial=0.0))
    return round_up(g * (1.0 + g) * row, terms + 4)


# ------------------------------------------------------------------ batched (a stack of matrices)
# The same tests on a stack (n, k, k) at once: every constant is computed per matrix exactly as above
# (tests/test_verified.py compares them with the one-matrix functions).


def round_up_array(x: np.ndarray, ops: int = 1) -> np.ndarray:
    """:func:`round_up` elementwise."""
    x = np.asarray(x, dtype=float)
    grown = x + np.abs(x) * (ops + 1) * UNIT_ROUNDOFF * 2.0
    return np.where(np.isfinite(x), np.nextafter(grown, np.inf), x)


def round_down_array(x: np.ndarray, ops: int = 1) -> np.ndarray:
    """Elementwise a lower bound of the exact result of computations whose float results are ``x`` after at
    most ``ops`` roundings each, each a relative error of at most u (products, quotients, sums of terms of one
    sign, in the normal range; :func:`round_up_array` mirrored)."""
    x = np.asarray(x, dtype=float)
    shrunk = x - np.abs(x) * (ops + 1) * UNIT_ROUNDOFF * 2.0
    return np.where(np.isfinite(x), np.nextafter(shrunk, -np.inf), x)


def rump_shift_batch(diag: np.ndarray) -> np.ndarray:
    """:func:`rump_shift` of every row of ``diag`` (n, k)."""
    d = np.asarray(diag, dtype=float)
    k = d.shape[-1]
    alpha = (np.arange(1, k + 1) + 2) * UNIT_ROUNDOFF
    c = np.sum(alpha * d, axis=-1) + 6.0 * k * (k + np.max(d, axis=-1)) * _ETA
    return round_up_array(c, k + 2)


def is_pd_batch(A: np.ndarray) -> np.ndarray:
    """:func:`is_pd` of every matrix of the stack ``A`` (n, k, k): a bool array (n,)."""
    A = np.asarray(A, dtype=float)
    n, k = A.shape[0], A.shape[-1]
    if k == 0:
        return np.ones(n, dtype=bool)
    d = np.diagonal(A, axis1=-2, axis2=-1)
    ok = np.all(np.isfinite(A), axis=(-2, -1)) & np.all(A == np.swapaxes(A, -1, -2), axis=(-2, -1)) & np.all(d > 0.0, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        s = np.exp2(-np.ceil(0.5 * np.log2(np.where(d > 0.0, d, 1.0))))
        As = A * s[:, :, None] * s[:, None, :]
        exact = np.all(np.isfinite(As), axis=(-2, -1)) & np.all(As / s[:, :, None] / s[:, None, :] == A, axis=(-2, -1))
    ok &= exact
    c = rump_shift_batch(np.diagonal(As, axis1=-2, axis2=-1))
    B = np.where(ok[:, None, None], As, np.eye(k))  # the matrices already refused: a placeholder
    idx = np.arange(k)
    B[:, idx, idx] = np.where(ok[:, None], np.nextafter(np.diagonal(As, axis1=-2, axis2=-1) - c[:, None], -np.inf), 1.0)
    try:
        np.linalg.cholesky(B)
        return ok
    except np.linalg.LinAlgError:  # some factorization failed: find which, one by one
        out = ok.copy()
        for i in np.flatnonzero(ok):
            try:
                np.linalg.cholesky(B[i])
            except np.linalg.LinAlgError:
                out[i] = False
        return out


def proves_at_least_batch(L_hat: np.ndarray, threshold: float, radius: np.ndarray) -> np.ndarray:
    """:func:`proves_at_least` of every matrix of the stack (n, k, k) with its own ``radius`` (n,)."""
    L = np.asarray(L_hat, dtype=float)
    shift = round_up_array(float(threshold) + np.asarray(radius, dtype=float), 1)
    B = L.copy()
    idx = np.arange(L.shape[-1])
    B[:, idx, idx] = np.nextafter(np.diagonal(L, axis1=-2, axis2=-1) - shift[:, None], -np.inf)
    return is_pd_batch(B)


def assembly_radius_batch(magnitude: np.ndarray, terms: int) -> np.ndarray:
    """:func:`assembly_radius` of every matrix of the stack (n, k, k)."""
    g = gamma(terms + 4)
    mag = np.abs(np.asarray(magnitude, dtype=float))
    row = np.max(np.sum(mag, axis=-1), axis=-1, initial=0.0)
    return round_up_array(g * (1.0 + g) * row, terms + 4)
