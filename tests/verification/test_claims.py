"""verify's "figures in the file match the re-check": every certified figure is an upper bound, so a
gains file may claim the re-checked value or a weaker one (e.g. a delay-dependent gain written before
the bounds on the intersection, docs/theory.md §6i), never a stronger one."""

from __future__ import annotations

import copy

import pytest

from robustsynth.artifacts.gains import gains_dict
from robustsynth.model import build_model
from robustsynth.synthesis import synthesize
from robustsynth.verification import verify

from ..conftest import make_config

CLAIM = "certificate: figures in the file match the re-check"


@pytest.fixture(scope="module")
def written():
    model = build_model(make_config())
    return model, gains_dict(model, synthesize(model, alpha_points=5))


def _claim_check(model, gd):
    v = verify(model, gd, runs=2)
    (c,) = [c for c in v.checks if c["name"] == CLAIM]
    return c


@pytest.mark.slow
@pytest.mark.parametrize("factor, passes", [(1.0, True), (1.01, True), (0.99, False)])
def test_a_file_may_claim_less_than_the_recheck_proves_never_more(written, factor, passes):
    model, gd = written
    gd = copy.deepcopy(gd)
    gd["certified"]["ultimate_bound"]["e_y"] *= factor
    gd["certified"]["motor_speed_bound"] *= factor
    c = _claim_check(model, gd)
    assert c["passed"] is passes
    if not passes:
        assert "ultimate_bound.e_y" in c["detail"] and "motor_speed_bound" in c["detail"]
