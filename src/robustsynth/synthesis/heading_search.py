"""The ultimate-bound search with the kinematic channels (docs/theory.md §9, :func:`_run_nonlinear`): it
starts from the linearized common certificate's alpha and heading, runs the alpha search for the configured
heading bound or for each of auto's, then tightens the best; where none certifies, the exit message names
the bounds tried, the linearized set's ranges and what each remedy gave (:func:`_first_try`)."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any, Callable

import numpy as np

from ..certificate import check_certificate
from ..config import SynthesisConfig
from ..errors import InfeasibleError, SolverFailure
from .alpha_search import ALPHA_RANGE, COSTLY_SOLVE_S, COSTLY_STOP_REL, Relaxed, _motor_pruner, _run_invariance
from .extension import extend_multipliers
from .lmis import generates_rows, heading_row_table
from .phase1 import (INTERVALS, PARALLEL, Active, _exact_end_vertices, _same_end_vertices, halvings_for, prove_no_set,
                     screen, screen_at, seed, seed_rows, settles)
from .runner import _Best, _Runner, _wider_turns
from .solve import RETRY


HEADING_GRID = (0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.7)  # heading_bound: auto tries these [rad]


# auto's heading bound binds when the certified set's heading within a period reaches this fraction of it; below,
# larger bounds are not tried (they widen every channel's interval and loosen only rows that do not bind: for each
# alpha the LMIs are convex, so their optimum is the one without the heading rows, over channels that only widen) and
# a smaller one is, just above the set's heading (HEADING_ROOM): the default robot's 0.1 rad left its set at 0.078 rad
HEADING_SLACK = 0.95


HEADING_ROOM = 1.03  # the smaller bound tried: this times the set's heading within a period (rounded up to 1e-3 rad)


HEADING_TIGHTEN = 2  # smaller bounds tried at most, each one solve at the best alpha


# auto's first try, where it lies below the grid's first bound by a tenth or more: this times the linearized set's own
# heading within a period (rounded up to 1e-3 rad).  The nonlinear set's heading measured 1.85 times the linearized
# one's on the default robot (0.0702 / 0.0379) and 1.54 times on configs/nonlinear-proof.yaml: the default's first
# bound 0.076 rad leaves its set room, where the grid's 0.1 rad needed a walk there and a tightening (16.6 s against
# 21 s, |e_y| 1.86 cm against 1.85).  Tried at the hint only: where it does not certify there, the grid goes on (one
# solve spent)
HEADING_FROM_LINEARIZED = 2.0


# The first heading bound's phase-1 problems cut the alpha range into half as many intervals as INTERVALS (each with one
# halving more, so the finest is as fine): the smallest bound, whose channels are the narrowest, settled far from any set
# on every long delay measured (its largest t* -4e-5 at d_hi 2, -7e-5 at d_hi 3, -1.2e-4 at d_hi 5, each at or below
# -phase1.COARSEN_T, after which the next bound's layout is halved anyway); on the default robot at d_hi 3 it settles in
# 12 s on 4 problems instead of 23 s on 8.  An interval left unsettled is halved as before (at worst 4 problems more).
FIRST_INTERVALS = INTERVALS // 2


# the first solver of the kinematic channels' problems: Clarabel without its equilibration concluded (optimal or
# infeasible) at every alpha and heading bound tried on the default robot, where the scaled one returned inaccurate
# points or failed at most of them (scaled: 9 of 10 solves at heading 0.1 rad inaccurate, 2 failed); on the tracks
# configs both conclude alike, the unscaled one in 0.3-0.7 s against 0.5-1.2 s (measured, stop 64).  The scaled
# Clarabel is its retry
KINEMATIC_PRIMARY = {"clarabel": "clarabel-unscaled"}


# a heading bound's alpha scan stops after this many solver failures in a row with nothing certified (the
# grid's lowest alphas are the hardest: a band of 3 failures there below a feasible minimum was seen in a
# constructed case; 5 is a third of the default grid)
NONLINEAR_GIVE_UP = 5


def _posed_rows(active: Active | None, model: Any) -> frozenset[bytes] | None:
    """The heading rows a main problem of ``model`` starts with (row generation, :class:`~.runner._Runner`): the
    active rows where the rows are many (:func:`.lmis.generates_rows`) and the active rows name some of them; else
    every row (None)."""
    if active is None or active.rows is None or not generates_rows(model):
        return None
    return active.row_set() if len(heading_row_table(model).indices(active.rows)) else None


def _tighten(model: Any, s: SynthesisConfig, search: list, motor: bool, say: Callable[[str], None], best: _Best,
             runner: _Runner, tried: list, active: Active | None = None) -> tuple[_Best, _Runner]:
    """heading_bound auto, past a certificate: a smaller bound just above the set's own heading within a period, one
    solve at the best alpha each (at most HEADING_TIGHTEN), kept while it certifies a smaller figure."""
    for _ in range(HEADING_TIGHTEN):
        tb0, h = float(best.check.figures["heading_bound"]), _heading_room(best)
        tb = math.ceil(HEADING_ROOM * h * 1e3) / 1e3
        if not tb < 0.9 * tb0:
            break
        say(f"{s.objective}, nonlinear kinematics with |e_theta(t)| <= {tb:g} rad (the set's heading within a period "
            f"at {tb0:g} rad was {h:.3g}): one solve at the best alpha")
        try:
            m = model.with_heading_bound(tb, within_period=s.lyapunov == "common")
            pb, pr = _run_invariance(m, s, search, motor, say, alpha_hint=float(best.cert["alpha"]), retry=False,
                                     probe_only=True, rows=_posed_rows(active, m), cuts=tuple(runner.cuts))
        except InfeasibleError as exc:  # below the slip's own turn within a period
            say(f"  {exc}")
            break
        tried.append((tb, "certified" if pb.cert is not None else "not certified at the best alpha"))
        if pb.cert is None or pb.value >= best.value:
            break
        best, runner = pb, pr
    return best, runner


def _no_proof(model: Any, given: SynthesisConfig, s: SynthesisConfig, motor: bool, say: Callable[[str], None],
              common: _Best, tried: list, tried_at: dict, auto: bool, below: str | None, hint: float | None,
              active: Active, start_solve: float = 0.0) -> None:
    """No heading bound gave a certificate: raise.  The last bound's runner is done with before this is called (it
    holds its problem, ~100 MB of expressions at d_hi = 3, which the remedies' own problems would otherwise sit
    beside; no other bound's is kept: a runner is kept only with its certificate, and none certified here).  The
    remedies are tried only where the start's solves are quick (``start_solve``, :func:`_largest_solved`, under
    COSTLY_SOLVE_S): a try's own start solves at least one such problem, and where each takes longer (the default robot
    at d_hi = 5: estimated 15 s, 17 s measured) a try spent the tries' 60 s on its start and one pair of heading bounds,
    and told nothing."""
    # exit 4 where no solve of any heading bound concluded (every one failed), exit 3 where one did (a solver's
    # infeasibility, or a bound below the slip's own turn): the same rule for one bound and for auto's several
    if not auto and below is not None:  # the configured bound itself is the cause
        raise InfeasibleError(f"{below}; raise synthesis.heading_bound above it, or set it to auto")
    if tried and all(why == "solver failed" for _, why in tried):
        retries = ""
        if auto:
            retries = (f"; the solves ran on {s.solver}; heading_bound: auto retries its failed points with "
                       f"{RETRY.get(s.solver)} only, a single synthesis.heading_bound also with the fallback solver"
                       if s.solver in RETRY else
                       "; heading_bound: auto retries nothing, a single synthesis.heading_bound retries with the "
                       "fallback solver")
        raise SolverFailure("ultimate-bound (nonlinear kinematics): every solve failed (numerical trouble, usually "
                            f"near infeasibility{retries}). " + _nonlinear_infeasible(model, common, tried, tried_at, auto))
    from .remedies import try_remedies

    slow = (f"a quick try's start solves a problem estimated at {start_solve:.1f} s here, quick tries need under "
            f"{COSTLY_SOLVE_S:g} s: run synthesize with that change in the config") if start_solve >= COSTLY_SOLVE_S else None
    tries = try_remedies(model, lambda m, end, said: _first_try(m, given, motor, hint=hint, active=active, say=said,
                                                                 deadline=end), say, skip=slow)
    raise InfeasibleError(_nonlinear_infeasible(model, common, tried, tried_at, auto)
                          + ((". Remedies (" if slow else ". Tried (") + "; ".join(tries) + ")" if tries else ""))


def _run_nonlinear(model: Any, s: SynthesisConfig, search: list, motor: bool,
                   say: Callable[[str], None]) -> tuple[_Best, _Runner]:
    """The ultimate-bound search with the kinematic channels (docs/theory.md §9): for the configured
    heading bound, or for each of HEADING_GRID (auto), the alpha search, walking from the
    linearized common certificate's best alpha; the smallest weighted bound wins.  When no bound gives a
    certificate it raises SolverFailure where every solve of every bound failed (after the retries: Clarabel
    unscaled, and for a configured bound the fallback solver too), else InfeasibleError, both naming the
    heading bounds, the alphas tried and the heading and forward-speed ranges of the linearized set; an exit 3
    also names what each remedy gave when tried (:mod:`robustsynth.synthesis.remedies`)."""
    common, crunner, least = _start(model, s, motor, say)
    start_solve = _largest_solved(crunner)
    given = s
    # the channels' searches below (the linearized start keeps the configured solver: on configs/turns.yaml's arc
    # channels the scaled one took 1.4 s a point against 2.0 s unscaled, both optimal)
    s = _kinematic(s)
    if common.cert is None and s.lyapunov == "common":
        _stop_if_the_start_is_infeasible(model, crunner, least, motor)
    hint = float(common.cert["alpha"]) if common.cert is not None else None
    auto = s.heading_bound == "auto"
    bounds = _auto_bounds(common) if auto else (float(s.heading_bound),)
    first_try = _first_try_bound(common, bounds) if auto else None
    if first_try is not None:
        bounds = (first_try,) + bounds
    best, runner, tried, below = _Best(), None, [], None
    phase1_alone = False  # whether phase-1 problems alone settled the previous bound (the next asks them first)
    layout = FIRST_INTERVALS  # how many intervals the next bound's phase-1 problems cut the alpha range into (Phase1.next_layout)
    tried_at: dict[float, tuple[int, int]] = {}  # heading bound -> (alphas solved, of which the solver failed)
    active = Active()  # the vertices that bound the last phase-1 problems, tried first at the next (the same order)
    _seed(active, crunner)  # the first, where none has yet: those that bind the linearized start
    # the linearized start's problems are done with: their compiled data goes back to the system before the channels'
    # problems take theirs, and the problems with the runner (the icr default at d_hi = 3, 432 vertices: the main
    # search's peak 1.76 -> 1.67 GB, the main process between its phase-1 problems ~0.7 -> 0.6 GB)
    crunner.release_compiled()
    del crunner
    for j, tb in enumerate(bounds):
        # the last bound's runner and problem are done with (``runner`` keeps the best's) before this bound builds its
        # own: on the default robot at d_hi = 5 each holds ~0.5 GB of LMIs (the main process 0.92 -> 1.41 GB at the
        # first)
        b = r = None
        trying = first_try is not None and j == 0  # auto's first try below the grid: the hint's solve first
        # the channels for slip changing within a period only where the certificate is proven at the
        # within-period vertices: a common Lyapunov matrix (Model.slip_variation)
        try:
            m = model.with_heading_bound(tb, within_period=s.lyapunov == "common")
        except InfeasibleError:
            if trying:  # below the slip's own turn: the grid as before
                continue
            raise
        # past a certified bound: one solve at its best alpha first, where a larger bound that is no better stops
        # the search; a better one walks on from there (the same problem, that solve counted: one compile)
        start = float(best.cert["alpha"]) if best.cert is not None else hint
        say(f"{s.objective}, nonlinear kinematics with |e_theta(t)| <= {tb:g} rad"
            + (f" (heading bound {j + 1} of at most {len(bounds)}: {', '.join(f'{b:g}' for b in bounds)} rad"
               + (f"; a first try, {HEADING_FROM_LINEARIZED:g} times the linearized set's heading within a period"
                  if trying else "") + ")" if auto else "")
            + ": alpha "
            + (f"walk from {start:.4g}" + (" (the best alpha so far)" if best.cert is not None else "")
               if start is not None else f"scan over {s.alpha_points} points")
            + f" ({len(m.vertices)} vertices, {m.vertices[0].n_q} kinematic channels each)")
        try:
            if active.rows is None and common.cert is not None:  # (the start's certificate: one Lyapunov matrix Q)
                # the first phase-1 problems pose the rows nearest their bound on the start's set, not every row
                seed_rows(active, m, common.cert["Q"], common.K)
            posed = dict(alpha_hint=start, rows=_posed_rows(active, m), give_up=NONLINEAR_GIVE_UP,
                         prune=_motor_pruner(m, s, say=say) if motor else None, stop_rel=COSTLY_STOP_REL,
                         cuts=active.cuts)
            if trying:  # one solve at the hint, which where it certifies starts the walk (bar: anything certified)
                b, r = _run_invariance(m, s, search, motor, say, retry=False, bar=math.inf, **posed)
            else:
                bar = best.value if best.cert is not None else None
                b, r = _run_invariance(m, s, search, motor, say, retry="cheap" if auto else True, bar=bar,
                                       cheaper_hint=_bound_relaxation(m, s, motor, say, posed["rows"], bar),
                                       prove=lambda m=m, n=layout: prove_no_set(m, s, motor, ALPHA_RANGE, say,
                                                                                 active=active, intervals=n,
                                                                                 halvings=halvings_for(n)),
                                       prove_first=phase1_alone,
                                       screen=lambda a, m=m: screen_at(m, s, motor, a, active, say), **posed)
            active.cuts = tuple(r.cuts) or active.cuts  # (none where phase-1 problems alone settled the bound)
            if trying and b.cert is None:
                say(f"  not certified at the hint: the grid's bounds from {bounds[1]:g} rad")
                continue
            if best.cert is not None and (b.cert is None or b.value >= best.value):
                tried.append((tb, "not better at the best alpha"))
                break
        except InfeasibleError as exc:  # the heading bound is below the slip's own turn
            say(f"  {exc}")
            tried.append((tb, "below the slip's own turn within a period"))
            below = str(exc)
            continue
        # per alpha, its final outcome (after any fallback): failed everywhere is a solver failure, not a proof
        solver_failed = b.cert is None and bool(r.failed_at) and all(r.failed_at.values())
        settled = b.cert is None and r.phase1 is not None and r.phase1.proven
        tried.append((tb, "certified" if b.cert is not None else "infeasible (phase-1)" if settled else
                      ("solver failed" if solver_failed else "infeasible")))
        tried_at[tb] = (len(r.failed_at), sum(r.failed_at.values()))
        phase1_alone = r.phase1_alone  # where the phase-1 problems alone settled this bound, the next asks them first
        if r.phase1 is not None:
            layout = r.phase1.next_layout(layout, len(active.indices))
        if b.cert is not None and b.value < best.value:
            best, runner = b, r
        elif best.cert is not None:  # past the best bound: larger headings cost more
            break
        room = _heading_room(b) if b.cert is not None else None
        if auto and room is not None and room < HEADING_SLACK * tb:
            say(f"  the set's heading within a period, {room:.3g} rad, leaves the bound room: larger bounds only widen "
                "the channels")
            break
    if auto and best.cert is not None:  # a smaller bound, just above the set's own heading
        best, runner = _tighten(model, s, search, motor, say, best, runner, tried, active)
    if best.cert is None:
        r = m = None  # noqa: F841  (the last bound's runner and model released before the remedies: _no_proof)
        _no_proof(model, given, s, motor, say, common, tried, tried_at, auto, below, hint, active, start_solve)
    return best, runner


def _bound_relaxation(m: Any, s: SynthesisConfig, motor: bool, say: Callable[[str], None],
                      rows: frozenset[bytes] | None, bar: float | None, probe: bool = False
                      ) -> Callable[[float | None], Relaxed | None] | None:
    """A heading bound's relaxation (alpha_search's ``cheaper_hint``, asked where a solve is costly and the phase-1
    problems asked first did not settle the range): its LMIs on the vertices with every delay instant at an end of its
    range, searched from the hint, their certificate carried to every vertex where the re-check proves it there
    (:func:`_end_vertices_hint`, the multipliers of the groups outside them found by
    :func:`.extension.extend_multipliers`).  Only where those are at most half the vertices (from d_hi = 2; at d_hi =
    1 two of three delay vertices are ends: little to gain).  Issue 51's robot (Ts 0.05 s, delay 20-140 ms, slip
    [0.8, 1]) at 0.3 rad: its 32 of 108 vertices walked from the hint and carried to all, |e_y| <= 8.96 cm in 15 s,
    where the search of all took about 75 s for 9.07 cm.  ``bar``: past a certified bound, the objective to beat
    (one solve of the subset at the hint where it does not); ``probe``: one solve of the subset at the hint only (a
    remedy's quick try)."""
    if not _ends_at_most_half(m):
        return None
    return lambda h, useless=None: _end_vertices_hint(m, s, motor, say, hint=h, rows=rows, bar=bar, probe=probe,
                                                      persist=False, useless=useless)


def _ends_at_most_half(model: Any) -> bool:
    """Whether ``model`` has vertices with every delay instant at an end of its range and they are at most half of its
    vertices (from d_hi = 2): where a relaxation on them is worth its search."""
    ends = _exact_end_vertices(model)
    return ends is not None and 2 * len(ends) <= len(model.vertices)


def _seed(active: Active, runner: _Runner) -> None:
    """Seed ``active`` (:func:`.phase1.seed`) from the duals of the last solve of the linearized start's ``runner``
    (or of the relaxation it took its certificate from, on a subset of its vertices)."""
    solved, within = runner, None
    if runner.stand_in is not None:
        solved, index = runner.stand_in
        within = (solved.model, index)
    for lp in (solved.active, solved.lp):
        if lp is not None and lp.problem.status in ("optimal", "optimal_inaccurate") and \
                seed(active, runner.model, lp, within=within):
            return


# The linearized start searches its end vertices first (_end_vertices_hint) where a solve is estimated at this or more
# and they are at most half of its vertices (else at COSTLY_SOLVE_S or more, as any search): the default robot at d_hi = 2
# (144 vertices, 64 at the ends, estimated 0.44 s and measured about 0.8 s a solve) scanned all 144 in 14 s.  At d_hi 1
# the end vertices are two thirds of the vertices (the default robot: 32 of 48, estimated 0.03 s), and turns' 8 of 12.
START_RELAX_S = 0.3


def _kinematic(s: SynthesisConfig) -> SynthesisConfig:
    """The settings of the kinematic channels' solves: the configured solver's KINEMATIC_PRIMARY."""
    return s.model_copy(update={"solver": KINEMATIC_PRIMARY.get(s.solver, s.solver)})


def _start(model: Any, s: SynthesisConfig, motor: bool, say: Callable[[str], None], hint: float | None = None
           ) -> tuple[_Best, _Runner, dict[float, float | None]]:
    """The linearized common certificate where a nonlinear search starts (its alpha and heading), the runner of
    its scan, and its least motor bounds per alpha where proven.  With ``hint`` (a remedy's quick try: the main
    search's alpha) a walk from it instead of the scan over the whole range, refined while a step gains COSTLY_GAIN
    (on the issue-51 robot 4-5 solves instead of 14)."""
    lin = model.linearized()
    if model.icr and model.covering_vertices:
        # the icr model's linearized certificate with the covering channels (and the arcs') costs as much as the
        # nonlinear one (48 vertices of 34-40 channels: minutes); its alpha and heading only start the search, which
        # the straight constant-slip one (no channels, seconds) does about as well
        lin = replace(lin, vertices=model.base_vertices, turns=None, covering_vertices=(), channels=_straight_channels(model))
    sc = s.model_copy(update={"lyapunov": "common", "kinematics": "linearized"})
    cheaper_from = START_RELAX_S if _ends_at_most_half(lin) else None
    say(f"the linearized common certificate, where the search starts ({len(lin.vertices)} vertices)")
    least: dict[float, float | None] = {}  # alpha -> the linearized LMIs' least motor bound, where proven
    common, crunner = _run_invariance(lin, sc, [], motor, say, prune=_motor_pruner(lin, sc, least, say=say) if motor else None,
                                      alpha_hint=hint, gain_rule=True if hint is not None else None,
                                      cheaper_hint=lambda h, useless=None: _end_vertices_hint(lin, sc, motor, say, hint=h,
                                                                                              useless=useless),
                                      cheaper_from=cheaper_from)
    return common, crunner, least


def _largest_solved(runner: _Runner) -> float:
    """The estimated time of one solve (:func:`.cost.solve_estimate`) of the largest problem the linearized start
    solved: its own, or where it took a relaxation's certificate, the relaxation's (0 where it solved none).  A
    heuristic for a remedy's quick start, on a model like this one, which mostly solves the same problems: where a
    relaxation's certificate held on every vertex here, a problem built and spared is not counted."""
    return max((r.estimate for r in runner.made_by() if r.solves), default=0.0)


def _end_vertices_hint(lin: Any, sc: SynthesisConfig, motor: bool, say: Callable[[str], None],
                       hint: float | None = None, deeper: bool = True, rows: frozenset[bytes] | None = None,
                       bar: float | None = None, probe: bool = False, persist: bool = True,
                       useless: Callable[[float], bool] | None = None) -> Relaxed | None:
    """Where the linearized start's solves are costly (a long delay's vertices: 432 at d_hi = 3, ~6.5 s a solve), the
    same LMIs on the vertices with every uncertain instant at an end of its range (a relaxation, about a third of them),
    scanned, or walked from ``hint`` (a remedy's start): it costs a fraction of the whole's, and the whole starts from
    its best alpha (one solve where it certifies the same bound there, else a walk; not a scan of twelve), or takes its
    certificate where the numpy re-check proves it on every vertex (:func:`_on_every_vertex`).  Where a solve on those
    is costly too (``deeper``; 256 end vertices at d_hi = 5, ~12 s a solve), they are searched the same way from the
    end vertices with every instant at the same end (:func:`.phase1._same_end_vertices`, 32 there, ~1.3 s a solve),
    and one solve of theirs at that alpha that certifies settles them: the start's alpha need not be their best (there
    8.45 cm at 0.0469 against 8.28 cm at their best, 0.0366; 38 s against 125 s for their scan).  None where there is
    no such subset, or it certified nothing (the vertices are then searched as they would have been).  ``rows``: the
    heading rows its problem starts with (a heading bound's, grown by row generation; None: every row); ``bar`` (with
    ``hint``): the objective to beat, as :func:`.alpha_search._run_invariance`'s: where the subset's solve at the hint
    does not certify below it, nor can the whole's there (a relaxation's objective is at most the whole's), and that
    one solve is all; ``probe`` (with ``hint``): that one solve only, whatever it gives (a remedy's quick try).
    ``persist`` False (a heading bound's relaxation): the subset searched no harder than the heading bound's own search
    (its scan stops after NONLINEAR_GIVE_UP solver failures in a row with nothing certified, and its failed points are
    not solved again): a hint that costs more than the search it helps is none (Ts 0.05 s, d_hi 2: the end vertices'
    scan, 15 failed solves of 4-8 s, then their retries, each on the problem without the mirror by both Clarabels,
    about 36 s a point).  ``useless``: where the problem these vertices relax has no set (its phase-1 problems): their
    certificate there is of no use to it, and no solve is made there."""
    ends = (_exact_end_vertices if deeper else _same_end_vertices)(lin)
    if ends is None:
        return None
    sub = _on_subset(lin, ends)
    how = ("one solve at the hint" if probe else "walk from the hint") if hint is not None else "scan"
    at = "an end" if deeper else "the same end"
    then = ("a solve of all at its best alpha, a walk from there where that does not certify its bound" if deeper else
            f"one solve of the {len(lin.vertices)} at its best alpha, enough for a start where it certifies, a walk "
            "from there where not")
    say(f"  each solve is costly: the {how} on the {len(ends)} vertices with every delay instant at {at} of its "
        f"range first, then its certificate re-checked on every vertex (or {then})")
    inner = lambda m: say("  " + m)  # noqa: E731
    best, runner = _run_invariance(sub, sc, [], motor, inner, alpha_hint=hint, gain_rule=True if hint is not None else None,
                                   cheaper_hint=(lambda h, _u=None: _end_vertices_hint(sub, sc, motor, inner, hint=h,
                                                                                      deeper=False, rows=rows,
                                                                                      persist=persist, useless=useless))
                                   if deeper else None, rows=rows, bar=bar if hint is not None else None,
                                   probe_only=probe and hint is not None, useless=useless,
                                   **({} if persist else {"retry": False, "give_up": NONLINEAR_GIVE_UP}))
    runner.release_compiled()
    if best.cert is None:
        return None
    # where these vertices' search started from a deeper relaxation, its value is no scan's best (settled at that
    # relaxation's alpha, or a walk's from there): this one settles too, with no claim that no alpha does better
    return Relaxed(float(best.cert["alpha"]), best.value, _on_every_vertex(lin, best, runner, ends, sc.solver, say),
                   settle=not deeper or runner.relaxed is not None)


def _on_subset(lin: Any, index: tuple[int, ...]) -> Any:
    """``lin`` on its vertices ``index``, with the within-period vertices (``covering_vertices``) of their groups only:
    a within-period vertex shares the multiplier of its group's vertices (one group per delay vertex, Vertex.group),
    so one whose group the subset lacks could not be re-checked (the linearized turning model at d_hi = 3: every
    certificate of the end vertices' subset was refused for it).  Fewer conditions: still a relaxation."""
    verts = tuple(lin.vertices[i] for i in index)
    groups = {v.group for v in verts}
    cover = tuple(v for v in lin.covering_vertices if v.group < 0 or v.group in groups)
    return replace(lin, vertices=verts, covering_vertices=cover)


def _on_every_vertex(lin: Any, best: _Best, runner: _Runner, ends: tuple[int, ...], solver: str | None = None,
                     say: Callable[[str], None] = lambda _m: None) -> tuple[_Best, tuple] | None:
    """The end vertices' certificate as one of ``lin`` (every vertex), where the numpy re-check proves it there: the
    LMIs at the other vertices (their instants inside their ranges) often hold already (the default robot at d_hi = 3:
    128 of 432 vertices, the re-check in 0.1 s against a 6.5 s solve of all).  Where the vertices carry uncertainty
    channels (the linearized turning model), each group of vertices the subset lacks needs its own multiplier: found
    with ``solver`` by :func:`.extension.extend_multipliers` (without a solver: None).  None where it does not hold.
    With it, the runner that solved (``runner``, or the relaxation ``runner`` took its own certificate from) and the
    indices in ``lin`` of the vertices it solved on."""
    if any(v.n_q for v in lin.vertices):
        Ms = extend_multipliers(lin, best.cert, best.K, ends, solver, say) if solver is not None else None
        if Ms is None:
            return None
    else:
        Ms = [np.zeros((0, 0))] * len(lin.vertices)
    cert = dict(best.cert, vertices=len(lin.vertices), multipliers=dict(best.cert["multipliers"], M=Ms))
    chk = check_certificate(lin, best.K, cert)
    if not chk.passed:
        return None
    if runner.stand_in is not None:  # runner took its certificate from a relaxation of its own: that one solved
        inner, index = runner.stand_in
        return replace(best, cert=cert, check=chk), (inner, tuple(ends[i] for i in index))
    return replace(best, cert=cert, check=chk), (runner, ends)


def _auto_bounds(common: _Best) -> tuple[float, ...]:
    """heading_bound: auto's bounds, upwards from the linearized set's own heading within a period (a smaller bound
    rarely helps: on the default, nonlinear-proof, turns and bench_nonlinear_proof's nine variants the certified bound
    was never below it, and the rungs below cost up to 39 s for a worse bound; the search tightens a certified one
    afterwards, to just above its set's heading)."""
    start = float(common.check.figures.get("heading_within_period", 0.0)) if common.check is not None else 0.0
    return tuple(b for b in HEADING_GRID if b >= start) or HEADING_GRID[-1:]


def _first_try_bound(common: _Best, bounds: tuple[float, ...]) -> float | None:
    """auto's first try below the grid (HEADING_FROM_LINEARIZED times the linearized set's heading within a period,
    rounded up to 1e-3 rad), where it lies at least a tenth below the first of ``bounds``; else None."""
    if common.check is None or common.cert is None:  # (no alpha to try it at)
        return None
    h = float(common.check.figures.get("heading_within_period") or 0.0)
    tb = math.ceil(HEADING_FROM_LINEARIZED * h * 1e3) / 1e3
    return tb if 0.0 < tb <= 0.9 * bounds[0] else None


def _first_try(model: Any, s: SynthesisConfig, motor: bool, hint: float | None = None, active: Active | None = None,
               say: Callable[[str], None] = lambda _m: None, deadline: float = math.inf
               ) -> tuple[dict[str, Any] | None, tuple[float, ...]]:
    """A quick search of the nonlinear certificate (remedies): the linearized start (a walk from ``hint``, the main
    search's alpha: a few solves near it, not the scan), then one solve at its best alpha for each heading bound auto
    would try, upwards: the certified figures of the first that certifies (a bound the full search reaches or improves
    on), or None, and the heading bounds left untried because ``deadline`` (time.perf_counter) had passed (checked
    before each bound but the first).  Where the main search needed phase-1 problems (``active``: the vertices that
    bound them, of a model with as many vertices as this one's), each such solve is first screened by a phase-1 problem
    at that alpha on those vertices, two bounds at a time (:func:`.phase1.screen`, a fraction of the solve's cost on the
    issue-51 robot: 10 of 108 vertices); where its t* <= -T_PROVEN the LMIs there have no set within 1 m, and the solve
    is spared.  From d_hi = 2 that solve is made on the end vertices first (:func:`_bound_relaxation`), and their
    certificate taken where it is carried to every vertex; else the solve of all as before."""
    common, _, _ = _start(model, s, motor, say, hint=hint)
    if common.cert is None:
        return None, ()
    s = _kinematic(s).model_copy(update={"heading_bound": "auto"})
    alpha = float(common.cert["alpha"])
    models = []
    for tb in _auto_bounds(common):
        try:
            models.append((tb, model.with_heading_bound(tb, within_period=s.lyapunov == "common")))
        except InfeasibleError:  # below the slip's own turn within a period
            continue
    usable = active is not None and bool(active.indices) and all(len(m.vertices) == active.vertices for _, m in models)
    if usable and models:
        # the rows the main search ranked are its model's: this one's, from its own start's set
        seed_rows(active, models[0][1], common.cert["Q"], common.K)
    step = PARALLEL if usable else 1
    for k in range(0, len(models), step):
        if k and time.perf_counter() > deadline:
            return None, tuple(tb for tb, _ in models[k:])
        chunk = models[k : k + step]
        ts = screen([m for _, m in chunk], s, motor, alpha, active) if usable else [None] * len(chunk)
        for (tb, m), t in zip(chunk, ts):
            if settles(t):
                say(f"  {tb:g} rad: phase-1 at alpha {alpha:.4g} on {len(active.indices)} vertices, t* = {t:.3g}: no solve")
                continue
            # from d_hi 2 the solve on the end vertices first, its certificate carried to every vertex where it holds
            # (the default at d_hi 2, slip half as wide: ~5 s instead of a 22 s solve of all)
            rows = _posed_rows(active, m)
            relax = _bound_relaxation(m, s, motor, say, rows, None, probe=True)
            got = relax(alpha) if relax is not None else None
            if got is not None and got.whole is not None:
                return dict(got.whole[0].check.figures), ()
            if relax is not None and got is None:
                # the end vertices certified nothing at alpha: where they are infeasible so is the whole (a relaxation),
                # and where their solve failed the whole's most likely fails too, only slower (the default at d_hi 3: 24
                # s on the 128 end vertices, then 113 s on all 432, both solver_error); a quick try's "none" proves
                # nothing, and it moves on to the next bound
                say(f"  {tb:g} rad: the end vertices certified nothing at alpha {alpha:.4g}: no solve of all")
                continue
            b, _ = _run_invariance(m, s, [], motor, say, alpha_hint=alpha, retry=False, probe_only=True, rows=rows)
            if b.cert is not None:
                return dict(b.check.figures), ()
    return None, ()


def _heading_room(best: _Best) -> float:
    """The certified set's largest |e_theta(t)| within a period (its heading rows' figure)."""
    f = best.check.figures
    return float(f.get("heading_within_period") or f["ultimate_bound"]["e_theta"])


def _stop_if_the_start_is_infeasible(model: Any, start: _Runner, least: dict[float, float | None], motor: bool) -> None:
    """Exit 3 at once when the linearized common certificate, where a nonlinear search starts, is proven
    infeasible at every alpha it tried (by the solver, or by a least motor bound above the limit): the nonlinear
    LMIs at any heading bound are these LMIs with the kinematic channels' terms added (S-procedure blocks that
    only tighten them, docs/theory.md §9; the icr start drops vertices, a relaxation too), so none of them has a
    solution at those alphas either (issue 50: a turning synthesis whose bound showed the motors short went on
    for minutes into every heading bound and the fallback solver).  A point where the solver failed proves
    nothing: then the search goes on."""
    if not start.failed_at or any(start.failed_at.values()):
        return
    cfg = model.config
    rho_max = cfg.robot.max_motor_speed
    known = [r for r in least.values() if r is not None and math.isfinite(r)]
    why = (f"with |rho| <= {rho_max:g} rad/s they need at least {min(known):.4g} rad/s" if motor and known
           and min(known) > rho_max else "they are infeasible")
    raise InfeasibleError(
        f"ultimate-bound (nonlinear kinematics): no certificate exists at any of the {len(start.failed_at)} alphas "
        f"tried: already the linearized LMIs with one Lyapunov matrix, which the nonlinear ones contain, have no "
        f"solution there ({why}); the heading bounds were not tried. "
        + (f"Raise robot.max_motor_speed, lower reference.speed{_wider_turns(model)}" if motor and known and min(known) > rho_max
           else f"Narrow network.delay or slip, lower reference.speed{_wider_turns(model)}")
        + ", or use synthesis.lyapunov: slip-dependent (a richer certificate than this bound covers)")


def _straight_channels(model: Any) -> tuple:
    """The constant-slip kinematic channels of a turning model's vertices without their yaw-rate columns (the
    straight segment's heading rows)."""
    return tuple(replace(ch, F_h=None) for ch in model.channels)


def _nonlinear_infeasible(model: Any, common: _Best, tried: list, tried_at: dict[float, tuple[int, int]],
                          auto: bool = True) -> str:
    """The message of exit 3 or 4: which heading bounds failed (at how many alphas: a scan gives up after
    NONLINEAR_GIVE_UP points in a row without a certificate), and the heading and forward-speed ranges of
    the linearized certificate's set, which the kinematic terms grow with.  For a bound set by hand (not
    ``auto``) also where it lies against that set's heading, and that auto searches."""
    def why_at(tb: float, why: str) -> str:
        n, failed = tried_at.get(tb, (0, 0))
        if why == "infeasible (phase-1)":
            return (f"no set with |e_x|, |e_y| <= 1 m at any alpha in [{ALPHA_RANGE[0]:g}, {ALPHA_RANGE[1]:g}]: phase-1 "
                    "problems, where the solver had failed")
        if why == "infeasible" and n:
            return f"infeasible at the {n} alphas tried" if not failed else \
                f"infeasible at {n - failed} of the {n} alphas tried, the solver failed at the others"
        if why == "solver failed" and n:
            return f"the solver failed at the {n} alphas tried"
        return why

    what = ", ".join(f"{tb:g} rad ({why_at(tb, why)})" for tb, why in tried)
    msg = f"synthesis.kinematics: nonlinear: found no invariant set for the nonlinear robot with |e_theta(t)| within {what}"
    if common.cert is not None and common.check is not None:
        from ..certificate import lyapunov_of
        from ..certificate.bounds import sup_on_set
        f = common.check.figures
        S = list(lyapunov_of(model.linearized(), common.cert).S)
        K = np.asarray(common.K)
        uD = np.array([model.V, 0.0])
        speed = 0.0  # the largest forward-speed deviation a on the set, at every slip corner
        for mu in model.corners:
            M = model.slip_matrix(mu)
            speed = max(speed, abs(float(M[0] @ uD) - model.V) + sup_on_set(np.array([M[0] @ K]), S, float(f["ellipsoid_level"])))
        msg += (f". The search's start, a linearized certificate with one Lyapunov matrix (|e_y| <= "
                f"{100 * f['ultimate_bound']['e_y']:.2f} cm; not the gain `synthesize` gives with synthesis.kinematics: "
                "linearized, whose search is its own), has a set that holds headings up to "
                f"{f.get('heading_within_period', f['ultimate_bound']['e_theta']):.3g} rad within a period and forward-speed "
                f"deviations up to {speed:.3g} m/s (V^D = {model.V:g} m/s): on it a sin e_theta alone reaches "
                f"{speed * np.sin(min(f.get('heading_within_period', 0.3), 1.0)):.3g} m/s. Narrow slip, lower "
                "reference.speed, " + _wider_turns(model, sep="") + (", " if getattr(model, "turns", None) is not None else "")
                + "or use synthesis.kinematics: linearized (whose proof is for the linearization)")
        heading = float(f.get("heading_within_period", f["ultimate_bound"]["e_theta"]))
        if not auto and tried:  # review, stop 47: a hand-set bound got only the advice above
            tb = float(tried[0][0])
            # review, stop 47: above the linearized heading the direction is not known (the nonlinear set is
            # usually larger than the linearized one, so a bound just above it may be too small)
            where = (f"below the linearized set's own {heading:.3g} rad, and a set within it rarely exists: raise it"
                     if tb < heading else
                     f"above the linearized set's {heading:.3g} rad; a larger bound widens every channel (like sin), a "
                     "smaller one constrains the set more: try another")
            grid = ", ".join(f"{x:g}" for x in HEADING_GRID)
            msg += (f". synthesis.heading_bound {tb:g} rad is {where}, or set it to auto, which tries {grid} rad "
                    "upwards from that heading")
    else:  # review, stop 47: a turning config too tight even for the linearized set ended without any remedy
        msg += (". The linearized common certificate, where the search starts, gave none either: narrow slip, lower "
                "reference.speed" + _wider_turns(model))
    if model.covering and model.config.synthesis.lyapunov == "common":
        msg += (". These channels cover slip changing at any time within a period; with synthesis.lyapunov "
                "slip-dependent (or delay-, path-dependent) they assume it constant within each period, which costs "
                "less and is stated with the certificate (docs/theory.md §9)")
    return msg
