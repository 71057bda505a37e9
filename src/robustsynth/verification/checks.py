"""``verify``: every check of a gain against a config, independent of how the gain was made.

Pass/fail rules (also in docs/reference/verification.md):

- certificate: the LMIs rebuilt in numpy from the file keep half their margin;
- frozen delays: spectral radius < 1 on the grid, and <= the certified decay rate + 1e-6;
- lifted model of the gain's kind, time-varying delays and slip (random, alternating, greedy worst
  case; for a turning certificate also random delays along arcs, on the kinematics linearized about
  them): V decreases as certified and states that start in the certified set never leave it
  (relative 1e-9);
- the nonlinear robot (Monte Carlo from steady states, extreme switching, a beam-search
  adversary): every run finite; it re-enters the certified set after every waypoint; on the steps
  the invariance claim covers (from the start, and after each waypoint from the re-entry on) its
  true lifted state stays in the certified set and |e_x|, |e_y|, |e_theta| and the commanded motor
  speed stay within the certified bounds themselves (``nonlinear_slack`` is fixed at 1); the motors
  saturate at rho_max in the simulation (``verification.motor_saturation``).  A gain without a
  certificate gets one searched for its fixed K (analysis LMIs, re-checked in numpy); either way it
  is judged after fixed transients: no divergence (|e_y| <= 1 m), commanded |rho| <= rho_max.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from ..artifacts.gains import as_gains
from ..errors import InfeasibleError, InputError
from ..model.slip import check_physical_feasibility
from ..plants.path import path_of
from ..scenarios import (alternating_delays, draw_scenario, random_delays, rate_limited_slip, slip_vertices,
                         steady_state_start)
from ..certificate import CertificateCheck, check_certificate, lyapunov_of
from ..certificate_turns import turn_bounds
from ..runtime.replay import monitor_summary
from .probe import boundary_probe, boundary_states

BOUNDARY_ADVERSARY_STEPS = 50  # the adversary from the boundary: what matters happens in the first periods
from .lifted import (arc_closed_loop_run, closed_loop_run, frozen_instant_grid, frozen_spectral_radius,
                     greedy_worst_case, random_yaw_rates, yaw_windows)
from .simulate import (ADVERSARY_OBJECTIVES, ARC_COURSES, FREE_YAW, SimResult, adversarial_nonlinear, adversary_courses,
                       merge_adversaries, run_logs, simulate)

__all__ = ["VerificationResult", "verify", "SPECTRAL_TOL", "LEVEL_TOL", "DIVERGENCE_LIMIT"]

SPECTRAL_TOL = 1e-6  # frozen spectral radius may exceed the certified rate by round-off only
GREEDY_RUNS, GREEDY_STEPS = 50, 100  # the lifted model's greedy search: boundary starts and periods
LEVEL_TOL = 1e-9  # relative round-off allowed on V in the lifted-model checks
DIVERGENCE_LIMIT = 1.0  # m: |e_y| beyond this after the transients is divergence (no-bound objectives)
PROBE_SAMPLES = 50_000  # boundary states probed on the nonlinear robot for one period (plus the figure maximizers)
PROBE_REFINE = 128  # of them, the worst runs a local search starts from (probe.boundary_probe(refine=...))
ADVERSARY_FROM_SEARCH = 8  # the beam search from the boundary also starts from this many of the search's worst states


@dataclass(frozen=True)
class VerificationResult:
    passed: bool
    checks: tuple[dict[str, Any], ...]
    certificate: CertificateCheck
    monte_carlo: dict[str, Any]
    lifted: dict[str, Any]
    frozen: dict[str, Any]
    sim: SimResult | None = field(default=None, repr=False)
    extreme_sim: SimResult | None = field(default=None, repr=False)
    scenario: Any = field(default=None, repr=False)
    lifted_traces: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    K: np.ndarray | None = field(default=None, repr=False)
    gains: dict[str, Any] = field(default_factory=dict, repr=False)
    nonlinear_V_over_level: np.ndarray | None = field(default=None, repr=False)
    mask: np.ndarray | None = field(default=None, repr=False)  # (N, steps): steps the verdict covers

    @property
    def failed_checks(self) -> list[str]:
        return [c["name"] for c in self.checks if not c["passed"]]


def _check(name: str, passed: bool, value: Any, threshold: Any, detail: str) -> dict[str, Any]:
    return {"name": name, "passed": bool(passed), "value": value, "threshold": threshold, "detail": detail}


def _V(xi: np.ndarray, P: np.ndarray) -> np.ndarray:
    return np.einsum("...i,ij,...j->...", xi, P, xi)


def _frozen(model, K, cert_rate: float | None) -> tuple[list[dict], dict]:
    n = model.config.verification.frozen_grid
    s = frozen_instant_grid(model, n)
    rho = frozen_spectral_radius(model, K, s)
    # constant delays tau: the physically frozen sweep used in the figure
    dl = model.config.network.delay
    taus = np.linspace(dl.min, dl.max, max(n, 2))
    s_tau = model.s_tilde(np.repeat(taus[:, None], model.d_hi + 1, axis=1))[:, 0, :]
    rho_tau = frozen_spectral_radius(model, K, s_tau)
    worst = float(np.max(rho))
    checks = [_check("frozen delays: spectral radius < 1", worst < 1.0, worst, 1.0,
                     f"{s.shape[0]} frozen switching-instant vectors over the admissible ranges")]
    if cert_rate is not None:
        checks.append(_check("frozen delays: spectral radius <= certified decay rate", worst <= cert_rate + SPECTRAL_TOL,
                             worst, cert_rate, f"tolerance {SPECTRAL_TOL:g}"))
    return checks, {"grid_points": int(s.shape[0]), "max_spectral_radius": worst,
                    "tau": taus, "spectral_radius_vs_tau": rho_tau}


def _lifted(model, K, cert: CertificateCheck, gains: dict) -> tuple[list[dict], dict, dict]:
    vc = model.config.verification
    rng = np.random.default_rng(vc.seed + 1)
    N, steps = vc.lifted_runs, vc.lifted_steps
    corners = slip_vertices(model)
    n_c = corners.shape[0]
    if not cert.passed:
        # no valid certificate: only look for divergence under the patterns
        xi0 = rng.normal(scale=0.05, size=(N, model.n_s))
        mu = corners[rng.integers(0, n_c, size=(N, steps))]
        xi = closed_loop_run(model, K, random_delays(model, rng, N, steps), mu, xi0)
        with np.errstate(all="ignore"):
            grow = float(np.nanmax(np.abs(xi[:, -1])) / max(np.max(np.abs(xi0)), 1e-12))
        return ([_check("lifted model: no certificate to test against", False, grow, None,
                        "the certificate check failed, so V and the invariant set are not available; "
                        f"value = growth of max|xi| over {steps} steps under random delays")],
                {"growth": grow}, {})
    c = gains["certificate"]
    lyap = lyapunov_of(model, c)
    objective = c["objective"]
    traces: dict[str, np.ndarray] = {}
    summary: dict[str, Any] = {"runs": N, "steps": steps}
    checks = []
    # slip sequences the certificate covers: corners switching every period, or rate-limited moves
    mu = corners[rng.integers(0, n_c, size=(N, steps + 1))] if lyap.slip_step is None else \
        rate_limited_slip(model, rng, N, steps + 1)
    z = rng.normal(size=(N, model.n_s))
    if objective == "ultimate-bound":
        level = float(cert.figures["ellipsoid_level"])
        alpha = float(c["alpha"])
        beta = np.asarray(c["beta"], dtype=float)
        # starting points: on the set's boundary, and far outside it (decay towards it)
        xi_in = z * np.sqrt(level / lyap.V(z, mu[:, 0]))[:, None]
        xi_out = xi_in * 5.0
        patterns = {
            "random": random_delays(model, rng, N, steps),
            "alternating": alternating_delays(model, N, steps),
        }
        worst_ratio, worst_dec = 0.0, -np.inf
        w = model.disturbance_coordinates(mu[:, :steps])  # c(mu) = sum lambda_i E_i w
        for name, taus in patterns.items():
            run = lambda xi0, taus=taus: closed_loop_run(model, K, taus, mu[:, :steps], xi0)  # noqa: E731
            dec, ratio = _decrease_runs(run, lyap, mu, _previous_delays(model, lyap, taus=taus), w, alpha, beta, level,
                                        (("boundary", xi_in), ("outside", xi_out)), name, traces)
            worst_dec, worst_ratio = max(worst_dec, dec), max(worst_ratio, ratio)
        n_g = min(N, GREEDY_RUNS)
        xg, tg, mug = greedy_worst_case(model, K, lyap.V, xi_in[:n_g], min(steps, GREEDY_STEPS), mu0=mu[:n_g, 0],
                                        with_delay=lyap.path)
        Vg = _greedy_V(model, lyap, xg, tg, mug, mu[:n_g, 0])
        traces["greedy/boundary"] = Vg
        worst_ratio = max(worst_ratio, float(np.max(Vg[:, 1:]) / level))
        arcs = _lifted_arcs(model, K, lyap, rng, mu, xi_in, xi_out, level, alpha, beta, traces, c.get("turns"))
        if arcs is not None:
            summary["arcs"] = arcs
            worst_dec = max(worst_dec, arcs["max_decrease_excess"])
            worst_ratio = max(worst_ratio, arcs["max_V_over_level"])
        on_arcs = "; and along arcs, random delays and the greedy search picking the yaw rates too (within the " \
                  "certificate's turns, the kinematics linearized about the arc)" if arcs is not None else ""
        checks.append(_check("lifted model: V(xi+) <= (1-alpha) V(xi) + sum beta_i w_i^2", worst_dec <= LEVEL_TOL,
                             worst_dec, LEVEL_TOL, "largest excess relative to max(V, level); random and alternating delays, "
                             "slip corners" + on_arcs))
        checks.append(_check("lifted model: states stay in the certified set", worst_ratio <= 1 + LEVEL_TOL,
                             worst_ratio, 1.0, "max V/level from the boundary; random, alternating, greedy worst case" + on_arcs))
        summary.update({"ellipsoid_level": level, "max_V_over_level": worst_ratio, "max_decrease_excess": worst_dec})
    else:
        r2 = float(cert.figures["decay_rate"]) ** 2 if cert.figures.get("decay_rate") else 1.0
        # the homogeneous part: the deviation from the steady state of a constant slip (paper: mu = 1)
        mu_h = np.ones_like(mu) if model.kind == "paper" else mu
        worst = -np.inf
        for name, taus in (("random", random_delays(model, rng, N, steps)), ("alternating", alternating_delays(model, N, steps))):
            xi = closed_loop_run(model, K, taus, mu_h[:, :steps], z, affine=False)
            V = lyap.V(xi, mu_h, _previous_delays(model, lyap, taus=taus))
            traces[f"{name}/homogeneous"] = V
            worst = max(worst, float(np.max(V[:, 1:] / V[:, :-1])))
        arcs = getattr(model, "turns", None) is not None  # (turning models are tracks-slip ones: Model.with_turns)
        if arcs:  # a turning certificate: the homogeneous part along arcs too (it depends on the yaw rates)
            taus = random_delays(model, rng, N, steps)
            xi = arc_closed_loop_run(model, K, taus, mu_h[:, :steps], random_yaw_rates(model, rng, N, steps), z, affine=False)
            V = lyap.V(xi, mu_h, _previous_delays(model, lyap, taus=taus))
            traces["arcs/homogeneous"] = V
            summary["arcs"] = {"max_V_ratio": float(np.max(V[:, 1:] / V[:, :-1]))}
            worst = max(worst, summary["arcs"]["max_V_ratio"])
        thr = r2 if objective == "stability" else 1.0
        checks.append(_check("lifted model: V(xi+) <= r^2 V(xi) for the deviation from steady state", worst <= thr * (1 + LEVEL_TOL),
                             worst, thr, "largest V ratio per step; random and alternating delays, slip corners"
                             + ("; and along arcs, random delays: the homogeneous part of the kinematics linearized about "
                                "them (the difference of two runs under one history)" if arcs else "")))
        summary.update({"max_V_ratio": worst})
    return checks, summary, traces


def _lifted_arcs(model, K, lyap, rng, mu, xi_in, xi_out, level, alpha, beta, traces, cert_turns) -> dict | None:
    """The ultimate-bound checks of :func:`_lifted` along arcs, for a turning certificate:
    random delays, the slip sequences ``mu`` and random yaw rates of the config's turns (:func:`random_yaw_rates`;
    the certificate covers them, or its re-check failed), the kinematics linearized about the arc
    (:func:`arc_closed_loop_run`), from the boundary and from outside.  The decrease's yaw terms are in the
    coordinates of the certificate's turns ``cert_turns`` (its beta is for those).  None for a straight model."""
    if getattr(model, "turns", None) is None or not cert_turns:
        return None
    N, steps = xi_in.shape[0], mu.shape[1] - 1
    taus = random_delays(model, rng, N, steps)
    yaw = random_yaw_rates(model, rng, N, steps)
    d_hi = model.d_hi
    certified = replace(model, turns=replace(model.turns, max_yaw_rate=float(cert_turns["max_yaw_rate"]),
                                             max_step=float(cert_turns["max_step"])))
    w = certified.disturbance_coordinates(mu[:, :steps], yaw_windows(yaw, d_hi))
    run = lambda xi0: arc_closed_loop_run(model, K, taus, mu[:, :steps], yaw, xi0)  # noqa: E731
    dec, ratio = _decrease_runs(run, lyap, mu, _previous_delays(model, lyap, taus=taus), w, alpha, beta, level,
                                (("boundary", xi_in), ("outside", xi_out)), "arcs", traces)
    # the greedy search along arcs: each period the delay, slip and yaw rate that make V largest
    n_g = min(N, GREEDY_RUNS)
    xg, tg, mug, wg = greedy_worst_case(model, K, lyap.V, xi_in[:n_g], min(steps, GREEDY_STEPS), mu0=mu[:n_g, 0],
                                        with_delay=lyap.path, yaw=True)
    Vg = _greedy_V(model, lyap, xg, tg, mug, mu[:n_g, 0])
    traces["arcs-greedy/boundary"] = Vg
    greedy = float(np.max(Vg[:, 1:])) / level
    return {"max_V_over_level": max(ratio, greedy), "max_V_over_level_random": ratio, "max_V_over_level_greedy": greedy,
            "max_decrease_excess": dec,
            "max_yaw_rate": float(max(np.max(np.abs(yaw)), np.max(np.abs(wg)))), "runs": N, "steps": steps}


