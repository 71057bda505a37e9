"""The icr slip model's kinematic channels (model/nonlinear.icr_covering_channels, docs/theory.md §12) against the
robot itself: one period of exact arcs with lateral slide, from random lifted states and commands, every slip
parameter jumping between values of its box at its own time within the period, random delays, on a straight
segment and along arcs with the turning feedforward: wherever |e_theta(t)| (on arcs: its deviation from the
reference's turn) stays within the heading bound, the robot's e_x, e_y and e_theta at t_{k+1} lie within what the
vertices' hull and the channels allow: the vertices of each command interval's twist with their channels (the
layout synthesis makes), and the constant-slip vertices with the channels alone (``icr_channels``: certificates made
before).  Negative controls: beyond the heading bound, and without the linear deviation channels or the vertices
that replace them, the robot leaves that allowance."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from robustsynth.config import load_config
from robustsynth.model import build_model
from robustsynth.model.slip import corner_weights, slip_changes
from robustsynth.plants.kinematic import KinematicRobot
from robustsynth.plants.path import frame_error, make_path, pose_from_error
from robustsynth.scenarios import random_delays

from ..conftest import ROOT

TOL = 1e-12  # round-off of one period's arcs against the vertex algebra (errors of order 1e-1)
THETA_BAR = 0.2


def _model(radius=None, icr_channels=False, **over):
    d = load_config(ROOT / "configs" / "icr-physics.yaml").model_dump(mode="json")
    d["synthesis"].update(kinematics="nonlinear", heading_bound=THETA_BAR)
    d["verification"]["motor_saturation"] = False
    d["reference"]["turn_radius"] = radius
    for key, v in over.items():
        node = d
        *path, last = key.split(".")
        for p in path:
            node = node[p]
        node[last] = v
    model = build_model(load_config(d))
    if icr_channels:  # the layout of a certificate made before the interval twists' vertices
        model = (model.with_heading_bound(THETA_BAR, icr_channels=True) if radius is None else
                 model.with_turns(model.turns.max_yaw_rate, model.turns.max_step, within_period=True, icr_channels=True))
    return model


def _history(model, rng, N, spread):
    """Random lifted states, new commands, delays and slip histories: every parameter from one value of its box
    to another at its own time within the period (half the runs between corners, half anywhere)."""
    d_hi = model.d_hi
    xi = np.zeros((N, model.n_s))
    xi[:, :3] = rng.uniform(-1, 1, (N, 3)) * np.array([0.1, 0.1, spread])
    xi[:, 3 : 3 + 2 * d_hi] = rng.uniform(-1, 1, (N, 2 * d_hi)) * np.tile([0.3, 0.8], d_hi)
    du = rng.uniform(-1, 1, (N, 2)) * np.array([0.3, 0.8])
    lo, hi = (np.array([r[k] for r in model.slip_ranges]) for k in (0, 1))
    p0 = lo + (hi - lo) * rng.integers(0, 2, (N, 4))
    p1 = lo + (hi - lo) * rng.integers(0, 2, (N, 4))
    p0[N // 2 :], p1[N // 2 :] = rng.uniform(lo, hi, (N - N // 2, 4)), rng.uniform(lo, hi, (N - N // 2, 4))
    times = rng.uniform(0.0, model.Ts, (N, 4))
    order = np.argsort(times, axis=1)
    rows = np.arange(N)
    changes, cur = [], p0.copy()
    for k in range(4):  # one parameter at a time, in time order
        cur = cur.copy()
        cur[rows, order[:, k]] = p1[rows, order[:, k]]
        changes.append((times[rows, order[:, k]], cur))
    S = model.s_tilde(random_delays(model, rng, N, 1))[:, 0]
    return xi, du, p0, changes, S


def _hull_weights(model, p0, changes, S):
    """The vertices' weights for a slip history: the period's average of the multilinear corner weights (the
    period's average twist is that combination of the corners'), times the delay vertices' weights."""
    N = p0.shape[0]
    ts = np.stack([np.zeros(N)] + [t for t, _ in changes] + [np.full(N, model.Ts)], axis=1)
    values = [p0] + [m for _, m in changes]
    lam_s = sum(((ts[:, k + 1] - ts[:, k]) / model.Ts)[:, None] * corner_weights(values[k], *model.slip_ranges)
                for k in range(len(values)))
    lam, _ = model.hull_coordinates(S, p0)
    n_c = lam_s.shape[1]
    delay = lam.reshape(N, n_c, -1).sum(axis=1)
    return (lam_s[:, :, None] * delay[:, None, :]).reshape(N, -1)


