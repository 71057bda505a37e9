"""Configuration: the default, valid variations (hypothesis) and a table of bad inputs whose
one-line message must name the key path."""

from __future__ import annotations

import copy
import math

import pytest
import yaml
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from robustsynth.config import MAX_GEAR_RADIUS, MAX_MOTION_PER_PERIOD, MAX_TRACK_DISTANCE, Config, load_config, parse_config
from robustsynth.errors import ConfigError

from .conftest import default_dict


def _dump(d) -> str:
    return yaml.safe_dump(d)


def test_default_loads_and_is_frozen() -> None:
    cfg = load_config()
    assert cfg.name == "default"
    assert cfg.network.delay.max == 0.08
    with pytest.raises(Exception):
        cfg.name = "x"  # type: ignore[misc]


def test_configs_default_equals_embedded() -> None:
    from pathlib import Path

    here = Path(__file__).resolve().parents[1] / "configs" / "default.yaml"
    assert load_config(here) == load_config()


def _with(path: str, value):
    d = copy.deepcopy(default_dict())
    node = d
    keys = path.split(".")
    for k in keys[:-1]:
        node = node.setdefault(k, {})
    if value is _DELETE:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return _dump(d)


class _Delete:
    """Sentinel: remove the key (a stable repr keeps the test ids the same in every process)."""

    def __repr__(self) -> str:
        return "<delete>"


_DELETE = _Delete()

BAD = [
    ("robot.gear_radius", 0.0, "robot.gear_radius: "),
    ("robot.gear_radius", -0.1, "robot.gear_radius: "),
    ("robot.track_distance", "wide", "robot.track_distance: "),
    ("robot.max_motor_speed", 0, "robot.max_motor_speed"),
    ("reference.speed", math.nan, "reference.speed: "),
    ("reference.speed", math.inf, "reference.speed: "),
    ("reference.speed", True, "reference.speed: "),
    ("network.sampling_time", 0, "network.sampling_time: "),
    ("network.delay.min", -0.01, "network.delay.min: "),
    ("network.delay.max", 0.005, "network.delay.max: must be >= network.delay.min (got 0.005 < 0.01)"),
    ("slip.right.min", 0.0, "slip.right.min: "),
    ("slip.left.max", 0.5, "slip.left.max: must be >= slip.left.min"),
    ("slip.left", _DELETE, "slip.left: required key is missing"),
    ("robot.wheels", 4, "robot.wheels: unknown key"),
    ("network.delay", [0.1, 0.2], "network.delay: "),
    ("synthesis.objective", "fastest", "synthesis.objective: "),
    ("synthesis.weights.e_y", -1.0, "synthesis.weights.e_y: "),
    ("verification.runs", 0, "verification.runs: "),
    ("reference.path", [[0, 0]], "reference.path: needs at least 2 waypoints"),
    ("reference.path", [[0, 0], [0, 0]], "reference.path: waypoints 0 and 1 coincide"),
    ("name", "../evil", "name: "),
    ("name", _DELETE, "name: required key is missing"),
    ("network.sampling_time", 0.001, "network.delay.max: must be <= 20 * network.sampling_time"),
    ("robot.gear_radius", 1e308, "robot.gear_radius: "),
]


@pytest.mark.parametrize("path,value,expected", BAD, ids=[f"{p}={v!r}" for p, v, _ in BAD])
def test_bad_values_name_the_key_path(path, value, expected) -> None:
    with pytest.raises(ConfigError) as exc:
        parse_config(_with(path, value))
    msg = str(exc.value)
    assert msg.startswith(expected), msg
    assert "\n" not in msg


@pytest.mark.parametrize(
    "text,expected",
    [
        ("- 1\n- 2\n", "the document must be a mapping"),
        ("", "the document is empty"),
        ("a: &x [1]\nb: *x\n", "YAML aliases are not allowed"),
        ("a: !!python/object/apply:os.system ['true']\n", "invalid YAML"),
        ("name: a\nname: b\n", "duplicate key 'name'"),
        ("name: [unclosed\n", "invalid YAML"),
    ],
)
def test_bad_documents(text, expected) -> None:
    with pytest.raises(ConfigError, match=expected):
        parse_config(text)


