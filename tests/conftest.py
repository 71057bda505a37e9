"""Shared fixtures and helpers: configs built from the embedded default with overrides."""

from __future__ import annotations

from typing import Any

import pytest
import yaml
from hypothesis import settings

# Deterministic property tests: the same examples on every machine and run (CI must not flake);
# no example database written into the work tree.
settings.register_profile("robustsynth", derandomize=True, database=None)
settings.load_profile("robustsynth")

from robustsynth.config import Config, default_config_text
from robustsynth.config import default_config as _default_with


def default_dict() -> dict[str, Any]:
    return yaml.safe_load(default_config_text())


def make_config(**overrides: Any) -> Config:
    """Default config with dotted-path overrides: make_config(**{"network.delay.max": 0.2})."""
    return _default_with(**overrides)


@pytest.fixture
def default_config() -> Config:
    return make_config()
