"""The runtime monitor over simulated robots (robustsynth.runtime.replay, issue 54): in the envelope, with pose
noise, it raises nothing; each kind of violation injected into the simulator (a delay spike, a loss burst, slip
outside the box, a push out of the set, a saturated command) is flagged within two periods (slip: once its window
is full), its cause named; the CLI replays logs with one line per alarm and refuses bad input."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from robustsynth.artifacts.gains import controller_description, load_gains
from robustsynth.artifacts.logs import write_log
from robustsynth.config import config_to_dict, load_config
from robustsynth.model import build_model
from robustsynth.plants.path import path_of
from robustsynth.runtime.replay import monitor_log, monitor_logs
from robustsynth.scenarios import draw_scenario, steady_state_start
from robustsynth.robot_verification.simulate import run_logs, simulate

ROOT = Path(__file__).resolve().parents[2]
NOISE = (0.0005, 0.0005)  # [m], [rad]: the pose noise of the runs (verification.noise; a motion-capture or RTK pose)
K0 = 150  # the period the violations start at (a straight stretch of the default's path)
DETECT = 2  # periods: every violation but slip is flagged within this many


@pytest.fixture(scope="module")
def default():
    """The default's committed gain under its config with pose noise: model, K, description, path, steps."""
    d = config_to_dict(load_config(ROOT / "configs" / "default.yaml"))
    d["verification"]["noise"] = {"position": NOISE[0], "heading": NOISE[1]}
    cfg = load_config(d)
    gains = load_gains(ROOT / "results" / "baselines" / "default" / "gains.json")
    model = build_model(cfg)
    path = path_of(cfg)
    return model, np.asarray(gains["K"]), controller_description(gains, cfg), path, int(path.duration / model.Ts)


def _runs(default, runs, seed=0, **change):
    model, K, desc, path, steps = default
    scen = steady_state_start(model, K, path, draw_scenario(model, runs, seed, steps, path, within_period=True))
    for key, fn in change.items():
        scen = replace(scen, **{key: fn(getattr(scen, key).copy())})
    return run_logs(model, simulate(model, K, path, scen), scen)


def test_in_the_envelope_with_pose_noise_nothing_is_raised(default) -> None:
    """100 Monte Carlo runs of the default's path (slip anywhere in its box, changing within periods, delays in
    [tau_min, tau_max], pose noise 0.5 mm / 0.5 mrad): no alarm in any period (make bench runs 1000)."""
    res = monitor_logs(_runs(default, 100, seed=3), default[2])
    assert res["runs_with_alarms"] == 0, res["first"]


def _first(log, desc):
    r = monitor_log(log, desc)
    return (r["alarms"][0]["period"], r["alarms"][0]["causes"]) if r["alarms"] else (None, "")


def test_each_injected_violation_is_flagged_with_its_cause(default) -> None:
    model, K, desc, path, steps = default
    d = model.d_hi

    def spike(tau):
        tau[:, d + K0] = model.config.network.delay.max + 0.07
        return tau

    def burst(tau):
        tau[:, d + K0: d + K0 + model.config.network.dropouts.max_consecutive + 1] = np.inf
        return tau

    def patch(mu):
        mu[:, K0:, :2] = 0.6  # a friction patch: traction far below the box's 0.97
        return mu

    cases = {"delay spike": (_runs(default, 2, taus=spike), "losses"),
             "loss burst": (_runs(default, 2, taus=burst), "losses"),
             "friction patch": (_runs(default, 2, mu=patch), None)}
    for name, (logs, cause) in cases.items():
        for log in logs:
            k, causes = _first(log, desc)
            assert k is not None and K0 <= k <= K0 + DETECT + (model.config.monitor.window if cause is None else 0), (name, k, causes)
            if cause is not None:
                assert cause in causes, (name, causes)
    # the late command's own report: a delay beyond tau_max, the period after
    r = monitor_log(cases["delay spike"][0][0], desc)
    assert any("delay" in a["causes"] for a in r["alarms"] if a["period"] <= K0 + DETECT)
    # a push: the robot's poses 5 cm aside from K0 on; a saturated command at K0
    log = _runs(default, 1, seed=5)[0]
    pushed = replace(log, y=np.where(np.arange(len(log)) >= K0, log.y + 0.05, log.y))
    assert _first(pushed, desc) == (K0, "set, slip")
    rho = log.rho_r.copy()
    rho[K0] = 1.5 * model.config.robot.max_motor_speed
    assert _first(replace(log, rho_r=rho), desc) == (K0, "motor")