def _interval_weights(model, p0, changes, S):
    """The weights of the interval twists' vertices (``model.covering_vertices``, vertices.icr_varying_vertices) for a
    slip history: per delay vertex, its weight times, per command interval live there, the interval's average of the
    multilinear corner weights (its uniform average twist is that combination of the corners' twists)."""
    from robustsynth.model.slip import slip_corners, twist_matrix
    from robustsynth.model.vertices import interval_coordinates

    N, Ts, d_hi = p0.shape[0], model.Ts, model.d_hi
    _, which = np.unique(np.round(twist_matrix(slip_corners(*model.slip_ranges), model.config.robot.track_distance),
                                  15), axis=0, return_inverse=True)
    n_t = int(which.max()) + 1
    ts = np.stack([np.zeros(N)] + [t for t, _ in changes] + [np.full(N, Ts)], axis=1)
    values = [p0] + [m for _, m in changes]
    ends = np.concatenate([np.full((N, 1), Ts), S, np.zeros((N, 1))], axis=1)
    per = []  # per interval (N, n_t)
    for i in range(d_hi + 1):
        b, a = ends[:, i], ends[:, i + 1]
        w = np.zeros((N, n_t))
        for k in range(len(values)):
            share = np.clip(np.minimum(ts[:, k + 1], b) - np.maximum(ts[:, k], a), 0.0, None) / np.where(b > a, b - a, 1.0)
            cw = corner_weights(values[k], *model.slip_ranges)
            for c in range(cw.shape[1]):
                w[:, which.ravel()[c]] += share * cw[:, c]
        w[b <= a] = np.eye(n_t)[0]  # an empty interval: no weight of its own
        per.append(w)
    lam, _ = model.hull_coordinates(S, p0)
    delay = lam.reshape(N, -1, model.delay_vertex_count).sum(axis=1)
    # the delay vertices' coordinates (h_j, q_j), as the model was built from them
    from robustsynth.model.build import _delay_vertices, _intervals, _nominal_model

    nominal = _nominal_model(model.config, None)
    iv = _intervals(_delay_vertices(model.config, nominal), nominal)
    L_all, W_all = interval_coordinates(iv.h, iv.q, Ts)
    out = []
    for t in range(model.delay_vertex_count):
        live = (np.abs(L_all[t]) > 1e-12 * Ts) | (np.abs(W_all[t]) > 1e-12 * Ts * Ts)
        combos = list(itertools.product(*[range(n_t) if lv else (0,) for lv in live]))
        for combo in combos:
            weight = delay[:, t].copy()
            for i, c in enumerate(combo):
                if live[i]:
                    weight = weight * per[i][:, c]
            out.append(weight)
    return np.stack(out, axis=1)


def _allowance(model, lam, xi, du, w, vertices=None):
    """The hull's centre (N, 3) and the channels' allowance |B_p| |q| (N, 3) on e_x, e_y, e_theta, over ``vertices``
    (default the model's own)."""
    vertices = model.vertices if vertices is None else vertices
    nominal = sum(lam[:, i, None] * (xi @ v.A.T + du @ v.B.T + w @ v.E.T) for i, v in enumerate(vertices))
    q = sum(lam[:, i, None] * (xi @ v.C_q.T + du @ v.D_q.T + w @ v.F.T) for i, v in enumerate(vertices))
    return nominal[:, :3], np.abs(q) @ np.abs(vertices[0].B_p[:3]).T


def _weights_and_vertices(model, p0, changes, S):
    """The hull the layout covers slip changing within a period with: the interval twists' vertices where the model
    carries them, else the constant-slip vertices."""
    if len(model.covering_vertices) != len(model.vertices):
        return _interval_weights(model, p0, changes, S), model.covering_vertices
    return _hull_weights(model, p0, changes, S), model.vertices


def _straight(model, rng, N, spread):
    xi, du, p0, changes, S = _history(model, rng, N, spread)
    path = make_path(((0.0, 0.0), (100.0, 0.0)), model.V)
    q0 = pose_from_error(path, xi[:, :3])
    robot = KinematicRobot.of(model)
    U = robot.send(robot.memory(xi[:, 3 : 3 + 2 * model.d_hi].reshape(N, model.d_hi, 2), N),
                   np.array([model.V, 0.0]) + du)
    e1 = frame_error(path, 0, robot.period(q0, U, S, p0, changes), model.Ts)
    heading = np.abs(xi[:, 2])
    for t in np.linspace(0.0, model.Ts, 101)[1:]:  # e_theta(t) is piecewise linear: a fine grid finds its extremes
        heading = np.maximum(heading, np.abs(robot.partial(q0, U, S, p0, t, changes)[:, 2]))
    lam, verts = _weights_and_vertices(model, p0, changes, S)
    return e1, heading, _allowance(model, lam, xi, du, np.ones((N, 1)), verts)


