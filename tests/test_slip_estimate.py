"""The slip estimate of the runtime monitor (robustsynth.monitor: Monitor.slip_estimate, slip_estimate_bound;
docs/theory/17-the-slip-estimate.md): its polygon against an independent LP, the true traction inside it on a
hand-driven robot and on simulated closed-loop runs (and outside it when the rate it assumes is too low: the
negative control), what it leaves unobserved, and its a-priori bound."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.monitor import Monitor, _mon_clip, slip_estimate_bound
from tests.test_monitor import TS, V, _description, _Robot

ROOT = Path(__file__).resolve().parents[1]
LP_TOL = 1e-7  # scipy's HiGHS tolerances (~1e-9) against the clipped polygon's exact vertices
BOX = [[0.6, 1.0], [0.6, 1.0]]
COMPONENTS = [[0.6, 1.0], [-0.4, 0.4], [0.6, 1.0], [-0.4, 0.4], [0.0, 0.0], [0.0, 0.0]]


def _estimating(max_rate=0.1, **kw):
    return Monitor(_description(max_rate=max_rate, slip_ranges=BOX, components=COMPONENTS, slip_model="tracks", **kw))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-0.5, 1.5), st.floats(1e-3, 0.3))
                .filter(lambda x: abs(x[0]) + abs(x[1]) > 0.05), min_size=1, max_size=6))
def test_the_clipped_polygon_is_the_lp_s_feasible_set(slabs) -> None:
    """mu_r = s + d/2 and mu_l = s - d/2 over the box cut by slabs |a s + b d - c| <= e: the clipped polygon's
    extremes against scipy's linprog on the same constraints (and both empty together)."""
    from scipy.optimize import linprog

    poly = [((r + l) / 2.0, r - l) for r, l in ((0.6, 0.6), (1.0, 0.6), (1.0, 1.0), (0.6, 1.0))]
    A, ub = [[1.0, 0.5], [-1.0, -0.5], [1.0, -0.5], [-1.0, 0.5]], [1.0, -0.6, 1.0, -0.6]  # (mu_r, mu_l) in the box
    for a, b, c, e in slabs:
        poly = _mon_clip(_mon_clip(poly, a, b, c + e), -a, -b, e - c)
        A += [[a, b], [-a, -b]]
        ub += [c + e, e - c]
    for w in ([1.0, 0.5], [1.0, -0.5]):
        lo = linprog(w, A_ub=A, b_ub=ub, bounds=[(None, None)] * 2)
        hi = linprog([-x for x in w], A_ub=A, b_ub=ub, bounds=[(None, None)] * 2)
        if lo.status == 2:  # infeasible
            assert not poly or max(abs(p[0] - q[0]) + abs(p[1] - q[1]) for p in poly for q in poly) < LP_TOL
            return
        if not poly:  # then the set is empty but for the LP's tolerance: a little tighter, the LP finds none either
            assert linprog(w, A_ub=A, b_ub=[u - LP_TOL for u in ub], bounds=[(None, None)] * 2).status == 2
            return
        vals = [w[0] * s + w[1] * d for s, d in poly]
        assert min(vals) == pytest.approx(lo.fun, abs=LP_TOL)
        assert max(vals) == pytest.approx(-hi.fun, abs=LP_TOL)


def test_a_straight_run_at_constant_traction_is_estimated_within_the_a_priori_bound() -> None:
    mon = _estimating(max_rate=0.1)
    _Robot(mon).run(12, mu=0.8)
    est = mon.slip_estimate()
    bound = slip_estimate_bound(mon.description)
    assert est["consistent"] and est["windows"] == 5
    for name in ("mu_r", "mu_l"):
        lo, hi = est["ranges"][name]
        assert lo <= 0.8 <= hi
        assert est["bound"][name] <= bound["half"][name] + 1e-9  # what the description promises on a straight run
        assert est["observed"][name] and est["bound"][name] < 0.2  # narrower than the box [0.6, 1]
    assert bound["at_action"]["mu_r"] == pytest.approx(bound["half"]["mu_r"] + 0.1 * (0.08 + TS + TS))


def test_a_traction_moving_at_the_rate_stays_inside_and_one_faster_leaves_it() -> None:
    """The robot's traction ramps by max_rate x Ts per period; the estimate at t_k must hold the traction of the
    period just ended.  The negative control: the same ramp against an estimate that assumes a twentieth of the rate."""
    def ramp(mon):
        robot, inside = _Robot(mon), []
        for k in range(40):
            mu = 0.65 + 0.01 * min(k, 30)  # 0.1 /s x 0.1 s per period, up to 0.95
            robot.run(1, mu=mu)
            est = mon.slip_estimate() if k else None
            if est and est["windows"]:
                prev = 0.65 + 0.01 * min(k - 1, 30)
                inside.append(est["consistent"] and est["ranges"]["mu_r"][0] <= prev <= est["ranges"]["mu_r"][1])
        return inside

    assert all(ramp(_estimating(max_rate=0.1)))
    assert not all(ramp(_estimating(max_rate=0.005)))


