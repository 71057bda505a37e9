"""Independent verification of a gain: certificate re-check (numpy), frozen delays, the lifted
model under time-varying delays, and Monte Carlo on the nonlinear networked robot."""

from __future__ import annotations

from .checks import VerificationResult, verify

__all__ = ["verify", "VerificationResult"]
