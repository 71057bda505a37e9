"""identify and check-log on logs of robustsynth's own simulator, made with known slip, delays and
losses: the identified box contains the truth and is close to it, the delay range and the longest
burst are those of the data, check-log accepts the truth and flags a config that is too narrow."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from robustsynth.artifacts.gains import load_gains
from robustsynth.artifacts.logs import write_log
from robustsynth.identification import check_log, fragment_yaml, identify
from robustsynth.model import build_model
from robustsynth.plants.path import make_path
from robustsynth.scenarios import draw_scenario, steady_state_start
from robustsynth.robot_verification.simulate import run_logs, simulate

from .conftest import make_config

ROOT = Path(__file__).resolve().parents[1]
TRUTH = {"delay": (0.02, 0.07), "right": (0.7, 0.95), "left": (0.6, 0.9)}
NOISE = (2e-5, 5e-5)  # pose noise of the logs [m], [rad]: a motion-capture system
BOX_REL = 0.02  # the box within 2 % of the true width at that noise (issue 24's target)
DELAY_ABS = 1e-3  # s: the extreme delays of ~10 000 uniform draws lie this close to the bounds


def _cfg(**over):
    base = {"network.delay.min": TRUTH["delay"][0], "network.delay.max": TRUTH["delay"][1],
            "slip.right.min": TRUTH["right"][0], "slip.right.max": TRUTH["right"][1],
            "slip.left.min": TRUTH["left"][0], "slip.left.max": TRUTH["left"][1],
            "network.dropouts.max_consecutive": 2, "robot.max_motor_speed": 20.0,
            "verification.noise.position": NOISE[0], "verification.noise.heading": NOISE[1]}
    base.update(over)
    return make_config(**base)


@pytest.fixture(scope="module")
def logs():
    cfg = _cfg()
    m = build_model(cfg)
    # any gain that holds the loop does; lossy-link's is certified for a box that contains this one (delays
    # [0.01, 0.08] s, slip [0.6, 1] per track, the same loss cap, 12 rad/s) and saves a synthesis
    base = load_gains(ROOT / "results" / "baselines" / "lossy-link" / "gains.json")
    assert base["config"]["network"]["dropouts"]["max_consecutive"] == 2 and base["config"]["network"]["delay"]["max"] >= 0.07
    K = np.array(base["K"], dtype=float)
    path = make_path(cfg.reference.path, cfg.reference.speed)
    scen = steady_state_start(m, K, path, draw_scenario(m, 40, seed=3, steps=250, path=path))
    sim = simulate(m, K, path, scen)
    lost = ~np.isfinite(scen.taus[:, m.d_hi:])
    longest = max(max((len(r) for r in "".join("1" if x else "0" for x in row).split("0")), default=0) for row in lost)
    return cfg, run_logs(m, sim, scen), longest


def test_identify_contains_the_truth_and_is_close_to_it(logs) -> None:
    cfg, lg, longest = logs
    ident = identify(lg, cfg.robot.gear_radius, cfg.robot.track_distance, max_motor_speed=cfg.robot.max_motor_speed)
    for side in ("right", "left"):
        lo, hi = ident.box[side]
        tlo, thi = TRUTH[side]
        assert lo <= tlo and hi >= thi, (side, ident.box[side])
        assert (tlo - lo) <= BOX_REL * (thi - tlo) and (hi - thi) <= BOX_REL * (thi - tlo), (side, ident.box[side])
    dlo, dhi = ident.delay_range
    assert TRUTH["delay"][0] <= dlo <= TRUTH["delay"][0] + DELAY_ABS
    assert TRUTH["delay"][1] - DELAY_ABS <= dhi <= TRUTH["delay"][1]
    assert ident.longest_burst == longest == 2
    frag = yaml.safe_load(fragment_yaml(ident))
    assert frag["slip"]["right"]["min"] == pytest.approx(ident.box["right"][0], rel=1e-3)
    assert frag["network"]["dropouts"]["max_consecutive"] == 2
    merged = _cfg(**{"slip.right.min": frag["slip"]["right"]["min"], "slip.right.max": frag["slip"]["right"]["max"]})
    assert merged.slip.right.min == frag["slip"]["right"]["min"]  # the fragment is a valid config


def test_check_log_accepts_the_truth_and_flags_a_narrow_config(logs) -> None:
    cfg, lg, _ = logs
    ok = check_log(lg, cfg, cfg.robot.max_motor_speed)
    assert all(r["fraction_outside"] <= 0.005 for r in ok), ok
    narrow = _cfg(**{"slip.left.min": 0.7, "network.delay.max": 0.05, "network.dropouts.max_consecutive": 1})
    bad = {r["assumption"]: r for r in check_log(lg, narrow, cfg.robot.max_motor_speed)}
    assert bad["slip.left"]["fraction_outside"] > 0.05 and "row" in bad["slip.left"]["where"]
    assert bad["network.delay"]["worst"] > 0.05 and bad["network.delay"]["where"]
    assert bad["network.dropouts.max_consecutive"]["worst"] == 2
    assert bad["slip.right"]["fraction_outside"] <= 0.005


def test_logs_of_delays_longer_than_a_period_say_when_each_command_acted() -> None:
    """Delays of 0.01-0.25 s on Ts = 0.1 s: a command often arrives before an older one.  The simulator
    holds it until the older has arrived (``s_tilde_sequence``), and the logs now say so: their applied
    instants, measured from each t_k, are the simulator's switching instants; no command is overtaken;
    check-log accepts the config the runs were drawn from.  (The raw arrivals had made check-log count
    18 % overtaken and slip estimates up to 1.28 on delay-multi-period's own runs: review.)"""
    from robustsynth.core.network import s_tilde_sequence

    from .conftest import committed_gain

    m, K, _ = committed_gain("delay-multi-period")
    cfg = m.config
    path = make_path(cfg.reference.path, cfg.reference.speed)
    scen = steady_state_start(m, K, path, draw_scenario(m, 6, seed=2, steps=120, path=path))
    arrival = (np.arange(scen.taus.shape[1]) - m.d_hi) * m.Ts + scen.taus
    assert np.any(np.diff(arrival, axis=1) < 0)  # some commands do arrive before older ones
    lg = run_logs(m, simulate(m, K, path, scen), scen)
    s = s_tilde_sequence(scen.taus[:, : m.d_hi + scen.steps], m.Ts, m.d_hi)  # (runs, steps, d_hi)
    for n, log in enumerate(lg):
        for k in range(m.d_hi, scen.steps):
            for j in range(m.d_hi):  # command k - j, in period k
                if np.isfinite(log.applied[k - j]):
                    assert np.clip(log.applied[k - j] - log.t[k], 0.0, m.Ts) == pytest.approx(s[n, k, j], abs=1e-12)
    res = {r["assumption"]: r for r in check_log(lg, cfg, cfg.robot.max_motor_speed)}
    assert res["in-order delivery"]["outside"] == 0
    assert res["network.delay"]["outside"] == 0
    assert all(r["fraction_outside"] <= 0.005 for r in res.values()), res


def test_cli_identify_and_check_log(logs, tmp_path) -> None:
    cfg, lg, _ = logs
    paths = []
    for log in lg[:12]:
        p = tmp_path / log.path
        write_log(p, log)
        paths.append(str(p))
    conf = tmp_path / "cfg.yaml"
    from robustsynth.config import config_to_dict

    conf.write_text(yaml.safe_dump(config_to_dict(cfg)))
    run = lambda *a: subprocess.run([sys.executable, "-m", "robustsynth", *a], capture_output=True, text=True)  # noqa: E731
    r = run("identify", *paths, "--config", str(conf), "-o", str(tmp_path / "frag.yaml"), "--max-motor-speed", "20")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "frag.yaml").exists() and (tmp_path / "frag.md").exists() and (tmp_path / "frag.png").exists()
    r = run("check-log", *paths, "--config", str(conf))  # the config's robot.max_motor_speed (20) by default
    assert r.returncode == 0, r.stdout + r.stderr
    narrow = config_to_dict(cfg)
    narrow["network"]["delay"]["max"] = 0.05
    (tmp_path / "narrow.yaml").write_text(yaml.safe_dump(narrow))
    r = run("check-log", *paths, "--config", str(tmp_path / "narrow.yaml"))
    assert r.returncode == 1 and "VIOLATED network.delay" in r.stdout
    r = run("identify", *paths, "--model", "bogus")
    assert r.returncode == 2 and "--model" in r.stderr