def test_without_a_rate_bound_the_traction_now_is_the_box() -> None:
    mon = Monitor(_description(slip_ranges=BOX, components=COMPONENTS, slip_model="tracks"))
    _Robot(mon).run(8, mu=0.8)
    est = mon.slip_estimate()
    assert est["windows"] == 0 and est["ranges"]["mu_r"] == (0.6, 1.0) and not est["observed"]["mu_r"]
    assert slip_estimate_bound(mon.description) is None


def test_a_description_made_before_has_no_estimate() -> None:
    mon = Monitor(_description())
    _Robot(mon).run(3)
    assert mon.slip_estimate() is None


def _closed_loop(config: str, gains: str, rate: float, assumed_rate: float, runs: int, noise: float = 0.0005):
    """Monte Carlo runs of the kinematic robot (slip within its box, moving at ``rate``, each track changing at its
    own time within the period) replayed through the monitor; per period k the estimate against the slip of
    period k - 1 (what the robot had just before t_k)."""
    from robustsynth.artifacts.gains import controller_description, load_gains
    from robustsynth.config import config_to_dict, load_config
    from robustsynth.model import build_model
    from robustsynth.plants.path import path_of
    from robustsynth.runtime.replay import monitor_log
    from robustsynth.scenarios import draw_scenario, steady_state_start
    from robustsynth.robot_verification.simulate import run_logs, simulate

    d = config_to_dict(load_config(ROOT / config))
    d["slip"]["max_rate"] = rate
    d["verification"]["noise"] = {"position": noise, "heading": noise}
    cfg = load_config(d)
    g = load_gains(ROOT / gains)
    model, K, path = build_model(cfg), np.asarray(g["K"]), path_of(cfg)
    desc = controller_description(g, cfg)
    desc["monitor"]["max_rate"] = assumed_rate
    steps = min(int(path.duration / model.Ts), 150)
    scen = steady_state_start(model, K, path, draw_scenario(model, runs, 3, steps, path, within_period=True))
    logs = run_logs(model, simulate(model, K, path, scen), scen)
    out = {"inside": 0, "outside": 0, "inconsistent": 0, "half": [], "est": []}
    for n, lg in enumerate(logs):
        for k, e in enumerate(monitor_log(lg, desc, estimate=True)["estimates"]):
            if k == 0 or not e["windows"]:
                continue
            if not e["consistent"]:
                out["inconsistent"] += 1
                continue
            out["est"].append(e)
            mu = scen.mu[n, k - 1]
            for name, true in (("mu_r", mu[0]), ("mu_l", mu[1]), ("traction", (mu[0] + mu[1]) / 2.0),
                               ("difference", mu[0] - mu[1])):
                lo, hi = e["ranges"][name]
                out["inside" if lo <= true <= hi else "outside"] += 1
                if name in ("mu_r", "mu_l"):
                    out["half"].append(e["bound"][name])
    return out


def test_closed_loop_runs_keep_the_true_traction_inside_the_estimate() -> None:
    """The committed nonlinear-proof gain (tracks [0.8, 1]) on 6 runs with the slip moving at 0.1 /s and pose
    noise 0.5 mm / 0.5 mrad (the estimate allows 6 sigma): every period's estimate holds the traction, and it is
    informative (narrower than the box's 0.1 in most periods); assuming a rate twenty times too low loses it."""
    res = _closed_loop("configs/nonlinear-proof.yaml", "results/baselines/nonlinear-proof/gains.json", 0.1, 0.1, 6)
    assert res["outside"] == 0 and res["inconsistent"] == 0 and res["inside"] > 1000
    assert np.median(res["half"]) < 0.09
    bad = _closed_loop("configs/nonlinear-proof.yaml", "results/baselines/nonlinear-proof/gains.json", 0.1, 0.005, 6)
    assert bad["outside"] + bad["inconsistent"] > 0


def test_the_icr_model_leaves_the_yaw_factor_x_icr_and_the_traction_difference_unobserved() -> None:
    """On the icr default the yaw factor and x_icr have no rate bound: they stay their box; the heading's yaw x d
    hides the traction difference, so each track's estimate is the traction sum's plus d's whole range."""
    res = _closed_loop("configs/default.yaml", "results/baselines/default/gains.json", 0.1, 0.1, 2, noise=0.0)
    assert res["outside"] == 0 and res["inconsistent"] == 0 and res["est"]
    for e in res["est"]:
        assert e["ranges"]["yaw"] == (0.53, 0.70) and e["ranges"]["icr_offset"] == (0.0, 0.10)
        assert not e["observed"]["yaw"] and not e["observed"]["icr_offset"] and not e["observed"]["difference"]
    # the traction sum is seen, by the forward slabs alone
    assert sum(e["observed"]["traction"] for e in res["est"]) > len(res["est"]) // 2
    from robustsynth.artifacts.gains import controller_description, load_gains
    from robustsynth.config import config_to_dict, load_config

    d = config_to_dict(load_config(ROOT / "configs/default.yaml"))
    d["slip"]["max_rate"] = 0.1
    desc = controller_description(load_gains(ROOT / "results/baselines/default/gains.json"), load_config(d))
    bound = slip_estimate_bound(desc)
    assert bound["observable"] is False and bound["half"]["mu_r"] == pytest.approx(bound["box_half"]["mu_r"])
    assert math.isclose(bound["lag"], 0.1 * (0.08 + 0.1 + 0.1))
