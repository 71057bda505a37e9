"""The kinematic channels (model/nonlinear.py) against the robot itself: one period of exact arcs
from random states, commands, slips and delays lies within what the augmented vertices allow, and
only while |e_theta(t)| stays within the heading bound."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.model import build_model, coverage_check
from robustsynth.model.slip import slip_matrix
from robustsynth.plants.kinematic import KinematicRobot
from robustsynth.plants.path import frame_error, make_path, pose_from_error
from robustsynth.scenarios import random_delays

from ..conftest import make_config

TOL = 1e-12  # round-off of one period's arcs against the vertex algebra (values of order 1e-2)
THETA_BAR = 0.3


def _nonlinear(**over):
    over = {"synthesis.kinematics": "nonlinear", "synthesis.heading_bound": THETA_BAR, "verification.motor_saturation": False,
            **over}
    return build_model(make_config(**over))


def _random_state(model, rng, N, spread):
    """Random lifted states (errors up to 0.1 m and ``spread`` rad, stored commands) and new commands."""
    n_e, n_u, d_hi = model.n_e, model.n_u, model.d_hi
    xi = np.zeros((N, model.n_s))
    xi[:, :n_e] = rng.uniform(-1, 1, (N, n_e)) * np.array([0.1, 0.1, spread])
    xi[:, n_e : n_e + d_hi * n_u] = rng.uniform(-1, 1, (N, d_hi * n_u)) * np.tile([0.4, 1.0], d_hi)
    du = rng.uniform(-1, 1, (N, n_u)) * np.array([0.4, 1.0])
    return xi, du


def _start(model, xi, du):
    """A straight path, the poses of the errors in ``xi``, the robot and its commands in flight."""
    n_e, n_u, d_hi, N = model.n_e, model.n_u, model.d_hi, xi.shape[0]
    path = make_path(((0.0, 0.0), (100.0, 0.0)), model.V)
    q0 = pose_from_error(path, xi[:, :n_e])
    robot = KinematicRobot.of(model)
    U = robot.send(robot.memory(xi[:, n_e : n_e + d_hi * n_u].reshape(N, d_hi, n_u), N), np.array([model.V, 0.0]) + du)
    return path, q0, robot, U


def _one_period(model, rng, N, spread):
    """Random lifted states (errors, stored commands), new commands, slips and delays; the robot's
    e at t_{k+1} and the largest |e_theta(t)| within the period (at the arcs' ends: it is linear in t)."""
    d_hi = model.d_hi
    xi, du = _random_state(model, rng, N, spread)
    (rl, rh), (ll, lh) = model.slip_ranges
    mu = np.stack([rng.uniform(rl, rh, N), rng.uniform(ll, lh, N)], axis=1)
    S = model.s_tilde(random_delays(model, rng, N, 1))[:, 0]
    path, q0, robot, U = _start(model, xi, du)
    q1 = robot.period(q0, U, S, mu)
    # e_theta is linear within each command's interval: its extremes are at the intervals' ends
    M = slip_matrix(mu, model.config.robot.track_distance)
    omega = np.einsum("nk,njk->nj", M[:, 1, :], U)  # turn rate of each command in flight
    heading = np.abs(xi[:, 2])
    th, t0 = xi[:, 2].copy(), np.zeros(N)
    for j in range(d_hi, -1, -1):
        end = S[:, j - 1] if j > 0 else np.full(N, model.Ts)
        th = th + omega[:, j] * (end - t0)
        heading = np.maximum(heading, np.abs(th))
        t0 = end
    e1 = frame_error(path, 0, q1, model.Ts)
    return xi, du, mu, S, e1, heading


def _excess(model, xi, du, mu, S, e1):
    """Per sample and row (e_x, e_y): |robot - nominal| minus what the channels allow (<= 0 inside)."""
    lam, _ = model.hull_coordinates(S, mu)
    w = np.ones((xi.shape[0], 1))
    nominal = sum(lam[:, i, None] * (xi @ v.A.T + du @ v.B.T + w @ v.E.T) for i, v in enumerate(model.vertices))
    q = sum(lam[:, i, None] * (xi @ v.C_q.T + du @ v.D_q.T + w @ v.F_q.T) for i, v in enumerate(model.vertices))
    Bp = model.vertices[0].B_p
    allowed = np.abs(q) @ np.abs(Bp[:2]).T  # (N, 2): rows e_x, e_y
    return np.abs(e1[:, :2] - nominal[:, :2]) - allowed, allowed


@pytest.mark.parametrize("over", [{}, {"network.delay.max": 0.18, "network.delay.min": 0.05},
                                  {"network.dropouts.max_consecutive": 1}])
def test_the_robot_stays_within_the_channels(over) -> None:
    """Every sample whose heading stays within the bound: the robot's e_x, e_y at t_{k+1} differ from
    the vertices' nominal by no more than the channels allow; e_theta exactly (it is linear)."""
    model = _nonlinear(**over)
    rng = np.random.default_rng(1)
    xi, du, mu, S, e1, heading = _one_period(model, rng, 4000, 0.25)
    ok = heading <= THETA_BAR
    assert ok.mean() > 0.5  # the test exercises many samples
    excess, allowed = _excess(model, xi[ok], du[ok], mu[ok], S[ok], e1[ok])
    assert np.max(excess) <= TOL, np.max(excess)
    # the bound is not vacuous: the robot uses a fair share of it somewhere
    used = (np.abs(excess + allowed) / np.maximum(allowed, 1e-300))
    assert np.max(used[:, 1]) > 0.3
    # e_theta: the linear map is exact
    lam, dlt = model.hull_coordinates(S[ok], mu[ok])
    A, B, c = model.from_hull(lam, dlt, np.ones((int(ok.sum()), 1)))
    lin = np.einsum("nij,nj->ni", A, xi[ok]) + np.einsum("nij,nj->ni", B, du[ok]) + c
    assert np.max(np.abs(lin[:, 2] - e1[ok, 2])) <= TOL


def test_headings_beyond_the_bound_break_the_channels() -> None:
    """The negative control: with headings up to 1 rad the same channels (for 0.3 rad) are exceeded."""
    model = _nonlinear()
    rng = np.random.default_rng(2)
    xi, du, mu, S, e1, heading = _one_period(model, rng, 4000, 1.0)
    excess, _ = _excess(model, xi, du, mu, S, e1)
    assert np.max(excess) > 1e-4


def test_linearization_is_inside_the_augmented_vertices() -> None:
    model = _nonlinear()
    assert model.kinematics == "nonlinear" and model.heading_bound == THETA_BAR
    assert all(v.diagonal and v.n_q == model.vertices[0].n_q for v in model.vertices)
    # B_p enters the LMIs quadratically (B_p M B_p'): it must be the same at every vertex
    assert all(np.array_equal(v.B_p, model.vertices[0].B_p) for v in model.vertices)
    assert coverage_check(model, 200, 10)["passed"]
    assert model.linearized().kinematics == "linearized"


# ---------------------------------------------------------------- slip changing within the period


def _heading_at(model, e0, U, S, mu, t_sw, mu_after, t):
    """e_theta(t) (N,) of the exact arcs, each track's slip jumping from mu to mu_after at its own
    time t_sw[:, i]: e_theta is the integral of omega = M(mu(s))[1] u(s), affine in each track's slip,
    so per command interval its length up to t and each track's share after its jump suffice."""
    D = model.config.robot.track_distance
    M0 = slip_matrix(mu, D)[:, 1, :]
    N_tr = [slip_matrix(np.eye(2)[i], D)[1] - slip_matrix(np.zeros(2), D)[1] for i in range(2)]
    ends = np.concatenate([np.full((S.shape[0], 1), model.Ts), S, np.zeros((S.shape[0], 1))], axis=1)
    out = e0.copy()
    for j in range(model.d_hi + 1):
        a, b = ends[:, j + 1], np.minimum(ends[:, j], t)
        out += np.maximum(b - a, 0.0) * np.einsum("nk,nk->n", M0, U[:, j])
        for i in range(2):
            share = np.maximum(b - np.maximum(a, t_sw[:, i]), 0.0)
            out += share * (mu_after[:, i] - mu[:, i]) * (U[:, j] @ N_tr[i])
    return out


def _within_period_samples(model, rng, N, spread):
    """Random lifted states, commands, delays and per-track slip jumps within the period; the robot's e
    at t_{k+1} through its exact arcs, the largest |e_theta(t)| and the switched linear map's e."""
    xi, du = _random_state(model, rng, N, spread)
    (rl, rh), (ll, lh) = model.slip_ranges
    lo, hi = np.array([rl, ll]), np.array([rh, lh])
    mu = lo + (hi - lo) * rng.integers(0, 2, (N, 2))  # jumps between the box's extremes: the hardest
    mu_after = lo + hi - mu
    t_sw = rng.uniform(0.0, model.Ts, (N, 2))
    S = model.s_tilde(random_delays(model, rng, N, 1))[:, 0]
    path, q0, robot, U = _start(model, xi, du)
    first = np.argmin(t_sw, axis=1)  # the earlier track's jump, then the other's
    mid = mu.copy()
    mid[np.arange(N), first] = mu_after[np.arange(N), first]
    q1 = robot.period(q0, U, S, mu, switch=[(np.min(t_sw, axis=1), mid), (np.max(t_sw, axis=1), mu_after)])
    e1 = frame_error(path, 0, q1, model.Ts)
    times = np.concatenate([np.zeros((N, 1)), S, t_sw, np.full((N, 1), model.Ts)], axis=1)
    heading = np.max([np.abs(_heading_at(model, xi[:, 2], U, S, mu, t_sw, mu_after, times[:, k]))
                      for k in range(times.shape[1])], axis=0)
    A, B, c = model.switched_exact(S, mu, t_sw, mu_after, per_track=True)
    lin = np.einsum("nij,nj->ni", A, xi) + np.einsum("nij,nj->ni", B, du) + c
    return xi, du, mu, S, e1, heading, lin, U, t_sw, mu_after


def _channel_excess(model, base, xi, du, mu, S, e1, lin):
    """|robot - (switched linear map + the channels' centres)| minus what the channels allow, per
    sample and row (e_x, e_y); the channels and centres are the same at every slip corner of a delay
    vertex, so the hull's delay weights combine them."""
    lam, _ = model.hull_coordinates(S, mu)
    w = np.ones((xi.shape[0], 1))
    shift = sum(lam[:, i, None] * (xi @ (v.A - b.A).T + du @ (v.B - b.B).T + w @ (v.E - b.E).T)
                for i, (v, b) in enumerate(zip(model.vertices, base)))
    q = sum(lam[:, i, None] * (xi @ v.C_q.T + du @ v.D_q.T + w @ v.F_q.T) for i, v in enumerate(model.vertices))
    allowed = np.abs(q) @ np.abs(model.vertices[0].B_p[:2]).T
    return np.abs(e1[:, :2] - lin[:, :2] - shift[:, :2]) - allowed, allowed


def test_slip_changing_within_the_period_stays_within_the_covering_channels() -> None:
    """theory §9, slip changing within a period: each track's slip jumps between its extremes at its own
    time; wherever |e_theta(t)| <= theta_bar the robot's e_x, e_y differ from the switched linear map
    (plus the channels' centres) by no more than the covering channels allow, e_theta not at all."""
    model = _nonlinear()
    assert model.covering_vertices and all(v.group >= 0 for v in model.vertices)
    rng = np.random.default_rng(5)
    xi, du, mu, S, e1, heading, lin, *_ = _within_period_samples(model, rng, 4000, 0.25)
    ok = heading <= THETA_BAR
    assert ok.mean() > 0.5
    assert np.max(np.abs(lin[ok, 2] - e1[ok, 2])) <= TOL  # e_theta is linear in the slip and the commands
    excess, allowed = _channel_excess(model, model.base_vertices, xi[ok], du[ok], mu[ok], S[ok], e1[ok], lin[ok])
    assert np.max(excess) <= TOL, np.max(excess)
    used = np.abs(excess + allowed) / np.maximum(allowed, 1e-300)
    assert np.max(used[:, 1]) > 0.3  # not vacuous


def test_without_the_deviation_channels_the_within_period_slip_is_not_covered() -> None:
    """The negative control: the same vertices with the tracks' deviation channels at zero width (the
    centre slip's channels only) are exceeded by the same histories."""
    from dataclasses import replace

    from robustsynth.model.nonlinear import augment, channel_scales

    model = _nonlinear()
    n_d = len(model.covering)
    narrow = [replace(ch, half_dev=np.zeros_like(ch.half_dev)) for ch in model.covering]
    sc = channel_scales(narrow, THETA_BAR, model.V)
    verts = tuple(augment(v, narrow[i % n_d], THETA_BAR, model.V, sc, group=i % n_d)
                  for i, v in enumerate(model.base_vertices))
    cut = replace(model, vertices=verts)
    rng = np.random.default_rng(5)
    xi, du, mu, S, e1, heading, lin, *_ = _within_period_samples(model, rng, 4000, 0.25)
    ok = heading <= THETA_BAR
    excess, _ = _channel_excess(cut, model.base_vertices, xi[ok], du[ok], mu[ok], S[ok], e1[ok], lin[ok])
    assert np.max(excess) > 1e-4


def _bound(chs, xi, du):
    """The heading rows' largest |r xi + d du + g| over the delay vertices and break points."""
    return np.max([np.max(np.abs(xi @ ch.C_h.T + du @ ch.D_h.T + ch.g_h), axis=1) for ch in chs], axis=0)


def test_the_covering_heading_rows_bound_the_heading() -> None:
    """|e_theta(t)| within the period is at most the covering heading rows' largest value over the
    delay vertices (each command interval at a slip corner of its own), on random jump histories."""
    model = _nonlinear()
    rng = np.random.default_rng(6)
    xi, du, mu, S, e1, heading, *_ = _within_period_samples(model, rng, 4000, 0.25)
    assert np.all(heading <= _bound(model.covering, xi, du) + TOL)


def test_one_slip_corner_per_period_does_not_bound_the_heading() -> None:
    """The negative control: the older command in flight reverses the left track, so it turns most with
    the left track's slip high, while the newer one turns most with it low.  The left track's slip drops
    from its maximum to its minimum at the switching instant (delay at its maximum, a delay vertex):
    |e_theta(t_{k+1})| exceeds what the rows of any one slip corner for the whole period allow (found by
    a random search over commands and jumps, 2e-2 rad), and the covering rows bound it."""
    model = _nonlinear()
    N = 21
    (rl, rh), (ll, lh) = model.slip_ranges
    tau = model.config.network.delay.max
    S = np.full((N, 1), tau)
    xi = np.zeros((N, model.n_s))
    xi[:, 2] = np.linspace(-0.01, 0.01, N)
    xi[:, 3:5] = [-0.6, 1.75]  # the older command (dV, dW)
    du = np.tile([0.8, 0.0], (N, 1))  # the newer one
    mu = np.tile([rh, lh], (N, 1))
    after = np.tile([rh, ll], (N, 1))
    robot = KinematicRobot.of(model)
    U = robot.send(robot.memory(xi[:, 3:5].reshape(N, 1, 2), N), np.array([model.V, 0.0]) + du)
    end = _heading_at(model, xi[:, 2], U, S, mu, np.full((N, 2), tau), after, np.full(N, model.Ts))
    assert np.all(np.abs(end) <= _bound(model.covering, xi, du) + TOL)
    assert np.all(np.abs(end) > _bound(model.channels, xi, du) + 1e-2)
