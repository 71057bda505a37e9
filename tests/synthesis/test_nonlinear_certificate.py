"""The certificate for the nonlinear robot (synthesis.kinematics: nonlinear, docs/theory.md §9):
re-checked in numpy with the kinematic channels and its heading bound, judged against the robot
itself from the boundary of its set, refused where it does not exist (exit 3)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustsynth.artifacts.gains import load_gains
from robustsynth.certificate import check_certificate, lyapunov_of
from robustsynth.cli import main
from robustsynth.config import load_config
from robustsynth.errors import ConfigError
from robustsynth.model import build_model
from robustsynth.verification.probe import boundary_probe

from ..conftest import make_config

ROOT = Path(__file__).resolve().parents[2]
LEVEL_TOL = 1e-9  # V/level: round-off only


@pytest.fixture(scope="module")
def committed():
    """The committed nonlinear-proof gain (results/baselines), its model and certificate."""
    m = build_model(load_config(ROOT / "configs" / "nonlinear-proof.yaml"))
    g = load_gains(ROOT / "results" / "baselines" / "nonlinear-proof" / "gains.json")
    return m, np.asarray(g["K"], dtype=float), g["certificate"]


def test_the_committed_certificate_passes_and_bounds_the_heading(committed) -> None:
    m, K, cert = committed
    assert cert["kinematics"] == "nonlinear"
    chk = check_certificate(m, K, cert)
    assert chk.passed, chk.reason
    f = chk.figures
    assert f["heading_within_period"] <= f["heading_bound"] == cert["heading_bound"]
    # between samples the heading bound covers the sampled one
    assert f["heading_within_period"] >= f["ultimate_bound"]["e_theta"] * (1 - 1e-9)


def test_the_nonlinear_robot_stays_in_the_set_from_its_boundary(committed) -> None:
    """Certificate vs simulation: exact arcs from states on V = level (random directions and each
    figure's maximizers, slip corners, admissible delays) never leave the set."""
    m, K, cert = committed
    level = float(check_certificate(m, K, cert).figures["ellipsoid_level"])
    r = boundary_probe(m, K, lyapunov_of(m, cert), level, samples=20_000, seed=4)
    assert r["samples"] > 15_000
    assert r["max_V_over_level_nonlinear"] <= 1.0 + LEVEL_TOL
    assert r["max_V_over_level_nonlinear"] > 0.5  # the probe does reach the boundary's neighbourhood


def test_a_smaller_heading_bound_or_the_linearized_model_is_refused(committed) -> None:
    m, K, cert = committed
    tampered = dict(cert, heading_bound=0.5 * float(cert["heading_bound"]))
    chk = check_certificate(m, K, tampered)
    assert not chk.passed
    lin = build_model(load_config(ROOT / "configs" / "nonlinear-proof.yaml").model_copy(
        update={"synthesis": load_config(ROOT / "configs" / "nonlinear-proof.yaml").synthesis.model_copy(
            update={"kinematics": "linearized"})}))
    chk = check_certificate(lin, K, cert)
    assert not chk.passed and "kinematics" in chk.reason


def test_the_default_robot_has_none_and_says_why(tmp_path) -> None:
    """Slip in [0.6, 1] per track: no heading bound gives an invariant set (measured); exit 3 with
    the heading and forward-speed ranges of the linearized set, and no gains file."""
    cfg = tmp_path / "c.yaml"
    text = (ROOT / "configs" / "default.yaml").read_text().replace("  objective: ultimate-bound",
                                                                      "  objective: ultimate-bound\n  kinematics: nonlinear")
    cfg.write_text(text)
    r = CliRunner().invoke(main, ["synthesize", str(cfg), "-o", str(tmp_path / "out")])
    assert r.exit_code == 3, r.output
    assert "e_theta(t)" in r.output and "forward-speed" in r.output
    assert "Traceback" not in r.output
    assert not (tmp_path / "out" / "gains.json").exists()


@pytest.mark.parametrize("over", [{"synthesis.objective": "stability"}, {"synthesis.model": "paper"},
                                  {"synthesis.delay_description": "norm-bounded"}])
def test_nonlinear_kinematics_needs_the_slip_aware_invariant_set_on_delay_vertices(over) -> None:
    with pytest.raises(ConfigError, match="kinematics"):
        make_config(**{"synthesis.kinematics": "nonlinear", **over})


def test_gains_round_trip_keeps_the_kinematics(committed, tmp_path) -> None:
    """gains.json -> .mat -> the certificate re-checks from the .mat as from the JSON."""
    from robustsynth.artifacts.gains import gains_mat_vars
    from scipy.io import savemat

    m, K, cert = committed
    gd = json.loads((ROOT / "results" / "baselines" / "nonlinear-proof" / "gains.json").read_text())
    savemat(tmp_path / "g.mat", gains_mat_vars(gd))
    back = load_gains(tmp_path / "g.mat")
    assert back["certificate"]["kinematics"] == "nonlinear"
    assert check_certificate(m, np.asarray(back["K"], dtype=float), back["certificate"]).passed