@pytest.mark.parametrize("icr_channels", [False, True])
@pytest.mark.parametrize("over", [{}, {"network.delay.min": 0.0, "network.delay.max": 0.1},
                                  {"network.dropouts.max_consecutive": 1},
                                  {"slip.yaw.min": 0.3, "slip.icr_offset.min": -0.2, "slip.icr_offset.max": 0.3}])
def test_the_robot_with_slip_changing_within_the_period_stays_within_the_channels(over, icr_channels) -> None:
    model = _model(icr_channels=icr_channels, **over)
    # the constant-slip vertices cover every history with the channels alone; else the interval twists' vertices
    assert (len(model.covering_vertices) == len(model.vertices)) == icr_channels
    assert model.slip_variation("common")[1] == ""
    e1, heading, (centre, allowed) = _straight(model, np.random.default_rng(1), 1500, 0.12)
    ok = heading <= THETA_BAR
    assert ok.mean() > 0.9
    excess = np.abs(e1 - centre) - allowed
    assert np.max(excess[ok]) <= TOL, np.max(excess[ok], axis=0)
    used = np.abs(e1 - centre)[ok] / np.maximum(allowed[ok], 1e-300)
    assert np.all(np.max(used, axis=0) > 0.2)  # not vacuous, in every row


def test_headings_beyond_the_bound_break_the_channels() -> None:
    model = _model()
    e1, heading, (centre, allowed) = _straight(model, np.random.default_rng(2), 1500, 1.0)
    assert np.max((np.abs(e1 - centre) - allowed)[heading > 1.5 * THETA_BAR, :2]) > 1e-3


def test_without_the_linear_deviation_channels_slip_changing_within_the_period_is_not_covered() -> None:
    """The negative controls of the third family: the corners' hull alone does not contain the robot's map when
    the slip changes within the period (e_theta is linear in the slip history, so the excess shows there first),
    neither without the linear deviation channels (a certificate made before the interval twists' vertices) nor with
    the channels that go with those vertices but without them."""
    model = _model()
    narrow = replace(model, covering=tuple(replace(c, lin_weight=np.zeros_like(c.lin_weight)) for c in model.covering))
    for m in (narrow.with_heading_bound(THETA_BAR, icr_channels=True),
              replace(model, covering=model.icr_covering, icr_varying=()).with_heading_bound(THETA_BAR)):
        e1, heading, (centre, allowed) = _straight(m, np.random.default_rng(3), 1500, 0.12)
        ok = heading <= THETA_BAR
        assert np.max((np.abs(e1 - centre) - allowed)[ok, 2]) > 1e-4


