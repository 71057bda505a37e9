"""The ICR slip model (slip.model: icr, docs/theory.md §12): per-track traction, a yaw factor and the
ICR's longitudinal offset, so the robot loses yaw rate and slides sideways.  Checked: the config's
refusals name their key; with yaw 1 and no offset it is the tracks model; its exact lifted map agrees
with a matrix exponential of the error with lateral velocity; its vertices contain the exact map on
more than 10 000 samples; the nonlinear robot (and the independent ODE reference) with lateral
velocity agrees with the linearization to second order around the equilibrium."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from robustsynth.config import load_config
from robustsynth.errors import ConfigError
from robustsynth.model import build_model, coverage_check
from robustsynth.model.slip import lateral_row, slip_matrix, twist_matrix
from robustsynth.plants.kinematic import KinematicRobot, arc_step
from robustsynth.plants.path import frame_error, make_path, pose_from_error
from robustsynth.plants.reference import ivp_arc

from ..conftest import ROOT, make_config

EXPM_TOL = 1e-12  # closed form vs matrix exponential: round-off
SAME_TOL = 1e-15  # icr with yaw 1, x_icr 0 vs the tracks model
ODE_TOL = 1e-9  # arc_step vs the numerical integration (DOP853 at rtol 1e-11)
ICR = ROOT / "configs" / "icr-physics.yaml"


def _icr(**over):
    base = {"slip.model": "icr", "slip.yaw": {"min": 0.54, "max": 0.67}, "slip.icr_offset": {"min": 0.0, "max": 0.09}}
    base.update(over)
    return make_config(**base)


@pytest.mark.parametrize("over, key", [
    ({"slip.model": "icr"}, "yaw"),
    ({"slip.yaw": {"min": 0.5, "max": 0.7}}, "yaw: only with slip.model: icr"),
])
def test_the_config_names_what_is_missing_or_misplaced(over, key) -> None:
    with pytest.raises(ConfigError, match=key):
        make_config(**over)


@pytest.mark.parametrize("over, what", [
    ({"synthesis.model": "paper"}, "slip-aware"),
    ({"synthesis.delay_description": "norm-bounded"}, "delay vertices"),
])
def test_icr_refuses_what_it_does_not_support(over, what) -> None:
    with pytest.raises(ConfigError, match=what):
        _icr(**over)


def test_twist_of_the_tracks_model_has_no_lateral_velocity() -> None:
    mu = np.array([[0.7, 0.9], [1.0, 0.6]])
    T = twist_matrix(mu, 0.45)
    assert np.array_equal(T[:, 1], np.zeros((2, 2)))
    assert np.array_equal(T[:, [0, 2]], slip_matrix(mu, 0.45))
    p = np.array([0.7, 0.9, 0.6, 0.05])
    assert np.allclose(slip_matrix(p, 0.45)[1], 0.6 * slip_matrix(p[:2], 0.45)[1], rtol=0, atol=SAME_TOL)
    assert np.allclose(lateral_row(p, 0.45), -0.05 * slip_matrix(p, 0.45)[1], rtol=0, atol=SAME_TOL)


def test_icr_without_yaw_loss_or_offset_is_the_tracks_model() -> None:
    tracks = build_model(make_config())
    icr = build_model(_icr(**{"slip.yaw": {"min": 1.0, "max": 1.0}, "slip.icr_offset": {"min": 0.0, "max": 0.0}}))
    assert len(icr.vertices) == len(tracks.vertices)
    rng = np.random.default_rng(0)
    S = rng.uniform(0.01, 0.08, (50, 1))
    mu = rng.uniform(0.6, 1.0, (50, 2))
    p = np.concatenate([mu, np.ones((50, 1)), np.zeros((50, 1))], axis=1)
    A0, B0 = tracks.exact(S, mu)
    A1, B1 = icr.exact(S, p)
    assert np.max(np.abs(A0 - A1)) <= SAME_TOL and np.max(np.abs(B0 - B1)) <= SAME_TOL
    assert np.max(np.abs(tracks.constant(mu) - icr.constant(p))) <= SAME_TOL
    for v, w in zip(tracks.vertices, icr.vertices):
        assert np.max(np.abs(v.A - w.A)) <= SAME_TOL and np.max(np.abs(v.E - w.E)) <= SAME_TOL


@pytest.fixture(scope="module")
def icr_model():
    return build_model(load_config(ICR))


def test_exact_map_agrees_with_the_matrix_exponential(icr_model) -> None:
    """e' = A_c e + (v_x - V, v_y, omega), twist = T(p) u: integrated piece by piece with expm."""
    m = icr_model
    rng = np.random.default_rng(1)
    uD = np.array([m.V, 0.0])
    for _ in range(20):
        s = rng.uniform(0.01, 0.08)
        p = np.array([rng.uniform(lo, hi) for lo, hi in m.slip_ranges])
        xi, du = rng.normal(size=m.n_s), rng.normal(size=2)
        A, B = m.exact(np.array([s]), p)
        lin = A @ xi + B @ du + m.constant(p)
        T = twist_matrix(p, m.config.robot.track_distance)
        e = xi[:3]
        for t0, t1, u in ((0.0, s, uD + xi[3:5]), (s, m.Ts, uD + du)):
            aug = np.zeros((4, 4))
            aug[:3, :3], aug[:3, 3] = m.A_c, T @ u - np.array([m.V, 0.0, 0.0])
            e = (expm(aug * (t1 - t0)) @ np.r_[e, 1.0])[:3]
        assert np.max(np.abs(lin[:3] - e)) <= EXPM_TOL
        assert np.array_equal(lin[3:], du)


