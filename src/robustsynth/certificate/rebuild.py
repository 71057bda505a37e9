"""The model a certificate's LMIs are written on: the config's model with the certificate's own
kinematics, heading bound, within-period channels and turning reference (where the config's model
allows them), or why there is none.  The checker (:mod:`.check`) rebuilds its LMIs on it."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .lmis import dense_multiplier

__all__ = ["model_of_certificate"]


def model_of_certificate(model: Any, cert: Mapping[str, Any], objective: str) -> Any:
    """The model the certificate's LMIs are written on (its kinematics, heading bound and turning
    reference, where the config's model allows them), or why there is none (a string)."""
    from ..objectives import objective as descriptor

    kin = cert.get("kinematics", "linearized")
    if not descriptor(objective).nonlinear_kinematics and kin == "linearized":
        # these LMIs are written on the linearization (synthesis.lmis.build_stability, the hinf design's build_hinf),
        # also when the config asks for nonlinear kinematics (robust stability of a fixed K: margins)
        model = model.linearized()
    if kin != model.kinematics:
        return (f"the certificate is for {kin} kinematics, the config asks for {model.kinematics} "
                "(synthesis.kinematics)")
    if kin == "nonlinear":  # the kinematic channels of the certificate's own heading bound
        hb = cert.get("heading_bound")
        if isinstance(hb, bool) or not isinstance(hb, (int, float)) or not 0.0 < float(hb) <= 1.0:
            return f"certificate.heading_bound: nonlinear kinematics need a number in (0, 1] rad (got {hb!r})"
        hb = float(hb)
        within = bool(cert.get("within_period_channels", False))  # for slip changing within a period (§9)
        if within and not model.covering:
            return ("the certificate's kinematic channels are for slip changing within a period, which this "
                    f"config's model does not cover ({model.varying_reason})")
        if hb != model.heading_bound or within != bool(model.covering_vertices):
            model = model.with_heading_bound(hb, within_period=within)
        if getattr(model, "turns", None) is None:  # (a turning model's: _model_of_turns)
            model = _icr_layout(model, cert, lambda m: m.with_heading_bound(hb, within_period=True, icr_channels=True))
    return _model_of_turns(model, cert)


def _icr_layout(model: Any, cert: Mapping[str, Any], legacy: Any) -> Any:
    """``model``, or for an icr certificate made before its linear map's vertices (docs/theory.md §12: its channels
    cover slip changing within a period alone) the model ``legacy(model)`` gives, where the certificate's multiplier
    fits that layout and not this one."""
    if not (model.icr_varying and model.covering_vertices) or _multiplier_size(cert) in (None, model.vertices[0].n_q ** 2):
        return model
    old = legacy(model)
    return old if _multiplier_size(cert) == old.vertices[0].n_q ** 2 else model


def _model_of_turns(model: Any, cert: Mapping[str, Any]) -> Any:
    """The model with the vertices of the certificate's own turning reference (model/arcs.py), or why
    it cannot carry them (a string)."""
    turns, have = cert.get("turns"), getattr(model, "turns", None)
    if turns is None:
        return "the certificate is for straight segments, the model for a turning reference" if have is not None else model
    want = (float(turns["max_yaw_rate"]), float(turns["max_step"]))
    if have is not None and not (want[0] >= have.max_yaw_rate and want[1] >= have.max_step):
        return (f"the certificate covers reference yaw rates up to {want[0]:.4g} rad/s (steps {want[1]:.4g}), "
                f"the model asks for {have.max_yaw_rate:.4g} (steps {have.max_step:.4g}): "
                "reference.turn_radius is smaller than the one the gain was certified for")
    if have is None:
        return (f"the certificate is for a reference turning along arcs (yaw rates up to {want[0]:.4g} rad/s), "
                "the config's path jumps at its waypoints (reference.turn_radius is null): set "
                "reference.turn_radius to the gain's radius or wider")
    # the turning vertices of the certificate's own yaw rates, for slip changing within a period where its
    # channels are (within_period_channels; a certificate made before they existed assumes it constant)
    within = bool(cert.get("within_period_channels", False))
    if within and not model.covering:
        return ("the certificate's channels are for slip changing within a period, which this config's "
                f"model does not cover ({model.varying_reason})")
    from ..errors import InputError

    try:
        if (have.max_yaw_rate, have.max_step) != want or within != bool(model.covering_vertices):
            model = model.with_turns(*want, within_period=within)
        model = _icr_layout(model, cert, lambda m: m.with_turns(*want, within_period=True, icr_channels=True))
        size = _multiplier_size(cert)
        if not within and size not in (None, model.vertices[0].n_q ** 2):
            # made before the arc channels were merged (docs/theory.md §10): their own layout, if it fits
            legacy = model.with_turns(*want, within_period=False, merged=False)
            if size == legacy.vertices[0].n_q ** 2:
                model = legacy
    except InputError as exc:
        return f"the certificate is for a turning reference, which this model cannot carry: {exc}"
    return model


def _multiplier_size(cert: Mapping[str, Any]) -> int | None:
    """The number of entries of the certificate's first multiplier, or None when it has none readable."""
    try:
        return int(np.asarray(dense_multiplier(cert["multipliers"]["M"][0]), dtype=float).size)
    except (KeyError, IndexError, TypeError, ValueError):
        return None
