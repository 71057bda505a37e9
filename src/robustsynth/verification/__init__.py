"""Independent verification of a gain, plant-generic: :func:`verify` hands a plant to its kind's verifier
(:data:`~.checks.VERIFIERS`); the certificate re-check, frozen delays and the lifted model under time-varying
delays live here, the tracked robot's own checks (its closed loop on the path, the boundary probe, the physics
robot) and its verdict (``VerificationResult``) in :mod:`robustsynth.robot_verification`."""

from __future__ import annotations

from .checks import verify

__all__ = ["verify"]
