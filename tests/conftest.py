"""Shared fixtures and helpers: configs built from the embedded default with overrides."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import settings

# Deterministic property tests: the same examples on every machine and run (CI must not flake);
# no example database written into the work tree.
settings.register_profile("robustsynth", derandomize=True, database=None)
settings.load_profile("robustsynth")

from robustsynth.config import Config, mapping_with

ROOT = Path(__file__).resolve().parents[1]
# The suite's base scenario: the seed paper's setting on the slip-aware model, tracks box [0.6, 1], linearized
# kinematics (fast to synthesize; the embedded default is the physics robot's icr box with arcs and the robot
# proof, which the tests of the default itself use)
BASE_CONFIG = ROOT / "tests" / "data" / "base.yaml"


# A quick config whose verification passes (the icr box of the physics robot on straight segments, linearized:
# the robot keeps its set), for tests of what a run writes and prints
PASSING_CONFIG = ROOT / "configs" / "icr-physics.yaml"


def default_dict() -> dict[str, Any]:
    """The base scenario as a mapping."""
    return yaml.safe_load(BASE_CONFIG.read_text())


def make_config(**overrides: Any) -> Config:
    """The base scenario with dotted-path overrides: make_config(**{"network.delay.max": 0.2})."""
    return mapping_with(default_dict(), **overrides)


@pytest.fixture
def default_config() -> Config:
    return make_config()


def committed_gain(name: str) -> tuple[Any, np.ndarray, dict[str, Any]]:
    """The model of configs/<name>.yaml, and the gain K and certificate of its committed baseline
    (results/baselines/<name>/gains.json)."""
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.config import load_config
    from robustsynth.model import build_model

    g = load_gains(ROOT / "results" / "baselines" / name / "gains.json")
    return build_model(load_config(ROOT / "configs" / f"{name}.yaml")), np.asarray(g["K"], dtype=float), g["certificate"]


def boundary_points(model, K: np.ndarray, lyap, level: float, n: int, rng: np.random.Generator):
    """States on the boundary V = level of a certificate's set (``n`` random directions and each bounded
    figure's maximizers, :func:`~robustsynth.robot_verification.probe.probe_directions`), each with a random slip
    corner: (xi (N, n_s), mu (N, 2))."""
    from robustsynth.scenarios import slip_vertices
    from robustsynth.robot_verification.probe import probe_directions

    dirs = probe_directions(model, K, lyap, n, rng)
    corners = slip_vertices(model)
    mu = corners[rng.integers(0, corners.shape[0], size=dirs.shape[0])]
    return dirs * np.sqrt(level / lyap.V(dirs, mu))[:, None], mu
