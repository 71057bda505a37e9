"""Norm-bounded embedding of the delay uncertainty (eqs. 31-33, docs/theory.md §4) and the slip box.

For an uncertain instant j, ``h = Ts - s~_j`` ranges over ``[h_min, h_max]`` and
``Gamma(h) = h B + g A B`` with ``g = h^2/2``.  We take as nominal the centre of the box spanned by
(h, g): ``Gamma_0 = h_c B + g_c A B``, so that

    Gamma(h) = Gamma_0 - [a1 B, a2 A B e2] diag(delta1 I2, delta2) [I2; e2^T],
    delta1 = (h_c - h)/a1,  delta2 = (g_c - g)/a2,  |delta_i| <= 1,

with ``a1 = (h_max - h_min)/2`` and ``a2 = (h_max^2 - h_min^2)/4``.  (The mid-range instant gives the same a1 and an a2 larger by (h_max - h_min)^2/8; the box centre is never worse.)
The block multiplies ``du_{k-j} - du_{k-j-1}``; ``A B`` has only its second column non-zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["UncertainInstant", "embed", "delta_for", "SlipBox", "slip_box"]

_WIDTH_TOL = 1e-12


@dataclass(frozen=True)
class UncertainInstant:
    """One uncertain switching instant s~_j and its block diag(delta1 I2, delta2) of Delta."""

    j: int
    s_range: tuple[float, float]
    h_range: tuple[float, float]
    h_c: float
    g_c: float
    alpha1: float
    alpha2: float

    @property
    def s_nominal(self) -> float:
        """The instant whose h is the centre h_c (the nominal Gamma's B part)."""
        return self.s_range[0] + (self.s_range[1] - self.s_range[0]) / 2.0


def embed(A, B, Ts, ranges, n_e, n_u, d_hi):
    """Return (instants, Gammas0, B_p, C_q, D_q).

    ``Gammas0[j]`` is the nominal Gamma_j (the exact one for a fixed instant); ``B_p``, ``C_q``,
    ``D_q`` act on the lifted state; Delta = blockdiag over instants of diag(d1, d1, d2).
    """
    from .linearize import Gamma

    AB = A @ B
    n_s = n_e + d_hi * n_u
    instants: list[UncertainInstant] = []
    Gammas0 = np.zeros((d_hi, n_e, n_u))
    for j in range(d_hi):
        lo, hi = float(ranges[j, 0]), float(ranges[j, 1])
        if hi - lo <= _WIDTH_TOL * max(Ts, 1.0):
            Gammas0[j] = Gamma(A, B, Ts - lo)
            continue
        h_min, h_max = Ts - hi, Ts - lo
        h_c = (h_min + h_max) / 2.0
        g_c = (h_min**2 + h_max**2) / 4.0
        a1 = (h_max - h_min) / 2.0
        a2 = (h_max**2 - h_min**2) / 4.0
        Gammas0[j] = h_c * B + g_c * AB
        instants.append(UncertainInstant(j, (lo, hi), (h_min, h_max), h_c, g_c, a1, a2))
    n_q = 3 * len(instants)
    B_p = np.zeros((n_s, n_q))
    C_q = np.zeros((n_q, n_s))
    D_q = np.zeros((n_q, n_u))
    e2 = np.zeros(n_u)
    e2[1] = 1.0
    sel = np.vstack([np.eye(n_u), e2])  # [I2; e2^T]
    for b, inst in enumerate(instants):
        rows = slice(3 * b, 3 * b + 3)
        B_p[:n_e, 3 * b : 3 * b + 2] = -inst.alpha1 * B
        B_p[:n_e, 3 * b + 2] = -inst.alpha2 * AB[:, 1]
        # q_b = sel (du_{k-j} - du_{k-j-1}); du_{k-j} is du_k for j = 0, else state slot j.
        j = inst.j
        if j == 0:
            D_q[rows] = sel
        else:
            C_q[rows, n_e + (j - 1) * n_u : n_e + j * n_u] = sel
        C_q[rows, n_e + j * n_u : n_e + (j + 1) * n_u] = -sel
    return tuple(instants), Gammas0, B_p, C_q, D_q


def delta_for(instants, Ts: float, s_tilde: np.ndarray) -> np.ndarray:
    """The diagonal of Delta reproducing the exact model at ``s_tilde[..., j]``; shape (..., 3*n_b)."""
    s_tilde = np.asarray(s_tilde, dtype=float)
    out = np.zeros(s_tilde.shape[:-1] + (3 * len(instants),))
    for b, inst in enumerate(instants):
        h = Ts - s_tilde[..., inst.j]
        d1 = (inst.h_c - h) / inst.alpha1
        d2 = (inst.g_c - h * h / 2.0) / inst.alpha2
        # the exact values lie in [-1, 1]; clipping removes round-off of (h_c - h) / alpha only
        d1 = np.clip(d1, -1.0, 1.0)
        d2 = np.clip(d2, -1.0, 1.0)
        out[..., 3 * b] = d1
        out[..., 3 * b + 1] = d1
        out[..., 3 * b + 2] = d2
    return out


@dataclass(frozen=True)
class SlipBox:
    """Slip deviation d = mu - 1 = W w with w in [-1, 1]^{n_w} (component-wise box).

    The centre ``d_c`` of a non-symmetric range is carried as one more bounded component
    (w_0 in [-1, 1] holding the value 1), so W = [d_c, diag(half-widths)] without zero columns.
    """

    d_min: tuple[float, float]
    d_max: tuple[float, float]
    W: np.ndarray  # (2, n_w)
    labels: tuple[str, ...]

    def coordinates(self, d: np.ndarray) -> np.ndarray:
        """The box coordinates w (..., n_w) of slip deviations d (..., 2): w_centre = 1 and
        w_i = (d_i - c_i) / half-width_i, so that d = W w and |w_i| <= 1 inside the box."""
        d = np.asarray(d, dtype=float)
        lo, hi = np.array(self.d_min), np.array(self.d_max)
        c, half = (lo + hi) / 2.0, (hi - lo) / 2.0
        cols = []
        for name in self.labels:
            if name == "centre":
                cols.append(np.ones(d.shape[:-1]))
            else:
                i = 0 if name == "dmu_r" else 1
                cols.append((d[..., i] - c[i]) / half[i])
        return np.stack(cols, axis=-1) if cols else np.zeros(d.shape[:-1] + (0,))


def slip_box(mu_r: tuple[float, float], mu_l: tuple[float, float]) -> SlipBox:
    d_min = (mu_r[0] - 1.0, mu_l[0] - 1.0)
    d_max = (mu_r[1] - 1.0, mu_l[1] - 1.0)
    centre = np.array([(d_min[0] + d_max[0]) / 2.0, (d_min[1] + d_max[1]) / 2.0])
    half = np.array([(d_max[0] - d_min[0]) / 2.0, (d_max[1] - d_min[1]) / 2.0])
    cols, labels = [], []
    if np.any(np.abs(centre) > _WIDTH_TOL):
        cols.append(centre)
        labels.append("centre")
    for i, name in enumerate(("dmu_r", "dmu_l")):
        if half[i] > _WIDTH_TOL:
            c = np.zeros(2)
            c[i] = half[i]
            cols.append(c)
            labels.append(name)
    W = np.stack(cols, axis=1) if cols else np.zeros((2, 0))
    W.setflags(write=False)
    return SlipBox(d_min, d_max, W, tuple(labels))
