"""The plant interface the Monte Carlo and the adversary drive: the command memory, sending, and one
period of the robot; a batch of candidates (any leading shape) moves exactly as each one alone."""

from __future__ import annotations

import numpy as np

from robustsynth.model import build_model
from robustsynth.plants.kinematic import KinematicRobot, arc_step

from ..conftest import make_config

BATCH_TOL = 1e-14  # round-off only: matrix products on other shapes may take other BLAS kernels


def _robot(**over):
    m = build_model(make_config(**over))
    return m, KinematicRobot.of(m)


def test_memory_and_send_shift_the_commands_in_flight() -> None:
    m, robot = _robot()
    rng = np.random.default_rng(1)
    du0 = rng.normal(size=(3, m.d_hi, 2))
    U = robot.memory(du0, 3)
    uD = np.array([m.V, 0.0])
    assert U.shape == (3, m.d_hi + 1, 2)
    assert np.array_equal(U[:, : m.d_hi], uD + du0) and np.array_equal(U[:, m.d_hi], uD + du0[:, -1])
    assert np.array_equal(robot.memory(None, 2), np.tile(uD, (2, m.d_hi + 1, 1)))
    new = rng.normal(size=(3, 2))
    U2 = robot.send(U, new)
    assert np.array_equal(U2[:, 0], new) and np.array_equal(U2[:, 1:], U[:, :-1])
    assert not np.shares_memory(U2, U)


def test_a_branched_batch_moves_as_each_candidate_alone() -> None:
    m, robot = _robot(**{"network.delay.max": 0.15})  # d_hi = 2: two switching instants
    rng = np.random.default_rng(2)
    P, C = 3, 4
    q = rng.normal(size=(P, 3))
    U = robot.memory(rng.normal(scale=0.2, size=(P, m.d_hi, 2)), P)
    S = np.sort(rng.uniform(0, m.Ts, size=(P, C, m.d_hi)), axis=-1)[..., ::-1]
    mu = rng.uniform(0.6, 1.0, size=(P, C, 2))
    batch = robot.period(np.broadcast_to(q[:, None], (P, C, 3)), np.broadcast_to(U[:, None], (P, C) + U.shape[1:]), S, mu)
    for p in range(P):
        for c in range(C):
            one = robot.period(q[p], U[p], S[p, c], mu[p, c])
            assert np.max(np.abs(batch[p, c] - one)) <= BATCH_TOL


def test_no_slip_no_delay_no_saturation_is_one_arc() -> None:
    """With mu = 1 every command acts as sent; with all switching instants at 0 the newest command
    acts for the whole period: one exact arc."""
    m, robot = _robot(**{"robot.max_motor_speed": None})
    q = np.array([0.3, -0.2, 0.4])
    U = robot.send(robot.memory(None, 1), np.array([[0.45, 0.3]]))[0]
    out = robot.period(q, U, np.zeros(m.d_hi), np.ones(2))
    assert np.allclose(out, arc_step(q, 0.45, 0.3, m.Ts), rtol=0, atol=1e-15)


def test_sinc_takes_each_formula_where_it_holds_on_any_shape() -> None:
    """_sinc is sin(x)/x from |x| = 1e-4 on and the series 1 - x^2/6 below (exact to rounding there), bit for bit,
    on arrays that are all small (a straight course), all large (an arc), mixed, 0-d and broadcast views."""
    from robustsynth.plants.kinematic import _sinc

    rng = np.random.default_rng(5)
    mixed = np.concatenate([rng.uniform(-2e-4, 2e-4, 500), rng.uniform(-3.0, 3.0, 500), [0.0, 1e-4, -1e-4]])
    for x in (np.zeros((4, 3)), rng.uniform(-9e-5, 9e-5, (7, 5)), rng.uniform(0.1, 3.0, (6, 2)), mixed,
              np.array(0.0), np.array(0.7), np.broadcast_to(np.array([0.2, 0.0, 5e-5]), (4, 3))):
        small = np.abs(x) < 1e-4
        want = np.where(small, 1.0 - x * x / 6.0, np.sin(np.where(small, 1.0, x)) / np.where(small, 1.0, x))
        got = _sinc(x)
        assert isinstance(got, np.ndarray) and got.shape == np.shape(x)
        assert np.array_equal(got, want)
    xs = rng.uniform(-1e-3, 1e-3, 2000)  # the two formulas meet: the series is sin(x)/x to rounding below 1e-3
    assert np.max(np.abs(_sinc(xs) - np.sin(xs) / xs)) <= 4 * np.finfo(float).eps
