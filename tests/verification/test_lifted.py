"""The lifted linear model in closed loop (verification/lifted.py) along arcs: the kinematics linearized about a
turning reference, run period after period, against the straight runs and against what a turning certificate
covers."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robustsynth.certificate import check_certificate, lyapunov_of
from robustsynth.scenarios import random_delays, slip_vertices
from robustsynth.verification.lifted import arc_closed_loop_run, closed_loop_run, random_yaw_rates, yaw_windows

from ..conftest import committed_gain

ROUND = 1e-12  # two implementations of the same linear map: round-off only


@pytest.fixture(scope="module")
def turning():
    m, K, cert = committed_gain("turns")
    level = float(check_certificate(m, K, cert).figures["ellipsoid_level"])
    return m, K, lyapunov_of(m, cert), level


def _runs(m, lyap, level, rng, N=100, steps=80):
    taus = random_delays(m, rng, N, steps)
    corners = slip_vertices(m)
    mu = corners[rng.integers(0, len(corners), (N, steps + 1))]
    z = rng.normal(size=(N, m.n_s))
    return taus, mu, z * np.sqrt(level / lyap.V(z, mu[:, 0]))[:, None]


def test_along_a_reference_that_does_not_turn_the_arc_runs_are_the_straight_ones(turning) -> None:
    m, K, lyap, level = turning
    taus, mu, xi0 = _runs(m, lyap, level, np.random.default_rng(0))
    steps = taus.shape[1] - m.d_hi
    a = closed_loop_run(m, K, taus, mu[:, :steps], xi0)
    b = arc_closed_loop_run(m, K, taus, mu[:, :steps], np.zeros((xi0.shape[0], steps + m.d_hi)), xi0)
    assert np.max(np.abs(a - b)) <= ROUND
    # with integral action and a longer lifting (the integrators, the stored commands' shift), any gain
    from robustsynth.model import build_model

    from ..conftest import make_config

    mi = build_model(make_config(**{"synthesis.integral_action": True, "synthesis.delay_description": "polytopic",
                                    "network.delay.min": 0.12, "network.delay.max": 0.22})).with_turns(0.5)
    rng = np.random.default_rng(6)
    Ki, x0 = 0.2 * rng.normal(size=(2, mi.n_s)), 0.02 * rng.normal(size=(4, mi.n_s))
    ti = random_delays(mi, rng, 4, 10)
    mui = np.full((4, 10, 2), 0.8)
    a = closed_loop_run(mi, Ki, ti, mui, x0)
    b = arc_closed_loop_run(mi, Ki, ti, mui, np.zeros((4, 10 + mi.d_hi)), x0)
    assert mi.n_z == 2 and np.max(np.abs(a - b)) <= ROUND * max(1.0, np.max(np.abs(a)))


def test_each_period_gets_the_yaw_rates_its_commands_carry() -> None:
    """On a lifting of three commands (delays over two periods) the arc runs hand period k the yaw rates
    (w_k, w_{k-1}, w_{k-2}): three periods of arc_closed_loop_run against linearized_arc_period called with them
    spelled out, and yaw_windows (which the verify's decrease terms use too) against the same."""
    from robustsynth.model import build_model
    from robustsynth.model.arcs import linearized_arc_period

    from ..conftest import make_config

    m = build_model(make_config(**{"network.delay.min": 0.12, "network.delay.max": 0.22,
                                   "synthesis.delay_description": "polytopic"})).with_turns(0.5)
    assert m.d_hi == 3
    rng = np.random.default_rng(3)
    N, steps = 5, 3
    K = 0.1 * rng.normal(size=(2, m.n_s))
    taus = random_delays(m, rng, N, steps)
    mu = np.full((N, steps, 2), 0.9)
    w = rng.uniform(-0.5, 0.5, (N, steps + m.d_hi))  # w_{-3}, ..., w_{2}
    xi0 = 0.01 * rng.normal(size=(N, m.n_s))
    got = arc_closed_loop_run(m, K, taus, mu, w, xi0)
    S = m.s_tilde(taus)
    x = xi0
    for k in range(steps):
        spelled = np.stack([w[:, k + 3], w[:, k + 2], w[:, k + 1], w[:, k]], axis=1)  # w_k, w_{k-1}, w_{k-2}, w_{k-3}
        assert np.array_equal(yaw_windows(w, m.d_hi)[:, k], spelled)
        du = x @ K.T
        e = linearized_arc_period(m, x, du, S[:, k], mu[:, k], spelled)
        x = np.concatenate([e, du, x[:, m.n_e : m.n_e + 2 * (m.d_hi - 1)]], axis=1)
        assert np.max(np.abs(got[:, k + 1] - x)) <= ROUND


def test_the_random_yaw_rates_are_the_ones_the_certificate_covers(turning) -> None:
    m = turning[0]
    t = m.turns
    w = random_yaw_rates(m, np.random.default_rng(1), 6, 60)
    assert np.all(np.abs(w) <= t.max_yaw_rate * (1 + 1e-12)) and np.all(np.abs(np.diff(w, axis=1)) <= t.max_step * (1 + 1e-12))
    assert np.all(w[:, : m.d_hi] == 0.0)  # the commands in memory at the start carry no feedforward
    odd = w[1::2]  # from one extreme to the other
    assert np.all(np.max(odd, axis=1) == t.max_yaw_rate) and np.all(np.min(odd, axis=1) == -t.max_yaw_rate)


def test_the_turning_certificate_holds_along_arcs_and_not_along_sharper_ones(turning) -> None:
    """From the boundary of the certified set, along the arcs the certificate covers, the linearized model stays
    in the set (configs/turns.yaml's gain: 0.81 here, 0.83 in verify); along arcs 10 times as sharp (0.5 m) it leaves
    it: the arcs' terms matter to the check."""
    m, K, lyap, level = turning
    rng = np.random.default_rng(2)
    taus, mu, xi0 = _runs(m, lyap, level, rng)
    steps = taus.shape[1] - m.d_hi
    out = {}
    for scale in (1.0, 10.0):
        ms = replace(m, turns=replace(m.turns, max_yaw_rate=scale * m.turns.max_yaw_rate, max_step=scale * m.turns.max_step))
        xi = arc_closed_loop_run(ms, K, taus, mu[:, :steps], random_yaw_rates(ms, rng, xi0.shape[0], steps), xi0)
        out[scale] = float(np.max(lyap.V_max(xi[:, 1:]))) / level
    assert out[1.0] <= 1.0 < out[10.0]


def test_the_greedy_search_along_arcs_replays_and_picks_admissible_yaw_rates(turning) -> None:
    """greedy_worst_case(yaw=True): the history it picks (delays, slips, yaw rates) replays through
    arc_closed_loop_run to the same states (its candidates are the arc map evaluated on a tensor of choices),
    the yaw rates are w_{k-1} or a step of max_step either way within +-max_yaw_rate from 0, and it pushes V
    higher than the random arc runs from the same boundary starts."""
    from robustsynth.verification.lifted import greedy_worst_case

    m, K, lyap, level = turning
    t = m.turns
    rng = np.random.default_rng(4)
    taus, mu, xi0 = _runs(m, lyap, level, rng, N=20, steps=40)
    xg, tg, mug, wg = greedy_worst_case(m, K, lyap.V, xi0, 40, mu0=mu[:, 0], yaw=True)
    assert np.all(wg[:, : m.d_hi] == 0.0) and np.all(np.abs(wg) <= t.max_yaw_rate * (1 + 1e-12))
    assert np.all(np.abs(np.diff(wg, axis=1)) <= t.max_step * (1 + 1e-12))
    assert np.max(np.abs(wg)) == t.max_yaw_rate  # it turns
    replay = arc_closed_loop_run(m, K, tg, mug, wg, xi0)
    assert np.max(np.abs(replay - xg)) <= ROUND
    rand = arc_closed_loop_run(m, K, taus, mu[:, :40], random_yaw_rates(m, rng, 20, 40), xi0)
    assert np.max(lyap.V_max(xg[:, 1:])) > np.max(lyap.V_max(rand[:, 1:]))


@pytest.mark.parametrize("over", [{"network.delay.min": 0.12, "network.delay.max": 0.22},
                                  {"synthesis.integral_action": True}])
def test_the_greedy_search_along_arcs_replays_on_longer_liftings_and_with_integrators(over) -> None:
    """The same replay on a lifting of four commands (d_hi = 3: the yaw window's order and the stored commands'
    shift matter) and with integral action (the integrators' update), with an arbitrary gain (the review of
    37608b7: on turns, d_hi = 1 and no integrators, a reversed window or a wrong shift passed)."""
    from robustsynth.model import build_model
    from robustsynth.verification.lifted import greedy_worst_case

    from ..conftest import make_config

    m = build_model(make_config(**{"synthesis.delay_description": "polytopic", **over})).with_turns(0.5)
    rng = np.random.default_rng(5)
    K = 0.2 * rng.normal(size=(2, m.n_s))
    xi0 = 0.02 * rng.normal(size=(6, m.n_s))
    V = lambda x, mu, prev=None: np.sum(x * x, axis=-1)  # noqa: E731  any V: the replay is what is checked
    xg, tg, mug, wg = greedy_worst_case(m, K, V, xi0, 12, yaw=True)
    assert np.max(np.abs(wg)) > 0.0
    assert np.max(np.abs(arc_closed_loop_run(m, K, tg, mug, wg, xi0) - xg)) <= ROUND * max(1.0, np.max(np.abs(xg)))


def test_the_homogeneous_arc_map_is_the_difference_of_two_runs_and_scales() -> None:
    """linearized_arc_period(homogeneous=True) is the map less its value at 0 (the same delays, slip and yaw
    rates), computed without that subtraction: it is linear down to states of 1e-30 (subtracting would leave
    round-off of the nominal commands' size there: a first version gave V ratios of 60 on decayed runs)."""
    from robustsynth.model import build_model
    from robustsynth.model.arcs import linearized_arc_period

    from ..conftest import make_config

    m = build_model(make_config(**{"synthesis.delay_description": "polytopic", "network.delay.min": 0.12,
                                   "network.delay.max": 0.22})).with_turns(0.5)
    rng = np.random.default_rng(7)
    N = 50
    x = 0.05 * rng.normal(size=(N, m.n_s))
    du = 0.1 * rng.normal(size=(N, 2))
    S = m.s_tilde(random_delays(m, rng, N, 1))[:, 0]
    mu = rng.uniform(0.6, 1.0, (N, 2))
    w = rng.uniform(-0.5, 0.5, (N, m.d_hi + 1))
    hom = linearized_arc_period(m, x, du, S, mu, w, homogeneous=True)
    diff = linearized_arc_period(m, x, du, S, mu, w) - linearized_arc_period(m, 0 * x, 0 * du, S, mu, w)
    assert np.max(np.abs(hom - diff)) <= ROUND
    tiny = linearized_arc_period(m, 1e-30 * x, 1e-30 * du, S, mu, w, homogeneous=True)
    assert np.max(np.abs(tiny * 1e30 - hom)) <= ROUND * np.max(np.abs(hom))


def test_a_stability_certificate_for_turns_holds_along_arcs() -> None:
    """A stability certificate of a turning model (bisection coarse, for time): the homogeneous part of the
    arc map, which depends on the yaw rates, decreases V by its r^2 as the straight one does (verify's check)."""
    from robustsynth.model import build_model
    from robustsynth.synthesis import synthesize
    from robustsynth.verification.lifted_checks import _lifted

    from ..conftest import make_config

    m = build_model(make_config(**{"synthesis.objective": "stability", "synthesis.delay_description": "polytopic",
                                   "slip.right.min": 0.9, "slip.left.min": 0.9,
                                   "synthesis.bisection_tol": 0.09})).with_turns(0.25)
    r = synthesize(m)
    checks, summary, traces = _lifted(m, r.K, r.check, {"K": r.K.tolist(), "certificate": r.certificate})
    r2 = r.check.figures["decay_rate"] ** 2
    assert "arcs/homogeneous" in traces and summary["arcs"]["max_V_ratio"] <= r2 * (1 + 1e-9)
    assert checks[0]["passed"] and "along arcs" in checks[0]["detail"]
