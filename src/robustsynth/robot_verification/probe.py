"""Probe the whole certified set on the nonlinear robot: one period from states on its boundary.

The Monte Carlo and the adversary start from steady states and visit only part of the certified set
``{V <= level}``; the invariance claim is about every state in it.  This probe takes states *on the
boundary* ``V(xi) = level``: random directions, and the directions that maximize each bounded figure
(|e_x|, |e_y|, |e_theta|, each motor speed).  Each state comes with stored past commands, which are
part of xi, a slip corner and the delays of the packets acting in the period.  The period is then
run twice:

- on the **nonlinear robot**: the deployed law computes du_k from the pose, and the kinematic plant
  moves through exact arcs, with saturating motors and in-order delivery;
- on the **exact lifted map** the certificate is about: ``Model.robot_exact`` plus ``constant``.

For each run it reports V(xi+)/level, with V taken at the next slip that makes it largest.  A value
above 1 is a state of the certified set that leaves it in one period.  On the linear map the
certificate forbids that.  On the nonlinear robot a linearized certificate does not: the kinematic
terms the linearization drops (docs/theory.md §2) are not in it (a nonlinear certificate covers them).

When slip may change at any time (no ``slip.max_rate``; the tracks model), half as many random runs again get a slip
jump to a random corner within the period: each track at its own random time in every other such run (a
third of them exactly at a command's arrival, :func:`jump_times`), both tracks at one random time in the
others (``Model.switched_exact`` on the linear side).  A
certificate that covers slip changing within a period (docs/theory.md §11) is judged on every run;
one that assumes slip constant within a period is judged on the others, and the jumps are reported
beside (``mid_period``).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, is_dataclass, replace
from typing import Any

import numpy as np

from ..law import Law
from ..plants.kinematic import KinematicRobot
from ..plants.path import arc_frame_error, frame_error, make_path, pose_from_error
from ..scenarios import random_delays, slip_candidates, slip_vertices, split_state, track_changes

__all__ = ["boundary_probe", "probe_directions", "boundary_states", "errors_between_samples", "arc_yaw_rates", "jump_times",
           "MAX_BOUNDARY_STARTS", "BETWEEN_INSTANTS", "REFINE_ROUNDS", "REFINE_TRIES"]

MAX_BOUNDARY_STARTS = 64  # the adversary's boundary starts: the figure-maximizing states, at most this many
BETWEEN_INSTANTS = 20  # instants per period at which the probe measures the errors between samples
REFINE_ROUNDS = 8  # the local search from the probe's worst runs (boundary_probe(refine=...)): rounds,
REFINE_TRIES = 32  # and perturbed states per start and round


def probe_directions(model: Any, K: np.ndarray, lyap: Any, random: int, rng: np.random.Generator) -> np.ndarray:
    """Directions (n, n_s) of the lifted state to probe.  They are ``random`` ones spread evenly over
    the ellipsoids ``xi' S^-1 xi <= 1`` of the Lyapunov matrices S (``L u``, with ``S = L L'`` and u
    Gaussian; a piece S is picked at random for each).  Then, for every S, +- the maximizer
    ``S c'`` of each bounded figure c xi: e_x, e_y, e_theta and the two motor speeds of the new
    command, ``J^-1 K xi``."""
    n_s = model.n_s
    rows = [np.eye(n_s)[i] for i in range(3)] + list(np.asarray(model.J_inv) @ np.asarray(K, dtype=float))
    extreme = [s * S @ c for S in lyap.S for c in rows for s in (1.0, -1.0)]
    L = np.array([np.linalg.cholesky(S) for S in lyap.S])
    pick = rng.integers(0, len(lyap.S), size=random)
    even = np.einsum("nij,nj->ni", L[pick], rng.normal(size=(random, n_s)))
    return np.vstack([even, np.array(extreme)])


def boundary_states(model: Any, K: np.ndarray, lyap: Any, level: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Start states on the boundary V = level for the adversary (:func:`~robustsynth.verification.
    simulate.adversarial_nonlinear`): the maximizers of each bounded figure (:func:`probe_directions`
    without random ones) at every slip corner, those whose stored commands are within the motor
    limit, at most MAX_BOUNDARY_STARTS (a random subset).  Returns (xi (N, n_s), mu (N, 2))."""
    rng = np.random.default_rng(seed)
    dirs = probe_directions(model, np.asarray(K, dtype=float), lyap, 0, rng)
    corners = slip_vertices(model)
    xi = np.repeat(dirs, corners.shape[0], axis=0)
    mu = np.tile(corners, (dirs.shape[0], 1))
    xi = xi * np.sqrt(level / lyap.V(xi, mu))[:, None]
    n_e, n_u, d_hi = model.n_e, model.n_u, model.d_hi
    ok = _within_motor_limit(model, np.array([model.V, 0.0]) + xi[:, n_e : n_e + d_hi * n_u].reshape(-1, d_hi, n_u))
    xi, mu = xi[ok], mu[ok]
    if xi.shape[0] > MAX_BOUNDARY_STARTS:
        pick = np.sort(rng.choice(xi.shape[0], MAX_BOUNDARY_STARTS, replace=False))
        xi, mu = xi[pick], mu[pick]
    return xi, mu


