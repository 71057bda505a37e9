"""verify_robot: its single-threaded checks (the lifted model's, the boundary probe, the monitor's replay) run in
forked children beside the adversary's threads (robustsynth.forked.beside); the verdict is the one they give run
here, value for value and key for key, and so are the lifted model's traces the figures draw."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from robustsynth import forked
from robustsynth.artifacts.gains import load_gains
from robustsynth.config import mapping_with
from robustsynth.model import build_model
from robustsynth.verification import verify

from ..conftest import ROOT


@pytest.mark.slow
@pytest.mark.skipif(not (forked.AVAILABLE and forked.cores() > 1), reason="nothing is forked here")
def test_the_verdict_is_the_same_with_its_checks_forked_beside_or_run_here(monkeypatch):
    d = yaml.safe_load((ROOT / "configs" / "default.yaml").read_text())
    # a short adversary: its searches from the boundary start at the probe's states, which come back from a child
    model = build_model(mapping_with(d, **{"verification.runs": 4, "verification.adversarial_runs": 1,
                                           "verification.adversarial_steps": 2}))
    gains = load_gains(ROOT / "results" / "baselines" / "default" / "gains.json")
    returned = []

    class Counted(forked.Forked):
        def result(self):
            value = super().result()  # raises where the child failed (beside then runs the call here)
            returned.append(type(value).__name__)
            return value

    monkeypatch.setattr(forked, "Forked", Counted)
    beside = verify(model, gains, seed=3)
    # the lifted model's checks, the monitor's replay and the boundary probe, each a child's own result
    assert sorted(returned) == ["dict", "dict", "tuple"], returned
    monkeypatch.setattr(forked, "AVAILABLE", False)
    here = verify(model, gains, seed=3)
    assert len(returned) == 3
    assert beside.monte_carlo["boundary_probe"]["adversary"]["starts"] > 0  # the probe's states went on
    # as plain data in its order (json.dumps writes NaN the same each time)
    assert json.dumps(beside.to_dict()) == json.dumps(here.to_dict())
    assert beside.lifted_traces.keys() == here.lifted_traces.keys()
    for key, trace in beside.lifted_traces.items():
        assert np.array_equal(trace, here.lifted_traces[key], equal_nan=True), key
