"""The runtime monitor (robustsynth.monitor), one check at a time on hand-built periods: what each bit of the
status means, by how much, when the fallback engages and what it sends.  The monitor against the simulated and
the physics robot is in tests/runtime/test_replay.py."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import pytest

from robustsynth.monitor import DELAY, HEADING, LOSSES, MOTOR, RATE, SET, SLIP, Monitor, describe

ROOT = Path(__file__).resolve().parents[1]
TS = 0.1
R, D, V = 0.09, 0.45, 0.5
EXACT = 1e-12  # amounts are differences of the given numbers


def _description(**monitor):
    m = {"tau_min": 0.01, "tau_max": 0.08, "max_lost": 0, "clock_tol": 1e-3, "P": [[[1.0 if i == j else 0.0 for j in range(5)]
         for i in range(5)]], "level": 1.0, "set_threshold": 1.0, "set_entry": 1.0, "heading_limit": 0.3,
         "rho_limit": 12.0, "window": 5, "components": [[0.97, 1.04], [-0.07, 0.07], [0.97, 1.04], [-0.07, 0.07],
                                                          [0.0, 0.0], [0.0, 0.0]],
         "position_noise": 0.0, "heading_noise": 0.0, "model_tol": 0.02, "fallback": "stop", "persistence": 2,
         "slow_factor": 0.5, "segment_starts": []}
    m.update(monitor)
    return {"sampling_time": TS, "gear_radius": R, "track_distance": D, "reference_speed": V, "turn_radius": 5.0,
            "path": [[0.0, 0.0], [10.0, 0.0]], "monitor": m}


class _Robot:
    """Drives a monitor along a straight line at traction ``mu`` (the robot moves mu V_hat per second), period by
    period: each command acts ``delay`` after its sampling instant (or never: ``lost``), and its report reaches the
    monitor at the first sampling instant at or after that."""

    def __init__(self, mon):
        self.mon, self.k, self.x, self.queue, self.acting = mon, 0, 0.0, [], 0.0

    def run(self, periods, mu=1.0, xi=(0.0, 0.0, 0.0, 0.0, 0.0), command=(V, 0.0), delays=None, lost=(), amounts=None):
        out = []
        for n in range(periods):
            k, t = self.k, self.k * TS
            due = sorted(r for r in self.queue if r[1] <= t + 1e-12)
            self.queue = [r for r in self.queue if r[1] > t + 1e-12]
            status, sent = self.mon.step(t, self.x, 0.0, 0.0, list(xi), command, k, [(j, a) for j, a in due])
            out.append(status)
            if amounts is not None:
                amounts.append(dict(self.mon.amounts))
            tau = 0.05 if delays is None else delays[n]
            if n not in lost:
                self.queue.append((k, t + tau))
                # the command in force acts until this one arrives (within the period: tau < Ts here)
                self.x += mu * (tau * self.acting + (TS - tau) * sent[0])
                self.acting = sent[0]
            else:
                self.x += mu * TS * self.acting
            self.k += 1
        return out


def _run(mon, periods, **kw):
    return _Robot(mon).run(periods, **kw)


def test_the_monitor_is_plain_python() -> None:
    """Exported verbatim beside the law: nothing but math."""
    tree = ast.parse((ROOT / "src" / "robustsynth" / "monitor.py").read_text())
    imported = {a.name for node in ast.walk(tree) if isinstance(node, ast.Import) for a in node.names}
    imported |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert imported == {"math"}


def test_a_robot_inside_every_assumption_raises_nothing() -> None:
    assert set(_run(Monitor(_description()), 40)) == {0}


def test_a_delay_beyond_tau_max_counts_the_command_lost_then_late() -> None:
    """The command of period 10 acts 0.15 s late: at t_11 it has no report past tau_max, so it is lost (cap 0:
    LOSSES, by one command); its report at t_12 is a delay beyond tau_max by 0.15 - 0.08 - clock_tol."""
    mon = Monitor(_description())
    delays = [0.05] * 40
    delays[10] = 0.15
    amounts: list = []
    st = _run(mon, 40, delays=delays, amounts=amounts)
    assert st[11] & LOSSES and not st[11] & DELAY and amounts[11]["losses"] == 1.0
    assert st[12] & DELAY and amounts[12]["delay"] == pytest.approx(0.15 - 0.08 - 1e-3, abs=EXACT)
    assert not any(s & (DELAY | LOSSES) for k, s in enumerate(st) if k not in (11, 12))


def test_a_delay_below_tau_min_and_a_loss_burst_beyond_the_cap() -> None:
    mon = Monitor(_description())
    delays = [0.05] * 30
    delays[5] = 0.002
    st = _run(mon, 30, delays=delays)
    assert st[6] & DELAY and sum(1 for s in st if s & DELAY) == 1
    capped = Monitor(_description(max_lost=1))
    st = _run(capped, 30, lost=(10, 11))
    assert not st[11] & LOSSES and st[12] & LOSSES  # one lost in a row is admissible, the second is not
    assert capped.lost_run == 0  # a command acting again ends the run


def test_set_heading_and_motor_count_once_the_state_was_inside() -> None:
    """Starting outside the set (V = 4) is the way in: no alarm; once inside, leaving is SET (by V/level), a heading
    beyond the bound HEADING, a command beyond the motor limit MOTOR; a path without turns re-arms at its waypoints."""
    mon = Monitor(_description(persistence=1000))  # no fallback: each check on its own
    robot = _Robot(mon)
    st = robot.run(3, xi=(2.0, 0, 0, 0, 0))
    assert set(st) == {0} and not mon.inside
    robot.run(2, xi=(0.1, 0, 0, 0, 0))
    assert mon.inside
    assert robot.run(1, xi=(1.5, 0, 0, 0, 0)) == [SET] and mon.amounts["set"] == pytest.approx(2.25)
    assert robot.run(1, xi=(0, 0, 0.35, 0, 0)) == [HEADING] and mon.amounts["heading"] == pytest.approx(0.05)
    rho_fast = 13.0
    assert robot.run(1, command=(rho_fast * R, 0.0)) == [MOTOR] and mon.amounts["motor"] == pytest.approx(rho_fast - 12.0)
    poly = Monitor(_description(segment_starts=[0.0, 2.0]))  # a path [0, 0] -> [1, 0] -> [1, 5] at 0.5 m/s
    robot = _Robot(poly)
    robot.run(3, xi=(0.1, 0, 0, 0, 0))
    assert poly.inside and poly.segment == 0
    robot.run(17, xi=(2.0, 0, 0, 0, 0))  # to t = 1.9 s: outside, on the first segment: SET each period
    assert poly.amounts.get("set") == pytest.approx(4.0)
    assert robot.run(1, xi=(2.0, 0, 0, 0, 0)) == [0]  # t = 2.0 s: the second segment (from t = 2 s): re-armed
    assert poly.segment == 1 and not poly.inside


def test_slip_outside_the_box_is_seen_once_the_window_is_full() -> None:
    """Traction 0.8 (the box: 0.97..1.04): the forward increments fall short of the commanded travel by 0.17 V Ts
    a period; with the window of 5 periods and no noise, flagged from the first full window on."""
    st = _run(Monitor(_description(persistence=1000)), 20, mu=0.8)
    first = next(k for k, s in enumerate(st) if s & SLIP)
    assert first <= 7 and all(s & SLIP for s in st[first:])
    assert set(_run(Monitor(_description()), 20, mu=1.03)) == {0}  # inside the box


def test_the_noise_bound_keeps_noisy_poses_from_alarming() -> None:
    """Poses with noise within the bound (uniform, a = 6 mm) on a robot inside the box: no slip alarm; the same
    poses with the noise bound zero alarm."""
    import random

    rng = random.Random(1)
    for a, expect in ((0.006, False), (0.0, True)):
        mon = Monitor(_description(position_noise=a))
        hits = False
        x = 0.0
        for k in range(60):
            t = k * TS
            rep = [(k - 1, (k - 1) * TS + 0.05)] if k else []
            st, _ = mon.step(t, x + rng.uniform(-0.006, 0.006), rng.uniform(-0.006, 0.006), 0.0, [0.0] * 5, (V, 0.0), k,
                             rep)
            hits = hits or bool(st & SLIP)
            x += V * TS
        assert hits == expect


@pytest.mark.parametrize("fallback, expect", [("stop", (0.0, 0.0)), ("hold", (V, 0.0)), ("slow", (0.5 * 0.6, 0.0))])
def test_the_fallback_engages_after_its_persistence_and_latches(fallback, expect) -> None:
    mon = Monitor(_description(fallback=fallback, persistence=2))
    robot = _Robot(mon)
    robot.run(3, xi=(0.1, 0, 0, 0, 0))
    assert robot.run(1, xi=(1.5, 0, 0, 0, 0), command=(0.6, 0.0)) == [SET]
    assert not mon.engaged and mon.last_sent == (0.6, 0.0)  # one alarmed period: not yet
    assert robot.run(1, xi=(1.5, 0, 0, 0, 0), command=(0.6, 0.0)) == [SET]
    assert mon.engaged and mon.last_sent == pytest.approx(expect)
    assert robot.run(1, xi=(0.0,) * 5, command=(0.6, 0.0)) == [0]
    assert mon.engaged and mon.last_sent == pytest.approx(expect)  # latched until reset
    mon.reset()
    assert not mon.engaged


def test_describe_names_the_bits() -> None:
    assert describe(0) == "ok" and describe(DELAY | SLIP) == "delay, slip"
    with pytest.raises(ValueError, match="no monitor"):
        Monitor({"sampling_time": TS, "monitor": None})
    assert math.isfinite(TS)


def test_slip_within_the_box_that_follows_a_turn_back_and_forth_raises_nothing() -> None:
    """A robot turning in place, left then right (omega_hat = +-1 rad/s, five periods each), whose yaw factor is the
    box's top while it turns left and its bottom while it turns right: every instant within the box.  Over a window
    the commanded turn nets zero while the heading nets (0.70 - 0.53) x 0.5 rad: bounding the integral of ys(t) omega(t)
    by [ys_lo, ys_hi] x (integral of omega) would call that slip; with omega's sign changing it is ys_mid x integral
    of omega +- ys_rad x integral of |omega|, which holds it (and a factor beyond the box is still seen)."""
    def spin(top, bottom, periods=40, tau=0.01):
        mon = Monitor(_description(window=10, persistence=1000, components=[[0.97, 1.04], [-0.07, 0.07], [0.53, 0.70],
                                                                            [-0.05, 0.05], [0.0, 0.0], [0.0, 0.0]]))
        theta, acting, out = 0.0, (0.0, 0.0), []
        for k in range(periods):
            t = k * TS
            w = 1.0 if (k // 5) % 2 == 0 else -1.0
            out.append(mon.step(t, 0.0, 0.0, theta, [0.0] * 5, (0.0, w), k, [(k - 1, t - TS + tau)] if k else [])[0])
            factor = lambda u: top if u > 0 else bottom  # noqa: E731 - the yaw factor follows the command's sign
            theta += factor(acting[1]) * acting[1] * tau + factor(w) * w * (TS - tau)
            acting = (0.0, w)
        return out

    assert set(spin(0.70, 0.53)) == {0}
    assert any(s & SLIP for s in spin(0.80, 0.53))  # a yaw factor of 0.8 turning left: outside the box


def test_a_traction_that_jumps_faster_than_the_rate_bound_is_flagged() -> None:
    """slip.max_rate 0.01 /s: traction 1.04, then 0.97 from period 20 on (both inside the box 0.97..1.04): the window's
    halves imply traction sums 0.07 apart, beyond 0.01 x 0.5 s and their allowances (no noise; model_tol 0.02 of each
    half's 0.1 m travel: 0.02 each) — flagged as 'rate' while the jump is inside the window, never as 'slip'.  The same
    change made at the rate bound (0.0005 a period) raises nothing; without max_rate nothing is checked."""
    def drive(max_rate, steps):
        robot = _Robot(Monitor(_description(max_rate=max_rate, persistence=1000)))
        return [s for mu in steps for s in robot.run(1, mu=mu)]

    jump = [1.04] * 20 + [0.97] * 20
    st = drive(0.01, jump)
    assert any(s & RATE for s in st[20:26]) and not any(s & RATE for s in st[:21]) and not any(s & SLIP for s in st)
    assert not any(s & RATE for s in st[30:])  # the jump has left the window
    assert set(drive(0.01, [1.04 - 0.0005 * k for k in range(40)])) == {0}
    assert set(drive(None, jump)) == {0}
    assert describe(RATE) == "rate"