def _greedy_V(model, lyap, xg: np.ndarray, tg: np.ndarray, mug: np.ndarray, mu0: np.ndarray) -> np.ndarray:
    """V along the greedy search's runs (:func:`greedy_worst_case`): the largest over the next slips where the
    LMIs hold for every next slip, else at the slips it picked (the start's first) with the delay weights of the
    previous period for a path-dependent V."""
    if lyap.any_next_slip:
        return lyap.V_max(xg)
    return np.concatenate([lyap.V(xg[:, :1], mu0[:, None]),
                           lyap.V(xg[:, 1:], mug, _previous_delays(model, lyap, taus=tg, part=slice(1, None)))], axis=1)


def _decrease_runs(run, lyap, mu, prev, w, alpha, beta, level, starts, name, traces) -> tuple[float, float]:
    """V along the runs ``run(xi0)`` from each of ``starts`` ((name, xi0) pairs), stored in ``traces`` as
    "name/start": the largest excess over ``(1 - alpha) V + sum beta_i w_i^2`` relative to max(V, level), and the
    largest V/level from the start named "boundary" (when the LMIs hold for every next slip, from step 1 on the
    state lies in the set of every slip, and the largest value over the corners is taken)."""
    dec, ratio = -np.inf, 0.0
    for start_name, xi0 in starts:
        xi = run(xi0)
        V = lyap.V(xi, mu, prev)
        rhs = (1 - alpha) * V[:, :-1] + (w**2) @ beta
        dec = max(dec, float(np.max((V[:, 1:] - rhs) / np.maximum(V[:, :-1], level))))
        if start_name == "boundary":
            Vc = lyap.V_max(xi[:, 1:]) if lyap.any_next_slip else V[:, 1:]
            ratio = max(ratio, float(np.max(Vc)) / level)
        traces[f"{name}/{start_name}"] = V
    return dec, ratio


