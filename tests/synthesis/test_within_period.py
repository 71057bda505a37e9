"""Constraint generation for slip changing within a period (docs/theory.md §11): the LMIs hold the
model's own vertices; a solved point that the re-check refuses only at within-period vertices gets
the worst of those added and is solved again.  At a decay rate where the constant-slip LMIs alone
give a gain that fails there, the runner certifies one with the added vertices, and without a way to
add them nothing is certified (the re-check, not the solver, decides)."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.certificate import check_certificate, varying_failures
from robustsynth.synthesis import synthesize
from robustsynth.synthesis.runner import _cert_common, _Runner
from robustsynth.synthesis.lmis import build_stability
from robustsynth.synthesis.solve import solve

from ..conftest import make_config

R_CUTS = 0.85  # a decay rate at which the default robot's constant-slip LMIs give a gain that fails (measured)


def _stability(model, r: float):
    s = model.config.synthesis

    def build(mdl):
        return build_stability(mdl, s.multiplier, s.margin, "common", symmetry=False)

    lp = build(model)
    lp.params["r2"].value = r * r

    def make_cert(vals: dict) -> dict:
        cert = _cert_common(model, vals, s.multiplier, s.margin, "stability")
        cert["r2"] = r * r
        return cert

    return lp, build, make_cert


def test_a_point_that_fails_only_within_the_period_gets_those_vertices(default_model) -> None:
    lp, build, make_cert = _stability(default_model, R_CUTS)
    held = {}

    def accept() -> bool:
        vals = lp.values()
        K = np.linalg.solve(vals["Q"].T, vals["Y"].T).T
        held["check"] = check_certificate(default_model, K, make_cert(vals))
        return True

    assert solve(lp.problem, "clarabel", accept, fallback=False).kind == "ok"
    chk = held["check"]
    failing = varying_failures(chk)
    assert failing, "the constant-slip LMIs alone must fail somewhere within the period here"
    own = [c for c in chk.checks if "within a period" not in c["name"]]
    assert all(c["passed"] for c in own)  # ... and nowhere else

    lp, build, make_cert = _stability(default_model, R_CUTS)
    runner = _Runner(default_model, lp, "clarabel", make_cert, full=build)
    out, cert, K, chk = runner.run(fallback=False)
    assert out.kind == "ok" and chk.passed and runner.cuts
    assert len(cert["multipliers"]["M"]) == len(default_model.vertices)  # the file holds the model's own
    assert chk.figures["slip_within_period"] == "covered"
    # the same point without a way to add vertices: refused, not certified
    lp, _, make_cert = _stability(default_model, R_CUTS)
    out, cert, K, chk = _Runner(default_model, lp, "clarabel", make_cert).run(fallback=False)
    assert out.kind == "failed" and cert is None


@pytest.fixture
def default_model():
    from robustsynth.model import build_model

    return build_model(make_config())


def test_the_stability_objective_certifies_slip_changing_within_a_period(default_model) -> None:
    res = synthesize(default_model, objective="stability")
    assert res.check.passed and res.certified["slip_within_period"] == "covered"
    within = [c for c in res.check.checks if "within a period" in c["name"]]
    assert len(within) == 1 and within[0]["passed"] and "768 vertex conditions" in within[0]["name"]
