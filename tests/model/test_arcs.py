"""The turning reference's vertices (model/arcs.py) against the robot itself: one period of exact
arcs, the robot following a reference that turns at w_k with the turning feedforward in its commands,
measured in the reference's frame at t_{k+1}, lies within what the augmented vertex allows, to first
order in the deviations from the nominal arc (the certificate is a linearized one); and the parts of
the augmentation are each needed (negative controls)."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.model import build_model
from robustsynth.model.arcs import FEEDFORWARD, Turns, _parts, heading_yaw_columns
from robustsynth.model.nonlinear import vertex_channels
from robustsynth.model.slip import slip_matrix
from robustsynth.model.vertices import Vertex
from robustsynth.plants.kinematic import KinematicRobot, period
from robustsynth.scenarios import random_delays, track_changes
from robustsynth.plants.path import arc_frame_error

from ..conftest import make_config

EPS = 1e-3  # the deviations from the nominal arc (errors, corrections, slip - 1, yaw-rate steps), scaled
# the terms a linearization drops are of second order in them: about V Ts (eta^2 + |a eta|) ~ 2e-8 here
# (measured: the robot stays 7e-8 inside the allowance), while the arc's channels allow first-order
# amounts (up to 9e-6; without them the robot leaves by 1e-6)
SECOND_ORDER = 5e-8
TOL_EXACT = 1e-12  # e_theta is exactly linear: round-off only


def _model(**over):
    over = {"verification.motor_saturation": False, "synthesis.delay_description": "polytopic", **over}
    return build_model(make_config(**over))


def _sample(model, turns, rng, N):
    """Random lifted states, new commands, slips, delays and reference yaw rates (w_k, ..., w_{k-d_hi})
    with the deviations scaled by EPS and w_k at full size."""
    n_e, n_u, d_hi = model.n_e, model.n_u, model.d_hi
    xi = np.zeros((N, model.n_s))
    xi[:, :n_e] = EPS * rng.uniform(-1, 1, (N, n_e)) * np.array([0.1, 0.1, 0.5])
    xi[:, n_e : n_e + d_hi * n_u] = EPS * rng.uniform(-1, 1, (N, d_hi * n_u)) * np.tile([0.4, 1.0], d_hi)
    du = EPS * rng.uniform(-1, 1, (N, n_u)) * np.array([0.4, 1.0])
    (rl, rh), (ll, lh) = model.slip_ranges
    mu = 1.0 + EPS * np.stack([rng.uniform(rl, rh, N) - 1.0, rng.uniform(ll, lh, N) - 1.0], axis=1)
    S = model.s_tilde(random_delays(model, rng, N, 1))[:, 0]
    wk = turns.max_yaw_rate * rng.choice([-1.0, -0.5, 0.0, 0.5, 1.0], N)
    wk = np.where(rng.random(N) < 0.5, wk, turns.max_yaw_rate * rng.uniform(-1, 1, N))
    b = turns.step_bounds(d_hi + 1)
    steps = EPS * rng.uniform(-1, 1, (N, d_hi)) * b  # w_k - w_{k-j}, j = 1..d_hi
    w = np.concatenate([wk[:, None], wk[:, None] - steps], axis=1)
    return xi, du, mu, S, w


def _robot(model, xi, du, mu, S, w):
    """e at t_{k+1} in the reference's frame at t_{k+1}: the robot starts at the errors of xi in the frame
    F_k of the reference at t_k (origin, heading 0), command j is (V^D, w_{k-j}) + du_{k-j}, the reference
    moves along its arc at V^D and w_k."""
    n_e, n_u, d_hi, V, Ts = model.n_e, model.n_u, model.d_hi, model.V, model.Ts
    N = xi.shape[0]
    U = np.empty((N, d_hi + 1, n_u))
    U[:, 0] = np.array([V, 0.0]) + du
    U[:, 1:] = np.array([V, 0.0]) + xi[:, n_e : n_e + d_hi * n_u].reshape(N, d_hi, n_u)
    U += w[:, :, None] * FEEDFORWARD
    q1 = KinematicRobot.of(model).period(xi[:, :n_e], U, S, mu)
    phi = w[:, 0] * Ts
    half = phi / 2.0
    sinc_half = np.where(np.abs(half) > 1e-300, np.sin(half) / np.where(half == 0, 1.0, half), 1.0)
    chord = V * Ts * sinc_half  # the reference's chord, at angle phi / 2
    dx, dy = q1[:, 0] - chord * np.cos(half), q1[:, 1] - chord * np.sin(half)
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([c * dx + s * dy, -s * dx + c * dy, q1[:, 2] - phi], axis=1)


def _allowed(model, turns, xi, du, mu, S, w, drop=(), theta_bar=0.0):
    """Per sample the centre and the allowance (|B_p| |q|) the augmented vertex at the sample's own
    delays and slip gives (the vertex algebra is affine in them, so the vertices' hull gives these).
    ``drop``: channel groups to leave out (negative controls): 'arc', 'rotation'.  ``theta_bar`` > 0:
    the vertex for the nonlinear robot with |eta(t)| <= theta_bar."""
    n_e, n_u, d_hi, V, Ts = model.n_e, model.n_u, model.d_hi, model.V, model.Ts
    D = model.config.robot.track_distance
    A, B = model.robot_exact(S, mu)
    c = model.constant(mu)
    h = Ts - S
    b = turns.step_bounds(d_hi + 1)
    centre, allow = np.empty((xi.shape[0], n_e)), np.empty((xi.shape[0], n_e))
    n_arc = None
    for i in range(xi.shape[0]):
        M = slip_matrix(mu[i], D)
        ch = vertex_channels(mu[i], np.stack([h[i], h[i] ** 2 / 2.0], axis=1), V, Ts, M, model.n_s, n_e, n_u, d_hi)
        v = Vertex(A[i], B[i], c[i][:, None], np.zeros((model.n_s, 0)), np.zeros((0, model.n_s)), np.zeros((0, n_u)), 0, "")
        Ai, Bi, Ei, Cq, Dq, Fq, Bp = _parts(v, ch, float(M[1, 1]), turns, Ts, V, n_e, n_u, d_hi, theta_bar)
        n_arc = Cq.shape[0] - 4  # the rotation's 4 channels come last
        wv = np.concatenate([[1.0, w[i, 0] / turns.max_yaw_rate], (w[i, 0] - w[i, 1:]) / b])
        q = Cq @ xi[i] + Dq @ du[i] + Fq @ wv
        keep = np.ones(len(q), dtype=bool)
        if "arc" in drop:
            keep[:n_arc] = False
        if "rotation" in drop:
            keep[n_arc:] = False
        centre[i] = (Ai @ xi[i] + Bi @ du[i] + Ei @ wv)[:n_e]
        allow[i] = (np.abs(Bp[:, keep]) @ np.abs(q[keep]))[:n_e]
    return centre, allow


@pytest.mark.parametrize("over", [{}, {"network.delay.min": 0.12, "network.delay.max": 0.22},
                                  {"slip.left.min": 0.9}])
def test_the_robot_on_an_arc_lies_within_the_turning_vertices(over):
    model = _model(**over)
    turns = Turns(0.5, 0.5)
    rng = np.random.default_rng(7)
    args = _sample(model, turns, rng, 400)
    e = _robot(model, *args)
    centre, allow = _allowed(model, turns, *args)
    excess = np.abs(e - centre) - allow
    assert np.max(np.abs(e[:, 2] - centre[:, 2])) <= TOL_EXACT  # e_theta: exact, no allowance
    assert np.all(allow[:, 2] == 0.0)
    assert np.max(excess[:, :2]) <= SECOND_ORDER
    # not vacuous: the robot uses a good part of the allowance somewhere
    used = np.abs(e - centre)[:, :2] / np.maximum(allow[:, :2], 1e-300)
    assert np.max(used) > 0.3


LIN_TOL = 1e-13  # the linearized map evaluated by quadrature against the vertex algebra: round-off only
FD_STEP = 1e-4  # [-] the scale of the deviations in the central difference of the robot
FD_TOL = 1e-8  # central difference: O(FD_STEP^2) times the third derivative, plus round-off / FD_STEP


def _robot_scaled(model, e0, vel, S, wk, lam):
    """The exact-arc robot of :func:`_robot` at t_{k+1}, in the reference's frame, with every deviation from the
    nominal arc scaled by ``lam``: the initial errors, each command's a_j and omega_j - w_k (``vel`` (N, d_hi + 1, 2)
    the velocities the slip makes of the commands, given directly)."""
    V, Ts = model.V, model.Ts
    U = np.stack([V + lam * (vel[..., 0] - V), wk[:, None] + lam * (vel[..., 1] - wk[:, None])], axis=-1)
    no_slip = np.broadcast_to(np.eye(2), (e0.shape[0], 2, 2))
    q1 = period(lam * e0, U, S, no_slip, Ts, np.eye(2), np.eye(2), None)
    return arc_frame_error(q1, wk, Ts, V)


@pytest.mark.parametrize("over", [{}, {"network.delay.min": 0.12, "network.delay.max": 0.22}])
def test_the_linearized_map_on_an_arc_is_the_robots_derivative_and_within_the_vertices(over):
    """model.arcs.linearized_arc_period, the kinematics linearized about the arc and integrated by quadrature,
    an implementation independent of the vertex algebra: (1) at full size it is the derivative of the exact-arc
    robot along the deviations from the nominal arc (initial errors, a_j, omega_j - w_k, with the slip exact as
    the map takes it), by central difference (the review of d688d86); (2) with w = 0 it is the straight lifted
    map; (3) it lies within the linearized turning vertex's allowance (an inclusion, tolerance round-off: the
    channels bound this map with no second-order slack, and use a good part of the allowance)."""
    from robustsynth.model.arcs import linearized_arc_period

    model = _model(**over)
    turns = Turns(0.5, 0.5)
    n_e, n_u, d_hi = model.n_e, model.n_u, model.d_hi
    rng = np.random.default_rng(11)
    xi, du, mu, S, w = _sample_full(model, turns, rng, 300)
    lin = linearized_arc_period(model, xi, du, S, mu, w)
    u = np.array([model.V, 0.0]) + np.concatenate([du[:, None, :], xi[:, n_e : n_e + d_hi * n_u].reshape(-1, d_hi, n_u)],
                                                  axis=1) + w[:, :, None] * FEEDFORWARD
    vel = np.einsum("nij,nkj->nki", slip_matrix(mu, model.config.robot.track_distance), u)
    fd = (_robot_scaled(model, xi[:, :n_e], vel, S, w[:, 0], FD_STEP)
          - _robot_scaled(model, xi[:, :n_e], vel, S, w[:, 0], -FD_STEP)) / (2 * FD_STEP)
    assert np.max(np.abs(fd - lin)) <= FD_TOL
    with pytest.raises(ValueError, match="yaw rates"):
        linearized_arc_period(model, xi, du, S, mu, w[:, :1])
    A, B = model.robot_exact(S, mu)
    straight = (np.einsum("nij,nj->ni", A, xi) + np.einsum("nij,nj->ni", B, du) + model.constant(mu))[:, :n_e]
    assert np.max(np.abs(linearized_arc_period(model, xi, du, S, mu, np.zeros_like(w)) - straight)) <= LIN_TOL
    centre, allow = _allowed(model, turns, xi, du, mu, S, w)
    assert np.max(np.abs(lin[:, 2] - centre[:, 2])) <= LIN_TOL and np.all(allow[:, 2] == 0.0)
    assert np.max(np.abs(lin - centre)[:, :2] - allow[:, :2]) <= LIN_TOL
    assert np.max(np.abs(lin - centre)[:, :2] / np.maximum(allow[:, :2], 1e-300)) > 0.3  # not vacuous
    # the turning model's disturbance coordinates (the lifted-model checks' beta terms) in the vertices' layout
    wv = np.concatenate([np.ones((len(w), 1)), w[:, :1] / 0.5, (w[:, :1] - w[:, 1:]) / turns.step_bounds(d_hi + 1)], axis=1)
    assert np.array_equal(model.with_turns(0.5).disturbance_coordinates(mu, w), wv)


@pytest.mark.parametrize("drop", ["arc", "rotation"])
def test_each_part_of_the_augmentation_is_needed(drop):
    """Without the arc's linearization channels, or without the change of frame's, the robot leaves
    the allowance by far more than the second-order terms."""
    model = _model()
    turns = Turns(0.5, 0.5)
    rng = np.random.default_rng(8)
    args = _sample(model, turns, rng, 400)
    e = _robot(model, *args)
    centre, allow = _allowed(model, turns, *args, drop=(drop,))
    assert np.max(np.abs(e - centre)[:, :2] - allow[:, :2]) > 10 * SECOND_ORDER


def test_a_reference_that_does_not_turn_gives_the_straight_map():
    """w = 0 and no steps: the centre is the straight lifted map, up to the factors' centres (of order
    phi_bar^2), and every channel's q is what the straight map's rows give."""
    model = _model()
    turns = Turns(1e-9, 1e-9)
    rng = np.random.default_rng(9)
    xi, du, mu, S, _ = _sample(model, turns, rng, 50)
    w = np.zeros((50, model.d_hi + 1))
    A, B = model.robot_exact(S, mu)
    straight = (np.einsum("nij,nj->ni", A, xi) + np.einsum("nij,nj->ni", B, du) + model.constant(mu))[:, :3]
    centre, allow = _allowed(model, turns, xi, du, mu, S, w)
    assert np.max(np.abs(centre - straight)) <= 1e-15
    assert np.max(allow) <= 1e-12


# ---------------------------------------------------------------- the nonlinear robot (theta_bar > 0)

THETA_BAR = 0.4  # [rad]: the heading deviation the nonlinear vertices are built for
EXACT = 1e-12  # [m]: round-off of one period of exact arcs (no second-order slack: the channels hold every term)


def _sample_full(model, turns, rng, N):
    """Full-size deviations (positions to 5 cm, headings to 0.3 rad, corrections to 0.3 m/s and 1.5
    rad/s, slip over the whole box, yaw-rate steps as large as allowed), as the certified sets hold."""
    n_e, n_u, d_hi = model.n_e, model.n_u, model.d_hi
    xi = np.zeros((N, model.n_s))
    xi[:, :n_e] = rng.uniform(-1, 1, (N, n_e)) * np.array([0.05, 0.05, 0.3])
    xi[:, n_e : n_e + d_hi * n_u] = rng.uniform(-1, 1, (N, d_hi * n_u)) * np.tile([0.3, 1.5], d_hi)
    du = rng.uniform(-1, 1, (N, n_u)) * np.array([0.3, 1.5])
    (rl, rh), (ll, lh) = model.slip_ranges
    mu = np.stack([rng.uniform(rl, rh, N), rng.uniform(ll, lh, N)], axis=1)
    mu[: N // 4] = np.array([[rl, ll], [rl, lh], [rh, ll], [rh, lh]])[rng.integers(0, 4, N // 4)]
    S = model.s_tilde(random_delays(model, rng, N, 1))[:, 0]
    wk = turns.max_yaw_rate * rng.choice([-1.0, 1.0], N)
    wk = np.where(rng.random(N) < 0.5, wk, turns.max_yaw_rate * rng.uniform(-1, 1, N))
    b = turns.step_bounds(d_hi + 1)
    w = np.concatenate([wk[:, None], np.clip(wk[:, None] - b * rng.choice([-1.0, 1.0], (N, d_hi)),
                                             -turns.max_yaw_rate, turns.max_yaw_rate)], axis=1)
    return xi, du, mu, S, w


def _eta_break_points(model, xi, du, mu, S, w):
    """eta = e_theta(t) - w_k t at t_k and after each command's interval (oldest first), from the robot's
    own turn rates (exact: e_theta is piecewise linear)."""
    n_e, n_u, d_hi, V, Ts = model.n_e, model.n_u, model.d_hi, model.V, model.Ts
    D = model.config.robot.track_distance
    N = xi.shape[0]
    U = np.empty((N, d_hi + 1, n_u))
    U[:, 0] = np.array([V, 0.0]) + du
    U[:, 1:] = np.array([V, 0.0]) + xi[:, n_e : n_e + d_hi * n_u].reshape(N, d_hi, n_u)
    U += w[:, :, None] * FEEDFORWARD
    omega = np.einsum("nj,nij->ni", slip_matrix(mu, D)[:, 1, :], U)  # (N, d_hi + 1)
    eta, start, out = xi[:, 2].copy(), np.zeros(N), [xi[:, 2].copy()]
    for j in range(d_hi, -1, -1):
        end = S[:, j - 1] if j > 0 else np.full(N, Ts)
        eta = eta + (omega[:, j] - w[:, 0]) * (end - start)
        start = end
        out.append(eta.copy())
    return np.stack(out, axis=1)


@pytest.mark.parametrize("over", [{}, {"network.delay.min": 0.12, "network.delay.max": 0.22},
                                  {"slip.left.min": 0.9}])
def test_the_nonlinear_robot_on_an_arc_lies_within_the_vertices_for_its_heading(over):
    """Full-size errors and corrections, exact arcs: wherever |eta(t)| <= theta_bar over the period, the
    robot lies within the nonlinear turning vertex's allowance at the sample's own delays and slip, to
    round-off (no second-order slack), and the heading rows with their yaw-rate columns give eta at
    every break point."""
    model = _model(**over)
    turns = Turns(0.5, 0.5)
    rng = np.random.default_rng(11)
    args = _sample_full(model, turns, rng, 600)
    eta = _eta_break_points(model, *args)
    keep = np.max(np.abs(eta), axis=1) <= THETA_BAR
    assert np.mean(keep) > 0.5  # most samples qualify: the test is about them
    args = tuple(a[keep] for a in args)
    e = _robot(model, *args)
    centre, allow = _allowed(model, turns, *args, theta_bar=THETA_BAR)
    assert np.max(np.abs(e[:, 2] - centre[:, 2])) <= EXACT
    assert np.max(np.abs(e - centre)[:, :2] - allow[:, :2]) <= EXACT
    used = np.abs(e - centre)[:, :2] / np.maximum(allow[:, :2], 1e-300)
    assert np.max(used) > 0.3  # not vacuous
    # the linearized turning vertex (theta_bar 0) does not hold the robot at these sizes
    c_lin, allow_lin = _allowed(model, turns, *args)
    assert np.max(np.abs(e - c_lin)[:, :2] - allow_lin[:, :2]) > 1e-4
    # the heading rows (vertex_channels' C_h, D_h, g_h and the turning F_h) at the sample's delays and slip
    xi, du, mu, S, w = args
    n_e, n_u, d_hi, V, Ts = model.n_e, model.n_u, model.d_hi, model.V, model.Ts
    D = model.config.robot.track_distance
    b = turns.step_bounds(d_hi + 1)
    eta = _eta_break_points(model, *args)
    for i in range(0, xi.shape[0], 7):
        M = slip_matrix(mu[i], D)
        h = Ts - S[i]
        ch = vertex_channels(mu[i], np.stack([h, h**2 / 2.0], axis=1), V, Ts, M, model.n_s, n_e, n_u, d_hi)
        F_h = heading_yaw_columns(ch, turns, n_e, n_u, d_hi)
        z = np.concatenate([[w[i, 0] / turns.max_yaw_rate], (w[i, 0] - w[i, 1:]) / b])
        rows = ch.C_h @ xi[i] + ch.D_h @ du[i] + ch.g_h + F_h @ z
        assert np.max(np.abs(rows - eta[i])) <= 1e-13


def test_the_nonlinear_turning_model_at_its_straight_point():
    """hull_coordinates of a nonlinear turning model: on a straight segment the vertices' hull at the
    returned weights and Delta is the exact linearized lifted map (coverage as for every model)."""
    from robustsynth.model import coverage_check

    model = _model(**{"synthesis.kinematics": "nonlinear", "synthesis.heading_bound": 0.3}).with_turns(0.3)
    assert model.kinematics == "nonlinear" and model.turns is not None
    rep = coverage_check(model, n_sequences=50, steps=5)
    assert rep["passed"], rep
    lin = model.linearized()
    assert lin.turns == model.turns and lin.heading_bound is None
    assert lin.vertices[0].n_q == model.vertices[0].n_q  # the same channels, narrower factor ranges
    width = [float(np.sum(np.abs(m.vertices[0].B_p) @ np.abs(m.vertices[0].C_q))) for m in (lin, model)]
    assert width[0] < width[1]  # |B_p| |C_q|: independent of the channels' scaling


# ---------------------------------------------------------------- slip changing within the period, on arcs


def _within_period(model, turns, rng, N, full):
    """Samples as :func:`_sample_full` (``full``) or :func:`_sample`, with each track's slip jumping between
    the two ends of its range (scaled about 1 by EPS when not ``full``) at its own random time within
    the period; the robot's e at t_{k+1} in the reference's frame then, eta at every break point and jump
    (its extremes: eta is piecewise linear), and the switched straight map (A, B, c) of the history."""
    from .test_nonlinear import _heading_at

    xi, du, _, S, w = (_sample_full if full else _sample)(model, turns, rng, N)
    (rl, rh), (ll, lh) = model.slip_ranges
    lo, hi = np.array([rl, ll]), np.array([rh, lh])
    if not full:
        lo, hi = 1.0 + EPS * (lo - 1.0), 1.0 + EPS * (hi - 1.0)
    pick = rng.integers(0, 2, (N, 2))
    mu, after = lo + (hi - lo) * pick, lo + (hi - lo) * (1 - pick)
    t_sw = rng.uniform(0.0, model.Ts, (N, 2))
    switch = track_changes(mu, after, t_sw)
    n_e, n_u, d_hi, V, Ts = model.n_e, model.n_u, model.d_hi, model.V, model.Ts
    U = np.empty((N, d_hi + 1, n_u))
    U[:, 0] = np.array([V, 0.0]) + du
    U[:, 1:] = np.array([V, 0.0]) + xi[:, n_e : n_e + d_hi * n_u].reshape(N, d_hi, n_u)
    U += w[:, :, None] * FEEDFORWARD
    q1 = KinematicRobot.of(model).period(xi[:, :n_e], U, S, mu, switch=switch)
    phi = w[:, 0] * Ts
    half = phi / 2.0
    chord = V * Ts * np.where(half != 0.0, np.sin(half) / np.where(half == 0.0, 1.0, half), 1.0)
    dx, dy = q1[:, 0] - chord * np.cos(half), q1[:, 1] - chord * np.sin(half)
    e = np.stack([np.cos(phi) * dx + np.sin(phi) * dy, -np.sin(phi) * dx + np.cos(phi) * dy, q1[:, 2] - phi], axis=1)
    times = np.concatenate([np.zeros((N, 1)), S, t_sw, np.full((N, 1), Ts)], axis=1)
    eta = np.stack([_heading_at(model, xi[:, 2], U, S, mu, t_sw, after, times[:, k]) - w[:, 0] * times[:, k]
                    for k in range(times.shape[1])], axis=1)
    A, B, c = model.switched_exact(S, mu, t_sw, after, per_track=True)
    return (xi, du, S, w), e, eta, (A, B, c), (lo, hi)


def _covering_allowed(model, turns, xi, du, S, w, maps, box, theta_bar, narrow=False):
    """Per sample the centre and allowance of the covering turning vertex at the sample's own delays and
    slip history (its straight map: the switched one, a point of the within-period vertices' hull; its
    channels: the delay vertex's covering ones, affine in the delay coordinates); and the heading rows'
    largest |eta| there.  ``narrow``: the deviation channels at zero width (the negative control)."""
    from dataclasses import replace

    from robustsynth.model.nonlinear import covering_channels

    n_e, n_u, d_hi, V, Ts = model.n_e, model.n_u, model.d_hi, model.V, model.Ts
    D = model.config.robot.track_distance
    lo, hi = box
    M11 = float(slip_matrix((lo + hi) / 2.0, D)[1, 1])
    A, B, c = maps
    h = Ts - S
    b = turns.step_bounds(d_hi + 1)
    centre, allow, rows = np.empty((xi.shape[0], n_e)), np.empty((xi.shape[0], n_e)), np.empty(xi.shape[0])
    for i in range(xi.shape[0]):
        ch = covering_channels((lo[0], hi[0]), (lo[1], hi[1]), np.stack([h[i], h[i] ** 2 / 2.0], axis=1), V, Ts, D,
                               model.n_s, n_e, n_u, d_hi)
        if narrow:
            ch = replace(ch, half_dev=np.zeros_like(ch.half_dev))
        v = Vertex(A[i], B[i], c[i][:, None], np.zeros((model.n_s, 0)), np.zeros((0, model.n_s)), np.zeros((0, n_u)), 0, "")
        Ai, Bi, Ei, Cq, Dq, Fq, Bp = _parts(v, ch, M11, turns, Ts, V, n_e, n_u, d_hi, theta_bar)
        z = np.concatenate([[w[i, 0] / turns.max_yaw_rate], (w[i, 0] - w[i, 1:]) / b])
        wv = np.concatenate([[1.0], z])
        q = Cq @ xi[i] + Dq @ du[i] + Fq @ wv
        centre[i] = (Ai @ xi[i] + Bi @ du[i] + Ei @ wv)[:n_e]
        allow[i] = (np.abs(Bp) @ np.abs(q))[:n_e]
        F_h = heading_yaw_columns(ch, turns, n_e, n_u, d_hi)
        rows[i] = np.max(np.abs(ch.C_h @ xi[i] + ch.D_h @ du[i] + ch.g_h + F_h @ z))
    return centre, allow, rows


@pytest.mark.parametrize("over", [{}, {"network.dropouts.max_consecutive": 1,
                                       "synthesis.delay_description": "lossy-polytopic"}])
@pytest.mark.parametrize("theta_bar", [0.0, THETA_BAR])
def test_slip_changing_within_the_period_on_an_arc_stays_within_the_covering_vertices(over, theta_bar):
    """Each track's slip jumps between the ends of its range at its own time within the period, on an arc
    with the feedforward in flight.  The robot lies within the covering turning vertex's allowance: to
    round-off for the nonlinear vertex (full-size deviations, wherever |eta(t)| <= theta_bar), to second
    order for the linearized one (deviations scaled by EPS).  e_theta is exact, and the heading rows with
    their yaw-rate columns bound |eta| at every break point and jump."""
    model = _model(**over)
    assert model.covering  # the model builds these channels (a lossy link: d_hi = 2)
    turns = Turns(0.5, 0.5)
    rng = np.random.default_rng(13)
    full = theta_bar > 0.0
    args, e, eta, maps, box = _within_period(model, turns, rng, 500, full)
    if full:
        keep = np.max(np.abs(eta), axis=1) <= theta_bar
        assert np.mean(keep) > 0.5
        args, e, eta = tuple(a[keep] for a in args), e[keep], eta[keep]
        maps = tuple(m[keep] for m in maps)
    centre, allow, rows = _covering_allowed(model, turns, *args, maps, box, theta_bar)
    slack = EXACT if full else SECOND_ORDER
    assert np.max(np.abs(e[:, 2] - centre[:, 2])) <= TOL_EXACT
    assert np.max(np.abs(e - centre)[:, :2] - allow[:, :2]) <= slack
    used = np.abs(e - centre)[:, :2] / np.maximum(allow[:, :2], 1e-300)
    assert np.max(used) > 0.3  # not vacuous
    assert np.all(np.max(np.abs(eta), axis=1) <= rows + TOL_EXACT)


def test_without_the_deviation_channels_slip_changing_on_an_arc_is_not_covered():
    """The negative control: the covering channels with the tracks' deviations at zero width (the centre
    slip's channels only) are exceeded by the same histories."""
    model = _model()
    turns = Turns(0.5, 0.5)
    rng = np.random.default_rng(13)
    args, e, eta, maps, box = _within_period(model, turns, rng, 500, True)
    keep = np.max(np.abs(eta), axis=1) <= THETA_BAR
    args, e = tuple(a[keep] for a in args), e[keep]
    maps = tuple(m[keep] for m in maps)
    centre, allow, _ = _covering_allowed(model, turns, *args, maps, box, THETA_BAR, narrow=True)
    assert np.max(np.abs(e - centre)[:, :2] - allow[:, :2]) > 1e-4