def boundary_probe(model: Any, K: np.ndarray, lyap: Any, level: float, samples: int = 2000,
                   seed: int = 0, within_period: bool = False, refine: int = 0) -> dict[str, Any]:
    """One period from ``samples`` random and every figure-maximizing boundary state.  Each gets a
    slip corner and random admissible delays, and the first few runs get constant minimum or
    maximum delays.  Returns the largest V(xi+)/level on the nonlinear robot and on the exact
    lifted map, the fraction of runs above 1, the largest per-period difference between the two
    in e_x, e_y and e_theta, and the worst run.  States whose stored commands exceed the motor
    limit are dropped: the controller never sent them from inside the set.  ``within_period``: the
    certificate covers slip changing within a period (see the module's docstring).  ``refine``: from that
    many of the worst runs, a local search along the boundary (:data:`REFINE_ROUNDS` rounds of
    :data:`REFINE_TRIES` perturbed states and switch times each, the step halving) keeps what raises
    V(xi+)/level; the maximum reported is then the larger of the two, the fraction outside that of the
    sample."""
    rng = np.random.default_rng(seed)
    K = np.asarray(K, dtype=float)
    corners = slip_vertices(model)
    # slip jumps within the period (the default slip class): samples // 2 more random runs, each with a
    # jump to a random corner at a random time
    n_jump = samples // 2 if model.slip_step is None and corners.shape[0] > 1 else 0
    starts = _starts(model, K, lyap, level, corners, samples, n_jump, seed, rng)
    N = starts.xi.shape[0]
    keep = starts.admissible
    r = _kept(_periods(model, K, starts, n_jump, rng), keep)
    st = r.st
    v_over_level = _v_next_over_level(lyap, level, slip_candidates(model, st.mu_after), st.dw)
    r_nl_all, r_lin_all = v_over_level(r.xi_nl), v_over_level(r.xi_lin)
    judged = np.ones_like(st.jumped) if within_period else ~st.jumped  # the runs the certificate speaks about
    r_nl, r_lin = r_nl_all[judged], r_lin_all[judged]
    worst = int(np.flatnonzero(judged)[np.argmax(r_nl)])
    refined = (_refine_straight(model, K, lyap, level, r, judged, r_nl_all, refine, bool(n_jump), v_over_level, rng)
               if refine else None)
    gap = np.max(np.abs(r.xi_nl[judged, :model.n_e] - r.xi_lin[judged, :model.n_e]), axis=0)
    arcs = (_arcs_record(model, K, lyap, level, r, judged, refine, bool(n_jump), v_over_level, rng)
            if r.xi_arc is not None else None)
    worst_run, max_nl, refinement = _worst_run(r, worst, r_nl_all, r_lin_all, float(np.max(r_nl)), refined)
    return {
        "arcs": arcs,
        "between_samples": _between_record(r, judged),
        "refinement": refinement,
        # the search's best states, worst first, and their slips: starts for the adversary (None without a search)
        "searched_states": (refined["states"], refined["states_mu"]) if refined is not None else None,
        "samples": int(np.count_nonzero(judged)),
        "directions": {"random": int(samples + n_jump), "figure_maximizing": int(N - samples - n_jump),
                       "dropped_inadmissible_memory": int(N - np.count_nonzero(keep))},
        "max_V_over_level_nonlinear": max_nl,
        "max_V_over_level_linear": float(np.max(r_lin)),
        "fraction_outside_nonlinear": float(np.mean(r_nl > 1.0)),
        "fraction_outside_linear": float(np.mean(r_lin > 1.0)),
        "max_period_gap": {"e_x": float(gap[0]), "e_y": float(gap[1]), "e_theta": float(gap[2])},
        "mid_period": _mid_record(r, r_nl_all, r_lin_all, within_period),
        # t_switch: each track's time (2,) when the probe drew jumps, else one time (the period's end: none)
        "worst": worst_run,
    }


