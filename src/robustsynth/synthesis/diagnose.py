"""Where is a design stuck?  Re-solve with one assumption relaxed at a time and see which one the
certified bound responds to.

Candidates (each a config override; one synthesis each, the same settings otherwise):

- the motor limit: ``robot.max_motor_speed`` x 1.5 (when the design enforces it);
- the slip range: half as wide, around the same largest value (the more slip is admitted, the
  larger the correction the set must contain);
- the delay range: ``network.delay.max`` halfway down to ``network.delay.min``;
- the slip rate: ``slip.max_rate`` halved (when set).

The candidate whose relaxation shrinks the certified |e_y| most is the binding one.  Nothing here
is a certificate for the original config: each line says what the relaxed problem certifies.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from ..config import Config, config_with
from ..errors import InfeasibleError, Interrupted, RobustSynthError

__all__ = ["Relaxation", "diagnose", "is_large", "LARGE_E_Y_OF_TRACK"]

LARGE_E_Y_OF_TRACK = 0.5  # a certified |e_y| above half the track distance is 'large' (diagnosed by default)


@dataclass(frozen=True)
class Relaxation:
    name: str  # the constraint: motor limit, slip range, delay bound, slip rate
    constraint: str  # what was relaxed, in words
    overrides: dict[str, Any]
    status: str  # certified | infeasible | solver-failure
    e_y: float | None  # certified |e_y| of the relaxed problem [m]
    change: float | None  # relative change of |e_y| against the original design (negative: smaller)
    time_s: float


def is_large(config: Config, certified: dict[str, Any]) -> bool:
    ub = certified.get("ultimate_bound") or {}
    return ub.get("e_y") is not None and ub["e_y"] > LARGE_E_Y_OF_TRACK * config.robot.track_distance


def _candidates(config: Config, motor: bool) -> list[tuple[str, str, dict[str, Any]]]:
    out: list[tuple[str, str, dict[str, Any]]] = []
    rho = config.robot.max_motor_speed
    if motor and rho is not None:
        out.append(("motor limit", f"motor limit {rho:g} -> {1.5 * rho:g} rad/s", {"robot.max_motor_speed": 1.5 * rho}))
    sl = config.slip
    if sl.right.max > sl.right.min or sl.left.max > sl.left.min:
        r_lo = sl.right.max - 0.5 * (sl.right.max - sl.right.min)
        l_lo = sl.left.max - 0.5 * (sl.left.max - sl.left.min)
        out.append(("slip range", f"slip range half as wide: mu_r in [{r_lo:.3g}, {sl.right.max:g}], mu_l in [{l_lo:.3g}, {sl.left.max:g}]",
                    {"slip.right.min": r_lo, "slip.left.min": l_lo}))
    dl = config.network.delay
    if dl.max > dl.min:
        mid = dl.min + 0.5 * (dl.max - dl.min)
        out.append(("delay bound", f"delay bound {dl.max:g} -> {mid:.4g} s", {"network.delay.max": mid}))
    if sl.max_rate is not None:
        out.append(("slip rate", f"slip rate {sl.max_rate:g} -> {sl.max_rate / 2:g} 1/s", {"slip.max_rate": sl.max_rate / 2}))
    return out


def diagnose(model: Any, certified: dict[str, Any], *, motor: bool = True,
             on_step: Callable[[str], None] | None = None, **settings: Any) -> list[Relaxation]:
    """One synthesis per candidate relaxation of the plant's config (``model.rebuilt``; the design of ``model``
    certified ``certified``); sorted with the most effective first."""
    import time

    from .design import synthesize

    config = model.config
    say = on_step if on_step is not None else (lambda _m: None)
    base = (certified.get("ultimate_bound") or {}).get("e_y")
    out: list[Relaxation] = []
    for name, label, over in _candidates(config, motor):
        t0 = time.perf_counter()
        try:
            res = synthesize(model.rebuilt(config_with(config, over)), **settings)
            e_y = float(res.certified["ultimate_bound"]["e_y"]) if res.certified.get("ultimate_bound") else None
            status = "certified"
        except Interrupted:
            raise
        except RobustSynthError as exc:
            e_y, status = None, "infeasible" if isinstance(exc, InfeasibleError) else "solver-failure"
        change = (e_y / base - 1.0) if (e_y is not None and base) else None
        out.append(Relaxation(name, label, over, status, e_y, change, time.perf_counter() - t0))
        say(f"  relaxed {label}: " + (f"|e_y| <= {100 * e_y:.2f} cm ({100 * change:+.0f} %)" if e_y is not None else status))
    return sorted(out, key=lambda r: r.change if r.change is not None else float("inf"))