def test_file_problems(tmp_path) -> None:
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "missing.yaml")
    big = tmp_path / "big.yaml"
    big.write_bytes(b"#" * (1 << 20) + b"\n")
    with pytest.raises(ConfigError, match="larger than 1 MiB"):
        load_config(big)
    bad = tmp_path / "latin1.yaml"
    bad.write_bytes(b"name: caf\xe9\n")
    with pytest.raises(ConfigError, match="not valid UTF-8"):
        load_config(bad)
    with pytest.raises(ConfigError, match="is a directory"):
        load_config(tmp_path)


def test_billion_laughs_is_refused_quickly() -> None:
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 10):
        lines.append(f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]")
    with pytest.raises(ConfigError, match="aliases"):
        parse_config("\n".join(lines))


@given(
    # lengths up to what a tracked robot has: beyond, refused as a likely unit mistake (test below)
    R=st.floats(1e-3, MAX_GEAR_RADIUS, exclude_max=True), D=st.floats(1e-3, MAX_TRACK_DISTANCE), V=st.floats(1e-3, 20),
    Ts=st.floats(1e-4, 2),
    t1=st.floats(0, 19.9), t2=st.floats(0, 19.9), m1=st.floats(1e-3, 3), m2=st.floats(1e-3, 3),
    rho=st.one_of(st.none(), st.floats(1e-3, 1e4)),
)
@settings(max_examples=100, deadline=None)
def test_valid_configs_roundtrip(R, D, V, Ts, t1, t2, m1, m2, rho) -> None:
    assume(V * Ts <= MAX_MOTION_PER_PERIOD)  # beyond: refused as a likely unit mistake (test below)
    d = default_dict()
    d["robot"] = {"gear_radius": R, "track_distance": D, "max_motor_speed": rho}
    d["reference"]["speed"] = V
    d["network"] = {"sampling_time": Ts, "delay": {"min": min(t1, t2) * Ts, "max": max(t1, t2) * Ts}}
    d["slip"]["right"] = {"min": min(m1, m2), "max": max(m1, m2)}
    cfg = parse_config(_dump(d))
    assert Config.model_validate(cfg.model_dump(mode="json")) == cfg


@pytest.mark.parametrize("value, expected", [
    (-1, "network.dropouts.max_consecutive: Input should be greater than or equal to 0"),
    (1.5, "network.dropouts.max_consecutive: Input should be a valid integer (got float)"),
    ("2", "network.dropouts.max_consecutive: Input should be a valid integer (got str)"),
    (20, "network.dropouts.max_consecutive: 20 lost commands after a delay of up to 0.08 s reach 2.08 s"),
])
def test_bad_dropouts_name_the_key_and_the_limit(value, expected) -> None:
    d = default_dict()
    d["network"]["dropouts"] = {"max_consecutive": value}
    with pytest.raises(ConfigError) as ei:
        parse_config(yaml.safe_dump(d))
    assert str(ei.value).startswith(expected), str(ei.value)
    if value == 20:
        assert "the lifting supports up to 20 * network.sampling_time = 2 s (max_consecutive <= 19 here)" in str(ei.value)


