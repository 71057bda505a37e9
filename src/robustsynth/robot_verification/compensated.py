"""The slip-compensated law judged on the true robot (docs/theory.md §18).

Its certificate is the ordinary one on the ratio box (model/compensation.py), under a condition: while a command
acts, each track's traction is within ``error`` of the estimate it was compensated with.  ``verify``'s other checks
judge the robot under that condition (the ratio box is their slip).  This one closes the loop with what the
certificate does not see: the robot's true slip moving in its true box at ``slip.max_rate``, each run's deployed
monitor estimating it from the poses and the compensated commands, and the law dividing its commands by that
estimate (:func:`~robustsynth.robot_verification.simulate.simulate_compensated`).

The theorem says: from a period whose state is in the set, as long as the monitored condition (half-width + lag <=
error) holds for every command that can act, the state stays in the set.  So a step k -> k + 1 is judged where the
state at t_k is in the set and the condition held for the commands of periods k - d_hi .. k; leaving the set on such
a step falsifies the certificate (the verdict fails).  Where the condition does not hold (the estimator's warm-up,
saturated periods) the theorem claims nothing: the record says how often, and what the robot reached there.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ..certificate import CertificateCheck, lyapunov_of
from ..monitor import CAUSES
from ..plants.path import path_of
from ..scenarios import draw_scenario
from ..verification.lifted_checks import _previous_delays
from .simulate import simulate_compensated
from ..verification.verdict import LEVEL_TOL, _check

__all__ = ["compensated_checks", "covered_steps", "judge", "true_robot", "jump_recovery"]

BOUND_TOL = 1e-9  # relative round-off allowed on the sampled error bounds


def covered_steps(holds: np.ndarray, d_hi: int) -> np.ndarray:
    """(N, steps) bool: the step k -> k + 1 is under the theorem's condition, i.e. it held for the commands of
    periods k - d_hi .. k (every command that can act within period k; none from before t_0)."""
    ok = holds.copy()
    for j in range(1, d_hi + 1):
        ok[:, j:] &= holds[:, :-j]
        ok[:, :j] = False
    return ok


def _true_error(mu: np.ndarray, mu_hat: np.ndarray, d_hi: int) -> np.ndarray:
    """(N, steps): the largest |mu_i - mu_hat_i| a command compensated at t_k can meet.  It acts within periods
    k .. k + d_hi (d_hi covers tau_max + m_lost Ts: model/build.py), and within period p the slip moves from
    ``mu[p - 1]`` to ``mu[p]`` (Scenario.slip_in_period): the slips of periods k - 1 .. k + d_hi."""
    N, steps, _ = mu.shape
    out = np.zeros((N, steps))
    for j in range(-1, d_hi + 1):
        idx = np.clip(np.arange(steps) + j, 0, steps - 1)
        out = np.maximum(out, np.max(np.abs(mu[:, idx] - mu_hat), axis=2))
    return out


def compensated_checks(model, K: np.ndarray, cert: CertificateCheck, gains: dict, runs: int, seed: int,
                       progress: Callable[[int, int], None] | None = None) -> tuple[list[dict], dict[str, Any], Any]:
    """The checks of the compensated law on the true robot, their record (``verify``'s ``monte_carlo
    ["compensated"]``) and the runs (:class:`~robustsynth.robot_verification.simulate.CompensatedRuns`, for their logs).
    ``model`` is the certificate's (built from a config with ``slip.compensation``)."""
    from ..artifacts.gains import controller_description

    user = model.user_config
    robot = true_robot(user)
    desc = controller_description(gains, user)
    path = path_of(user)
    steps = max(1, int(math.floor(path.duration / model.Ts + 1e-9)))
    scen = draw_scenario(robot, runs, seed, steps, path, within_period=True)
    res = simulate_compensated(robot, K, path, scen, desc, progress)
    checks, rec = judge(model, cert, gains, desc, scen, res, seed)
    if "skipped" not in rec:
        rec["jump"] = jump_recovery(model, robot, K, path, desc, gains, cert, min(runs, JUMP_RUNS), seed)
    return checks, rec, res


JUMP_RUNS = 20  # runs of the slip-jump experiment (not in the verdict: nothing is claimed of a jump)