def _previous_delays(model, lyap, taus: np.ndarray, part: slice = slice(None)) -> np.ndarray | None:
    """For a path-dependent certificate, the previous period's delay weights at samples 0..T of runs
    whose packets have the delays ``taus`` (N, T + d_hi): (N, T + 1, n_d)[:, part], NaN at sample 0
    (unknown: V takes the largest value over the previous delay vertices).  None otherwise."""
    if not lyap.path:
        return None
    dw = model.delay_weights(model.s_tilde(taus))
    return np.concatenate([np.full(dw.shape[:1] + (1,) + dw.shape[2:], np.nan), dw], axis=1)[:, part]


def _maxima(e: np.ndarray, rho: np.ndarray, mask: np.ndarray) -> dict[str, np.ndarray]:
    """Per-run maxima of |e| (N, T, 3) and |rho| (N, T, 2) over the steps where ``mask`` (N, T)."""
    m = mask[..., None]
    ea = np.where(m, np.abs(e), 0.0)
    ra = np.where(m, np.abs(rho), 0.0)
    return {
        "e_x": np.max(ea[..., 0], axis=1),
        "e_y": np.max(ea[..., 1], axis=1),
        "e_theta": np.max(ea[..., 2], axis=1),
        "motor_speed": np.max(ra, axis=(1, 2)),
        "motor_speed_all": np.max(np.abs(rho), axis=(1, 2)),
    }


def _transients(model, sim: SimResult, mask: np.ndarray) -> dict[str, Any]:
    """What the verdict does not cover: the steps outside ``mask`` (after waypoints, until the robot
    is back in the certified set, or the fixed transients), and the motor commands over whole runs
    against the physical limit."""
    e = np.abs(sim.e[:, :-1])
    off = ~mask
    rho = np.max(np.abs(sim.rho), axis=2)  # (N, T) larger commanded motor speed
    rho_max = model.config.robot.max_motor_speed
    out: dict[str, Any] = {
        "excluded_steps_fraction": float(np.mean(off)),
        "max": {k: float(np.max(np.where(off, e[..., i], 0.0))) for i, k in enumerate(("e_x", "e_y", "e_theta"))},
        "max_commanded_motor_speed": float(np.max(rho)),
        "motor_limit": rho_max,
        "saturated": bool(model.config.verification.motor_saturation and rho_max is not None),
    }
    if rho_max is not None:
        above = rho > rho_max
        from ..model.network import longest_burst

        out["steps_above_limit_fraction"] = float(np.mean(above))
        out["longest_above_limit_s"] = float(np.max(longest_burst(above), initial=0)) * model.Ts
    return out


def _stats(x: np.ndarray) -> dict[str, float]:
    return {"max": float(np.max(x)), "p95": float(np.percentile(x, 95)), "mean": float(np.mean(x)),
            "worst_run": int(np.argmax(x))}


def _certified_mask(sim: SimResult, v_ratio: np.ndarray, starts_inside: bool) -> tuple[np.ndarray, list[dict]]:
    """Steps (N, steps) covered by the invariance claim: from the start when the run starts inside
    the certified set, and after each waypoint from the first instant the robot is back inside it
    (V/level <= 1) until the next waypoint.  Also one record per waypoint switch."""
    N, T = v_ratio.shape
    seg = sim.segment[:T]
    bounds = [0] + [k for k in range(1, T) if seg[k] != seg[k - 1]] + [T]
    mask = np.zeros((N, T), dtype=bool)
    records = []
    for i, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
        if i == 0 and starts_inside:
            mask[:, a:b] = True
            continue
        inside = v_ratio[:, a:b] <= 1.0
        first = np.where(inside.any(axis=1), inside.argmax(axis=1), b - a)
        mask[:, a:b] = np.arange(b - a)[None, :] >= first[:, None]
        records.append({"segment": int(seg[a]), "t_switch_s": float(sim.t[a]),
                        "max_V_over_level_at_switch": float(np.max(v_ratio[:, a])),
                        "max_time_to_reenter_s": float(np.max(first) * (sim.t[1] - sim.t[0])),
                        "runs_not_reentered": int(np.sum(first >= b - a)),
                        "segment_duration_s": float((b - a) * (sim.t[1] - sim.t[0]))})
    return mask, records


