"""The deployable controller: a verified gain with its memory, path and motor mapping.

No cvxpy, no matplotlib: reading a gains file (:mod:`robustsynth.artifacts.gains`) needs numpy,
the config module (pydantic, PyYAML) and, for a ``.mat``, scipy; stepping needs nothing beyond the
Python standard library."""

from __future__ import annotations

from pathlib import Path

from ..artifacts.gains import DESCRIPTION_FORMAT, controller_description, load_gains
from ..law import Controller as _PureController

__all__ = ["Controller", "controller_description", "DESCRIPTION_FORMAT"]


class Controller(_PureController):
    __doc__ = _PureController.__doc__

    @classmethod
    def from_files(cls, gains_path: str | Path, config_path: str | Path | None = None) -> "Controller":
        """The controller of a ``gains.json`` (or ``gains.mat``); the path and reference speed come
        from ``config_path``, else from the config stored in the gains file, else the embedded
        default."""
        from ..config import load_config

        gains = load_gains(gains_path)
        return cls(controller_description(gains, load_config(config_path) if config_path is not None else None))
