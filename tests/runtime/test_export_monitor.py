"""The runtime monitor exported as C99 (runtime/export_monitor.py): compiled, it gives the Python class's status,
command and amounts bit for bit over simulated periods in the envelope and with each kind of violation."""

from __future__ import annotations

import math
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from robustsynth.artifacts.gains import controller_description, load_gains
from robustsynth.config import load_config
from robustsynth.law import Controller
from robustsynth.model import build_model
from robustsynth.monitor import CAUSES, RATE, Monitor
from robustsynth.plants.path import path_of
from robustsynth.runtime.export import c_files
from robustsynth.scenarios import draw_scenario, steady_state_start
from robustsynth.verification.simulate import run_logs, simulate

ROOT = Path(__file__).resolve().parents[2]
CC = shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler")
CONFIGS = ("default", "icr-physics", "nonlinear-proof")  # arcs and icr; a polyline and icr; a polyline and tracks
# every committed robot gain with a certified set (make test-slow), 10 000 periods or more each
ALL = tuple(sorted(p.parent.name for p in (ROOT / "results" / "baselines").glob("*/gains.json")
                   if "ellipsoid_level" in p.read_text() and "\"kind\": \"lti\"" not in p.read_text()
                   # the slip-compensated law has no C99 form yet (tests/runtime/test_export.py: refused)
                   and "\"compensation\": {" not in p.read_text()))
LONG = 10_000  # periods replayed per gain in the slow run