@dataclass(frozen=True)
class _Starts:
    """The probe's starts, one per run: the states ``xi`` on the boundary V = level of their slip ``mu``, the
    delays ``taus`` of the packets acting in the period and their instants ``S`` (with the delay weights ``dw``
    of a path-dependent V), whether the stored commands are ``admissible`` (within the motor limit), and the
    slip jumps within the period (``jumped``, to ``mu_after`` at ``t_sw``)."""

    xi: np.ndarray
    mu: np.ndarray
    taus: np.ndarray
    S: np.ndarray
    dw: np.ndarray | None
    du_past: np.ndarray
    admissible: np.ndarray
    jumped: np.ndarray
    mu_after: np.ndarray
    t_sw: np.ndarray


def _starts(model: Any, K: np.ndarray, lyap: Any, level: float, corners: np.ndarray, samples: int, n_jump: int,
            seed: int, rng: np.random.Generator) -> _Starts:
    """``samples`` random and every figure-maximizing boundary state (:func:`probe_directions`), ``n_jump`` more
    random ones with a slip jump, each at a random slip corner with random admissible delays (the first few at
    constant minimum or maximum delays), on the boundary of the set of its slip with the largest value over an
    unknown previous delay.  Stored commands beyond the motor limit the certificate enforces in the set are
    marked inadmissible: a state with them in its memory is never reached."""
    dirs = probe_directions(model, K, lyap, samples + n_jump, rng)
    N = dirs.shape[0]
    mu = corners[rng.integers(0, corners.shape[0], size=N)]
    scale = np.sqrt(level / lyap.V(dirs, mu))
    xi = dirs * scale[:, None]
    taus = random_delays(model, rng, N, 1)  # (N, 1 + d_hi): the packets acting in the period
    dl = model.config.network.delay
    taus[: min(N, 8) : 2] = dl.min
    taus[1 : min(N, 8) : 2] = dl.max
    S = model.s_tilde(taus)[:, 0]  # (N, d_hi)
    dw = model.delay_weights(S) if lyap.path else None
    du_past = split_state(model, xi)[1]
    admissible = _within_motor_limit(model, np.array([model.V, 0.0]) + du_past)
    jumped = np.zeros(N, dtype=bool)
    jumped[samples : samples + n_jump] = True
    mu_after = np.where(jumped[:, None], corners[rng.integers(0, corners.shape[0], size=N)], mu)
    t_sw = jump_times(model, S, samples, n_jump, rng, np.random.default_rng((seed, 1)))
    return _Starts(xi, mu, taus, S, dw, du_past, admissible, jumped, mu_after, t_sw)


@dataclass(frozen=True)
class _Runs:
    """The probe's runs of one period from their starts ``st``: the lifted state at t_k+1 on the nonlinear robot
    (``xi_nl``) and on the exact lifted map (``xi_lin``), the largest errors between the samples and their rise
    above the ends (``between``, ``rise``); on arcs (None without turns) the state at t_k+1, the errors between
    the samples, whose memory with the feedforward is within the motor limit, and the yaw rates ``w``."""

    st: _Starts
    xi_nl: np.ndarray
    xi_lin: np.ndarray
    between: np.ndarray
    rise: np.ndarray
    arc_memory: np.ndarray
    xi_arc: np.ndarray | None = None
    between_arc: np.ndarray | None = None
    w: np.ndarray | None = None


def _kept(record: Any, keep: np.ndarray) -> Any:
    """The runs ``keep`` selects (those with an admissible memory) of a record of per-run arrays (:class:`_Starts`,
    :class:`_Runs`): every array indexed, None kept, a record within it likewise."""
    def part(x: Any) -> Any:
        return None if x is None else _kept(x, keep) if is_dataclass(x) else x[keep]

    return replace(record, **{f.name: part(getattr(record, f.name)) for f in fields(record)})


