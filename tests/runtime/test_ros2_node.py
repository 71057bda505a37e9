"""The ROS 2 node export (issue 54): `export --to ros2` writes the parameters, rs_controller.py and rs_node.py; the
node's loop (plain Python; rclpy only in its main) runs the exported law and monitor on the node's clock with the
base's reports, and says what `robustsynth monitor` says of the same run."""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from robustsynth.artifacts.gains import controller_description, load_gains
from robustsynth.config import load_config
from robustsynth.model import build_model
from robustsynth.plants.path import path_of
from robustsynth.runtime.export import export_controller
from robustsynth.runtime.replay import monitor_log
from robustsynth.scenarios import draw_scenario
from robustsynth.robot_verification.simulate import run_logs, simulate

ROOT = Path(__file__).resolve().parents[2]
T0 = 1733.25  # the node clock at the path's start [s]: the loop must count from it
LATE = 0.003  # the timer's callbacks run this late [s]; the base stamps an application on the same clock
K0 = 150
COMMAND_TOL = 1e-12  # the simulator's vectorized law against the exported one, per command [m/s, rad/s]


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    return mod


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    out = tmp_path_factory.mktemp("ros2")
    export_controller(ROOT / "results" / "baselines" / "default" / "gains.json", "ros2", out)
    return out


def test_the_export_writes_the_node_beside_its_parameters_and_the_law(exported) -> None:
    assert sorted(p.name for p in exported.iterdir()) == ["rs_controller.py", "rs_controller.ros2.yaml", "rs_node.py"]
    params = yaml.safe_load((exported / "rs_controller.ros2.yaml").read_text())["robustsynth_controller"]["ros__parameters"]
    ctl = _load(exported / "rs_controller.py", "rs_controller")
    assert params["gains_id"] == ctl.DESCRIPTION["gains_id"] and params["has_monitor"]
    # importable without ROS 2: rclpy only inside main(), which says what is missing
    r = subprocess.run([sys.executable, "-c", "import rs_node, sys; sys.exit(0 if 'rclpy' not in sys.modules else 3)"],
                       cwd=exported, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([sys.executable, "rs_node.py"], cwd=exported, capture_output=True, text=True)
    if importlib.util.find_spec("rclpy") is None:
        assert r.returncode == 1 and "rs_node needs ROS 2 (rclpy" in r.stderr and "Traceback" not in r.stderr


def test_yaw_of_a_quaternion() -> None:
    from robustsynth.runtime.ros2_node import yaw_of

    for yaw in np.linspace(-3.1, 3.1, 13):
        assert yaw_of(0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)) == pytest.approx(yaw, abs=1e-12)


def test_the_nodes_loop_says_what_the_monitor_replay_says(exported) -> None:
    """A simulated run of the default with a loss burst from period K0: the node's loop, fed the run's poses and the
    base's reports on a clock starting at T0, sends the run's commands and raises, period by period, the statuses
    `robustsynth monitor` raises over the run's log, until its fallback engages; from then on it sends the fallback's
    command (the log's run went on with the law's: there the two part)."""
    ctl_mod = _load(exported / "rs_controller.py", "rs_controller")
    node = _load(exported / "rs_node.py", "rs_node")
    cfg = load_config(ROOT / "configs" / "default.yaml")
    gains = load_gains(ROOT / "results" / "baselines" / "default" / "gains.json")
    model, K, path = build_model(cfg), np.asarray(gains["K"]), path_of(cfg)
    steps = int(path.duration / model.Ts)
    scen = draw_scenario(model, 1, 4, steps, path, within_period=True)  # from rest: the node's law starts with no memory
    taus = scen.taus.copy()
    taus[:, model.d_hi + K0: model.d_hi + K0 + cfg.network.dropouts.max_consecutive + 2] = np.inf
    scen = replace(scen, taus=taus)
    log = run_logs(model, simulate(model, K, path, scen), scen)[0]
    desc = controller_description(gains, cfg)
    want = monitor_log(log, desc)
    loop = node.Loop(ctl_mod.Controller(), ctl_mod.Monitor())
    pending = sorted((float(log.applied[k]), int(log.seq[k])) for k in range(len(log)) if math.isfinite(float(log.applied[k])))
    R, D = float(cfg.robot.gear_radius), float(cfg.robot.track_distance)
    statuses, nxt, engaged = [], 0, None
    for k in range(len(log)):
        t = float(log.t[k])
        while nxt < len(pending) and pending[nxt][0] <= t + 1e-12:
            loop.applied(pending[nxt][1], T0 + LATE + pending[nxt][0])
            nxt += 1
        V, omega, seq, status = loop.tick(T0 + LATE + t, float(log.x[k]), float(log.y[k]), float(log.theta[k]))
        assert seq == k
        statuses.append(status)
        if engaged is None and loop.monitor.engaged:
            engaged = k
        if engaged is None:
            assert V == pytest.approx(R / 2 * (log.rho_r[k] + log.rho_l[k]), abs=COMMAND_TOL), k
            assert omega == pytest.approx(R / D * (log.rho_r[k] - log.rho_l[k]), abs=COMMAND_TOL), k
        elif desc["monitor"]["fallback"] == "stop":
            assert (V, omega) == (0.0, 0.0)
    assert next(k for k, s in enumerate(statuses) if s) == K0 + 1 and statuses[K0 + 1] & 2  # losses
    assert engaged == want["fallback_engaged_at"] and statuses[:engaged + 1] == want["statuses"][:engaged + 1]


