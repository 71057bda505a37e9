"""The form of one check of ``verify``'s verdict and the tolerances its rules use (docs/reference/verification.md)."""

from __future__ import annotations

from typing import Any

from ..results import Check

__all__ = ["SPECTRAL_TOL", "LEVEL_TOL", "DIVERGENCE_LIMIT"]

SPECTRAL_TOL = 1e-6  # frozen spectral radius may exceed the certified rate by round-off only
LEVEL_TOL = 1e-9  # relative round-off allowed on V in the lifted-model checks
DIVERGENCE_LIMIT = 1.0  # m: |e_y| beyond this after the transients is divergence (no-bound objectives)


def _check(name: str, passed: bool, value: Any, threshold: Any, detail: str) -> dict[str, Any]:
    """One check of the verdict in the form every plant's checks share (:class:`robustsynth.results.Check`)."""
    return Check(name, bool(passed), value, threshold, detail).to_dict()