def _periods(model: Any, K: np.ndarray, st: _Starts, n_jump: int, rng: np.random.Generator) -> _Runs:
    """One period from each start: on the nonlinear robot on a straight line along x, at the pose of the
    error e (and the errors between the samples, docs/theory.md §9: the period cut at BETWEEN_INSTANTS
    instants, in the frame of the reference at t, which moves at V^D along x from the pose at t_k); with a
    turning certificate (reference.turn_radius) the same states, slips (and jumps) and delays on arcs, the
    reference turning at yaw rates w_k it allows (:func:`arc_yaw_rates`), the feedforward in the commands in
    flight; and on the exact lifted map of the certificate."""
    n_e = model.n_e
    xi, mu, S = st.xi, st.mu, st.S
    xi_nl, du, U, changes = _robot_period(model, K, xi, S, mu, st.mu_after, st.t_sw, bool(n_jump))
    between, rise = errors_between_samples(model, xi[:, :n_e], U, S, mu, changes)
    arcs: dict[str, Any] = {"arc_memory": st.admissible}  # on arcs the stored commands also carry their feedforward
    if getattr(model, "turns", None) is not None:
        w = arc_yaw_rates(model, xi.shape[0], rng)
        e_arc = arc_period(model, xi[:, :n_e], du, st.du_past, S, mu, rng, switch=changes, w=w)
        U_arc = arc_commands(model, du, st.du_past, w)
        arcs = {"xi_arc": np.concatenate([e_arc, xi_nl[:, n_e:]], axis=1),  # the same memory and integrators
                "between_arc": errors_between_samples(model, xi[:, :n_e], U_arc, S, mu, changes, w[:, 0])[0],
                "arc_memory": _within_motor_limit(model, U_arc[:, 1:]), "w": w}
    A, B, c = model.switched_exact(S, mu, st.t_sw, st.mu_after, per_track=bool(n_jump))
    xi_lin = np.einsum("nij,nj->ni", A, xi) + np.einsum("nij,nj->ni", B, du) + c
    return _Runs(st=st, xi_nl=xi_nl, xi_lin=xi_lin, between=between, rise=rise, **arcs)


def _v_next_over_level(lyap: Any, level: float, nxt: np.ndarray, dw: np.ndarray | None) -> Any:
    """``v(x, runs=None)``: V/level at t_k+1 of the states x of ``runs`` (default: every kept run), the largest
    over the next slips the world may pick (``nxt`` (n, n_c, 2), from the slip at t_k+1), at the period's delay
    weights ``dw`` where V is path-dependent."""

    def v(x: np.ndarray, runs: np.ndarray | None = None) -> np.ndarray:
        nx = nxt if runs is None else nxt[runs]
        xb = np.broadcast_to(x[:, None, :], nx.shape[:2] + x.shape[1:])
        if lyap.path:
            d = dw if runs is None else dw[runs]
            return np.max(lyap.V(xb, nx, prev=np.broadcast_to(d[:, None, :], nx.shape[:2] + d.shape[1:])), axis=1) / level
        return np.max(lyap.V(xb, nx), axis=1) / level

    return v


def _refine_straight(model: Any, K: np.ndarray, lyap: Any, level: float, r: _Runs, judged: np.ndarray,
                     r_all: np.ndarray, refine: int, jumps: bool, v_over_level: Any, rng: np.random.Generator
                     ) -> dict[str, Any]:
    """The local search (:func:`_refine_worst`) from the ``refine`` worst judged runs on the straight line."""
    st = r.st
    uD = np.array([model.V, 0.0])

    def one_period(x: np.ndarray, runs: np.ndarray, t: np.ndarray) -> np.ndarray:
        return _robot_period(model, K, x, st.S[runs], st.mu[runs], st.mu_after[runs], t, jumps)[0]

    return _refine_worst(model, lyap, level, st.xi, st.mu, st.t_sw, st.jumped, np.flatnonzero(judged), r_all, refine,
                         one_period, v_over_level, rng,
                         lambda x, runs: _within_motor_limit(model, uD + split_state(model, x)[1]))


