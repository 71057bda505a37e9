"""verify / run end to end: a certified gain passes, destabilizing gains fail with exit 1 naming
the failing checks, figures are produced and non-empty, files are consistent."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustsynth.cli import main

from robustsynth.config import load_config

from ..conftest import BASE_CONFIG, PASSING_CONFIG, make_config


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    # the base scenario: a linearized certificate on the tracks box, which the robot leaves from the set's
    # boundary: the verdict fails (exit 1) and names what did it
    r = CliRunner().invoke(main, ["run", str(BASE_CONFIG), "-o", str(out), "--runs", "40"])
    assert r.exit_code == 1, r.output
    assert "FAILED: nonlinear: one period from the boundary of the certified set stays in it" in r.output
    assert "the robot left from e = (" in r.output and "delays of the packets acting in the period" in r.output
    return out


@pytest.fixture(scope="module")
def passing_dir(tmp_path_factory):
    """A run whose verdict passes (the icr box of the physics robot, linearized: the robot keeps its set)."""
    out = tmp_path_factory.mktemp("passing")
    r = CliRunner().invoke(main, ["run", str(PASSING_CONFIG), "-o", str(out), "--runs", "10", "--no-plots"])
    assert r.exit_code == 0, r.output
    return out


def test_run_writes_everything(run_dir) -> None:
    for name in ("model.json", "model.md", "gains.json", "gains.mat", "synthesis.md", "verification.json",
                 "verification.md", "report.md", "summary.json"):
        assert (run_dir / name).stat().st_size > 0, name
    figs = sorted(p.name for p in (run_dir / "figures").iterdir())
    assert figs == sorted(f"{n}.png" for n in ("path", "errors", "commands", "network", "lyapunov", "ellipsoid", "frozen"))
    for p in (run_dir / "figures").iterdir():
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 10_000
    report = (run_dir / "report.md").read_text()
    for n in ("path", "errors", "ellipsoid"):
        assert f"figures/{n}.png" in report
    # the default's linearized certificate, which the robot leaves from its boundary, says so under the verdict
    assert report.split("\n\n")[2].startswith("> Note: the proof is for the robot's linearization: from the boundary")


def test_verification_json_is_consistent(run_dir) -> None:
    from robustsynth.artifacts.gains import gains_id

    v = json.loads((run_dir / "verification.json").read_text())
    # failed by the robot, and by nothing else: the probe from the boundary and the adversary from it
    assert v["passed"] is False
    assert {c["name"] for c in v["checks"] if not c["passed"]} == {
        "nonlinear: one period from the boundary of the certified set stays in it",
        "nonlinear: the adversary from the boundary of the certified set keeps it there"}
    g = json.loads((run_dir / "gains.json").read_text())
    assert v["gains_id"] == g["gains_id"] == gains_id(g)
    for c in v["checks"]:
        assert set(c) == {"name", "passed", "value", "threshold", "detail"}
    mc = v["monte_carlo"]
    assert mc["runs"] == 40 and set(mc["maxima"]) >= {"e_x", "e_y", "e_theta", "motor_speed"}
    # the certificate covers slip changing at any time within a period: the runs' slip does so
    assert mc["boundary_probe"]["mid_period"]["covered"] is True
    # the probe's local search, and the adversary from its worst states: on this linearized certificate both find
    # the robot leaving the set (1.07 on the default; the adversary from the figure maximizers alone stayed at 0.999)
    bp = mc["boundary_probe"]
    ref = bp["refinement"]
    assert ref["starts"] == 128 and bp["max_V_over_level_nonlinear"] == max(ref["max_V_over_level_before"],
                                                                             ref["max_V_over_level_after"]) > 1.0
    assert bp["adversary"]["searched_starts"] == 8 and bp["adversary"]["max_V_over_level"] > 1.0
    assert mc["slip_changes"].startswith("at uniform random times within the periods")
    # and the adversary searched the times of the changes too (a second search, merged with the first)
    assert mc["adversarial"]["slip_change_times"] == [0.0, 0.5]


@pytest.mark.slow
def test_verify_without_plots_leaves_no_earlier_figures(run_dir, tmp_path) -> None:
    """figures/ belongs to the verification: with --no-plots, an earlier run's figures go (they read as this
    verification's, a review found them kept); a file of another kind in figures/ stays."""
    import shutil

    shutil.copytree(run_dir, tmp_path / "r")
    assert len(list((tmp_path / "r" / "figures").glob("*.png"))) == 7
    (tmp_path / "r" / "figures" / "notes.txt").write_text("mine\n")
    r = CliRunner().invoke(main, ["verify", str(BASE_CONFIG), "-o", str(tmp_path / "r"), "--runs", "1", "--no-plots"])
    assert r.exit_code == 1, r.output  # the robot leaves this linearized certificate's set
    assert sorted(p.name for p in (tmp_path / "r" / "figures").iterdir()) == ["notes.txt"]
    md = (tmp_path / "r" / "verification.md").read_text()
    assert "figures/" not in md
    # a linearized certificate that the robot leaves says so under its verdict, in the terminal and the report
    bp = json.loads((tmp_path / "r" / "verification.json").read_text())["monte_carlo"]["boundary_probe"]
    top = max(bp["max_V_over_level_nonlinear"], bp["adversary"]["max_V_over_level"])
    said = f"the proof is for the robot's linearization: from the boundary of its set the nonlinear robot reaches V/level {top:.3f}"
    assert top > 1.0 and said in r.output and md.splitlines()[2] == f"> Note: {said}, so the verdict fails; " \
        "synthesis.kinematics: nonlinear proves the set for the robot, where one exists: docs/theory.md §9."


