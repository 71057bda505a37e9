"""The model family: the seed paper's lifted norm-bounded model and the slip-aware model.

:func:`build_model` (:mod:`.build`) turns a :class:`~robustsynth.config.Config` into a frozen
:class:`Model` (:mod:`.model`, where the interface every kind hands synthesis and verification is
described); the other modules are its mathematics: kinematics, linearization, lifting under
time-varying delay, slip, vertices and the norm-bounded embedding (the network and its losses:
:mod:`robustsynth.core.network`).
"""

from __future__ import annotations

from .build import build_model
from .coverage import coverage_check
from .model import (ERROR_NAMES, INPUT_NAMES, MAX_POLYTOPIC_INSTANTS, MODEL_KINDS, SLIP_NAMES, Model, gain_lifting,
                    lifted_slice, pad_gain, state_names)
from .uncertainty import SlipBox, UncertainInstant
from .vertices import Vertex

__all__ = ["Model", "Vertex", "build_model", "coverage_check", "pad_gain", "gain_lifting", "lifted_slice",
           "UncertainInstant", "SlipBox", "state_names", "INPUT_NAMES", "ERROR_NAMES", "SLIP_NAMES", "MODEL_KINDS",
           "MAX_POLYTOPIC_INSTANTS"]
