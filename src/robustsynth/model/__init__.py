"""The seed paper's model: kinematics, linearized error, lifted delay model, norm-bounded form.

:func:`build_model` turns a :class:`~robustsynth.config.Config` into a frozen :class:`Model`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..config import Config
from .kinematics import J_inverse, J_matrix
from .lifting import delay_indices, instant_ranges, lift, lifted_exact, s_tilde_sequence
from .linearize import Gamma, Gamma_D, Phi, continuous_matrices
from .uncertainty import SlipBox, UncertainInstant, delta_for, embed, slip_box

__all__ = ["Model", "build_model", "UncertainInstant", "SlipBox", "state_names", "INPUT_NAMES"]

INPUT_NAMES = ("dV", "omega")
ERROR_NAMES = ("e_x", "e_y", "e_theta")
SLIP_NAMES = ("dmu_r", "dmu_l")


def state_names(d_hi: int) -> tuple[str, ...]:
    """e_x, e_y, e_theta, dV[k-1], omega[k-1], ..., dV[k-d_hi], omega[k-d_hi] (math.md §7)."""
    names = list(ERROR_NAMES)
    for j in range(1, d_hi + 1):
        names += [f"dV[k-{j}]", f"omega[k-{j}]"]
    return tuple(names)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Model:
    """Lifted, norm-bounded model of the networked tracking error (eqs. 25, 31-33).

    ``xi_{k+1} = A xi_k + B du_k + B_d d_k + B_p p_k``, ``p_k = Delta_k q_k``,
    ``q_k = C_q xi_k + D_q du_k``, ``Delta_k = blockdiag(delta1 I2, delta2, ...)``, |delta| <= 1.
    """

    config: Config
    d_lo: int
    d_hi: int
    Ts: float
    V: float
    instant_ranges: np.ndarray  # (d_hi, 2): [lo, hi] of s~_j
    A_c: np.ndarray
    B_c: np.ndarray
    B_D_c: np.ndarray
    Phi: np.ndarray
    Gamma_D: np.ndarray
    A: np.ndarray
    B: np.ndarray
    B_d: np.ndarray
    B_p: np.ndarray
    C_q: np.ndarray
    D_q: np.ndarray
    instants: tuple[UncertainInstant, ...]
    slip: SlipBox
    J: np.ndarray = field(repr=False)
    J_inv: np.ndarray = field(repr=False)

    n_e: int = 3
    n_u: int = 2

    @property
    def n_s(self) -> int:
        return self.n_e + self.d_hi * self.n_u

    @property
    def n_q(self) -> int:
        return self.B_p.shape[1]

    @property
    def state_names(self) -> tuple[str, ...]:
        return state_names(self.d_hi)

    @property
    def input_names(self) -> tuple[str, ...]:
        return INPUT_NAMES

    @property
    def B_w(self) -> np.ndarray:
        """Slip input in normalized box coordinates: B_d W (d = W w, |w_i| <= 1)."""
        return self.B_d @ self.slip.W

    def exact(self, s_tilde: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact (A~(s~), B~(s~)) for switching instants ``s_tilde[..., j]`` (eq. 25)."""
        A, B, _ = lifted_exact(self.A_c, self.B_c, self.B_D_c, self.Ts, s_tilde)
        return A, B

    def delta(self, s_tilde: np.ndarray) -> np.ndarray:
        """diag(Delta) that reproduces :meth:`exact` at ``s_tilde`` in the embedding (eqs. 31-33)."""
        return delta_for(self.instants, self.Ts, s_tilde)

    def s_tilde(self, taus: np.ndarray) -> np.ndarray:
        """Switching instants for packet delays ``taus[..., i]`` of packets sent at t_{i-d_hi}."""
        return s_tilde_sequence(taus, self.Ts, self.d_hi)


def build_model(config: Config) -> Model:
    """Build the lifted norm-bounded model of ``config`` (math.md §1-4)."""
    R = config.robot.gear_radius
    D = config.robot.track_distance
    V = config.reference.speed
    Ts = config.network.sampling_time
    tmin, tmax = config.network.delay.min, config.network.delay.max
    A_c, B_c, B_D_c = continuous_matrices(V, D)
    d_lo, d_hi = delay_indices(tmin, tmax, Ts)
    ranges = instant_ranges(tmin, tmax, Ts, d_hi)
    n_e, n_u = B_c.shape
    instants, Gammas0, B_p, C_q, D_q = embed(A_c, B_c, Ts, ranges, n_e, n_u, d_hi)
    Ph = Phi(A_c, Ts)
    GD = Gamma_D(A_c, B_D_c, Ts)
    A, B, B_d = lift(Ph, Gammas0, Gamma(A_c, B_c, Ts), GD)
    slip = slip_box((config.slip.right.min, config.slip.right.max), (config.slip.left.min, config.slip.left.max))
    return Model(
        config=config,
        d_lo=d_lo,
        d_hi=d_hi,
        Ts=Ts,
        V=V,
        instant_ranges=_frozen(ranges),
        A_c=_frozen(A_c),
        B_c=_frozen(B_c),
        B_D_c=_frozen(B_D_c),
        Phi=_frozen(Ph),
        Gamma_D=_frozen(GD),
        A=_frozen(A),
        B=_frozen(B),
        B_d=_frozen(B_d),
        B_p=_frozen(B_p),
        C_q=_frozen(C_q),
        D_q=_frozen(D_q),
        instants=instants,
        slip=slip,
        J=_frozen(J_matrix(R, D)),
        J_inv=_frozen(J_inverse(R, D)),
    )


def coverage_check(model: Model, n_sequences: int = 1000, steps: int = 20, seed: int = 0) -> dict:
    """Embedding coverage on random admissible delay sequences and on the instant-range corners.

    Returns the largest |Delta_ii| and the largest residual between the exact matrices and
    the embedding with that Delta.
    """
    cfg = model.config.network
    rng = np.random.default_rng(seed)
    taus = rng.uniform(cfg.delay.min, cfg.delay.max, size=(n_sequences, steps + model.d_hi))
    # extremes: alternate min/max, and constant min / max
    taus[0, :] = cfg.delay.min
    taus[1, :] = cfg.delay.max
    taus[2, ::2] = cfg.delay.min
    taus[2, 1::2] = cfg.delay.max
    s = model.s_tilde(taus).reshape(-1, model.d_hi)
    corners = np.array(np.meshgrid(*[r for r in model.instant_ranges], indexing="ij")).reshape(model.d_hi, -1).T
    s = np.vstack([s, corners])
    A_ex, B_ex = model.exact(s)
    dlt = model.delta(s)
    A_emb = model.A + np.einsum("ij,nj,jk->nik", model.B_p, dlt, model.C_q)
    B_emb = model.B + np.einsum("ij,nj,jk->nik", model.B_p, dlt, model.D_q)
    res = max(float(np.max(np.abs(A_ex - A_emb), initial=0.0)), float(np.max(np.abs(B_ex - B_emb), initial=0.0)))
    max_delta = float(np.max(np.abs(dlt), initial=0.0))
    return {
        "samples": int(s.shape[0]),
        "max_abs_delta": max_delta,
        "max_residual": res,
        "passed": bool(max_delta <= 1.0 + 1e-12 and res <= 1e-12),
    }
