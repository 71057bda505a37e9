"""The Lyapunov function of a checked certificate, V(xi, mu) (common, slip-, delay- or
path-dependent), which the judges evaluate on runs (docs/theory.md §6)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .lmis import _sym

__all__ = ["Lyapunov", "lyapunov_of", "rows_times"]


def rows_times(x: np.ndarray, M: np.ndarray) -> np.ndarray:
    """``x @ M`` for a batch of row vectors ``x`` (..., n) and a small matrix ``M`` (n, m), as one 2-D product where
    ``x`` is C-contiguous: numpy's matmul over a stack of (1, n) rows runs one tiny product per row (the adversary's
    66 816 candidates x 5 states: 7.2 ms against 0.6 ms as one product, BLAS on one thread).  The sums are those of a
    matrix product either way; their rounding may differ in the last bit (BLAS's kernels).  Other layouts (broadcast
    views) keep the stacked product."""
    x = np.asarray(x)
    if x.ndim <= 2 or not x.flags.c_contiguous:
        return x @ M
    return (x.reshape(-1, x.shape[-1]) @ M).reshape(x.shape[:-1] + (M.shape[-1],))


@dataclass(frozen=True)
class Lyapunov:
    """V(xi, mu) of a certificate: ``xi' S(mu)^-1 xi`` with S(mu) = Q (common) or the convex
    combination sum_m lambda_m(mu) S_m of the slip-corner matrices (slip-dependent), lambda the
    model's corner weights; delay-dependent: ``max_d xi' S(mu, d)^-1 xi`` over the delay vertices d,
    S(mu, d) = sum_m lambda_m(mu) S_(m, d) -- a piecewise-quadratic function that needs no delay;
    path-dependent: ``max_b xi' S(mu, prev, b)^-1 xi`` with ``prev`` the previous period's delay
    weights (``Model.delay_weights``), the largest over the previous delay vertices where it is not
    known (NaN) -- an upper bound (``Model.lyapunov_conditions``).  ``V_max`` is the largest value
    over every matrix (an upper bound for any mu and delays)."""

    model: Any
    S: tuple[np.ndarray, ...]
    P: tuple[np.ndarray, ...]
    slip_step: float | None = None  # a rate-bounded certificate: the slip moves at most this per period
    delay_vertices: int = 1  # delay-dependent: S_(m, d) at index m * n_d + d; path-dependent: S_(m, a, b)
    path: bool = False  # at (m * n_d + a) * n_d + b, a the previous period's delay vertex

    @property
    def any_next_slip(self) -> bool:
        """True when the LMIs hold for every next slip and delay (common Q, or slip may jump and the
        matrices do not depend on a past delay): then from one step on the state lies in the set of
        every slip, and ``V_max`` <= level."""
        return len(self.S) == 1 or (self.slip_step is None and not self.path)

    def V(self, xi: np.ndarray, mu: np.ndarray | None = None, prev: np.ndarray | None = None) -> np.ndarray:
        """``prev`` (..., n_d): the previous period's delay weights (path-dependent only; None or NaN
        rows: unknown, the largest value over the previous delay vertices)."""
        xi = np.asarray(xi, dtype=float)
        if len(self.S) == 1 or mu is None:
            return self.V_max(xi)
        lam = self.model.corner_weights(np.asarray(mu, dtype=float))
        n_d = self.delay_vertices
        n = self.S[0].shape[0]
        if not self.path:
            return self._max_over_d(xi, lam, np.array(self.S).reshape((-1, n_d, n, n)))
        allS = np.array(self.S).reshape((-1, n_d, n_d, n, n))  # (n_c, a, b, n, n)
        batch = xi.shape[:-1]
        lam = np.broadcast_to(lam, batch + lam.shape[-1:])
        prev = np.full(batch + (n_d,), np.nan) if prev is None else np.broadcast_to(np.asarray(prev, dtype=float), batch + (n_d,))
        known = np.all(np.isfinite(prev), axis=-1)
        out = np.empty(batch)
        if np.any(known):  # S(mu, prev, b) for the known previous weights
            out[known] = self._max_over_d(xi[known], lam[known], np.einsum("ka,mabij->kmbij", prev[known], allS))
        if not np.all(known):  # the largest over the previous delay vertex a
            u = ~known
            out[u] = np.max([self._max_over_d(xi[u], lam[u], allS[:, a]) for a in range(n_d)], axis=0)
        return out

    @staticmethod
    def _max_over_d(xi, lam, mats):
        """max_d xi' (sum_m lam_m mats[..., m, d])^-1 xi; ``mats`` (n_c, n_d, n, n) or per sample."""
        out = None
        for d in range(mats.shape[-3]):
            S = np.einsum("...m,...mij->...ij", lam, mats[..., d, :, :])
            sol = np.linalg.solve(S, xi[..., None])[..., 0]
            val = np.einsum("...i,...i->...", xi, sol)
            out = val if out is None else np.maximum(out, val)
        return out

    def V_max(self, xi: np.ndarray) -> np.ndarray:
        xi = np.asarray(xi, dtype=float)
        vals = [np.sum(rows_times(xi, P) * xi, axis=-1) for P in self.P]
        return np.max(vals, axis=0)


def lyapunov_of(model: Any, cert: Mapping[str, Any]) -> Lyapunov:
    """The Lyapunov function of a (checked) certificate."""
    step = None
    kind = cert.get("lyapunov", "common")
    n_d = 1
    if kind in ("slip-dependent", "delay-dependent", "path-dependent"):
        S = tuple(_sym(np.asarray(x, dtype=float)) for x in cert["S"])
        step = None if cert.get("slip_step") is None else float(cert["slip_step"])
        n_d = model.delay_vertex_count if kind != "slip-dependent" else 1
    else:
        S = (_sym(np.asarray(cert["Q"], dtype=float)),)
    return Lyapunov(model, S, tuple(np.linalg.inv(x) for x in S), step, n_d, kind == "path-dependent")
