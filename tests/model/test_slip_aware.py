"""The slip-aware model: vertex hull coverage, agreement with the nonlinear robot to second order,
the slip-compensated steady state, and the physical feasibility check."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.errors import InfeasibleError
from robustsynth.model import build_model, coverage_check
from robustsynth.model.kinematics import J_inverse
from robustsynth.model.slip import (
    check_physical_feasibility,
    compensated_command,
    corner_weights,
    required_motor_speeds,
    slip_corners,
    slip_matrix,
)
from robustsynth.model.vertices import triangle, triangle_coordinates
from robustsynth.plants.kinematic import period
from robustsynth.plants.path import frame_error, make_path

from ..conftest import make_config

HULL_TOL = 1e-12  # exact matrices rebuilt from the vertices with explicit convex weights
COVERAGE_SAMPLES = 10_000  # issue 8: >= 10 000 random (slip, delay history) samples

RANGES = {
    "default (d_hi = 1)": {},
    "full period": {"network.delay.min": 0.0, "network.delay.max": 0.1},
    "two periods": {"network.delay.max": 0.18},
    "three periods": {"network.delay.min": 0.02, "network.delay.max": 0.25},
    "d_lo = 1": {"network.delay.min": 0.12, "network.delay.max": 0.22},
    "one track fixed": {"slip.left.min": 1.0},
}


@pytest.mark.parametrize("desc", ["polytopic", "norm-bounded"])
@pytest.mark.parametrize("name", list(RANGES))
def test_vertex_hull_contains_the_exact_slip_aware_map(name, desc) -> None:
    for integral in (False, True):
        m = build_model(make_config(**RANGES[name], **{"synthesis.delay_description": desc,
                                                       "synthesis.integral_action": integral}))
        cov = coverage_check(m, n_sequences=COVERAGE_SAMPLES // 10, steps=10, seed=3)
        assert cov["samples"] >= COVERAGE_SAMPLES
        assert cov["passed"], cov
        assert cov["max_residual"] <= HULL_TOL and cov["min_weight"] >= -HULL_TOL


def test_vertex_counts() -> None:
    assert len(build_model(make_config()).vertices) == 4 * 3  # 4 slip corners x 1 triangle
    assert len(build_model(make_config(**{"network.delay.max": 0.25, "synthesis.delay_description": "polytopic"})).vertices) == 4 * 27
    assert len(build_model(make_config(**{"network.delay.max": 0.25})).vertices) == 4  # auto: norm-bounded
    assert len(build_model(make_config(**{"synthesis.model": "paper"})).vertices) == 1
    assert len(build_model(make_config(**{"slip.left.min": 1.0})).vertices) == 2 * 3  # a fixed track has 1 value


def test_a_model_rebuilt_from_another_config_is_that_configs_model() -> None:
    """``Model.rebuilt`` (what the plant-generic diagnosis and remedies build another scenario with): the model of
    the new config, as build_model gives it, also after ``replace`` (the nonlinear and compensated models are
    replacements of the built one); a Model not made by build_model says it cannot be rebuilt."""
    from dataclasses import replace

    from robustsynth.config import config_with

    m = build_model(make_config())
    cfg = config_with(m.config, {"network.delay.max": 0.25, "synthesis.delay_description": "polytopic"})
    for src in (m, replace(m, vertices=m.vertices[:1])):
        r = src.rebuilt(cfg)
        assert r.config == cfg and r.d_hi == build_model(cfg).d_hi == 3 and len(r.vertices) == 4 * 27
    with pytest.raises(ValueError, match="cannot be rebuilt"):
        replace(m, builder=None).rebuilt(cfg)


def test_triangle_coordinates_reproduce_the_parabola() -> None:
    h = np.linspace(0.02, 0.09, 101)
    w = triangle_coordinates(h, 0.02, 0.09)
    assert np.all(w >= 0) and np.allclose(w.sum(axis=1), 1.0, atol=HULL_TOL)
    pts = w @ triangle(0.02, 0.09)
    assert np.max(np.abs(pts - np.stack([h, h**2 / 2], axis=1))) <= HULL_TOL


def test_corner_weights_reproduce_the_slip_matrix() -> None:
    rng = np.random.default_rng(0)
    mu = np.stack([rng.uniform(0.6, 1.0, 500), rng.uniform(0.4, 1.1, 500)], axis=1)
    corners = slip_corners((0.6, 1.0), (0.4, 1.1))
    lam = corner_weights(mu, (0.6, 1.0), (0.4, 1.1))
    assert np.all(lam >= 0) and np.allclose(lam.sum(axis=1), 1.0)
    M = np.einsum("nm,mij->nij", lam, slip_matrix(corners, 0.45))
    assert np.max(np.abs(M - slip_matrix(mu, 0.45))) <= HULL_TOL


def test_compensated_command_and_required_motor_speeds() -> None:
    mu = np.array([[0.6, 1.0], [0.4, 0.4], [1.0, 1.0]])
    V, R, D = 0.5, 0.09, 0.45
    du = compensated_command(mu, V, D)
    u = np.array([V, 0.0]) + du
    assert np.allclose(np.einsum("nij,nj->ni", slip_matrix(mu, D), u), [V, 0.0])  # the robot moves at u^D
    rho = u @ J_inverse(R, D).T
    assert np.allclose(rho, required_motor_speeds(mu, V, R))  # = H^-1 J^-1 u^D
    assert required_motor_speeds(np.array([0.6, 0.4]), V, R) == pytest.approx([9.259, 13.889], rel=1e-3)


def test_physical_feasibility_names_track_slip_need_and_limit() -> None:
    check_physical_feasibility(make_config())  # 9.26 rad/s <= 12
    with pytest.raises(InfeasibleError, match=r"right track with slip mu = 0.6 .* 9.26 rad/s .* = 9 rad/s"):
        check_physical_feasibility(make_config(**{"robot.max_motor_speed": 9.0}))
    check_physical_feasibility(make_config(**{"robot.max_motor_speed": None, "slip.left.min": 0.1}))  # no limit


def test_equilibrium_is_independent_of_the_delay() -> None:
    m = build_model(make_config(**{"network.delay.max": 0.25}))
    rng = np.random.default_rng(1)
    K = rng.normal(scale=0.3, size=(2, m.n_s))
    K[:, :3] = [[-1.0, 0.0, 0.0], [0.0, -2.0, -1.5]]
    mu = np.array([0.7, 0.95])
    xi = m.equilibrium(K, mu)
    for s in (m.instant_ranges[:, 0], m.instant_ranges[:, 1]):
        A, B = m.robot_exact(s, mu)
        assert np.max(np.abs((A + B @ K) @ xi + m.constant(mu) - xi)) <= 1e-12
    stored = xi[3:].reshape(-1, 2)
    assert np.allclose(stored, compensated_command(mu, m.V, 0.45))  # every stored command is du*


def _one_period(m, e, du_hist, du_new, s_tilde, mu):
    """The nonlinear robot over one period from error e with stored commands du_hist (d_hi, 2)."""
    path = make_path(((0.0, 0.0), (100.0, 0.0)), m.V)
    q = np.array([e[0], e[1], e[2]])
    uD = np.array([m.V, 0.0])
    U = np.concatenate([[uD + du_new], uD + du_hist])[None]  # u_hat_{k-j}, j = 0..d_hi
    q1 = period(q[None], U, s_tilde[None], slip_matrix(mu, 0.45)[None], m.Ts, np.asarray(m.J), np.asarray(m.J_inv), None)
    return frame_error(path, 0, q1[0], m.Ts)


@pytest.mark.parametrize("over", [{}, {"network.delay.max": 0.18}])
def test_model_matches_the_nonlinear_robot_to_second_order(over) -> None:
    """Around the slip-compensated steady state, the lifted slip-aware map predicts the nonlinear
    robot's next error with a residual of order |deviation|^2 (halving it quarters the residual)."""
    m = build_model(make_config(**over))
    rng = np.random.default_rng(2)
    for _ in range(20):
        mu = np.array([rng.uniform(0.6, 1.0), rng.uniform(0.6, 1.0)])
        du_star = compensated_command(mu, m.V, 0.45)
        s_tilde = np.sort(rng.uniform(m.instant_ranges[:, 0], m.instant_ranges[:, 1]))[::-1]
        e_star = np.array([rng.normal(scale=0.05), rng.normal(scale=0.05), 0.0])
        d_e, d_u, d_new = rng.normal(size=3), rng.normal(size=(m.d_hi, 2)), rng.normal(size=2)
        res = []
        for eps in (1e-2, 5e-3, 2.5e-3):
            e = e_star + eps * d_e * [1.0, 1.0, 0.5]
            hist = du_star + eps * d_u * [0.2, 0.5]
            new = du_star + eps * d_new * [0.2, 0.5]
            xi = np.concatenate([e, hist.reshape(-1)])
            A, B = m.robot_exact(s_tilde, mu)
            pred = (A @ xi + B @ new + m.constant(mu))[:3]
            res.append(np.max(np.abs(_one_period(m, e, hist, new, s_tilde, mu) - pred)))
        assert res[0] < 1e-4
        ratios = [res[0] / res[1], res[1] / res[2]]
        assert all(3.0 < r < 5.0 for r in ratios), (res, ratios)  # second order: ratio 4
