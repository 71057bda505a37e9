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


def _validate(cfg: Path, out: Path, episodes: int = 2):
    return CliRunner().invoke(main, ["validate", str(cfg), "--gains", str(ROOT / "results" / "baselines" / "tracks-box" /
                                                                          "gains.json"), "--episodes", str(episodes), "-o", str(out)])


def test_validate_writes_verdict_logs_and_the_observed_slip(tmp_path) -> None:
    """The default gain on the physics robot: straight segments inside the certified bounds, the turns
    reported (larger), the slip the engine shows on the straight segments inside the config's box
    [0.6, 1] (about 0.98: the soft contact's sink), and in the turns outside it (the outer track
    above 1: skid steering is not the paper's slip model)."""
    r = _validate(ROOT / "configs" / "tracks-box.yaml", tmp_path)
    assert r.exit_code == 0, r.output
    vd = json.loads((tmp_path / "validation.json").read_text())
    assert vd["episodes"] == 2 and len(vd["per_episode"]) == 2 and vd["passed"]
    for k in ("e_x", "e_y", "e_theta"):
        assert vd["straight_max"][k] <= vd["certified"][k]
        assert vd["turn_max"][k] >= vd["straight_max"][k]
    assert vd["slip"]["inside_box"] is True
    assert 0.95 < vd["slip"]["estimated"]["right"][0] <= vd["slip"]["estimated"]["right"][1] < 1.0
    assert vd["slip_whole_episodes"]["estimated"]["left"][1] > 1.0
    logs = sorted((tmp_path / "logs").glob("*.csv"))
    assert len(logs) == 2 and len(read_log(logs[0])) == vd["steps"]