@pytest.mark.parametrize("bp, says", [
    ({}, False),
    ({"in_verdict": True, "max_V_over_level_nonlinear": 1.2}, "1.200"),  # every verdict judges the robot now
    ({"in_verdict": False, "max_V_over_level_nonlinear": 0.97, "adversary": {"max_V_over_level": 0.99}}, False),
    ({"in_verdict": False, "max_V_over_level_nonlinear": 0.97, "max_V_over_level_linear": 0.95,
      "adversary": {"max_V_over_level": 1.04}}, "1.040"),
    ({"in_verdict": False, "max_V_over_level_nonlinear": 1.07, "max_V_over_level_linear": 0.98,
      "arcs": {"max_V_over_level_nonlinear": 1.09}}, "1.090"),
])
def test_robot_leaves_is_said_only_of_a_linearized_certificate_the_robot_leaves(bp, says) -> None:
    from robustsynth.robot_verification.lines import robot_leaves

    got = robot_leaves({"boundary_probe": bp} if bp else {}, make_config())
    assert (got == "") if says is False else (f"linearization: from the boundary of its set the nonlinear robot reaches "
                                              f"V/level {says}, so the verdict fails" in got
                                              and "synthesis.kinematics: nonlinear proves the set for the robot" in got)


def test_robot_leaves_blames_the_model_the_exact_map_leaves_and_suggests_only_what_the_config_can_have() -> None:
    """The paper's model: the exact (slip-aware) lifted map leaves the set too, so the linearization is not
    the cause (review: the note blamed it at 1.348 on the exact map).  The icr slip model has nonlinear
    kinematics now: it is suggested there too.  A nonlinear certificate the robot leaves is a defect, said so."""
    from robustsynth.robot_verification.lines import robot_leaves

    bp = {"in_verdict": True, "max_V_over_level_nonlinear": 2.584, "max_V_over_level_linear": 1.348}
    got = robot_leaves({"boundary_probe": bp}, make_config(**{"synthesis.model": "paper"}))
    assert got.startswith("the certificate's model is not the robot's: from the boundary of its set the exact lifted map "
                          "reaches V/level 1.348 and the nonlinear robot 2.584") and "synthesis.model: slip-aware" in got
    assert "linearization" not in got and "kinematics: nonlinear" not in got
    bp = {"in_verdict": True, "max_V_over_level_nonlinear": 1.024, "max_V_over_level_linear": 0.95}
    icr = robot_leaves({"boundary_probe": bp}, make_config(**{"slip.model": "icr", "slip.yaw.min": 0.54, "slip.yaw.max": 0.67,
                                                          "slip.icr_offset.min": 0.0, "slip.icr_offset.max": 0.09}))
    assert "synthesis.kinematics: nonlinear proves the set for the robot" in icr
    nl = robot_leaves({"boundary_probe": bp}, load_config(PASSING_CONFIG.parent / "nonlinear-proof.yaml"))
    assert nl.startswith("the robot leaves a set proven for it (V/level 1.024)")