def steady_offsets(model, K: np.ndarray) -> dict[str, Any]:
    """Steady state of the robot under each constant slip corner (docs/theory.md §2): e*, du*."""
    corners = np.asarray(model.corners)
    xi = model.equilibrium(K, corners)
    return {
        "corners": corners.tolist(),
        "e": xi[:, : model.n_e].tolist(),
        "max_abs": {"e_x": float(np.max(np.abs(xi[:, 0]))), "e_y": float(np.max(np.abs(xi[:, 1]))),
                    "e_theta": float(np.max(np.abs(xi[:, 2])))},
    }


def _between_samples_ratio(probe: dict, figures: dict) -> tuple[float, str] | None:
    """The boundary probe's largest error between samples over the certificate's bound for all t
    (``ultimate_bound_between_samples``), and on the straight line the largest rise above the larger end of
    the period over what that bound adds to the sampled one (the chord term, docs/theory.md §9: the bound
    for all t at an instant is near the sampled bound, so the first ratio alone would not see that term);
    the larger, and what it was.  None without those figures."""
    bound = figures.get("ultimate_bound_between_samples") or {}
    sampled = figures.get("ultimate_bound") or {}
    between = probe.get("between_samples") or {}
    worst = None

    def consider(ratio: float, what: str) -> None:
        nonlocal worst
        if worst is None or ratio > worst[0]:
            worst = (ratio, what)

    for course in ("straight", "arcs"):
        for name, value in (between.get(course) or {}).items():
            b = bound.get(name)
            if b is not None and b > 0.0:
                consider(value / b, f"{name} on {'arcs' if course == 'arcs' else 'the straight line'}")
    for name, value in (between.get("straight_rise") or {}).items():
        if bound.get(name) is not None and sampled.get(name) is not None and bound[name] > sampled[name]:
            consider(value / (bound[name] - sampled[name]), f"{name}'s rise above the period's ends on the straight line, "
                     "over the chord term")
    return worst


def _loss_stats(model, scen, adv) -> dict[str, Any]:
    from ..model.network import longest_burst

    ch = model.config.verification.dropouts
    lost = np.isinf(scen.taus[:, model.d_hi:])
    out = {"max_consecutive": model.dropouts, "channel": {"model": "Gilbert-Elliott", "probability": ch.probability,
                                                          "mean_burst": ch.mean_burst},
           "lost_fraction": float(lost.mean()), "longest_burst": int(longest_burst(lost).max(initial=0)),
           "lost_packets": int(lost.sum())}
    if adv is not None:
        out["adversary_lost_fraction"] = float(np.mean(np.isinf(adv["tau"])))
    return out


def _beyond_cap(model, K, gains: dict, cert: CertificateCheck, ub, runs: int, seed: int) -> dict[str, Any]:
    """Runs on the configured channel with bursts *not* cut at the cap: outside the model when a
    burst is longer than ``max_consecutive``.  Reported apart; not part of the verdict.  The robot
    is simulated on a lifting long enough to hold the command in force through the longest burst
    (the same control law, see :func:`robustsynth.model.pad_gain`)."""
    from ..model import build_model, lifted_slice, pad_gain
    from ..model.network import longest_burst

    vc = model.config.verification
    path = path_of(model.config)
    steps = max(1, int(math.floor(path.duration / model.Ts + 1e-9)))
    within = cert.figures.get("slip_within_period") == "covered"  # as the main Monte Carlo (_nonlinear)
    scen = draw_scenario(model, runs, seed + 5, steps, path, losses="uncapped", within_period=within)
    burst = longest_burst(np.isinf(scen.taus))
    extra = max(0, int(burst.max(initial=0)) - model.dropouts)
    longer = build_model(model.config, min_lifting=model.d_hi + extra)
    Kp = pad_gain(K, longer)
    # the longer lifting needs `extra` more packets sent before t_0: received, like the others there
    pre = np.full((runs, longer.d_hi - model.d_hi), model.config.network.delay.min)
    scen = steady_state_start(longer, Kp, path, replace(scen, taus=np.concatenate([pre, scen.taus], axis=1)))
    sim = simulate(longer, Kp, path, scen, vc.transient)
    outside = burst > model.dropouts
    e = np.abs(sim.e[:, :-1])
    out: dict[str, Any] = {
        "runs": runs,
        "runs_outside_model": int(outside.sum()),
        "longest_burst": int(burst.max(initial=0)),
        "lost_fraction": float(np.mean(np.isinf(scen.taus[:, longer.d_hi:]))),
        "finite": bool(np.all(np.isfinite(sim.q))),
        "max_outside": None, "max_inside": None,
        "note": "not part of the verdict: bursts longer than network.dropouts.max_consecutive are outside the model; "
                "maxima over whole runs (waypoint transients included)",
    }
    for name, sel in (("max_outside", outside), ("max_inside", ~outside)):
        if sel.any():
            out[name] = {"e_x": float(np.max(e[sel, :, 0])), "e_y": float(np.max(e[sel, :, 1])),
                         "e_theta": float(np.max(e[sel, :, 2])), "motor_speed": float(np.max(np.abs(sim.rho[sel])))}
    if ub and outside.any():
        lyap = lyapunov_of(model, gains["certificate"])
        xi = sim.true_xi()[..., lifted_slice(model, longer)]
        v = lyap.V(xi, scen.mu) / float(cert.figures["ellipsoid_level"])
        out["max_V_over_level_outside"] = float(np.max(v[outside]))
        out["ratio_to_certified_outside"] = {k: out["max_outside"][k] / ub[k] for k in ("e_x", "e_y", "e_theta")}
    return out


ADVERSARY_WORKERS = 2  # threads for the adversary's searches (numpy releases the GIL in its array loops)


def _adversary(within: bool, model, *args, workers: int = ADVERSARY_WORKERS, **kwargs) -> dict:
    """:func:`adversarial_nonlinear`; where the certificate covers slip changing within a period
    (``within``), merged with the same search that also picks the times of the changes (a beam search
    with more choices keeps different histories and does not always find more); for a turning model,
    merged with the same searches along the arcs of :func:`~robustsynth.verification.simulate.adversary_course` and
    along references whose yaw rates the adversary picks (FREE_YAW; with slip changing at the sampling instants only:
    the times within a period multiply its choices by 4 again, 17 s against 3 s on configs/turns.yaml for the same
    figures, and the fixed courses pick them).  The searches are independent: they run on ``workers`` threads and
    are merged in their order, so the result does not depend on ``workers``."""
    jobs = [(course, w) for course in adversary_courses(model)
            for w in ((False, True) if within and course != FREE_YAW else (False,))]
    outs = _threaded(lambda job: adversarial_nonlinear(model, *args, within_period=job[1], course=job[0], **kwargs),
                     jobs, workers)
    out = outs[0]
    for adv in outs[1:]:
        out = merge_adversaries(out, adv)
    return out


