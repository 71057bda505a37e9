"""The objectives' designs, one module each (the descriptors: :mod:`robustsynth.objectives`).

A design module has two functions, one per plant kind the objective serves:

- ``robot(model, settings, search, say) -> (best, runner, notes)``: the search for the tracked robot
  (:func:`robustsynth.synthesis.synthesize` has validated the settings and the model's physics); ``search``
  collects one record per solve, ``say`` a line per step; ``best`` (a ``runner._Best``) holds the proven point,
  ``notes`` what the result should say.  It raises :class:`~robustsynth.errors.InfeasibleError` or
  :class:`~robustsynth.errors.SolverFailure` when no point is proven.
- ``linear(job) -> LtiDesign``: the design for a linear plant (:class:`robustsynth.synthesis.lti.LinearJob`),
  certified or not (:func:`robustsynth.synthesis.lti.synthesize_lti` raises for the latter).
"""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["design_of"]


def design_of(name: str) -> ModuleType:
    """The design module of the objective ``name`` (its descriptor's ``design``)."""
    from ...objectives import objective

    return importlib.import_module(objective(name).design)