def _arcs_record(model: Any, K: np.ndarray, lyap: Any, level: float, r: _Runs, judged: np.ndarray, refine: int,
                 jumps: bool, v_over_level: Any, rng: np.random.Generator) -> dict[str, Any]:
    """The runs on arcs, judged as on the straight line (the runs with a jump only where the certificate covers
    them) among those whose memory with the feedforward is admissible: the largest V(xi+)/level and the fraction
    outside, the runs with a jump judged or not, and (``refine``) the local search on the arcs, each start
    keeping its yaw rates."""
    st = r.st
    r_arc_all = v_over_level(r.xi_arc)
    on_arc = judged & r.arc_memory
    r_arc = r_arc_all[on_arc]
    arcs = {"runs": int(r_arc.size), "mid_period_runs": int(np.count_nonzero(st.jumped & on_arc)),
            "dropped_inadmissible_memory": int(np.count_nonzero(judged & ~r.arc_memory)),
            "max_yaw_rate": float(model.turns.max_yaw_rate),
            "max_V_over_level_nonlinear": float(np.max(r_arc)), "fraction_outside_nonlinear": float(np.mean(r_arc > 1.0))}
    if np.any(st.jumped & r.arc_memory):  # the runs with a jump, judged or not
        arcs["mid_period_max_V_over_level_nonlinear"] = float(np.max(r_arc_all[st.jumped & r.arc_memory]))
    if refine:
        ra = _refine_arcs(model, K, lyap, level, r, on_arc, r_arc_all, refine, jumps, v_over_level, rng)
        arcs["refinement"] = {"starts": ra["starts"], "runs": ra["runs"],
                              "max_V_over_level_before": arcs["max_V_over_level_nonlinear"],
                              "max_V_over_level_after": ra["max"]}
        arcs["max_V_over_level_nonlinear"] = max(arcs["max_V_over_level_nonlinear"], ra["max"])
    return arcs


def _refine_arcs(model: Any, K: np.ndarray, lyap: Any, level: float, r: _Runs, on_arc: np.ndarray, r_all: np.ndarray,
                 refine: int, jumps: bool, v_over_level: Any, rng: np.random.Generator) -> dict[str, Any]:
    """The local search (:func:`_refine_worst`) from the ``refine`` worst judged runs on arcs, each start keeping
    its yaw rates; a memory is admissible with the feedforward of its yaw rates."""
    st = r.st
    n_e, uD = model.n_e, np.array([model.V, 0.0])

    def arc_one_period(x: np.ndarray, runs: np.ndarray, t: np.ndarray) -> np.ndarray:
        _, _, du_r, after = _law_step(model, K, x)
        changes_r = track_changes(st.mu[runs], st.mu_after[runs], t) if jumps else None
        e = arc_period(model, x[:, :n_e], du_r, split_state(model, x)[1], st.S[runs], st.mu[runs], rng,
                       switch=changes_r, w=r.w[runs])
        return np.concatenate([e, after], axis=1)

    def arc_admissible(x: np.ndarray, runs: np.ndarray) -> np.ndarray:
        return _within_motor_limit(model, uD + split_state(model, x)[1] + r.w[runs, 1:, None] * model.turn_feedforward)

    return _refine_worst(model, lyap, level, st.xi, st.mu, st.t_sw, st.jumped, np.flatnonzero(on_arc), r_all, refine,
                         arc_one_period, v_over_level, rng, arc_admissible)


def _between_record(r: _Runs, judged: np.ndarray) -> dict[str, Any]:
    """The largest errors between the samples over the judged runs, on the straight line (and their rise above
    the larger end: e_x and e_y, the chord term) and on arcs; the runs whose slip jumps within the period,
    which this certificate does not cover, reported beside."""
    st = r.st
    names = ("e_x", "e_y", "e_theta")
    cont = {"instants": BETWEEN_INSTANTS, "states": int(np.count_nonzero(judged)),
            "straight": dict(zip(names, (float(x) for x in np.max(r.between[judged], axis=0)))),
            "straight_rise": dict(zip(names[:2], (float(x) for x in np.max(r.rise[judged, :2], axis=0))))}
    if r.between_arc is not None:
        cont["arcs"] = dict(zip(names, (float(x) for x in np.max(r.between_arc[judged & r.arc_memory], axis=0))))
    if np.any(st.jumped & ~judged):
        cont["mid_period"] = {"runs": int(np.count_nonzero(st.jumped & ~judged)),
                              **dict(zip(names, (float(x) for x in np.max(r.between[st.jumped & ~judged], axis=0))))}
    return cont


def _mid_record(r: _Runs, r_nl_all: np.ndarray, r_lin_all: np.ndarray, within_period: bool) -> dict[str, Any]:
    """The runs with a slip jump within the period: how many, whether the certificate covers them, and the
    largest V(xi+)/level they reach on the nonlinear robot and on the exact map."""
    st = r.st
    mid = {"runs": int(np.count_nonzero(st.jumped)), "covered": bool(within_period)}
    if mid["runs"]:
        mid.update(max_V_over_level_nonlinear=float(np.max(r_nl_all[st.jumped])),
                   max_V_over_level_linear=float(np.max(r_lin_all[st.jumped])))
    return mid


