"""Independent verification of a gain, plant-generic: :func:`verify` hands a plant to its kind's verifier
(:data:`~.checks.VERIFIERS`); the certificate re-check, frozen delays and the lifted model under time-varying
delays live here, the tracked robot's own checks (its closed loop on the path, the boundary probe, the physics
robot) in :mod:`robustsynth.robot_verification`."""

from __future__ import annotations

from importlib import import_module
from typing import Any

from .checks import verify

__all__ = ["verify"]


def __getattr__(name: str) -> Any:
    if name == "VerificationResult":  # the robot's verdict, which lived here (one release, with a warning)
        import warnings

        warnings.warn("robustsynth.verification.VerificationResult moved: use "
                      "robustsynth.robot_verification.VerificationResult", DeprecationWarning, stacklevel=2)
        return import_module("robustsynth.robot_verification.verify").VerificationResult
    raise AttributeError(f"module 'robustsynth.verification' has no attribute {name!r}")
