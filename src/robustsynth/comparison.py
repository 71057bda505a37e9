"""Paper model vs slip-aware model, side by side for one config (the same robot, the same runs).

For the configured model kind and the other one: the certified bounds, the steady offsets of the
real (slip-aware) robot under each constant slip corner, and, when asked, what the nonlinear robot
does with each gain on the same Monte Carlo runs (same seed) and whether that gain's own
certificate holds for it.  Plain data; the Markdown is in :mod:`robustsynth.report.comparison`.
"""

from __future__ import annotations

from typing import Any

from .objectives import OBJECTIVES

__all__ = ["other_kind", "other_config", "compare_models"]


def other_kind(kind: str) -> str:
    return "paper" if kind == "slip-aware" else "slip-aware"


def _row(model: Any, gains: dict[str, Any] | None, vd: dict[str, Any] | None, status: str, message: str = "") -> dict:
    from .robot_verification.nonlinear_checks import steady_offsets
    import numpy as np

    row: dict[str, Any] = {"model": model.kind, "status": status, "message": message, "certified": None,
                           "steady_state": None, "nonlinear": None}
    if gains is None:
        return row
    row["certified"] = gains["certified"]
    row["steady_state"] = steady_offsets(model, np.asarray(gains["K"], dtype=float))["max_abs"]
    if vd is not None:
        mc = vd["monte_carlo"]
        adv = (mc.get("adversarial") or {}).get("max", {})
        row["nonlinear"] = {
            "verification_passed": vd["passed"],
            "max": {k: max(mc["maxima"][k]["max"], mc["extreme_maxima"][k], adv.get(k, 0.0))
                    for k in ("e_x", "e_y", "e_theta", "motor_speed")},
            "max_V_over_level": max((mc.get("V_over_level") or {}).get("max_in_certified_steps", float("nan")),
                                    (mc.get("adversarial") or {}).get("max_V_over_level", 0.0)),
        }
    return row


def other_config(cfg: Any, kind: str, gains: dict[str, Any]) -> Any:
    """The config of the other model kind's design: the settings ``gains`` was made with (the config's, with its
    ``synthesis_overrides``: --objective, --solver, ...; review, stop 47: the other design ignored them), the
    model ``kind`` and a common Lyapunov matrix."""
    from .config import SynthesisConfig

    over = {k.split(".", 1)[1]: v for k, v in (gains.get("synthesis_overrides") or {}).items()}
    data = {**cfg.synthesis.model_dump(), **over, "model": kind, "lyapunov": "common"}
    if kind == "paper":  # the paper's model is linearized: no heading bound (fourth review: validating a nonlinear
        data.update(kinematics="linearized", heading_bound="auto")  # config's copy raised, a traceback)
    return cfg.model_copy(update={"synthesis": SynthesisConfig.model_validate(data)})


def compare_models(model: Any, gains: dict[str, Any], vd: dict[str, Any] | None = None, runs: int | None = None,
                   seed: int | None = None, other_gains: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """Rows for ``model``'s kind (its ``gains`` and, if given, verification data ``vd``) and for the
    other kind (synthesized here; verified on the same runs when ``vd`` is given).  None when the
    objective certifies no bounds (only ultimate-bound designs are compared)."""
    from .errors import RobustSynthError
    from .model import build_model
    from .artifacts.gains import gains_dict
    from .report.verification import verification_dict
    from .synthesis import synthesize
    from .verification import verify

    obj = OBJECTIVES.get(gains.get("objective"))
    if obj is None or obj.figure != "ultimate_bound":  # the comparison is of the ultimate bounds
        return None
    cfg = model.config
    if cfg.slip.model == "icr":  # the paper's model has no yaw factor or lateral slip (the config refuses it)
        return None
    other = build_model(other_config(cfg, other_kind(model.kind), gains))
    rows = [_row(model, gains, vd, "certified")]
    try:
        og = other_gains if other_gains is not None else gains_dict(other, synthesize(other))
    except RobustSynthError as exc:
        rows.append(_row(other, None, None, "infeasible" if exc.exit_code == 3 else "solver-failure", str(exc)))
    else:
        ovd = None
        if vd is not None:
            ores = verify(other, og, runs=runs, seed=seed)
            ovd = verification_dict(other, ores, "(comparison)", og["gains_id"])
        rows.append(_row(other, og, ovd, "certified"))
        rows[-1]["gains"] = og  # reused by a later call (not written to files)
    order = {"paper": 0, "slip-aware": 1}
    rows.sort(key=lambda r: order[r["model"]])
    return {"rows": rows, "runs": (vd or {}).get("monte_carlo", {}).get("runs"),
            "seed": (vd or {}).get("monte_carlo", {}).get("seed")}