def test_the_loop_publishes_the_monitors_slip_estimate_only_with_a_rate() -> None:
    """The slip_estimate topic's data: the monitor's estimate of the period ([consistent, windows, lo, hi per
    parameter]) where the config has slip.max_rate, None (nothing published) without."""
    from robustsynth.law import Controller
    from robustsynth.monitor import Monitor
    from robustsynth.runtime.ros2_node import Loop

    gains = load_gains(ROOT / "results" / "baselines" / "nonlinear-proof" / "gains.json")
    cfg = load_config(ROOT / "configs" / "nonlinear-proof.yaml")
    rated = cfg.model_copy(update={"slip": cfg.slip.model_copy(update={"max_rate": 0.1})})
    for c, expect in ((cfg, False), (rated, True)):
        desc = controller_description(gains, c)
        loop = Loop(Controller(desc), Monitor(desc))
        x, acting = 0.0, 0.0
        for k in range(15):  # straight ahead at traction 0.9, every command applied 50 ms after its instant
            if k:
                loop.applied(k - 1, T0 + (k - 1) * 0.1 + 0.05)
            V, _, _, _ = loop.tick(T0 + k * 0.1, x, 0.0, 0.0)
            x, acting = x + 0.9 * (0.05 * acting + 0.05 * V), V
        msg = loop.slip_estimate_message()
        if not expect:
            assert msg is None
            continue
        e = loop.monitor.slip_estimate()
        assert msg == [1.0, float(e["windows"]), *e["ranges"]["mu_r"], *e["ranges"]["mu_l"], *e["ranges"]["traction"],
                       *e["ranges"]["difference"]] and e["windows"] > 0


def test_the_nodes_loop_runs_the_compensated_law_as_compensator_step(tmp_path: Path) -> None:
    """The committed slip-compensated gain (docs/theory.md §18), exported to ROS 2: the node's loop, with the exported
    Compensator, fed a closed-loop run's poses and the base's reports on a clock starting at T0, sends exactly what
    ``Compensator.step`` sends for the same inputs and publishes on ``compensation`` its condition, margin and the
    tractions divided by, period by period (==); the condition fails in the first periods (the estimator's warm-up),
    then holds.  An uncompensated loop publishes nothing there."""
    from robustsynth.law import Compensator, Controller
    from robustsynth.monitor import Monitor
    from robustsynth.robot_verification.compensated import true_robot
    from robustsynth.robot_verification.simulate import applied_times, simulate_compensated

    name = "harsh-compensated"
    out = tmp_path / "ros2"
    export_controller(ROOT / "results" / "baselines" / name / "gains.json", "ros2", out)
    params = yaml.safe_load((out / "rs_controller.ros2.yaml").read_text())["robustsynth_controller"]["ros__parameters"]
    assert params["has_compensation"] and all(v is not None for v in params.values())
    ctl_mod = _load(out / "rs_controller.py", "rs_controller_compensated")
    node = _load(out / "rs_node.py", "rs_node_compensated")
    cfg = load_config(ROOT / "configs" / f"{name}.yaml")
    gains = load_gains(ROOT / "results" / "baselines" / name / "gains.json")
    desc = controller_description(gains, cfg)
    robot, path = true_robot(cfg), path_of(cfg)
    scen = draw_scenario(robot, 1, 2, int(path.duration / robot.Ts), path, within_period=True)
    res = simulate_compensated(robot, np.asarray(gains["K"]), path, scen, desc)
    applied = applied_times(robot, scen.taus, scen.steps)[0]
    loop = node.Loop(ctl_mod.Controller(), ctl_mod.Monitor(), ctl_mod.Compensator())
    ctl, mon, comp = Controller(desc), Monitor(desc), Compensator(desc)
    pending = sorted((float(applied[j]), j) for j in range(scen.steps) if math.isfinite(float(applied[j])))
    start, nxt, held = T0 + LATE, 0, []
    for k in range(scen.steps):
        t = k * robot.Ts
        reports = []
        while nxt < len(pending) and pending[nxt][0] <= t + 1e-12:
            loop.applied(pending[nxt][1], start + pending[nxt][0])
            reports.append((pending[nxt][1], (start + pending[nxt][0]) - start))  # the node's clock, as it reads it
            nxt += 1
        x, y, th = (float(v) for v in res.sim.q[0, k] + scen.noise[0, k])
        V, omega, seq, status = loop.tick(start + t, x, y, th)
        want_status, want = comp.step(ctl, mon, t, x, y, th, k, reports)
        assert (seq, status, (V, omega)) == (k, want_status, want), k
        msg = loop.compensation_message()
        assert msg[:2] == [float(comp.holds), float(comp.covered)] and tuple(msg[3:]) == comp.mu, k
        assert math.isnan(msg[2]) if comp.margin is None else msg[2] == comp.margin, k
        held.append(comp.holds)
    assert not held[0] and sum(held) > 0.9 * len(held)
    plain = node.Loop(ctl_mod.Controller(), ctl_mod.Monitor())  # no compensator: the ordinary law, nothing published
    plain.tick(start, 0.0, 0.0, 0.0)
    assert plain.compensation_message() is None