def _worst_run(r: _Runs, worst: int, r_nl_all: np.ndarray, r_lin_all: np.ndarray, max_nl: float,
               refined: dict[str, Any] | None) -> tuple[dict[str, Any], float, dict[str, Any] | None]:
    """The worst judged run (its start, slips, switch times, delays, state at t_k+1 and V(xi+)/level), replaced
    by the local search's best state where that went higher (the exact map was not run on it); the largest
    V(xi+)/level on the nonlinear robot, ``max_nl`` or the search's; and the search's record (None without one)."""
    st = r.st
    worst_run = {"xi": st.xi[worst], "mu": st.mu[worst], "mu_after": st.mu_after[worst], "t_switch": st.t_sw[worst],
                 "tau": st.taus[worst], "xi_next": r.xi_nl[worst],
                 "V_over_level": float(r_nl_all[worst]), "V_over_level_linear": float(r_lin_all[worst])}
    if refined is None:
        return worst_run, max_nl, None
    refinement = {"starts": refined["starts"], "rounds": REFINE_ROUNDS, "tries": REFINE_TRIES, "runs": refined["runs"],
                  "max_V_over_level_before": max_nl, "max_V_over_level_after": refined["max"]}
    if refined["max"] > max_nl:
        j = refined["run"]
        worst_run = {"xi": refined["xi"], "mu": st.mu[j], "mu_after": st.mu_after[j], "t_switch": refined["t_switch"],
                     "tau": st.taus[j], "xi_next": refined["xi_next"], "V_over_level": refined["max"],
                     "V_over_level_linear": None}
        max_nl = refined["max"]
    return worst_run, max_nl, refinement


def jump_times(model: Any, S: np.ndarray, samples: int, n_jump: int, rng: np.random.Generator,
               pick: np.random.Generator) -> np.ndarray:
    """When each track's slip jumps within the period, for the probe's N = ``S.shape[0]`` runs (the first
    ``samples`` without a jump, the next ``n_jump`` with one, the rest, the figure maximizers, without):
    (N, 2) times, the period's end Ts for no jump.  Of the jump runs, every other one has both tracks
    jump at one random time (as the Monte Carlo), the others each track at its own; and a third of those
    each track exactly at one of the period's switching instants ``S`` strictly inside it (a command's
    arrival), so that the command intervals on its two sides run at independent slip corners: the
    combinations the covering certificate's heading rows and within-period vertices take (docs/theory.md
    §11), which random times reach only approximately (review, stop 47).  Without jumps (``n_jump`` 0): one time per run, Ts.
    The random times come from ``rng``, the instants from ``pick``."""
    N = S.shape[0]
    if not n_jump:  # slip.max_rate, the icr model, one slip corner
        return np.full(N, model.Ts)
    jumped = np.zeros(N, dtype=bool)
    jumped[samples : samples + n_jump] = True
    t_sw = np.where(jumped[:, None], rng.uniform(0.0, model.Ts, (N, 2)), model.Ts)
    t_sw[samples : samples + n_jump : 2, 1] = t_sw[samples : samples + n_jump : 2, 0]
    at = np.arange(samples + 1, samples + n_jump, 2)[::3]  # every third per-track run
    if at.size and S.shape[1]:
        # only arrivals inside the period (review: with d_hi >= 2 or a lossy link most s~ sit at 0 or Ts, where a
        # change is no change, or one for the whole period); a run with none keeps its random times
        inside = (S[at] > 0.0) & (S[at] < model.Ts)  # (n, d_hi)
        score = np.where(inside[:, None, :], pick.random((at.size, 2, S.shape[1])), -1.0)
        j = np.argmax(score, axis=-1)  # (n, 2): a random arrival inside, per track
        ok = np.any(inside, axis=-1)
        t_sw[at[ok]] = np.take_along_axis(S[at[ok]], j[ok], axis=-1)
    return t_sw


