"""verify_robot: its single-threaded checks (the lifted model's, the boundary probe, the monitor's replay) run in
forked children beside the adversary's threads (robustsynth.forked.beside); the verdict is the one they give run
here, one after the other, value for value."""

from __future__ import annotations

import json

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
    # no adversary (its threads are no check's input): the children's values against the same calls made here
    model = build_model(mapping_with(d, **{"verification.runs": 4, "verification.adversarial_runs": 0}))
    gains = load_gains(ROOT / "results" / "baselines" / "default" / "gains.json")
    children = []

    class Counted(forked.Forked):
        def __init__(self, fn, expected=()):
            children.append(fn)
            super().__init__(fn, expected)

    monkeypatch.setattr(forked, "Forked", Counted)
    beside = verify(model, gains, seed=3)
    assert len(children) == 3  # the lifted model's checks, the monitor's replay, the boundary probe
    monkeypatch.setattr(forked, "AVAILABLE", False)
    here = verify(model, gains, seed=3)
    assert len(children) == 3
    assert beside.passed == here.passed
    # as plain data, NaN included (json.dumps writes it the same each time)
    assert json.dumps(beside.to_dict(), sort_keys=True) == json.dumps(here.to_dict(), sort_keys=True)