def test_gain_without_certificate_gets_one_searched_for_its_fixed_K(run_dir, tmp_path) -> None:
    """A bare K (from another tool): the analysis LMIs find a robust-stability certificate for it,
    re-checked in numpy, and the report says where the certificate came from and what it proves."""
    g = json.loads((run_dir / "gains.json").read_text())
    bare = tmp_path / "handmade.json"
    bare.write_text(json.dumps({"K": g["K"]}))
    r = CliRunner().invoke(main, ["verify", str(BASE_CONFIG), "--gains", str(bare), "-o", str(tmp_path / "v"), "--runs", "10", "--no-plots"])
    assert r.exit_code == 0, r.output
    v = json.loads((tmp_path / "v" / "verification.json").read_text())
    chk = {c["name"]: c for c in v["checks"]}
    assert chk["certificate: LMIs re-checked in numpy"]["passed"] is True
    assert "certificate from the analysis of the fixed K" in chk["certificate: LMIs re-checked in numpy"]["detail"]
    assert v["monte_carlo"]["certificate_source"].startswith("analysis of the fixed K")
    assert chk["nonlinear: max commanded |rho| <= rho_max"]["threshold"] == 12.0  # the physical limit itself


def test_gain_nothing_certifies_fails_and_says_so(run_dir, tmp_path) -> None:
    g = json.loads((run_dir / "gains.json").read_text())
    bare = tmp_path / "handmade.json"
    bare.write_text(json.dumps({"K": (20.0 * np.asarray(g["K"])).tolist()}))  # unstable: nothing can certify it
    r = CliRunner().invoke(main, ["verify", str(BASE_CONFIG), "--gains", str(bare), "-o", str(tmp_path / "v"), "--runs", "10", "--no-plots"])
    assert r.exit_code == 1
    v = json.loads((tmp_path / "v" / "verification.json").read_text())
    chk = {c["name"]: c for c in v["checks"]}
    assert chk["certificate: LMIs re-checked in numpy"]["passed"] is False
    assert "none found for the fixed K by the analysis LMIs" in chk["certificate: LMIs re-checked in numpy"]["detail"]


def test_report_shows_the_turns(run_dir) -> None:
    """report.md says what the verdict excludes: the turn transients, their errors and the motor
    commands against rho_max (saturated in the simulation by default)."""
    report = (run_dir / "report.md").read_text()
    assert "**Turns and other excluded steps**" in report
    v = json.loads((run_dir / "verification.json").read_text())
    tr = v["monte_carlo"]["transients"]
    assert tr["saturated"] is True and tr["motor_limit"] == 12.0
    if tr["max_commanded_motor_speed"] > 12.0:
        assert "the simulated motors saturate there" in report
    assert 0.0 < tr["excluded_steps_fraction"] < 0.5


@pytest.mark.parametrize(
    "content,expected",
    [("{", "invalid JSON"), ("[1, 2]", "must be a JSON object"), ('{"K": "x"}', "K: must be"),
     ('{"K": [[1, 2, 3]]}', "K: has shape")],
)
def test_bad_gains_file_exits_2(tmp_path, content, expected) -> None:
    p = tmp_path / "g.json"
    p.write_text(content)
    r = CliRunner().invoke(main, ["verify", "--gains", str(p), "-o", str(tmp_path / "v"), "--no-plots"])
    assert r.exit_code == 2, r.output
    assert expected in r.output and len(r.output.strip().splitlines()) == 1
    assert not (tmp_path / "v" / "verification.json").exists()


def test_missing_gains_exits_2(tmp_path) -> None:
    r = CliRunner().invoke(main, ["verify", "-o", str(tmp_path)])
    assert r.exit_code == 2 and "gains file not found" in r.output


