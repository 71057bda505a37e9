"""A sweep over a linear plant's config (plant: kind: lti): one synthesize_lti (and verify_lti) per
point, its rows against direct calls, a key of the lti config checked against its own schema."""

from __future__ import annotations

from pathlib import Path

import pytest

from robustsynth.errors import ConfigError
from robustsynth.sweeps import sweep
from robustsynth.sweeps.spec import parse_sweep

ROOT = Path(__file__).resolve().parents[2]


def test_lti_sweep_rows_match_direct_synthesis(tmp_path) -> None:
    from robustsynth.config import config_with
    from robustsynth.model.lti import lti_plant
    from robustsynth.synthesis.lti import synthesize_lti

    spec = parse_sweep(f"base: {ROOT / 'configs' / 'dc-motor.yaml'}\naxes:\n  network.delay.max: [0.01, 0.04]\n"
                       "  plant.disturbance.bound: [0.005, 0.02]\n")
    assert spec.figure == "output_bound"
    res = sweep(spec, tmp_path, verify_runs=4, workers=1)
    # the larger disturbance: Clarabel's statuses are inaccurate ones and errors, SCS's points fail the numpy proof;
    # nothing shows that no gain exists, so the point is a solver failure, not infeasible
    assert [r["status"] for r in res.rows] == ["certified", "solver-failure", "certified", "solver-failure"]
    assert all("also with the fallback solver" in r["message"] for r in res.rows[1::2])
    for row, pt in zip(res.rows, spec.points()):
        if row["status"] != "certified":
            continue
        cfg = config_with(spec.base, pt)
        plant = lti_plant(cfg)
        d = synthesize_lti(plant, 0.05, 0.005, pt["network.delay.max"], 0, "ultimate-bound")
        direct = max(o["bound"] / s for o, s in zip(d.certified["outputs"], plant["scale"]))
        assert row["output_bound"] == pytest.approx(direct, rel=1e-9)
        assert row["verified"] is True and row["e_y_m"] is None
    assert (tmp_path / "sweep.csv").exists() and (tmp_path / "sweep.png").exists()


def test_lti_sweep_keys_are_the_lti_schema() -> None:
    with pytest.raises(ConfigError, match="axes.robot.gear_radius: no such config key"):
        parse_sweep(f"base: {ROOT / 'configs' / 'dc-motor.yaml'}\naxes:\n  robot.gear_radius: [0.1, 0.2]\n")
    with pytest.raises(ConfigError, match="figure: e_y is the robot's"):
        parse_sweep(f"base: {ROOT / 'configs' / 'dc-motor.yaml'}\nfigure: e_y\naxes:\n  network.delay.max: [0.01]\n")
    # and the other way round (an empty heatmap and exit 0 before)
    with pytest.raises(ConfigError, match="figure: output_bound is a linear plant's"):
        parse_sweep(f"base: {ROOT / 'configs' / 'default.yaml'}\nfigure: output_bound\naxes:\n  network.delay.max: [0.05]\n")