def test_a_command_overtaken_by_a_newer_one_never_acts() -> None:
    """In-order delivery: seq 1 arrives (0.15 s) after seq 2 was applied (0.13 s), so only seq 0 and
    seq 2 act in the period [0.1, 0.2): 0.1-0.13 under seq 0, 0.13-0.2 under seq 2."""
    from robustsynth.artifacts.logs import RobotLog
    from robustsynth.identification import _segments

    t = np.array([0.0, 0.1, 0.2, 0.3])
    log = RobotLog("o.csv", t, np.zeros(4), np.zeros(4), np.zeros(4), np.arange(4.0), np.ones(4), np.ones(4), t.copy(),
                   np.array([0.02, 0.15, 0.13, 0.33]))
    idx, dur, known = _segments(log)
    used = [(int(i), round(float(d), 12)) for i, d in zip(idx[1], dur[1]) if i >= 0]
    assert used == [(0, 0.03), (2, 0.07)]


# --- the icr model (issue 24): open-loop excitation of the model's own robot, a new slip every period or few
ICR_TRUTH = {"right": (0.95, 1.02), "left": (0.95, 1.02), "yaw": (0.54, 0.67), "icr_offset": (0.0, 0.09)}
ICR_NOISE = (4e-6, 1e-5)  # [m], [rad]: the icr box within 2 % needs 5x less noise than the tracks' (see docs/tutorials/robot-logs.md)
ICR_EPISODES = 16  # x 629 periods: ~10 000


