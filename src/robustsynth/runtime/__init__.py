"""The controller as it runs on the robot: :mod:`.law` (plain Python, also the exported module)
and :class:`Controller` (the same, read from a gains file)."""

from __future__ import annotations

from .controller import DESCRIPTION_FORMAT, Controller, controller_description
from ..law import Law, PathTable

__all__ = ["Controller", "controller_description", "Law", "PathTable", "DESCRIPTION_FORMAT"]