def test_a_box_the_physics_leaves_fails_the_verdict(tmp_path) -> None:
    """A config whose slip box excludes what the engine shows on straight ground (0.98 outside
    [0.6, 0.9]): the certificate does not apply to this robot, exit 1, and it says so."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text((ROOT / "configs" / "tracks-box.yaml").read_text().replace("{min: 0.6, max: 1.0}", "{min: 0.6, max: 0.9}"))
    r = _validate(cfg, tmp_path / "out", episodes=1)
    assert r.exit_code == 1, r.output
    assert "does not apply" in r.output
    assert json.loads((tmp_path / "out" / "validation.json").read_text())["slip"]["inside_box"] is False


def test_validate_without_gains_is_a_usage_error(tmp_path) -> None:
    r = CliRunner().invoke(main, ["validate", str(ROOT / "configs" / "tracks-box.yaml"), "-o", str(tmp_path)])
    assert r.exit_code == 2


@pytest.mark.slow
def test_end_to_end_excite_identify_synthesize_validate(tmp_path) -> None:
    """The recipe of docs/tutorials/robot-logs.md: excitation logs -> identify (the slip box of the turns) -> a config ->
    synthesize -> validate: on straight segments the physics robot stays within the certified
    bounds, and the slip it shows there lies in the identified box."""
    import yaml

    exc = CliRunner().invoke(main, ["validate", str(ROOT / "configs" / "tracks-box.yaml"), "--excite", "--episodes", "2",
                                    "-o", str(tmp_path / "exc")])
    assert exc.exit_code == 0, exc.output
    logs = sorted((tmp_path / "exc" / "logs").glob("*.csv"))
    frag = tmp_path / "frag.yaml"
    r = CliRunner().invoke(main, ["identify", *map(str, logs), "--max-motor-speed", "12", "-o", str(frag), "--no-plots"])
    assert r.exit_code == 0, r.output
    f = yaml.safe_load(frag.read_text())
    assert f["slip"]["left"]["max"] > 1.0  # skid steering: the outer track's factor exceeds 1 in turns
    d = yaml.safe_load((ROOT / "configs" / "tracks-box.yaml").read_text())
    d.update(name="physics-identified", slip=f["slip"])
    d["network"]["delay"] = f["network"]["delay"]
    cfg = tmp_path / "identified.yaml"
    cfg.write_text(yaml.safe_dump(d))
    r = CliRunner().invoke(main, ["synthesize", str(cfg), "-o", str(tmp_path / "syn")])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["validate", str(cfg), "--gains", str(tmp_path / "syn" / "gains.json"), "--episodes", "2",
                                  "-o", str(tmp_path / "val")])
    assert r.exit_code == 0, r.output
    vd = json.loads((tmp_path / "val" / "validation.json").read_text())
    assert vd["passed"] and vd["slip"]["inside_box"]
    assert all(vd["straight_max"][k] <= vd["certified"][k] for k in ("e_x", "e_y", "e_theta"))


def test_excite_and_gains_are_exclusive(tmp_path) -> None:
    r = CliRunner().invoke(main, ["validate", str(ROOT / "configs" / "tracks-box.yaml"), "--excite", "--gains",
                                  str(ROOT / "results" / "baselines" / "tracks-box" / "gains.json"), "-o", str(tmp_path)])
    assert r.exit_code == 2 and "exactly one" in r.output


def test_workers_split_the_episodes_without_changing_them() -> None:
    """--workers: each episode has its own random stream, so 3 episodes on 2 processes are the same
    episodes as on one."""
    import numpy as np

    from robustsynth import build_model, load_config
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.robot_verification.physics import validate_physics

    m = build_model(load_config(ROOT / "configs" / "tracks-box.yaml"))
    g = load_gains(ROOT / "results" / "baselines" / "tracks-box" / "gains.json")
    one = validate_physics(m, g, episodes=3, seed=1)
    two = validate_physics(m, g, episodes=3, seed=1, workers=2)
    assert np.array_equal(one["e"], two["e"]) and np.array_equal(one["q"], two["q"])
    assert one["validation"]["per_episode"] == two["validation"]["per_episode"]


def test_the_kinematic_engine_recovers_its_own_slip(tmp_path) -> None:
    """--engine kinematic: the model's own robot with one slip per episode from the box; identify finds
    slips inside the box, and the straight segments stay within the certified bounds."""
    r = CliRunner().invoke(main, ["validate", str(ROOT / "configs" / "tracks-box.yaml"), "--engine", "kinematic", "--gains",
                                  str(ROOT / "results" / "baselines" / "tracks-box" / "gains.json"), "--episodes", "3",
                                  "--no-plots", "-o", str(tmp_path)])
    assert r.exit_code == 0, r.output
    vd = json.loads((tmp_path / "validation.json").read_text())
    assert vd["engine"].startswith("kinematic") and vd["slip"]["inside_box"]
    assert vd["torque_saturated_s"] == 0.0


@pytest.mark.parametrize("case", ["edited K", "another config's gain"])
def test_a_gain_whose_certificate_does_not_hold_here_fails(tmp_path, case) -> None:
    """The episodes are judged against the certificate re-checked for this config, not against the figures a
    gains file states: an edited K, or the default's gain on heavy-slip's wider slip box, has no certified
    bounds here, and validation fails (a review found both passing)."""
    gains = json.loads((ROOT / "results" / "baselines" / "tracks-box" / "gains.json").read_text())
    cfg = ROOT / "configs" / "tracks-box.yaml"
    if case == "edited K":
        gains["K"][0][0] += 5.0
    else:
        cfg = ROOT / "configs" / "heavy-slip.yaml"
    g = tmp_path / "gains.json"
    g.write_text(json.dumps(gains))
    r = CliRunner().invoke(main, ["validate", str(cfg), "--engine", "kinematic", "--gains", str(g), "--episodes", "1",
                                  "--no-plots", "-o", str(tmp_path / "out")])
    assert r.exit_code == 1, r.output
    assert "no certified bounds" in r.output and "covers it" not in r.output
    vd = json.loads((tmp_path / "out" / "validation.json").read_text())
    assert not vd["passed"] and not vd["certificate"]["passed"] and vd["certified"]["e_y"] is None


def test_a_linear_plants_gain_or_a_k_of_another_size_is_bad_input(tmp_path) -> None:
    """No law to run: exit 2 with one line, and no output directory (a traceback before, review)."""
    bad = tmp_path / "lti.json"
    bad.write_text(json.dumps({"kind": "lti", "K": [[0.1, 0.2]], "lifting": {"n": 2, "m": 1, "d": 0}}))
    for cfg, g, what in ((ROOT / "configs" / "tracks-box.yaml", bad, "a linear plant's gains"),
                         (ROOT / "configs" / "delay-multi-period.yaml", ROOT / "results" / "baselines" / "tracks-box" /
                          "gains.json", "K has 2 x 5 entries; this config's controller needs 2 x 9")):
        r = CliRunner().invoke(main, ["validate", str(cfg), "--engine", "kinematic", "--gains", str(g), "--episodes", "1",
                                      "--no-plots", "-o", str(tmp_path / "out")])
        assert r.exit_code == 2 and what in r.output, r.output
        assert not (tmp_path / "out").exists()


def test_on_a_path_rounded_by_arcs_the_straight_segments_leave_the_arcs_out(tmp_path) -> None:
    """With reference.turn_radius the path has no waypoint switch: the straight segments (judged, and
    where the slip is estimated) are where no command in flight carries a turning feedforward."""
    import numpy as np

    from robustsynth import build_model, load_config
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.plants.path import path_of
    from robustsynth.robot_verification.physics import validate_physics

    m = build_model(load_config(ROOT / "configs" / "turns.yaml"))
    g = load_gains(ROOT / "results" / "baselines" / "turns" / "gains.json")
    res = validate_physics(m, g, episodes=1, seed=0, engine="kinematic")
    path = path_of(m.config)
    w = np.array([path.feedforward(t) for t in res["t"]])
    assert res["validation"]["straight_rule"].startswith("between the arcs")
    assert not np.any(res["straight"][0] & (w != 0.0)) and np.any(res["straight"][0])
    assert res["validation"]["turn_max"]["e_y"] > 0.0


def test_a_second_run_leaves_no_stale_logs_or_figure(tmp_path) -> None:
    """validate into a directory an earlier validate filled: its logs beyond this run's episodes and its figure
    (this run has --no-plots) are removed; identify had fitted the stale logs with the new ones (review)."""
    g = str(ROOT / "results" / "baselines" / "tracks-box" / "gains.json")
    cfg = str(ROOT / "configs" / "tracks-box.yaml")
    r = CliRunner().invoke(main, ["validate", cfg, "--engine", "kinematic", "--gains", g, "--episodes", "3", "-o", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "validation.png").exists() and len(list((tmp_path / "logs").glob("episode_*.csv"))) == 3
    (tmp_path / "logs" / "mine.csv").write_text("kept\n")  # not a name validate writes: it stays
    r = CliRunner().invoke(main, ["validate", cfg, "--engine", "kinematic", "--gains", g, "--episodes", "1", "--no-plots",
                                  "-o", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (tmp_path / "logs").iterdir()) == ["episode_000.csv", "mine.csv"]
    assert not (tmp_path / "validation.png").exists()


def test_a_gains_mat_validates_and_bounds_that_are_not_the_robots_are_said(tmp_path) -> None:
    """A gains.mat (K as an array) had crashed with a traceback and exit 1.  A stability certificate states no
    error bounds, and a paper-model certificate's bounds are the paper model's, not the robot's: validate says so
    (it had said "passed" with nothing judged, and "the certificate covers it" of a paper-model gain: review)."""
    from scipy.io import savemat

    from robustsynth.artifacts.gains import gains_mat_vars

    gains = json.loads((ROOT / "results" / "baselines" / "tracks-box" / "gains.json").read_text())
    savemat(tmp_path / "gains.mat", gains_mat_vars(gains))
    cfg = str(ROOT / "configs" / "tracks-box.yaml")
    r = CliRunner().invoke(main, ["validate", cfg, "--engine", "kinematic", "--gains", str(tmp_path / "gains.mat"),
                                  "--episodes", "1", "--no-plots", "-o", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    assert "certified" in r.output and "covers it" in r.output
    from robustsynth.artifacts.files import to_jsonable
    from robustsynth.config import load_config
    from robustsynth.model import build_model
    from robustsynth.synthesis.analysis import analyze_stability

    stab = analyze_stability(build_model(load_config(cfg)), gains["K"], lyapunov="common")  # a stability certificate
    assert stab.certified
    for model, said in (("paper", "the paper's model"), ("stability", "states no error bounds")):
        cert = dict(gains["certificate"], model=model) if model == "paper" else to_jsonable(stab.certificate)
        g = dict(gains, certificate=cert)
        (tmp_path / f"{model}.json").write_text(json.dumps(g))
        r = CliRunner().invoke(main, ["validate", cfg, "--engine", "kinematic", "--gains", str(tmp_path / f"{model}.json"),
                                      "--episodes", "1", "--no-plots", "-o", str(tmp_path / model)])
        assert said in r.output, r.output
        # the slip box is covered by a stability certificate (robust stability), not by the paper model's
        assert ("covers it" in r.output) == (model == "stability"), r.output


def _narrow_robot(tmp_path, **physics) -> Path:
    """tracks-box with the tracks 0.38 m apart on a short straight path (a tiny episode), ``physics:`` as given."""
    import yaml

    d = yaml.safe_load((ROOT / "configs" / "tracks-box.yaml").read_text())
    d["name"] = "narrow"
    d["robot"]["track_distance"] = 0.38
    d["reference"]["path"] = [[0.0, 0.0], [1.5, 0.0]]
    if physics:
        d["physics"] = physics
    p = tmp_path / f"narrow-{len(physics)}.yaml"
    p.write_text(yaml.safe_dump(d))
    return p


def test_validate_says_which_physics_robot_it_ran_and_derives_it_from_the_config(tmp_path) -> None:
    """A robot whose tracks are 0.38 m apart (issue 50: run silently on the default 0.6 x 0.5 m chassis): the
    chassis is as wide as its tracks imply (0.38 + 2 x 0.025 m), the wheels are its sprockets (robot.gear_radius),
    and the CLI line and validation.json say so, with what is a default; the engine really runs that chassis
    (the same episode on the default-width chassis, set explicitly, moves differently) and a size the config
    sets is kept."""
    import numpy as np

    from robustsynth import build_model, load_config
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.robot_verification.physics import validate_physics

    cfg = _narrow_robot(tmp_path)
    r = CliRunner().invoke(main, ["validate", str(cfg), "--gains", str(ROOT / "results" / "baselines" / "tracks-box" /
                                                                          "gains.json"), "--episodes", "1", "--no-plots",
                                  "-o", str(tmp_path / "out")])
    assert r.exit_code in (0, 1), r.output
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    line = next(ln for ln in r.output.splitlines() if ln.startswith("physics robot (MuJoCo): "))
    assert "chassis 20 kg (default)" in line and "0.6 x 0.43 x 0.15 m (width from robot.track_distance: 0.38 m" in line
    assert "tracks 0.38 m apart (robot.track_distance)" in line and "sprocket radius 0.09 m (robot.gear_radius)" in line
    ph = json.loads((tmp_path / "out" / "validation.json").read_text())["physics"]
    assert ph["parameters"]["chassis_size"] == [0.6, 0.43, 0.15] and ph["parameters"]["track_spacing"] == 0.38
    assert ph["parameters"]["sprocket_radius"] == 0.09 and ph["source"]["chassis_mass"] == "default"
    assert ph["source"]["chassis_size"].startswith("width from robot.track_distance")
    assert {"chassis_size", "sprocket_radius", "track_spacing"} <= set(ph["derived"])
    # explicitly set values are kept, and the engine runs what the record says
    wide = load_config(_narrow_robot(tmp_path, chassis_size=[0.6, 0.5, 0.15], chassis_mass=12.0))
    g = load_gains(ROOT / "results" / "baselines" / "tracks-box" / "gains.json")
    res_wide = validate_physics(build_model(wide), g, episodes=1, seed=0)
    rec = res_wide["validation"]["physics"]
    assert rec["parameters"]["chassis_size"] == [0.6, 0.5, 0.15] and rec["source"]["chassis_size"] == "config"
    assert rec["parameters"]["chassis_mass"] == 12.0 and "chassis 12 kg (physics: in the config)" in rec["summary"]
    narrow12 = load_config(_narrow_robot(tmp_path, chassis_mass=12.0))
    res_narrow = validate_physics(build_model(narrow12), g, episodes=1, seed=0)
    assert res_narrow["validation"]["physics"]["parameters"]["chassis_size"] == [0.6, 0.43, 0.15]
    assert not np.array_equal(res_narrow["q"], res_wide["q"])  # another chassis in the engine, not just in the record
    # the kinematic engine runs no physics robot: nothing to state
    assert validate_physics(build_model(narrow12), g, episodes=1, engine="kinematic")["validation"]["physics"] is None


# --------------------------------------------------------------------------- the runtime monitor on the physics robot
K0 = 150  # the injections' period


@pytest.fixture(scope="module")
def default_robot():
    from robustsynth.artifacts.gains import controller_description, load_gains
    from robustsynth.config import load_config
    from robustsynth.model import build_model

    cfg = load_config(ROOT / "configs" / "default.yaml")
    gains = load_gains(ROOT / "results" / "baselines" / "default" / "gains.json")
    return build_model(cfg), gains, controller_description(gains, cfg)


def _alarms(model, gains, desc, inject=None, episodes=1):
    from robustsynth.runtime.replay import monitor_log
    from robustsynth.robot_verification.physics import validate_physics

    res = validate_physics(model, gains, episodes=episodes, seed=3, inject=inject)
    return [monitor_log(log, desc)["alarms"] for log in res["logs"]], res["validation"]


def test_episodes_inside_the_assumptions_raise_no_alarm(default_robot) -> None:
    """The default's gain on the physics robot, whole path (turns included), perturbed starts: the monitor is silent."""
    alarms, val = _alarms(*default_robot, episodes=3)
    assert val["passed"] and alarms == [[], [], []]