def _threaded(fn: Callable[[Any], Any], jobs: list, workers: int) -> list:
    """``[fn(job) for job in jobs]`` on ``workers`` threads, BLAS on one thread meanwhile (the threads share the
    cores).  An interrupt reaches the jobs through :func:`~robustsynth.errors.check_interrupt` (every period of a
    search); the waiting thread does not wait for them to end."""
    workers = max(1, min(int(workers), len(jobs)))
    if workers == 1:
        return [fn(job) for job in jobs]
    from concurrent.futures import ThreadPoolExecutor

    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="robustsynth-adversary")
        try:
            futures = [pool.submit(fn, job) for job in jobs]
            return [f.result() for f in futures]
        finally:
            pool.shutdown(wait=False, cancel_futures=True)


def _fmt(x: Any, scale: float = 1.0, digits: int = 3) -> str:
    return "(" + ", ".join(f"{scale * float(v):.{digits}g}" for v in np.atleast_1d(np.asarray(x, dtype=float))) + ")"


def describe_probe_run(model, worst: dict[str, Any]) -> str:
    """The probe's worst run in words: the boundary state (errors in cm and rad, the stored commands), the slip
    (and its change within the period), the delays of the packets acting in the period, and V(xi+)/level."""
    xi = np.asarray(worst["xi"], dtype=float)
    n_e, n_u, d_hi = model.n_e, model.n_u, model.d_hi
    names = ", ".join(model.slip_names)
    mu, after = np.asarray(worst["mu"], dtype=float), np.asarray(worst["mu_after"], dtype=float)
    t_sw = np.atleast_1d(np.asarray(worst["t_switch"], dtype=float))
    jump = "" if np.allclose(mu, after) or np.all(t_sw >= model.Ts) else \
        f" changing to {_fmt(after)} at {_fmt(t_sw, 1e3)} ms into the period"
    taus = np.asarray(worst["tau"], dtype=float)
    return (f"e = {_fmt(xi[:2], 100)} cm, e_theta = {xi[2]:.4g} rad, stored commands (dV, omega) "
            f"{_fmt(xi[n_e:n_e + d_hi * n_u])}, slip ({names}) = {_fmt(mu)}{jump}, delays of the packets acting in the "
            f"period {_fmt(taus, 1e3)} ms: one period later V/level = {float(worst['V_over_level']):.4g}")


def describe_adversary_run(model, worst: dict[str, Any], starts: np.ndarray, level: float) -> str:
    """The adversary's worst history from the boundary in words: its start, course, slips and delays per period."""
    mu = np.asarray(worst["mu"], dtype=float)
    taus = np.asarray(worst["tau"], dtype=float)
    x0 = np.asarray(starts[int(worst["start"])], dtype=float)
    shown = min(mu.shape[0], 4)
    return (f"{mu.shape[0]} periods on the {worst.get('course', 'straight')} course from the boundary state "
            f"e = {_fmt(x0[:2], 100)} cm, e_theta = {x0[2]:.4g} rad; slip per period "
            + ", ".join(_fmt(m) for m in mu[:shown]) + (" ..." if mu.shape[0] > shown else "")
            + f"; delays {_fmt(taus[: shown + model.d_hi], 1e3)}" + (" ..." if taus.size > shown + model.d_hi else "")
            + f" ms: V/level {float(worst['value']) / level:.4g} at its end")


