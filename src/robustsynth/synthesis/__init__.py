"""LMI synthesis of the robust state feedback ``du_k = K xi_k`` (docs/theory.md §6).

:func:`synthesize` runs one objective, checks every returned point with the numpy certificate
check (:mod:`robustsynth.certificate`) and returns a :class:`SynthesisResult` whose
certified figures come from that check.  cvxpy is imported only inside this package.
"""

from __future__ import annotations

from .design import SynthesisResult, synthesize

__all__ = ["synthesize", "SynthesisResult"]