def _icr_cfg(**over):
    from robustsynth.config import config_with, load_config

    from .conftest import ROOT

    base = {"verification.noise.position": ICR_NOISE[0], "verification.noise.heading": ICR_NOISE[1],
            "network.dropouts.max_consecutive": 2}
    base.update(over)
    return config_with(load_config(ROOT / "configs" / "icr-physics.yaml"), base)


@pytest.fixture(scope="module")
def icr_logs():
    from robustsynth.robot_verification.physics import excitation_slip, excitation_steps, excite

    cfg = _icr_cfg()
    m = build_model(cfg)
    logs = excite(m, episodes=ICR_EPISODES, seed=0, engine="kinematic")
    truth = excitation_slip(m, ICR_EPISODES, excitation_steps(m), 0)
    return cfg, logs, truth


def test_icr_lines_hold_the_true_slip_and_the_true_offset() -> None:
    """Noise-free logs: at s = 1/yaw every period's line gives the true traction factors and x_icr --
    exactly for one command per period, within the line's own model uncertainty (the chord's bend)
    when a delayed command switches within it (the algebra of identification_icr against the
    simulator's arcs)."""
    from robustsynth.identification import _icr_lines
    from robustsynth.robot_verification.physics import excitation_slip, excitation_steps, excite

    cfg = _icr_cfg(**{"verification.noise.position": 0.0, "verification.noise.heading": 0.0})
    m = build_model(cfg)
    logs = excite(m, episodes=2, seed=4, engine="kinematic")
    truth = excitation_slip(m, 2, excitation_steps(m), 4)
    lines, periods, _ = _icr_lines(logs, cfg.robot.gear_radius, cfg.robot.track_distance, (0.0, 0.0), None)
    rows = np.array([int(f[7:10]) for f, _ in (w for p in periods for w in p.where)])
    k = np.array([r - 2 for p in periods for _, r in p.where])
    tr = truth[rows, k]
    s = 1.0 / tr[:, 2]
    one = lines.dur[:, 1] == 0  # one command acted in the whole period
    assert one.sum() > 50 and (~one).sum() > 500
    tol = 1e-7  # the Gauss-Newton fit through exact arcs (finite-difference Jacobian)
    err_r, err_l = np.abs(lines.ar + lines.br * s - tr[:, 0]), np.abs(lines.al + lines.bl * s - tr[:, 1])
    assert np.max(err_r[one]) < tol and np.max(err_l[one]) < tol
    assert np.all(err_r <= 3 * lines.sig_r) and np.all(err_l <= 3 * lines.sig_l)  # the bend is in the uncertainty
    turn = lines.turning & (np.abs(lines.omega) > 0.05)
    err_x = np.abs(lines.x_at(s) - tr[:, 3])
    assert turn.sum() > 500 and np.max(err_x[turn & one]) < 1e-6 and np.all(err_x[turn] <= 3 * lines.sig_x[turn])