@pytest.mark.parametrize("kind, cause, within", [
    ("delay", "delay", 2), ("losses", "losses", 2), ("push", "set", 2), ("command", "motor", 2),
    ("friction", "slip", 10),  # the slip check's window (monitor.window: 10 periods)
])
def test_each_violation_injected_on_the_physics_robot_is_flagged_with_its_cause(default_robot, kind, cause, within) -> None:
    """Each kind of violation, injected from period K0 into an episode on the MuJoCo robot (validate --inject): the
    monitor names its cause within two periods (slip: within its window), and raises nothing before K0."""
    from robustsynth.robot_verification.physics import Injection

    alarms, val = _alarms(*default_robot, inject=Injection(kind, K0))
    assert val["injected"].startswith(f"{kind} from period {K0}")
    periods = [a["period"] for a in alarms[0]]
    assert periods and min(periods) >= K0, alarms[0][:3]
    seen = {c for a in alarms[0] if a["period"] <= K0 + within for c in a["causes"].split(", ")}
    assert cause in seen, alarms[0][:5]


def test_validate_inject_says_when_the_monitor_flagged_it_and_refuses_what_cannot_happen(tmp_path) -> None:
    gains = str(ROOT / "results" / "baselines" / "default" / "gains.json")
    cfg = str(ROOT / "configs" / "default.yaml")
    r = CliRunner().invoke(main, ["validate", cfg, "--gains", gains, "--episodes", "1", "--inject", "command",
                                  "--no-plots", "-o", str(tmp_path / "v")])
    # one command beyond the motor limit (the motors clip it) keeps this robot within its bounds: the verdict judges
    # what the robot did, the monitor says which assumption broke
    assert r.exit_code == 0 and "validation passed" in r.output, r.output
    assert f"injected command from period {K0}" in r.output and f"episode 0: period {K0} (motor" in r.output
    assert json.loads((tmp_path / "v" / "validation.json").read_text())["injected"].startswith("command")
    for args, words in ((["--inject", "push", "--inject-period", "100000"], "--inject-period"),
                        (["--inject", "push", "--engine", "kinematic"], "only on the physics robot"),
                        (["--inject-size", "2"], "--inject-size without --inject"),
                        (["--inject", "push", "--inject-size", "-1"], "--inject-size")):
        r = CliRunner().invoke(main, ["validate", cfg, "--gains", gains, "-o", str(tmp_path / "bad"), *args])
        assert r.exit_code == 2 and words in r.output, (args, r.output)
        assert not (tmp_path / "bad").exists()


