"""The runtime monitor exported as C99 (runtime/export_monitor.py): compiled, it gives the Python class's status,
command and amounts bit for bit over simulated periods in the envelope and with each kind of violation; for the
slip-compensated law, its compensated step is Compensator.step's bit for bit over closed-loop runs."""

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
from robustsynth.robot_verification.simulate import run_logs, simulate

ROOT = Path(__file__).resolve().parents[2]
CC = shutil.which("cc") or shutil.which("gcc")
pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler")
CONFIGS = ("default", "icr-physics", "nonlinear-proof")  # arcs and icr; a polyline and icr; a polyline and tracks
# every committed robot gain with a certified set (make test-slow), 10 000 periods or more each
ALL = tuple(sorted(p.parent.name for p in (ROOT / "results" / "baselines").glob("*/gains.json")
                   if "ellipsoid_level" in p.read_text() and "\"kind\": \"lti\"" not in p.read_text()))
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
    for block, r in _under_valgrind(files, lines, tmp_path):
        assert r.returncode == 0, r.stderr[:2000]


def _under_valgrind(files: dict, lines: list[str], tmp_path: Path, *args: str) -> list:
    """The harness built at -O0 -g from ``files`` and run under valgrind's memcheck once per run of ``lines`` (the
    blocks between 'reset' lines), with ``args``: (block, completed process) per run."""
    for k, v in files.items():
        (tmp_path / k).write_bytes(v)
    exe = tmp_path / "rs_monitor_harness"
    subprocess.run([CC, "-std=c99", "-O0", "-g", "-o", str(exe), str(tmp_path / "rs_monitor_harness.c"),
                    str(tmp_path / "rs_monitor.c"), "-lm"], check=True)
    return [(block, subprocess.run(["valgrind", "-q", "--error-exitcode=9", str(exe), *args], input=block + "\n",
                                   capture_output=True, text=True))
            for block in "\n".join(lines).split("reset\n")[1:]]


# ------------------------------------------------------------------ the slip-compensated law (docs/theory.md §18)

COMPENSATED = "harsh-compensated"  # the committed compensated gain


class _Recording:
    """A Controller whose step also keeps the law's command (what the C step is given beside xi)."""

    def __init__(self, controller: Controller) -> None:
        self.controller, self.command = controller, None

    def step(self, t, x, y, theta):
        self.command = self.controller.step(t, x, y, theta)
        return self.command

    @property
    def state(self):
        return self.controller.state


def _compensated_periods(runs: int, seed: int = 3, error: float | None = None):
    """Lines for the harness's --compensated mode and Compensator.step's outputs, over ``runs`` closed-loop runs of the
    committed compensated gain on its true slip (simulate_compensated: [0.6, 1] moving at 0.02 /s, the estimator in the
    loop), each run from the box's centre (the condition fails in its first periods), replayed period by period
    through Compensator.step with the reports of the commands applied by t_k; run 1 with a delay spike and a lost
    command (reported lost), run 2 with the poses pushed 5 cm sideways from period 120 (the set check fires): the
    fallback engages in both.  ``error``: the description's compensation error in place of the gain's (a smaller one:
    the condition fails with a margin below 0 in many periods).  Returns the files, the lines, the expected outputs,
    the sent commands' motor speeds and the description."""
    from robustsynth.law import Compensator
    from robustsynth.robot_verification.compensated import true_robot
    from robustsynth.robot_verification.simulate import applied_times, simulate_compensated

    cfg = load_config(ROOT / "configs" / f"{COMPENSATED}.yaml")
    gains = load_gains(ROOT / "results" / "baselines" / COMPENSATED / "gains.json")
    d = controller_description(gains, cfg)
    if error is not None:
        d = dict(d, compensation=dict(d["compensation"], error=error))
    robot, path = true_robot(cfg), path_of(cfg)
    steps = int(path.duration / robot.Ts)
    scen = draw_scenario(robot, runs, seed, steps, path, within_period=True)
    tau = scen.taus.copy()
    tau[1, robot.d_hi + 60] = cfg.network.delay.max + 0.05
    tau[1, robot.d_hi + 90] = np.inf
    scen = replace(scen, taus=tau)
    res = simulate_compensated(robot, np.asarray(gains["K"]), path, scen, d)
    applied = applied_times(robot, scen.taus, scen.steps)
    lines, expected, rhos = [], [], []
    for n in range(runs):
        ctl, mon, comp = _Recording(Controller(d)), Monitor(d), Compensator(d)
        lines.append("reset")
        expected.append("reset")
        order = sorted((float(applied[n, j]), j) for j in range(steps) if np.isfinite(applied[n, j]))
        for k in range(steps):
            t = k * robot.Ts
            reports = [(j, a) for a, j in order if (k == 0 or a > (k - 1) * robot.Ts + 1e-12) and a <= t + 1e-12]
            if n == 1 and k == 91:  # the lost command reported lost (NaN)
                reports.append((90, float("nan")))
            x, y, th = (float(v) for v in res.sim.q[n, k] + scen.noise[n, k])
            if n == 2 and k >= 120:
                y += 0.05
            st, out = comp.step(ctl, mon, t, x, y, th, k, reports)
            V, w = ctl.command
            lines.append(" ".join([repr(t), repr(x), repr(y), repr(th), repr(V), repr(w), str(k)]
                                  + [repr(float(v)) for v in ctl.state] + [str(len(reports))]
                                  + [f"{s} {a!r}" for s, a in reports]))
            cstate = (int(comp.holds), int(comp.covered), comp.wait, int(comp.margin is not None),
                      0.0 if comp.margin is None else comp.margin, comp.mu[0], comp.mu[1])
            expected.append((st, out[0], out[1], [mon.amounts.get(c, 0.0) for c, _ in CAUSES], int(mon.engaged),
                             _estimate(mon), cstate))
            rhos.append(mon._rho(*out))
    return c_files(d), lines, expected, rhos, d


