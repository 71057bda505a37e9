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


def _one_period(model, rng, N, spread):
    """Random lifted states (errors, stored commands), new commands, slips and delays; the robot's
    e at t_{k+1} and the largest |e_theta(t)| within the period (at the arcs' ends: it is linear in t)."""
    n_e, n_u, d_hi = model.n_e, model.n_u, model.d_hi
    xi = np.zeros((N, model.n_s))
    xi[:, :n_e] = rng.uniform(-1, 1, (N, n_e)) * np.array([0.1, 0.1, spread])
    xi[:, n_e : n_e + d_hi * n_u] = rng.uniform(-1, 1, (N, d_hi * n_u)) * np.tile([0.4, 1.0], d_hi)
    du = rng.uniform(-1, 1, (N, n_u)) * np.array([0.4, 1.0])
    (rl, rh), (ll, lh) = model.slip_ranges
    mu = np.stack([rng.uniform(rl, rh, N), rng.uniform(ll, lh, N)], axis=1)
    S = model.s_tilde(random_delays(model, rng, N, 1))[:, 0]
    uD = np.array([model.V, 0.0])
    path = make_path(((0.0, 0.0), (100.0, 0.0)), model.V)
    q0 = pose_from_error(path, xi[:, :n_e])
    robot = KinematicRobot.of(model)
    U = robot.send(robot.memory(xi[:, n_e : n_e + d_hi * n_u].reshape(N, d_hi, n_u), N), uD + du)
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
