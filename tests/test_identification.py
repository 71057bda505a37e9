"""identify and check-log on logs of robustsynth's own simulator, made with known slip, delays and
losses: the identified box contains the truth and is close to it, the delay range and the longest
burst are those of the data, check-log accepts the truth and flags a config that is too narrow."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import yaml

from robustsynth.artifacts.logs import write_log
from robustsynth.config import default_config
from robustsynth.identification import check_log, fragment_yaml, identify
from robustsynth.model import build_model
from robustsynth.plants.path import make_path
from robustsynth.scenarios import draw_scenario, steady_state_start
from robustsynth.synthesis import synthesize
from robustsynth.verification.simulate import run_logs, simulate

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
    return default_config(**base)


@pytest.fixture(scope="module")
def logs():
    cfg = _cfg()
    m = build_model(cfg)
    K = synthesize(m).K
    path = make_path(cfg.verification.path, cfg.reference.speed)
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
    r = run("check-log", *paths, "--config", str(conf), "--max-motor-speed", "20")
    assert r.returncode == 0, r.stdout + r.stderr
    narrow = config_to_dict(cfg)
    narrow["network"]["delay"]["max"] = 0.05
    (tmp_path / "narrow.yaml").write_text(yaml.safe_dump(narrow))
    r = run("check-log", *paths, "--config", str(tmp_path / "narrow.yaml"))
    assert r.returncode == 1 and "VIOLATED network.delay" in r.stdout
    r = run("identify", *paths, "--model", "icr")
    assert r.returncode == 2 and "not available yet" in r.stderr


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