def _synthetic_lines(ar, br, al, bl, sig=1e-4):
    from robustsynth.identification_icr import IcrLines

    n = len(ar)
    z = np.zeros(n)
    return IcrLines(np.asarray(ar, float), np.asarray(br, float), np.asarray(al, float), np.asarray(bl, float),
                    z, z, np.full(n, sig), np.full(n, sig), np.full(n, sig), np.ones(n), np.ones(n, bool),
                    np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 1, 2)), np.ones((n, 1)))


def test_feasible_s_against_a_brute_force_grid() -> None:
    """The closed-form interval of s in which a line lies in a box (any slope sign, flat lines) against
    a dense grid of s."""
    from robustsynth.identification_icr import feasible_s

    rng = np.random.default_rng(7)
    n = 4000
    br, bl = rng.normal(size=n) * 0.3, rng.normal(size=n) * 0.3
    br[:400], bl[200:600] = 0.0, 0.0  # flat lines too
    ar, al = 1.0 - br * 1.6 + rng.normal(size=n) * 0.08, 1.0 - bl * 1.6 + rng.normal(size=n) * 0.08
    lines = _synthetic_lines(ar, br, al, bl, sig=0.01)
    box = np.array([[0.95, 1.05], [0.93, 1.04], [1.2, 2.0]])
    lo, hi = feasible_s(lines, box, z=2.0)
    grid = np.linspace(1.2, 2.0, 8001)
    inside = ((np.abs(ar[:, None] + br[:, None] * grid - 1.0) <= 0.05 + 0.02)
              & (np.abs(al[:, None] + bl[:, None] * grid - 0.985) <= 0.055 + 0.02))
    step = grid[1] - grid[0]
    some = inside.any(axis=1)
    assert np.array_equal(some, lo <= hi + step) or np.sum(some != (lo <= hi)) <= 3  # grid resolution at the edges
    g_lo = np.where(some, grid[np.argmax(inside, axis=1)], np.nan)
    g_hi = np.where(some, grid[::-1][np.argmax(inside[:, ::-1], axis=1)], np.nan)
    both = some & (lo <= hi)
    assert np.allclose(g_lo[both], lo[both], atol=step) and np.allclose(g_hi[both], hi[both], atol=step)