def _nonlinear(model, K, cert: CertificateCheck, gains: dict, runs: int, seed: int, progress):
    vc = model.config.verification
    path = path_of(model.config)
    steps = max(1, int(math.floor(path.duration / model.Ts + 1e-9)))
    # a certificate that covers slip changing at any time within a period (docs/theory.md §11) is
    # judged on runs whose slip changes at random times within the periods, not only at the instants
    within = cert.figures.get("slip_within_period") == "covered"
    scen = steady_state_start(model, K, path, draw_scenario(model, runs, seed, steps, path, within_period=within))
    sim = simulate(model, K, path, scen, vc.transient, progress)
    ext_scen = steady_state_start(model, K, path, draw_scenario(model, 4, seed + 2, steps, path, delays="alternating",
                                                                slip="corners", within_period=within))
    ext = simulate(model, K, path, ext_scen, vc.transient)
    finite = bool(np.all(np.isfinite(sim.q)) and np.all(np.isfinite(ext.q)))
    ub = cert.figures.get("ultimate_bound") if cert.passed else None
    slack = vc.nonlinear_slack
    off = vc.initial_offset
    starts_inside = off.x == 0 and off.y == 0 and off.theta == 0
    checks = [_check("nonlinear: every run finite", finite, None, None, f"{runs} Monte Carlo runs + 4 extreme-switching runs")]
    has_steady = scen.du0 is not None
    mc: dict[str, Any] = {
        "runs": runs, "seed": seed, "steps": steps, "duration_s": steps * model.Ts, "transient_s": vc.transient,
        "start": ("steady state of each run's first slip" if has_steady else "reference pose (the gain has no steady state)")
        + ("" if starts_inside else " + the configured initial offset"),
        "slip_profiles": {p: int(sum(1 for x in scen.profiles if x == p)) for p in sorted(set(scen.profiles))},
        "slip_max_rate": model.config.slip.max_rate,
        "slip_changes": ("at the sampling instants" if scen.mu_switch is None else
                         "at uniform random times within the periods, both tracks at one time or each at its own "
                         "(every other run; the certificate covers "
                         "slip changing at any time)" + ("; with slip.max_rate at one time per run and track, the same "
                                                         "in every period" if model.slip_step is not None else "")),
        "delays": "uniform iid in [tau_min, tau_max]; plus 4 runs alternating min/max with corner-switching slip"
        + ("; commands lost on a Gilbert-Elliott channel, bursts capped at network.dropouts.max_consecutive"
           if model.dropouts else ""),
        "certified": {},
        "ratio_to_certified": {},
        "nonlinear_slack": slack,
        "steady_state": steady_offsets(model, K) if has_steady else None,
    }
    v_ratio = None
    adv = None
    adv_v = None
    if ub:
        lyap = lyapunov_of(model, gains["certificate"])
        level = float(cert.figures["ellipsoid_level"])
        v_ratio = lyap.V(sim.true_xi(), scen.mu, _previous_delays(model, lyap, taus=scen.taus, part=slice(None, -1))) / level
        v_ext = lyap.V(ext.true_xi(), ext_scen.mu, _previous_delays(model, lyap, taus=ext_scen.taus, part=slice(None, -1))) / level
        mask, switches = _certified_mask(sim, v_ratio, starts_inside)
        mask_ext, sw_ext = _certified_mask(ext, v_ext, starts_inside)
        rule = "certified set (V/level <= 1): from the start, and after each waypoint from the robot's re-entry on"
        not_back = sum(r["runs_not_reentered"] for r in switches + sw_ext)
        if switches or sw_ext:  # a path rounded by arcs has no waypoint switch: then only runs that start outside
            at_waypoints = any(r["segment"] > 0 for r in switches + sw_ext)
            checks.append(_check("nonlinear: re-enters the certified set after every waypoint" if at_waypoints else
                                 "nonlinear: re-enters the certified set from a start outside it", not_back == 0, not_back, 0,
                                 "runs that did not re-enter before the next waypoint (the set is attracting)" if at_waypoints
                                 else "runs that did not re-enter before the end of the path (the set is attracting)"))
        if vc.adversarial_runs:
            objectives = tuple(o for o in ADVERSARY_OBJECTIVES  # |rho| only against a certified motor bound
                               if o != "motor_speed" or "motor_speed_bound" in cert.figures)
            adv = _adversary(within, model, K, lyap.V, slip_vertices(model), vc.adversarial_steps,
                             width=vc.adversarial_runs, objectives=objectives, with_delay=lyap.path, slip_free=len(lyap.S) == 1)
            times = [t for t in adv["switch_times"] if t > 0.0]
            adv_v = adv["V"] / level
            mc["adversarial"] = {
                "runs": vc.adversarial_runs, "steps": vc.adversarial_steps,
                "search": "beam search from the steady states of the slip corners, on a straight line"
                          + (f" and along arcs at the largest yaw rate the certificate covers ({model.turns.max_yaw_rate:.3g} "
                             "rad/s, left and right in turn from the start; arcs of A periods with G straight between them, A/G "
                             + ", ".join("/".join(c.split("-")[1:]) for c in ARC_COURSES) + "), and along references "
                             "whose yaw rate the adversary picks each period (w_{k-1} or a step of "
                             f"{model.turns.max_step:.3g} rad/s either way, within the largest)"
                             if getattr(model, "turns", None) is not None else "")
                          + ": every period "
                          "each kept history goes on with every slip the adversary may pick"
                          + (" (also a second search in which each track's new slip takes over at "
                             + ", ".join(f"{t:.3g}" for t in times) + " of the period, from the second period on"
                             + (", on the fixed courses" if getattr(model, "turns", None) is not None else "") + ")"
                             if times else "")
                          + " and 9 delays of the newest packet; kept are each start's greedy history (largest V) and, for each of "
                          + ", ".join({"V": "V", "e_x": "|e_x|", "e_y": "|e_y|", "e_theta": "|e_theta|",
                                       "motor_speed": "|rho|"}[o] for o in objectives)
                          + f", the {vc.adversarial_runs} next states that make it largest",
                "max": dict(adv["max"]),
                "slip_change_times": [0.0] + times,  # within a period, in periods
                "max_V_over_level": adv["max_V"] / level,
                "fraction_of_steps_outside": float(np.mean(adv_v > 1.0)),
            }
        mc["V_over_level"] = {
            "max_in_certified_steps": float(max(np.max(np.where(mask, v_ratio, 0.0)), np.max(np.where(mask_ext, v_ext, 0.0)))),
            "fraction_of_certified_steps_outside": float(np.sum((v_ratio > 1.0) & mask) / max(np.sum(mask), 1)),
            "samples_outside": int(np.sum((v_ratio > 1.0 + LEVEL_TOL) & mask) + np.sum((v_ext > 1.0 + LEVEL_TOL) & mask_ext)
                                   + (int(np.sum(adv_v > 1.0 + LEVEL_TOL)) if adv is not None else 0)),
            "waypoints": switches,
        }
        # the verdict judges the robot, whatever the certificate's kind (issue 49): a nonlinear certificate claims
        # that no state of its set leaves it (docs/theory.md §9); a linearized one proves it for the robot's
        # linearization only, and where the robot leaves its set the verdict says so (it fails) and names the
        # state, slip, delays and period that did it (docs/theory.md §7)
        probe = boundary_probe(model, K, lyap, level, samples=PROBE_SAMPLES, seed=seed,
                               within_period=cert.figures.get("slip_within_period") == "covered", refine=PROBE_REFINE)
        nonlinear_proof = gains["certificate"].get("kinematics", "linearized") == "nonlinear"
        mc["boundary_probe"] = {k: v for k, v in probe.items() if k not in ("worst", "searched_states") and v is not None}
        mc["boundary_probe"]["in_verdict"] = True
        # what the certificate covers: the kinematic terms (nonlinear) or the linearization only
        mc["boundary_probe"]["kinematics"] = "nonlinear" if nonlinear_proof else "linearized"
        if cert.figures.get("ultimate_bound_between_samples"):  # beside what the probe measured between the samples
            mc["boundary_probe"]["between_samples"] = dict(probe["between_samples"],
                                                           bound=dict(cert.figures["ultimate_bound_between_samples"]),
                                                           sampled=dict(cert.figures["ultimate_bound"]))
        if vc.adversarial_runs:  # the beam search again, now from the boundary (multi-period histories)
            xb, mb = boundary_states(model, K, lyap, level, seed=seed)
            n_fig = int(xb.shape[0])
            if probe.get("searched_states") is not None:  # and from the probe's worst states after its local search
                xs, ms = probe["searched_states"]
                xb, mb = np.vstack([xb, xs[:ADVERSARY_FROM_SEARCH]]), np.vstack([mb, ms[:ADVERSARY_FROM_SEARCH]])
            if xb.shape[0]:
                steps_b = min(vc.adversarial_steps, BOUNDARY_ADVERSARY_STEPS)
                adv_b = _adversary(within, model, K, lyap.V, mb, steps_b, width=vc.adversarial_runs, objectives=("V",),
                                   with_delay=lyap.path, starts=xb, slip_free=len(lyap.S) == 1)
                mc["boundary_probe"]["adversary"] = {"starts": int(xb.shape[0]), "searched_starts": int(xb.shape[0]) - n_fig,
                                                     "steps": steps_b,
                                                     "max_V_over_level": adv_b["max_V"] / level,
                                                     "courses": list(adversary_courses(model)),
                                                     "worst": describe_adversary_run(model, adv_b["worst"]["V"], xb, level)}
        # waypoint turns: the certificate's bounds through each frame change, beside the verdict (the
        # measured switch values are in V_over_level.waypoints); docs/theory.md §10
        mc["turns"] = turn_bounds(model, K, gains["certificate"], cert.figures)
        kind = ("the nonlinear certificate's claim" if nonlinear_proof else
                "a certificate for the linearization: judged on the robot all the same")
        bp = probe["max_V_over_level_nonlinear"]
        checks.append(_check("nonlinear: one period from the boundary of the certified set stays in it", bp <= 1.0 + LEVEL_TOL,
                             bp, 1.0, f"max V(xi+)/level over {probe['samples']} boundary states (exact arcs, slip corners, "
                             "admissible delays)" + (f" and a local search from the {probe['refinement']['starts']} worst"
                                                     if probe.get("refinement") else "")
                             + f": {kind}" + ("" if bp <= 1.0 + LEVEL_TOL else
                                              f"; the robot left from {describe_probe_run(model, probe['worst'])}")))
        arcs = probe.get("arcs")
        if arcs is not None:  # a turning certificate for the nonlinear robot claims the arcs too (theory §10)
            checks.append(_check("nonlinear: one period on an arc from the boundary of the certified set stays in it",
                                 arcs["max_V_over_level_nonlinear"] <= 1.0 + LEVEL_TOL, arcs["max_V_over_level_nonlinear"],
                                 1.0, f"max V(xi+)/level over {arcs['runs']} boundary states, the reference turning at "
                                 f"up to {arcs['max_yaw_rate']:.3g} rad/s with the steps the certificate allows (exact "
                                 "arcs, slip corners, admissible delays"
                                 + (f"; {arcs['mid_period_runs']} with the slip jumping within the period"
                                    if arcs.get("mid_period_runs") else "") + ")"))
        bs = _between_samples_ratio(probe, cert.figures)
        if bs is not None:  # the bounds for all t are a claim about the robot too (theory §9, §10)
            checks.append(_check("nonlinear: between samples, the errors from the boundary of the certified set stay "
                                 "within the bounds for all t", bs[0] <= 1.0 + LEVEL_TOL, bs[0], 1.0,
                                 f"largest |error(t)| / its bound over {probe['between_samples']['states']} boundary "
                                 f"states at {probe['between_samples']['instants']} instants of the period (exact arcs"
                                 + (", on a straight line and on arcs" if "arcs" in probe["between_samples"] else "")
                                 + f"): {bs[1]}"))
        if "adversary" in mc["boundary_probe"]:
            ab = mc["boundary_probe"]["adversary"]
            left = "" if ab["max_V_over_level"] <= 1.0 + LEVEL_TOL else f"; it left along {ab['worst']}"
            checks.append(_check("nonlinear: the adversary from the boundary of the certified set keeps it there",
                                 ab["max_V_over_level"] <= 1.0 + LEVEL_TOL, ab["max_V_over_level"], 1.0,
                                 f"beam search over {ab['steps']} periods from {ab['starts']} boundary states (each "
                                 "figure's maximizer at every slip corner"
                                 + (f", and the probe's {ab['searched_starts']} worst after its local search"
                                    if ab.get("searched_starts") else "") + ")" + (", on a straight line and along arcs, fixed ones and ones whose "
                                                                              "yaw rates the adversary picks"
                                                                              if len(ab["courses"]) > 1 else "")
                                 + left))
        worst_v = max(mc["V_over_level"]["max_in_certified_steps"], mc["adversarial"]["max_V_over_level"] if adv else 0.0)
        checks.append(_check("nonlinear: the robot's lifted state stays in the certified set", worst_v <= 1.0 + LEVEL_TOL,
                             worst_v, 1.0, f"max V/level on the certified steps of the Monte Carlo, extreme and adversarial "
                             f"runs; {mc['V_over_level']['samples_outside']} samples outside"))
    else:
        rule = f"fixed transients of {vc.transient:g} s after each waypoint" + ("" if starts_inside else " and the start")
        mask = np.broadcast_to(sim.settled[None, :-1], sim.rho.shape[:2])
        mask_ext = np.broadcast_to(ext.settled[None, :-1], ext.rho.shape[:2])
    if model.dropouts:
        mc["dropouts"] = _loss_stats(model, scen, adv)
    if vc.dropouts.exceed_cap:
        mc["beyond_cap"] = _beyond_cap(model, K, gains, cert, ub, runs, seed)
    mc["excluded"] = rule
    mx = _maxima(sim.e[:, :-1], sim.rho, mask)
    mx_ext = _maxima(ext.e[:, :-1], ext.rho, mask_ext)
    mc["maxima"] = {k: _stats(v) for k, v in mx.items()}
    mc["extreme_maxima"] = {k: float(np.max(v)) for k, v in mx_ext.items()}
    mc["certified_steps"] = int(np.sum(mask))
    mc["transients"] = _transients(model, sim, mask)
    if int(np.sum(mask)) == 0:  # otherwise every maximum below would be vacuous
        checks.append(_check("nonlinear: steps after the transients exist", False, 0, 1,
                             "no sampling instant is covered: lengthen reference.path or shorten verification.transient"))
    worst_of = {k: max(float(np.max(mx[k])), float(np.max(mx_ext[k])), (adv and mc["adversarial"]["max"].get(k)) or 0.0)
                for k in ("e_x", "e_y", "e_theta", "motor_speed")}
    if ub:
        where = "Monte Carlo, extreme and adversarial runs"
        for key, unit in (("e_x", "m"), ("e_y", "m"), ("e_theta", "rad")):
            worst = worst_of[key]
            ratio = worst / ub[key]
            mc["certified"][key] = ub[key]
            mc["ratio_to_certified"][key] = ratio
            checks.append(_check(f"nonlinear: max |{key}| <= {slack:g} x certified", ratio <= slack,
                                 worst, slack * ub[key], f"ratio {ratio:.3f} ({unit}); {where}, steps in the {rule}"))
        msb = cert.figures.get("motor_speed_bound")
        if msb is not None:
            worst = worst_of["motor_speed"]
            ratio = worst / msb
            mc["certified"]["motor_speed"] = msb
            mc["ratio_to_certified"]["motor_speed"] = ratio
            checks.append(_check(f"nonlinear: max commanded |rho| <= {slack:g} x certified", ratio <= slack,
                                 worst, slack * msb, f"ratio {ratio:.3f} (rad/s; the adversary's runs included); max over whole Monte Carlo runs "
                                 f"{float(np.max(mx['motor_speed_all'])):.3f} rad/s"))
    else:
        worst = worst_of["e_y"]
        checks.append(_check("nonlinear: no divergence (max |e_y| after transients)", finite and worst <= DIVERGENCE_LIMIT,
                             worst, DIVERGENCE_LIMIT, "no certified bound to compare with; divergence limit in m"))
    rho_max = model.config.robot.max_motor_speed
    if rho_max is not None and (not ub or cert.figures.get("motor_speed_bound") is None):
        # no certified motor bound to judge by: the physical limit itself, on the steps judged
        worst = worst_of["motor_speed"]
        checks.append(_check("nonlinear: max commanded |rho| <= rho_max", worst <= rho_max, worst, rho_max,
                             f"(rad/s) the motors' physical limit, on the steps in the {rule}"))
    # the runtime monitor over the runs (robustsynth.monitor; recorded, not in the verdict): they keep every
    # assumption of the certificate, so an alarm is its false alarm unless the robot left its set (judged above)
    mc["monitor"] = monitor_summary(run_logs(model, sim, scen), gains, model.config)
    return checks, mc, sim, ext, scen, v_ratio, np.asarray(mask)


