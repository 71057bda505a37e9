"""Delay-dependent Lyapunov matrices (one per slip corner and delay vertex) and path-dependent ones
(and the previous period's delay vertex): the conditions' layout, the certificate (numpy re-check,
tampering), each class containing the previous one, and the piecewise-quadratic V = max over the
current delay vertex decreasing along exact lifted trajectories."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.errors import InputError
from robustsynth.model import build_model
from robustsynth.synthesis import synthesize
from robustsynth.certificate import Lyapunov, check_certificate, lyapunov_of
from robustsynth.scenarios import random_delays, slip_vertices
from robustsynth.verification.lifted import closed_loop_run

from ..conftest import make_config
from .conftest import invariance_at

ALPHA = 0.22  # near the best alpha of the default robot for both kinds
CLASS_REL = 1e-3  # the delay-dependent optimum may exceed the slip-dependent one by solver accuracy only
DECREASE_TOL = 1e-9  # V(xi+) - (1-alpha) V(xi) - sum beta, relative to max(V, level): round-off only


def _solve_at(model, lyapunov: str, alpha: float = ALPHA):
    """One invariance solve at a fixed alpha, taken as synthesis takes it (``invariance_at``): the
    product's solver settings and its acceptance rule.  A point the solver calls 'optimal' or
    'optimal_inaccurate' is accepted only when every LMI, rebuilt in numpy from the values, passes
    the certificate check; the status string alone decides nothing (Clarabel 0.11 reports
    'optimal_inaccurate' for the path-dependent LMIs at the product's 1e-9 tolerances, on some
    machines also at its defaults, with a certificate that passes).  Clarabel only, no fallback:
    the newest Clarabel must certify these classes itself."""
    lp, K, cert, chk = invariance_at(model, lyapunov, alpha)
    assert chk.passed  # what "ok" means: the numpy re-check of every vertex condition
    return K, cert, float(lp.problem.value)


@pytest.fixture(scope="module")
def model():
    return build_model(make_config(**{"synthesis.lyapunov": "delay-dependent"}))


@pytest.fixture(scope="module")
def solved(model):
    return _solve_at(model, "delay-dependent")


def test_conditions_layout(model):
    n_c, n_d = model.corners.shape[0], model.delay_vertex_count
    assert (n_c, n_d) == (4, 3)
    assert model.lyapunov_count("delay-dependent") == n_c * n_d
    table = model.lyapunov_conditions("delay-dependent", None)
    for i, (v, conds) in enumerate(zip(model.vertices, table)):
        # left: the vertex's own (corner, delay vertex); right: every next corner (slip may jump) x
        # every next delay vertex, each once
        assert {j for j, _, _ in conds} == {int(v.corner) * n_d + i % n_d}
        rights = sorted(n for _, right, _ in conds for w, n in right if w == 1.0)
        assert rights == list(range(n_c * n_d))
    # the slip-dependent layout is the special case with one delay vertex
    sd = model.lyapunov_conditions("slip-dependent", None)
    assert all({j for j, _, _ in c} == {int(v.corner)} for v, c in zip(model.vertices, sd))


def test_certificate_rechecked_and_tampering_fails(model, solved):
    K, cert, _ = solved
    chk = check_certificate(model, K, cert)
    assert chk.passed, chk.reason
    assert "144 vertex conditions" in " ".join(c["name"] for c in chk.checks)
    bad = dict(cert, S=[0.5 * S if j == 4 else S for j, S in enumerate(cert["S"])])
    bad["P"] = [np.linalg.inv(S) for S in bad["S"]]
    assert not check_certificate(model, K, bad).passed
    short = dict(cert, S=cert["S"][:4], P=cert["P"][:4])
    res = check_certificate(model, K, short)
    assert not res.passed and "one per slip corner and delay vertex (12)" in res.reason


def test_contains_the_slip_dependent_class(model, solved):
    """S_(m, d) = S_m for every d is a delay-dependent point: at the same alpha the optimum is no worse."""
    _, _, dd = solved
    _, _, sd = _solve_at(model, "slip-dependent")
    assert dd <= sd * (1 + CLASS_REL)


def test_piecewise_quadratic_V_decreases_without_the_delays(model, solved):
    """The checked certificate's V = max_d ... obeys V(xi+) <= (1-alpha) V(xi) + sum beta on exact
    lifted runs (random and alternating delays, slip jumping between corners), computed from the
    states and slips only."""
    K, cert, _ = solved
    lyap = lyapunov_of(model, cert)
    level = float(np.sum(cert["beta"]) / cert["alpha"])
    rng = np.random.default_rng(7)
    N, steps = 200, 60
    corners = slip_vertices(model)
    n_d = model.delay_vertex_count
    single = [Lyapunov(model, lyap.S[d::n_d], lyap.P[d::n_d]) for d in range(n_d)]  # one delay vertex's quadratic
    worst, worst_single = -np.inf, np.full(n_d, -np.inf)

    def excess(V):
        ex = V[:, 1:] - (1 - cert["alpha"]) * V[:, :-1] - np.sum(cert["beta"])
        return float(np.max(ex / np.maximum(V[:, :-1], level)))

    for taus in (random_delays(model, rng, N, steps), model.network.pattern("alternating", (N, steps + model.d_hi))):
        mu = corners[rng.integers(0, corners.shape[0], size=(N, steps + 1))]
        xi0 = rng.normal(scale=0.05, size=(N, model.n_s))
        xi = closed_loop_run(model, K, taus, mu[:, :steps], xi0)
        worst = max(worst, excess(lyap.V(xi, mu)))
        worst_single = np.maximum(worst_single, [excess(s.V(xi, mu)) for s in single])
    assert worst <= DECREASE_TOL
    # the check can fail: no single delay vertex's quadratic decreases on these runs (the max over
    # the delay vertices is what the proof needs)
    assert np.all(worst_single > 0)


def test_refused_without_delay_vertices():
    # d_hi = 3: 'auto' picks the norm-bounded embedding, one delay vertex per corner
    m = build_model(make_config(**{"synthesis.lyapunov": "delay-dependent", "network.delay.max": 0.25}))
    with pytest.raises(InputError, match="delay-dependent needs 2 to 9 delay vertices"):
        synthesize(m)
    with pytest.raises(ValueError, match="delay-dependent needs delay vertices"):
        make_config(**{"synthesis.lyapunov": "delay-dependent", "synthesis.delay_description": "norm-bounded"})


# ----------------------------------------------------------------------------- path-dependent


@pytest.fixture(scope="module")
def path_solved(model):
    pm = build_model(make_config(**{"synthesis.lyapunov": "path-dependent"}))
    return pm, _solve_at(pm, "path-dependent")


def test_path_conditions_layout(model):
    n_c, n_d = 4, model.delay_vertex_count
    table = model.lyapunov_conditions("path-dependent", None)
    assert model.lyapunov_count("path-dependent") == n_c * n_d * n_d
    for i, (v, conds) in enumerate(zip(model.vertices, table)):
        m, b = int(v.corner), i % n_d
        # left: S_(m, a, b) for every previous delay vertex a; right: S_(n, b, c) for every n, c
        assert {j for j, _, _ in conds} == {(m * n_d + a) * n_d + b for a in range(n_d)}
        rights = {n for _, right, _ in conds for w, n in right}
        assert rights == {(n * n_d + b) * n_d + c for n in range(n_c) for c in range(n_d)}


def test_path_certificate_and_V_with_the_previous_delay(path_solved, solved):
    """Re-checked in numpy, no worse than the delay-dependent class at the same alpha, and
    V(xi, mu, prev) = max_b ... decreases on exact lifted runs given the previous period's delay
    weights -- which it needs: with the weights of a wrong previous delay it does not."""
    pm, (K, cert, value) = path_solved
    chk = check_certificate(pm, K, cert)
    assert chk.passed, chk.reason
    _, _, dd = solved  # the delay-dependent optimum at the same alpha
    assert value <= dd * (1 + CLASS_REL)
    lyap = lyapunov_of(pm, cert)
    assert lyap.path and not lyap.any_next_slip
    level = float(np.sum(cert["beta"]) / cert["alpha"])
    rng = np.random.default_rng(11)
    N, steps = 200, 60
    corners = slip_vertices(pm)
    worst, worst_wrong = -np.inf, -np.inf
    for taus in (random_delays(pm, rng, N, steps), pm.network.pattern("alternating", (N, steps + pm.d_hi))):
        mu = corners[rng.integers(0, corners.shape[0], size=(N, steps + 1))]
        xi = closed_loop_run(pm, K, taus, mu[:, :steps], rng.normal(scale=0.05, size=(N, pm.n_s)))
        dw = pm.delay_weights(pm.s_tilde(taus))  # (N, steps, n_d): period k's weights
        prev = np.concatenate([np.full((N, 1, dw.shape[-1]), np.nan), dw], axis=1)
        wrong = np.concatenate([np.full((N, 1, dw.shape[-1]), np.nan), dw[..., ::-1]], axis=1)
        for p, sink in ((prev, "right"), (wrong, "wrong")):
            V = lyap.V(xi, mu, p)
            ex = V[:, 1:] - (1 - cert["alpha"]) * V[:, :-1] - np.sum(cert["beta"])
            val = float(np.max(ex / np.maximum(V[:, :-1], level)))
            if sink == "right":
                worst = max(worst, val)
            else:
                worst_wrong = max(worst_wrong, val)
    assert worst <= DECREASE_TOL
    assert worst_wrong > 0


def test_path_dependent_adversary_replays(path_solved):
    """The nonlinear adversary evaluates a path-dependent V with the period's delay weights, as verify
    does: the worst history, replayed by the simulator, reaches the V the search reported."""
    from robustsynth.robot_verification.simulate import adversarial_nonlinear

    from ..robot_verification.test_simulate import REPLAY_TOL, replay_worst

    pm, (K, cert, _) = path_solved
    lyap = lyapunov_of(pm, cert)
    corners = slip_vertices(pm)
    adv = adversarial_nonlinear(pm, K, lyap.V, corners, 40, width=4, with_delay=True)
    h = adv["worst"]["V"]
    assert h["value"] == adv["max_V"]
    assert abs(replay_worst(pm, K, lyap, corners, h)["V"] - h["value"]) <= REPLAY_TOL * max(1.0, h["value"])