def test_the_monitor_command_replays_logs_and_refuses_bad_input(default, tmp_path) -> None:
    logs = _runs(default, 2, taus=lambda tau: np.where(np.arange(tau.shape[1]) == default[0].d_hi + K0, 0.2, tau))
    for lg in logs:
        write_log(tmp_path / lg.path, lg)
    gains = ROOT / "results" / "baselines" / "default" / "gains.json"
    run = lambda *a: subprocess.run([sys.executable, "-m", "robustsynth", "monitor", *a], capture_output=True, text=True)
    r = run(*(str(tmp_path / lg.path) for lg in logs), "--gains", str(gains), "-o", str(tmp_path / "out"))
    assert r.returncode == 1, r.stderr
    assert f"period {K0 + 1} (t = {(K0 + 1) * 0.1:.3f} s): losses by 1" in r.stdout
    assert "monitor: 2 of 2 logs with alarms" in r.stdout and (tmp_path / "out" / "monitor.json").exists()
    truncated = tmp_path / "cut.csv"
    truncated.write_bytes((tmp_path / logs[0].path).read_bytes()[:300])
    lti = ROOT / "results" / "baselines" / "dc-motor" / "gains.json"
    for args in ([str(truncated), "--gains", str(gains)], [str(tmp_path / logs[0].path), "--gains", str(lti)],
                 [str(tmp_path / logs[0].path), "--gains", str(ROOT / "configs" / "default.yaml")]):
        r = run(*args, "-o", str(tmp_path / "bad"))
        assert r.returncode == 2 and r.stderr.startswith("error: ") and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert "Traceback" not in r.stderr and not (tmp_path / "bad").exists()


def test_with_a_slip_rate_the_monitor_command_prints_and_records_the_slip_estimate(tmp_path) -> None:
    """tracks-box (tracks [0.6, 1]) with slip.max_rate 0.1 and exact poses: the replay's slip estimate over the
    logs is printed and written, and it is informative (the box's half-width is 0.2)."""
    import json

    import yaml

    d = config_to_dict(load_config(ROOT / "configs" / "tracks-box.yaml"))
    d["slip"]["max_rate"] = 0.1
    (tmp_path / "rate.yaml").write_text(yaml.safe_dump(d))
    cfg = load_config(d)
    gains = ROOT / "results" / "baselines" / "tracks-box" / "gains.json"
    model, path = build_model(cfg), path_of(cfg)
    K = np.asarray(load_gains(gains)["K"])
    scen = steady_state_start(model, K, path, draw_scenario(model, 2, 0, 120, path, within_period=True))
    for lg in run_logs(model, simulate(model, K, path, scen), scen):
        write_log(tmp_path / lg.path, lg)
    r = subprocess.run([sys.executable, "-m", "robustsynth", "monitor", *(str(p) for p in sorted(tmp_path.glob("run_*.csv"))),
                        "--gains", str(gains), "--config", str(tmp_path / "rate.yaml"), "-o", str(tmp_path / "out")],
                       capture_output=True, text=True)
    assert r.returncode in (0, 1), r.stderr
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("slip estimate over "))
    est = json.loads((tmp_path / "out" / "monitor.json").read_text())["slip_estimate"]
    assert est["periods"] > 200 and est["inconsistent"] == 0
    assert est["parameters"]["mu_r"]["median_half"] < 0.1 and "mu_r within +-" in line