def _provenance(model: Any, gains: dict[str, Any]) -> str:
    """'the gain was made for config NAME, which differs in: key a -> b, ...' ('' when the gains file
    holds no config or the same design settings)."""
    from ..artifacts.gains import stored_config
    from ..config import config_to_dict

    try:
        made = stored_config(gains)
    except InputError:
        return "the config stored in the gains file is not valid"
    if made is None:
        return ""

    def flat(d: Any, pre: str = "") -> dict[str, Any]:
        out: dict[str, Any] = {}
        for k, v in d.items():
            key = f"{pre}{k}"
            if isinstance(v, dict):
                out.update(flat(v, key + "."))
            else:
                out[key] = v
        return out

    a, b = flat(config_to_dict(made)), flat(config_to_dict(model.config))
    # the path (reference.path, once verification.path) and the verification and physics settings make no gain
    keys = [k for k in sorted(set(a) | set(b)) if k not in ("name", "reference.path")
            and not k.startswith(("verification.", "physics.")) and a.get(k) != b.get(k)]
    if not keys:
        return ""
    shown = ", ".join(f"{k} {a.get(k)!r} -> {b.get(k)!r}" for k in keys[:6]) + (f" and {len(keys) - 6} more" if len(keys) > 6 else "")
    return f"the gain was made for config {made.name!r}, which differs from this one in: {shown}"