def test_gauge_box_sees_flat_violators_and_never_inverts() -> None:
    """A flat line (a straight period) outside every other period's traction is explained by the
    gauge (the cutting planes add it although it is not among the seeded periods), and noisy
    constant-slip lines do not buy an inverted box with their slack."""
    from robustsynth.identification_icr import feasible_s, gauge_box

    rng = np.random.default_rng(3)
    n = 3000
    br = rng.choice([-0.2, -0.1, 0.1, 0.2], size=n)
    ar = 1.0 - br * 1.6 + rng.normal(size=n) * 1e-3
    al = 0.98 + br * 1.6 + rng.normal(size=n) * 1e-3
    ar[1234], br[1234] = 1.10, 0.0  # flat, and its mu_r above everyone's
    lines = _synthetic_lines(ar, br, al, -br, sig=1e-3)
    box = gauge_box(lines, z=3.0, seed=1)
    lo, hi = feasible_s(lines, box, z=3.0)
    assert np.all(lo <= hi + 1e-9) and box[0, 1] >= 1.10 - 3e-3 - 1e-9
    assert np.all(box[:, 1] >= box[:, 0])


def test_fragment_bounds_are_yaml_numbers_rounded_outwards() -> None:
    from robustsynth.identification import _round

    for x, d in ((1.0200000000001, 1), (0.95, -1), (-3.2e-6, -1), (1e-5, 1), (-1e-9, -1), (0.5379, -1)):
        v = yaml.safe_load(_round(x, d))
        assert isinstance(v, float) and ((v <= x) if d < 0 else (v >= x)), (x, d, v)


def test_icr_gauge_is_the_least_box_that_explains_every_period(icr_logs) -> None:
    """The gauge LP's box: every period's line meets it (checked in closed form, not by the LP), and no
    box that explains the data costs less -- in particular not the true box, which explains it too."""
    from scipy.stats import norm

    from robustsynth.identification import _icr_lines
    from robustsynth.identification_icr import S_WEIGHT, feasible_s, gauge_box

    cfg, logs, _ = icr_logs
    lines, _, _ = _icr_lines(logs, cfg.robot.gear_radius, cfg.robot.track_distance, ICR_NOISE, cfg.robot.max_motor_speed)
    z = float(norm.isf(0.05 / (4 * len(lines))))
    box = gauge_box(lines, z)
    lo, hi = feasible_s(lines, box, z)
    slack = 1e-9  # the LP's feasibility tolerance, in s
    assert np.all(lo <= hi + slack)
    true_box = np.array([ICR_TRUTH["right"], ICR_TRUTH["left"], (1 / ICR_TRUTH["yaw"][1], 1 / ICR_TRUTH["yaw"][0])])
    tlo, thi = feasible_s(lines, true_box, z)
    assert np.mean(tlo <= thi) >= 0.999  # the truth explains (almost) every period within z sigma of its noise

    def cost(b):
        return b[0, 1] - b[0, 0] + b[1, 1] - b[1, 0] + S_WEIGHT * (b[2, 1] - b[2, 0])

    assert cost(box) <= cost(true_box) + 1e-9


def test_identify_icr_contains_the_truth_and_is_close_to_it(icr_logs) -> None:
    cfg, logs, truth = icr_logs
    ident = identify(logs, cfg.robot.gear_radius, cfg.robot.track_distance, model="icr",
                     max_motor_speed=cfg.robot.max_motor_speed, pose_noise=ICR_NOISE)
    assert ident.slip.mu.shape == (len(ident.slip.where), 4) and ident.slip.mu.shape[0] > 9000
    for i, key in enumerate(("right", "left", "yaw", "icr_offset")):
        lo, hi = ident.box[key]
        tlo, thi = float(truth[..., i].min()), float(truth[..., i].max())
        assert (tlo, thi) == pytest.approx(ICR_TRUTH[key], abs=1e-12)  # the profiles reach the box's corners
        assert lo <= tlo and hi >= thi, (key, ident.box[key])
        assert (tlo - lo) <= BOX_REL * (thi - tlo) and (hi - thi) <= BOX_REL * (thi - tlo), (key, ident.box[key])
    assert ident.longest_burst == 2
    frag = yaml.safe_load(fragment_yaml(ident))
    assert frag["slip"]["model"] == "icr"
    for key in ("right", "left", "yaw", "icr_offset"):  # rounded outwards: the fragment's box holds the identified one
        assert frag["slip"][key]["min"] <= ident.box[key][0] and frag["slip"][key]["max"] >= ident.box[key][1]
    from robustsynth.config import config_with

    merged = config_with(cfg, {f"slip.{k}.{e}": frag["slip"][k][e] for k in ICR_TRUTH for e in ("min", "max")})
    assert merged.slip.yaw.max == frag["slip"]["yaw"]["max"]  # the fragment is a valid config


