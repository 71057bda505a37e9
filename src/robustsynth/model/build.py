"""Config -> :class:`~.model.Model`: :func:`build_model` (docs/theory.md §1-5)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..config import Config
from ..errors import ConfigError
from .compensation import certificate_config, compensation_of
from .kinematics import J_inverse, J_matrix
from ..core.lifting import delay_indices, instant_ranges, lift
from .linearize import Gamma, Gamma_D, Phi, continuous_matrices
from .slip import lateral_row, slip_corners, slip_matrix, slip_parameter_ranges
from .uncertainty import embed, slip_box
from .model import DEFAULT_HEADING_BOUND, MAX_POLYTOPIC_INSTANTS, WIDTH_TOL, Model, frozen_array, frozen_vertex
from .nonlinear import covering_channels, icr_covering_channels, vertex_channels
from .vertices import (Vertex, add_lateral, apply_slip, augment_integral, delay_cover_ranges, delay_vertex_gammas,
                       icr_constant,
                       icr_varying_vertices, interval_coordinates, loss_vertex_gammas,
                       varying_slip_vertices)

__all__ = ["build_model", "MAX_VARYING_VERTICES"]

# slip changing within a period (docs/theory.md §11): at most this many vertices, else the certificate
# assumes slip constant within a period (16 per track pair and command interval, per delay vertex)
MAX_VARYING_VERTICES = 4096


def _augment_rows(X: np.ndarray, n_z: int) -> np.ndarray:
    return np.vstack([X, np.zeros((n_z, X.shape[1]))]) if n_z else X


def _augment_cols(X: np.ndarray, n_z: int) -> np.ndarray:
    return np.hstack([X, np.zeros((X.shape[0], n_z))]) if n_z else X


def _resolve_delay_description(requested: str, n_uncertain: int, nonlinear: bool = False) -> str:
    if requested == "auto":  # the kinematic channels need delay vertices (model/nonlinear.py)
        return "polytopic" if n_uncertain <= MAX_POLYTOPIC_INSTANTS or nonlinear else "norm-bounded"
    return requested


PAPER_VARYING_REASON = "the paper's model describes slip as an additive box, not per command interval"


@dataclass(frozen=True)
class _Delays:
    """The delay description the model is built with, and its delay vertices (none for norm-bounded):
    ``labels`` and ``gammas`` per delay vertex, the lifted ``A_t``, ``B_t`` at each (before slip), and
    how the polytopic description covers the instants (``cover``, ``uncertain``, ``cover_h``, ``combos``:
    the Model's ``delay_*`` fields)."""

    description: str
    cover: str = "product"
    uncertain: list = field(default_factory=list)
    cover_h: np.ndarray | None = None
    combos: list = field(default_factory=list)
    labels: Any = None
    gammas: np.ndarray | None = None
    A_t: np.ndarray | None = None
    B_t: np.ndarray | None = None


@dataclass(frozen=True)
class _Intervals:
    """Each delay vertex's command intervals: ``h`` and ``q`` (n_d, d_hi + 1), the coordinates (h_j, h_j^2/2)
    the kinematic channels are made from, and ``lengths``, each interval's length."""

    h: np.ndarray
    q: np.ndarray
    lengths: np.ndarray


@dataclass(frozen=True)
class _WithinPeriod:
    """Slip changing within a period (docs/theory.md §11): its vertices (None: not covered), the delay vertex
    of each, the covering kinematic channels per delay vertex, and why it is not covered ("" when it is)."""

    varying: list[Vertex] | None = None
    varying_delay: list[int] = field(default_factory=list)
    covering: list = field(default_factory=list)
    reason: str = ""
    # the icr model's: vertices for its linear map (vertices.icr_varying_vertices), their delay vertices and the
    # channels that go with them (nonlinear.icr_covering_channels with by_vertices), per delay vertex
    icr: tuple = ((), (), ())


def build_model(config: Config, min_lifting: int | None = None) -> Model:
    """Build the model of ``config`` (kind ``config.synthesis.model``; docs/theory.md §1-5).

    ``min_lifting``: keep at least this many past inputs in the lifted state even when the delay
    bound needs fewer (the extra switching instants are fixed at 0): to analyse a gain designed for
    a longer lifting on a shorter delay range.

    Parameters
    ----------
    config : Config
        The scenario.
    min_lifting : int or None
        The least number of past inputs in the lifted state (default: what the delay bound needs).

    Returns
    -------
    Model
        The frozen lifted model: its matrices, vertices and uncertainty structure.
    """
    from ..config import refuse_lti

    refuse_lti(config, "build_model")
    comp = compensation_of(config)
    if comp is not None:  # the compensated law: certified on the ratio box (model/compensation.py)
        return replace(build_model(certificate_config(config, comp), min_lifting), compensation=comp)
    nominal = _nominal_model(config, min_lifting)
    if nominal.kind == "paper":
        delays = _Delays("norm-bounded")
        vertices = [Vertex(nominal.A, nominal.B, nominal.B_d @ nominal.slip.W, nominal.B_p, nominal.C_q, nominal.D_q, 0,
                           "nominal (mu = 1), slip as additive box")]
        channels: list = []
        within = _WithinPeriod(reason=PAPER_VARYING_REASON)
    else:
        delays = _delay_vertices(config, nominal)
        intervals = None if delays.description == "norm-bounded" else _intervals(delays, nominal)
        within = _within_period(config, nominal, delays, intervals)
        vertices, channels = _corner_vertices(config, nominal, delays, intervals)
    frozen_vertices = tuple(frozen_vertex(v) for v in vertices)
    model = replace(nominal, vertices=frozen_vertices, base_vertices=frozen_vertices, channels=tuple(channels),
                    delay_description=delays.description, delay_cover=delays.cover,
                    delay_uncertain=tuple(delays.uncertain),
                    delay_cover_h=None if delays.cover_h is None else frozen_array(delays.cover_h),
                    delay_combos=tuple(delays.combos), varying=tuple(frozen_vertex(v) for v in within.varying or ()),
                    varying_reason=within.reason, covering=tuple(within.covering),
                    varying_delay=tuple(within.varying_delay),
                    icr_varying=tuple(frozen_vertex(v) for v in within.icr[0]), icr_varying_delay=within.icr[1],
                    icr_covering=within.icr[2])
    return _with_kinematic_terms(model, config)


def _nominal_model(config: Config, min_lifting: int | None) -> Model:
    """The model's nominal part, its vertices still to be added: the continuous matrices at V^D, the delay's
    lifting (d_lo, d_hi, the switching instants' ranges), the norm-bounded embedding (B_p, C_q, D_q), the
    lifted A, B, B_d (with the integrators when asked), the slip box and its corners.  A lost command is
    superseded when its successor arrives: the lifting covers an effective delay of up to tau_max + m Ts
    (m lost in a row) with a zero-length active interval (docs/theory.md, packet loss); ``min_lifting``
    lengthens it."""
    R = config.robot.gear_radius
    D = config.robot.track_distance
    V = config.reference.speed
    Ts = config.network.sampling_time
    integral = config.synthesis.integral_action
    n_z = 2 if integral else 0
    dropouts = config.network.dropouts.max_consecutive
    tmin, tmax = config.network.delay.min, config.network.delay.max + dropouts * config.network.sampling_time
    A_c, B_c, B_D_c = continuous_matrices(V, D)
    d_lo, d_hi = delay_indices(tmin, tmax, Ts)
    d_hi = max(d_hi, int(min_lifting or 0))
    inst_ranges = instant_ranges(tmin, tmax, Ts, d_hi)
    n_e, n_u = B_c.shape
    instants, Gammas0, B_p, C_q, D_q = embed(A_c, B_c, Ts, inst_ranges, n_e, n_u, d_hi)
    Ph = Phi(A_c, Ts)
    GD = Gamma_D(A_c, B_D_c, Ts)
    A, B, B_d = lift(Ph, Gammas0, Gamma(A_c, B_c, Ts), GD)
    if integral:  # the nominal matrices in the augmented state
        A, B = augment_integral(A, B, Ts, n_e)
    arrays = {"instant_ranges": inst_ranges, "A_c": A_c, "B_c": B_c, "B_D_c": B_D_c, "Phi": Ph, "Gamma_D": GD, "A": A,
              "B": B, "B_d": _augment_rows(B_d, n_z), "B_p": _augment_rows(B_p, n_z), "C_q": _augment_cols(C_q, n_z),
              "D_q": D_q, "corners": slip_corners(*slip_parameter_ranges(config.slip)), "J": J_matrix(R, D),
              "J_inv": J_inverse(R, D)}
    slip = slip_box((config.slip.right.min, config.slip.right.max), (config.slip.left.min, config.slip.left.max))
    return Model(config=config, kind=config.synthesis.model, d_lo=d_lo, d_hi=d_hi, Ts=Ts, V=V, instants=instants,
                 slip=slip, vertices=(), delay_description="norm-bounded", integral=integral, builder=build_model,
                 **{k: frozen_array(v) for k, v in arrays.items()})


def _delay_vertices(config: Config, nominal: Model) -> _Delays:
    """The delay description of the slip-aware model and its delay vertices, the same for every slip corner.
    ``auto`` takes delay vertices where the kinematic channels, the icr model's lateral term or the turning
    vertices need them; with lost commands and tau_max <= Ts the lossy-polytopic ones (the instants a lossy
    link produces), whose requirement tau_max <= Ts raises ConfigError when asked for explicitly."""
    syn = config.synthesis
    A_c, B_c, Ts, Ph, GD = nominal.A_c, nominal.B_c, nominal.Ts, nominal.Phi, nominal.Gamma_D
    tau_hi = config.network.delay.max  # of a received command (lost ones: the effective tmax)
    nonlinear = syn.kinematics == "nonlinear"
    turning = config.reference.turn_radius is not None  # the turning vertices need the delay vertices too
    icr = config.slip.model == "icr"  # its lateral term needs them too
    description = _resolve_delay_description(syn.delay_description, len(nominal.instants), nonlinear or icr or turning)
    dropouts = nominal.dropouts
    if syn.delay_description == "lossy-polytopic" or (syn.delay_description == "auto" and dropouts and tau_hi <= Ts):
        if tau_hi > Ts * (1 + 1e-12):
            raise ConfigError(f"synthesis.delay_description: lossy-polytopic needs network.delay.max <= "
                              f"network.sampling_time (got {tau_hi:g} > {Ts:g}); use auto or norm-bounded")
        labels, gammas = loss_vertex_gammas(A_c, B_c, Ts, config.network.delay.min, tau_hi, dropouts, nominal.d_hi,
                                            WIDTH_TOL * max(Ts, 1.0))
        A_t, B_t, _ = lift(Ph, gammas, Gamma(A_c, B_c, Ts), GD)
        return _Delays("lossy-polytopic", labels=labels, gammas=gammas, A_t=A_t, B_t=B_t)
    if description not in ("polytopic", "polytopic-product", "in-order-common"):
        return _Delays(description)
    ranges = nominal.instant_ranges
    cover = {"polytopic": "in-order", "polytopic-product": "product"}.get(description, description)
    labels, gammas, uncertain, combos = delay_vertex_gammas(A_c, B_c, Ts, ranges, WIDTH_TOL * max(Ts, 1.0), cover)
    if cover == "in-order" and len(combos) == 3 ** len(uncertain):
        cover = "product"  # no two instants share a range: the product itself, with its weights
    cover_h = delay_cover_ranges(Ts, ranges, WIDTH_TOL * max(Ts, 1.0), cover)[1]
    A_t, B_t, _ = lift(Ph, gammas, Gamma(A_c, B_c, Ts), GD)
    return _Delays("polytopic", cover=cover, uncertain=uncertain, cover_h=cover_h, combos=combos, labels=labels,
                   gammas=gammas, A_t=A_t, B_t=B_t)


def _intervals(delays: _Delays, nominal: Model) -> _Intervals:
    """The command intervals of each delay vertex, read off its gammas: gammas[t, j] = h_j B + q_j A B
    (vertices.py), with B[0, 0] = 1 and (A B)[1, 1] = V^D > 0."""
    h = delays.gammas[:, :, 0, 0]
    q = delays.gammas[:, :, 1, 1] / nominal.V
    return _Intervals(h, q, interval_coordinates(h, q, nominal.Ts)[0])


def _within_period(config: Config, nominal: Model, delays: _Delays, iv: _Intervals | None) -> _WithinPeriod:
    """Whether and how the slip-aware model covers slip changing within a period (docs/theory.md §11, §12):
    the tracks model by the slip averages' vertices and their kinematic channels (per delay vertex), the icr
    model by its covering channels alone and, for the certificates whose vertices carry the kinematic channels, by
    the vertices of each command interval's twist with their channels (``icr``); neither without delay vertices
    (``iv`` None), nor the vertices when they would be more than MAX_VARYING_VERTICES.  Says why where it does not."""
    V, Ts, D = nominal.V, nominal.Ts, config.robot.track_distance
    dims = (nominal.n_s, nominal.n_e, nominal.n_u, nominal.d_hi)
    mu_r = (config.slip.right.min, config.slip.right.max)
    mu_l = (config.slip.left.min, config.slip.left.max)
    if config.slip.model == "icr":
        reason = ("the icr slip model is not affine in its parameters (the yaw factor multiplies the tracks' factors), "
                  "so the slip averages of §11 do not describe it; its channels cover slip changing within a period "
                  "with synthesis.kinematics: nonlinear (docs/theory.md §12)")
        if iv is None:
            return _WithinPeriod(reason=reason)
        ranges = slip_parameter_ranges(config.slip)  # the channels for parameters changing within the period
        coords = [np.stack([iv.h[t], iv.q[t]], axis=1) for t in range(len(delays.labels))]
        built = icr_varying_vertices(nominal.Phi, nominal.A_c, nominal.B_c, Ts, V, D, ranges, iv.h, iv.q,
                                     delays.labels, nominal.integral, MAX_VARYING_VERTICES)
        icr = ((), (), ()) if built is None else (
            tuple(built[0]), tuple(built[1]),
            tuple(icr_covering_channels(ranges, c, V, Ts, D, *dims, by_vertices=True) for c in coords))
        return _WithinPeriod(covering=[icr_covering_channels(ranges, c, V, Ts, D, *dims) for c in coords],
                             reason=reason, icr=icr)
    if iv is None:
        return _WithinPeriod(reason="the norm-bounded delay description has no delay vertices to tie the slip averages "
                                    "to (synthesis.delay_description: polytopic or lossy-polytopic)")
    built = varying_slip_vertices(nominal.Phi, nominal.A_c, nominal.B_c, Ts, V, D, mu_r, mu_l, iv.h, iv.q,
                                  delays.labels, nominal.integral, MAX_VARYING_VERTICES)
    if built is None:
        return _WithinPeriod(reason=f"the delay range spans more than two command intervals in a period (covering it "
                                    f"would also take up to 16^intervals vertices, at most {MAX_VARYING_VERTICES})")
    varying, varying_delay = built  # the kinematic channels for slip changing within the period, per delay vertex
    return _WithinPeriod(varying, varying_delay, [covering_channels(mu_r, mu_l, np.stack([iv.h[t], iv.q[t]], axis=1),
                                                                    V, Ts, D, *dims)
                                                  for t in range(len(delays.labels))])


def _corner_vertices(config: Config, nominal: Model, delays: _Delays, iv: _Intervals | None
                     ) -> tuple[list[Vertex], list]:
    """The slip-aware model's vertices, slip corner by slip corner, and their kinematic channels: one vertex per
    corner with the delay embedding's Delta (norm-bounded, ``iv`` None), else one per corner and delay vertex,
    with the icr model's lateral velocity and the integrators, and the channels from the delay vertex's
    coordinates (h_j, h_j^2/2)."""
    n_s, n_e, n_u, d_hi = nominal.n_s, nominal.n_e, nominal.n_u, nominal.d_hi
    D, icr = config.robot.track_distance, config.slip.model == "icr"
    vertices: list[Vertex] = []
    channels: list = []
    for m, mu in enumerate(nominal.corners):
        M = slip_matrix(mu, D)
        c = (mu - 1.0) @ nominal.B_d.T if not icr else icr_constant(nominal.A_c, nominal.B_c, nominal.Ts, nominal.V,
                                                                     mu, D, n_s)
        E = c[:, None]
        name = f"mu=({mu[0]:g}, {mu[1]:g})" + (f", yaw={mu[2]:g}, x_icr={mu[3]:g}" if icr else "")
        if iv is None:
            Am, Bm = apply_slip(nominal.A, nominal.B, M, n_e, n_u, d_hi)
            T = np.eye(n_s)
            for j in range(d_hi):
                T[n_e + j * n_u : n_e + (j + 1) * n_u, n_e + j * n_u : n_e + (j + 1) * n_u] = M
            vertices.append(Vertex(Am, Bm, E, nominal.B_p, nominal.C_q @ T, nominal.D_q @ M, m, name))
            continue
        At, Bt = apply_slip(delays.A_t, delays.B_t, M, n_e, n_u, d_hi)
        if icr:  # the lateral velocity: each command interval's length times v_y into e_y
            At, Bt = add_lateral(At, Bt, iv.lengths, lateral_row(mu, D), n_e, n_u)
        if nominal.integral:
            At, Bt = augment_integral(At, Bt, nominal.Ts, n_e)
        for t, lab in enumerate(delays.labels):
            vertices.append(Vertex(At[t], Bt[t], E, np.zeros((n_s, 0)), np.zeros((0, n_s)),
                                   np.zeros((0, n_u)), m, f"{name}; {lab}", instants=tuple(map(float, iv.h[t]))))
            channels.append(vertex_channels(mu, np.stack([iv.h[t], iv.q[t]], axis=1), nominal.V, nominal.Ts, M, n_s,
                                            n_e, n_u, d_hi, lateral=lateral_row(mu, D) if icr else None))
    return vertices, channels


def _with_kinematic_terms(model: Model, config: Config) -> Model:
    """The slip-aware model with what its certificate must cover beyond the linearization: the kinematic terms
    at the heading bound (synthesis.kinematics: nonlinear; auto starts at DEFAULT_HEADING_BOUND, synthesis
    searches) and the reference turning along arcs (reference.turn_radius; model/arcs.py)."""
    syn = config.synthesis
    kind, Ts = syn.model, config.network.sampling_time
    if kind != "paper" and syn.kinematics == "nonlinear":
        hb = syn.heading_bound
        model = model.with_heading_bound(DEFAULT_HEADING_BOUND if hb == "auto" else float(hb),
                                         within_period=syn.lyapunov == "common")
    if kind != "paper" and config.reference.turn_radius is not None:  # corners rounded by arcs
        wbar = config.reference.speed / config.reference.turn_radius
        ramp = config.reference.turn_ramp  # eased turns: the yaw rate changes by at most wbar Ts / ramp per period
        model = model.with_turns(wbar, max_step=wbar * min(1.0, Ts / ramp) if ramp else None,
                                 within_period=syn.lyapunov == "common")
    return model
