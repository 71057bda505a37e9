"""Shared fixtures and helpers: configs built from the embedded default with overrides."""

from __future__ import annotations

import copy
from typing import Any

import pytest
import yaml
from hypothesis import settings

# Deterministic property tests: the same examples on every machine and run (CI must not flake);
# no example database written into the work tree.
settings.register_profile("robustsynth", derandomize=True, database=None)
settings.load_profile("robustsynth")

from robustsynth.config import Config, default_config_text


def default_dict() -> dict[str, Any]:
    return yaml.safe_load(default_config_text())


def make_config(**overrides: Any) -> Config:
    """Default config with dotted-path overrides: make_config(**{"network.delay.max": 0.2})."""
    d = copy.deepcopy(default_dict())
    for path, value in overrides.items():
        node = d
        keys = path.split(".")
        for k in keys[:-1]:
            node = node.setdefault(k, {})
        node[keys[-1]] = value
    return Config.model_validate(d)


@pytest.fixture
def default_config() -> Config:
    return make_config()
