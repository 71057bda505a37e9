"""``verify``'s checks on the nonlinear robot (:func:`_nonlinear`): Monte Carlo from steady states, extreme
switching, the beam-search adversary and the boundary probe, judged against the certified set and bounds
on the steps the invariance claim covers; the runs beyond the loss cap, the waypoint turns and the monitor
reported beside the verdict; the worst runs in words."""

from __future__ import annotations

import math
from contextlib import nullcontext
from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from ..certificate import CertificateCheck, lyapunov_of
from ..certificate.turns import turn_bounds
from ..forked import beside
from ..plants.path import path_of
from ..runtime.replay import monitor_summary
from ..scenarios import draw_scenario, slip_vertices, steady_state_start
from ..verification.lifted_checks import _previous_delays
from .probe import boundary_probe, boundary_states
from .simulate import (ADVERSARY_OBJECTIVES, ARC_COURSES, FREE_YAW, SimResult, adversarial_nonlinear, adversary_courses,
                       merge_adversaries, run_logs, simulate)
from ..verification.verdict import DIVERGENCE_LIMIT, LEVEL_TOL, _check


BOUNDARY_ADVERSARY_STEPS = 50  # the adversary from the boundary: what matters happens in the first periods
PROBE_SAMPLES = 50_000  # boundary states probed on the nonlinear robot for one period (plus the figure maximizers)
PROBE_REFINE = 128  # of them, the worst runs a local search starts from (probe.boundary_probe(refine=...))
ADVERSARY_FROM_SEARCH = 8  # the beam search from the boundary also starts from this many of the search's worst states


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
        from ..core.network import longest_burst

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
    the period over the chord term (``between_samples_rise``: the chord terms each at its worst, docs/theory.md §9:
    the bound for all t at an instant is near the sampled bound, so the first ratio alone would not see that term);
    the larger, and what it was.  None without those figures."""
    bound = figures.get("ultimate_bound_between_samples") or {}
    rise_bound = figures.get("between_samples_rise") or {}
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
        if rise_bound.get(name, 0.0) > 0.0:
            consider(value / rise_bound[name], f"{name}'s rise above the period's ends on the straight line, over the "
                     "chord term")
    return worst


def _loss_stats(model, scen, adv) -> dict[str, Any]:
    from ..core.network import longest_burst

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
    from ..core.network import longest_burst

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
    merged with the same searches along the arcs of :func:`~robustsynth.robot_verification.simulate.adversary_course` and
    along references whose yaw rates the adversary picks (FREE_YAW; with slip changing at the sampling instants only:
    the times within a period multiply its choices by 4 again, 17 s against 3 s on configs/turns.yaml for the same
    figures, and the fixed courses pick them).  The searches are independent: they run on ``workers`` threads and
    are merged in their order, so the result does not depend on ``workers``."""
    jobs = [(course, w) for course in adversary_courses(model)
            for w in ((False, True) if within and course != FREE_YAW else (False,))]
    # the longest first, so that the threads end together (on the default: the searches that pick the times within
    # a period 17-28 s each, the free yaw's 8 s, the others 2-8 s); merged in the jobs' order all the same
    order = sorted(range(len(jobs)), key=lambda i: (not jobs[i][1], jobs[i][0] != FREE_YAW))
    done = _threaded(lambda job: adversarial_nonlinear(model, *args, within_period=job[1], course=job[0], **kwargs),
                     [jobs[i] for i in order], workers)
    outs = [done[order.index(i)] for i in range(len(jobs))]
    out = outs[0]
    for adv in outs[1:]:
        out = merge_adversaries(out, adv)
    return out


def beside_on_one_core(fn: Callable[[], Any]) -> Any:
    """``fn()`` beside this process (:func:`robustsynth.forked.beside`: a forked child where there are two cores),
    BLAS on one thread there: it shares the cores with the adversary's threads.  ``.result()`` its value."""

    def alone() -> Any:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            return fn()

    return beside(alone)


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
    r = _draw_runs(model, K, cert, gains, runs, seed, progress)
    # the runtime monitor over the runs (robustsynth.monitor; recorded, not in the verdict): they keep every
    # assumption of the certificate, so an alarm is its false alarm unless the robot left its set (judged below)
    # (a slip-compensated law: these runs are the robot under its condition, the slip its ratio mu / mu_hat, which
    # its monitor does not watch; the monitor runs in the loop of robot_verification/compensated.py).  It runs on
    # one core beside the adversary's threads (forked.beside): its record is the same whenever it runs.
    with (nullcontext() if model.compensation is not None else beside_on_one_core(
            lambda: monitor_summary(run_logs(model, r.sim, r.scen), gains, model.config))) as monitor:
        checks, mc, v_ratio, mask = _judge_runs(r, runs, seed)
        mc["monitor"] = None if monitor is None else monitor.result()
    return checks, mc, r.sim, r.ext, r.scen, v_ratio, mask


