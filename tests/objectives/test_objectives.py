"""robustsynth.objectives: the registry every floor reads, and a toy objective added as docs/architecture.md's
"How to add an objective" says (tests/objectives/toy_decay.py: one module and its registry line), run through
the config, the CLI, the synthesis, the certificate's check and the report of the robot, and the config and
the synthesis of a linear plant."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robustsynth import objectives
from robustsynth.errors import ConfigError

from ..conftest import BASE_CONFIG, make_config
from . import toy_decay

ROOT = Path(__file__).resolve().parents[2]
RATE_TOL = 1e-9  # a proven decay rate is rounded outwards, never below what was asked
RATE_ROUNDING = 1e-6  # ... and by no more than this (relative): the figure is the rate the toy asked for
SPECTRAL_TOL = 1e-9  # frozen closed loops of a gain proven to decay at r: spectral radius <= r


def _constant_delay_radii(plant, K: np.ndarray, thetas) -> np.ndarray:
    """The closed loop's spectral radius at 9 constant delays across the network's range (and every slip corner):
    an independent judge of a decay rate (a gain proven to decay at r has every frozen loop's radius <= r)."""
    from robustsynth.verification.lifted import periodic_spectral_radius

    net = plant.network
    return periodic_spectral_radius(plant, K, np.linspace(net.delay_min, net.delay_max, 9)[:, None], thetas)


@pytest.fixture
def toy():
    objectives.register(toy_decay.TOY)
    yield toy_decay
    objectives.unregister(toy_decay.NAME)


@pytest.mark.parametrize("name", objectives.names())
def test_every_objective_has_its_design_and_its_rows_on_their_floors(name: str) -> None:
    obj = objectives.objective(name)
    assert obj.design.startswith("robustsynth.synthesis.objectives.")  # the solver's floor
    design = importlib.import_module(obj.design)
    for plant, fn in (("tracked-robot", "robot"), ("lti", "linear")):
        assert callable(getattr(design, fn, None)) == (plant in obj.plants), (name, fn)
    if "tracked-robot" in obj.plants:
        assert obj.check.startswith("robustsynth.certificate.objectives.")  # the checker's floor: no solver there
        assert callable(importlib.import_module(obj.check).rows)


def test_the_checkers_rows_import_no_solver() -> None:
    """The registry's modules are imported by name (importlib), which tests/test_architecture.py does not see:
    in a fresh interpreter, every objective's rows and a checked certificate leave cvxpy unimported."""
    code = ("import importlib, sys\n"
            "from robustsynth import objectives\n"
            "from robustsynth.artifacts.gains import load_gains\n"
            "from robustsynth.certificate import recheck_gains\n"
            "from robustsynth.config import load_config\n"
            "from robustsynth.model import build_model\n"
            "for o in objectives.OBJECTIVES.values():\n"
            "    importlib.import_module(o.check).rows\n"
            f"g = load_gains({str(ROOT / 'results' / 'baselines' / 'default' / 'gains.json')!r})\n"
            f"assert recheck_gains(build_model(load_config({str(ROOT / 'configs' / 'default.yaml')!r})), g).passed\n"
            "print('cvxpy' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stderr


def test_a_name_is_registered_once_and_a_descriptor_is_checked() -> None:
    with pytest.raises(ValueError, match="taken"):
        objectives.register(objectives.objective("hinf"))
    with pytest.raises(ValueError, match="taken"):
        objectives.register(objectives.Objective("auto", "decay", "decay_rate", "", design="x", check="y"))
    with pytest.raises(ValueError, match="guarantee"):
        objectives.Objective("x", "bound", "decay_rate", "", design="x", check="y")
    with pytest.raises(ValueError, match="certificate's rows"):
        objectives.Objective("x", "decay", "decay_rate", "", design="x")
    with pytest.raises(ValueError, match="needs a label"):
        objectives.Objective("x", "gain", "x_gain", "", design="x", check="y", figures=("x_gain",))
    # an objective of the linear plant only adds nothing to the robot's figures
    objectives.register(objectives.Objective("lin-only", "gain", "lin_gain", "", design="x", plants=("lti",),
                                             figures=("lin_gain",), label="a linear gain"))
    try:
        assert "lin_gain" not in objectives.certified_keys()
        assert objectives.labelled_figures(objectives.ROBOT_FIGURES_SHOWN) == [("hinf_gain", objectives.objective(
            "hinf").label)]
    finally:
        objectives.unregister("lin-only")
    with pytest.raises(KeyError, match="ultimate-bound, stability, hinf"):
        objectives.objective("h-inf")


def test_the_config_and_the_cli_offer_what_is_registered(toy) -> None:
    from click.testing import CliRunner

    from robustsynth.cli import main

    assert make_config(**{"synthesis.objective": toy.NAME}).synthesis.objective == toy.NAME
    with pytest.raises(ConfigError, match="synthesis.objective: Input should be 'ultimate-bound', 'stability', "
                                          f"'hinf' or '{toy.NAME}'"):
        make_config(**{"synthesis.objective": "h-inf"})
    help_text = CliRunner().invoke(main, ["synthesize", "--help"]).output
    assert f"{toy.NAME}]" in help_text.replace("\n", "").replace(" ", "")


def test_a_toy_objective_runs_through_the_robot_synthesis_check_and_report(toy, tmp_path) -> None:
    """The toy's gain is proven by the checker (its rows named by the registry), decays at its rate on every
    frozen delay (an independent judge: the closed loop's spectral radius), and is refused once its rate is
    claimed lower than proven; the CLI writes it, the report says what it optimizes."""
    from click.testing import CliRunner

    from robustsynth import build_model, synthesize
    from robustsynth.artifacts.gains import gains_dict
    from robustsynth.certificate import check_certificate, recheck_gains
    from robustsynth.cli import main
    from robustsynth.verification.checks import claimed_beyond

    model = build_model(make_config(**{"synthesis.objective": toy.NAME}))
    res = synthesize(model)
    assert res.objective == toy.NAME and res.check.passed
    assert toy.RATE - RATE_TOL <= res.certified["decay_rate"] <= toy.RATE * (1 + RATE_ROUNDING)
    gd = gains_dict(model, res)
    assert recheck_gains(model, gd).passed
    # its own figure, written by its rows only: V halves within it at the proven rate, not one period sooner
    half = gd["certified"]["toy_half_life"]
    r = res.certified["decay_rate"]
    assert r ** (2 * half) <= 0.5 < r ** (2 * (half - 1))
    # verify's comparison of a file's figures with the re-check reads the toy's figure: a shorter one is refused
    assert claimed_beyond(dict(gd["certified"], toy_half_life=half - 1), res.certified) == ["toy_half_life"]
    assert claimed_beyond(gd["certified"], res.certified) == []
    radii = _constant_delay_radii(model, res.K, np.asarray(model.parameter_corners())[:, None, :])
    assert np.max(radii) <= toy.RATE + SPECTRAL_TOL
    # a stronger claim than the gain meets is refused by the same rows: frozen, the loop decays at max(radii)
    claim = dict(res.certificate, r2=(0.5 * np.min(radii)) ** 2)
    refused = check_certificate(model, res.K, claim)
    assert not refused.passed
    assert any(c["name"].startswith("decay LMI (6a)") and not c["passed"] for c in refused.checks)

    out = tmp_path / "out"
    run = CliRunner().invoke(main, ["synthesize", str(BASE_CONFIG), "--objective", toy.NAME, "-o", str(out)])
    assert run.exit_code == 0, run.output
    gains = json.loads((out / "gains.json").read_text())
    assert gains["objective"] == toy.NAME and gains["certified"]["decay_rate"] >= toy.RATE - RATE_TOL
    assert gains["certified"]["toy_half_life"] == half
    assert f"periods for V to halve {half:.4g}" in run.output  # the console's line of certified figures
    md = (out / "synthesis.md").read_text()
    assert toy.TOY.text in md and f"| periods for V to halve | {half} |" in md


def test_a_toy_objective_runs_through_the_linear_plant(toy) -> None:
    """A linear plant's config names the toy (validated by the registry), and robustsynth.synthesize designs it
    with the toy's linear design: decaying at its rate, no faster and no slower, on every constant delay."""
    import yaml

    import robustsynth
    from robustsynth.config import load_config
    from robustsynth.plants.linear import LinearPlant

    data = yaml.safe_load((ROOT / "configs" / "dc-motor.yaml").read_text())
    data["synthesis"] = dict(data.get("synthesis") or {}, objective=toy.NAME)
    cfg = load_config(data)
    lin = LinearPlant.from_config(cfg, str(ROOT / "configs"))
    design = robustsynth.synthesize(lin)
    assert design.check.passed and design.plant_kind == "lti" and design.objective == toy.NAME
    assert toy.RATE - RATE_TOL <= design.certified["decay"] <= toy.RATE * (1 + RATE_ROUNDING)
    data["synthesis"]["objective"] = "h-inf"
    with pytest.raises(ConfigError, match="synthesis.objective: Input should be 'auto', 'ultimate-bound', "
                                          f"'stability', 'hinf' or '{toy.NAME}'"):
        load_config(data)
    assert np.max(_constant_delay_radii(lin, design.K, None)) <= toy.RATE + SPECTRAL_TOL


def test_a_descriptor_whose_modules_are_missing_is_one_line(toy) -> None:
    from robustsynth import build_model, synthesize
    from robustsynth.certificate.check import _rows_of

    objectives.unregister(toy.NAME)
    objectives.register(objectives.Objective("toy-broken", "decay", "decay_rate", "", design="tests.objectives.nowhere",
                                             check="tests.objectives.nowhere"))
    try:
        with pytest.raises(RuntimeError, match="toy-broken: its design module tests.objectives.nowhere cannot be"):
            synthesize(build_model(make_config(**{"synthesis.objective": "toy-broken"})))
        with pytest.raises(RuntimeError, match=r"toy-broken: its certificate's rows \(tests.objectives.nowhere.rows\)"):
            _rows_of("toy-broken")
    finally:
        objectives.unregister("toy-broken")
    with pytest.raises(ValueError, match="built in"):
        objectives.unregister("hinf")
