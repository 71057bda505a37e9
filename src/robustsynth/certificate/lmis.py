"""The LMIs of a certificate at one vertex of the model, or at a stack of vertices, rebuilt in numpy
(docs/theory.md §6): the matrices :mod:`robustsynth.certificate` proves ``>= threshold I``, and the same
formulas on absolute values (their magnitudes, which bound the assembly's rounding)."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["lmi_stability", "lmi_invariance", "multiplier_structure_error", "dense_multiplier", "compact_multipliers",
           "COMPACT_ABOVE"]


def _T(X: np.ndarray) -> np.ndarray:
    """Transpose of a matrix or of every matrix of a stack."""
    return np.swapaxes(X, -1, -2)


def _sym(X: np.ndarray) -> np.ndarray:
    return (X + _T(X)) / 2.0


def _block(rows: list[list[Any]]) -> np.ndarray:
    """``np.block`` for blocks that may be stacks (..., r, c): the others are broadcast to the stack."""
    batch = np.broadcast_shapes(*[np.shape(b)[:-2] for row in rows for b in row])
    if not batch:
        return np.block(rows)
    full = lambda b: np.broadcast_to(b, batch + np.shape(b)[-2:])  # noqa: E731
    return np.concatenate([np.concatenate([full(b) for b in row], axis=-1) for row in rows], axis=-2)


def _minus(a, b, mag: bool):
    """a - b, or a + b for the magnitude of a formula (see :func:`robustsynth.verified.assembly_radius`)."""
    return a + b if mag else a - b


# The LMIs below take one vertex and its multiplier, or a stack of vertices and of their multipliers
# (their matrices (n, ., .)); they return the matrix, or the stack of matrices, to prove >= threshold I.


def lmi_stability(v, X, left, right, Y, M, r2, mag: bool = False):
    """Vertex v: [[r2 left, (A X + B Y)', (C_q X + D_q Y)'], [A X + B Y, right - B_p M B_p', 0],
    [C_q X + D_q Y, 0, M]] (>= 0 certifies V(xi+) <= r^2 V(xi) at the vertex; docs/theory.md §6a).
    ``mag``: the inputs are absolute values and the subtraction is an addition (the magnitude)."""
    AX = v.A @ X + v.B @ Y
    n_s, n_q = X.shape[0], v.B_p.shape[-1]
    if n_q == 0:
        return _sym(_block([[r2 * left, _T(AX)], [AX, right]]))
    CX = v.C_q @ X + v.D_q @ Y
    Z = np.zeros((n_s, n_q))
    return _sym(_block([[r2 * left, _T(AX), _T(CX)], [AX, _minus(right, v.B_p @ M @ _T(v.B_p), mag), Z], [CX, Z.T, M]]))


def lmi_invariance(v, X, left, right, Y, M, beta, alpha, mag: bool = False):
    """Vertex v: V(xi+) <= (1-alpha) V(xi) + sum beta_i w_i^2 for all |Delta| <= 1 (docs/theory.md §6b), as

    [[(1-alpha) left, 0, (AX+BY)', (C_qX+D_qY)'], [0, diag(beta), E', F_q'],
     [AX+BY, E, right - B_p M B_p', 0], [C_qX+D_qY, F_q, 0, M]] >= 0."""
    AX = v.A @ X + v.B @ Y
    n_s, n_q, n_w = X.shape[0], v.B_p.shape[-1], v.E.shape[-1]
    Zsw = np.zeros((n_s, n_w))
    rows = [
        [(1.0 - alpha) * left, Zsw, _T(AX)],
        [Zsw.T, np.diag(beta), _T(v.E)],
        [AX, v.E, _minus(right, v.B_p @ M @ _T(v.B_p), mag) if n_q else right],
    ]
    if n_q:
        CX = v.C_q @ X + v.D_q @ Y
        F = v.F  # q = C_q xi + D_q du + F_q w
        rows[0].append(_T(CX))
        rows[1].append(_T(F))
        rows[2].append(np.zeros((n_s, n_q)))
        rows.append([CX, F, np.zeros((n_q, n_s)), M])
    return _sym(_block(rows))


# A certificate's multipliers are written as {"diag": [...]} where they are diagonal and hold more than this many entries
# in all: the default robot's 48 multipliers of 60 channels (172 800 entries, a 1 MB gains.json) stay whole matrices;
# the linearized turning model at d_hi 2 (144 of 80 channels, 921 600) made a gains.json of 9.2 MB, beyond what
# load_gains reads (MAX_GAINS_BYTES, 8 MiB), and at d_hi 3 one of 48 MB
COMPACT_ABOVE = 500_000


def dense_multiplier(x: Any) -> Any:
    """A multiplier as a matrix: ``{"diag": d}`` (a diagonal one, written compactly) as ``diag(d)``; anything else as
    it is (the re-check then says what is wrong with it)."""
    if isinstance(x, dict) and set(x) == {"diag"}:
        d = np.asarray(x["diag"], dtype=float)
        return np.diag(d) if d.ndim == 1 else d
    return x


def compact_multipliers(Ms: Any) -> Any:
    """The per-vertex multipliers ``Ms`` as a certificate writes them: each diagonal one as ``{"diag": d}`` where they
    hold more than COMPACT_ABOVE entries in all and every one is diagonal (else as they are)."""
    mats = [np.asarray(dense_multiplier(M), dtype=float) for M in Ms]
    if sum(M.size for M in mats) <= COMPACT_ABOVE:
        return Ms
    if not all(M.ndim == 2 and M.shape[0] == M.shape[1] and not np.any(M[~np.eye(M.shape[0], dtype=bool)])
               for M in mats):
        return Ms
    return [{"diag": np.diag(M).copy()} for M in mats]


def multiplier_structure_error(M: np.ndarray, n_blocks: int, kind: str, diagonal: bool = False) -> str:
    """'' when M has the structure the S-procedure needs for Delta = blockdiag(d1 I2, d2, ...), or for a
    diagonal Delta of independent scalars (``diagonal``: M must be diagonal)."""
    if diagonal:
        if M.ndim != 2 or M.shape[0] != M.shape[1]:
            return f"multiplier has shape {M.shape}, expected a square diagonal matrix"
        if np.any(M[~np.eye(M.shape[0], dtype=bool)] != 0.0):
            return "multiplier of independent scalar channels must be diagonal (the S-procedure would not hold)"
        return ""
    n = 3 * n_blocks
    if M.shape != (n, n):
        return f"multiplier has shape {M.shape}, expected {(n, n)}"
    allowed = np.zeros((n, n), dtype=bool)
    for b in range(n_blocks):
        allowed[3 * b : 3 * b + 2, 3 * b : 3 * b + 2] = True
        allowed[3 * b + 2, 3 * b + 2] = True
    if np.any(M[~allowed] != 0.0):
        return "multiplier has entries outside the blocks of Delta (the S-procedure would not hold)"
    if kind == "full" and n and not np.allclose(M, M[0, 0] * np.eye(n), rtol=0, atol=0):
        return "a 'full' multiplier must be mu * I"
    return ""


class _Stack:
    """Vertices as one stack: each matrix (n, ., .) (their absolute values with ``absolute``, for the
    magnitude of a formula); their channels must have one shape."""

    def __init__(self, verts: Any, absolute: bool = False) -> None:
        f = np.abs if absolute else np.asarray
        for name in ("A", "B", "E", "B_p", "C_q", "D_q", "F"):
            setattr(self, name, f(np.stack([np.asarray(getattr(v, name)) for v in verts])))


_STACKED: list[tuple[Any, _Stack, _Stack]] = []  # the last model's within-period vertices, stacked


def _stacks(verts: tuple) -> tuple[_Stack, _Stack]:
    """:class:`_Stack` of ``verts`` and of their absolute values, kept for the next check of the same
    model (a synthesis re-checks every point it solves; stacking 768 vertices costs about 4 ms)."""
    hit = _STACKED[0] if _STACKED else None
    if hit is None or hit[0] is not verts:
        hit = (verts, _Stack(verts), _Stack(verts, absolute=True))
        _STACKED[:] = [hit]
    return hit[1], hit[2]


class _AbsVertex:
    """A vertex with every matrix replaced by its absolute value (for the magnitude of a formula)."""

    def __init__(self, v: Any) -> None:
        for name in ("A", "B", "E", "B_p", "C_q", "D_q"):
            setattr(self, name, np.abs(np.asarray(getattr(v, name))))
        self.F = np.abs(np.asarray(v.F))
        self.label = v.label
