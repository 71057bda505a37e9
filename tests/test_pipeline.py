"""The stages of the one pipeline, for every plant (issue 52): the same stage types, the same files in the same
order of writing, every record headed alike and naming the gain it belongs to; a new gain sets the old
verification aside, and a config another plant's stages wrote is set aside, not mixed with."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robustsynth import __version__
from robustsynth.artifacts.files import SCHEMA_VERSION, json_bytes
from robustsynth.config import load_config
from robustsynth.pipeline import (ModelStage, SynthesisStage, VerificationStage, model_stage, plant_of, synthesis_stage,
                                  verification_stage)
from robustsynth.artifacts.certified import certified_lines
from robustsynth.results import CertificateCheck, Err
from robustsynth.synthesis import SynthesisResult

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
PLANTS = [("paper-model", "tracked-robot"), ("dc-motor", "lti")]  # the quickest committed config of each kind


def _json(path: Path) -> dict:
    return json.loads(path.read_text())


@pytest.mark.parametrize("name,kind", PLANTS)
def test_every_plant_goes_through_the_same_stages(tmp_path, name, kind) -> None:
    path = CONFIGS / f"{name}.yaml"
    cfg = load_config(path)
    out = tmp_path / "r"
    ms = model_stage(cfg, out, path)
    assert isinstance(ms, ModelStage) and ms.model.plant_kind == kind and ms.cleared == ()
    assert ms.files[-1] == out / "model.json"  # the primary file last
    plant = ms.model
    ss = synthesis_stage(plant, out, compare=False, diagnose=None if kind == "lti" else False)
    assert isinstance(ss, SynthesisStage) and isinstance(ss.result, SynthesisResult)
    assert ss.result.plant_kind == kind and isinstance(ss.result.check, CertificateCheck) and ss.result.check.passed
    assert [p.name for p in ss.files] == ["gains.mat", "synthesis.md", "gains.json"]
    gd = _json(out / "gains.json")
    assert gd == json.loads(json_bytes(ss.gains)) and gd["K"] == ss.result.K.tolist()  # the file is the stage's record
    # the lines the CLI prints come from the results themselves (issue 52, item 2)
    assert ss.result.lines(plant) == certified_lines(ss.gains)[:1] + [f"note: {n}" for n in gd.get("notes", [])]
    assert ss.result.check.lines()[0].startswith(f"certificate check passed: {len(ss.result.check.checks)} famil")
    assert ss.result.check.lines()[0].endswith(f"smallest margin found {ss.result.check.min_eig_margin:.3g}")
    vs = verification_stage(plant, out, runs=4, plots=False)
    assert isinstance(vs, VerificationStage) and vs.figures == {}
    said = vs.result.lines()
    assert [line for line in said if isinstance(line, Err)] == [
        line for line in said if line.startswith("FAILED: ")] and len([l for l in said if isinstance(l, Err)]) == len(
        vs.result.failed_checks)
    assert any(line.startswith(f"verification {'passed' if vs.result.passed else 'FAILED'}: {len(vs.result.checks)} "
                               "checks, ") for line in said)
    assert [p.name for p in vs.files] == ["verification.md", "verification.json"]
    vd = _json(out / "verification.json")
    # the record says what the result says (paper-model's verdict fails: the nonlinear robot leaves the paper model's
    # certified set, the subject of issue 49)
    assert vd["gains_id"] == gd["gains_id"] and vd["passed"] is bool(vs.result.passed) and vs.result.checks
    for record in (_json(out / "model.json"), gd, vd):  # every record says which schema and version wrote it
        assert (record["schema_version"], record["robustsynth_version"]) == (SCHEMA_VERSION, __version__)
    # every plant's verdict answers alike: passed, checks, failed_checks, details, to_dict (plain data)
    res = vs.result
    assert res.failed_checks == [c["name"] for c in res.checks if not c["passed"]] and isinstance(res.details, dict)
    d = json.loads(json.dumps(res.to_dict()))
    assert d["passed"] is bool(res.passed) and [c["name"] for c in d["checks"]] == [c["name"] for c in res.checks]
    assert set(res.details) <= set(d)
    # a new gain makes the verification of the old one stale: set aside, never left beside it
    synthesis_stage(plant, out, compare=False, diagnose=None if kind == "lti" else False)
    assert not (out / "verification.json").exists() and list((out / "stale").rglob("verification.json"))


def test_a_directory_of_the_other_plant_is_set_aside(tmp_path) -> None:
    """The robot's model stage into a directory a linear plant's stages wrote: their files are moved aside (one
    directory never reads as one run of two configs), whichever plant wrote them."""
    lin = CONFIGS / "dc-motor.yaml"
    out = tmp_path / "r"
    model_stage(load_config(lin), out, lin)
    robot = CONFIGS / "paper-model.yaml"
    ms = model_stage(load_config(robot), out, robot)
    assert ms.cleared and all("stale" in c for c in ms.cleared)
    assert _json(out / "model.json")["config"]["name"] == "paper-model"


def test_plant_of_builds_the_plant_a_config_describes() -> None:
    from robustsynth.model import Model
    from robustsynth.plants.linear import LinearPlant

    lin = plant_of(load_config(CONFIGS / "dc-motor.yaml"), CONFIGS / "dc-motor.yaml")
    assert isinstance(lin, LinearPlant) and lin.config.name == "dc-motor" and lin.user_config is lin.config
    assert isinstance(plant_of(load_config(CONFIGS / "paper-model.yaml")), Model)


def test_a_robot_option_on_a_linear_plant_is_refused_before_any_work(tmp_path) -> None:
    from robustsynth.errors import InputError

    path = CONFIGS / "dc-motor.yaml"
    plant = plant_of(load_config(path), path)
    for options in ({"diagnose": True}, {"multiplier": "full"}):
        with pytest.raises(InputError, match=rf"^{next(iter(options))}: a tracked robot's option"):
            synthesis_stage(plant, tmp_path / "x", **options)
    with pytest.raises(InputError, match=r"^progress: a tracked robot's option"):
        verification_stage(plant, tmp_path / "x", CONFIGS.parent / "results" / "baselines" / "dc-motor" / "gains.json",
                           progress=lambda done, total: None)
    assert not (tmp_path / "x").exists()
