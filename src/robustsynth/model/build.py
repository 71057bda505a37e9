"""Config -> :class:`~.model.Model`: :func:`build_model` (docs/theory.md §1-5) and the coverage
test of the vertex description (:func:`coverage_check`)."""

from __future__ import annotations

import numpy as np

from ..config import Config
from ..errors import ConfigError
from .kinematics import J_inverse, J_matrix
from .lifting import delay_indices, instant_ranges, lift
from .linearize import Gamma, Gamma_D, Phi, continuous_matrices
from .slip import lateral_row, slip_corners, slip_matrix, slip_parameter_ranges
from .uncertainty import embed, slip_box
from .model import DEFAULT_HEADING_BOUND, MAX_POLYTOPIC_INSTANTS, WIDTH_TOL, Model, frozen_array, frozen_vertex
from .nonlinear import covering_channels, icr_covering_channels, vertex_channels
from .vertices import (Vertex, add_lateral, apply_slip, augment_integral, delay_cover_ranges, delay_vertex_gammas,
                       icr_constant,
                       interval_coordinates, loss_vertex_gammas, varying_slip_vertices)

__all__ = ["build_model", "coverage_check", "MAX_VARYING_VERTICES"]

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
    inst_ranges = instant_ranges(tmin, tmax, Ts, d_hi)
    n_e, n_u = B_c.shape
    instants, Gammas0, B_p, C_q, D_q = embed(A_c, B_c, Ts, inst_ranges, n_e, n_u, d_hi)
    Ph = Phi(A_c, Ts)
    GD = Gamma_D(A_c, B_D_c, Ts)
    A, B, B_d = lift(Ph, Gammas0, Gamma(A_c, B_c, Ts), GD)
    mu_r = (config.slip.right.min, config.slip.right.max)
    mu_l = (config.slip.left.min, config.slip.left.max)
    slip = slip_box(mu_r, mu_l)
    ranges = slip_parameter_ranges(config.slip)
    icr = config.slip.model == "icr"
    corners = slip_corners(*ranges)
    # nominal matrices in the (possibly augmented) state
    if integral:
        A, B = augment_integral(A, B, Ts, n_e)
    B_d = _augment_rows(B_d, n_z)
    B_p = _augment_rows(B_p, n_z)
    C_q = _augment_cols(C_q, n_z)
    n_s = A.shape[0]
    delay_description = "norm-bounded"
    delay_cover, delay_uncertain, delay_cover_h, delay_combos = "product", [], None, []
    vertices: list[Vertex] = []
    channels: list = []
    varying: list[Vertex] | None = None
    varying_delay: list[int] = []
    covering: list = []
    varying_reason = ""
    if kind == "paper":
        varying_reason = "the paper's model describes slip as an additive box, not per command interval"
        vertices.append(Vertex(A, B, B_d @ slip.W, B_p, C_q, D_q, 0, "nominal (mu = 1), slip as additive box"))
    else:
        tau_hi = config.network.delay.max  # of a received command (lost ones: the effective tmax)
        nonlinear = syn.kinematics == "nonlinear"
        # the kinematic channels and the icr slip model's lateral term need delay vertices
        turning = config.reference.turn_radius is not None  # the turning vertices need the delay vertices too
        delay_description = _resolve_delay_description(syn.delay_description, len(instants), nonlinear or icr or turning)
        if syn.delay_description == "lossy-polytopic" or (syn.delay_description == "auto" and dropouts and tau_hi <= Ts):
            if tau_hi > Ts * (1 + 1e-12):
                raise ConfigError(f"synthesis.delay_description: lossy-polytopic needs network.delay.max <= "
                                  f"network.sampling_time (got {tau_hi:g} > {Ts:g}); use auto or norm-bounded")
            delay_description = "lossy-polytopic"
            labels, gammas = loss_vertex_gammas(A_c, B_c, Ts, tmin, tau_hi, dropouts, d_hi, WIDTH_TOL * max(Ts, 1.0))
            A_t, B_t, _ = lift(Ph, gammas, Gamma(A_c, B_c, Ts), GD)
        elif delay_description in ("polytopic", "polytopic-product", "in-order-common"):  # the same for every slip corner
            delay_cover = {"polytopic": "in-order", "polytopic-product": "product"}.get(delay_description, delay_description)
            delay_description = "polytopic"
            labels, gammas, delay_uncertain, delay_combos = delay_vertex_gammas(
                A_c, B_c, Ts, inst_ranges, WIDTH_TOL * max(Ts, 1.0), delay_cover)
            if delay_cover == "in-order" and len(delay_combos) == 3 ** len(delay_uncertain):
                delay_cover = "product"  # no two instants share a range: the product itself, with its weights
            delay_cover_h = delay_cover_ranges(Ts, inst_ranges, WIDTH_TOL * max(Ts, 1.0), delay_cover)[1]
            A_t, B_t, _ = lift(Ph, gammas, Gamma(A_c, B_c, Ts), GD)
        if delay_description == "norm-bounded":
            varying_reason = ("the norm-bounded delay description has no delay vertices to tie the slip averages "
                              "to (synthesis.delay_description: polytopic or lossy-polytopic)")
        else:
            h = gammas[:, :, 0, 0]  # gammas[t, j] = h_j B + q_j A B (vertices.py): B[0, 0] = 1, (A B)[1, 1] = V
            q = gammas[:, :, 1, 1] / V  # (V^D > 0)
            lengths = interval_coordinates(h, q, Ts)[0]  # (n_d, d_hi + 1): each command interval's length
        if icr:
            varying_reason = ("the icr slip model is not affine in its parameters (the yaw factor multiplies the "
                              "tracks' factors), so the slip averages of §11 do not describe it; its channels cover slip "
                              "changing within a period with synthesis.kinematics: nonlinear (docs/theory.md §12)")
            if delay_description != "norm-bounded":  # the channels for parameters changing within the period
                covering = [icr_covering_channels(ranges, np.stack([h[t], q[t]], axis=1), V, Ts, D, n_s, n_e, n_u, d_hi)
                            for t in range(len(labels))]
        elif delay_description != "norm-bounded":
            built = varying_slip_vertices(Ph, A_c, B_c, Ts, V, D, mu_r, mu_l, h, q, labels, integral,
                                          MAX_VARYING_VERTICES)
            if built is None:
                varying_reason = (f"the delay range spans more than two command intervals in a period (covering "
                                  f"it would also take up to 16^intervals vertices, at most {MAX_VARYING_VERTICES})")
            else:  # the kinematic channels for slip changing within the period, per delay vertex
                varying, varying_delay = built
                covering = [covering_channels(mu_r, mu_l, np.stack([h[t], q[t]], axis=1), V, Ts, D, n_s, n_e, n_u, d_hi)
                            for t in range(len(labels))]
        for m, mu in enumerate(corners):
            M = slip_matrix(mu, D)
            c = (mu - 1.0) @ B_d.T if not icr else icr_constant(A_c, B_c, Ts, V, mu, D, n_s)
            E = c[:, None]
            name = f"mu=({mu[0]:g}, {mu[1]:g})" + (f", yaw={mu[2]:g}, x_icr={mu[3]:g}" if icr else "")
            if delay_description == "norm-bounded":
                Am, Bm = apply_slip(A, B, M, n_e, n_u, d_hi)
                T = np.eye(n_s)
                for j in range(d_hi):
                    T[n_e + j * n_u : n_e + (j + 1) * n_u, n_e + j * n_u : n_e + (j + 1) * n_u] = M
                vertices.append(Vertex(Am, Bm, E, B_p, C_q @ T, D_q @ M, m, name))
            else:
                At, Bt = apply_slip(A_t, B_t, M, n_e, n_u, d_hi)
                if icr:  # the lateral velocity: each command interval's length times v_y into e_y
                    At, Bt = add_lateral(At, Bt, lengths, lateral_row(mu, D), n_e, n_u)
                if integral:
                    At, Bt = augment_integral(At, Bt, Ts, n_e)
                for t, lab in enumerate(labels):
                    vertices.append(Vertex(At[t], Bt[t], E, np.zeros((n_s, 0)), np.zeros((0, n_s)),
                                           np.zeros((0, n_u)), m, f"{name}; {lab}"))
                    # the kinematic channels, from the delay vertex's coordinates (h_j, h_j^2/2)
                    channels.append(vertex_channels(mu, np.stack([h[t], q[t]], axis=1), V, Ts, M, n_s, n_e, n_u, d_hi,
                                                    lateral=lateral_row(mu, D) if icr else None))
    frozen_vertices = tuple(frozen_vertex(v) for v in vertices)
    model = Model(
        config=config,
        kind=kind,
        d_lo=d_lo,
        d_hi=d_hi,
        Ts=Ts,
        V=V,
        instant_ranges=frozen_array(inst_ranges),
        A_c=frozen_array(A_c),
        B_c=frozen_array(B_c),
        B_D_c=frozen_array(B_D_c),
        Phi=frozen_array(Ph),
        Gamma_D=frozen_array(GD),
        A=frozen_array(A),
        B=frozen_array(B),
        B_d=frozen_array(B_d),
        B_p=frozen_array(B_p),
        C_q=frozen_array(C_q),
        D_q=frozen_array(D_q),
        instants=instants,
        slip=slip,
        corners=frozen_array(corners),
        vertices=frozen_vertices,
        delay_description=delay_description,
        integral=integral,
        dropouts=dropouts,
        J=frozen_array(J_matrix(R, D)),
        J_inv=frozen_array(J_inverse(R, D)),
        channels=tuple(channels),
        base_vertices=frozen_vertices,
        varying=tuple(frozen_vertex(v) for v in varying or ()),
        varying_reason=varying_reason,
        covering=tuple(covering),
        varying_delay=tuple(varying_delay),
        delay_cover=delay_cover,
        delay_uncertain=tuple(delay_uncertain),
        delay_cover_h=None if delay_cover_h is None else frozen_array(delay_cover_h),
        delay_combos=tuple(delay_combos),
    )
    if kind != "paper" and syn.kinematics == "nonlinear":
        hb = syn.heading_bound
        model = model.with_heading_bound(DEFAULT_HEADING_BOUND if hb == "auto" else float(hb),
                                         within_period=syn.lyapunov == "common")
    if kind != "paper" and config.reference.turn_radius is not None:  # corners rounded by arcs (model/arcs.py)
        wbar = config.reference.speed / config.reference.turn_radius
        ramp = config.reference.turn_ramp  # eased turns: the yaw rate changes by at most wbar Ts / ramp per period
        model = model.with_turns(wbar, max_step=wbar * min(1.0, Ts / ramp) if ramp else None,
                                 within_period=syn.lyapunov == "common")
    return model


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
        if model.delay_cover != "product":  # the corners delivery in order can produce (s~_0 >= s~_1 >= ...)
            corners = corners[np.all(np.diff(corners, axis=1) <= 0.0, axis=1)]
    s = np.vstack([s, corners])
    ranges = model.slip_ranges
    mu = np.stack([rng.uniform(lo, hi, s.shape[0]) for lo, hi in ranges], axis=1)
    mu[: model.corners.shape[0]] = model.corners  # every slip corner at least once
    mu[-1] = [hi for _, hi in ranges]
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


