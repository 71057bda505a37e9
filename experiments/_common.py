"""Shared helpers of the experiments (not part of the robustsynth package)."""

from __future__ import annotations

import cvxpy as cp

from robustsynth.config import default_config as config  # noqa: F401  (the default with dotted overrides)
from robustsynth.synthesis.lmis import motor_constraints as motor_lmis  # noqa: F401  (docs/theory.md §6, motor limits)
from robustsynth.synthesis.solve import SOLVER_OPTIONS


def solve_optimal(problem: cp.Problem) -> bool:
    """Solve with Clarabel at robustsynth's tolerances; True only for status 'optimal'."""
    try:
        problem.solve(**SOLVER_OPTIONS["clarabel"])
    except cp.error.SolverError:
        return False
    return problem.status == "optimal"