def test_identify_icr_needs_the_pose_noise(icr_logs) -> None:
    from robustsynth.errors import InputError

    cfg, logs, _ = icr_logs
    with pytest.raises(InputError, match="--pose-noise"):
        identify(logs, cfg.robot.gear_radius, cfg.robot.track_distance, model="icr")


def test_check_log_icr_accepts_the_truth_and_blames_the_right_parameter(icr_logs) -> None:
    cfg, logs, _ = icr_logs
    ok = {r["assumption"]: r for r in check_log(logs, cfg, cfg.robot.max_motor_speed)}
    assert {"slip.right", "slip.left", "slip.yaw", "slip.icr_offset"} <= set(ok)
    assert all(r["fraction_outside"] <= 0.005 for r in ok.values()), ok
    narrow = _icr_cfg(**{"slip.yaw.max": 0.62, "slip.icr_offset.max": 0.06})
    bad = {r["assumption"]: r for r in check_log(logs, narrow, cfg.robot.max_motor_speed)}
    assert bad["slip.yaw"]["fraction_outside"] > 0.05 and bad["slip.yaw"]["worst"] > 0.64 and "row" in bad["slip.yaw"]["where"]
    assert bad["slip.icr_offset"]["fraction_outside"] > 0.05 and bad["slip.icr_offset"]["worst"] > 0.08
    assert bad["slip.right"]["fraction_outside"] <= 0.005 and bad["slip.left"]["fraction_outside"] <= 0.005
    traction = _icr_cfg(**{"slip.right.max": 0.99})
    bad = {r["assumption"]: r for r in check_log(logs, traction, cfg.robot.max_motor_speed)}
    assert bad["slip.right"]["fraction_outside"] > 0.05 and bad["slip.right"]["worst"] > 1.0
    assert bad["slip.left"]["fraction_outside"] <= 0.005


def _run(*a):
    return subprocess.run([sys.executable, "-m", "robustsynth", *a], capture_output=True, text=True)


def _excited(tmp_path, cfg, episodes: int):
    """The config written to tmp_path, and `validate --excite --engine kinematic`'s logs of it."""
    from robustsynth.config import config_to_dict

    conf = tmp_path / f"{cfg.name}.yaml"
    conf.write_text(yaml.safe_dump(config_to_dict(cfg)))
    r = _run("validate", str(conf), "--excite", "--engine", "kinematic", "--episodes", str(episodes), "-o",
             str(tmp_path / "exc"))
    assert r.returncode == 0, r.stderr
    return conf, sorted(str(p) for p in (tmp_path / "exc" / "logs").glob("*.csv")), r


def test_cli_excite_kinematic_identify_icr_and_check_log(tmp_path) -> None:
    conf, paths, r = _excited(tmp_path, _icr_cfg(), 3)
    run = _run
    assert len(paths) == 3 and "--model icr" in r.stdout
    r = run("identify", *paths, "--config", str(conf), "--model", "icr", "-o", str(tmp_path / "frag.yaml"))
    assert r.returncode == 0, r.stderr
    frag = yaml.safe_load((tmp_path / "frag.yaml").read_text())
    assert frag["slip"]["model"] == "icr" and set(frag["slip"]) >= {"yaw", "icr_offset"}
    assert "yaw" in (tmp_path / "frag.md").read_text() and (tmp_path / "frag.png").exists()
    r = run("check-log", *paths, "--config", str(conf))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "ok       slip.yaw" in r.stdout and "slip.icr_offset" in r.stdout
    r = run("identify", *paths, "--model", "icr", "--pose-noise", "-1", "0")
    assert r.returncode == 2 and "--pose-noise" in r.stderr