def _compensated(tmp_path, *args):
    gains = str(ROOT / "results" / "baselines" / "harsh-compensated" / "gains.json")
    r = CliRunner().invoke(main, ["validate", str(ROOT / "configs" / "harsh-compensated.yaml"), "--gains", gains,
                                  "--episodes", "2", "--no-plots", "-o", str(tmp_path), *args])
    return r, json.loads((tmp_path / "validation.json").read_text())


def test_the_compensated_law_on_the_physics_robot_over_a_friction_patch(tmp_path) -> None:
    """Issue 55: the slip-compensated law (docs/theory.md §18) on the MuJoCo robot, driving onto ground of friction
    0.4 at period 150 and back after 100 periods: the deployed monitor and compensator in the loop, the estimate near
    the traction identify reads (about 0.98: the soft contact's sink; the patch hardly moves it on this robot), the
    condition held but in the estimator's first periods, the set kept wherever it held, the errors within the bounds
    for all t over the whole path, and the monitor silent."""
    r, vd = _compensated(tmp_path / "patch", "--inject", "patch", "--inject-size", "0.4")
    assert r.exit_code == 0 and "validation passed" in r.output, r.output
    comp = vd["compensated"]
    assert comp["condition_held_share"] > 0.95 and comp["samples_judged"] > 0.9 * 2 * vd["steps"]
    assert comp["samples_judged_outside_the_set"] == 0 and comp["episodes_not_back_at_the_end"] == 0
    assert all(0.95 < m < 1.0 for m in comp["estimate_median"])
    assert vd["injected"].startswith("patch from period 150")
    assert all(vd["ratio_to_certified"][k] < 1.0 for k in ("e_x", "e_y", "e_theta"))
    assert vd["monitor"]["runs_with_alarms"] == 0


def test_the_compensated_law_stuck_in_mud_fails_its_validation(tmp_path) -> None:
    """The mud patch (friction 0.3 and a drag, validate --inject friction) moves the traction faster than its rate:
    the monitor flags it, the condition stops holding, and the robot does not come back into its set: the
    validation fails although every sample the condition covered was in the set."""
    r, vd = _compensated(tmp_path / "mud", "--inject", "friction")
    assert r.exit_code == 1 and "validation FAILED" in r.output, r.output
    comp = vd["compensated"]
    assert comp["episodes_not_back_at_the_end"] == 2 and comp["samples_judged_outside_the_set"] == 0
    assert comp["condition_held_share"] < 0.7
    assert vd["monitor"]["alarm_periods"]["rate"] + vd["monitor"]["alarm_periods"]["slip"] > 0
