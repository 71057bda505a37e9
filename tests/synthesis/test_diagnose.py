"""Where the design is stuck: one re-synthesis per relaxed constraint, reported in synthesis.md
and on the terminal."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from robustsynth.cli import main
from robustsynth.config import load_config
from robustsynth.model import build_model
from robustsynth.synthesis import synthesize
from robustsynth.synthesis.diagnose import diagnose, is_large

from ..conftest import BASE_CONFIG

RELAX_TOL = 0.02  # a relaxed problem's bound may exceed the original by the alpha grid's resolution only


@pytest.fixture(scope="module")
def default_diagnosis():
    cfg = load_config(BASE_CONFIG)
    model = build_model(cfg)
    res = synthesize(model)
    return cfg, res, diagnose(model, res.certified)


@pytest.mark.slow
def test_each_constraint_is_relaxed_once_and_sorted(default_diagnosis) -> None:
    cfg, res, rel = default_diagnosis
    assert {r.name for r in rel} == {"motor limit", "slip range", "delay bound"}  # no slip rate configured
    changes = [r.change for r in rel]
    assert all(r.status == "certified" for r in rel) and changes == sorted(changes)
    # relaxing a constraint enlarges the feasible set: the bound cannot get (materially) worse
    assert all(c <= RELAX_TOL for c in changes)
    assert changes[0] < -0.05  # and something binds on the default
    by = {r.name: r for r in rel}
    assert by["motor limit"].overrides == {"robot.max_motor_speed": 18.0}
    assert by["delay bound"].overrides == {"network.delay.max": pytest.approx(0.045)}


def test_large_is_relative_to_the_robot(default_diagnosis) -> None:
    cfg, res, _ = default_diagnosis
    assert not is_large(cfg, res.certified)  # 4.4 cm on a 45 cm wide robot
    assert is_large(cfg, {"ultimate_bound": {"e_y": 0.3}})


@pytest.mark.slow
def test_cli_diagnose_writes_the_section_and_prints_it(tmp_path) -> None:
    r = CliRunner().invoke(main, ["synthesize", str(BASE_CONFIG), "-o", str(tmp_path), "--diagnose"])
    assert r.exit_code == 0, r.output
    assert "where the design is stuck" in r.output and r.output.count("|e_y| <= ") >= 4
    md = (tmp_path / "synthesis.md").read_text()
    assert "## Where the design is stuck" in md and "responds most to the **" in md


@pytest.mark.slow
def test_slip_above_one_with_slow_motors_is_diagnosed_not_a_solver_failure(tmp_path) -> None:
    """Issue 13: slip above 1 on a robot whose motors cannot use it once ran 64 s and ended 'every
    solve failed' (exit 4).  Now: certified when the motors allow it, else exit 3 naming the motors."""
    import yaml

    from ..conftest import default_dict

    d = default_dict()
    d["slip"] = {"right": {"min": 0.9, "max": 1.5}, "left": {"min": 0.9, "max": 1.5}}
    d["robot"]["max_motor_speed"] = 6.5  # holding V^D at mu = 0.9 needs 6.17 rad/s: no room to correct
    cfg = tmp_path / "slippy.yaml"
    cfg.write_text(yaml.safe_dump(d))
    r = CliRunner().invoke(main, ["synthesize", str(cfg), "-o", str(tmp_path / "a")])
    assert r.exit_code == 3 and "raise robot.max_motor_speed" in r.output, r.output
    assert not (tmp_path / "a" / "gains.json").exists()
    d["robot"]["max_motor_speed"] = 12.0
    cfg.write_text(yaml.safe_dump(d))
    r = CliRunner().invoke(main, ["synthesize", str(cfg), "-o", str(tmp_path / "b")])
    assert r.exit_code == 0, r.output
