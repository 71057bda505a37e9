"""A certificate for a reference that turns along arcs (Model.with_turns, model/arcs.py, docs/theory.md
§10): synthesized, re-checked in numpy with the turning vertices it names, its motor bound holding the
turning feedforward, and judged against the robot closing its loop over the network on arcs."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.certificate import check_certificate
from robustsynth.law import wrap_angle
from robustsynth.model import build_model
from robustsynth.model.arcs import FEEDFORWARD
from robustsynth.plants.kinematic import KinematicRobot
from robustsynth.scenarios import random_delays, track_changes
from robustsynth.synthesis import synthesize

from ..conftest import committed_gain, make_config

W_BAR = 0.25  # [rad/s]: arcs of radius V^D / W_BAR = 2 m
RUNS, PERIODS = 300, 160


@pytest.fixture(scope="module")
def models():
    """The slip box [0.8, 1] (nonlinear-proof's): the straight-segment model and its turning one."""
    base = build_model(make_config(**{"slip.right.min": 0.8, "slip.left.min": 0.8,
                                      "synthesis.delay_description": "polytopic"}))
    return base, base.with_turns(W_BAR)


@pytest.fixture(scope="module")
def designs(models):
    """:func:`models` and a certificate for each (a short alpha scan: the test needs certificates, not the best
    ones; the turning one, with 22 channels per vertex, the shortest)."""
    base, turning = models
    return base, turning, synthesize(base, alpha_points=5), synthesize(turning, alpha_points=3)


def _schedule(periods: int) -> np.ndarray:
    """w_k: straight, a left arc, straight, a right arc, ... (20 periods each; steps of W_BAR)."""
    pattern = [0.0] * 20 + [W_BAR] * 20 + [0.0] * 20 + [-W_BAR] * 20
    return np.array((pattern * (periods // len(pattern) + 1))[:periods])


def _closed_loop(model, K, P, level, w, seed=0):
    """The exact robot (arcs, slip at a random corner per run, random delays) with the law measuring in
    the frame of a reference that moves at V^D and turns at w_k, sending (V^D, w_k) + K xi_k; max V/level
    over the sampling instants per run, and the largest |e_y|."""
    rng = np.random.default_rng(seed)
    n_u, d_hi, V, Ts = model.n_u, model.d_hi, model.V, model.Ts
    (rl, rh), (ll, lh) = model.slip_ranges
    mu = np.stack([rng.choice([rl, rh], RUNS), rng.choice([ll, lh], RUNS)], axis=1)
    S = model.s_tilde(random_delays(model, rng, RUNS, len(w)))
    robot = KinematicRobot.of(model)
    U = robot.memory(None, RUNS)
    q = np.zeros((RUNS, 3))
    ref = np.zeros(3)  # the reference's pose (x, y, heading)
    past = np.zeros((RUNS, d_hi * n_u))
    worst, ey = np.zeros(RUNS), 0.0
    for k, wk in enumerate(w):
        c, s = np.cos(ref[2]), np.sin(ref[2])
        dx, dy = q[:, 0] - ref[0], q[:, 1] - ref[1]
        e = np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(q[:, 2] - ref[2])], axis=1)
        xi = np.concatenate([e, past], axis=1)
        worst = np.maximum(worst, np.einsum("ni,ij,nj->n", xi, P, xi) / level)
        ey = max(ey, float(np.max(np.abs(e[:, 1]))))
        du = xi @ K.T
        U = robot.send(U, np.array([V, 0.0]) + du + wk * FEEDFORWARD)
        past = np.concatenate([du, past[:, : (d_hi - 1) * n_u]], axis=1)
        q = robot.period(q, U, S[:, k], mu)
        # the reference's arc over the period, exactly
        phi = wk * Ts
        chord = V * Ts * (np.sinc(phi / (2.0 * np.pi)))
        ref = ref + np.array([chord * np.cos(ref[2] + phi / 2.0), chord * np.sin(ref[2] + phi / 2.0), phi])
    return worst, ey


@pytest.mark.slow
def test_the_turning_certificate_is_rechecked_with_the_turns_it_names(designs) -> None:
    base, turning, _, r = designs
    assert r.check.passed, r.check.reason
    assert r.certificate["turns"] == {"max_yaw_rate": W_BAR, "max_step": W_BAR}
    chk = check_certificate(turning, r.K, r.certificate)
    assert chk.passed, chk.reason
    assert chk.figures["ultimate_bound"] == r.check.figures["ultimate_bound"]
    # a model whose path jumps at its waypoints (no turns) is not what the gain is certified for
    refused = check_certificate(base, r.K, r.certificate)
    assert not refused.passed and "reference.turn_radius is null" in refused.reason
    # the same matrices do not prove faster turns, nor straight segments without naming them
    faster = dict(r.certificate, turns={"max_yaw_rate": 2 * W_BAR, "max_step": 2 * W_BAR})
    assert not check_certificate(turning, r.K, faster).passed
    # a model asking for faster turns (a smaller turn radius) than certified is refused, also when the
    # certificate names slower ones; one asking for slower turns is covered by the certificate's own
    for asks in (2 * W_BAR, 1.01 * W_BAR):
        refused = check_certificate(base.with_turns(asks), r.K, r.certificate)
        assert not refused.passed and "smaller than the one the gain was certified for" in refused.reason
    slower = dict(r.certificate, turns={"max_yaw_rate": 1e-9, "max_step": 1e-9})
    assert not check_certificate(turning, r.K, slower).passed
    assert check_certificate(base.with_turns(W_BAR / 2), r.K, r.certificate).passed
    straight = {k: v for k, v in r.certificate.items() if k != "turns"}
    assert not check_certificate(turning, r.K, straight).passed
    # between samples: bounds that cover the sampled ones (on the exact arcs); slip: what it assumes
    cont = chk.figures["ultimate_bound_between_samples"]
    assert all(cont[k] > chk.figures["ultimate_bound"][k] for k in ("e_x", "e_y"))
    assert cont["e_theta"] == chk.figures["heading_within_period"] >= chk.figures["ultimate_bound"]["e_theta"] * (1 - 1e-9)
    # slip changing within a period: covered by the channels the certificate names (docs/theory.md §10)
    assert r.certificate["within_period_channels"] is True and turning.covering_vertices
    assert chk.figures["slip_within_period"] == "covered"
    constant = {k: v for k, v in r.certificate.items() if k != "within_period_channels"}
    refused = check_certificate(turning, r.K, constant)  # its multipliers are for the covering channels
    n, m = turning.vertices[0].n_q, turning.with_turns(W_BAR, within_period=False).vertices[0].n_q
    assert n > m and not refused.passed and f"multipliers.M[0] has {n * n} entries, expected {m} x {m}" in refused.reason


def test_the_motor_bound_holds_the_turning_feedforward(designs) -> None:
    base, turning, _, r = designs
    cfg = base.config
    ff = cfg.reference.speed / cfg.robot.gear_radius + W_BAR * cfg.robot.track_distance / (2 * cfg.robot.gear_radius)
    assert turning.feedforward_motor_speed == pytest.approx(ff, rel=1e-15)
    motor = r.check.figures["motor_speed_bound"]
    assert ff < motor <= cfg.robot.max_motor_speed


def test_exit_3_of_a_turning_model_names_the_turn_radius_as_a_remedy() -> None:
    """Gentler arcs lower the feedforward and the arc channels: the synthesis's exit-3 messages offer a wider
    reference.turn_radius for a turning model, with the model's own radius V^D / max_yaw_rate (a model turned by
    Model.with_turns has none in its config: the review of 2840f4e found the message crashing there), and only
    for one.  Reached here through the motor check before any solve; from a config, motors too weak for the
    arcs' feedforward are refused earlier still, by the physical check, which names the radius too."""
    from robustsynth.errors import InfeasibleError
    from robustsynth.synthesis.runner import _wider_turns

    straight = build_model(make_config(**{"synthesis.delay_description": "polytopic", "robot.max_motor_speed": 7.0,
                                          "slip.right.min": 0.9, "slip.left.min": 0.9}))
    assert straight.feedforward_motor_speed < 7.0 and _wider_turns(straight) == ""
    turning = straight.with_turns(1.0)  # 0.5 m arcs: the feedforward alone asks 8.06 rad/s
    with pytest.raises(InfeasibleError, match=r"raise robot.max_motor_speed, widen reference.turn_radius \(now 0.5 m\) "
                                              r"or lower reference.speed$"):
        synthesize(turning)
    with pytest.raises(InfeasibleError, match="physically infeasible.*raise reference.turn_radius"):
        synthesize(build_model(make_config(**{"reference.turn_radius": 1.0, "robot.max_motor_speed": 6.0})))


def _jumps(rng, mu, lo, hi, Ts):
    """Each track's slip jumping to the other end of its range at its own random time within the period,
    as ``period``'s ``switch`` list (``scenarios.track_changes``)."""
    return track_changes(mu, lo + hi - mu, rng.uniform(0.0, Ts, (mu.shape[0], 2)))


def _boundary(model, K, P, level, wbar, N=20000, seed=1, within=False):
    """One period of the exact robot from N states on the set's boundary (random directions of the
    lifted state, past commands included), slip at a corner, random delays, the reference turning at
    w_k in {-wbar, 0, wbar} after w_{k-1} within wbar of it: max V+/level.  ``within``: each track's
    slip also jumps to the other end of its range at its own time within the period."""
    rng = np.random.default_rng(seed)
    n_e, n_u, d_hi, V, Ts = model.n_e, model.n_u, model.d_hi, model.V, model.Ts
    x = rng.normal(size=(N, model.n_s))
    x /= np.sqrt(np.einsum("ni,ij,nj->n", x, P, x) / level)[:, None]
    (rl, rh), (ll, lh) = model.slip_ranges
    mu = np.stack([rng.choice([rl, rh], N), rng.choice([ll, lh], N)], axis=1)
    S = model.s_tilde(random_delays(model, rng, N, 1))[:, 0]
    wk = wbar * rng.choice([-1.0, 0.0, 1.0], N)
    w_prev = np.clip(wk - wbar * rng.choice([-1.0, 0.0, 1.0], N), -wbar, wbar)
    du = x @ K.T
    U = np.empty((N, d_hi + 1, n_u))
    U[:, 0] = np.array([V, 0.0]) + du + wk[:, None] * FEEDFORWARD
    U[:, 1:] = (np.array([V, 0.0]) + x[:, n_e : n_e + d_hi * n_u].reshape(N, d_hi, n_u)
                + w_prev[:, None, None] * FEEDFORWARD)
    switch = _jumps(rng, mu, np.array([rl, ll]), np.array([rh, lh]), Ts) if within else None
    q1 = KinematicRobot.of(model).period(x[:, :n_e], U, S, mu, switch=switch)
    phi = wk * Ts
    chord = V * Ts * np.sinc(phi / (2.0 * np.pi))
    dx, dy = q1[:, 0] - chord * np.cos(phi / 2.0), q1[:, 1] - chord * np.sin(phi / 2.0)
    c, s = np.cos(phi), np.sin(phi)
    e = np.stack([c * dx + s * dy, -s * dx + c * dy, q1[:, 2] - phi], axis=1)
    xi = np.concatenate([e, du, x[:, n_e : n_e + (d_hi - 1) * n_u]], axis=1)
    return float(np.max(np.einsum("ni,ij,nj->n", xi, P, xi) / level))


def test_the_robot_on_arcs_stays_in_the_turning_set_and_leaves_the_straight_one(designs) -> None:
    """Certificate vs simulation, on the nonlinear robot.  From zero errors along arcs and straight
    pieces: within the turning certificate's set at every sampling instant and its |e_y| bound.  From
    the boundary of each set, one period on arcs: the turning set holds (measured 0.83), the
    straight-segment certificate's set, which does not know the arcs, is left (measured 1.25; 1.0003 on
    straight segments, the linearization's gap)."""
    base, turning, r0, r = designs
    w = _schedule(PERIODS)
    P, level = np.asarray(r.certificate["P"]), r.check.figures["ellipsoid_level"]
    worst, ey = _closed_loop(turning, r.K, P, level, w)
    assert np.max(worst) <= 1.0
    assert ey <= r.check.figures["ultimate_bound"]["e_y"]
    assert _boundary(turning, r.K, P, level, W_BAR) <= 1.0
    assert _boundary(turning, r.K, P, level, W_BAR, within=True) <= 1.0  # the certificate covers slip jumps
    P0, level0 = np.asarray(r0.certificate["P"]), r0.check.figures["ellipsoid_level"]
    assert _boundary(base, r0.K, P0, level0, W_BAR) > 1.1
    # the price of the turns: a larger set than for straight segments only
    assert r.check.figures["ultimate_bound"]["e_y"] > r0.check.figures["ultimate_bound"]["e_y"]


def test_a_heading_bound_on_a_turning_model_keeps_its_turns(models) -> None:
    """A heading bound on a turning model gives the turning vertices for the nonlinear robot (the review
    of 533bd04: it once kept ``turns`` and dropped the turning vertices); linearized() gives the
    linearized turning vertices back.  The H-infinity gain is built for straight segments: refused."""
    from robustsynth.errors import InputError

    _, turning = models
    nl = turning.with_heading_bound(0.3)
    assert nl.turns == turning.turns and nl.kinematics == "nonlinear" and nl.heading_bound == 0.3
    assert len(nl.vertices) == len(turning.vertices)
    for a, b in zip(nl.linearized().vertices, turning.vertices):
        assert np.array_equal(a.A, b.A) and np.array_equal(a.B_p, b.B_p) and np.array_equal(a.C_q, b.C_q)
    assert any(not np.array_equal(a.A, b.A) for a, b in zip(nl.vertices, turning.vertices))
    with pytest.raises(InputError, match="hinf bounds the slip input only"):
        synthesize(turning, objective="hinf")
    with pytest.raises(InputError, match="more than pi/2"):  # the arc factors' ranges need w_bar Ts <= pi/2
        turning.with_turns(20.0)


def test_the_committed_turning_gain_is_a_proof_for_the_nonlinear_robot() -> None:
    """configs/turns.yaml's committed gain (nonlinear kinematics, 5 m arcs): re-checked on the config's
    model with its heading bound and turns, |e_theta(t)| on arcs within that bound, refused for the
    linearized kinematics; from the boundary of its set, one period of the exact robot on arcs stays in
    it (no second-order slack: the certificate holds every kinematic term), also with each track's slip
    jumping within the period."""
    import json
    from pathlib import Path

    from robustsynth.certificate import lyapunov_of
    from robustsynth.config import load_config

    root = Path(__file__).resolve().parents[2]
    cfg = load_config(root / "configs" / "turns.yaml")
    model = build_model(cfg)
    g = json.loads((root / "results" / "baselines" / "turns" / "gains.json").read_text())
    K, cert = np.asarray(g["K"], dtype=float), g["certificate"]
    assert cert["kinematics"] == "nonlinear" and model.kinematics == "nonlinear"
    wbar = cfg.reference.speed / cfg.reference.turn_radius
    assert cert["turns"]["max_yaw_rate"] == pytest.approx(wbar, rel=1e-15)
    chk = check_certificate(model, K, cert)
    assert chk.passed, chk.reason
    f = chk.figures
    assert f["heading_within_period"] <= f["heading_bound"] == cert["heading_bound"]
    lin = build_model(cfg.model_copy(update={"synthesis": cfg.synthesis.model_copy(update={"kinematics": "linearized"})}))
    refused = check_certificate(lin, K, cert)
    assert not refused.passed and "nonlinear kinematics" in refused.reason
    P = lyapunov_of(model, cert).P[0]
    level = f["ellipsoid_level"]
    assert _boundary(model, K, P, level, wbar, seed=2) <= 1.0
    assert cert["within_period_channels"] and _boundary(model, K, P, level, wbar, seed=2, within=True) <= 1.0


def test_between_samples_on_arcs_the_robot_stays_within_the_continuous_bounds() -> None:
    """Certificate vs simulation between the sampling instants, on arcs: the committed turning gain,
    from states on its set's boundary (random directions and each figure's maximizers, slip corners,
    admissible delays), the reference turning at -w_bar, 0 or w_bar after a step the certificate allows,
    and in every other run each track's slip jumping to the other end of its range at its own time (the
    certificate covers slip changing within a period); at 41 instants of the period (the exact arcs cut
    at t) the errors in the frame of the reference at t stay within ultimate_bound_between_samples
    (|e_theta(t)|: heading_within_period)."""
    from robustsynth.certificate import lyapunov_of
    from robustsynth.model.slip import slip_matrix
    from robustsynth.plants.kinematic import period

    from ..conftest import boundary_points, committed_gain

    m, K, cert = committed_gain("turns")
    chk = check_certificate(m, K, cert)
    assert chk.passed, chk.reason
    f = chk.figures
    level, cont = float(f["ellipsoid_level"]), f["ultimate_bound_between_samples"]
    lyap = lyapunov_of(m, cert)
    rng = np.random.default_rng(5)
    xi, mu = boundary_points(m, K, lyap, level, 3000, rng)
    N = xi.shape[0]
    n_e, n_u, d_hi, V, Ts = m.n_e, m.n_u, m.d_hi, m.V, m.Ts
    wbar = m.turns.max_yaw_rate
    wk = wbar * rng.choice([-1.0, 0.0, 1.0], N)
    steps = m.turns.step_bounds(d_hi + 1) * rng.choice([-1.0, 0.0, 1.0], (N, d_hi))
    w = np.concatenate([wk[:, None], np.clip(wk[:, None] - steps, -wbar, wbar)], axis=1)
    U = np.empty((N, d_hi + 1, n_u))
    U[:, 0] = np.array([V, 0.0]) + xi @ K.T
    U[:, 1:] = np.array([V, 0.0]) + xi[:, n_e : n_e + d_hi * n_u].reshape(N, d_hi, n_u)
    U += w[:, :, None] * FEEDFORWARD
    S = m.s_tilde(random_delays(m, rng, N, 1))[:, 0]
    robot = KinematicRobot.of(m)
    D = m.config.robot.track_distance
    M = slip_matrix(mu, D)
    assert cert["within_period_channels"] and chk.figures["slip_within_period"] == "covered"
    (rl, rh), (ll, lh) = m.slip_ranges
    jumps = _jumps(rng, mu, np.array([rl, ll]), np.array([rh, lh]), Ts)
    jumps = [(np.where(np.arange(N) % 2 == 0, t_j, Ts), slip_matrix(np.where((np.arange(N) % 2 == 0)[:, None], mu_j, mu), D))
             for t_j, mu_j in jumps]  # every other run
    worst = np.zeros(3)
    for t in np.linspace(0.0, Ts, 41)[1:]:
        qt = period(xi[:, :n_e], U, np.minimum(S, t), M, t, robot.J, robot.J_inv, robot.rho_max, switch=jumps)
        psi = wk * t
        chord = V * t * np.sinc(psi / (2.0 * np.pi))  # the reference's chord from t_k, at angle psi / 2
        dx, dy = qt[:, 0] - chord * np.cos(psi / 2.0), qt[:, 1] - chord * np.sin(psi / 2.0)
        c, s = np.cos(psi), np.sin(psi)
        e = np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(qt[:, 2] - psi)], axis=1)
        worst = np.maximum(worst, np.max(np.abs(e), axis=0))
    assert worst[0] <= cont["e_x"] and worst[1] <= cont["e_y"] and worst[2] <= cont["e_theta"], (worst, cont)
    assert worst[1] > 0.5 * cont["e_y"]  # the states do reach out: the comparison is not vacuous