def _refine_worst(model: Any, lyap: Any, level: float, xi: np.ndarray, mu: np.ndarray, t_sw: np.ndarray,
                  jumped: np.ndarray, judged: np.ndarray, r: np.ndarray, starts: int, one_period: Any, v_over_level: Any,
                  rng: np.random.Generator, admissible: Any) -> dict[str, Any]:
    """A local search from the ``starts`` worst of the ``judged`` runs (indices; ``r`` their V(xi+)/level):
    each round perturbs every start's state by ``sigma sqrt(level) L u`` (S = L L' a Lyapunov matrix, u
    Gaussian), puts it back on the boundary V = level of its slip, perturbs the switch times of a run with a
    slip jump by ``sigma Ts`` (within the period), drops memories beyond the motor limit, runs one period
    (``one_period``) and keeps the best per start; sigma starts at 0.2 and halves each round.  ``admissible(x,
    runs)``: which memories the controller can have sent from the set (within the motor limit)."""
    top = judged[np.argsort(r[judged])[::-1][:starts]]
    best_x, best_t, best_r = xi[top].copy(), t_sw[top].copy(), r[top].copy()
    best_next = np.full_like(best_x, np.nan)
    Ls = np.array([np.linalg.cholesky(S) for S in lyap.S])
    runs = 0
    for rnd in range(REFINE_ROUNDS):
        sigma = 0.2 * 0.5**rnd
        rep = np.repeat(np.arange(top.size), REFINE_TRIES)
        step = np.einsum("nij,nj->ni", Ls[rng.integers(0, Ls.shape[0], rep.size)], rng.normal(size=(rep.size, xi.shape[1])))
        x = best_x[rep] + sigma * np.sqrt(level) * step
        x *= np.sqrt(level / lyap.V(x, mu[top[rep]]))[:, None]
        t = best_t[rep].copy()
        moves = jumped[top[rep]]
        if t.ndim == 2 and np.any(moves):
            t[moves] = np.clip(t[moves] + sigma * model.Ts * rng.normal(size=t[moves].shape), 0.0, model.Ts)
        ok = admissible(x, top[rep])
        if not np.any(ok):
            continue
        rep, x, t = rep[ok], x[ok], t[ok]
        xn = one_period(x, top[rep], t)
        v = v_over_level(xn, top[rep])
        runs += int(rep.size)
        for k in np.unique(rep):
            mine = np.flatnonzero(rep == k)
            b = mine[np.argmax(v[mine])]
            if v[b] > best_r[k]:
                best_x[k], best_t[k], best_r[k], best_next[k] = x[b], t[b], v[b], xn[b]
    order = np.argsort(best_r)[::-1]
    j = int(order[0])
    return {"starts": int(top.size), "runs": runs, "max": float(best_r[j]), "run": int(top[j]), "xi": best_x[j],
            "states": best_x[order], "states_mu": mu[top[order]],
            "t_switch": best_t[j], "xi_next": best_next[j]}


def _robot_period(model: Any, K: np.ndarray, xi: np.ndarray, S: np.ndarray, mu: np.ndarray, mu_after: np.ndarray,
                  t_sw: np.ndarray, jumps: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, list | None]:
    """One period of the nonlinear robot on a straight line along x from the lifted states ``xi`` (N, n_s):
    the deployed law computes du_k from the pose, the commands in flight act at the instants ``S``, the
    slip is ``mu`` (jumping to ``mu_after`` at ``t_sw`` when ``jumps``).  Returns the lifted state at
    t_k+1, du_k, the commands in flight and the slip changes."""
    path, q0, du, after = _law_step(model, K, xi)
    robot = KinematicRobot.of(model)
    U = robot.send(robot.memory(split_state(model, xi)[1], xi.shape[0]), np.array([model.V, 0.0]) + du)
    changes = track_changes(mu, mu_after, t_sw) if jumps else None
    q1 = robot.period(q0, U, S, mu, switch=changes)
    return np.concatenate([frame_error(path, 0, q1, model.Ts), after], axis=1), du, U, changes


def _law_step(model: Any, K: np.ndarray, xi: np.ndarray) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray]:
    """The deployed law at t_k from the lifted states ``xi`` on a straight line along x: (the path, the poses,
    du_k (N, 2), the law's memory and integrators after the step (N, n_s - n_e))."""
    n_u, d_hi, n_z = model.n_u, model.d_hi, model.n_z
    e, du_past, z = split_state(model, xi)
    path = make_path(((0.0, 0.0), (model.V * model.Ts * 20.0, 0.0)), model.V)
    q0 = pose_from_error(path, e)
    law = Law(np.asarray(K, dtype=float).tolist(), model.Ts, bool(n_z), path.table)
    law.reset(past=[du_past[:, j, i].copy() for j in range(d_hi) for i in range(n_u)],
              z=[z[:, i].copy() for i in range(n_z)])
    dv, dom = law.correction(0.0, q0[:, 0], q0[:, 1], q0[:, 2])
    return path, q0, np.stack([dv, dom], axis=1), np.stack(law.past + law.z, axis=1)


