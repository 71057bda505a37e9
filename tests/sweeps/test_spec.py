"""Sweep files: points in order, generated values, and every problem of the file named by its key
path before anything runs (exit 2)."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from robustsynth.cli import main
from robustsynth.errors import ConfigError
from robustsynth.sweeps import load_sweep, parse_sweep


def test_grid_points_vary_the_last_axis_fastest() -> None:
    s = parse_sweep("axes:\n  network.delay.max: [0.04, 0.08]\n  slip.left.min: [0.6, 0.7, 0.8]\n")
    pts = s.points()
    assert s.shape == (2, 3) and len(pts) == 6
    assert pts[0] == {"network.delay.max": 0.04, "slip.left.min": 0.6}
    assert pts[1] == {"network.delay.max": 0.04, "slip.left.min": 0.7}
    assert pts[3] == {"network.delay.max": 0.08, "slip.left.min": 0.6}


def test_zip_and_generators() -> None:
    s = parse_sweep("mode: zip\naxes:\n  reference.speed: {linspace: [0.1, 0.5, 5]}\n"
                    "  robot.max_motor_speed: {logspace: [10, 1000, 5]}\n")
    assert s.points()[2] == {"reference.speed": 0.3, "robot.max_motor_speed": 100.0}
    assert s.points()[1]["robot.max_motor_speed"] == pytest.approx(10 ** 1.5)
    assert [p["reference.speed"] for p in s.points()] == [0.1, 0.2, 0.3, 0.4, 0.5]  # no round-off tails


def test_base_is_relative_to_the_sweep_file(tmp_path) -> None:
    (tmp_path / "cfg").mkdir()
    (tmp_path / "cfg" / "robot.yaml").write_text(
        "name: other\nrobot: {gear_radius: 0.09, track_distance: 0.45, max_motor_speed: 15}\nreference: {speed: 0.5}\n"
        "network: {sampling_time: 0.1, delay: {min: 0.01, max: 0.08}}\n"
        "slip: {right: {min: 0.6, max: 1.0}, left: {min: 0.6, max: 1.0}}\n")
    (tmp_path / "sw").mkdir()
    (tmp_path / "sw" / "s.yaml").write_text("base: ../cfg/robot.yaml\naxes:\n  reference.speed: [0.3]\n")
    s = load_sweep(tmp_path / "sw" / "s.yaml")
    assert s.base.name == "other" and s.base.robot.max_motor_speed == 15


@pytest.mark.parametrize("text, message", [
    ("axes:\n  network.delay.mx: [0.1]\n", "axes.network.delay.mx: no such config key (did you mean network.delay.max?)"),
    ("axes:\n  network.delay: [0.1]\n", "axes.network.delay: is a section"),
    ("axes:\n  robot.gear_radius.x: [0.1]\n", "axes.robot.gear_radius.x: robot.gear_radius is a value, not a section"),
    ("axes:\n  reference.speed: []\n", "axes.reference.speed: needs at least one value"),
    ("axes:\n  reference.speed: {linspace: [0.1, 0.5]}\n", "axes.reference.speed.linspace: must be [first, last, n]"),
    ("axes:\n  reference.speed: {logspace: [0, 1, 3]}\n", "axes.reference.speed.logspace: first and last must be > 0"),
    ("axes:\n  reference.speed: {range: [0, 1, 3]}\n", "axes.reference.speed: unknown generator 'range'"),
    ("mode: zip\naxes:\n  reference.speed: [0.1, 0.2]\n  slip.left.min: [0.6]\n", "axes: mode zip needs axes of equal length"),
    ("mode: diagonal\naxes:\n  reference.speed: [0.1]\n", "mode: must be grid or zip"),
    ("axes: {}\n", "axes: required"),
    ("axis:\n  reference.speed: [0.1]\n", "axis: unknown key"),
    ("figure: e_z\naxes:\n  reference.speed: [0.1]\n", "figure: must be one of"),
])
def test_problems_of_the_file_name_the_key(text, message) -> None:
    with pytest.raises(ConfigError) as ei:
        parse_sweep(text, "s.yaml")
    assert str(ei.value).startswith(f"s.yaml: {message}"), str(ei.value)


def test_cli_unknown_axis_key_exits_2_before_anything_runs(tmp_path) -> None:
    spec = tmp_path / "s.yaml"
    spec.write_text("axes:\n  network.dealy.max: [0.1]\n")
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["sweep", str(spec), "-o", str(out)])
    assert r.exit_code == 2
    lines = r.output.strip().splitlines()
    assert lines == [f"error: {spec}: axes.network.dealy.max: no such config key (did you mean network.delay.max?)"]
    assert not out.exists()