def test_the_synthesis_heading_rows_carry_the_turning_yaw_rates(models) -> None:
    """The synthesis's heading constraint leaves room theta_bar - |g| - sum|F_h| per row, as the re-check
    does (the review of e758184: it used |g| only, so a binding row after t_k gave sets the re-check
    refused): a heading bound above every |g| but below a row's |g| + sum|F_h| is refused up front."""
    from types import SimpleNamespace

    from robustsynth.errors import InfeasibleError
    from robustsynth.synthesis.lmis import heading_constraints

    _, turning = models
    probe = turning.with_heading_bound(1.0)
    g = max(float(np.max(np.abs(ch.g_h))) for ch in probe.heading_channels)
    off = max(float(np.max(ch.heading_offsets)) for ch in probe.heading_channels)
    assert off > g + 1e-3  # the yaw-rate columns matter
    model = turning.with_heading_bound((g + off) / 2.0)
    n_s, n_u = model.n_s, model.n_u
    lv = SimpleNamespace(X=np.zeros((n_s, n_s)), Y=np.zeros((n_u, n_s)), mats=[None], left=lambda j: np.eye(n_s))
    with pytest.raises(InfeasibleError, match="the turning reference's yaw rates included"):
        heading_constraints(model, lv)
    assert heading_constraints(turning.with_heading_bound(min(1.0, off + 0.01)), lv)  # room everywhere: constraints