def test_vertices_contain_the_exact_map(icr_model) -> None:
    cov = coverage_check(icr_model, n_sequences=520)
    assert cov["samples"] >= 10_000 and cov["passed"], cov
    assert icr_model.corners.shape == (16, 4) and len(icr_model.vertices) == 16 * 3


def test_the_robot_slides_as_the_linearization_says(icr_model) -> None:
    """One period of the nonlinear robot (exact arcs with lateral velocity) from states near the
    equilibrium of a constant slip: the difference from the lifted map quarters when the deviation
    halves (second order: the lateral term's sign and size are right)."""
    from robustsynth.synthesis import synthesize

    m = icr_model
    K = synthesize(m).K
    p = np.array([1.0, 0.96, 0.55, 0.08])
    xs = m.equilibrium(K, p)
    rng = np.random.default_rng(2)
    direction = rng.normal(size=m.n_s)
    S = np.array([0.05])
    A, B = m.exact(S, p)
    robot = KinematicRobot.of(m)
    path = make_path(((0.0, 0.0), (20.0, 0.0)), m.V)
    uD = np.array([m.V, 0.0])
    res = []
    for scale in (4e-3, 2e-3, 1e-3):
        x = xs + scale * direction
        d = K @ x
        q0 = pose_from_error(path, x[None, :3])
        U = robot.send(robot.memory(x[None, 3:5][:, None, :], 1), (uD + d)[None])
        e1 = frame_error(path, 0, robot.period(q0, U, S[None], p[None]), m.Ts)[0]
        res.append(np.max(np.abs(e1 - (A @ x + B @ d + m.constant(p))[:3])))
    assert res[1] / res[0] < 0.3 and res[2] / res[1] < 0.3, res


def test_arc_step_with_lateral_velocity_matches_the_ode() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.normal(size=3)
        v, w, vy, h = rng.uniform(0, 1), rng.uniform(-2, 2), rng.uniform(-0.1, 0.1), rng.uniform(0.0, 0.1)
        assert np.max(np.abs(arc_step(q, v, w, h, vy) - ivp_arc(q, v, w, h, vy=vy))) <= ODE_TOL


def test_the_rate_bound_is_the_tracks_and_the_other_parameters_jump() -> None:
    """slip.max_rate bounds mu_r, mu_l only: the adversary's next slips reach every yaw and x_icr corner,
    and a rate wider than the tracks' range bounds nothing (whatever the other ranges are)."""
    from robustsynth.scenarios import slip_candidates

    m = build_model(_icr(**{"slip.max_rate": 0.1, "slip.right": {"min": 0.9, "max": 1.0},
                            "slip.left": {"min": 0.9, "max": 1.0}}))
    nxt = slip_candidates(m, m.corners[:1])[0]
    assert set(np.round(nxt[:, 2], 12)) == {0.54, 0.67} and set(np.round(nxt[:, 3], 12)) == {0.0, 0.09}
    assert np.max(np.abs(nxt[:, :2] - m.corners[0, :2])) <= 0.1 * m.Ts + 1e-12
    wide = build_model(_icr(**{"slip.max_rate": 2.0, "slip.right": {"min": 0.9, "max": 1.0},
                               "slip.left": {"min": 0.9, "max": 1.0}}))
    assert m.rate_bounded and not wide.rate_bounded  # 0.2 per period covers [0.9, 1]; yaw's 0.13 does not count


def test_check_log_checks_every_icr_parameter_even_without_periods() -> None:
    """check-log on an icr config has a row per slip parameter (tests/test_identification.py checks them on
    logs); with no usable period each has no samples and nothing outside."""
    from robustsynth.identification import check_log

    rows = {r["assumption"]: r for r in check_log([], load_config(ICR), pose_noise=(1e-4, 1e-4))}
    for key in ("right", "left", "yaw", "icr_offset"):
        assert rows[f"slip.{key}"]["samples"] == 0 and rows[f"slip.{key}"]["outside"] == 0
