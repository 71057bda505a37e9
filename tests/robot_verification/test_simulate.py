"""Nonlinear networked-robot simulator: exact arcs vs solve_ivp, vectorized vs per-run reference,
convergence with a constant delay and no slip."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.model import build_model
from robustsynth.synthesis import synthesize
from robustsynth.scenarios import slip_vertices
from robustsynth.plants.reference import ivp_arc, simulate_run
from robustsynth.plants.kinematic import arc_step
from robustsynth.plants.path import make_path
from robustsynth.scenarios import draw_scenario, steady_state_start
from robustsynth.robot_verification.simulate import adversarial_nonlinear, ADVERSARY_OBJECTIVES, adversary_start, simulate

from ..conftest import make_config

ARC_TOL = 1e-9  # exact arc vs DOP853 at rtol 1e-11
REF_TOL = 1e-9  # vectorized vs per-run reference (issue 4)


@given(
    x=st.floats(-10, 10), y=st.floats(-10, 10), th=st.floats(-4, 4),
    v=st.floats(-2, 2), w=st.one_of(st.just(0.0), st.floats(-1e-9, 1e-9), st.floats(-5, 5)), h=st.floats(0, 0.3),
)
@settings(max_examples=60, deadline=None)
def test_arc_matches_solve_ivp(x, y, th, v, w, h) -> None:
    q = np.array([x, y, th])
    assert np.max(np.abs(arc_step(q, v, w, h) - ivp_arc(q, v, w, h))) <= ARC_TOL


SETUPS = {
    "paper": {},
    "multi-period": {"network.delay.min": 0.03, "network.delay.max": 0.25},
    "d_lo>=1": {"network.delay.min": 0.12, "network.delay.max": 0.22, "verification.noise.position": 0.005,
                "verification.noise.heading": 0.01},
    "ideal-actuator": {"verification.motor_saturation": False},  # saturation is the default
    "integral": {"synthesis.integral_action": True, "robot.max_motor_speed": None},
    "offset": {"verification.initial_offset.y": 0.05},
    # the simulator, not the description, is under test: the quick norm-bounded one
    "lossy": {"network.dropouts.max_consecutive": 3, "verification.dropouts.probability": 0.3,
              "synthesis.delay_description": "norm-bounded"},
}


class _Setups(dict):
    """name -> (model, a stability gain), each built on first use: a test pays only for the gains it asks for, and
    setups whose configs differ in their verification section alone (what the simulator reads, not the synthesis)
    share one gain."""

    def __missing__(self, name: str):
        m = build_model(make_config(**SETUPS[name]))
        key = {k: v for k, v in SETUPS[name].items() if not k.startswith("verification.")}
        twin = next((n for n in self if {k: v for k, v in SETUPS[n].items() if not k.startswith("verification.")} == key),
                    None)
        self[name] = (m, self[twin][1] if twin is not None else synthesize(m, objective="stability").K)
        return self[name]


@pytest.fixture(scope="module")
def setups():
    return _Setups()


def _agrees_with_reference(m, K, path, scen, vec) -> None:
    """Every run of the vectorized simulation ``vec`` equals the per-run reference's (poses, errors,
    corrections)."""
    for n in range(scen.runs):
        q, e, du = simulate_run(m, K, path, scen, n)
        assert np.max(np.abs(q - vec.q[n])) <= REF_TOL
        assert np.max(np.abs(e - vec.e[n])) <= REF_TOL
        assert np.max(np.abs(du - vec.du[n])) <= REF_TOL


@pytest.mark.parametrize("name,steady,within", [
    ("paper", False, False), ("paper", True, False), ("multi-period", True, False), ("d_lo>=1", False, False),
    ("ideal-actuator", True, False), ("integral", True, False), ("lossy", True, False), ("lossy", False, False),
    ("paper", True, True), ("multi-period", True, True), ("lossy", True, True)])
@pytest.mark.slow
def test_vectorized_equals_per_run_reference(setups, name, steady, within) -> None:
    """The vectorized simulator against the per-run reference.  ``within``: slip that changes at a
    random time within each period (Scenario.mu_switch; in the simulator one more piece of the exact
    arcs, in the reference one more actuation event), and the change must matter: the same runs with
    the changes at the sampling instants end elsewhere."""
    m, K = setups[name]
    path = make_path(m.config.reference.path, m.V)
    steps = int(path.duration / m.Ts)
    scen = draw_scenario(m, 6, seed=3, steps=steps, path=path, slip="corners" if within else None, within_period=within)
    if steady:
        scen = steady_state_start(m, K, path, scen)
        assert scen.du0 is not None
    vec = simulate(m, K, path, scen)
    _agrees_with_reference(m, K, path, scen, vec)
    if within:  # both tracks change, at different times within one period, somewhere
        both = np.all(scen.mu[:, 1:] != scen.mu[:, :-1], axis=-1) & np.all(scen.mu_switch[:, 1:] > 0.0, axis=-1)
        assert np.any(both)
        at_instants = simulate(m, K, path, replace(scen, mu_switch=None))
        assert np.max(np.abs(at_instants.q - vec.q)) > 1e3 * REF_TOL


def test_within_period_changes_are_drawn_apart_and_only_where_slip_may_jump(setups) -> None:
    m, _ = setups["paper"]
    path = make_path(m.config.reference.path, m.V)
    a = draw_scenario(m, 5, seed=9, steps=50, path=path)
    b = draw_scenario(m, 5, seed=9, steps=50, path=path, within_period=True)
    # the other draws are unchanged (a stream of its own), the times lie in the period, none at t_0
    assert a.mu_switch is None
    assert all(np.array_equal(getattr(a, f), getattr(b, f)) for f in ("taus", "mu", "noise", "q0"))
    assert b.mu_switch.shape == (5, 50, 2) and np.all(b.mu_switch[:, 0] == 0.0)
    # every other run both tracks at one time (a corner jump), the others each track at its own
    assert np.all(b.mu_switch[::2, :, 0] == b.mu_switch[::2, :, 1])
    assert np.all(b.mu_switch[1::2, 1:, 0] != b.mu_switch[1::2, 1:, 1])
    assert np.all((b.mu_switch >= 0.0) & (b.mu_switch < m.Ts))
    # a slip rate bound: one time per run, the same in every period (the changes stay a period apart)
    rated = build_model(make_config(**{"slip.max_rate": 0.5}))
    sw = draw_scenario(rated, 5, seed=9, steps=50, path=path, within_period=True).mu_switch
    assert np.all(sw[:, 1:] == sw[:, 1:2]) and np.all((sw[:, 1] > 0.0) & (sw[:, 1] < m.Ts)) and np.all(sw[:, 0] == 0.0)
    # the icr model: its channels cover changes within a period (theory §12), each parameter changing at one of
    # the two tracks' times (the yaw factor with the right's, x_icr with the left's)
    icr = build_model(make_config(**{"slip.model": "icr", "slip.yaw": {"min": 0.54, "max": 0.67},
                                     "slip.icr_offset": {"min": 0.0, "max": 0.09}}))
    sw = draw_scenario(icr, 5, seed=9, steps=50, path=path, within_period=True).mu_switch
    assert sw.shape == (5, 50, 2) and np.all(sw[:, 0] == 0.0) and np.all((sw >= 0.0) & (sw < m.Ts))


def test_constant_delay_no_slip_converges_to_zero(setups) -> None:
    m, K = setups["offset"]
    path = make_path(((0.0, 0.0), (20.0, 0.0)), m.V)  # straight: no waypoint transient
    steps = int(path.duration / m.Ts)
    for delays in ("constant-min", "constant-max"):
        scen = draw_scenario(m, 2, seed=0, steps=steps, path=path, delays=delays, slip="none")
        sim = simulate(m, K, path, scen)
        assert np.max(np.abs(sim.e[:, 0])) > 0.04  # the initial offset (5 cm)
        assert np.max(np.abs(sim.e[:, -1])) < 1e-9


def test_slip_profiles_stay_in_bounds(setups) -> None:
    m, _ = setups["paper"]
    path = make_path(m.config.reference.path, m.V)
    scen = draw_scenario(m, 30, seed=1, steps=300, path=path)
    assert set(scen.profiles) == {"constant", "random-walk", "steps", "corners"}
    assert np.all(scen.mu >= 0.6 - 1e-12) and np.all(scen.mu <= 1.0 + 1e-12)
    walk = scen.mu[[i for i, p in enumerate(scen.profiles) if p == "random-walk"]]
    assert np.all(np.std(walk, axis=1) > 0)
    corners = scen.mu[[i for i, p in enumerate(scen.profiles) if p == "corners"]]
    assert np.all(np.isin(corners, [0.6, 1.0]))  # only box corners, and they do switch
    assert np.all(np.max(np.abs(np.diff(corners, axis=1)), axis=(1, 2)) == pytest.approx(0.4))


RATE_TOL = 1e-12  # round-off on a slip increment


def test_rate_bounded_slip_profiles_respect_the_rate() -> None:
    m = build_model(make_config(**{"slip.max_rate": 0.5}))
    path = make_path(m.config.reference.path, m.V)
    scen = draw_scenario(m, 40, seed=4, steps=300, path=path)
    step = np.max(np.abs(np.diff(scen.mu, axis=1)))
    assert step <= 0.5 * m.Ts + RATE_TOL and step > 0.5 * m.Ts * 0.99  # ramps use the whole rate
    assert np.all(scen.mu >= 0.6 - RATE_TOL) and np.all(scen.mu <= 1.0 + RATE_TOL)


STEADY_TOL = 1e-12  # a steady state of the lifted model is one of the nonlinear robot, to round-off


@pytest.mark.parametrize("name", ["paper", "multi-period", "integral"])
def test_steady_state_is_an_equilibrium_of_the_nonlinear_robot(setups, name) -> None:
    """Started at xi*(mu) of the lifted slip-aware model, under that constant slip and any delays,
    the nonlinear robot keeps its error exactly: the slip-compensated command makes it move at u^D."""
    m, K = setups[name]
    path = make_path(((0.0, 0.0), (30.0, 0.0)), m.V)
    scen = steady_state_start(m, K, path, draw_scenario(m, 8, seed=5, steps=200, path=path, slip="constant"))
    sim = simulate(m, K, path, scen)
    e_star = m.equilibrium(K, scen.mu[:, 0])[:, :3]
    assert np.max(np.abs(sim.e - e_star[:, None, :])) <= STEADY_TOL * 1e3  # 200 steps of round-off
    assert np.max(np.abs(e_star[:, 2])) <= STEADY_TOL
    if m.integral:
        assert np.max(np.abs(e_star)) <= STEADY_TOL


def test_adversary_pushes_harder_than_random_runs(setups) -> None:
    """The adversary's greedy histories maximize V of the next state among their candidates: their V
    must exceed that of the same robot under random slip and delays from the same starts."""
    m = build_model(make_config())
    res = synthesize(m, alpha_points=7)
    from robustsynth.certificate import lyapunov_of

    lyap = lyapunov_of(m, res.certificate)
    mu0 = np.array([[0.6, 1.0], [1.0, 0.6], [0.6, 0.6], [1.0, 1.0]])
    adv = adversarial_nonlinear(m, res.K, lyap.V, mu0, 60)
    assert adv["V"].shape == (60, 4 + 1) and np.all(np.isin(adv["worst"]["V"]["mu"], [0.6, 1.0]))
    path = make_path(((0.0, 0.0), (40.0, 0.0)), m.V)
    rnd = simulate(m, res.K, path, steady_state_start(m, res.K, path, draw_scenario(m, 40, seed=6, steps=60, path=path)))
    assert adv["max_V"] > np.max(lyap.V_max(rnd.true_xi()))
    # a wider search keeps the same greedy histories (one per start, independent of the rest): never less V
    wide = adversarial_nonlinear(m, res.K, lyap.V, mu0, 60, width=8, objectives=ADVERSARY_OBJECTIVES)
    assert np.array_equal(wide["V"][:, :4], adv["V"][:, :4])
    assert wide["max_V"] >= np.max(adv["V"][:, :4])


REPLAY_TOL = 1e-9  # the search's robot, one period per candidate, vs the simulator over the replayed history


@pytest.fixture(scope="module")
def certified():
    """Certified gains: slip jumping (common Q), and rate-limited slip (slip-dependent S(mu))."""
    from robustsynth.certificate import lyapunov_of

    out = {}
    for name, over in {"jumps": {}, "rate-limited": {"slip.max_rate": 0.5, "synthesis.lyapunov": "slip-dependent"}}.items():
        m = build_model(make_config(**over))
        res = synthesize(m, alpha_points=3)
        out[name] = (m, res.K, lyapunov_of(m, res.certificate))
    return out


def replay_worst(m, K, lyap, mu0, h):
    """Replay a worst history of :func:`adversarial_nonlinear` with :func:`simulate` (one period more:
    the slip V was taken at, the last delay held) and evaluate every objective at the state it reached."""
    from dataclasses import replace

    T = h["mu"].shape[0]
    path, start = adversary_start(m, K, mu0[h["start"]][None], T + 1, course=h["course"], yaw=h["yaw"])
    mu = np.concatenate([h["mu"], h["mu_next"][None]])[None]  # the next period's slip: the one V was taken at
    taus = np.append(h["tau"], h["tau"][-1])[None]
    # when within each period the slip took its new value (0: at the instant; the last period's is not used)
    sw = np.concatenate([h["t_switch"], np.zeros((1, 2))])[None] if np.any(h["t_switch"] > 0.0) else None
    sim = simulate(m, K, path, replace(start, taus=taus, mu=mu, noise=np.zeros((1, T + 1, 3)), mu_switch=sw))
    xi = sim.true_xi()[0, T]
    prev = m.delay_weights(m.s_tilde(taus))[0, T - 1] if lyap.path else None  # period T-1's delay weights
    return {"V": float(lyap.V(xi, h["mu_next"], prev)), "e_x": abs(sim.e[0, T, 0]), "e_y": abs(sim.e[0, T, 1]),
            "e_theta": abs(sim.e[0, T, 2]), "motor_speed": float(np.max(np.abs(sim.rho[0, T])))}


@pytest.mark.parametrize("name,within", [("jumps", False), ("jumps", True), ("jumps", "only"), ("rate-limited", False)])
def test_adversary_histories_replay_and_are_admissible(certified, name, within, monkeypatch) -> None:
    """Every objective's worst history is admissible (slip in the box, within the rate bound from the
    start's slip on; delays in [tau_min, tau_max]; a change within a period only where slip may jump,
    never in the first) and, replayed by the simulator, reaches the value the search reported, which
    is also its reported maximum.  ``only``: the adversary may change slip only within a period (each
    track at 1/3 or 2/3 of it), so that the replay of such changes is exercised whatever the worst
    histories are."""
    from robustsynth.robot_verification import simulate as sim_mod

    if within == "only":
        monkeypatch.setattr(sim_mod, "WITHIN_PERIOD_TIMES", (1.0 / 3.0, 2.0 / 3.0))
    WITHIN_PERIOD_TIMES = sim_mod.WITHIN_PERIOD_TIMES
    m, K, lyap = certified[name]
    mu0 = slip_vertices(m)
    adv = adversarial_nonlinear(m, K, lyap.V, mu0, 80, width=6, objectives=ADVERSARY_OBJECTIVES, within_period=within)
    assert adv["V"].shape == (80, mu0.shape[0] + 6 * len(ADVERSARY_OBJECTIVES))
    dl, step = m.config.network.delay, m.slip_step
    changes_within = 0
    for o, h in adv["worst"].items():
        assert h["t_switch"].shape == (h["mu"].shape[0], 2)  # each track's time
        assert np.all(h["t_switch"][0] == 0.0) and np.all(np.isin(h["t_switch"][1:], m.Ts * np.asarray(WITHIN_PERIOD_TIMES)))
        changed = np.diff(np.concatenate([mu0[h["start"]][None], h["mu"]]), axis=0) != 0.0  # per track
        changes_within += int(np.sum(changed & (h["t_switch"] > 0.0)))
        assert within or not np.any(h["t_switch"] > 0.0)
        mu = np.concatenate([mu0[h["start"]][None], h["mu"], h["mu_next"][None]])
        assert np.all((mu >= 0.6) & (mu <= 1.0))
        if step is not None:
            assert np.max(np.abs(np.diff(mu, axis=0))) <= step * (1 + 1e-12)
        else:
            assert np.all(np.isin(h["mu"], [0.6, 1.0]))
        assert np.all((h["tau"] >= dl.min) & (h["tau"] <= dl.max))
        got = replay_worst(m, K, lyap, mu0, h)
        assert abs(got[o] - h["value"]) <= REPLAY_TOL * max(1.0, h["value"]), (o, got[o], h["value"])
        ref = adv["max_V"] if o == "V" else adv["max"][o]
        assert h["value"] == ref or (o == "motor_speed" and h["value"] <= ref)  # |rho| also counts the start
    if step is not None:  # slow slip: the beam must still find histories that move the robot sideways
        assert adv["max"]["e_y"] > 0.005
    if within == "only":  # every change after the first period was within it, and was replayed above
        assert changes_within > 0


def test_the_adversary_along_arcs_turns_and_its_histories_replay() -> None:
    """A turning certificate (configs/turns.yaml's committed gain): each of the adversary's courses of arcs
    turns at the largest yaw rate it covers, both ways, from the first period on, with steps of at most
    w_bar; every objective's worst history along the harshest one replays with the simulator (the turning
    feedforward in the commands) to the value the search reported; the arcs push harder than the straight
    line, from the steady states (|e_y|) and from the boundary of the set (V) alike (the review of b7bf029:
    a course that started straight gave the boundary search exactly the straight line's V)."""
    from robustsynth.certificate import check_certificate, lyapunov_of
    from robustsynth.robot_verification.probe import boundary_states
    from robustsynth.robot_verification.simulate import ARC_COURSES, FREE_YAW, adversary_course, adversary_courses

    from ..conftest import committed_gain

    m, K, cert = committed_gain("turns")
    lyap = lyapunov_of(m, cert)
    level = float(check_certificate(m, K, cert).figures["ellipsoid_level"])
    wbar = m.turns.max_yaw_rate
    assert adversary_courses(m) == ("straight",) + ARC_COURSES + (FREE_YAW,)
    for course in ARC_COURSES:
        w = np.asarray(adversary_course(m, 60, course).table.ref_w)[:60]
        assert np.max(w) == pytest.approx(wbar, rel=1e-12) and np.min(w) == pytest.approx(-wbar, rel=1e-12)
        assert abs(w[0]) == pytest.approx(wbar, rel=1e-12)  # turning from the start
        assert np.max(np.abs(np.diff(w))) <= wbar * (1 + 1e-12)
    with pytest.raises(ValueError, match="for a turning model"):
        adversary_course(build_model(make_config()), 60, "arcs-1-1")
    mu0 = slip_vertices(m)
    adv = adversarial_nonlinear(m, K, lyap.V, mu0, 60, width=4, objectives=ADVERSARY_OBJECTIVES, course="arcs-1-1")
    for o, h in adv["worst"].items():
        assert h["course"] == "arcs-1-1"
        got = replay_worst(m, K, lyap, mu0, h)
        assert abs(got[o] - h["value"]) <= REPLAY_TOL * max(1.0, h["value"]), (o, got[o], h["value"])
    straight = adversarial_nonlinear(m, K, lyap.V, mu0, 60, width=4, objectives=ADVERSARY_OBJECTIVES)
    assert adv["max"]["e_y"] > straight["max"]["e_y"]
    xb, mb = boundary_states(m, K, lyap, level, seed=0)
    on = [adversarial_nonlinear(m, K, lyap.V, mb, 10, width=4, starts=xb, course=c)["max_V"] for c in ("straight", "arcs-1-1")]
    assert on[1] > on[0]


def test_the_adversary_that_picks_the_yaw_rates_keeps_them_admissible_and_its_histories_replay() -> None:
    """On the FREE_YAW course each history has its own reference: the adversary picks w_k each period among
    w_{k-1} and its steps of max_step either way (w_{-1} = 0: the starts' commands carry no feedforward), within
    +-max_yaw_rate.  Here max_step is half of max_yaw_rate (the certificate covers smaller steps), so that the
    three picks are distinct almost everywhere.  Every objective's worst history is admissible, turns both ways,
    and replays with the simulator on the reference built from its yaw rates (law.PathTable.from_yaw_rates, the
    deployed law) to the value the search reported; the search runs in the frame of each history's reference,
    the replay in the world's: two independent paths to the same numbers.  For |rho| the next period's yaw rate
    is the adversary's pick too: no other admissible pick replays to more."""
    from dataclasses import replace

    from robustsynth.certificate import lyapunov_of
    from robustsynth.robot_verification.simulate import FREE_YAW

    from ..conftest import committed_gain

    m, K, cert = committed_gain("turns")
    lyap = lyapunov_of(m, cert)
    wbar = m.turns.max_yaw_rate
    step = wbar / 2.0
    m = replace(m, turns=replace(m.turns, max_step=step))
    mu0 = slip_vertices(m)
    adv = adversarial_nonlinear(m, K, lyap.V, mu0, 40, width=4, objectives=ADVERSARY_OBJECTIVES, course=FREE_YAW)
    turned = []
    for o, h in adv["worst"].items():
        assert h["course"] == FREE_YAW and h["yaw"].shape == (h["mu"].shape[0] + 1,)  # and the next period's
        w = np.concatenate([[0.0], h["yaw"]])
        assert np.all(np.abs(w) <= wbar * (1 + 1e-12)) and np.all(np.abs(np.diff(w)) <= step * (1 + 1e-12))
        assert np.all(np.isin(np.round(w / step, 9), np.arange(-2, 3)))  # multiples of the step: the picks
        turned.append(h["yaw"])
        got = replay_worst(m, K, lyap, mu0, h)
        assert abs(got[o] - h["value"]) <= REPLAY_TOL * max(1.0, h["value"]), (o, got[o], h["value"])
    # one period from the steady states (w_0 within a step of 0, so w_1 is not clipped to w_0): the |rho| found is
    # the largest over the next period's admissible picks
    short = adversarial_nonlinear(m, K, lyap.V, mu0, 1, width=4, objectives=("motor_speed",), course=FREE_YAW)
    h = short["worst"]["motor_speed"]
    picks = [float(np.clip(h["yaw"][-2] + d, -wbar, wbar)) for d in (-step, 0.0, step)]
    replays = [replay_worst(m, K, lyap, mu0, dict(h, yaw=np.append(h["yaw"][:-1], w)))["motor_speed"] for w in picks]
    assert len(set(picks)) == 3 and max(replays) - min(replays) > 0.01  # the picks matter
    assert abs(max(replays) - h["value"]) <= REPLAY_TOL * h["value"]
    turned = np.concatenate(turned)
    assert np.max(turned) > 0.0 > np.min(turned)


def test_scenarios_are_reproducible(setups) -> None:
    m, _ = setups["paper"]
    path = make_path(m.config.reference.path, m.V)
    a = draw_scenario(m, 5, seed=9, steps=50, path=path)
    b = draw_scenario(m, 5, seed=9, steps=50, path=path)
    assert np.array_equal(a.taus, b.taus) and np.array_equal(a.mu, b.mu)


def test_saturation_clips_motor_speeds_and_changes_the_turns(setups) -> None:
    from robustsynth.plants.kinematic import saturate

    m, K = setups["paper"]
    assert m.config.verification.motor_saturation  # the default: real motors saturate
    J, J_inv = np.asarray(m.J), np.asarray(m.J_inv)
    u = np.array([[0.5, 3.0], [2.0, 0.0], [0.4, -0.1]])
    rho = saturate(u, J, J_inv, 12.0) @ J_inv.T
    assert np.all(np.abs(rho) <= 12.0 + 1e-12)
    assert np.allclose(saturate(u[2:], J, J_inv, 12.0), u[2:])  # inside the limit: unchanged
    path = make_path(m.config.reference.path, m.V)
    steps = int(path.duration / m.Ts)
    scen = draw_scenario(m, 4, seed=2, steps=steps, path=path)
    sat = simulate(m, K, path, scen)
    free = simulate(setups["ideal-actuator"][0], K, path, scen)
    assert np.max(np.abs(free.rho)) > 12.0  # the turns ask for more than the motors give...
    assert np.max(np.abs(sat.q - free.q)) > 1e-6  # ...so clipping changes the motion


def test_lossy_scenarios_lose_packets_in_capped_bursts(setups) -> None:
    from robustsynth.core.network import longest_burst

    m, _ = setups["lossy"]
    path = make_path(m.config.reference.path, m.V)
    scen = draw_scenario(m, 40, seed=2, steps=300, path=path)
    lost = np.isinf(scen.taus)
    assert lost.mean() == pytest.approx(0.3, abs=0.05)  # the configured long-run loss fraction
    assert longest_burst(lost).max() == 3  # capped at network.dropouts.max_consecutive
    wild = draw_scenario(m, 40, seed=2, steps=300, path=path, losses="uncapped")
    assert longest_burst(np.isinf(wild.taus)).max() > 3
    clean = draw_scenario(m, 40, seed=2, steps=300, path=path, losses=False)
    assert not np.isinf(clean.taus).any()
    np.testing.assert_array_equal(clean.mu, scen.mu)  # losses come from their own stream


DEPLOY_TOL = 1e-12  # simulator's commands vs the deployed Controller (issue 11); both run runtime.law


@pytest.mark.parametrize("name", ["paper", "d_lo>=1", "integral", "multi-period"])
def test_simulator_commands_are_the_deployed_controllers(setups, name) -> None:
    """A full Monte Carlo run (the config's runs, steady-state starts, noise where configured): the
    commands the simulator applied equal Controller.step on the measured poses, step by step."""
    from robustsynth.config import config_to_dict
    from robustsynth.runtime import Controller, controller_description

    m, K = setups[name]
    path = make_path(m.config.reference.path, m.V)
    steps = int(path.duration / m.Ts)
    scen = steady_state_start(m, K, path, draw_scenario(m, m.config.verification.runs, seed=5, steps=steps, path=path))
    sim = simulate(m, K, path, scen)
    ctl = Controller(controller_description({"K": K.tolist(), "config": config_to_dict(m.config)}))
    meas = sim.q[:, :-1] + scen.noise[:, :steps]
    worst = 0.0
    for n in range(scen.runs):
        ctl.reset(past=scen.du0[n].reshape(-1).tolist(), integrators=None if scen.z0 is None else scen.z0[n].tolist())
        cmd = np.array([ctl.step(sim.t[k], *meas[n, k]) for k in range(steps)])
        worst = max(worst, float(np.max(np.abs(cmd - (np.array([m.V, 0.0]) + sim.du[n])))))
    assert worst <= DEPLOY_TOL
    assert len(set(sim.segment.tolist())) > 1  # the run crossed waypoints


def test_vectorized_equals_per_run_reference_on_arcs(setups) -> None:
    """A path rounded by arcs (reference.turn_radius): the simulator and the per-run reference send the
    same turning feedforward and measure against the same reference; and the arcs matter (the same
    runs on the polyline end elsewhere)."""
    from robustsynth.plants.path import path_of

    _, K = setups["paper"]  # the simulator is under test, not the certificate: a gain of the same lifting
    m = build_model(make_config(**{"reference.turn_radius": 2.0, "slip.right.min": 0.8, "slip.left.min": 0.8}))
    path = path_of(m.config)
    assert path.turning
    steps = int(path.duration / m.Ts)
    scen = steady_state_start(m, K, path, draw_scenario(m, 6, seed=4, steps=steps, path=path, within_period=True))
    vec = simulate(m, K, path, scen)
    _agrees_with_reference(m, K, path, scen, vec)
    polyline = make_path(m.config.reference.path, m.V)
    assert np.max(np.abs(simulate(m, K, polyline, scen).q - vec.q)) > 0.1


def _top_distinct_by_full_sort(score: np.ndarray, width: int) -> np.ndarray:
    """The beam's pick by sorting every score (what _top_distinct did before it sorted a prefix)."""
    finite = np.flatnonzero(np.isfinite(score))
    order = finite[np.argsort(-score[finite], kind="stable")]
    s = score[order]
    new = np.ones(s.size, dtype=bool)
    new[1:] = np.abs(np.diff(s)) > 1e-12 * np.maximum(1.0, np.abs(s[1:]))
    return np.resize(np.concatenate([order[new], order[~new]])[:width], width)


@settings(max_examples=300, deadline=None)
@given(n=st.integers(1, 3000), width=st.integers(1, 40), levels=st.integers(1, 400), seed=st.integers(0, 2**31 - 1),
       infs=st.floats(0.0, 0.9))
def test_top_distinct_sorts_a_prefix_and_picks_what_the_full_sort_picks(n, width, levels, seed, infs) -> None:
    """Few distinct levels make ties (and runs short of distinct scores, where the full sort decides),
    -inf marks masked candidates, and ties closer than the 1e-12 tolerance count as one score."""
    from robustsynth.robot_verification.simulate import _top_distinct

    rng = np.random.default_rng(seed)
    score = rng.integers(0, levels, size=n).astype(float) + rng.choice([0.0, 1e-14], size=n)
    score[rng.random(n) < infs] = -np.inf
    assert np.array_equal(_top_distinct(score, width), _top_distinct_by_full_sort(score, width))


def test_the_adversarys_searches_on_threads_give_what_one_thread_gives() -> None:
    """verify runs the adversary's independent searches (courses, slip changing within the period or not) on
    threads and merges them in their order: every figure and every worst history is the one of a single thread,
    bit for bit (configs/turns.yaml's committed gain: five courses, a turning model)."""
    from robustsynth.certificate import lyapunov_of
    from robustsynth.robot_verification.nonlinear_checks import _adversary

    from ..conftest import committed_gain

    m, K, cert = committed_gain("turns")
    lyap = lyapunov_of(m, cert)
    runs = [_adversary(True, m, K, lyap.V, slip_vertices(m), 12, width=3, objectives=ADVERSARY_OBJECTIVES, workers=w)
            for w in (1, 2)]

    def same(a, b) -> bool:
        if isinstance(a, dict):
            return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
        if isinstance(a, (list, tuple)):
            return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
        return np.array_equal(np.asarray(a), np.asarray(b))

    assert same(*runs)