def _judge_runs(r: "_Runs", runs: int, seed: int) -> tuple[list, dict[str, Any], np.ndarray | None, np.ndarray]:
    """:func:`_nonlinear`'s checks of the drawn runs: its checks, the Monte Carlo record, V/level of the runs (None
    without a certified set) and the steps the verdict covers."""
    model, K, cert, gains = r.model, r.K, r.cert, r.gains
    vc = model.config.verification
    sim, ext, scen = r.sim, r.ext, r.scen
    finite = bool(np.all(np.isfinite(sim.q)) and np.all(np.isfinite(ext.q)))
    ub = cert.figures.get("ultimate_bound") if cert.passed else None
    slack = vc.nonlinear_slack
    checks = [_check("nonlinear: every run finite", finite, None, None, f"{runs} Monte Carlo runs + 4 extreme-switching runs")]
    mc = _monte_carlo_summary(r, runs, seed, slack)
    v_ratio = None
    adv = None
    if ub:
        v_ratio, mask, mask_ext, adv = _on_the_set(r, checks, mc)
        rule = "certified set (V/level <= 1): from the start, and after each waypoint from the robot's re-entry on"
    else:
        rule = f"fixed transients of {vc.transient:g} s after each waypoint" + ("" if r.starts_inside else " and the start")
        mask = np.broadcast_to(sim.settled[None, :-1], sim.rho.shape[:2])
        mask_ext = np.broadcast_to(ext.settled[None, :-1], ext.rho.shape[:2])
    if model.dropouts:
        mc["dropouts"] = _loss_stats(model, scen, adv)
    if vc.dropouts.exceed_cap:
        mc["beyond_cap"] = _beyond_cap(model, K, gains, cert, ub, runs, seed)
    mc["excluded"] = rule
    checks += _bound_checks(r, mc, mask, mask_ext, adv, ub, slack, finite, rule)
    return checks, mc, v_ratio, np.asarray(mask)


@dataclass(frozen=True)
class _Runs:
    """The runs the checks on the nonlinear robot judge: the Monte Carlo (``sim``, drawn as ``scen``) and the
    extreme-switching runs (``ext``, drawn as ``ext_scen``), with the gain, its certificate and how they were drawn
    (``within``: slip changing within the periods; ``starts_inside``: from the steady state, no initial offset)."""

    model: Any
    K: np.ndarray
    cert: CertificateCheck
    gains: dict
    seed: int
    steps: int
    within: bool
    starts_inside: bool
    scen: Any
    sim: SimResult
    ext_scen: Any
    ext: SimResult


def _draw_runs(model, K, cert: CertificateCheck, gains: dict, runs: int, seed: int, progress) -> _Runs:
    """The Monte Carlo runs and the 4 extreme-switching runs along the config's path, simulated."""
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
    off = vc.initial_offset
    starts_inside = off.x == 0 and off.y == 0 and off.theta == 0
    return _Runs(model, K, cert, gains, seed, steps, within, starts_inside, scen, sim, ext_scen, ext)


def _monte_carlo_summary(r: _Runs, runs: int, seed: int, slack: float) -> dict[str, Any]:
    """The Monte Carlo's record as it starts: how the runs were drawn, the steady states (the figures and ratios
    are filled in by the checks)."""
    model, K, scen, steps, starts_inside = r.model, r.K, r.scen, r.steps, r.starts_inside
    vc = model.config.verification
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
    return mc


def _on_the_set(r: _Runs, checks: list, mc: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict | None]:
    """The checks against the certified set (appended to ``checks``, their records into ``mc``): the re-entry after
    every waypoint, the adversary, the boundary probe and the lifted state on the steps the invariance claim covers.
    Returns V/level of the Monte Carlo runs, the steps covered (Monte Carlo, extreme runs) and the adversary's result."""
    model, cert, sim, ext, scen, ext_scen = r.model, r.cert, r.sim, r.ext, r.scen, r.ext_scen
    starts_inside = r.starts_inside
    lyap = lyapunov_of(model, r.gains["certificate"])
    level = float(cert.figures["ellipsoid_level"])
    v_ratio = lyap.V(sim.true_xi(), scen.mu, _previous_delays(model, lyap, taus=scen.taus, part=slice(None, -1))) / level
    v_ext = lyap.V(ext.true_xi(), ext_scen.mu, _previous_delays(model, lyap, taus=ext_scen.taus, part=slice(None, -1))) / level
    mask, switches = _certified_mask(sim, v_ratio, starts_inside)
    mask_ext, sw_ext = _certified_mask(ext, v_ext, starts_inside)
    not_back = sum(rec["runs_not_reentered"] for rec in switches + sw_ext)
    if switches or sw_ext:  # a path rounded by arcs has no waypoint switch: then only runs that start outside
        at_waypoints = any(rec["segment"] > 0 for rec in switches + sw_ext)
        checks.append(_check("nonlinear: re-enters the certified set after every waypoint" if at_waypoints else
                             "nonlinear: re-enters the certified set from a start outside it", not_back == 0, not_back, 0,
                             "runs that did not re-enter before the next waypoint (the set is attracting)" if at_waypoints
                             else "runs that did not re-enter before the end of the path (the set is attracting)"))
    # the boundary probe on one core beside the adversary's threads (forked.beside): its result is the same whenever
    # it runs
    with beside_on_one_core(lambda: _probe(r, lyap, level)) as probe_job:
        adv = adv_v = None
        if model.config.verification.adversarial_runs:
            adv, adv_v = _adversarial(r, lyap, level, mc)
        probe = probe_job.result()
    mc["V_over_level"] = {
        "max_in_certified_steps": float(max(np.max(np.where(mask, v_ratio, 0.0)), np.max(np.where(mask_ext, v_ext, 0.0)))),
        "fraction_of_certified_steps_outside": float(np.sum((v_ratio > 1.0) & mask) / max(np.sum(mask), 1)),
        "samples_outside": int(np.sum((v_ratio > 1.0 + LEVEL_TOL) & mask) + np.sum((v_ext > 1.0 + LEVEL_TOL) & mask_ext)
                               + (int(np.sum(adv_v > 1.0 + LEVEL_TOL)) if adv is not None else 0)),
        "waypoints": switches,
    }
    _boundary(r, lyap, level, mc, probe)
    checks += _boundary_checks(r, probe, mc)
    worst_v = max(mc["V_over_level"]["max_in_certified_steps"], mc["adversarial"]["max_V_over_level"] if adv else 0.0)
    checks.append(_check("nonlinear: the robot's lifted state stays in the certified set", worst_v <= 1.0 + LEVEL_TOL,
                         worst_v, 1.0, f"max V/level on the certified steps of the Monte Carlo, extreme and adversarial "
                         f"runs; {mc['V_over_level']['samples_outside']} samples outside"))
    return v_ratio, mask, mask_ext, adv