def _periods(name: str, runs: int = 3, periods: int = 0, max_rate: float | None = None):
    """Lines for the harness and the Python monitor's outputs, over simulated runs of the committed gain (one run in
    the envelope, one with a delay spike and a loss, one pushed and given a command beyond the motor limit);
    ``max_rate``: the config's slip.max_rate (the runs' slip still jumps within the box: the rate check fires)."""
    cfg = load_config(ROOT / "configs" / f"{name}.yaml")
    if max_rate is not None:
        cfg = cfg.model_copy(update={"slip": cfg.slip.model_copy(update={"max_rate": max_rate})})
    gains = load_gains(ROOT / "results" / "baselines" / name / "gains.json")
    d = controller_description(gains, cfg)
    model = build_model(cfg)
    K = np.asarray(gains["K"])
    path = path_of(cfg)
    steps = int(path.duration / model.Ts)
    runs = max(runs, -(-periods // steps))
    scen = steady_state_start(model, K, path, draw_scenario(model, runs, 1, steps, path))
    tau = scen.taus.copy()
    tau[1, model.d_hi + 60] = cfg.network.delay.max + 0.05
    tau[1, model.d_hi + 90] = np.inf
    scen = replace(scen, taus=tau)
    logs = run_logs(model, simulate(model, K, path, scen), scen)
    lg = logs[2]
    logs[2] = replace(lg, y=np.where(np.arange(len(lg)) >= 120, lg.y + 0.05, lg.y),
                      rho_r=np.where(np.arange(len(lg)) == 150, 1.5 * (cfg.robot.max_motor_speed or 10.0), lg.rho_r))
    lines, expected = [], []
    R, D = d["gear_radius"], d["track_distance"]
    for lg in logs:
        ctl, mon = Controller(d), Monitor(d)
        lines.append("reset")
        expected.append("reset")
        pending = sorted((float(lg.applied[k]), k) for k in range(len(lg)) if math.isfinite(float(lg.applied[k])))
        nxt = 0
        for k in range(len(lg)):
            t = float(lg.t[k])
            reports = []
            while nxt < len(pending) and pending[nxt][0] <= t + 1e-12:
                reports.append((int(lg.seq[pending[nxt][1]]), pending[nxt][0]))
                nxt += 1
            if k == 90:  # the lost command reported lost (NaN) too, once
                reports.append((89, float("nan")))
            x, y, th = float(lg.x[k]), float(lg.y[k]), float(lg.theta[k])
            ctl.step(t, x, y, th)
            V, w = R / 2.0 * (lg.rho_r[k] + lg.rho_l[k]), R / D * (lg.rho_r[k] - lg.rho_l[k])
            xi = ctl.state
            st, (Vo, wo) = mon.step(t, x, y, th, xi, (float(V), float(w)), int(lg.seq[k]), reports)
            lines.append(" ".join([repr(t), repr(x), repr(y), repr(th), repr(float(V)), repr(float(w)), str(int(lg.seq[k]))]
                                  + [repr(float(v)) for v in xi] + [str(len(reports))]
                                  + [f"{s} {a!r}" for s, a in reports]))
            expected.append((st, Vo, wo, [mon.amounts.get(c, 0.0) for c, _ in CAUSES], int(mon.engaged), _estimate(mon)))
    return c_files(d), lines, expected


def _estimate(mon: Monitor):
    """What the harness prints of the slip estimate after ``E``: consistent (1/0), the windows used and (lo, hi) of
    mu_r, mu_l (and the icr model's yaw, x_icr; (0, 0) where inconsistent)."""
    e = mon.slip_estimate()
    if e is None:
        return None
    return [int(e["consistent"]), e["windows"]] + [v for k in mon.estimate_names for v in e["ranges"].get(k, (0.0, 0.0))]


@pytest.mark.parametrize("name", CONFIGS)
def test_the_c_monitor_is_the_python_monitor_bit_for_bit(name: str, tmp_path: Path) -> None:
    _compare(*_periods(name), tmp_path)


@pytest.mark.parametrize("name", ("default", "nonlinear-proof"))  # icr and tracks
def test_the_c_monitors_rate_check_is_the_pythons(name: str, tmp_path: Path) -> None:
    """With slip.max_rate 0.001 /s (the simulated slip jumps within the box every few periods): the rate check fires,
    and C says what Python says, bit for bit."""
    files, lines, expected = _periods(name, max_rate=0.001)
    assert any(e != "reset" and e[0] & RATE for e in expected)
    _compare(files, lines, expected, tmp_path)


@pytest.mark.parametrize("name", ("default", "nonlinear-proof"))  # icr and tracks
def test_the_c_slip_estimate_is_the_pythons(name: str, tmp_path: Path) -> None:
    """With slip.max_rate 0.1 /s (the simulated slip moves at that rate): the slip estimate of every period, its
    windows and its ranges, bit for bit; most periods estimated from a window, and on the tracks model many narrower
    than the box (on the icr default each track's range is the box: the traction difference is unobserved)."""
    files, lines, expected = _periods(name, max_rate=0.1)
    est = [e[5] for e in expected if e != "reset"]
    narrower = sum(1 for e in est if e[0] and any(hi - lo < 0.999 * (b - a) for (lo, hi), (a, b) in
                                                  zip(zip(e[2:6:2], e[3:6:2]), _box(name))))
    assert narrower > 100 if name == "nonlinear-proof" else narrower == 0
    assert _compare(files, lines, expected, tmp_path) > len(est) // 2


def _box(name: str):
    from robustsynth.model.slip import slip_parameter_ranges

    return slip_parameter_ranges(load_config(ROOT / "configs" / f"{name}.yaml").slip)


@pytest.mark.slow
@pytest.mark.parametrize("name", ALL)
def test_every_committed_gains_c_monitor_is_its_python_monitor_over_10000_periods(name: str, tmp_path: Path) -> None:
    files, lines, expected = _periods(name, periods=LONG)
    assert sum(1 for e in expected if e != "reset") >= LONG
    _compare(files, lines, expected, tmp_path)


def _compare(files, lines, expected, tmp_path: Path) -> None:
    for k, v in files.items():
        (tmp_path / k).write_bytes(v)
    exe = tmp_path / "rs_monitor_harness"
    subprocess.run([CC, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror", "-ffp-contract=off", "-o", str(exe),
                    str(tmp_path / "rs_monitor_harness.c"), str(tmp_path / "rs_monitor.c"), "-lm"], check=True)
    blocks = "\n".join(lines).split("reset\n")[1:]
    exp_blocks, cur = [], None
    for e in expected:
        if e == "reset":
            cur = []
            exp_blocks.append(cur)
        else:
            cur.append(e)
    alarms = estimated = 0
    for block, exp in zip(blocks, exp_blocks):  # one harness run per simulated run: it starts from rs_monitor_init
        out = subprocess.run([str(exe)], input=block + "\n", capture_output=True, text=True, check=True).stdout.split("\n")
        rows = [r for r in out if r]
        assert len(rows) == len(exp)
        for row, (st, Vo, wo, amounts, engaged, est) in zip(rows, exp):
            got = row.split()
            n = 3 + len(CAUSES)
            assert int(got[0]) == st and float(got[1]) == Vo and float(got[2]) == wo, (row, st, Vo, wo)
            assert [float(v) for v in got[3:n]] == amounts and int(got[n]) == engaged, (row, amounts)
            if est is not None:  # the slip estimate, bit for bit: "E ok windows lo hi ..."
                assert got[n + 1] == "E" and [int(got[n + 2]), int(got[n + 3])] == est[:2], (row, est)
                assert [float(v) for v in got[n + 4:n + 2 + len(est)]] == est[2:], (row, est)
                estimated += est[1] > 0
            alarms += bool(st)
    assert alarms > 0  # the violations were there to be seen
    return estimated


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="no valgrind")
@pytest.mark.parametrize("name, max_rate", [("default", None), ("delay-multi-period", None),  # d_hi 3: no command yet
                                             ("nonlinear-proof", 0.1)])  # the slip estimate's windows and clipping
def test_the_c_monitor_reads_no_uninitialised_memory(name: str, max_rate: float | None, tmp_path: Path) -> None:
    """valgrind's memcheck over the harness (every run, violations included): a read of an uninitialised or freed
    value is an error (an empty schedule once read its entry -1: bit-identical by luck until a long run)."""
    files, lines, _ = _periods(name, max_rate=max_rate)
    for k, v in files.items():
        (tmp_path / k).write_bytes(v)
    exe = tmp_path / "rs_monitor_harness"
    subprocess.run([CC, "-std=c99", "-O0", "-g", "-o", str(exe), str(tmp_path / "rs_monitor_harness.c"),
                    str(tmp_path / "rs_monitor.c"), "-lm"], check=True)
    for block in "\n".join(lines).split("reset\n")[1:]:
        r = subprocess.run(["valgrind", "-q", "--error-exitcode=9", str(exe)], input=block + "\n", capture_output=True,
                           text=True)
        assert r.returncode == 0, r.stderr[:2000]
