"""A path whose corners are rounded by arcs (reference.turn_radius; law.PathTable, plants/path.py): the
reference is the unicycle at V^D with yaw rates constant per period and within what the certificate
covers, it follows the rounded path, the law measures against it continuously and sends its yaw rate
as feedforward; paths the arcs do not fit are refused with the waypoint named."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from robustsynth.config import ConfigError
from robustsynth.law import Law, PathTable, frame_error
from robustsynth.plants.path import make_path, path_of

from ..conftest import make_config

PATH = [(0.0, 0.0), (6.0, 0.0), (10.0, 2.0), (16.0, 2.0)]  # the default: turns of +-0.464 rad
V, TS, R = 0.5, 0.1, 2.0
ROUND = 1e-12  # round-off of the table's sums over a few hundred periods (values of order 10 m)


def _rounded_distance(p: np.ndarray) -> float:
    """Distance of point p from the default path with its two corners rounded by arcs of radius R."""
    wp = np.array(PATH)
    d = np.diff(wp, axis=0)
    h = np.arctan2(d[:, 1], d[:, 0])
    best = math.inf
    pieces = []
    for i in (1, 2):  # per corner: the arc's centre, start and end
        turn = h[i] - h[i - 1]
        tan = R * math.tan(abs(turn) / 2.0)
        u0, u1 = d[i - 1] / np.linalg.norm(d[i - 1]), d[i] / np.linalg.norm(d[i])
        a, b = wp[i] - tan * u0, wp[i] + tan * u1
        normal = np.sign(turn) * np.array([-u0[1], u0[0]])
        pieces.append((a + R * normal, a, b))
    ends = [wp[0]] + [x for c, a, b in pieces for x in (a, b)] + [wp[3]]
    for j, (a, b) in enumerate(zip(ends[0::2], ends[1::2])):  # the straight pieces; the last goes on
        t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0 if j < 2 else np.inf)
        best = min(best, float(np.linalg.norm(p - (a + t * (b - a)))))
    for c, a, b in pieces:  # the arcs (each spans less than pi: the point's angle lies between its ends)
        u, ua, ub = p - c, a - c, b - c
        cross = lambda x, y: x[0] * y[1] - x[1] * y[0]  # noqa: E731
        inside = cross(ua, u) * cross(ua, ub) >= 0 and cross(ub, u) * cross(ub, ua) >= 0
        best = min(best, abs(float(np.linalg.norm(u)) - R) if inside else best)
    return best


def test_the_reference_follows_the_rounded_path_within_the_certified_yaw_rates() -> None:
    p = PathTable(PATH, V, R, TS)
    w = np.array(p.ref_w)
    assert p.turning and p.t_start == [0.0]  # one frame: no waypoint switches
    assert np.max(np.abs(w)) <= V / R and np.max(np.abs(np.diff(w))) <= V / R * (1 + 1e-9)
    full = np.abs(np.abs(w) - V / R) <= 1e-9 * V / R  # both arcs, at full rate for most of their 1.86 s
    assert np.count_nonzero(full & (w > 0)) >= 15 and np.count_nonzero(full & (w < 0)) >= 15
    # the unicycle with the per-period yaw rates stays on the rounded path (it cuts each transition's corner
    # by a fraction of a millimetre) and ends on the last segment's heading
    dist = max(_rounded_distance(np.array([x, y])) for x, y in zip(p.ref_x, p.ref_y))
    assert dist <= 1e-3
    assert abs(p.ref_heading[-1] - 0.0) <= ROUND and abs(p.ref_y[-1] - 2.0) <= 1e-3
    # the poses advance at V^D: chords of one period
    steps = np.hypot(np.diff(p.ref_x), np.diff(p.ref_y))
    assert np.all(steps <= V * TS * (1 + ROUND)) and np.all(steps >= V * TS * math.cos(V / R * TS / 2) - ROUND)


def test_a_reference_given_by_its_yaw_rates_is_the_rounded_paths_own() -> None:
    """PathTable.from_yaw_rates (the adversary's references, each history its own yaw rates) from the rounded
    path's first pose and its per-period yaw rates is that path's reference, pose for pose, and the law measures
    the same error against both at any time; after its last yaw rate it goes on straight."""
    from robustsynth.plants.path import path_from_yaw_rates

    c, s = math.cos(0.7), math.sin(0.7)  # the default path turned by 0.7 rad and moved away from the origin
    moved = [(3.0 + c * x - s * y, -2.0 + s * x + c * y) for x, y in PATH]
    p = PathTable(moved, V, R, TS)
    q = PathTable.from_yaw_rates(moved[0], p.heading[0], V, TS, p.ref_w[:-1])
    for a in ("ref_x", "ref_y", "ref_heading", "ref_w", "ref_cos", "ref_sin", "t_start", "heading", "cos", "sin"):
        assert getattr(q, a) == getattr(p, a), a
    assert q.turning and q.max_yaw_rate == pytest.approx(V / R, rel=1e-9)
    assert q.duration == pytest.approx(TS * (len(p.ref_w) - 1), rel=1e-12)  # its yaw rates' periods
    rng = np.random.default_rng(1)
    for t in rng.uniform(0.0, p.duration + 1.0, 30):
        pose = (rng.uniform(0, 16), rng.uniform(-1, 3), rng.uniform(-1, 1))
        assert frame_error(q, 0, t, *pose) == frame_error(p, 0, t, *pose)
    g = path_from_yaw_rates([0.2, 0.2, -0.1], V, TS)  # from the origin along x
    end = np.array(g.desired_pose(3 * TS + 1.0))
    x3, y3, h3 = g.table.ref_x[3], g.table.ref_y[3], g.table.ref_heading[3]
    assert h3 == pytest.approx(0.3 * TS, abs=ROUND) and g.feedforward(3 * TS + 1.0) == 0.0
    assert np.allclose(end, [x3 + V * math.cos(h3), y3 + V * math.sin(h3), h3], atol=ROUND)


def test_the_frame_moves_continuously_along_each_periods_arc() -> None:
    """The reference advanced along period k's arc to its end is the table's pose k+1: the error of a
    fixed pose is continuous across the sampling instants."""
    p = PathTable(PATH, V, R, TS)
    rng = np.random.default_rng(0)
    for k in rng.integers(0, len(p.ref_w) - 1, 40):
        pose = (p.ref_x[k] + rng.normal(0, 0.05), p.ref_y[k] + rng.normal(0, 0.05), p.ref_heading[k] + rng.normal(0, 0.1))
        before = frame_error(p, 0, (k + 1) * TS - 1e-11, *pose)
        at = frame_error(p, 0, (k + 1) * TS, *pose)
        assert np.max(np.abs(np.array(before) - np.array(at))) <= 1e-11


def test_the_law_sends_the_reference_yaw_rate_as_feedforward() -> None:
    """On the reference pose with no past corrections the law corrects nothing and sends (V^D, w_k)."""
    from robustsynth.law import Controller

    d = {"K": [[1.0, 0.0, 0.0, 0.0, 0.0], [0.0, 2.0, 3.0, 0.0, 0.0]], "sampling_time": TS, "d_hi": 1,
         "integral_action": False, "reference_speed": V, "path": [list(x) for x in PATH], "turn_radius": R,
         "gear_radius": 0.09, "track_distance": 0.45, "segment_eps": 1e-12}
    ctl = Controller(d)
    p = ctl.path
    for k in (0, 40, 60, 100, 200):
        ctl.reset()
        V_hat, om = ctl.step(k * TS, p.ref_x[k], p.ref_y[k], p.ref_heading[k])
        assert abs(V_hat - V) <= ROUND and abs(om - p.ref_w[k]) <= ROUND
    assert Law(d["K"], TS, False, p).feedforward(60 * TS) == p.ref_w[60]


@pytest.mark.parametrize("path,words", [
    ([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], "segment 0-1 is 1 m long"),
    ([(0.0, 0.0), (5.0, 0.0), (0.0, 0.1)], "waypoint 1 turns by"),
    ([(0.0, 0.0), (6.0, 0.0), (6.0, 6.0), (12.05, 6.0), (12.05, 12.0)], "two turns lie so close"),
])
def test_paths_the_arcs_do_not_fit_are_refused_naming_the_place(path, words) -> None:
    with pytest.raises(ValueError, match=words):
        PathTable(path, V, 3.0, TS)
    with pytest.raises(ConfigError, match=r"^reference\.path: with reference\.turn_radius 3 m, .*" + words):
        make_config(**{"reference.turn_radius": 3.0, "reference.path": path})


def test_the_turn_radius_needs_a_certificate_that_can_carry_it(tmp_path) -> None:
    with pytest.raises(ConfigError, match="reference.turn_radius: the turning certificate needs synthesis.objective "
                       "ultimate-bound or stability"):
        make_config(**{"reference.turn_radius": 2.0, "synthesis.objective": "hinf"})
    with pytest.raises(ConfigError, match="reference.turn_radius: the turning certificate needs delay vertices"):
        make_config(**{"reference.turn_radius": 2.0, "synthesis.delay_description": "norm-bounded"})
    assert make_config(**{"reference.turn_radius": 2.0, "synthesis.kinematics": "nonlinear"}).reference.turn_radius == 2.0
    # the review of e758184: a radius that turns the reference by more than pi/2 per period crashed in the model
    with pytest.raises(ConfigError, match="reference.turn_radius: 0.03 m turns the reference by 1.67 rad per sampling "
                       "period .* at least 0.0319 m"):
        make_config(**{"reference.turn_radius": 0.03})
    assert make_config(**{"reference.turn_radius": 0.0319}).reference.turn_radius == 0.0319  # the radius it names
    cfg = tmp_path / "bad.yaml"
    cfg.write_text("name: bad\nrobot: {gear_radius: 0.09, track_distance: 0.45}\nreference: {speed: 0.5, turn_radius: 30}\n"
                   "network: {sampling_time: 0.1, delay: {min: 0.01, max: 0.08}}\nslip: {right: {min: 0.8, max: 1}, "
                   "left: {min: 0.8, max: 1}}\n")
    r = subprocess.run([sys.executable, "-m", "robustsynth", "build-model", str(cfg), "-o", str(tmp_path / "out")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith("error: reference.path: with reference.turn_radius 30 m, segment")
    assert not (tmp_path / "out" / "model.json").exists()


def test_a_config_path_of_its_turn_radius() -> None:
    cfg = make_config(**{"reference.turn_radius": R})
    p = path_of(cfg)
    assert p.turning and p.table.turn_radius == R and p.table.sampling_time == cfg.network.sampling_time
    assert not path_of(make_config()).turning and not make_path(PATH, V).turning
    k = 70
    assert np.allclose(p.desired_pose(k * TS), [p.table.ref_x[k], p.table.ref_y[k], p.table.ref_heading[k]], atol=1e-15)
    assert p.feedforward(k * TS) == p.table.ref_w[k]
