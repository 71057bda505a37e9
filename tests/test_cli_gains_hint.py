"""A file robustsynth wrote, given where CONFIG goes (issue 50: `robustsynth verify gains.json` printed an
18-item validation error wall): one line naming what the file is and what to do, exit 2; and `verify --gains G`
without CONFIG verifies G on the config stored in it, as `margin` does."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from robustsynth.cli import main

ROOT = Path(__file__).resolve().parents[1]
BASELINES = ROOT / "results" / "baselines"
GAINS = BASELINES / "icr-physics" / "gains.json"


def _one_line_error(r, code: int = 2) -> str:
    assert r.exit_code == code, r.output
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    assert "Traceback" not in r.output and len(r.stderr.strip().splitlines()) == 1, r.stderr
    return r.stderr.strip()


@pytest.mark.parametrize("args", [
    ["verify", "{G}"], ["verify", "{G}", "--gains", "{G}"], ["margin", "{G}"], ["validate", "{G}", "--gains", "{G}"],
    ["check-log", "log.csv", "--config", "{G}"],
])
def test_a_gains_file_given_as_config_says_to_use_gains(args, tmp_path) -> None:
    g = tmp_path / "gains.json"
    shutil.copy(GAINS, g)
    (tmp_path / "log.csv").write_text("t,x,y,theta\n")
    argv = [a.replace("{G}", str(g)).replace("log.csv", str(tmp_path / "log.csv")) for a in args]
    line = _one_line_error(CliRunner().invoke(main, argv + (["-o", str(tmp_path / "out")] if args[0] != "check-log" else [])))
    assert line == f"error: {g}: this is a gains file, not a config: use --gains {g} (its config is stored inside)"
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("cmd", ["build-model", "synthesize", "run"])
def test_a_gains_file_given_to_a_command_without_gains_names_the_command(cmd, tmp_path) -> None:
    r = CliRunner().invoke(main, [cmd, str(GAINS), "-o", str(tmp_path / "out")])
    line = _one_line_error(r)
    assert f"{GAINS}: this is a gains file, not a config: `robustsynth {cmd}` takes a config YAML" in line
    assert not (tmp_path / "out").exists()


def test_a_gains_mat_and_a_linear_plants_gains_file_are_gains_files_too(tmp_path) -> None:
    from scipy.io import savemat

    from robustsynth.artifacts.gains import gains_mat_vars

    mat = tmp_path / "gains.mat"
    savemat(mat, gains_mat_vars(json.loads(GAINS.read_text())))
    lti = tmp_path / "lti.json"
    lti.write_text(json.dumps({"kind": "lti", "K": [[0.1, 0.2]], "lifting": {"n": 1, "m": 1, "d": 1},
                               "gains_id": "x" * 64}))
    for g in (mat, lti):
        line = _one_line_error(CliRunner().invoke(main, ["verify", str(g), "-o", str(tmp_path / "out")]))
        assert line == f"error: {g}: this is a gains file, not a config: use --gains {g} (its config is stored inside)"


def test_other_files_robustsynth_wrote_are_named(tmp_path) -> None:
    """model.json, summary.json, verification.json, the controller description: named as what they are."""
    r = CliRunner().invoke(main, ["build-model", str(ROOT / "tests" / "data" / "base.yaml"), "-o", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    desc = tmp_path / "e"
    assert CliRunner().invoke(main, ["export", str(GAINS), "--to", "json", "-o", str(desc)]).exit_code == 0
    ver = tmp_path / "verification.json"  # the fields `robustsynth verify` writes at the top
    ver.write_text(json.dumps({"schema_version": 1, "robustsynth_version": "0", "passed": True, "gains_file": "gains.json",
                               "gains_id": "0" * 64, "config": {"name": "x"}, "checks": [], "frozen": {}, "lifted": {},
                               "monte_carlo": {}}))
    for path, what in ((tmp_path / "m" / "model.json", "a model file (model.json"),
                       (BASELINES / "default" / "summary.json", "a run summary (summary.json"),
                       (ver, "a verification record (verification.json"),
                       (desc / "rs_controller.json", "a controller description")):
        line = _one_line_error(CliRunner().invoke(main, ["synthesize", str(path), "-o", str(tmp_path / "out")]))
        assert line.startswith(f"error: {path}: this is {what}") and "not a config: pass the config YAML" in line, line


def test_export_config_option_given_a_gains_file(tmp_path) -> None:
    line = _one_line_error(CliRunner().invoke(main, ["export", str(GAINS), "--to", "c", "-o", str(tmp_path / "c"),
                                                     "--config", str(GAINS)]))
    assert line == f"error: --config: {GAINS}: this is a gains file, not a config: give it as GAINS (its config is stored inside)"
    assert not (tmp_path / "c").exists()


def test_a_config_that_is_wrong_still_gets_its_own_errors(tmp_path) -> None:
    """Only files robustsynth wrote are recognized: a config written as JSON with a bad key keeps its message."""
    import yaml

    d = yaml.safe_load((ROOT / "configs" / "tracks-box.yaml").read_text())
    d["robot"]["track_distance"] = -1.0
    p = tmp_path / "c.json"
    p.write_text(json.dumps(d))
    r = CliRunner().invoke(main, ["build-model", str(p), "-o", str(tmp_path / "out")])
    assert r.exit_code == 2 and "robot.track_distance" in r.output and "not a config" not in r.output


def test_verify_with_gains_only_uses_the_config_stored_in_it(tmp_path) -> None:
    """`verify --gains G` without CONFIG: the config stored in G (it had verified the gain on the embedded default
    config), said in one line; verification.json records it."""
    g = tmp_path / "gains.json"
    shutil.copy(GAINS, g)
    r = CliRunner().invoke(main, ["verify", "--gains", str(g), "--runs", "1", "--no-plots"])
    assert r.exit_code == 0, r.output
    assert f"config: the one stored in {g} ('icr-physics'), the gain's own; pass CONFIG to verify it on another" in r.stdout
    v = json.loads((tmp_path / "verification.json").read_text())
    from robustsynth.config import config_from_dict, config_to_dict

    # the stored config as the config model reads it (a baseline written before reference.path holds verification.path)
    stored = config_to_dict(config_from_dict(json.loads(g.read_text())["config"]))
    assert v["config"]["name"] == "icr-physics" and v["config"] == stored
    # and the export then finds this gain's verification beside it
    r = CliRunner().invoke(main, ["export", str(g), "--to", "json", "-o", str(tmp_path / "e")])
    assert r.exit_code == 0 and "verification: passed for exactly this gain (verification.json" in r.stdout, r.output