def _compensated_outputs(files, lines, tmp_path: Path):
    """The harness's --compensated output rows, one list per run (compiled as the other tests compile it)."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    for k, v in files.items():
        (tmp_path / k).write_bytes(v)
    exe = tmp_path / "rs_monitor_harness"
    subprocess.run([CC, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror", "-ffp-contract=off", "-o", str(exe),
                    str(tmp_path / "rs_monitor_harness.c"), str(tmp_path / "rs_monitor.c"), "-lm"], check=True)
    return [[r for r in subprocess.run([str(exe), "--compensated"], input=block + "\n", capture_output=True, text=True,
                                       check=True).stdout.split("\n") if r]
            for block in "\n".join(lines).split("reset\n")[1:]]


def _first_difference(outputs, expected):
    """(run, period, what) of the first row where the C step's output is not Compensator.step's, exactly: the
    ``status``, the slip ``estimate``, the compensator's ``condition`` (holds, covered, wait, whether there is a
    margin), ``margin`` or ``mu``, the ``command`` sent, the ``amounts`` or ``engaged``; None when every row is."""
    runs = [[]]
    for e in expected[1:]:
        if e == "reset":
            runs.append([])
        else:
            runs[-1].append(e)
    assert len(outputs) == len(runs)
    n = 3 + len(CAUSES)
    for r, (rows, exp) in enumerate(zip(outputs, runs)):
        assert len(rows) == len(exp)
        for k, (row, (st, Vo, wo, amounts, engaged, est, cs)) in enumerate(zip(rows, exp)):
            got = row.split()
            c = got.index("C")
            checks = (("status", int(got[0]) == st),  # in the order each depends on the one before
                      ("estimate", got[n + 1] == "E" and [int(got[n + 2]), int(got[n + 3])]  # the tracks' 4 ranges
                       + [float(v) for v in got[n + 4:n + 2 + len(est)]] == est),
                      ("condition", [int(v) for v in got[c + 1:c + 5]] == list(cs[:4])),
                      ("margin", float(got[c + 5]) == cs[4]), ("mu", (float(got[c + 6]), float(got[c + 7])) == cs[5:]),
                      ("command", (float(got[1]), float(got[2])) == (Vo, wo)),
                      ("amounts", [float(v) for v in got[3:n]] == amounts), ("engaged", int(got[n]) == engaged))
            for what, same in checks:
                if not same:
                    return r, k, what
    return None


@pytest.fixture(scope="module")
def compensated_long():
    """31 closed-loop runs of the committed compensated gain: 10 106 periods."""
    return _compensated_periods(runs=31)


def test_the_c_compensated_step_is_compensator_step_bit_for_bit(compensated_long, tmp_path: Path) -> None:
    """rs_compensator_step against Compensator.step over >= 10 000 replayed periods of the committed compensated gain:
    the status, the compensated command sent (the fallback's once engaged), the amounts, the slip estimate, whether
    the condition holds and is covered, the wait, the margin and the estimate divided by, every period exactly (==).
    The runs cover the estimator's warm-up (the condition fails in each run's first periods), the fallback (engaged in the two runs with violations) and commands the motors turn beyond the
    certificate's limit but within their own (rho_limit < rho <= saturation_limit: judged by the slip estimate)."""
    files, lines, expected, rhos, d = compensated_long
    rows = [e for e in expected if e != "reset"]
    assert len(rows) >= LONG
    first = [expected[i + 1] for i, e in enumerate(expected) if e == "reset"]
    assert all(e[6][0] == 0 and e[6][1] == 0 for e in first)  # each run starts with the condition not (yet) holding
    held = [e[6][0] for e in rows]
    assert 0.9 * len(rows) < sum(held) < len(rows)
    assert {e[6][3] for e in rows} == {0, 1}  # periods without an estimate (no margin) and with one
    assert sum(e[4] for e in rows) > 0 and any(e[0] for e in rows)  # the fallback engaged, alarms raised
    m = d["monitor"]
    assert sum(1 for r in rhos if m["rho_limit"] < r <= m["saturation_limit"]) > 100
    assert _first_difference(_compensated_outputs(files, lines, tmp_path), expected) is None


