"""The tracked robot's own checks, above the plant-generic verification room: the robot in closed loop on its
path (:mod:`.simulate`), the boundary probe (:mod:`.probe`), the checks on the nonlinear robot
(:mod:`.nonlinear_checks`), the slip-compensated law (:mod:`.compensated`), the MuJoCo robot (:mod:`.physics`),
and the verdict that gathers them (:func:`verify_robot`, which :func:`robustsynth.verification.verify` hands a
robot's model to)."""

from __future__ import annotations

from .verify import VerificationResult, verify_robot

__all__ = ["VerificationResult", "verify_robot"]