def jump_recovery(model, robot, K: np.ndarray, path: Any, desc: dict, gains: dict, cert: CertificateCheck, runs: int,
                  seed: int) -> dict[str, Any]:
    """What a jump of the traction does to the compensated law (docs/theory.md §18: the certificate assumes the rate
    bound only, so nothing is certified here; this is measured): ``runs`` runs whose tracks' traction is constant at a
    random point of the box, jumps at mid-path to another random point at least half the box away (each track), and
    stays there.  Recorded, in periods from the jump: until the condition first fails (the monitor noticed),
    until it holds again for every command that can act (``recovery_periods``) and until the state is back in the set
    under it; the periods in which the condition claimed to hold while a command met a traction farther than the
    error from its estimate (before the monitor noticed); the largest V/level and errors until back in the set."""
    from dataclasses import replace

    steps = max(1, int(math.floor(path.duration / model.Ts + 1e-9)))
    rng = np.random.default_rng([seed, 55])
    lo = np.array([r[0] for r in robot.slip_ranges])
    hi = np.array([r[1] for r in robot.slip_ranges])
    before = rng.uniform(lo, hi, size=(runs, 2))
    half = (hi - lo) / 2.0
    u = rng.uniform(0.0, 1.0, size=(runs, 2))
    # to the far side, at least half the box away
    after = np.where(before > lo + half, lo + u * (before - half - lo), before + half + u * (hi - before - half))
    k_jump = steps // 2
    mu = np.empty((runs, steps, 2))
    mu[:, :k_jump], mu[:, k_jump:] = before[:, None], after[:, None]
    scen = replace(draw_scenario(robot, runs, seed + 5, steps, path), mu=mu, mu_switch=None,
                   profiles=tuple("jump" for _ in range(runs)))
    res = simulate_compensated(robot, K, path, scen, desc)
    covered = covered_steps(res.holds, model.d_hi)
    level = float(cert.figures["ellipsoid_level"])
    v = lyapunov_of(model, gains["certificate"]).V_max(res.sim.true_xi()) / level
    true_err = _true_error(scen.mu, res.mu_hat, model.d_hi)
    error = float(desc["compensation"]["error"])
    seen, back, inside_again, wrong = [], [], [], 0
    for n in range(runs):
        after_jump = slice(k_jump, steps)
        fail = np.flatnonzero(~covered[n, after_jump])
        seen.append(int(fail[0]) if fail.size else None)  # periods from the jump until the condition fails
        start = fail[0] if fail.size else 0
        c = np.flatnonzero(covered[n, k_jump + start:])
        back.append(int(start + c[0]) if c.size else None)
        ins = np.flatnonzero(covered[n, k_jump + start:] & (v[n, k_jump + start:] <= 1.0))
        inside_again.append(int(start + ins[0]) if ins.size else None)
        # the periods the condition claimed to hold while a command met a traction farther than the error
        wrong += int(np.sum(res.holds[n, after_jump] & (true_err[n, after_jump] > error + 1e-9)))
    ends = [k_jump + (b if b is not None else steps - k_jump) for b in inside_again]
    peak_v = max(float(np.max(v[n, k_jump:max(e, k_jump + 1)])) for n, e in enumerate(ends))
    peak_e = {k: max(float(np.max(np.abs(res.sim.e[n, k_jump:max(e, k_jump + 1), i]))) for n, e in enumerate(ends))
              for i, k in enumerate(("e_x", "e_y", "e_theta"))}

    def stats(xs: list) -> dict[str, Any]:
        got = [x for x in xs if x is not None]
        return {"median": float(np.median(got)) if got else None, "max": int(max(got)) if got else None,
                "runs_never": len(xs) - len(got)}

    return {"runs": runs, "jump_period": k_jump, "jump_size_min": float(np.min(np.abs(after - before))),
            "condition_lost_after": stats(seen), "recovery_periods": stats(back),
            "back_in_the_set_periods": stats(inside_again), "periods_claimed_wrongly": wrong,
            "max_V_over_level_in_recovery": peak_v, "max_in_recovery": peak_e}


def true_robot(config: Any):
    """The model of the robot a compensated ``config`` drives: its true slip box and rate, no compensation (the
    plant only: linearized kinematics, no kinematic channels are needed to simulate it)."""
    from ..config import config_from_dict, config_to_dict
    from ..model import build_model

    d = config_to_dict(config)
    d["slip"]["compensation"] = None
    d["synthesis"]["kinematics"] = "linearized"
    return build_model(config_from_dict(d))