def _within_motor_limit(model: Any, commands: np.ndarray) -> np.ndarray:
    """Per run, whether every command (N, ..., 2) is within the motor limit (all True without one): a
    memory beyond it is never reached from the set, whose commands the certificate keeps within it."""
    rho_max = model.config.robot.max_motor_speed
    if rho_max is None:
        return np.ones(commands.shape[0], dtype=bool)
    rho = np.abs(commands @ np.asarray(model.J_inv).T)
    return np.all(rho <= rho_max * (1.0 + 1e-9), axis=tuple(range(1, rho.ndim)))


def arc_yaw_rates(model: Any, N: int, rng: np.random.Generator) -> np.ndarray:
    """Reference yaw rates (N, d_hi + 1), (w_k, w_{k-1}, ..., w_{k-d_hi}), an admissible history: w_k is
    -w_bar, 0 or w_bar (a third uniform in between) and each older one a step of -max_step, 0 or max_step
    from the next newer one (within +-w_bar)."""
    wbar = model.turns.max_yaw_rate
    wk = np.where(rng.random(N) < 1.0 / 3.0, rng.uniform(-wbar, wbar, N), wbar * rng.choice([-1.0, 0.0, 1.0], N))
    w = [wk]
    for _ in range(model.d_hi):
        w.append(np.clip(w[-1] - model.turns.max_step * rng.choice([-1.0, 0.0, 1.0], N), -wbar, wbar))
    return np.stack(w, axis=1)


def arc_commands(model: Any, du: np.ndarray, du_past: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The commands in flight (N, d_hi + 1, 2) on an arc: command j is (V^D, 0) + w_{k-j} g + du_{k-j} (g the turning
    feedforward, ``Model.turn_feedforward``)."""
    uD = np.array([model.V, 0.0])
    return np.concatenate([(uD + du)[:, None], uD + du_past], axis=1) + w[:, :, None] * model.turn_feedforward


def errors_between_samples(model: Any, e0: np.ndarray, U: np.ndarray, S: np.ndarray, mu: np.ndarray,
                           switch: list | None = None, w: np.ndarray | None = None,
                           instants: int = BETWEEN_INSTANTS) -> tuple[np.ndarray, np.ndarray]:
    """Per run, the largest |e_x(t)|, |e_y(t)|, |e_theta(t)| (N, 3) over ``instants`` instants of the period
    (the exact arcs cut at t, ``KinematicRobot.partial``), from the errors ``e0`` at t_k with the commands
    ``U`` in flight, in the frame of the reference at t: a straight line, or turning at ``w`` (N,).  And
    how far each rises above the larger of its two ends, |e(t_k)| and |e(t_k+1)| (N, 3): on a straight line
    that is the distance from the chord the bound for all t allows for (docs/theory.md §9)."""
    robot = KinematicRobot.of(model)
    wk = np.zeros(e0.shape[0]) if w is None else np.asarray(w, dtype=float)
    out = np.zeros((e0.shape[0], 3))
    for t in np.linspace(0.0, model.Ts, instants + 1)[1:]:
        e = np.abs(arc_frame_error(robot.partial(e0, U, S, mu, t, switch), wk, t, model.V))
        out = np.maximum(out, e)
    return out, out - np.maximum(np.abs(e0), e)


def arc_period(model: Any, e0: np.ndarray, du: np.ndarray, du_past: np.ndarray, S: np.ndarray, mu: np.ndarray,
               rng: np.random.Generator, switch: list | None = None, w: np.ndarray | None = None) -> np.ndarray:
    """e at t_{k+1} of one period on an arc (docs/theory.md §10): the robot starts at the errors ``e0`` in
    the frame of the reference at t_k, command j is (V^D, w_{k-j}) + du_{k-j}, the reference turns at
    w_k; the yaw rates ``w`` (N, d_hi + 1), or drawn by :func:`arc_yaw_rates`.  ``switch``: the slip's
    changes within the period (``KinematicRobot.period``).  Measured in the reference's frame at t_{k+1}."""
    if w is None:
        w = arc_yaw_rates(model, e0.shape[0], rng)
    q1 = KinematicRobot.of(model).period(e0, arc_commands(model, du, du_past, w), S, mu, switch=switch)
    return arc_frame_error(q1, w[:, 0], model.Ts, model.V)
