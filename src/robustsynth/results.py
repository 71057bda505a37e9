"""The shapes every plant's results share (issue 52: one result schema).

A verdict is a list of :class:`Check`: one claim, the value the tool measured, the threshold it is
held to, and whether it holds.  The robot's ``verify`` and the linear plant's ``verify_lti`` write
their checks in this one form (``to_dict``), so reports, sweeps, the regression and the console read
one key set: ``name``, ``passed``, ``value``, ``threshold``, ``detail``."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["Check", "all_passed", "failed_names"]


@dataclass(frozen=True)
class Check:
    """One claim of a verdict: ``value`` measured against ``threshold``; ``passed`` says whether it holds
    (how the two compare is the claim's own rule, stated in its name or detail)."""

    name: str
    passed: bool
    value: Any
    threshold: Any
    detail: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "passed": bool(self.passed), "value": self.value, "threshold": self.threshold,
                "detail": self.detail}


def all_passed(checks: Iterable[Mapping[str, Any]]) -> bool:
    """Whether every check (as written by :meth:`Check.to_dict`) passed."""
    return all(c["passed"] for c in checks)


def failed_names(checks: Iterable[Mapping[str, Any]]) -> list[str]:
    """The names of the checks that failed, in order."""
    return [c["name"] for c in checks if not c["passed"]]