def verify(model, gains: Any, runs: int | None = None, seed: int | None = None,
           progress: Callable[[int, int], None] | None = None) -> VerificationResult:
    """Run every check of ``gains`` against ``model``: a gains.json mapping (:func:`~robustsynth.artifacts.gains.load_gains`),
    the result of :func:`~robustsynth.synthesis.synthesize`, or a bare matrix K.

    Parameters
    ----------
    model : Model
        The model of the config to verify against.
    gains : Mapping, SynthesisResult, numpy.ndarray or str
        The gain: a gains mapping or file, a synthesis result, or a bare K.
    runs : int or None
        Monte Carlo runs (default ``verification.runs``).
    seed : int or None
        Their random seed (default ``verification.seed``).
    progress : callable or None
        Called with (runs done, runs in all).

    Returns
    -------
    VerificationResult
        ``passed``, every check with its value and threshold, and the simulations behind them.
    """
    gains = as_gains(model, gains)
    vc = model.config.verification
    runs = vc.runs if runs is None else runs
    seed = vc.seed if seed is None else seed
    if runs < 1:
        raise InputError(f"--runs: must be >= 1 (got {runs})")
    K = np.asarray(gains["K"], dtype=float)
    if K.shape != (model.n_u, model.n_s):
        raise InputError(f"K: has shape {K.shape}, the config's model needs {(model.n_u, model.n_s)} "
                         f"(d_hi = {model.d_hi}); was the gain made for another delay range?")
    cert_data = gains.get("certificate")
    source = "gains file"
    if isinstance(cert_data, dict):
        cert = check_certificate(model, K, cert_data)
    else:
        # a gain from elsewhere: search a robust-stability certificate for this fixed K (the analysis
        # LMIs of `robustsynth margin`); it counts only once re-checked in numpy, like any other
        from ..synthesis.analysis import STABILITY_R, analyze_stability

        ana = analyze_stability(model, K, lyapunov="auto")
        if ana.certified:  # then the best decay rate it certifies (bisection, 6 steps: to 1/64 of the range)
            lo, hi = 0.0, STABILITY_R
            for _ in range(6):
                mid = (lo + hi) / 2.0
                faster = analyze_stability(model, K, lyapunov=ana.lyapunov, r=mid)
                if faster.certified:
                    hi, ana = mid, faster
                else:
                    lo = mid
            cert, cert_data, source = ana.check, ana.certificate, f"analysis of the fixed K ({ana.lyapunov} Lyapunov)"
            gains = dict(gains, certificate=cert_data)
        else:
            cert = CertificateCheck(False, (), {}, "no certificate in the gains file, and none found for the fixed K "
                                    f"by the analysis LMIs ({'; '.join(ana.attempts)})")
            source = None
    if not cert.passed and source == "gains file":  # say what the gain was made for, and what differs
        made_for = _provenance(model, gains)
        if made_for:
            cert = CertificateCheck(False, cert.checks, cert.figures, f"{cert.reason}; {made_for}")
    checks = [_check("certificate: LMIs re-checked in numpy", cert.passed,
                     None if not cert.checks else cert.min_eig_margin,
                     None if not cert.checks else 0.5 * float(cert_data.get("margin", float("nan"))),
                     cert.reason or f"{len(cert.checks)} conditions, smallest margin found {cert.min_eig_margin:.3g}, every "
                     "LMI proven in verified arithmetic (largest rounding allowance "
                     f"{max((c.get('rounding_allowance') or 0.0) for c in cert.checks):.1e})"
                     + ("" if source == "gains file" else f"; certificate from the {source}: robust stability with "
                        f"decay rate {cert.figures.get('decay_rate', float('nan')):.4g}, no error bounds"))]
    claimed = gains.get("certified") or {}
    if cert.passed and isinstance(claimed, dict):
        # every figure is an upper bound (a decay rate, a bound, a gain): a file may claim the re-checked
        # value or a weaker one (e.g. a delay-dependent gain written before the bounds on the intersection
        # of docs/theory.md §6i), never a stronger one
        def _stronger(c: Any, f: float) -> bool:
            return not float(c) >= float(f) * (1.0 - 1e-6)

        mism = [k for k in ("decay_rate", "motor_speed_bound", "hinf_gain")
                if claimed.get(k) is not None and cert.figures.get(k) is not None and _stronger(claimed[k], cert.figures[k])]
        if claimed.get("slip_within_period") == "covered" and cert.figures.get("slip_within_period") != "covered":
            mism.append("slip_within_period")  # claims slip may change within a period; the re-check does not cover it
        for key in ("ultimate_bound", "ultimate_bound_between_samples"):
            ubc, ubf = claimed.get(key), cert.figures.get(key)
            if ubc and ubf:
                mism += [f"{key}.{k}" for k in ubf if ubf[k] is not None and ubc.get(k) is not None
                         and _stronger(ubc[k], ubf[k])]
        checks.append(_check("certificate: figures in the file match the re-check", not mism, None, None,
                             "claims more than the re-check proves: " + ", ".join(mism) if mism else
                             "every certified figure reproduced, or claimed weaker than the re-check proves (rel 1e-6)"))
    try:  # a config no controller can follow (a motor too slow for its slip) is named as such
        check_physical_feasibility(model.config)
    except InfeasibleError as exc:
        checks.append(_check("physics: the config's slip can be compensated within the motor limit", False, None, None,
                             str(exc)))
    cert_rate = cert.figures.get("decay_rate") if cert.passed else None
    fchecks, frozen = _frozen(model, K, cert_rate)
    lchecks, lifted, traces = _lifted(model, K, cert, gains)
    nchecks, mc, sim, ext, scen, v_ratio, mask = _nonlinear(model, K, cert, gains, runs, seed, progress)
    checks += fchecks + lchecks + nchecks
    passed = all(c["passed"] for c in checks)
    mc["certificate_source"] = source
    return VerificationResult(passed, tuple(checks), cert, mc, lifted, frozen, sim, ext, scen, traces, K, dict(gains),
                              v_ratio, mask)