def test_check_log_icr_on_exact_logs_with_zero_noise_flags_nothing() -> None:
    """Exact poses (--pose-noise 0 0): the lines' model error (two commands per period) is in their
    uncertainty, so a robot inside the box is not flagged; the config's zero noise alone is refused."""
    from robustsynth.errors import InputError
    from robustsynth.robot_verification.physics import excite

    cfg = _icr_cfg(**{"verification.noise.position": 0.0, "verification.noise.heading": 0.0})
    logs = excite(build_model(cfg), episodes=4, seed=2, engine="kinematic")
    rows = {r["assumption"]: r for r in check_log(logs, cfg, cfg.robot.max_motor_speed, (0.0, 0.0))}
    assert all(rows[f"slip.{k}"]["outside"] == 0 for k in ICR_TRUTH), rows
    with pytest.raises(InputError, match="--pose-noise"):
        check_log(logs, cfg, cfg.robot.max_motor_speed)
    for bad in ((float("nan"), 0.0), (float("inf"), 1.0), (-1.0, 0.0), (1.0,)):
        with pytest.raises(InputError, match="--pose-noise"):
            check_log(logs, cfg, cfg.robot.max_motor_speed, bad)


def test_identify_icr_refuses_logs_without_turns_and_skips_a_track_at_rest(icr_logs) -> None:
    """Straight driving only: the yaw factor is not determined (exit 2, not a fragment that is no
    config); check-log says the yaw factor and x_icr were not checked.  A period with a track at rest
    is skipped and counted (its traction factor is not seen), not a crash."""
    import dataclasses

    from robustsynth.errors import InputError

    cfg, logs, _ = icr_logs
    straight = [dataclasses.replace(lg, rho_l=lg.rho_r.copy(), theta=np.zeros(len(lg)), y=np.zeros(len(lg))) for lg in logs[:3]]
    with pytest.raises(InputError, match="turn"):
        identify(straight, cfg.robot.gear_radius, cfg.robot.track_distance, model="icr", pose_noise=ICR_NOISE)
    rows = {r["assumption"]: r for r in check_log(straight, cfg, None, ICR_NOISE)}
    assert rows["slip.yaw"]["samples"] == 0 and rows["slip.icr_offset"]["samples"] == 0
    from robustsynth.robot_verification.physics import excite

    wide = _icr_cfg(**{"robot.track_distance": 1.0})  # at 2 rad/m the inner track stands still
    rest = excite(build_model(wide), episodes=4, seed=1, engine="kinematic")
    ident = identify(rest, wide.robot.gear_radius, wide.robot.track_distance, model="icr", pose_noise=ICR_NOISE)
    assert ident.slip.skipped["a track at rest"] > 0


def test_identify_icr_on_constant_slip_draws_its_figure(tmp_path) -> None:
    """One slip for the whole log (a robot on one surface): every yaw estimate is the same number, and
    the report's histograms still draw (one bin), with the true point inside the box."""
    point = {f"slip.{k}.{e}": v for k, v in (("right", 0.98), ("left", 0.97), ("yaw", 0.6), ("icr_offset", 0.03))
             for e in ("min", "max")}
    conf, paths, _ = _excited(tmp_path, _icr_cfg(**point), 1)
    r = _run("identify", *paths, "--config", str(conf), "--model", "icr", "-o", str(tmp_path / "frag.yaml"))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "frag.png").exists()
    frag = yaml.safe_load((tmp_path / "frag.yaml").read_text())["slip"]
    for key, (lo, hi) in (("right", (0.98,) * 2), ("left", (0.97,) * 2), ("yaw", (0.6,) * 2), ("icr_offset", (0.03,) * 2)):
        assert frag[key]["min"] <= lo and frag[key]["max"] >= hi, (key, frag[key])