def test_the_c_compensated_step_is_compensator_step_where_the_margin_is_below_zero(tmp_path: Path) -> None:
    """With the compensation error at the a-priori bound (0.0316, factor 1: docs/theory.md §18) in place of the gain's
    0.0474, the estimate is consistent but not within it in many periods (margin < 0, holds 0, the wait restarting):
    6 runs, every period exactly as Compensator.step."""
    files, lines, expected, _, _ = _compensated_periods(runs=6, seed=5, error=0.0316)
    rows = [e for e in expected if e != "reset"]
    below = [e for e in rows if e[6][3] and e[6][4] < 0.0]
    assert len(below) > 100 and all(e[6][0] == 0 and e[6][2] == 2 for e in below)  # wait back to d_hi + 1
    assert sum(e[6][0] for e in rows) > len(rows) // 2 and sum(e[6][1] for e in rows) > len(rows) // 3
    assert _first_difference(_compensated_outputs(files, lines, tmp_path), expected) is None


def _edited(files, old: str, new: str):
    c = files["rs_monitor.c"].decode()
    assert c.count(old) == 1, old
    return dict(files, **{"rs_monitor.c": c.replace(old, new).encode()})


def test_the_compensated_comparison_fails_for_a_c_step_off_by_an_ulp_an_operation_or_a_rule(tmp_path: Path) -> None:
    """The negative controls of the comparison above (3 runs, 978 periods): the error constant one ulp larger makes
    the margins differ; each track's speed multiplied by 1 / mu in place of divided by mu (one rounding more) makes the
    commands differ; the motors' own limit (SATURATION_LIMIT, the schedule's flag) set to the certificate's (RHO_LIMIT)
    leaves periods out of the slip estimate, which then differs; and each of the compensator's rules broken in turn
    (no suspension of the set checks, covered without the wait, the box's centre after an inconsistent estimate)
    shows where it acts first."""
    files, lines, expected, _, d = _compensated_periods(runs=3)
    assert _first_difference(_compensated_outputs(files, lines, tmp_path / "as-is"), expected) is None
    err, m = d["compensation"]["error"], d["monitor"]
    bad = {
        "margin": (f"COMPENSATION_ERROR = {err!r};", f"COMPENSATION_ERROR = {math.nextafter(err, 1.0)!r};"),
        "command": ("double vr = (V + omega * half_D) / mu_r;", "double vr = (V + omega * half_D) * (1.0 / mu_r);"),
        "estimate": (f"SATURATION_LIMIT = {float(m['saturation_limit'])!r};", f"SATURATION_LIMIT = {m['rho_limit']!r};"),
        # the set checks not suspended where the condition is not covered: an alarm the Python step does not raise
        "status": ("if (!rs_compensator_update(k, m)) rs_monitor_suspend(m);", "rs_compensator_update(k, m);"),
        # covered as soon as the condition holds, not after d_hi + 1 periods of it
        "condition": ("k->wait = k->holds ? (k->wait - 1 > 0 ? k->wait - 1 : 0) : COMPENSATION_D_HI + 1;",
                      "k->wait = k->holds ? 0 : COMPENSATION_D_HI + 1;"),
        # an inconsistent estimate falling back to the box's centre, not keeping the last consistent one
        "mu": ("k->margin = 0.0;\n    }", "k->margin = 0.0;\n        k->mu[0] = COMPENSATION_CENTRE[0];\n"
               "        k->mu[1] = COMPENSATION_CENTRE[1];\n    }"),
    }
    for what, (old, new) in bad.items():
        diff = _first_difference(_compensated_outputs(_edited(files, old, new), lines, tmp_path / what), expected)
        assert diff is not None and diff[2] == what, (what, diff)


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="no valgrind")
def test_the_c_compensated_step_reads_no_uninitialised_memory(tmp_path: Path) -> None:
    """valgrind's memcheck over the --compensated harness (3 runs: warm-up, violations, the fallback)."""
    files, lines, _, _, _ = _compensated_periods(runs=3)
    for block, r in _under_valgrind(files, lines, tmp_path, "--compensated"):
        assert r.returncode == 0 and r.stdout.count("\n") == len(block.splitlines()), r.stderr[:2000]
