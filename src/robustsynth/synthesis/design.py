""":func:`synthesize`: validates the settings, hands the search to the objective's design (a module of
:mod:`.objectives`, named by its descriptor in :mod:`robustsynth.objectives`) and assembles the result.

The rooms beside it: the solves of one problem and their re-check (:mod:`.runner`), the alpha line search
(:mod:`.alpha_search`) and the heading-bound search of the kinematic channels (:mod:`.heading_search`)."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any, Callable

import numpy as np

from ..config import SynthesisConfig
from ..errors import InputError, SolverFailure
from ..objectives import listed, objective
from .objectives import design_of
from .result import SynthesisResult
from .runner import _SPLIT, _Split, multiplier_used
from .solve import solver_version

__all__ = ["SynthesisResult", "synthesize"]

MAX_DELAY_VERTICES = 9  # delay-dependent Lyapunov matrices: conditions grow with the square of this


CLI_OVERRIDES = ("objective", "solver", "multiplier")  # the settings `robustsynth synthesize` overrides by option
MODEL_SETTINGS = ("model", "delay_description", "kinematics", "integral_action")  # build_model reads them


def synthesize(model: Any, settings: SynthesisConfig | None = None, *, on_step: Callable[[str], None] | None = None,
               **overrides: Any) -> SynthesisResult:
    """Design and certify ``du_k = K xi_k`` for ``model``.

    ``settings`` defaults to ``model.config.synthesis``; keyword ``overrides`` (``objective``,
    ``solver``, ``multiplier``, ...) replace single settings.  Raises :class:`~robustsynth.errors.InfeasibleError`
    (exit 3) when the LMIs have no solution and :class:`~robustsynth.errors.SolverFailure` (exit 4) when the solvers
    fail or no returned point passes the certificate check.  ``on_step`` receives one line per
    solve (the alpha scan, the decay-rate bisection): what was tried, by which solver, how long.

    Any plant: a :class:`~robustsynth.plants.linear.LinearPlant` is designed for as
    :func:`~robustsynth.synthesis.lti.synthesize_lti` designs (its objective's ``linear`` design), with a
    linear plant's settings (``LtiSynthesisConfig``, its defaults when None); its result has ``plant_kind`` "lti".

    Parameters
    ----------
    model : Model or LinearPlant
        The plant to design for (:func:`~robustsynth.model.build_model`, or a linear plant).
    settings : SynthesisConfig, LtiSynthesisConfig or None
        The synthesis settings (default: the model's config's; a linear plant's defaults).
    on_step : callable or None
        Receives one line per solve.
    **overrides : Any
        Single settings replaced (``objective``, ``solver``, ``multiplier``, ...).

    Returns
    -------
    SynthesisResult
        The gain ``K``, its certificate and the figures the numpy re-check proves (``certified``), any plant.

    Raises
    ------
    InfeasibleError
        No gain meets the guarantee (exit 3).
    SolverFailure
        No solve concluded, or none passed the certificate check (exit 4).
    """
    if getattr(model, "plant_kind", None) == "lti":  # a LinearPlant
        return _synthesize_linear(model, settings, on_step, overrides)
    token = _SPLIT.set(_Split())
    try:
        return _synthesize(model, settings, on_step, overrides)
    finally:
        _SPLIT.reset(token)


def _validated(settings: Any, overrides: dict[str, Any], validate: Callable[[dict], Any]) -> Any:
    """``settings`` with the ``overrides`` given (not None) replaced, validated as strictly as the config file and
    the CLI (``validate``: a dict -> the settings, raising pydantic's ValidationError): an unknown key or value is an
    InputError naming the override (the command line's option, or synthesize()'s keyword) and the setting."""
    given = {k: v for k, v in overrides.items() if v is not None}
    if not given:
        return settings
    from pydantic import ValidationError

    from ..config import _format_validation_error

    data = settings.model_dump()
    data.update(given)
    try:
        return validate(data)
    except ValidationError as exc:
        said = ", ".join(f"synthesis.{k}: {v} (overridden{': --' + k if k in CLI_OVERRIDES else ''})"
                         for k, v in given.items())
        raise InputError(f"{said}: {_format_validation_error(exc)}") from None


def _synthesize_linear(plant: Any, settings: Any, on_step: Callable[[str], None] | None,
                       overrides: dict[str, Any]) -> Any:
    """:func:`synthesize` for a linear plant: its settings (given; else the config's it came from; else the defaults
    with the plant's pieces) with the overrides, the plant's network and vertex description (``pieces`` is the
    plant's: a setting that differs shapes another plant)."""
    from ..config import LtiSynthesisConfig, LtiSynthesisSection
    from .lti import synthesize_lti

    if settings is None:
        settings = plant.settings if plant.settings is not None else LtiSynthesisConfig(pieces=plant.pieces)
    if not isinstance(settings, LtiSynthesisConfig):
        raise InputError(f"synthesize: a linear plant's settings are an LtiSynthesisConfig (a plant: kind: lti config's "
                         f"synthesis section), got {type(settings).__name__}")
    s = _validated(settings, overrides, lambda data: LtiSynthesisSection.model_validate({"synthesis": data}).synthesis)
    if s.pieces != plant.pieces:
        raise InputError(f"synthesis.pieces: {s.pieces} differs from the {plant.pieces} the plant's vertex description "
                         "was built with; it shapes the plant, not only the solve: build the LinearPlant with it")
    net = plant.network
    result = synthesize_lti(plant.arrays, net.sampling_time, net.delay_min, net.delay_max, net.max_lost, s.objective,
                            decay=s.decay, pieces=plant.pieces, alpha_points=s.alpha_points, solver=s.solver,
                            say=on_step if on_step is not None else (lambda _m: None),
                            threads=None if s.threads == "auto" else s.threads, name=plant.name)
    return replace(result, settings=s)


def _timings(total: float, solve: float) -> dict[str, float]:
    """total_s and solve_s (the chosen search's solver calls), and the split of the whole synthesis:
    build_s (writing the LMIs), cvxpy_s (canonicalization and unpacking), solver_s (the solver's own),
    check_s (the numpy re-check), other_s (the rest: model checks, search logic), solves (all)."""
    out = {"total_s": total, "solve_s": solve}
    split = _SPLIT.get()
    if split is not None:
        out.update(build_s=split.build_s, cvxpy_s=max(split.call_s - split.solver_s, 0.0), solver_s=split.solver_s,
                   check_s=split.check_s, other_s=max(total - split.build_s - split.call_s - split.check_s, 0.0),
                   solves=float(split.solves))
    return out


def _synthesize(model: Any, settings: SynthesisConfig | None, on_step: Callable[[str], None] | None,
                overrides: dict[str, Any]) -> SynthesisResult:
    from ..config import refuse_lti

    refuse_lti(model, "synthesize")
    if not hasattr(model, "vertices"):
        raise InputError(f"synthesize: takes a model (robustsynth.build_model(config)), got {type(model).__name__}")
    say = on_step if on_step is not None else (lambda _m: None)
    s = settings if settings is not None else model.config.synthesis
    if overrides:  # inside a section, so that every problem is named by its synthesis.<key> path
        from ..config import SynthesisSection

        s = _validated(s, overrides, lambda data: SynthesisSection.model_validate({"synthesis": data}).synthesis)
    built = model.config.synthesis  # the settings the model's structure comes from: an override cannot change it
    fixed = [k for k in MODEL_SETTINGS if getattr(s, k) != getattr(built, k)
             and not (k == "delay_description" and s.delay_description == model.delay_description)]  # auto's own
    if fixed:  # review, stop 47: they were ignored, and the gains file recorded them as made with
        k = fixed[0]
        raise InputError(f"synthesis.{k}: {getattr(s, k)} differs from the {getattr(built, k)} the model was built with; "
                         "it shapes the model, not only the solve: set it in the config and build the model again "
                         "(robustsynth.build_model(config))")
    t0 = time.perf_counter()
    search: list[dict[str, Any]] = []
    notes: list[str] = []
    obj = objective(s.objective)
    if s.lyapunov != "common" and (model.kind != "slip-aware" or obj.common_lyapunov_only):
        raise InputError(f"synthesis.lyapunov: {s.lyapunov} needs synthesis.model: slip-aware and the "
                         f"{listed(lambda o: not o.common_lyapunov_only)} objective")
    if s.lyapunov in ("delay-dependent", "path-dependent") and not 1 < model.delay_vertex_count <= MAX_DELAY_VERTICES:
        raise InputError(f"synthesis.lyapunov: {s.lyapunov} needs 2 to {MAX_DELAY_VERTICES} delay vertices per slip "
                         f"corner; this model has {model.delay_vertex_count} ({model.delay_description} delays, "
                         f"d_hi = {model.d_hi}): use slip-dependent")
    if obj.turns is not None and getattr(model, "turns", None) is not None:
        raise InputError(f"synthesis.objective: {obj.turns}; a turning reference (reference.turn_radius) needs "
                         f"{listed(lambda o: o.turns is None)}")
    model.check_physical_feasibility()  # physics first: no LMI can beat a motor that is too slow
    best, runner, found = design_of(s.objective, "tracked-robot")(model, s, search, say)
    notes += found
    rec = best.record
    if best.check is not None:
        notes += validity_notes(model, best.check.figures, best.cert or {})
    used = multiplier_used(model, s.multiplier)
    if s.multiplier == "full" and used != "full":  # asked for explicitly (structured is the default): say it was moot
        why = ("one scalar multiplier per kinematic or arc channel" if used == "diagonal"
               else "its delay vertices have no norm-bounded Delta")
        notes.append(f"synthesis.multiplier: full has no effect on this model ({why}; it applies to delay_description: "
                     "norm-bounded)")
    if runner.fallbacks and rec is not None:
        notes.append(f"fallback solver used in {runner.fallbacks} of {len(search)} solves; the accepted K is "
                     f"from {rec.name}")
    if best.cert is None or best.check is None or not best.check.passed or rec is None:
        raise SolverFailure(f"{s.objective}: no certified point")  # unreachable: each branch above raised
    cert = dict(best.cert)
    cert["min_eig_margin_found"] = best.check.min_eig_margin
    # (where the certificate is a relaxation's, carried to every vertex: that relaxation's solves, with its own)
    made_by = runner.made_by()
    solver = {
        "name": rec.name,
        "version": solver_version(rec.name),
        "status": rec.status,
        "iterations": rec.iterations,
        "solve_time_s": float(sum(r.solve_time_s for m in made_by for r in m.records)),
        "fallback_used": bool(runner.fallbacks),
        "solves": sum(m.solves for m in made_by),
    }
    return SynthesisResult(
        K=best.K,
        objective=s.objective,
        multiplier=used,
        certificate=cert,
        check=best.check,
        solver=solver,
        search=tuple(search),
        timings=_timings(time.perf_counter() - t0, solver["solve_time_s"]),
        notes=tuple(notes),
        settings=s,
    )


LINEARIZATION_HEADING = 0.5  # [rad]: beyond it sin e_theta differs from e_theta by more than 4 %


def validity_notes(model: Any, figures: dict[str, Any], cert: dict[str, Any]) -> list[str]:
    """Certified bounds that leave the region where the model they are proven for holds, in words:
    a heading beyond what the linearization covers (a nonlinear certificate covers its own heading
    bound), errors larger than half the shortest path segment (the segment frames stop meaning much)."""
    ub = figures.get("ultimate_bound") or {}
    out = []
    th = ub.get("e_theta")
    if th is not None and cert.get("kinematics", "linearized") == "linearized" and th > LINEARIZATION_HEADING:
        out.append(f"certified |e_theta| <= {th:.3g} rad lies beyond where the linearization holds (~{LINEARIZATION_HEADING:g} "
                   "rad: sin e_theta ~ e_theta); the bound is proven for the linearization only "
                   "(synthesis.kinematics: nonlinear proves its own heading bound)")
    wp = np.asarray(model.config.reference.path, dtype=float)
    seg = float(np.min(np.hypot(*np.diff(wp, axis=0).T))) if wp.shape[0] > 1 else math.inf
    big = max((ub.get(k) or 0.0) for k in ("e_x", "e_y")) if ub else 0.0
    if big > seg / 2:
        out.append(f"a certified position bound ({100 * big:.3g} cm) exceeds half the shortest path segment "
                   f"({seg / 2:.3g} m): the robot may be nearer another segment than its own")
    return out
