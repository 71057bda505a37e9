"""`robustsynth validate`: the deployed law on the physics robot, end to end through the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from robustsynth.artifacts.logs import read_log
from robustsynth.cli import main
from robustsynth.plants.physics import available

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(bool(available()), reason=available() or "MuJoCo available")


def test_validate_writes_verdict_logs_and_the_observed_slip(tmp_path) -> None:
    """The default gain on the physics robot: straight segments far inside the certified bounds, the
    turns reported, and the slip the engine shows in turns (outer track above 1) outside the config's
    box [0.6, 1], so the verdict says the certificate does not apply: exit 1."""
    r = CliRunner().invoke(main, ["validate", str(ROOT / "configs" / "default.yaml"), "--gains",
                                  str(ROOT / "results" / "baselines" / "default" / "gains.json"), "--episodes", "2",
                                  "-o", str(tmp_path)])
    assert r.exit_code == 1, r.output
    vd = json.loads((tmp_path / "validation.json").read_text())
    assert vd["episodes"] == 2 and len(vd["per_episode"]) == 2
    for k in ("e_x", "e_y", "e_theta"):
        assert vd["straight_max"][k] <= vd["certified"][k]
        assert vd["turn_max"][k] >= vd["straight_max"][k]
    assert vd["slip"]["inside_box"] is False and vd["slip"]["estimated"]["left"][1] > 1.0
    assert "does not apply" in r.output
    logs = sorted((tmp_path / "logs").glob("*.csv"))
    assert len(logs) == 2 and len(read_log(logs[0])) == vd["steps"]


def test_validate_without_gains_is_a_usage_error(tmp_path) -> None:
    r = CliRunner().invoke(main, ["validate", str(ROOT / "configs" / "default.yaml"), "-o", str(tmp_path)])
    assert r.exit_code == 2
