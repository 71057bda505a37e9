"""``verify``: every check of a gain against its plant, independent of how the gain was made.

Any plant: :func:`verify` hands the plant to its kind's verifier (:data:`VERIFIERS`): the tracked robot's
(:func:`robustsynth.robot_verification.verify.verify_robot`: the certificate's re-check, frozen delays, the lifted
model, the nonlinear robot; its pass/fail rules there and in docs/reference/verification.md) or the linear plant's
(:func:`robustsynth.verification.lti.verify_linear`).  This room is plant-generic: it names the plants' verifiers
and imports one only when a plant of its kind is verified, as the objectives' registry names their designs."""

from __future__ import annotations

import importlib
from typing import Any, Callable

from ..objectives import scalar_figures

__all__ = ["VERIFIERS", "claimed_beyond", "verify"]

# each plant kind's verifier (robustsynth.objectives.PLANTS): its module and function, imported when a plant of the
# kind is verified (a new plant: one verifier module and one line here)
VERIFIERS = {
    "tracked-robot": ("robustsynth.robot_verification.verify", "verify_robot"),
    "lti": ("robustsynth.verification.lti", "verify_linear"),
}


def claimed_beyond(claimed: dict[str, Any], figures: dict[str, Any]) -> list[str]:
    """The figures a gains file claims stronger than the re-check proves (``figures``): every figure is an upper
    bound (a decay rate, a bound, a gain, an objective's own figure), so a file may claim the re-checked value or
    a weaker one (e.g. a delay-dependent gain written before the bounds on the intersection of docs/theory.md §6i),
    never a smaller one (rel 1e-6); and slip covered within a period only where the re-check covers it."""
    def stronger(c: Any, f: float) -> bool:
        return not float(c) >= float(f) * (1.0 - 1e-6)

    mism = [k for k in scalar_figures()
            if claimed.get(k) is not None and figures.get(k) is not None and stronger(claimed[k], figures[k])]
    if claimed.get("slip_within_period") == "covered" and figures.get("slip_within_period") != "covered":
        mism.append("slip_within_period")  # claims slip may change within a period; the re-check does not cover it
    for key in ("ultimate_bound", "ultimate_bound_between_samples"):
        ubc, ubf = claimed.get(key), figures.get(key)
        if ubc and ubf:
            mism += [f"{key}.{k}" for k in ubf if ubf[k] is not None and ubc.get(k) is not None and stronger(ubc[k], ubf[k])]
    return mism


def verify(model, gains: Any, runs: int | None = None, seed: int | None = None,
           progress: Callable[[int, int], None] | None = None) -> Any:
    """Run every check of ``gains`` against ``model``: a gains.json mapping (:func:`~robustsynth.artifacts.gains.load_gains`),
    the result of :func:`~robustsynth.synthesis.synthesize`, or a bare matrix K.

    Any plant: for a :class:`~robustsynth.plants.linear.LinearPlant` the gain is the
    :class:`~robustsynth.synthesis.SynthesisResult` that ``synthesize(plant)`` returns (or a linear plant's gains
    mapping, ``kind: lti``), and the checks are :func:`~robustsynth.verification.lti.verify_lti`'s on the exactly
    lifted loop, returned as a :class:`~robustsynth.results.Verdict` (``passed``, ``checks``, ``failed_checks``
    as the robot's result has them; ``to_dict()``: verify_lti's mapping).

    Parameters
    ----------
    model : Model or LinearPlant
        The model of the config to verify against, or a linear plant.
    gains : Mapping, SynthesisResult, numpy.ndarray or str
        The gain: a gains mapping or file, a synthesis result, or a bare K (the robot's).
    runs : int or None
        Monte Carlo runs (default ``verification.runs``; a linear plant's delay sequences per family: 64).
    seed : int or None
        Their random seed (default ``verification.seed``; a linear plant's: 0).
    progress : callable or None
        Called with (runs done, runs in all) (the robot's).

    Returns
    -------
    VerificationResult or Verdict
        ``passed``, every check with its value and threshold (``failed_checks``: the names of those that
        failed), and the simulations behind them (a linear plant's: ``Verdict.details``).
    """
    kind = getattr(model, "plant_kind", "tracked-robot")
    if kind not in VERIFIERS:
        raise TypeError(f"verify: no verifier for the plant kind {kind!r} (robustsynth.verification.checks.VERIFIERS)")
    module, name = VERIFIERS[kind]
    fn = getattr(importlib.import_module(module), name)
    return fn(model, gains, runs, seed, progress)
