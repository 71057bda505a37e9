"""``ultimate-bound``: the smallest invariant, attracting set for every admissible delay and slip, with the motor speeds
within their limit on it (docs/theory.md §6b): a line search over alpha on the linearized kinematics, or the heading
bound's search on the nonlinear ones (§9).  A linear plant's: the smallest set under its disturbance (§15)."""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ...config import SynthesisConfig
from ...errors import InfeasibleError, InputError, SolverFailure
from ..alpha_search import _motor_pruner, _run_invariance
from ..heading_search import _end_vertices_hint, _run_nonlinear
from ..runner import _Best, _delay_text, _Runner, _wider_turns

__all__ = ["robot", "linear"]


def robot(model: Any, s: SynthesisConfig, search: list, say: Callable[[str], None]) -> tuple[_Best, _Runner, list[str]]:
    """The set's search, after what makes it moot or hopeless: no slip to bound, a motor limit below the
    feedforward's own need."""
    cfg, notes = model.config, []
    if all(not np.any(np.asarray(v.E)) for v in model.vertices):
        raise InputError(
            "slip: every slip range has zero width and centre 1, so the ultimate bound is 0; "
            "use synthesis.objective: stability"
        )
    rho_max = cfg.robot.max_motor_speed
    motor = bool(s.motor_limits and rho_max is not None)
    if motor and rho_max <= model.feedforward_motor_speed:
        turning = getattr(model, "turns", None) is not None
        raise InfeasibleError(
            f"ultimate-bound: robot.max_motor_speed = {rho_max:g} rad/s is below "
            f"{'V^D/R + max_yaw_rate D/(2R)' if turning else 'V^D/R'} = {model.feedforward_motor_speed:.4g} rad/s "
            f"needed to follow the path: raise robot.max_motor_speed{_wider_turns(model)} or lower reference.speed"
        )
    if model.heading_bound is not None:
        best, runner = _run_nonlinear(model, s, search, motor, say)
    else:
        best, runner = _run_linearized(model, s, search, motor, say)
    if not motor and rho_max is not None and s.motor_limits is False:
        notes.append("motor limits not enforced (synthesis.motor_limits: false)")
    return best, runner, notes


def linear(job: Any) -> Any:
    """The linear plant's line search over alpha with the disturbance (the set's output bounds)."""
    from ..lti import line_search_design

    return line_search_design(job, dist=True)


def _run_linearized(model: Any, s: SynthesisConfig, search: list, motor: bool,
                    say: Callable[[str], None]) -> tuple[_Best, _Runner]:
    """The ultimate-bound search on the linearized kinematics (docs/theory.md §6b); raises when no
    gain is certified."""
    cfg = model.config
    rho_max = cfg.robot.max_motor_speed
    hint = None
    if s.lyapunov != "common":
        # the common certificate is cheap (one Lyapunov matrix) and its best alpha lies near the
        # richer classes' (measured: within a grid step on every class of the default robot)
        sc = s.model_copy(update={"lyapunov": "common"})
        say(f"the common certificate first: its best alpha starts the {s.lyapunov} search ({len(model.vertices)} vertices)")
        common, _ = _run_invariance(model, sc, [], motor, say, prune=_motor_pruner(model, sc, say=say) if motor else None,
                                    cheaper_hint=_cheaper(model, sc, motor, say))
        hint = float(common.cert["alpha"]) if common.cert is not None else None
    how = (f"walk of alpha from the common certificate's {hint:.4g}" if hint is not None
           else f"scan of alpha over {s.alpha_points} points")
    say(f"{s.objective}: {how}, then parabolic steps ({model.kind} model, {len(model.vertices)} vertices, "
        f"motor limits {'on' if motor else 'off'})")
    least: dict[float, float | None] = {}  # alpha -> the least motor bound, where proven (else None)
    best, runner = _run_invariance(model, s, search, motor, say, alpha_hint=hint,
                                   prune=_motor_pruner(model, s, least, say) if motor else None,
                                   cheaper_hint=_cheaper(model, s, motor, say) if s.lyapunov == "common" else None)
    if best.cert is None:
        if runner.failures and runner.failures == len(search):
            raise SolverFailure("ultimate-bound: every solve failed, also retried (unscaled) and with the fallback solver")
        if motor:
            probe, _ = _run_invariance(model, s.model_copy(update={"alpha_points": 5}), [], False)
            if probe.cert is not None:
                known = [r for r in least.values() if r is not None]
                need = ""
                if known and rho_max < min(known) < math.inf:  # a figure at or below the limit would say nothing
                    need = (f"; these LMIs need at least {min(known):.4g} rad/s"
                            + (" at every alpha of the scan" if len(known) == len(least) else
                               f" at the {len(known)} of the scan's {len(least)} alphas where that was solved"))
                raise InfeasibleError(
                    f"ultimate-bound: no gain keeps |rho| <= {rho_max:g} rad/s for {_delay_text(model)}"
                    + (f" (the feedforward alone takes {model.feedforward_motor_speed:.3g} rad/s of it, the turning "
                       "reference's included)" if getattr(model, "turns", None) is not None else "")
                    + f"{need}: raise robot.max_motor_speed{_wider_turns(model)} or lower reference.speed"
                )
        raise InfeasibleError(
            f"ultimate-bound: no gain makes an ellipsoid invariant for {_delay_text(model)} and slip in "
            f"[{cfg.slip.right.min:g}, {cfg.slip.right.max:g}] x [{cfg.slip.left.min:g}, {cfg.slip.left.max:g}]"
            + (f" (yaw [{cfg.slip.yaw.min:g}, {cfg.slip.yaw.max:g}], x_icr [{cfg.slip.icr_offset.min:g}, "
               f"{cfg.slip.icr_offset.max:g}] m)" if cfg.slip.model == "icr" else "") + ": "
            f"narrow network.delay or slip{_wider_turns(model)}, or lower reference.speed"
        )
    return best, runner


def _cheaper(model: Any, s: SynthesisConfig, motor: bool, say: Callable[[str], None]
             ) -> Callable[..., Any]:
    """The relaxation a costly common search starts from (alpha_search's ``cheaper_hint``): the same LMIs on the
    vertices with every delay instant at an end of its range (:func:`.heading_search._end_vertices_hint`), as the
    nonlinear search's linearized start does.  On the default robot at d_hi = 3 with linearized kinematics (432
    vertices of 80 channels each, about 2 min a solve) the scan of the whole never concluded in 900 s."""
    return lambda h, useless=None: _end_vertices_hint(model, s, motor, say, hint=h, useless=useless)