@pytest.mark.slow
def test_pdf_figures(passing_dir, tmp_path) -> None:
    r = CliRunner().invoke(main, ["verify", str(PASSING_CONFIG), "--gains", str(passing_dir / "gains.json"), "-o", str(tmp_path),
                                  "--runs", "5",
                                  "--format", "pdf"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "figures" / "errors.pdf").read_bytes()[:5] == b"%PDF-"


def test_run_forwards_synthesis_options(tmp_path) -> None:
    r = CliRunner().invoke(main, ["run", str(BASE_CONFIG), "-o", str(tmp_path), "--objective", "stability", "--multiplier", "full",
                                  "--runs", "5", "--no-plots"])
    assert r.exit_code == 0, r.output
    g = json.loads((tmp_path / "gains.json").read_text())
    # the default's delay vertices have no Delta: the certificate records that no multiplier was taken, and a
    # note that the forwarded --multiplier full had no effect (stop 47: it recorded 'full')
    assert g["objective"] == "stability" and g["certificate"]["multipliers"]["kind"] == "none"
    assert any(n.startswith("synthesis.multiplier: full has no effect") for n in g["notes"])
    # the file records the config and, beside it, the settings the gain was made with that differ (stop 47)
    assert g["config"]["synthesis"]["objective"] == "ultimate-bound"
    assert g["synthesis_overrides"] == {"synthesis.objective": "stability", "synthesis.multiplier": "full"}
    v = json.loads((tmp_path / "verification.json").read_text())
    assert v["passed"] is True


def test_verify_reads_gains_mat(passing_dir, tmp_path) -> None:
    r = CliRunner().invoke(main, ["verify", str(PASSING_CONFIG), "--gains", str(passing_dir / "gains.mat"), "-o", str(tmp_path), "--runs", "5",
                                  "--no-plots"])
    assert r.exit_code == 0, r.output
    v = json.loads((tmp_path / "verification.json").read_text())
    names = {c["name"]: c["passed"] for c in v["checks"]}
    assert names["certificate: LMIs re-checked in numpy"] is True


@pytest.mark.slow
def test_verify_mat_with_only_K(passing_dir, tmp_path) -> None:
    from scipy.io import savemat

    g = json.loads((passing_dir / "gains.json").read_text())
    p = tmp_path / "other_tool.mat"
    savemat(p, {"K": np.asarray(g["K"])})
    r = CliRunner().invoke(main, ["verify", str(PASSING_CONFIG), "--gains", str(p), "-o", str(tmp_path / "v"), "--runs", "5", "--no-plots"])
    assert r.exit_code == 0, r.output  # no certificate in the file: one is found for the fixed K
    bad = tmp_path / "broken.mat"
    bad.write_bytes(b"not a mat file")
    r = CliRunner().invoke(main, ["verify", "--gains", str(bad), "-o", str(tmp_path / "w"), "--no-plots"])
    assert r.exit_code == 2 and "not a readable MATLAB .mat file" in r.output


def test_path_shorter_than_transient_fails_instead_of_passing_vacuously(run_dir, tmp_path) -> None:
    """A gain without a certificate is judged after fixed transients; a path shorter than them must
    fail a check rather than pass with no step looked at."""
    import yaml

    from ..conftest import default_dict

    d = default_dict()
    d["reference"]["path"] = [[0, 0], [1.0, 0]]  # 2 s of path
    d["verification"] = {"transient": 5.0, "runs": 5}
    cfg = tmp_path / "short.yaml"
    cfg.write_text(yaml.safe_dump(d))
    g = json.loads((run_dir / "gains.json").read_text())
    bare = tmp_path / "bare.json"
    bare.write_text(json.dumps({"K": g["K"]}))
    r = CliRunner().invoke(main, ["verify", str(cfg), "--gains", str(bare), "-o", str(tmp_path / "v"), "--no-plots"])
    assert r.exit_code == 1
    assert "FAILED: nonlinear: steps after the transients exist" in r.output


def test_certified_gain_is_judged_from_the_start_of_a_short_path(passing_dir, tmp_path) -> None:
    """With a certificate the runs start in the certified set (steady state of their first slip), so
    every step of a path without waypoints is covered and judged against the certificate itself."""
    import yaml

    d = yaml.safe_load(PASSING_CONFIG.read_text())
    d["reference"]["path"] = [[0, 0], [1.0, 0]]
    d["verification"] = {"runs": 5, "adversarial_runs": 2, "adversarial_steps": 20}
    cfg = tmp_path / "short.yaml"
    cfg.write_text(yaml.safe_dump(d))
    r = CliRunner().invoke(main, ["verify", str(cfg), "--gains", str(passing_dir / "gains.json"), "-o", str(tmp_path / "v"),
                                  "--no-plots"])
    assert r.exit_code == 0, r.output
    v = json.loads((tmp_path / "v" / "verification.json").read_text())
    mc = v["monte_carlo"]
    assert mc["certified_steps"] == 5 * mc["steps"] and mc["nonlinear_slack"] == 1.0


def test_a_gain_for_another_config_names_it_and_the_physics(tmp_path) -> None:
    """Issue 27: verify of the default gain on a config with another slip range says which config the
    gain was made for and what differs, and that the new config cannot be followed within the motor
    limit (mu 0.3 needs 18.5 rad/s > 12)."""
    from click.testing import CliRunner

    from robustsynth.cli import main

    root = Path(__file__).resolve().parents[2]
    cfg = tmp_path / "other.yaml"
    cfg.write_text((root / "configs" / "tracks-box.yaml").read_text().replace("{min: 0.6, max: 1.0}", "{min: 0.3, max: 1.0}")
                   .replace("name: default", "name: other"))
    r = CliRunner().invoke(main, ["verify", str(cfg), "--gains", str(root / "results" / "baselines" / "tracks-box" / "gains.json"),
                                  "-o", str(tmp_path / "out"), "--no-plots", "--runs", "3"])
    assert r.exit_code == 1
    assert "made for config 'tracks-box'" in r.output and "slip.right.min 0.6 -> 0.3" in r.output
    assert "required >= 5e-08" in r.output
    assert "physically infeasible" in r.output and "18.5 rad/s" in r.output


def test_a_turning_gain_on_a_path_that_jumps_is_refused_cleanly(tmp_path) -> None:
    """The review of 98b3471: the turns baseline verified with `reference.turn_radius: null` crashed in the
    lifted checks.  Now the re-check fails with the reason (exit 1), and export refuses the config (exit 2)."""
    root = Path(__file__).resolve().parents[2]
    gains = root / "results" / "baselines" / "turns" / "gains.json"
    cfg = tmp_path / "jumps.yaml"
    cfg.write_text((root / "configs" / "turns.yaml").read_text().replace("turn_radius: 5.0 ", "turn_radius: null "))
    r = CliRunner().invoke(main, ["verify", str(cfg), "--gains", str(gains), "-o", str(tmp_path / "v"), "--runs", "4",
                                  "--no-plots"])
    assert r.exit_code == 1, r.output
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception  # no crash
    assert "the config's path jumps at its waypoints (reference.turn_radius is null)" in r.output
    r = CliRunner().invoke(main, ["export", str(gains), "--to", "json", "-o", str(tmp_path / "e"), "--config", str(cfg)])
    assert r.exit_code == 2 and "certified for arcs of 5.0 m and wider" in r.output
    assert not (tmp_path / "e").exists()


def test_an_unwritable_log_place_is_refused_before_the_work(tmp_path) -> None:
    """--log that cannot be written ends with exit 2 before verification runs: no verification files, one line
    (a review found the whole verification done and written, "passed" printed, and then exit 2)."""
    (tmp_path / "afile").write_text("x")
    out = tmp_path / "out"
    gains = Path(__file__).resolve().parents[2] / "results" / "baselines" / "tracks-box" / "gains.json"
    r = CliRunner().invoke(main, ["verify", "--gains", str(gains), "--runs", "1", "--no-plots", "--log",
                                  str(tmp_path / "afile" / "logs"), "-o", str(out)])
    assert r.exit_code == 2, r.output
    assert "afile/logs: cannot write" in r.output and "passed" not in r.output
    assert not (out / "verification.json").exists()


def test_a_failed_verify_leaves_no_empty_log_place(tmp_path) -> None:
    """--log's directory is made before the work; when the work then fails (here: gains of another size) it
    is removed again, with the parents it made, rather than left empty (a review)."""
    gains = tmp_path / "bad.json"
    gains.write_text(json.dumps({"K": [[1.0, 2.0]]}))
    logs = tmp_path / "new" / "logs"
    r = CliRunner().invoke(main, ["verify", "--gains", str(gains), "--runs", "1", "--no-plots", "--log", str(logs),
                                  "-o", str(tmp_path / "out")])
    assert r.exit_code == 2, r.output
    assert not (tmp_path / "new").exists()
    kept = tmp_path / "kept"
    kept.mkdir()
    r = CliRunner().invoke(main, ["verify", "--gains", str(gains), "--runs", "1", "--no-plots", "--log", str(kept),
                                  "-o", str(tmp_path / "out")])
    assert r.exit_code == 2 and kept.is_dir()  # a place that existed before stays


def test_a_synthesized_gains_mat_exports_as_certified_and_an_edited_one_does_not(passing_dir, tmp_path) -> None:
    """A gains.mat keeps the certificate, not its figures: export re-checks it on the stored config and carries the
    figures of gains.json (a review found every synthesized gains.mat exported as UNCERTIFIED); K edited in the
    .mat fails the re-check (exported only with allow_unverified)."""
    from scipy.io import loadmat, savemat

    from robustsynth.runtime.export import export_controller

    d_mat, _ = export_controller(passing_dir / "gains.mat", "python", tmp_path / "m")
    d_json, _ = export_controller(passing_dir / "gains.json", "python", tmp_path / "j")
    assert d_mat["certified"]["ultimate_bound"] == pytest.approx(d_json["certified"]["ultimate_bound"], rel=1e-9)
    assert "the certified networked-robot controller" in (tmp_path / "m" / "rs_controller.py").read_text()
    m = loadmat(passing_dir / "gains.mat")
    m["K"][0, 0] += 5.0
    savemat(tmp_path / "edited.mat", {k: v for k, v in m.items() if not k.startswith("__")})
    d, _ = export_controller(tmp_path / "edited.mat", "python", tmp_path / "e", allow_unverified=True)
    assert not d.get("certified") and "UNCERTIFIED" in (tmp_path / "e" / "rs_controller.py").read_text()
