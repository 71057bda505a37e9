"""Robustness margins of a given gain, for any plant: how far can the delay bound, the loss cap (and the
robot's slip range) be pushed before the gain's proof, and then its stability, is lost?

For each margin two numbers bracket the truth:

- **certified**: the furthest value at which the gain has a robust-stability certificate (the plant's
  analysis LMIs, K fixed, every accepted point re-checked in numpy), found by bisection;
- **exhibited**: the nearest value at which an instability is *shown*: a periodic delay/loss (/slip)
  sequence whose lifted closed-loop product has spectral radius above 1 (constant delays are the
  period-1 case).  The sequence is returned as the witness.

The truth lies between them; the gap is how conservative the certificate is (or how weak the search).
:func:`margin` takes the tracked robot's config (:mod:`.robot`: delay_max, slip_min, the icr model's
slip parameters, dropouts) or a :class:`~robustsynth.plants.linear.LinearPlant` (:mod:`.linear`:
delay_max, dropouts) and returns one :class:`MarginReport` either way (:mod:`robustsynth.results`).
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ..model import pad_gain
from ..results import Margin, MarginReport
from .linear import lti_margins
from .robot import EXHIBIT_TOL, find_instability, witness_delays

__all__ = ["Margin", "MarginReport", "margin", "find_instability", "witness_delays", "pad_gain", "EXHIBIT_TOL",
           "lti_margins"]


def margin(plant: Any, K: np.ndarray | None = None, *, lyapunov: str | None = None,
           on_step: Callable[[str], None] | None = None, settings: Any = None) -> MarginReport:
    """Margins of the gain ``K`` (u_k = K xi_k on the lifted state) on a plant.

    Parameters
    ----------
    plant : Config, Model or LinearPlant
        The tracked robot's config (or its :class:`~robustsynth.model.Model`), whose delay, loss and slip
        ranges are the starting point; or a linear plant with its network.  A linear plant's config is
        refused with the way to its plant (``LinearPlant.from_config``).
    K : numpy.ndarray or None
        The gain; for a linear plant, None takes the plant's own (its config's ``controller.gain``).
    lyapunov : str or None
        The robot's certificates tried at each point: 'common', 'slip-dependent', 'delay-dependent' or
        'path-dependent' (one matrix per slip corner only where a point's delays have no vertices), or
        'auto' (common, then slip-dependent where common fails: tighter, several times slower); default
        ``config.synthesis.lyapunov``.  A linear plant's certificate is one common quadratic function.
    on_step : callable or None
        Receives one line per step of the searches.
    settings : LtiMarginConfig or None
        A linear plant's margin settings (pieces, tolerance, delay_far); default the plant's config's
        ``margin:``, else the defaults.

    Returns
    -------
    MarginReport
        Each margin's configured, certified and exhibited values, with the destabilizing witness.
    """
    from ..config import refuse_lti
    from ..errors import InputError

    say = on_step or (lambda _msg: None)
    kind = getattr(plant, "plant_kind", None)
    if kind == "lti":
        from ..config.lti import LtiMarginConfig
        from .linear import linear_margin

        if lyapunov is not None:
            raise InputError("lyapunov: a linear plant's certificate is one common quadratic function")
        if K is None:
            K = plant.arrays.get("K")
            if K is None:
                raise InputError("K: required for a linear plant without its own gain (controller.gain)")
        return linear_margin(plant, K, settings or plant.margin_settings or LtiMarginConfig(), say)
    if settings is not None:
        raise InputError("settings: a linear plant's margin settings; the robot's are its config's")
    config = plant.config if kind == "tracked-robot" else plant
    refuse_lti(config, "margin")
    if K is None:
        raise InputError("K: the gain whose margins are taken is required for the tracked robot")
    from .robot import robot_margin

    return robot_margin(config, K, lyapunov, say)
