"""The slip-compensated law in closed loop (robustsynth.robot_verification.simulate.simulate_compensated and
robustsynth.robot_verification.compensated; docs/theory.md §18): the simulated law is the deployed one bit for bit (the
vectorized loop against Compensator.step per robot), the committed certificate holds wherever its condition does,
and when the slip moves faster than the monitor assumes the checks fail (the negative control)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from robustsynth.config import config_from_dict, config_to_dict, load_config
from robustsynth.model import build_model

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "configs" / "harsh-compensated.yaml"
GAINS = ROOT / "results" / "baselines" / "harsh-compensated" / "gains.json"
IDENT_TOL = 0.01  # identify's box against the runs' true slip range (measured: within 0.004 on the 4 runs below)


@pytest.fixture(scope="module")
def setup():
    from robustsynth.artifacts.gains import controller_description
    from robustsynth.certificate import check_certificate
    from robustsynth.plants.path import path_of

    cfg = load_config(CONFIG)
    model = build_model(cfg)
    gains = json.loads(GAINS.read_text())
    K = np.asarray(gains["K"], dtype=float)
    cert = check_certificate(model, K, gains["certificate"])
    return cfg, model, gains, K, cert, controller_description(gains, cfg), path_of(cfg)


def test_the_simulated_compensated_law_is_the_deployed_one_bit_for_bit(setup) -> None:
    """3 runs of 80 periods: per robot, the deployed Controller, Monitor and Compensator (floats, Compensator.step),
    given the poses the simulated robot took, send exactly the motor speeds the vectorized simulation sent and see
    the same status, estimate and condition; the monitor's fallback is kept out (persistence beyond the run), as in
    verify's runs.  (The robot itself is the simulator's; only the controller is compared.)"""
    from robustsynth.law import Compensator, Controller
    from robustsynth.monitor import Monitor
    from robustsynth.scenarios import draw_scenario
    from robustsynth.robot_verification.compensated import true_robot
    from robustsynth.robot_verification.simulate import applied_times, simulate_compensated

    cfg, model, gains, K, cert, desc, path = setup
    desc = dict(desc, monitor=dict(desc["monitor"], persistence=1000))
    robot_model = true_robot(cfg)
    scen = draw_scenario(robot_model, 3, 5, 80, path, within_period=True)
    res = simulate_compensated(robot_model, K, path, scen, desc)
    applied = applied_times(robot_model, scen.taus, scen.steps)
    Ts = robot_model.Ts
    compared = 0
    for n in range(scen.runs):
        ctl, mon, comp = Controller(desc), Monitor(desc), Compensator(desc)
        order = sorted((float(applied[n, j]), j) for j in range(scen.steps) if np.isfinite(applied[n, j]))
        for k in range(scen.steps):
            t = k * Ts
            reports = [(j, a) for a, j in order if (k == 0 or a > (k - 1) * Ts + 1e-12) and a <= t + 1e-12]
            meas = res.sim.q[n, k] + scen.noise[n, k]
            status, out = comp.step(ctl, mon, t, float(meas[0]), float(meas[1]), float(meas[2]), k, reports)
            assert status == res.status[n, k] and comp.holds == res.holds[n, k] and comp.mu == tuple(res.mu_hat[n, k])
            assert out == tuple(res.sent[n, k]), (n, k)
            compared += 1
    assert compared == 240 and res.holds.any() and (res.mu_hat != 0.8).any()


def test_the_committed_certificate_holds_wherever_its_condition_does(setup) -> None:
    """20 runs with the estimator in the loop on the true slip ([0.6, 1.04] moving at 0.02 /s): every check passes,
    the condition holds in most periods (the misses: the estimator's first periods), and the robot's errors on the
    covered samples stay within the certified bounds."""
    from robustsynth.robot_verification.compensated import compensated_checks

    cfg, model, gains, K, cert, desc, path = setup
    assert cert.passed
    checks, rec, runs = compensated_checks(model, K, cert, gains, 20, 0)
    assert checks and all(c["passed"] for c in checks), [c for c in checks if not c["passed"]]
    assert rec["condition_held_share"] > 0.9 and rec["steps_judged"] > 0.9 * 20 * rec["steps"]
    assert rec["condition_first_period"]["max"] <= 5
    assert all(v <= 1.0 for v in rec["ratio_to_certified"].values())
    assert rec["estimate_unsound_steps"] == 0 and rec["steps_leaving_the_set"] == 0
    # a jump of the traction (not certified, measured): the monitor sees it within two periods, every run recovers
    jump = rec["jump"]
    assert jump["jump_size_min"] >= 0.2 and jump["condition_lost_after"]["max"] <= 2
    assert jump["recovery_periods"]["runs_never"] == 0 and jump["back_in_the_set_periods"]["runs_never"] == 0
    assert jump["max_V_over_level_in_recovery"] > 1.0  # the jump throws the state out (nothing is claimed there)


def test_a_slip_faster_than_the_monitor_assumes_fails_the_checks(setup) -> None:
    """The negative control: the true traction moves at 2 /s (a hundred times the stated 0.02 /s) while the monitor
    and the compensator believe the config.  The estimate then claims its condition where a command meets a
    traction farther than the error from it, and the robot leaves its set on steps the condition covered."""
    from robustsynth.scenarios import draw_scenario
    from robustsynth.robot_verification.compensated import judge, true_robot
    from robustsynth.robot_verification.simulate import simulate_compensated

    cfg, model, gains, K, cert, desc, path = setup
    d = config_to_dict(cfg)
    d["slip"]["max_rate"] = 2.0
    d["slip"]["compensation"] = {"error": gains["compensation"]["error"]}  # the same ratio box, the rate unknown to it
    fast = true_robot(config_from_dict(d))
    steps = int(math.floor(path.duration / model.Ts))
    scen = draw_scenario(fast, 20, 0, steps, path, within_period=True)
    res = simulate_compensated(fast, K, path, scen, desc)
    checks, rec = judge(model, cert, gains, desc, scen, res, 0)
    failed = {c["name"] for c in checks if not c["passed"]}
    assert "compensated: the estimate holds the true traction whenever its condition holds" in failed
    assert rec["estimate_unsound_steps"] > 0


def test_the_runs_logs_carry_the_estimate_and_replay_check_log_and_identify_read_it(setup, tmp_path) -> None:
    """verify --log of a compensated law writes its runs on the true slip with the estimate's columns: the monitor's
    replay of each log finds the logged estimate and condition its own in every period (the log holds motor speeds,
    so the traction agrees to ESTIMATE_TOL), a log whose estimate was moved by 1e-6 does not; check-log counts the
    periods the condition did not hold after it first held; identify, reading the commands that acted (compensated),
    finds the range of the runs' true traction."""
    import dataclasses

    from robustsynth.artifacts.logs import read_log, write_log
    from robustsynth.identification import check_log, identify
    from robustsynth.runtime.replay import monitor_logs
    from robustsynth.robot_verification.compensated import compensated_checks

    cfg, model, gains, K, cert, desc, path = setup
    _, _, runs = compensated_checks(model, K, cert, gains, 4, 0)
    logs = runs.logs()
    for lg in logs:
        write_log(tmp_path / lg.path, lg)
    back = [read_log(tmp_path / lg.path) for lg in logs]
    assert all(b.estimate is not None and np.array_equal(b.estimate, lg.estimate) for b, lg in zip(back, logs))
    rep = monitor_logs(back, desc)["compensation"]
    assert rep["logs_with_the_estimate"] == 4 and rep["periods_the_logged_estimate_differs"] == 0
    assert rep["condition_held_share"] == pytest.approx(float(runs.holds.mean()), abs=1e-12)
    moved = dataclasses.replace(back[0], estimate=back[0].estimate + np.array([1e-6, 0.0, 0.0]))
    assert monitor_logs([moved], desc)["compensation"]["periods_the_logged_estimate_differs"] > 0
    row = next(r for r in check_log(back, cfg) if r["assumption"].startswith("slip.compensation"))
    after_first = sum(len(lg) - int(np.argmax(lg.estimate[:, 2] == 1.0)) for lg in back)
    assert row["samples"] == after_first and row["outside"] == int(sum(
        np.sum(lg.estimate[int(np.argmax(lg.estimate[:, 2] == 1.0)):, 2] == 0.0) for lg in back))
    ident = identify(back, cfg.robot.gear_radius, cfg.robot.track_distance, max_motor_speed=cfg.robot.max_motor_speed)
    for i, side in enumerate(("right", "left")):
        lo, hi = ident.box[side]
        true = runs.scen.mu[..., i]
        assert abs(lo - true.min()) <= IDENT_TOL and abs(hi - true.max()) <= IDENT_TOL, (side, lo, hi, true.min(), true.max())
