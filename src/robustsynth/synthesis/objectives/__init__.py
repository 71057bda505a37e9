"""The objectives' designs, one module each (the descriptors: :mod:`robustsynth.objectives`).

A design module has two functions, one per plant kind the objective serves:

- ``robot(model, settings, search, say) -> (best, runner, notes)``: the search for the tracked robot
  (:func:`robustsynth.synthesis.synthesize` has validated the settings and the model's physics); ``search``
  collects one record per solve, ``say`` a line per step; ``best`` (a ``runner._Best``) holds the proven point,
  ``notes`` what the result should say.  It raises :class:`~robustsynth.errors.InfeasibleError` or
  :class:`~robustsynth.errors.SolverFailure` when no point is proven.
- ``linear(job) -> candidate``: the design for a linear plant (:class:`robustsynth.synthesis.lti.LinearJob`),
  certified or not (``synthesis.lti._Candidate``); :func:`robustsynth.synthesis.lti.synthesize_lti` makes a
  certified one the :class:`~robustsynth.synthesis.SynthesisResult` and raises for the rest.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable

__all__ = ["design_of"]


def design_of(name: str, plant: str) -> Callable[..., Any]:
    """The objective ``name``'s design for the plant kind ``plant``: ``robot`` or ``linear`` of its descriptor's
    ``design`` module.  A descriptor whose module or function is missing is one line (RuntimeError: a defect of the
    registry, not of the user's input), not a traceback from deep in a run."""
    from ...objectives import objective

    obj = objective(name)
    try:
        module = importlib.import_module(obj.design)
    except ImportError as exc:
        raise RuntimeError(f"objective {name}: its design module {obj.design} cannot be imported ({exc})") from None
    fn = {"tracked-robot": "robot", "lti": "linear"}[plant]
    design = getattr(module, fn, None)
    if not callable(design):
        raise RuntimeError(f"objective {name}: its design module {obj.design} has no {fn}() for the {plant} plant")
    return design