def judge(model, cert: CertificateCheck, gains: dict, desc: dict, scen: Any, res: Any, seed: int
          ) -> tuple[list[dict], dict[str, Any]]:
    """The checks of :func:`compensated_checks` on runs already simulated (``scen`` drawn, ``res`` from
    :func:`~robustsynth.robot_verification.simulate.simulate_compensated` with the description ``desc``)."""
    user = model.user_config
    runs, steps = scen.runs, scen.steps
    comp = model.compensation
    error = float(desc["compensation"]["error"])
    rec: dict[str, Any] = {"runs": runs, "seed": seed, "steps": steps, "error": error, "lag": desc["compensation"]["lag"],
                           "ratio_box": [list(r) for r in comp.ratio], "true_box": desc["compensation"]["box"],
                           "max_rate": user.slip.max_rate,
                           "start": "on the path, no stored commands, the estimate at the box's centre"}
    if not cert.passed or not (cert.figures.get("ultimate_bound")):
        rec["skipped"] = "no checked certificate with a set to judge the runs against"
        return [], rec
    lyap = lyapunov_of(model, gains["certificate"])
    level = float(cert.figures["ellipsoid_level"])
    lo = np.array([r[0] for r in comp.ratio])
    hi = np.array([r[1] for r in comp.ratio])
    ratio = np.clip(scen.mu / res.mu_hat, lo, hi)  # the slip the certificate sees at each period's start
    xi = res.sim.true_xi()
    v = lyap.V(xi, ratio, _previous_delays(model, lyap, taus=scen.taus, part=slice(None, -1))) / level  # (N, steps)
    covered = covered_steps(res.holds, model.d_hi)
    inside = v <= 1.0
    judged = covered[:, :-1] & inside[:, :-1]  # steps k -> k + 1 from inside the set under the condition
    after = v[:, 1:]
    left = judged & (after > 1.0 + LEVEL_TOL)
    ub = cert.figures["ultimate_bound"]
    e = np.abs(res.sim.e[:, :-1])
    on_set = covered & inside  # samples the theorem covers: in the set under the condition
    true_err = _true_error(scen.mu, res.mu_hat, model.d_hi)
    first = [int(np.argmax(res.holds[n])) if res.holds[n].any() else None for n in range(runs)]
    held = [f for f in first if f is not None]
    names = ("e_x", "e_y", "e_theta")
    rec.update({
        "condition_held_share": float(res.holds.mean()),
        "condition_first_period": {"median": float(np.median(held)) if held else None,
                                   "max": int(max(held)) if held else None, "runs_never": runs - len(held)},
        "steps_covered_share": float(covered.mean()),
        "steps_judged": int(judged.sum()),
        "runs_never_judged": int(np.sum(~judged.any(axis=1))),
        # a run that leaves its set (or the condition) must come back: in the set under the condition at its end
        "runs_not_back_at_the_end": int(np.sum(~(covered[:, -2] & inside[:, -2] & (v[:, -1] <= 1.0)))),
        "steps_leaving_the_set": int(left.sum()),
        "max_V_over_level_judged": float(np.max(np.where(judged, after, 0.0))),
        "max_V_over_level_all": float(np.max(v)),
        "max_on_set": {k: float(np.max(np.where(on_set, e[..., i], 0.0))) for i, k in enumerate(names)},
        "max_all": {k: float(np.max(e[..., i])) for i, k in enumerate(names)},
        "ratio_to_certified": {k: float(np.max(np.where(on_set, e[..., i], 0.0)) / ub[k]) for i, k in enumerate(names)},
        "margin_median": float(np.nanmedian(res.margin)) if np.isfinite(res.margin).any() else None,
        "estimate_unsound_steps": int(np.sum(res.holds & (true_err > error + 1e-9))),
        "monitor_alarm_periods": {name: int(np.sum((res.status & bit) != 0)) for name, bit in CAUSES},
    })
    if left.any():
        n, k = (int(x) for x in np.argwhere(left)[0])
        rec["first_departure"] = {"run": n, "period": k, "V_over_level": float(after[n, k]),
                                  "slip": scen.mu[n, k].tolist(), "estimate": res.mu_hat[n, k].tolist(),
                                  "delay": float(scen.taus[n, k + model.d_hi])}
    bound_ok = all(rec["max_on_set"][k] <= ub[k] * (1.0 + BOUND_TOL) for k in names)
    where = rec.get("first_departure")
    checks = [
        _check("compensated: the true robot keeps its set wherever the estimate's condition holds", not left.any(),
               rec["max_V_over_level_judged"], 1.0,
               f"{rec['steps_judged']} steps judged over {runs} runs with the estimator in the loop (true slip in "
               f"{desc['compensation']['box']} moving at {user.slip.max_rate:g} /s); the condition held in "
               f"{100 * rec['condition_held_share']:.1f} % of the periods"
               + ("" if where is None else f"; run {where['run']} left at period {where['period']} (V/level "
                  f"{where['V_over_level']:.3f}, slip {where['slip']}, estimate {where['estimate']})")),
        _check("compensated: the errors on the covered samples within the certified bounds", bound_ok,
               max(rec["ratio_to_certified"].values()), 1.0,
               "observed / certified: " + ", ".join(f"{k} {rec['ratio_to_certified'][k]:.3f}" for k in names)),
        _check("compensated: every run ends in its set under the condition", rec["runs_not_back_at_the_end"] == 0,
               rec["runs_not_back_at_the_end"], 0, "runs whose last step was not from the set under the condition into "
               f"it (the set attracts; a run that does not come back is not what was proven); "
               f"{rec['runs_never_judged']} runs with no judged step at all"),
        _check("compensated: the estimate holds the true traction whenever its condition holds",
               rec["estimate_unsound_steps"] == 0, rec["estimate_unsound_steps"], 0,
               "periods in which the condition held but a command met a traction farther than the error from its "
               "estimate (the estimator's own assumptions broken)"),
    ]
    return checks, rec