def _adversarial(r: _Runs, lyap: Any, level: float, mc: dict[str, Any]) -> tuple[dict, np.ndarray]:
    """The beam-search adversary from the steady states of the slip corners (its record into ``mc``): its result and
    V/level along its histories."""
    model, K, cert, within = r.model, r.K, r.cert, r.within
    vc = model.config.verification
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
    return adv, adv_v


def _probe(r: _Runs, lyap: Any, level: float) -> dict[str, Any]:
    """The boundary probe of the certified set on the nonlinear robot (:func:`.probe.boundary_probe`).  The verdict
    judges the robot, whatever the certificate's kind (issue 49): a nonlinear certificate claims that no state of its
    set leaves it (docs/theory.md §9); a linearized one proves it for the robot's linearization only, and where the
    robot leaves its set the verdict says so (it fails) and names the state, slip, delays and period that did it
    (docs/theory.md §7)."""
    return boundary_probe(r.model, r.K, lyap, level, samples=PROBE_SAMPLES, seed=r.seed,
                          within_period=r.cert.figures.get("slip_within_period") == "covered", refine=PROBE_REFINE)


def _boundary(r: _Runs, lyap: Any, level: float, mc: dict[str, Any], probe: dict[str, Any]) -> None:
    """The boundary ``probe``'s record and the adversary from the boundary, and the bounds through the waypoint turns
    (their records into ``mc``)."""
    model, K, cert, gains, seed, within = r.model, r.K, r.cert, r.gains, r.seed, r.within
    vc = model.config.verification
    nonlinear_proof = gains["certificate"].get("kinematics", "linearized") == "nonlinear"
    mc["boundary_probe"] = {k: v for k, v in probe.items() if k not in ("worst", "searched_states") and v is not None}
    mc["boundary_probe"]["in_verdict"] = True
    # what the certificate covers: the kinematic terms (nonlinear) or the linearization only
    mc["boundary_probe"]["kinematics"] = "nonlinear" if nonlinear_proof else "linearized"
    if cert.figures.get("ultimate_bound_between_samples"):  # beside what the probe measured between the samples
        mc["boundary_probe"]["between_samples"] = dict(probe["between_samples"],
                                                       bound=dict(cert.figures["ultimate_bound_between_samples"]),
                                                       sampled=dict(cert.figures["ultimate_bound"]),
                                                       rise_bound=dict(cert.figures.get("between_samples_rise") or {}))
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


def _boundary_checks(r: _Runs, probe: dict[str, Any], mc: dict[str, Any]) -> list[dict[str, Any]]:
    """The checks of the boundary probe (one period from the set's boundary, on a straight line and on arcs, and
    between the samples) and of the adversary from the boundary."""
    model, cert = r.model, r.cert
    nonlinear_proof = r.gains["certificate"].get("kinematics", "linearized") == "nonlinear"
    checks = []
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
    return checks


def _bound_checks(r: _Runs, mc: dict[str, Any], mask: np.ndarray, mask_ext: np.ndarray, adv: dict | None, ub: Any,
                  slack: float, finite: bool, rule: str) -> list[dict[str, Any]]:
    """The maxima of the runs on the steps judged (into ``mc``) against the certified bounds, or against
    divergence and the motors' physical limit where there are none."""
    model, cert, sim, ext = r.model, r.cert, r.sim, r.ext
    checks = []
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
    return checks