@pytest.mark.parametrize("icr_channels", [False, True])
@pytest.mark.parametrize("radius, over", [(3.0, {}), (1.0, {"network.delay.min": 0.05, "network.delay.max": 0.18})])
def test_the_robot_on_an_arc_with_slip_changing_within_the_period_stays_within_the_channels(radius, over,
                                                                                           icr_channels) -> None:
    """Along arcs: the reference turns at w_k (any value up to V^D / r, steps the certificate allows before it),
    command j carries the feedforward w_{k-j} g through the slip; the error measured in the reference's frame at
    t_{k+1}; the heading bound on eta(t) = theta(t) - w_k t."""
    model = _model(radius, icr_channels, **over)
    turns = model.turns
    rng = np.random.default_rng(4)
    N = 1500
    xi, du, p0, changes, S = _history(model, rng, N, 0.12)
    d_hi, V, Ts = model.d_hi, model.V, model.Ts
    wk = turns.max_yaw_rate * rng.choice([-1.0, -0.5, 0.0, 0.5, 1.0], N)
    steps = rng.uniform(-1, 1, (N, d_hi)) * turns.step_bounds(d_hi + 1)
    w = np.concatenate([wk[:, None], np.clip(wk[:, None] - steps, -turns.max_yaw_rate, turns.max_yaw_rate)], axis=1)
    U = np.empty((N, d_hi + 1, 2))
    U[:, 0] = np.array([V, 0.0]) + du
    U[:, 1:] = np.array([V, 0.0]) + xi[:, 3 : 3 + 2 * d_hi].reshape(N, d_hi, 2)
    U += w[:, :, None] * model.turn_feedforward
    robot = KinematicRobot.of(model)
    q0 = xi[:, :3].copy()  # in the frame F_k of the reference at t_k
    q1 = robot.period(q0, U, S, p0, changes)
    phi, half = w[:, 0] * Ts, w[:, 0] * Ts / 2.0
    chord = V * Ts * np.sinc(half / np.pi)
    dx, dy = q1[:, 0] - chord * np.cos(half), q1[:, 1] - chord * np.sin(half)
    e1 = np.stack([np.cos(phi) * dx + np.sin(phi) * dy, -np.sin(phi) * dx + np.cos(phi) * dy, q1[:, 2] - phi], axis=1)
    heading = np.abs(xi[:, 2])
    for t in np.linspace(0.0, Ts, 101)[1:]:
        heading = np.maximum(heading, np.abs(robot.partial(q0, U, S, p0, t, changes)[:, 2] - w[:, 0] * t))
    lam, verts = _weights_and_vertices(model, p0, changes, S)
    centre, allowed = _allowance(model, lam, xi, du, model.disturbance_coordinates(p0, w), verts)
    ok = heading <= THETA_BAR
    assert ok.mean() > 0.9
    excess = np.abs(e1 - centre) - allowed
    assert np.max(excess[ok]) <= TOL, np.max(excess[ok], axis=0)
    assert np.all(np.max(np.abs(e1 - centre)[ok] / np.maximum(allowed[ok], 1e-300), axis=0) > 0.2)


def test_the_heading_rows_bound_the_robots_heading_within_the_period() -> None:
    """|e_theta(t)| over the period never exceeds the largest |heading row| at the run's own delay vertices (the
    rows are affine in the delay coordinates and in each command interval's slip average)."""
    model = _model()
    rng = np.random.default_rng(5)
    xi, du, p0, changes, S = _history(model, rng, 1000, 0.12)
    path = make_path(((0.0, 0.0), (100.0, 0.0)), model.V)
    q0 = pose_from_error(path, xi[:, :3])
    robot = KinematicRobot.of(model)
    U = robot.send(robot.memory(xi[:, 3:5].reshape(-1, 1, 2), xi.shape[0]), np.array([model.V, 0.0]) + du)
    heading = np.abs(xi[:, 2])
    for t in np.linspace(0.0, model.Ts, 101)[1:]:
        heading = np.maximum(heading, np.abs(robot.partial(q0, U, S, p0, t, changes)[:, 2]))
    rows = np.max([np.max(np.abs(xi @ c.C_h.T + du @ c.D_h.T + c.g_h), axis=1) for c in model.covering], axis=0)
    assert np.max(heading - rows) <= TOL


def test_switched_exact_of_the_icr_model() -> None:
    """The icr model's exact lifted map with a slip change within the period (the probe's linear side): without
    a change it is robot_exact and constant; with one, e_theta is the robot's exactly (it is linear), and e_x, e_y
    differ by second-order terms only (tiny deviations)."""
    model = build_model(load_config(ROOT / "configs" / "icr-physics.yaml"))
    rng = np.random.default_rng(6)
    N = 400
    lo, hi = (np.array([r[k] for r in model.slip_ranges]) for k in (0, 1))
    mu0, mu1 = rng.uniform(lo, hi, (N, 4)), rng.uniform(lo, hi, (N, 4))
    t = rng.uniform(0.0, model.Ts, (N, 2))
    S = model.s_tilde(random_delays(model, rng, N, 1))[:, 0]
    A, B, c = model.switched_exact(S, mu0, np.full((N, 2), model.Ts), mu1, per_track=True)
    A0, B0 = model.robot_exact(S, mu0)
    assert np.max(np.abs(A - A0)) <= TOL and np.max(np.abs(B - B0)) <= TOL
    assert np.max(np.abs(c - model.constant(mu0))) <= TOL
    xi = np.zeros((N, model.n_s))
    xi[:, :3] = rng.uniform(-1, 1, (N, 3)) * 1e-4
    xi[:, 3:5] = rng.uniform(-1, 1, (N, 2)) * 1e-4
    du = rng.uniform(-1, 1, (N, 2)) * 1e-4
    A, B, c = model.switched_exact(S, mu0, t, mu1, per_track=True)
    lin = np.einsum("nij,nj->ni", A, xi) + np.einsum("nij,nj->ni", B, du) + c
    path = make_path(((0.0, 0.0), (100.0, 0.0)), model.V)
    robot = KinematicRobot.of(model)
    U = robot.send(robot.memory(xi[:, 3:5].reshape(N, 1, 2), N), np.array([model.V, 0.0]) + du)
    e1 = frame_error(path, 0, robot.period(pose_from_error(path, xi[:, :3]), U, S, mu0, slip_changes(mu0, mu1, t)), model.Ts)
    assert np.max(np.abs(e1[:, 2] - lin[:, 2])) <= TOL
    # what the robot's heading drift (up to |omega*| Ts ~ 5 mrad) makes of the forward speed: second order
    assert np.max(np.abs(e1[:, :2] - lin[:, :2])) <= 1e-5


