"""The model family: the seed paper's lifted norm-bounded model and the slip-aware model.

:func:`build_model` turns a :class:`~robustsynth.config.Config` into a frozen :class:`Model`.
Every kind hands synthesis and verification the same interface (docs/theory.md §3-5):

- ``vertices``: the uncertain lifted model as LFT vertices (:class:`~.vertices.Vertex`), the only
  thing the LMIs and the certificate check read;
- ``exact(s_tilde, mu)`` and ``constant(mu)``: the exact lifted map ``xi+ = A xi + B du + c`` of the
  kind, for given switching instants and slip (what the lifted-model checks simulate);
- ``robot_exact`` / ``equilibrium``: the slip-aware map the real robot follows (whatever the kind),
  and its steady state under constant slip;
- ``hull_coordinates``: explicit convex (and Delta) coordinates that reproduce ``exact`` from the
  vertices (the coverage test).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..config import Config
from ..errors import ConfigError
from .kinematics import J_inverse, J_matrix
from .lifting import delay_indices, instant_ranges, lift, lifted_exact, s_tilde_sequence
from .linearize import Gamma, Gamma_D, Phi, continuous_matrices
from .slip import corner_weights, next_corner_weights, slip_corners, slip_matrix
from .uncertainty import SlipBox, UncertainInstant, delta_for, embed, slip_box
from .vertices import (Vertex, apply_slip, augment_integral, delay_vertex_gammas, loss_hull_coordinates,
                       loss_instant_grid, loss_vertex_gammas, triangle_coordinates)

__all__ = ["Model", "Vertex", "build_model", "pad_gain", "gain_lifting", "UncertainInstant", "SlipBox", "state_names", "INPUT_NAMES",
           "MODEL_KINDS", "MAX_POLYTOPIC_INSTANTS"]

INPUT_NAMES = ("dV", "omega")
ERROR_NAMES = ("e_x", "e_y", "e_theta")
SLIP_NAMES = ("dmu_r", "dmu_l")
INTEGRATOR_NAMES = ("int_e_x", "int_e_y")
MODEL_KINDS = ("slip-aware", "paper")
# 'auto' uses the exact-hull (polytopic) delay description up to this many uncertain instants
# (4 * 3^n vertices); beyond it the norm-bounded embedding, whose size grows linearly.
MAX_POLYTOPIC_INSTANTS = 1
_WIDTH_TOL = 1e-12


def state_names(d_hi: int, integral: bool = False) -> tuple[str, ...]:
    """e_x, e_y, e_theta, dV[k-1], omega[k-1], ..., dV[k-d_hi], omega[k-d_hi] [, int_e_x, int_e_y]."""
    names = list(ERROR_NAMES)
    for j in range(1, d_hi + 1):
        names += [f"dV[k-{j}]", f"omega[k-{j}]"]
    if integral:
        names += list(INTEGRATOR_NAMES)
    return tuple(names)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Model:
    """Lifted model of the networked tracking error (eqs. 25, 31-33) and its vertex description.

    ``A, B, B_d, B_p, C_q, D_q`` are the nominal (mu = 1) norm-bounded form of the paper,
    ``xi_{k+1} = A xi_k + B du_k + B_d d_k + B_p p_k``, ``p_k = Delta_k q_k``,
    ``q_k = C_q xi_k + D_q du_k`` (with the integrator rows when ``integral``); ``vertices`` is what
    the LMIs use for this ``kind``.
    """

    config: Config
    kind: str
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
    corners: np.ndarray  # (n_c, 2): slip corners (mu_r, mu_l)
    vertices: tuple[Vertex, ...]
    delay_description: str  # 'norm-bounded' or 'polytopic' (what the vertices use)
    integral: bool
    J: np.ndarray = field(repr=False)
    J_inv: np.ndarray = field(repr=False)

    n_e: int = 3
    n_u: int = 2
    dropouts: int = 0  # at most this many consecutive commands lost (network.dropouts.max_consecutive)

    @property
    def n_z(self) -> int:
        return 2 if self.integral else 0

    @property
    def n_s(self) -> int:
        return self.n_e + self.d_hi * self.n_u + self.n_z

    @property
    def n_q(self) -> int:
        return self.B_p.shape[1]

    @property
    def state_names(self) -> tuple[str, ...]:
        return state_names(self.d_hi, self.integral)

    @property
    def input_names(self) -> tuple[str, ...]:
        return INPUT_NAMES

    @property
    def B_w(self) -> np.ndarray:
        """Slip input in normalized box coordinates: B_d W (d = W w, |w_i| <= 1)."""
        return self.B_d @ self.slip.W

    @property
    def n_w(self) -> int:
        """Columns of every vertex's E (the bounded disturbance w, |w_i| <= 1)."""
        return self.vertices[0].E.shape[1]

    @property
    def slip_ranges(self) -> tuple[tuple[float, float], tuple[float, float]]:
        s = self.config.slip
        return (s.right.min, s.right.max), (s.left.min, s.left.max)

    # ------------------------------------------------------------------ exact maps

    def _base_exact(self, s_tilde: np.ndarray, mu: np.ndarray | None, slip_aware: bool):
        A, B, _ = lifted_exact(self.A_c, self.B_c, self.B_D_c, self.Ts, s_tilde)
        if slip_aware and mu is not None:
            M = slip_matrix(mu, self.config.robot.track_distance)
            A, B = apply_slip(A, B, M, self.n_e, self.n_u, self.d_hi)
        if self.integral:
            A, B = augment_integral(A, B, self.Ts, self.n_e)
        return A, B

    def exact(self, s_tilde: np.ndarray, mu: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Exact (A~, B~) of this kind for switching instants ``s_tilde[..., j]`` and slip ``mu[..., 2]``
        (eq. 25; the paper's kind ignores mu, the slip-aware kind multiplies the commands by M(mu))."""
        return self._base_exact(s_tilde, mu, self.kind == "slip-aware")

    def robot_exact(self, s_tilde: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The slip-aware exact map, which the real robot follows to first order whatever the kind."""
        return self._base_exact(s_tilde, mu, True)

    def constant(self, mu: np.ndarray) -> np.ndarray:
        """c(mu) = B~_d (mu - 1), the constant term of the exact map, shape (..., n_s)."""
        return (np.asarray(mu, dtype=float) - 1.0) @ np.asarray(self.B_d).T

    def disturbance_coordinates(self, mu: np.ndarray) -> np.ndarray:
        """w (..., n_w) with ``sum_i lambda_i E_i w = c(mu)`` for the hull weights lambda: the slip box
        coordinates for the paper's kind, w = 1 (the constant column) for the slip-aware kind."""
        mu = np.asarray(mu, dtype=float)
        if self.kind == "paper":
            return self.slip.coordinates(mu - 1.0)
        return np.ones(mu.shape[:-1] + (1,))

    def delta(self, s_tilde: np.ndarray) -> np.ndarray:
        """diag(Delta) that reproduces the exact delay matrices in the norm-bounded embedding (eqs. 31-33)."""
        return delta_for(self.instants, self.Ts, s_tilde)

    def s_tilde(self, taus: np.ndarray) -> np.ndarray:
        """Switching instants for packet delays ``taus[..., i]`` of packets sent at t_{i-d_hi}."""
        return s_tilde_sequence(taus, self.Ts, self.d_hi)

    def nominal_instants(self) -> np.ndarray:
        """A fixed admissible instant vector (the middle of every range), shape (d_hi,)."""
        return self.instant_ranges.mean(axis=1)

    def equilibrium(self, K: np.ndarray, mu: np.ndarray) -> np.ndarray:
        """Steady state xi*(mu) of the robot's lifted closed loop under constant slip (..., n_s):
        ``xi* = (A + B K) xi* + c(mu)``; independent of the delay (the stored commands are all du*)."""
        mu = np.asarray(mu, dtype=float)
        A, B = self.robot_exact(self.nominal_instants(), mu)
        Acl = A + B @ np.asarray(K, dtype=float)
        rhs = np.broadcast_to(self.constant(mu), Acl.shape[:-1])
        return np.linalg.solve(np.eye(self.n_s) - Acl, rhs[..., None])[..., 0]

    # ------------------------------------------------------------------ hull coordinates

    def corner_weights(self, mu: np.ndarray) -> np.ndarray:
        return corner_weights(mu, *self.slip_ranges)

    @property
    def slip_step(self) -> float | None:
        """Largest slip change in one period (slip.max_rate * Ts), None without a rate bound."""
        rate = self.config.slip.max_rate
        return None if rate is None else rate * self.Ts

    @property
    def rate_bounded(self) -> bool:
        """True when the rate bound restricts the next slip (narrower than some track's range)."""
        step = self.slip_step
        return step is not None and any(step < hi - lo for lo, hi in self.slip_ranges if hi > lo)

    @property
    def delay_vertex_count(self) -> int:
        """Delay vertices per slip corner: the vertices are corner-major, so vertex i has slip corner
        ``i // n`` and delay vertex ``i % n`` (1 for the paper's model and the norm-bounded embedding)."""
        return max(1, len(self.vertices) // max(1, int(np.asarray(self.corners).shape[0])))

    def next_corner_weights(self, m: int) -> np.ndarray:
        """Weights (n_next, n_c) over the corners of the slips that can follow corner m (one period)."""
        return next_corner_weights(self.corners[m], *self.slip_ranges, self.slip_step)

    def lyapunov_count(self, kind: str) -> int:
        """How many Lyapunov matrices a certificate of ``kind`` has (see :meth:`lyapunov_conditions`)."""
        n_c = int(np.asarray(self.corners).shape[0])
        n_d = self.delay_vertex_count
        return {"common": 1, "slip-dependent": n_c, "delay-dependent": n_c * n_d, "path-dependent": n_c * n_d * n_d}[kind]

    def lyapunov_conditions(self, kind: str, slip_step: float | None) -> list[list[tuple[int, list[tuple[float, int]], str]]]:
        """Per vertex i, the pairs (left, right, label) of one-period conditions a certificate of ``kind``
        must meet: ``left`` indexes the Lyapunov matrix of this period, ``right`` is the combination
        [(weight, index)] of the next period's.

        - ``common``: one matrix (index 0) on both sides;
        - ``slip-dependent``: one per slip corner m (index m); the right side is S at every slip that
          may follow corner m within ``slip_step`` (None: every corner) -- bilinear interpolation
          weights, which extrapolate;
        - ``delay-dependent``: one per slip corner m and delay vertex d (index m * n_d + d); vertex i
          (corner m, delay vertex d) has S_(m, d) on the left and, on the right, every next slip as
          above with every next delay vertex.  The conditions are multi-affine in this and the next
          period's slip and delay weights, so they hold for every admissible pair; with
          ``V(xi, mu) = max_d xi' S(mu, d)^-1 xi`` (S(mu, d) the corner interpolation) they give
          ``V(xi+, mu+) <= (1 - alpha) V(xi, mu) + ...`` without knowing the delays;
        - ``path-dependent``: one per slip corner m, delay vertex a of the previous period and b of
          this one (index (m * n_d + a) * n_d + b); vertex i (corner m, delay vertex b) has
          S_(m, a, b) on the left for every a and S_(n, b, c) on the right for every next slip and
          every c.  With ``V(xi, mu, prev) = max_b xi' S(mu, prev, b)^-1 xi`` (prev: the previous
          period's delay weights) the same inequality holds; V needs the previous period's delay."""
        if kind == "common":
            return [[(0, [(1.0, 0)], "")] for _ in self.vertices]
        n_d = self.delay_vertex_count if kind in ("delay-dependent", "path-dependent") else 1
        path = kind == "path-dependent"

        def index(m: int, a: int, b: int) -> int:  # S of slip corner m, previous delay vertex a, current b
            return (m * n_d + a) * n_d + b if path else m * n_d + b

        out = []
        for i, v in enumerate(self.vertices):
            m, b = int(v.corner), i % n_d
            W = next_corner_weights(self.corners[m], *self.slip_ranges, slip_step)
            conds = []
            for a in range(n_d if path else 1):
                for k, w in enumerate(W):
                    for c in range(n_d):
                        right = [(float(w[n]), index(n, b, c)) for n in range(w.size) if w[n] != 0.0]
                        lab = (f" (previous delay vertex {a})" if path else "") + f" -> next slip {k}" + (
                            f", next delay vertex {c}" if n_d > 1 else "")
                        conds.append((index(m, a, b), right, lab))
            out.append(conds)
        return out

    def delay_weights(self, s_tilde: np.ndarray) -> np.ndarray:
        """Convex weights (..., n_d) of one period's switching instants over the delay vertices (the
        delay part of :meth:`hull_coordinates`)."""
        w, _ = self.hull_coordinates(s_tilde, np.ones(2))
        n_c = max(1, len(self.vertices) // self.delay_vertex_count)
        return w.reshape(w.shape[:-1] + (n_c, self.delay_vertex_count)).sum(axis=-2)

    def reachable_instants(self, n: int) -> np.ndarray | None:
        """Switching-instant vectors the link can produce, delays on an n-point grid, when the model
        describes exactly those (lossy-polytopic); None when every vector in the instant ranges counts."""
        if self.delay_description != "lossy-polytopic":
            return None
        dl = self.config.network.delay
        return loss_instant_grid(self.Ts, dl.min, dl.max, self.dropouts, self.d_hi, n)

    def hull_coordinates(self, s_tilde: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Convex weights (..., n_vertices) and diag(Delta) (..., n_q) such that
        ``sum_i lambda_i (A_i + B_p Delta C_q_i, B_i + B_p Delta D_q_i, E_i w(mu))`` is the exact
        ``(A~(s~, mu), B~(s~, mu), c(mu))`` of this kind."""
        s_tilde = np.asarray(s_tilde, dtype=float)
        mu = np.asarray(mu, dtype=float)
        batch = np.broadcast_shapes(s_tilde.shape[:-1], mu.shape[:-1])
        s_tilde = np.broadcast_to(s_tilde, batch + s_tilde.shape[-1:])
        mu = np.broadcast_to(mu, batch + (2,))
        dlt = self.delta(s_tilde) if self.n_q else np.zeros(batch + (0,))
        if self.kind == "paper":
            return np.ones(batch + (1,)), dlt
        lam = self.corner_weights(mu)  # (..., n_c)
        if self.delay_description == "norm-bounded":
            return lam, dlt
        if self.delay_description == "lossy-polytopic":
            cfg = self.config
            w = loss_hull_coordinates(s_tilde, self.Ts, cfg.network.delay.min, cfg.network.delay.max, self.dropouts,
                                      self.d_hi, _WIDTH_TOL * max(self.Ts, 1.0))
            out = (lam[..., :, None] * w[..., None, :]).reshape(batch + (-1,))
            return out, np.zeros(batch + (0,))
        # polytopic: corner-major, then the product of the per-instant triangle coordinates
        tri = [np.ones(batch + (1,))]
        for j in range(self.d_hi):
            lo, hi = self.instant_ranges[j]
            if hi - lo <= _WIDTH_TOL * max(self.Ts, 1.0):
                continue
            t = triangle_coordinates(self.Ts - s_tilde[..., j], self.Ts - hi, self.Ts - lo)
            tri.append(t)
        w = tri[0]
        for t in tri[1:]:
            w = (w[..., :, None] * t[..., None, :]).reshape(batch + (-1,))
        out = (lam[..., :, None] * w[..., None, :]).reshape(batch + (-1,))
        return out, np.zeros(batch + (0,))

    def from_hull(self, weights: np.ndarray, delta: np.ndarray, w: np.ndarray):
        """Recombine the vertices: (A, B, c) for hull weights, diag(Delta) and disturbance w."""
        A = sum(weights[..., i, None, None] * (v.A + (v.B_p * delta[..., None, :]) @ v.C_q) for i, v in enumerate(self.vertices))
        B = sum(weights[..., i, None, None] * (v.B + (v.B_p * delta[..., None, :]) @ v.D_q) for i, v in enumerate(self.vertices))
        c = sum(weights[..., i, None] * (w @ v.E.T) for i, v in enumerate(self.vertices))
        return A, B, c


def _augment_rows(X: np.ndarray, n_z: int) -> np.ndarray:
    return np.vstack([X, np.zeros((n_z, X.shape[1]))]) if n_z else X


def _augment_cols(X: np.ndarray, n_z: int) -> np.ndarray:
    return np.hstack([X, np.zeros((X.shape[0], n_z))]) if n_z else X


def _resolve_delay_description(requested: str, n_uncertain: int) -> str:
    if requested == "auto":
        return "polytopic" if n_uncertain <= MAX_POLYTOPIC_INSTANTS else "norm-bounded"
    return requested


def build_model(config: Config, min_lifting: int | None = None) -> Model:
    """Build the model of ``config`` (kind ``config.synthesis.model``; docs/theory.md §1-5).

    ``min_lifting``: keep at least this many past inputs in the lifted state even when the delay
    bound needs fewer (the extra switching instants are fixed at 0): to analyse a gain designed for
    a longer lifting on a shorter delay range."""
    R = config.robot.gear_radius
    D = config.robot.track_distance
    V = config.reference.speed
    Ts = config.network.sampling_time
    syn = config.synthesis
    kind = syn.model
    integral = syn.integral_action
    n_z = 2 if integral else 0
    dropouts = config.network.dropouts.max_consecutive
    # a lost command is superseded when its successor arrives: an effective delay of up to
    # tau_max + m Ts with a zero-length active interval (docs/theory.md, packet loss)
    tmin, tmax = config.network.delay.min, config.network.delay.max + dropouts * config.network.sampling_time
    A_c, B_c, B_D_c = continuous_matrices(V, D)
    d_lo, d_hi = delay_indices(tmin, tmax, Ts)
    d_hi = max(d_hi, int(min_lifting or 0))
    ranges = instant_ranges(tmin, tmax, Ts, d_hi)
    n_e, n_u = B_c.shape
    instants, Gammas0, B_p, C_q, D_q = embed(A_c, B_c, Ts, ranges, n_e, n_u, d_hi)
    Ph = Phi(A_c, Ts)
    GD = Gamma_D(A_c, B_D_c, Ts)
    A, B, B_d = lift(Ph, Gammas0, Gamma(A_c, B_c, Ts), GD)
    mu_r = (config.slip.right.min, config.slip.right.max)
    mu_l = (config.slip.left.min, config.slip.left.max)
    slip = slip_box(mu_r, mu_l)
    corners = slip_corners(mu_r, mu_l)
    # nominal matrices in the (possibly augmented) state
    if integral:
        A, B = augment_integral(A, B, Ts, n_e)
    B_d = _augment_rows(B_d, n_z)
    B_p = _augment_rows(B_p, n_z)
    C_q = _augment_cols(C_q, n_z)
    n_s = A.shape[0]
    delay_description = "norm-bounded"
    vertices: list[Vertex] = []
    if kind == "paper":
        vertices.append(Vertex(A, B, B_d @ slip.W, B_p, C_q, D_q, 0, "nominal (mu = 1), slip as additive box"))
    else:
        tau_hi = config.network.delay.max  # of a received command (lost ones: the effective tmax)
        delay_description = _resolve_delay_description(syn.delay_description, len(instants))
        if syn.delay_description == "lossy-polytopic" or (syn.delay_description == "auto" and dropouts and tau_hi <= Ts):
            if tau_hi > Ts * (1 + 1e-12):
                raise ConfigError(f"synthesis.delay_description: lossy-polytopic needs network.delay.max <= "
                                  f"network.sampling_time (got {tau_hi:g} > {Ts:g}); use auto or norm-bounded")
            delay_description = "lossy-polytopic"
            labels, gammas = loss_vertex_gammas(A_c, B_c, Ts, tmin, tau_hi, dropouts, d_hi, _WIDTH_TOL * max(Ts, 1.0))
            A_t, B_t, _ = lift(Ph, gammas, Gamma(A_c, B_c, Ts), GD)
        elif delay_description == "polytopic":  # the delay vertices, the same for every slip corner
            labels, gammas, _ = delay_vertex_gammas(A_c, B_c, Ts, ranges, _WIDTH_TOL * max(Ts, 1.0))
            A_t, B_t, _ = lift(Ph, gammas, Gamma(A_c, B_c, Ts), GD)
        for m, mu in enumerate(corners):
            M = slip_matrix(mu, D)
            c = (mu - 1.0) @ B_d.T
            E = c[:, None]
            name = f"mu=({mu[0]:g}, {mu[1]:g})"
            if delay_description == "norm-bounded":
                Am, Bm = apply_slip(A, B, M, n_e, n_u, d_hi)
                T = np.eye(n_s)
                for j in range(d_hi):
                    T[n_e + j * n_u : n_e + (j + 1) * n_u, n_e + j * n_u : n_e + (j + 1) * n_u] = M
                vertices.append(Vertex(Am, Bm, E, B_p, C_q @ T, D_q @ M, m, name))
            else:
                At, Bt = apply_slip(A_t, B_t, M, n_e, n_u, d_hi)
                if integral:
                    At, Bt = augment_integral(At, Bt, Ts, n_e)
                for t, lab in enumerate(labels):
                    vertices.append(Vertex(At[t], Bt[t], E, np.zeros((n_s, 0)), np.zeros((0, n_s)),
                                           np.zeros((0, n_u)), m, f"{name}; {lab}"))
    frozen_vertices = tuple(
        Vertex(*(_frozen(x) for x in (v.A, v.B, v.E, v.B_p, v.C_q, v.D_q)), v.corner, v.label) for v in vertices
    )
    return Model(
        config=config,
        kind=kind,
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
        corners=_frozen(corners),
        vertices=frozen_vertices,
        delay_description=delay_description,
        integral=integral,
        dropouts=dropouts,
        J=_frozen(J_matrix(R, D)),
        J_inv=_frozen(J_inverse(R, D)),
    )


def coverage_check(model: Model, n_sequences: int = 1000, steps: int = 20, seed: int = 0) -> dict:
    """Coverage of the vertex description on random admissible (slip, delay history) samples, the
    delay extremes and the slip corners: the exact lifted matrices of the model's kind and its
    constant term are rebuilt from the vertices with explicit hull weights (>= 0, summing to 1) and
    Delta (|Delta_ii| <= 1).  Returns the sample count, the extremes of the coordinates and the
    largest residual."""
    cfg = model.config
    dl = cfg.network.delay
    rng = np.random.default_rng(seed)
    taus = rng.uniform(dl.min, dl.max, size=(n_sequences, steps + model.d_hi))
    # extremes: alternate min/max, and constant min / max
    taus[0, :] = dl.min
    taus[1, :] = dl.max
    taus[2, ::2] = dl.min
    taus[2, 1::2] = dl.max
    if model.dropouts:  # random bursts of up to m lost commands (inf) on all but the extremes
        from .network import gilbert_elliott, with_losses

        lost = gilbert_elliott(rng, taus.shape, 0.3, max(1.0, model.dropouts), model.dropouts)
        lost[:3] = False
        taus = with_losses(taus, lost)
    s = model.s_tilde(taus).reshape(-1, model.d_hi)
    if model.delay_description == "lossy-polytopic":  # only the instants a lossy link produces
        corners = model.reachable_instants(5)
    else:
        corners = np.array(np.meshgrid(*[r for r in model.instant_ranges], indexing="ij")).reshape(model.d_hi, -1).T
    s = np.vstack([s, corners])
    (rl, rh), (ll, lh) = model.slip_ranges
    mu = np.stack([rng.uniform(rl, rh, s.shape[0]), rng.uniform(ll, lh, s.shape[0])], axis=1)
    mu[: model.corners.shape[0]] = model.corners  # every slip corner at least once
    mu[-1] = [rh, lh]
    A_ex, B_ex = model.exact(s, mu)
    c_ex = model.constant(mu)
    lam, dlt = model.hull_coordinates(s, mu)
    A_h, B_h, c_h = model.from_hull(lam, dlt, model.disturbance_coordinates(mu))
    res = max(float(np.max(np.abs(A_ex - A_h), initial=0.0)), float(np.max(np.abs(B_ex - B_h), initial=0.0)),
              float(np.max(np.abs(c_ex - c_h), initial=0.0)))
    max_delta = float(np.max(np.abs(dlt), initial=0.0))
    min_weight = float(np.min(lam))
    sum_err = float(np.max(np.abs(lam.sum(axis=-1) - 1.0)))
    return {
        "samples": int(s.shape[0]),
        "vertices": len(model.vertices),
        "max_abs_delta": max_delta,
        "min_weight": min_weight,
        "max_weight_sum_error": sum_err,
        "max_residual": res,
        "passed": bool(max_delta <= 1.0 + 1e-12 and min_weight >= -1e-12 and sum_err <= 1e-12 and res <= 1e-12),
    }


def gain_lifting(K: np.ndarray, integral: bool) -> int:
    """How many past inputs a gain ``K`` (2 x (3 + 2 d + 2 integral)) acts on; InputError otherwise."""
    from ..errors import InputError

    K = np.asarray(K, dtype=float)
    n_z = 2 if integral else 0
    past = K.shape[1] - 3 - n_z if K.ndim == 2 else -1
    if K.ndim != 2 or K.shape[0] != len(INPUT_NAMES) or past < 2 or past % 2:
        raise InputError(f"K has shape {K.shape}: expected {len(INPUT_NAMES)} rows and 3 + 2 d_hi"
                         + (" + 2" if n_z else "") + " columns (e, past inputs" + (", integrators)" if n_z else ")"))
    return past // 2


def pad_gain(K: np.ndarray, model: Model) -> np.ndarray:
    """The same control law ``du_k = K xi_k`` on ``model``'s (possibly longer) lifted state: zero
    columns for the older inputs the gain does not use, integrator columns kept last."""
    from ..errors import InputError

    K = np.asarray(K, dtype=float)
    n_z = model.n_z
    d_k = gain_lifting(K, model.integral)
    if d_k > model.d_hi:
        raise InputError(f"K uses {d_k} past inputs; the model keeps {model.d_hi} (build it with min_lifting)")
    out = np.zeros((model.n_u, model.n_s))
    out[:, : 3 + 2 * d_k] = K[:, : 3 + 2 * d_k]
    if n_z:
        out[:, -n_z:] = K[:, -n_z:]
    return out


def lifted_slice(model: Model, longer: Model) -> np.ndarray:
    """Indices of ``model``'s lifted state inside the state of ``longer`` (same config, longer lifting)."""
    head = np.arange(3 + 2 * model.d_hi)
    tail = np.arange(longer.n_s - model.n_z, longer.n_s)
    return np.concatenate([head, tail])
