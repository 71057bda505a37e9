"""The :class:`Model`: what synthesis and verification read of a scenario (docs/theory.md §3-5).

Every kind (the seed paper's lifted norm-bounded model, the slip-aware model) hands on the same
interface:

- ``vertices``: the uncertain lifted model as LFT vertices (:class:`~.vertices.Vertex`), the only
  thing the LMIs and the certificate check read;
- ``exact(s_tilde, mu)`` and ``constant(mu)``: the exact lifted map ``xi+ = A xi + B du + c`` of the
  kind, for given switching instants and slip (what the lifted-model checks simulate);
- ``robot_exact`` / ``equilibrium``: the slip-aware map the real robot follows (whatever the kind),
  and its steady state under constant slip;
- ``hull_coordinates``: explicit convex (and Delta) coordinates that reproduce ``exact`` from the
  vertices (the coverage test).

Also the lifted state's layout: its names (:func:`state_names`) and how a gain's columns map onto
it (:func:`gain_lifting`, :func:`pad_gain`, :func:`lifted_slice`).  :mod:`.build` makes a Model.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, Sequence

import numpy as np

from ..config import Config
from ..core.network import Network, s_tilde_sequence
from .linearize import lifted_exact
from .mirror import Mirror, closure, find_mirror, mirror_pairs, restrict
from .slip import (SLIP_PARAMETERS, check_physical_feasibility, corner_weights, lateral_row, next_corner_weights,
                   nominal_slip, slip_matrix, slip_parameter_ranges)
from .uncertainty import SlipBox, UncertainInstant, delta_for
from .vertices import (Vertex, add_lateral, apply_slip, augment_integral, icr_constant, interval_coordinates,
                       interval_slip_averages, loss_hull_coordinates, loss_instant_grid, piecewise_twist_averages,
                       triangle_coordinates, varying_slip_maps, in_order_weights)

__all__ = ["Model", "Mirror", "state_names", "gain_lifting", "pad_gain", "lifted_slice", "INPUT_NAMES", "ERROR_NAMES",
           "SLIP_NAMES", "INTEGRATOR_NAMES", "MODEL_KINDS", "MAX_POLYTOPIC_INSTANTS", "WIDTH_TOL",
           "DEFAULT_HEADING_BOUND"]

INPUT_NAMES = ("dV", "omega")
ERROR_NAMES = ("e_x", "e_y", "e_theta")
SLIP_NAMES = ("dmu_r", "dmu_l")
INTEGRATOR_NAMES = ("int_e_x", "int_e_y")
MODEL_KINDS = ("slip-aware", "paper")
# 'auto' uses the covering-triangle (polytopic) delay description up to this many uncertain instants
# (4 * 3^n vertices); beyond it the norm-bounded embedding, whose size grows linearly.
MAX_POLYTOPIC_INSTANTS = 1
# nonlinear kinematics with heading_bound: auto: the model is built at this bound, synthesis searches
DEFAULT_HEADING_BOUND = 0.3
WIDTH_TOL = 1e-12


def state_names(d_hi: int, integral: bool = False) -> tuple[str, ...]:
    """e_x, e_y, e_theta, dV[k-1], omega[k-1], ..., dV[k-d_hi], omega[k-d_hi] [, int_e_x, int_e_y]."""
    names = list(ERROR_NAMES)
    for j in range(1, d_hi + 1):
        names += [f"dV[k-{j}]", f"omega[k-{j}]"]
    if integral:
        names += list(INTEGRATOR_NAMES)
    return tuple(names)


def frozen_array(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def frozen_vertex(v: Vertex) -> Vertex:
    """The vertex with read-only copies of its matrices."""
    mats = ("A", "B", "E", "B_p", "C_q", "D_q", "F_q")
    return replace(v, **{k: frozen_array(getattr(v, k)) for k in mats if getattr(v, k) is not None})


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
    # the kinematic channels of every vertex (model/nonlinear.py; delay vertices only, else empty) and
    # the linearized vertices they augment; heading_bound is set when ``vertices`` carry them
    channels: tuple = field(default=(), repr=False)
    base_vertices: tuple = field(default=(), repr=False)
    heading_bound: float | None = None
    # slip that changes within a period (docs/theory.md §11): vertices whose hull contains the
    # linearized lifted map for every slip history in the box, or () and why they are not built
    # (read them through :meth:`slip_variation`)
    varying: tuple = field(default=(), repr=False)
    varying_reason: str = ""
    # the kinematic channels that also hold for slip changing within a period, one per delay vertex
    # (model/nonlinear.covering_channels; () where ``varying`` is not built), the delay vertex of each
    # of ``varying``, and, on a model whose vertices carry these channels, ``varying`` augmented with them
    covering: tuple = field(default=(), repr=False)
    varying_delay: tuple = field(default=(), repr=False)
    covering_vertices: tuple = field(default=(), repr=False)
    # the icr model's linear map for slip changing within a period by vertices (vertices.icr_varying_vertices), the
    # delay vertex of each, and the covering channels that go with them, per delay vertex (docs/theory.md §12): what
    # a model with the kinematic channels covers slip changing within a period with (() where not built; ``covering``
    # then, as for a linearized model and for a certificate made before)
    icr_varying: tuple = field(default=(), repr=False)
    icr_varying_delay: tuple = field(default=(), repr=False)
    icr_covering: tuple = field(default=(), repr=False)
    # the channels for slip changing within a period that the vertices carry, one per delay vertex (``covering`` or
    # ``icr_covering``; () where they carry none): their heading rows bound |e_theta(t)|
    cover_channels: tuple = field(default=(), repr=False)
    appended: int = 0  # how many of ``vertices`` (the last) are within-period vertices :meth:`with_cuts` appended
    # the reference yaw rates the vertices cover (model/arcs.py; None: straight segments only)
    turns: Any = None
    # polytopic delays: which combinations of the instants' triangles are vertices (vertices.DELAY_COVERS),
    # the uncertain instants, their triangles' h-ranges (n, 2) and the combination of each delay vertex
    delay_cover: str = "product"
    delay_uncertain: tuple = ()
    delay_cover_h: Any = field(default=None, repr=False)
    delay_combos: tuple = field(default=(), repr=False)
    # the slip-compensated law (model/compensation.py, docs/theory.md §18): ``config`` is then the certificate's
    # (the ratio box), and this holds the user's config, the estimate error and the ratio box; None: uncompensated
    compensation: Any = None
    # how this plant is built from a config (:func:`~robustsynth.model.build.build_model`, which sets it): what
    # :meth:`rebuilt` calls, so that the plant-generic rooms build another scenario of it without importing the model
    builder: Any = field(default=None, repr=False, compare=False)

    @property
    def user_config(self) -> Config:
        """The config as the user wrote it: ``config`` itself, or for a compensated law the one with the true slip
        box (``config`` is then the certificate's, docs/theory.md §18)."""
        return self.config if self.compensation is None else self.compensation.config

    def rebuilt(self, config: Config) -> "Model":
        """The same plant built again from ``config``: another scenario of it (a relaxed constraint, a remedy).  The
        plant-generic rooms change a plant's scenario through this (synthesis.diagnose, synthesis.remedies), so they
        need not know how a tracked robot's model is built."""
        if self.builder is None:
            raise ValueError("this model was not made by build_model, so it cannot be rebuilt from a config")
        return self.builder(config)

    @property
    def kinematics(self) -> str:
        """'nonlinear' when the vertices carry the kinematic channels (docs/theory.md §9)."""
        return "nonlinear" if self.heading_bound is not None else "linearized"

    def linearized(self) -> "Model":
        """The model without the kinematic channels (itself when it has none)."""
        if self.heading_bound is None:
            return self
        out = replace(self, vertices=self.base_vertices, heading_bound=None, covering_vertices=(), cover_channels=())
        if self.turns is not None:  # the linearized turning vertices (model/arcs.py), covering what these cover
            from .arcs import turning_vertices

            verts, cover = turning_vertices(out, self.turns, within_period=bool(self.covering_vertices))
            out = replace(out, vertices=tuple(frozen_vertex(v) for v in verts),
                          covering_vertices=tuple(frozen_vertex(v) for v in cover))
        return out

    @property
    def heading_channels(self) -> tuple:
        """The channels whose heading rows bound |e_theta(t)| within a period: the covering ones when
        the vertices carry them (every slip corner per command interval), else one per vertex."""
        return (self.cover_channels or self.covering) if self.covering_vertices else self.channels

    def within_period_cover(self, nonlinear: bool, icr_channels: bool = False) -> tuple[tuple, tuple, tuple]:
        """The channels for slip changing within a period (one per delay vertex) and the vertices of its linear map
        with the delay vertex of each: ``covering``, ``varying``; for the icr model with the kinematic channels
        (``nonlinear``) its own vertices (``icr_varying``, which hold only with their channels ``icr_covering``),
        unless ``icr_channels`` (a certificate made before them: the channels alone, docs/theory.md §12)."""
        if nonlinear and self.icr_varying and not icr_channels:
            return self.icr_covering, self.icr_varying, self.icr_varying_delay
        return self.covering, self.varying, self.varying_delay

    def with_heading_bound(self, theta_bar: float, within_period: bool = True, icr_channels: bool = False) -> "Model":
        """The same model whose vertices carry the kinematic channels for |e_theta(t)| <= theta_bar:
        for slip changing within a period where the model covers it (``within_period``, and
        ``covering`` built: docs/theory.md §9), else for slip constant within each period.  The icr model
        covers it by the vertices of each command interval's twist where it has them (``icr_varying``), or
        with ``icr_channels`` (a certificate made before them) by channels alone (§12)."""
        from ..errors import InputError
        from .nonlinear import augment, channel_scales

        if not self.channels:
            raise InputError("synthesis.kinematics: nonlinear needs delay vertices (delay_description polytopic "
                             "or lossy-polytopic) and the slip-aware model")
        theta_bar = float(theta_bar)
        if not 0.0 < theta_bar <= 1.0:
            raise InputError(f"synthesis.heading_bound: {theta_bar:g} rad is outside (0, 1]")
        if self.turns is not None:  # the turning vertices for the nonlinear robot (model/arcs.py)
            from .arcs import turning_vertices

            within = within_period and bool(self.covering)
            verts, cover = turning_vertices(self, self.turns, theta_bar, within, icr_channels=icr_channels)
            return replace(self, vertices=tuple(frozen_vertex(v) for v in verts), heading_bound=theta_bar,
                           covering_vertices=tuple(frozen_vertex(v) for v in cover),
                           cover_channels=self.within_period_cover(True, icr_channels)[0] if within else ())
        covering = within_period and bool(self.covering)
        channels, varying, varying_delay = self.within_period_cover(True, icr_channels)
        # covering: one multiplier per delay vertex (vertices are corner-major: vertex i has delay vertex i % n_d)
        n_d = len(channels)
        groups = [i % n_d if covering else -1 for i in range(len(self.base_vertices))]
        chans = [channels[i % n_d] for i in range(len(groups))] if covering else list(self.channels)
        scales = channel_scales(chans, theta_bar, self.V)
        verts = tuple(frozen_vertex(augment(v, ch, theta_bar, self.V, scales, group=g))
                      for v, ch, g in zip(self.base_vertices, chans, groups))
        if not covering:
            cover = ()
        elif self.icr and not varying:  # the icr channels cover every slip history on the constant-slip vertices (§12)
            cover = verts
        else:
            cover = tuple(frozen_vertex(augment(v, channels[t], theta_bar, self.V, scales, group=t))
                          for v, t in zip(varying, varying_delay))
        return replace(self.linearized(), vertices=verts, heading_bound=theta_bar, covering_vertices=cover,
                       cover_channels=channels if covering else ())

    def with_turns(self, max_yaw_rate: float, max_step: float | None = None,
                   within_period: bool | None = None, merged: bool = True, icr_channels: bool = False) -> "Model":
        """The same model whose vertices cover a reference turning along arcs: yaw rate |w_k| <=
        ``max_yaw_rate`` [rad/s], constant on each sampling period, changing by at most ``max_step``
        (default ``max_yaw_rate``) between periods, with the turning feedforward in the commands
        (docs/theory.md §10, model/arcs.py), for the linearization or, on a model with a heading bound, the
        nonlinear robot.  The tracks slip model.  ``within_period``: slip may also change within a period
        (the covering channels, one multiplier per delay vertex, and the within-period vertices; where the
        model builds them: ``covering``); None: as the model's own vertices do (a nonlinear model), else
        for a common Lyapunov matrix (``synthesis.lyapunov``).  ``merged``: :attr:`~.arcs.Turns.merged` (False
        re-checks certificates made before the arc channels were merged); ``icr_channels``: as
        :meth:`with_heading_bound`'s."""
        from ..errors import InputError
        from .arcs import Turns, turning_heading, turning_vertices

        if self.kind != "slip-aware":
            raise InputError("turning references: built for the slip-aware model only")
        if not self.channels:
            raise InputError("turning references need delay vertices (synthesis.delay_description polytopic or "
                             "lossy-polytopic)")
        wbar = float(max_yaw_rate)
        step = wbar if max_step is None else float(max_step)
        if not (np.isfinite(wbar) and wbar > 0.0 and np.isfinite(step) and step > 0.0):
            raise InputError(f"turning references: max_yaw_rate and max_step must be positive (got {wbar:g}, {step:g})")
        if wbar * self.Ts > np.pi / 2:  # the arc factors' ranges (arcs.arc_ranges) need it
            raise InputError(f"turning references: max_yaw_rate {wbar:g} rad/s turns by {wbar * self.Ts:.3g} rad per "
                             "sampling period, more than pi/2 (reference.turn_radius too small)")
        turns = Turns(wbar, step, merged)
        if within_period is None:
            within_period = (bool(self.covering_vertices) if self.heading_bound is not None
                             else self.config.synthesis.lyapunov == "common")
        within = within_period and bool(self.covering)
        verts, cover = turning_vertices(self, turns, self.heading_bound, within, icr_channels=icr_channels)
        channels, covering, icr_covering = turning_heading(self, turns)
        out = replace(self, vertices=tuple(frozen_vertex(v) for v in verts), turns=turns, channels=channels,
                      covering=covering, icr_covering=icr_covering, covering_vertices=tuple(frozen_vertex(v) for v in cover))
        nonlinear = self.heading_bound is not None
        return replace(out, cover_channels=out.within_period_cover(True, icr_channels)[0] if within and nonlinear else ())

    @property
    def turn_feedforward(self) -> np.ndarray:
        """The command (dV, omega) per rad/s of the reference's yaw rate (:func:`~.slip.turn_feedforward`)."""
        from .slip import turn_feedforward

        return turn_feedforward(self.config.slip, self.config.robot.track_distance)

    @property
    def feedforward_motor_speed(self) -> float:
        """The largest motor speed the feedforward alone asks [rad/s]: V^D/R, plus the turning
        reference's share, max_yaw_rate |J^-1 g| for the feedforward direction g (D/(2R) for g = (0, 1))."""
        cfg = self.config
        R = cfg.robot.gear_radius
        if self.turns is None:
            return cfg.reference.speed / R
        J_inv = np.asarray(self.J_inv)
        uD = np.array([cfg.reference.speed, 0.0])
        return float(np.max(np.abs(J_inv @ uD) + self.turns.max_yaw_rate * np.abs(J_inv @ self.turn_feedforward)))

    def slip_variation(self, lyapunov: str = "common", objective: str = "ultimate-bound") -> tuple[tuple[Vertex, ...], str]:
        """The vertices that cover slip changing at any time within a period for a certificate of kind
        ``lyapunov`` and ``objective`` (docs/theory.md §11), and ``""``; or ``()`` and the reason such a
        certificate on this model assumes slip constant within each period."""
        from ..objectives import objective as descriptor

        why = descriptor(objective).within_period
        if why is not None:
            return (), why
        if self.turns is not None and not self.covering_vertices and lyapunov == "common":
            return (), (self.varying_reason or "the turning reference's vertices were built for slip constant "
                        "within a period")
        if self.heading_bound is not None and not self.covering_vertices:
            return (), ("the kinematic channels (synthesis.kinematics: nonlinear) are built for slip constant "
                        "within a period" + (f": {self.varying_reason}" if self.varying_reason else ""))
        if lyapunov != "common":
            return (), (f"a {lyapunov} certificate indexes its Lyapunov matrices by the slip at the sampling "
                        "instants")
        if not self.varying and not self.covering_vertices:
            return (), self.varying_reason
        return (self.covering_vertices or self.varying), ""

    @cached_property
    def _within_mirror(self) -> list[int] | None:
        """Each within-period vertex's mirror image among them (``mirror.mirror_pairs``), where the model's own
        vertices have the mirror symmetry (§6h); None where they have not (found once per model)."""
        m = self.mirror("common")
        return None if m is None else mirror_pairs(self.covering_vertices or self.varying, m.t, m.tu)

    def with_mirrors(self, indices: list[int]) -> list[int]:
        """``indices`` into the within-period vertices (``covering_vertices or varying``), each followed by its mirror
        image's where the model's own vertices have the mirror symmetry (``_within_mirror``), once each."""
        pairs = self._within_mirror
        chosen: list[int] = []
        for i in indices:
            chosen += [j for j in (i, None if pairs is None else pairs[i]) if j is not None and j not in chosen]
        return chosen

    def with_cuts(self, indices: list[int]) -> "Model":
        """The model whose LMI vertices also include the within-period vertices ``(covering_vertices or varying)[indices]``
        (constraint generation, docs/theory.md §11; common certificates only): appended after the
        model's own vertices, so a certificate's per-vertex data for those come first; each with its mirror image
        (:meth:`with_mirrors`), so that the LMIs keep the mirror symmetry where the model's own vertices have it."""
        family = self.covering_vertices or self.varying
        extra = tuple(replace(family[i], corner=0) for i in self.with_mirrors(indices))
        return replace(self, vertices=tuple(self.vertices) + extra, appended=self.appended + len(extra))

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
    def slip_ranges(self) -> tuple[tuple[float, float], ...]:
        """(min, max) of each slip parameter: (mu_r, mu_l), and (yaw, x_icr) with slip.model icr."""
        return slip_parameter_ranges(self.config.slip)

    @property
    def slip_names(self) -> tuple[str, ...]:
        return SLIP_PARAMETERS[self.config.slip.model]

    @property
    def n_p(self) -> int:
        """How many slip parameters (the last axis of every ``mu``)."""
        return len(self.slip_names)

    @property
    def icr(self) -> bool:
        return self.config.slip.model == "icr"

    # ------------------------------------------------------------------ exact maps

    def _base_exact(self, s_tilde: np.ndarray, mu: np.ndarray | None, slip_aware: bool):
        A, B, _ = lifted_exact(self.A_c, self.B_c, self.B_D_c, self.Ts, s_tilde)
        if slip_aware and mu is not None:
            D = self.config.robot.track_distance
            M = slip_matrix(mu, D)
            A, B = apply_slip(A, B, M, self.n_e, self.n_u, self.d_hi)
            if self.icr:  # the lateral velocity (docs/theory.md §12)
                h = self.Ts - np.asarray(s_tilde, dtype=float)
                A, B = add_lateral(A, B, interval_coordinates(h, h * h / 2.0, self.Ts)[0], lateral_row(mu, D),
                                   self.n_e, self.n_u)
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

    def switched_exact(self, s_tilde: np.ndarray, mu: np.ndarray, t_switch: np.ndarray,
                       mu_after: np.ndarray, per_track: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The slip-aware exact map ``xi+ = A xi + B du + c`` when the slip jumps from ``mu`` to
        ``mu_after`` at ``t_switch`` in [0, Ts] within the period (docs/theory.md §11): each command
        interval sees the slip's uniform and (Ts - t)-weighted averages over it.  ``t_switch`` (...)
        holds for both tracks; with ``per_track`` it is each track's own time (..., 2).  With no jump
        (t_switch = Ts, or mu_after = mu) it is :meth:`robot_exact` and :meth:`constant`."""
        s = np.asarray(s_tilde, dtype=float)
        h = self.Ts - s
        L, W = interval_coordinates(h, h * h / 2.0, self.Ts)
        D = self.config.robot.track_distance
        if self.icr:  # multi-affine, not affine: the averages of the twist over the pieces of constant slip
            from .slip import slip_changes

            ts = np.asarray(t_switch, dtype=float)
            ts = ts if per_track else np.stack([ts, ts], axis=-1)
            tb, tt = piecewise_twist_averages(s, self.Ts, mu, slip_changes(mu, mu_after, ts), D)
            A, B, c = varying_slip_maps(np.asarray(self.Phi), np.asarray(self.A_c), np.asarray(self.B_c), self.Ts, self.V,
                                        L, W, tb[..., [0, 2], :], tt[..., [0, 2], :], tb[..., 1, :])
        else:
            bar, til = interval_slip_averages(s, self.Ts, t_switch, mu, mu_after, per_track)
            A, B, c = varying_slip_maps(np.asarray(self.Phi), np.asarray(self.A_c), np.asarray(self.B_c), self.Ts, self.V,
                                        L, W, slip_matrix(bar, D), slip_matrix(til, D))
        if self.integral:
            A, B = augment_integral(A, B, self.Ts, self.n_e)
            c = np.concatenate([c, np.zeros(c.shape[:-1] + (self.n_z,))], axis=-1)
        return A, B, c

    def constant(self, mu: np.ndarray) -> np.ndarray:
        """c(mu) = B~_d (mu - 1), the constant term of the exact map, shape (..., n_s) (with slip.model
        icr: :func:`~.vertices.icr_constant`)."""
        mu = np.asarray(mu, dtype=float)
        if self.icr:
            return icr_constant(np.asarray(self.A_c), np.asarray(self.B_c), self.Ts, self.V, mu,
                                self.config.robot.track_distance, self.n_s)
        return (mu - 1.0) @ np.asarray(self.B_d).T

    def disturbance_coordinates(self, mu: np.ndarray, yaw: np.ndarray | None = None) -> np.ndarray:
        """w (..., n_w) with ``sum_i lambda_i E_i w = c(mu)`` for the hull weights lambda: the slip box
        coordinates for the paper's kind, w = 1 (the constant column) for the slip-aware kind.  A turning model
        adds its reference's coordinates (model/arcs.py): ``w_k / max_yaw_rate`` and ``(w_k - w_{k-j}) / b_j``
        for ``yaw`` (..., d_hi + 1) = (w_k, w_{k-1}, ..., w_{k-d_hi}); without ``yaw`` a straight segment (zeros)."""
        mu = np.asarray(mu, dtype=float)
        if self.kind == "paper":
            return self.slip.coordinates(mu - 1.0)
        w = np.ones(mu.shape[:-1] + (1,))
        if self.turns is not None:
            if yaw is None:
                turn = np.zeros(mu.shape[:-1] + (self.n_w - 1,))
            else:
                yaw = np.asarray(yaw, dtype=float)
                turn = np.concatenate([yaw[..., :1] / self.turns.max_yaw_rate,
                                       (yaw[..., :1] - yaw[..., 1:]) / self.turns.step_bounds(yaw.shape[-1])], axis=-1)
            w = np.concatenate([w, np.broadcast_to(turn, mu.shape[:-1] + turn.shape[-1:])], axis=-1)
        return w

    def delta(self, s_tilde: np.ndarray) -> np.ndarray:
        """diag(Delta) that reproduces the exact delay matrices in the norm-bounded embedding (eqs. 31-33)."""
        return delta_for(self.instants, self.Ts, s_tilde)

    # ------------------------------------------------------------------ the Plant protocol (core/plant.py)
    @property
    def network(self) -> Network:
        """The link the commands cross (the config's ``network:``): every delay and loss sequence."""
        return Network.from_config(self.config)

    @property
    def dropouts(self) -> int:
        """At most this many consecutive commands lost (the network's cap)."""
        return self.network.max_lost

    @property
    def n_x(self) -> int:
        """The plant's own states: the tracking error (e_x, e_y, e_theta)."""
        return self.n_e

    def lifted(self, s_tilde: np.ndarray, theta: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`exact` under the protocol's name (theta: the slip)."""
        return self.exact(s_tilde, theta)

    def continuous(self, theta: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(A_c, B_c) of the linearized error whose period :meth:`exact`'s error rows are: the command reaches
        the robot as M(mu) u (slip-aware kind), plus the icr model's lateral velocity on e_y."""
        if self.kind != "slip-aware" or theta is None:
            return np.asarray(self.A_c), np.asarray(self.B_c)
        D = self.config.robot.track_distance
        B = np.asarray(self.B_c) @ slip_matrix(theta, D)
        if self.icr:
            B = B.copy()
            B[1] += lateral_row(theta, D)
        return np.asarray(self.A_c), B

    def parameter_corners(self) -> np.ndarray:
        """The slip box's corners (n_c, 2), or (n_c, 4) with the icr parameters."""
        return np.asarray(self.corners)

    plant_kind = "tracked-robot"  # core.plant.Plant: which plant this is (the names of objectives.PLANTS)

    # the robot's own mathematics, for the rooms that take the plant rather than import its modules
    def slip_matrix(self, mu: np.ndarray) -> np.ndarray:
        """The commands-to-twist matrix at slip ``mu`` (``robustsynth.model.slip.slip_matrix``)."""
        return slip_matrix(mu, self.config.robot.track_distance)

    def lateral_row(self, mu: np.ndarray) -> np.ndarray:
        """The icr model's lateral velocity row at slip ``mu`` (``robustsynth.model.slip.lateral_row``)."""
        return lateral_row(mu, self.config.robot.track_distance)

    def linearized_arc_period(self, xi: np.ndarray, du: np.ndarray, S: np.ndarray, mu: np.ndarray, w: np.ndarray,
                              homogeneous: bool = False) -> np.ndarray:
        """One period along the reference's arc (``robustsynth.model.arcs.linearized_arc_period``), (..., 3)."""
        from .arcs import linearized_arc_period

        return linearized_arc_period(self, xi, du, S, mu, w, homogeneous=homogeneous)

    def check_physical_feasibility(self) -> None:
        """InfeasibleError when the motors cannot follow the path at all (``robustsynth.model.slip``)."""
        check_physical_feasibility(self.config)

    def coverage(self, samples: int = 1000, seed: int = 0) -> dict:
        """``robustsynth.model.coverage_check`` on ``samples`` delay histories."""
        from .coverage import coverage_check

        return coverage_check(self, n_sequences=samples, seed=seed)

    def to_dict(self) -> dict:
        """What a report records of the robot closed over its network (plain JSON)."""
        net = self.network
        return {"kind": "tracked-robot", "model": self.kind, "n_x": self.n_e, "n_u": self.n_u, "d_hi": self.d_hi,
                "n_s": self.n_s, "sampling_time": net.sampling_time, "delay": [net.delay_min, net.delay_max],
                "max_lost": net.max_lost, "slip_corners": np.asarray(self.corners).tolist(),
                "vertices": len(self.vertices), "delay_description": self.delay_description}

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
    def nominal_slip(self) -> np.ndarray:
        """The parameters of a robot that does not slip: (1, 1), or (1, 1, 1, 0) for the icr model."""
        return nominal_slip(self.n_p)

    @property
    def slip_step(self) -> float | None:
        """Largest slip change in one period (slip.max_rate * Ts), None without a rate bound."""
        rate = self.config.slip.max_rate
        return None if rate is None else rate * self.Ts

    @property
    def rate_bounded(self) -> bool:
        """True when the rate bound restricts the next slip (narrower than some track's range)."""
        step = self.slip_step
        return step is not None and any(step < hi - lo for lo, hi in self.slip_ranges[:2] if hi > lo)  # mu_r, mu_l

    @property
    def delay_vertex_count(self) -> int:
        """Delay vertices per slip corner: the vertices are corner-major, so vertex i has slip corner
        ``i // n`` and delay vertex ``i % n`` (1 for the paper's model and the norm-bounded embedding); not
        counting the within-period vertices :meth:`with_cuts` appends (``appended``)."""
        own = len(self.vertices) - self.appended
        return max(1, own // max(1, int(np.asarray(self.corners).shape[0])))

    def next_corner_weights(self, m: int) -> np.ndarray:
        """Weights (n_next, n_c) over the corners of the slips that can follow corner m (one period)."""
        return next_corner_weights(self.corners[m], self.slip_ranges, self.slip_step)

    def lyapunov_count(self, kind: str) -> int:
        """How many Lyapunov matrices a certificate of ``kind`` has (see :meth:`lyapunov_conditions`)."""
        n_c = int(np.asarray(self.corners).shape[0])
        n_d = self.delay_vertex_count
        return {"common": 1, "slip-dependent": n_c, "delay-dependent": n_c * n_d, "path-dependent": n_c * n_d * n_d}[kind]

    def mirror(self, kind: str) -> "Mirror | None":
        """The robot's left/right mirror symmetry, when this model has it (docs/theory.md §6h): the
        reflection ``T`` (e_y, e_theta, omega and int_e_y change sign) maps vertex i's data onto vertex
        ``vertex[i]``'s, whose slip corner has the tracks swapped, ``A_s(i) = T A_i T``,
        ``B_s(i) = T B_i T_u``, ``E_s(i) = T E_i (+-)``.  Then a certificate of ``kind`` may be taken
        mirror-invariant at no loss (average it with its mirror image), and each condition of a mirrored
        pair is the other's congruence.  None when a slip box is not symmetric (the tracks' ranges
        differ) or the data are not mirror images.  Vertices with uncertainty channels (the
        norm-bounded delay embedding, the kinematic channels of §9) map with a sign per channel,
        ``B_p,s(i) = T B_p,i S_i``, ``C_q,s(i) = S_i C_q,i T``, ``D_q,s(i) = S_i D_q,i T_u``,
        ``F_q,s(i) = S_i F_q,i (+-)`` (``q_signs[i]`` = diag S_i); their multipliers map as
        ``M_s(i) = S_i M_i S_i``.  The icr model's kinematic channels (§12: sums and differences of the
        tracks) map so; the tracks model's per-track channels for slip changing within a period swap between
        the tracks instead (no sign per channel): None.  (The mirrored channel problems were once left out as
        numerically fragile under the scaled Clarabel; the channels' searches now start unscaled, where the
        default robot's mirrored problems all concluded, 1.4 s a solve against 4.4 s for the full ones.)"""
        return find_mirror(np.asarray(self.corners, dtype=float), self.state_names, INPUT_NAMES, self.delay_vertex_count,
                           self.vertices, kind)

    def mirror_on(self, index: Sequence[int], mirror: "Mirror | None" = None) -> tuple[tuple[int, ...], "Mirror | None"]:
        """The vertices ``index`` closed under the mirror symmetry (``mirror``: this model's, :meth:`mirror` of a
        common Lyapunov matrix; None: none, ``index`` sorted as it is) and the symmetry of the model on just those
        vertices, with which a problem on them may be posed mirror-invariant (None where the images are not exact:
        ``mirror.restrict``)."""
        if mirror is None:
            return tuple(sorted(int(i) for i in index)), None
        closed = closure(mirror, index)
        return closed, restrict(mirror, self.vertices, closed)

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
            W = next_corner_weights(self.corners[m], self.slip_ranges, slip_step)
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
        w, _ = self.hull_coordinates(s_tilde, self.nominal_slip)
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
        ``(A~(s~, mu), B~(s~, mu), c(mu))`` of this kind (for a turning model: on a straight segment)."""
        s_tilde = np.asarray(s_tilde, dtype=float)
        mu = np.asarray(mu, dtype=float)
        batch = np.broadcast_shapes(s_tilde.shape[:-1], mu.shape[:-1])
        s_tilde = np.broadcast_to(s_tilde, batch + s_tilde.shape[-1:])
        mu = np.broadcast_to(mu, batch + mu.shape[-1:])
        dlt = self.delta(s_tilde) if self.n_q else np.zeros(batch + (0,))
        if self.kind == "paper":
            return np.ones(batch + (1,)), dlt
        lam = self.corner_weights(mu)  # (..., n_c)
        if self.delay_description == "norm-bounded":
            return lam, dlt
        # delay vertices have no delay Delta; with the kinematic channels, the one of the linearization
        if self.turns is not None:  # the turning vertices on a straight segment (w = 0: every factor at 0)
            from .arcs import straight_delta

            dlt = np.broadcast_to(straight_delta(self.heading_channels[0], self.turns.max_yaw_rate * self.Ts,
                                                 self.heading_bound or 0.0, self.turns.merged),
                                  batch + (self.vertices[0].n_q,))
        elif self.heading_bound is not None:  # (every kinematic factor at 0)
            from .nonlinear import linearization_delta

            dlt = np.broadcast_to(linearization_delta(self.heading_channels[0]), batch + (self.vertices[0].n_q,))
        else:
            dlt = np.zeros(batch + (0,))
        if self.delay_description == "lossy-polytopic":
            cfg = self.config
            w = loss_hull_coordinates(s_tilde, self.Ts, cfg.network.delay.min, cfg.network.delay.max, self.dropouts,
                                      self.d_hi, WIDTH_TOL * max(self.Ts, 1.0))
            out = (lam[..., :, None] * w[..., None, :]).reshape(batch + (-1,))
            return out, dlt
        if self.delay_cover != "product":  # corner-major, then the in-order coupling of the instants' coordinates
            h = self.Ts - s_tilde[..., list(self.delay_uncertain)]
            w = in_order_weights(h, self.delay_cover_h, list(self.delay_combos)) if self.delay_uncertain else \
                np.ones(batch + (1,))
            return (lam[..., :, None] * w[..., None, :]).reshape(batch + (-1,)), dlt
        # polytopic: corner-major, then the product of the per-instant triangle coordinates
        tri = [np.ones(batch + (1,))]
        for j in range(self.d_hi):
            lo, hi = self.instant_ranges[j]
            if hi - lo <= WIDTH_TOL * max(self.Ts, 1.0):
                continue
            t = triangle_coordinates(self.Ts - s_tilde[..., j], self.Ts - hi, self.Ts - lo)
            tri.append(t)
        w = tri[0]
        for t in tri[1:]:
            w = (w[..., :, None] * t[..., None, :]).reshape(batch + (-1,))
        out = (lam[..., :, None] * w[..., None, :]).reshape(batch + (-1,))
        return out, dlt

    def from_hull(self, weights: np.ndarray, delta: np.ndarray, w: np.ndarray):
        """Recombine the vertices: (A, B, c) for hull weights, diag(Delta) and disturbance w."""
        A = sum(weights[..., i, None, None] * (v.A + (v.B_p * delta[..., None, :]) @ v.C_q) for i, v in enumerate(self.vertices))
        B = sum(weights[..., i, None, None] * (v.B + (v.B_p * delta[..., None, :]) @ v.D_q) for i, v in enumerate(self.vertices))
        c = sum(weights[..., i, None] * (w @ v.E.T + ((w @ v.F.T) * delta) @ v.B_p.T) for i, v in enumerate(self.vertices))
        return A, B, c


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
