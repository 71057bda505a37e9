"""Vertex descriptions of the uncertain lifted model (docs/theory.md §4-5).

Every model of the family hands synthesis and verification the same thing: a tuple of
:class:`Vertex` es, each an LFT in the delay ``(A_i, B_i, E_i, B_p, C_q_i, D_q_i)`` that may have
no Delta at all, such that for every admissible slip and delay history the exact lifted matrices
are a convex combination of the vertices' (with one Delta, |Delta| <= 1, shared by all of them).
An LMI that is affine in (A, B, E, C_q, D_q) and holds at every vertex (each with its own
multiplier) therefore holds everywhere.

- ``paper``: one vertex, the norm-bounded form of eqs. 31-33, slip as the additive box ``B_w w``.
- ``slip-aware``: per slip corner m the command columns are multiplied by ``M(mu_m)`` and the
  constant column ``c_m = B~_d (mu_m - 1)`` is tied to the vertex (E_m = c_m, w = 1); delays either
  by the norm-bounded embedding (same Delta for every corner) or by the exact hull: the curve
  (h, h^2/2) lies in the triangle of its end points and the crossing of its end tangents, so each
  uncertain instant contributes 3 vertices (4 * 3^n_b in all).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

__all__ = ["Vertex", "apply_slip", "augment_integral", "triangle", "triangle_coordinates", "delay_vertex_gammas"]


@dataclass(frozen=True)
class Vertex:
    """One vertex: ``xi+ = A xi + B du + E w + B_p p``, ``p = Delta q``, ``q = C_q xi + D_q du``.

    ``corner`` indexes the slip corner (the Lyapunov matrix of a slip-dependent certificate);
    ``label`` names the vertex in reports."""

    A: np.ndarray
    B: np.ndarray
    E: np.ndarray
    B_p: np.ndarray
    C_q: np.ndarray
    D_q: np.ndarray
    corner: int
    label: str

    @property
    def n_q(self) -> int:
        return self.B_p.shape[1]


def apply_slip(A: np.ndarray, B: np.ndarray, M: np.ndarray, n_e: int, n_u: int, d_hi: int):
    """Multiply every command entering the error rows by the slip matrix M (..., 2, 2).

    In the lifted map the error rows hold ``Gamma(h) (du_{k-j} - du_{k-j-1})``; the robot receives
    ``M du``, so exactly these blocks (and B's error rows) are right-multiplied by M.  The shift
    register rows (stored commands) are what the controller sent and stay as they are."""
    A = np.array(A, dtype=float, copy=True)
    B = np.array(B, dtype=float, copy=True)
    M = np.asarray(M, dtype=float)
    shape = np.broadcast_shapes(A.shape[:-2], M.shape[:-2])
    A = np.broadcast_to(A, shape + A.shape[-2:]).copy()
    B = np.broadcast_to(B, shape + B.shape[-2:]).copy()
    for j in range(d_hi):
        cols = slice(n_e + j * n_u, n_e + (j + 1) * n_u)
        A[..., :n_e, cols] = A[..., :n_e, cols] @ M
    B[..., :n_e, :] = B[..., :n_e, :] @ M
    return A, B


def augment_integral(A: np.ndarray, B: np.ndarray, Ts: float, n_e: int = 3):
    """Append the integrator states z = (int_e_x, int_e_y), ``z+ = z + Ts (e_x, e_y)``, last to xi."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    n = A.shape[-1]
    Aa = np.zeros(A.shape[:-2] + (n + 2, n + 2))
    Aa[..., :n, :n] = A
    Aa[..., n, 0] = Ts
    Aa[..., n + 1, 1] = Ts
    Aa[..., n:, n:] = np.eye(2)
    Ba = np.zeros(B.shape[:-2] + (n + 2, B.shape[-1]))
    Ba[..., :n, :] = B
    return Aa, Ba


def triangle(h_min: float, h_max: float) -> np.ndarray:
    """Vertices (h, h^2/2) of the triangle that contains the curve (h, h^2/2) on [h_min, h_max]:
    the two end points and the crossing of the end tangents ((h_min+h_max)/2, h_min h_max/2)."""
    return np.array([[h_min, h_min**2 / 2.0], [h_max, h_max**2 / 2.0], [(h_min + h_max) / 2.0, h_min * h_max / 2.0]])


def triangle_coordinates(h: np.ndarray, h_min: float, h_max: float) -> np.ndarray:
    """Barycentric coordinates (..., 3) of (h, h^2/2) in :func:`triangle`; all in [0, 1] for h in range.

    With t = (h - h_min)/(h_max - h_min): weights (1-t)^2, t^2, 2 t (1-t) (a quadratic Bezier curve
    whose control point is the tangents' crossing)."""
    t = (np.asarray(h, dtype=float) - h_min) / (h_max - h_min)
    return np.stack([(1.0 - t) ** 2, t**2, 2.0 * t * (1.0 - t)], axis=-1)


def delay_vertex_gammas(A_c: np.ndarray, B_c: np.ndarray, Ts: float, ranges: np.ndarray, width_tol: float):
    """Per-instant Gammas of every delay vertex: (list of labels, array (n_v, d_hi, n_e, n_u), list of
    uncertain instant indices).  A fixed instant contributes its exact Gamma."""
    AB = A_c @ B_c
    per, unc = [], []
    for j, (lo, hi) in enumerate(np.asarray(ranges)):
        h_min, h_max = Ts - hi, Ts - lo
        if h_max - h_min <= width_tol:
            per.append([(f"s{j}={lo:g}", h_max * B_c + h_max**2 / 2.0 * AB)])
            continue
        unc.append(j)
        tri = triangle(h_min, h_max)
        names = (f"s{j}={hi:g}", f"s{j}={lo:g}", f"s{j}:tangents")
        per.append([(names[v], tri[v, 0] * B_c + tri[v, 1] * AB) for v in range(3)])
    labels, gammas = [], []
    for combo in itertools.product(*per):
        labels.append(", ".join(c[0] for c in combo))
        gammas.append(np.stack([c[1] for c in combo]))
    return labels, np.array(gammas), unc
