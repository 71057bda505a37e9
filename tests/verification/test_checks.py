"""verification.checks: the plant-generic ``verify`` hands each plant kind to its registered verifier, names what it
cannot verify, and imports no concrete plant (tests/test_architecture.py holds the imports)."""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest

from robustsynth.objectives import PLANTS
from robustsynth.verification import checks, verify


class _ToyPlant:
    """A plant of a kind of its own, as a new plant would bring (docs/architecture.md, "A new plant kind")."""

    plant_kind = "toy"


def _toy_verifier(plant, gains, runs, seed, progress):
    return ("toy verdict", plant, gains, runs, seed, progress)


def test_every_plant_kind_has_an_importable_verifier() -> None:
    assert set(checks.VERIFIERS) == set(PLANTS)
    for kind, (module, name) in checks.VERIFIERS.items():
        assert callable(getattr(importlib.import_module(module), name)), kind


def test_a_registered_kind_is_handed_its_plant_gain_and_settings(monkeypatch) -> None:
    monkeypatch.setitem(checks.VERIFIERS, "toy", (__name__, "_toy_verifier"))
    plant, K = _ToyPlant(), np.zeros((1, 1))
    out = verify(plant, K, runs=3, seed=7, progress=print)
    assert out[0] == "toy verdict" and out[1] is plant and out[2] is K and out[3:] == (3, 7, print)


def test_an_unregistered_kind_is_named() -> None:
    with pytest.raises(TypeError, match=r"no verifier for the plant kind 'toy'.*VERIFIERS"):
        verify(_ToyPlant(), np.zeros((1, 1)))


def test_the_robot_verdict_is_imported_only_when_a_robot_is_verified() -> None:
    """The generic room names the robot's verifier; importing it does not import the robot's judges."""
    code = ("import sys, robustsynth.verification as v; "
            "print(any(m.startswith('robustsynth.robot_verification') for m in sys.modules))")
    import subprocess

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False"]
