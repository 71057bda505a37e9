"""runtime.Controller: read from files, reset, segment switching, motor mapping, light imports."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from robustsynth.config import config_from_dict
from robustsynth.errors import InputError
from robustsynth.model.kinematics import motor_speeds
from robustsynth.runtime import Controller, controller_description
from robustsynth.law import PathTable, segment_at
from robustsynth.plants.path import make_path

ROOT = Path(__file__).resolve().parents[2]
GAINS = sorted(p for p in (ROOT / "results" / "baselines").glob("*/gains.json")
               if json.loads(p.read_text()).get("kind") != "lti")  # the robot's (a linear plant's: test_linear_law)
EXACT = 0.0  # two runs of the same law on the same inputs agree bit for bit
MAP_TOL = 1e-12  # motor mapping vs kinematics.motor_speeds (numpy)


def _poses_along(path, steps: int, rng: np.random.Generator, Ts: float):
    """Measured poses near the desired pose at t_k = k Ts (a few cm and degrees off), across waypoints."""
    t = np.arange(steps) * Ts
    des = np.array([path.desired_pose(tk) for tk in t])
    return t, des + rng.normal(0.0, [0.03, 0.03, 0.05], size=des.shape)


def test_committed_gains_are_found() -> None:
    assert len(GAINS) >= 5


@pytest.mark.parametrize("gains", GAINS, ids=lambda p: p.parent.name)
def test_from_files_uses_the_gains_config_and_reset_restarts(gains: Path) -> None:
    g = json.loads(gains.read_text())
    c = Controller.from_files(gains)
    cfg = g["config"]
    assert c.Ts == cfg["network"]["sampling_time"] and c.V == cfg["reference"]["speed"]
    # read like any stored config: a file written before the path moved holds it as verification.path
    waypoints = config_from_dict(cfg).reference.path
    assert c.description["path"] == [list(map(float, p)) for p in waypoints]
    assert c.description["K"] == g["K"] and c.description["gains_id"] == g["gains_id"]
    path = make_path(waypoints, c.V)
    t, q = _poses_along(path, int(path.duration / c.Ts) + 20, np.random.default_rng(1), c.Ts)
    first = [c.step(tk, *qk) for tk, qk in zip(t, q)]
    assert len(c.state) == len(g["K"][0])
    c.reset()
    again = [c.step(tk, *qk) for tk, qk in zip(t, q)]
    assert np.max(np.abs(np.subtract(first, again))) <= EXACT


def test_segment_rule_matches_the_path_geometry() -> None:
    """The segment switches at each waypoint time (within SEGMENT_EPS), the last one goes on."""
    tab = PathTable([(0, 0), (6, 0), (10, 2), (16, 2)], 0.5)
    assert tab.t_start[0] == 0.0 and tab.t_start[1] == 12.0
    assert segment_at(tab.t_start, -1.0) == 0
    assert segment_at(tab.t_start, 12.0 - 1e-9) == 0
    assert segment_at(tab.t_start, 12.0 - 1e-13) == 1
    assert segment_at(tab.t_start, 1e6) == 2


def test_step_is_the_law_written_out() -> None:
    """One step by hand on segment 1 of the default path: e in the frame, du = K xi, memory shift."""
    c = Controller.from_files(ROOT / "results" / "baselines" / "tracks-box" / "gains.json")
    K = np.array(c.description["K"])
    tab = c.path
    t = tab.t_start[1] + 0.3
    q = np.array([tab.x0[1] + 0.1, tab.y0[1] + 0.05, tab.heading[1] + 0.02])
    h = tab.heading[1]
    R = np.array([[np.cos(h), np.sin(h)], [-np.sin(h), np.cos(h)]])
    e = np.concatenate([R @ (q[:2] - [tab.x0[1], tab.y0[1]]) - [c.V * 0.3, 0.0], [0.02]])
    past = [0.01, -0.02]
    c.reset(past=past)
    V, w = c.step(t, *q)
    du = K @ np.concatenate([e, past])
    assert abs(V - (c.V + du[0])) <= MAP_TOL and abs(w - du[1]) <= MAP_TOL
    assert c.law.past == pytest.approx(list(du), abs=MAP_TOL)


def test_motor_speeds_are_J_inverse() -> None:
    c = Controller.from_files(ROOT / "results" / "baselines" / "tracks-box" / "gains.json")
    rng = np.random.default_rng(0)
    R, D = c.description["gear_radius"], c.description["track_distance"]
    for V, w in rng.normal(0, 1, size=(50, 2)):
        assert np.max(np.abs(np.array(c.motor_speeds(V, w)) - motor_speeds(np.array([V, w]), R, D))) <= MAP_TOL


def test_a_config_with_another_sampling_time_is_refused(tmp_path: Path) -> None:
    g = json.loads((ROOT / "results" / "baselines" / "tracks-box" / "gains.json").read_text())
    cfg = tmp_path / "other.yaml"
    cfg.write_text((ROOT / "configs" / "tracks-box.yaml").read_text().replace("sampling_time: 0.1", "sampling_time: 0.05"))
    assert "sampling_time: 0.05" in cfg.read_text()
    with pytest.raises(InputError, match=r"network\.sampling_time: 0\.05 in the config, but the gain was designed with 0\.1"):
        Controller.from_files(ROOT / "results" / "baselines" / "tracks-box" / "gains.json", cfg)
    # a different path is fine: it does not change the certificate
    data = yaml.safe_load((ROOT / "configs" / "tracks-box.yaml").read_text())
    data["reference"]["path"] = [[0.0, 0.0], [3.0, 4.0]]
    path_cfg = tmp_path / "path.yaml"
    path_cfg.write_text(yaml.safe_dump(data))
    d = Controller.from_files(ROOT / "results" / "baselines" / "tracks-box" / "gains.json", path_cfg).description
    assert d["K"] == g["K"] and d["path"] == [[0.0, 0.0], [3.0, 4.0]]


def test_a_gain_of_the_wrong_width_is_refused() -> None:
    g = json.loads((ROOT / "results" / "baselines" / "tracks-box" / "gains.json").read_text())
    g["K"] = [row + [0.0] for row in g["K"]]
    with pytest.raises(InputError, match="K: has 2 x 6 entries"):
        controller_description(g)


def test_runtime_imports_neither_cvxpy_nor_matplotlib() -> None:
    code = ("import sys; from robustsynth.runtime import Controller; "
            f"c = Controller.from_files({str(ROOT / 'results' / 'baselines' / 'tracks-box' / 'gains.json')!r}); c.step(0.0, 0.0, 0.0, 0.0); "
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'cvxpy', 'matplotlib', 'clarabel'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