def test_cli_exits_2_on_a_bad_dropout_cap(tmp_path) -> None:
    from click.testing import CliRunner

    from robustsynth.cli import main

    d = default_dict()
    d["network"]["dropouts"] = {"max_consecutive": -2}
    p = tmp_path / "c.yaml"
    p.write_text(yaml.safe_dump(d))
    r = CliRunner().invoke(main, ["synthesize", str(p), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2
    assert r.output.strip().splitlines() == ["error: network.dropouts.max_consecutive: Input should be greater than or equal to 0 (got -2)"]
    assert not (tmp_path / "o").exists()


def test_every_problem_is_named_with_did_you_mean() -> None:
    """A misspelled key is named with the key it stands for (not only as that key missing), and
    every other problem of the document is named too, on one line."""
    d = default_dict()
    d["robot"]["track_distnace"] = d["robot"].pop("track_distance")
    d["robot"]["gear_radius"] = -1.0
    d["verification"] = {"runz": 5}
    with pytest.raises(ConfigError) as exc:
        parse_config(_dump(d))
    msg = str(exc.value)
    assert "\n" not in msg
    assert "robot.track_distnace: unknown key (did you mean robot.track_distance?)" in msg
    assert "robot.gear_radius: " in msg and "verification.runz: unknown key (did you mean verification.runs?)" in msg
    assert "robot.track_distance: required key is missing" not in msg  # said once, as the near-miss
    d = default_dict()
    d["robot"]["wheels"] = 4
    del d["robot"]["track_distance"]
    msg = str(pytest.raises(ConfigError, parse_config, _dump(d)).value)
    assert "robot.wheels: unknown key;" in msg or msg.endswith("robot.wheels: unknown key")
    assert "robot.track_distance: required key is missing" in msg  # no near-miss: both named


def test_slack_is_fenced_at_one_and_motors_saturate_by_default() -> None:
    assert load_config(None).verification.motor_saturation is True
    d = default_dict()
    d["verification"] = {"nonlinear_slack": 3.0}
    with pytest.raises(ConfigError, match=r"verification\.nonlinear_slack: Input should be less than or equal to 1"):
        parse_config(_dump(d))


@pytest.mark.parametrize("name", ["baselines", "sweeps"])
def test_reserved_names_are_refused(name) -> None:
    d = default_dict()
    d["name"] = name
    with pytest.raises(ConfigError, match=rf"name: '{name}' is reserved"):
        parse_config(_dump(d))


def test_default_config_name_option() -> None:
    from robustsynth.config import named_default_config_text

    text = named_default_config_text("my-robot")
    assert parse_config(text).name == "my-robot" and text.startswith("#")  # comments kept
    with pytest.raises(ConfigError, match=r"^--name: "):
        named_default_config_text("../evil")



@pytest.mark.parametrize("Ts, hint", [(50.0, "did you mean 0.05 s?"), (5.0, "did you mean 0.005 s?"), (0.5, "")])
def test_implausible_motion_per_period_is_named_a_unit_mistake(Ts, hint) -> None:
    """sampling_time in ms (50 instead of 0.05): the robot would move metres per period; one line
    naming the key, the motion and the likely unit."""
    d = default_dict()
    d["network"] = {"sampling_time": Ts, "delay": {"min": 0.0, "max": 0.01}}
    d["reference"]["speed"] = 5.0
    with pytest.raises(ConfigError) as exc:
        parse_config(_dump(d))
    msg = str(exc.value)
    assert msg.startswith("network.sampling_time:") and "per sampling period" in msg and hint in msg
    assert "\n" not in msg


def test_an_empty_file_and_a_bound_say_what_they_got(tmp_path) -> None:
    p = tmp_path / "empty.yaml"
    p.write_text("")
    with pytest.raises(ConfigError, match="the document is empty"):
        load_config(p)
    d = default_dict()
    d["robot"]["gear_radius"] = -0.09
    with pytest.raises(ConfigError, match=r"robot.gear_radius: Input should be greater than 0 \(got -0.09\)"):
        parse_config(_dump(d))


def test_load_config_takes_a_mapping_with_the_same_rules() -> None:
    d = default_dict()
    assert load_config(d) == parse_config(_dump(d))
    d["network"]["delay"]["maxx"] = 0.1
    with pytest.raises(ConfigError, match="network.delay.maxx: unknown key"):
        load_config(d)


def test_yaml_exponents_and_what_a_linear_plant_config_refuses() -> None:
    """YAML 1.1 reads 1e6 as a string; a config means the number.  A zero disturbance matrix and a
    zero output row are refused naming the key."""
    from robustsynth.config import ConfigError, parse_config

    base = ("name: t\nplant:\n  kind: lti\n  A: [[0, 1], [0, -0.1]]\n  B: [[0], [1e-1]]\n"
            "network: {sampling_time: 5e-1, delay: {min: 0, max: 2.5E-1}}\n")
    cfg = parse_config(base)
    assert cfg.network.sampling_time == 0.5 and cfg.plant.B == [[0.0], [0.1]]
    with pytest.raises(ConfigError, match="plant.disturbance.E: .*is zero"):
        parse_config(base.replace("network:", "  disturbance: {E: [[0], [0]], bound: 1e6}\nnetwork:"))
    with pytest.raises(ConfigError, match=r"plant.outputs.C: .*C\[1\]: is zero"):
        parse_config(base.replace("network:", "  outputs: {C: [[1, 0], [0, 0]]}\nnetwork:"))
    with pytest.raises(ConfigError, match=r"synthesis.integral_action: the tracked robot's; not available for a linear"):
        parse_config(base + "synthesis: {integral_action: true}\n")
    with pytest.raises(ConfigError, match="reference: a section of the tracked robot's config"):
        parse_config(base + "reference: {speed: 0.5}\n")


@pytest.mark.parametrize("value, expected", [
    (5, "synthesis.heading_bound: should be 'auto' or less than or equal to 1 (got 5)"),
    ("big", "synthesis.heading_bound: should be 'auto' or a valid number (got str)"),
])
def test_a_union_key_is_one_problem_in_the_config_words(value, expected) -> None:
    """A key that takes 'auto' or a number is named once, as the config writes it, with what it takes;
    not once per branch of the type with pydantic's names for them (literal['auto'], constrained-float)."""
    d = default_dict()
    d["synthesis"] = {"kinematics": "nonlinear", "heading_bound": value}
    with pytest.raises(ConfigError) as exc:
        parse_config(_dump(d))
    msg = str(exc.value)
    assert msg.startswith(expected) and "literal[" not in msg and "constrained-" not in msg


def test_a_heading_bound_without_nonlinear_kinematics_is_refused() -> None:
    """synthesis.heading_bound is the nonlinear certificate's; with linearized kinematics it would be
    ignored, so it is refused with the key and the way out ('auto', the default, is no request)."""
    d = default_dict()
    d["synthesis"] = {"heading_bound": 0.3}
    with pytest.raises(ConfigError) as exc:
        parse_config(_dump(d))
    assert str(exc.value).startswith("synthesis.heading_bound: 0.3 rad is for synthesis.kinematics: nonlinear")
    d["synthesis"] = {"heading_bound": "auto"}
    assert parse_config(_dump(d)).synthesis.kinematics == "linearized"


def test_a_misspelt_key_that_looks_like_a_type_name_keeps_its_name() -> None:
    """Only a union-typed key's branches are merged: a key the user typed (a hyphen for an underscore
    is the likeliest slip here, values like slip-aware are hyphenated) is named as typed."""
    d = default_dict()
    d["synthesis"] = {"heading-bound": "auto", "alpha-points": 3}
    d["slip"]["float"] = 1
    with pytest.raises(ConfigError) as exc:
        parse_config(_dump(d))
    msg = str(exc.value)
    assert "synthesis.heading-bound: unknown key (did you mean synthesis.heading_bound?)" in msg
    assert "synthesis.alpha-points: unknown key (did you mean synthesis.alpha_points?)" in msg
    assert "slip.float: unknown key" in msg and "should be" not in msg


def test_a_bare_yaml_off_is_the_setting_off() -> None:
    """Review, stop 47: the README (now docs/) writes `synthesis.symmetry: off`, which YAML 1.1 reads as false, and
    the config refused its own documented value ("Input should be 'auto' or 'off'")."""
    d = default_dict()
    text = _dump(d) + "\n"
    assert parse_config(text.replace("synthesis:\n", "synthesis:\n  symmetry: off\n", 1)).synthesis.symmetry == "off"
    assert parse_config(text.replace("synthesis:\n", "synthesis:\n  symmetry: 'off'\n", 1)).synthesis.symmetry == "off"
    with pytest.raises(ConfigError, match=r"synthesis\.symmetry: write auto or off"):
        parse_config(text.replace("synthesis:\n", "synthesis:\n  symmetry: on\n", 1))


# ---------------------------------------------------------------- the path is the reference's (issue 50, item 6)

DEFAULT_WAYPOINTS = [[0.0, 0.0], [6.0, 0.0], [10.0, 2.0], [16.0, 2.0]]


def test_the_path_is_under_reference_and_dumped_only_there() -> None:
    """The path the controller follows (export bakes it in) is ``reference.path``; the dumped config and the
    schema hold it there only (``reference.path`` was an unknown key)."""
    from robustsynth.config import check_config_key, config_schema, config_to_dict

    d = default_dict()
    d["reference"]["path"] = [[0, 0], [5, 0], [5, 5]]
    cfg = parse_config(_dump(d))
    assert cfg.reference.path == ((0.0, 0.0), (5.0, 0.0), (5.0, 5.0))
    dumped = config_to_dict(cfg)
    assert dumped["reference"]["path"] == [[0.0, 0.0], [5.0, 0.0], [5.0, 5.0]] and "path" not in dumped["verification"]
    assert Config.model_validate(dumped) == cfg
    assert config_to_dict(load_config())["reference"]["path"] == DEFAULT_WAYPOINTS
    schema = config_schema()["$defs"]
    assert schema["ReferenceConfig"]["properties"]["path"]["default"] == DEFAULT_WAYPOINTS
    assert "path" not in schema["VerificationConfig"]["properties"]
    check_config_key("reference.path")


def test_the_old_verification_path_still_reads_as_the_reference_path() -> None:
    """A file (or an override) writing the path at its old place, verification.path, is the same config as one
    writing reference.path; both given: one line naming both keys."""
    from robustsynth.config import config_with, default_config

    new, old = default_dict(), default_dict()
    new["reference"]["path"] = [[0, 0], [4, 0], [4, 3]]
    old["verification"]["path"] = [[0, 0], [4, 0], [4, 3]]
    assert parse_config(_dump(old)) == parse_config(_dump(new)) != parse_config(_dump(default_dict()))
    both = copy.deepcopy(new)
    both["verification"]["path"] = [[0, 0], [4, 0], [4, 3]]
    with pytest.raises(ConfigError) as exc:
        parse_config(_dump(both))
    assert str(exc.value) == ("verification.path: reference.path is given too: give the path once, as reference.path "
                              "(verification.path is its old place)")
    # an override at the old place replaces the path, also of the default (which writes reference.path)
    assert default_config(**{"verification.path": [[0, 0], [3, 0]]}).reference.path == ((0.0, 0.0), (3.0, 0.0))
    assert config_with(load_config(), {"verification.path": [[0, 0], [2, 0]]}).reference.path == ((0.0, 0.0), (2.0, 0.0))


def test_a_stored_config_with_the_path_at_its_old_place_is_the_same_config() -> None:
    """Every committed baseline's gains.json stores its config with verification.path (fast's is not the default
    path): read through config_from_dict it is the config of configs/<name>.yaml, which writes reference.path."""
    import json
    from pathlib import Path

    from robustsynth.config import config_from_dict, config_to_dict
    from robustsynth.artifacts.results_dir import _same_config

    root = Path(__file__).resolve().parents[1]
    fast = json.loads((root / "results" / "baselines" / "fast" / "gains.json").read_text())["config"]
    assert fast["verification"]["path"] == [[0.0, 0.0], [18.0, 0.0], [30.0, 6.0], [48.0, 6.0]] and "path" not in fast["reference"]
    assert "path:" in (root / "configs" / "fast.yaml").read_text().split("network:")[0]  # under reference:
    cfg = load_config(root / "configs" / "fast.yaml")
    assert config_from_dict(fast) == cfg and _same_config(fast, config_to_dict(cfg))
    assert cfg.reference.path == ((0.0, 0.0), (18.0, 0.0), (30.0, 6.0), (48.0, 6.0))


def test_default_config_writes_every_key_a_user_needs_with_a_comment() -> None:
    """`robustsynth default-config` spells out, each with a comment, the keys every user sets: the path (the default's
    own waypoints), the turn radius, the kinematics the proof is for, the Monte Carlo runs and seed."""
    from robustsynth.config import default_config_text

    text = default_config_text()
    raw = yaml.safe_load(text)
    assert raw["reference"]["path"] == DEFAULT_WAYPOINTS
    assert "path" not in raw["verification"]
    for section, key in (("reference", "path"), ("reference", "turn_radius"), ("synthesis", "kinematics"),
                         ("verification", "runs"), ("verification", "seed")):
        assert key in raw[section], (section, key)
        lines = text.splitlines()
        start = lines.index(f"{section}:")
        i = next(j for j in range(start + 1, len(lines)) if lines[j].startswith(f"  {key}:"))
        assert "#" in lines[i] or lines[i - 1].lstrip().startswith("#"), f"{section}.{key} has no comment"
    assert load_config() == parse_config(text)


# ---------------------------------------------------------------- lengths in the wrong unit (issue 50, item 6)

@pytest.mark.parametrize("robot, expected", [
    ({"gear_radius": 7}, "robot.gear_radius: 7 m is not a plausible sprocket radius (below 1 m for a tracked robot; "
                         "lengths are in metres: 7 looks like centimetres, did you mean 0.07 m?)"),
    ({"gear_radius": 90}, "robot.gear_radius: 90 m is not a plausible sprocket radius (below 1 m for a tracked robot; "
                          "lengths are in metres: 90 looks like millimetres, did you mean 0.09 m?)"),
    ({"gear_radius": 1.2}, "robot.gear_radius: 1.2 m is not a plausible sprocket radius (below 1 m for a tracked robot; "
                           "lengths are in metres)"),
    ({"track_distance": 45}, "robot.track_distance: 45 m is not a plausible distance between the tracks (at most 10 m "
                             "for a tracked robot; lengths are in metres: 45 looks like centimetres, did you mean 0.45 m?)"),
    ({"track_distance": 450}, "robot.track_distance: 450 m is not a plausible distance between the tracks (at most 10 m "
                              "for a tracked robot; lengths are in metres: 450 looks like millimetres, did you mean 0.45 m?)"),
    ({"gear_radius": 9, "track_distance": 45}, "robot.gear_radius: 9 m is not a plausible sprocket radius (below 1 m for "
                                              "a tracked robot; lengths are in metres: 9 looks like centimetres, did you "
                                              "mean 0.09 m?)"),
])
def test_a_length_no_tracked_robot_has_is_named_a_unit_mistake(robot, expected) -> None:
    """Centimetres or millimetres written as metres (gear_radius: 7) are refused in one line naming the key and
    the unit they look like, as times in milliseconds are; a gear radius above the schema's old bound too."""
    d = default_dict()
    d["robot"].update(robot)
    with pytest.raises(ConfigError) as exc:
        parse_config(_dump(d))
    assert str(exc.value) == expected


@pytest.mark.parametrize("R, D", [(0.09, 0.45), (0.35, 3.1), (0.01, 0.08), (0.09, 0.05), (0.999, 10.0), (0.002, 0.004)])
def test_lengths_of_real_tracked_robots_are_accepted(R, D) -> None:
    """The default, a main battle tank, a pipe crawler, the narrow robot of tests/test_reliability.py and the bounds."""
    d = default_dict()
    d["robot"].update(gear_radius=R, track_distance=D)
    cfg = parse_config(_dump(d))
    assert (cfg.robot.gear_radius, cfg.robot.track_distance) == (R, D)


def test_a_linear_plants_unknown_key_is_matched_against_its_own_keys() -> None:
    """The "did you mean" of a linear plant's config names its own keys (it had looked at the robot's: 'monitr' got
    'monitor', a section a linear plant does not have)."""
    from pathlib import Path

    base = yaml.safe_load((Path(__file__).resolve().parents[1] / "configs" / "dc-motor.yaml").read_text())
    for key, want in (("monitr", "monitr: unknown key"), ("netwrk", "netwrk: unknown key (did you mean network?)"),
                      ("plnt", "plnt: unknown key (did you mean plant?)")):
        with pytest.raises(ConfigError) as exc:
            parse_config(yaml.safe_dump(dict(base, **{key: {}})))
        assert str(exc.value).split("; ")[0].endswith(want), str(exc.value)
        assert "did you mean monitor" not in str(exc.value)
    with pytest.raises(ConfigError, match=r"network\.delayy: unknown key \(did you mean network\.delay\?\)"):
        parse_config(yaml.safe_dump(dict(base, network=dict(base["network"], delayy=1))))