def test_the_heading_rows_of_every_yaw_choice_are_the_row_by_row_enumeration() -> None:
    """nonlinear._break_rows (one level of break points at a time over every choice of a yaw row per live command
    interval, numpy) gives the rows of the row-by-row enumeration (_break_points per choice, itertools.product order,
    each row at its first occurrence) bit for bit: d_hi 1 to 4, random interval lengths (one dead), random yaw rows
    with repeats (rows shared by choices)."""
    import itertools

    from robustsynth.model.nonlinear import _break_points, _break_rows

    rng = np.random.default_rng(7)
    for d_hi in (1, 2, 3, 4):
        n_e, n_u = 3, 2
        n_s = n_e + d_hi * n_u
        lens = rng.uniform(0.0, 0.05, d_hi + 1)
        live = [True] * (d_hi + 1)
        if d_hi > 1:
            lens[1], live[1] = 0.0, False
        yaw = rng.normal(size=(4, n_u))
        yaw[3] = yaw[1]  # a repeated row: its choices give rows seen before
        uD = np.array([0.5, 0.0])
        seen: dict[bytes, tuple] = {}
        for combo in itertools.product(*[range(len(yaw)) if lv else (0,) for lv in live]):
            for cc, dd, g, t in _break_points(lens, [yaw[k] for k in combo], uD, n_s, n_e, n_u, d_hi):
                seen.setdefault(np.concatenate([cc, dd, [g, t]]).tobytes(), (cc, dd, g, t))
        want = [np.array(x) for x in zip(*seen.values())]
        got = _break_rows(lens, yaw, live, uD, n_s, n_e, n_u, d_hi)
        for w, g in zip(want, got):
            assert w.shape == g.shape and w.tobytes() == np.ascontiguousarray(g).tobytes()


def test_a_certificate_made_before_the_interval_twists_vertices_is_rechecked_in_its_layout() -> None:
    """configs/default.yaml's gain as committed at stop 83 (tests/data: the icr channels alone cover slip changing
    within a period): re-checked on the layout it was made for, with its own figures; its multipliers fit that layout
    only, and a new certificate of the config gets the interval twists' vertices."""
    from pathlib import Path

    from robustsynth.artifacts.gains import load_gains
    from robustsynth.certificate import check_certificate

    g = load_gains(Path(__file__).resolve().parents[1] / "data" / "default-icr-channels-stop83-gains.json")
    K, cert = np.asarray(g["K"], dtype=float), g["certificate"]
    model = build_model(load_config(ROOT / "configs" / "default.yaml"))
    assert len(model.covering_vertices) > len(model.vertices)  # what a new certificate of this config gets
    chk = check_certificate(model, K, cert)
    assert chk.passed, chk.reason
    assert chk.figures["slip_within_period"] == "covered"
    assert chk.figures["ultimate_bound"]["e_y"] == pytest.approx(g["certified"]["ultimate_bound"]["e_y"], rel=1e-9)
    # for all t its own figure or a tighter one (the chord terms are joined to the start's e_y since, docs/theory §12)
    assert chk.figures["ultimate_bound_between_samples"]["e_y"] <= g["certified"]["ultimate_bound_between_samples"]["e_y"]
    turns = model.turns
    new, old = (model.with_turns(turns.max_yaw_rate, turns.max_step, within_period=True, icr_channels=c)
                for c in (False, True))
    assert np.asarray(cert["multipliers"]["M"][0]).size == old.vertices[0].n_q ** 2 != new.vertices[0].n_q ** 2
