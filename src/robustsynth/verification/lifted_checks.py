"""``verify``'s checks on the linear models: the frozen delays' spectral radius, and the lifted model under
time-varying delays and slip (random, alternating, the greedy worst case; along arcs for a turning
certificate), against the certificate's decrease and invariant set."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..certificate import CertificateCheck, lyapunov_of
from ..objectives import objective
from ..scenarios import random_delays, rate_limited_slip, slip_vertices
from .lifted import (arc_closed_loop_run, closed_loop_run, frozen_instant_grid, frozen_spectral_radius,
                     greedy_worst_case, random_yaw_rates, yaw_windows)
from .verdict import LEVEL_TOL, SPECTRAL_TOL, _check

GREEDY_RUNS, GREEDY_STEPS = 50, 100  # the lifted model's greedy search: boundary starts and periods


def _frozen(model, K, cert_rate: float | None) -> tuple[list[dict], dict]:
    n = model.config.verification.frozen_grid
    s = frozen_instant_grid(model, n)
    rho = frozen_spectral_radius(model, K, s)
    # constant delays tau: the physically frozen sweep used in the figure
    taus = model.network.grid(max(n, 2))
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
    guarantee = objective(c["objective"]).guarantee
    traces: dict[str, np.ndarray] = {}
    summary: dict[str, Any] = {"runs": N, "steps": steps}
    checks = []
    # slip sequences the certificate covers: corners switching every period, or rate-limited moves
    mu = corners[rng.integers(0, n_c, size=(N, steps + 1))] if lyap.slip_step is None else \
        rate_limited_slip(model, rng, N, steps + 1)
    z = rng.normal(size=(N, model.n_s))
    if guarantee == "set":
        level = float(cert.figures["ellipsoid_level"])
        alpha = float(c["alpha"])
        beta = np.asarray(c["beta"], dtype=float)
        # starting points: on the set's boundary, and far outside it (decay towards it)
        xi_in = z * np.sqrt(level / lyap.V(z, mu[:, 0]))[:, None]
        xi_out = xi_in * 5.0
        patterns = {
            "random": random_delays(model, rng, N, steps),
            "alternating": model.network.pattern("alternating", (N, steps + model.d_hi)),
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
        alternating = model.network.pattern("alternating", (N, steps + model.d_hi))
        for name, taus in (("random", random_delays(model, rng, N, steps)), ("alternating", alternating)):
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
        thr = r2 if guarantee == "decay" else 1.0
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