def test_a_turning_certificate_made_before_the_channels_were_merged_is_rechecked() -> None:
    """configs/turns.yaml's gain as committed at stop 40 (tests/data: 3 m arcs, nonlinear kinematics, slip
    constant within a period, each arc family and its turned twin a channel of its own): re-checked on
    the layout it was made for (the review of 62d0794: it was refused), and it says that it assumes slip
    constant within a period."""
    from pathlib import Path

    from robustsynth.artifacts.gains import load_gains

    g = load_gains(Path(__file__).resolve().parents[1] / "data" / "turns-3m-stop40-gains.json")
    K, cert = np.asarray(g["K"], dtype=float), g["certificate"]
    assert "within_period_channels" not in cert
    model = build_model(make_config(**{"slip.right.min": 0.8, "slip.left.min": 0.8, "reference.turn_radius": 3.0,
                                       "synthesis.kinematics": "nonlinear"}))
    assert model.covering_vertices and model.turns.merged  # what a new certificate of this config gets
    chk = check_certificate(model, K, cert)
    assert chk.passed, chk.reason
    assert chk.figures["slip_within_period"].startswith("assumed constant")
    assert chk.figures["ultimate_bound"]["e_y"] == pytest.approx(g["certified"]["ultimate_bound"]["e_y"], rel=1e-12)
    # its multipliers fit the unmerged layout only (14 merged channels against 24, d_hi = 1)
    w = model.turns.max_yaw_rate
    merged, legacy = (model.with_turns(w, within_period=False, merged=m).vertices[0].n_q for m in (True, False))
    assert np.asarray(cert["multipliers"]["M"][0]).size == legacy**2 and merged < legacy


def test_a_turning_model_without_even_a_linearized_set_names_the_turn_radius() -> None:
    """Review, stop 47: `turn_radius: 1` on turns.yaml ended in exit 3 after every heading bound with no
    remedy at all, since the remedies came with the linearized set's ranges, and it had none."""
    from robustsynth.synthesis.heading_search import _nonlinear_infeasible
    from robustsynth.synthesis.runner import _Best

    model = committed_gain("turns")[0]
    msg = _nonlinear_infeasible(model, _Best(), [(0.1, "infeasible"), (0.15, "infeasible")], {0.1: (15, 0), 0.15: (15, 0)})
    assert "0.1 rad (infeasible at the 15 alphas tried)" in msg
    radius = model.V / model.turns.max_yaw_rate
    assert f"gave none either: narrow slip, lower reference.speed, widen reference.turn_radius (now {radius:.3g} m)" in msg
