"""The alpha line search of the invariance LMIs (:func:`_run_invariance`): a log grid scanned upwards, or a
walk from a cheaper certificate's alpha, then parabolic steps (a golden section where no parabola fits);
and the least motor bound per alpha, which proves a motor-limited scan's points infeasible before they are
retried (:func:`_motor_pruner`)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..config import SynthesisConfig
from .lmis import build_invariance
from .phase1 import Phase1, settles
from .cost import solve_estimate
from .runner import _attempts, _Best, _build, _cert_common, _duration, _Runner, _weights, lmi_count, lmi_rows
from .solve import RETRY, Outcome, SolveRecord, solve
from .solver_process import trim_heap


ALPHA_RANGE = (0.005, 0.95)  # line search range of alpha (log-spaced grid, then parabolic steps)


@dataclass(frozen=True)
class Relaxed:
    """What a relaxation of a costly problem gave (:func:`_run_invariance`'s ``cheaper_hint``: the same LMIs on a subset
    of its vertices, searched first): its best alpha and objective (at most the problem's at every alpha); ``whole``:
    its certificate where the numpy re-check proves it on every vertex of the problem, with the relaxation's runner and
    its vertices' indices (else None); ``settle``: a certified solve of the problem at that alpha ends the search, with
    no comparison with ``value`` (a search's start, which needs no finer alpha; where the relaxation's own search was
    settled or walked from a deeper one, ``value`` is no best over alpha)."""

    alpha: float
    value: float
    whole: tuple[_Best, tuple] | None = None
    settle: bool = False


GOLDEN_STEPS = 10  # a golden section where a parabola cannot be fitted (an infeasible neighbour)


GOLDEN_MIN_BRACKET = 0.02  # ... down to a bracket this narrow in log alpha


# the alpha search stops when a step moves the objective by less than this (relative; the objective is a
# weighted sum of squared bounds, so a bound moves by half of it).  1e-4 let the unweighted e_x of
# configs/heavy-slip.yaml drift by 0.9 % along the flat valley; 1e-5 keeps every figure within 0.1 %
HINT_STOP_REL = 1e-5


def _golden(evaluate: Callable[[float], float], a: float, b: float, rel: float = HINT_STOP_REL) -> None:
    """Golden-section search of ``evaluate`` (log alpha) on [a, b]; it stops once the
    two inner points agree to ``rel`` (the bound then moves by less than that)."""
    phi = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - phi * (b - a), a + phi * (b - a)
    fc, fd = evaluate(c), evaluate(d)
    for _ in range(GOLDEN_STEPS):
        if math.isfinite(fc) and math.isfinite(fd) and abs(fc - fd) <= rel * min(fc, fd):
            return
        if b - a < GOLDEN_MIN_BRACKET:  # alpha known to 2 %: where solves keep failing near a flat minimum (the icr
            return  # model's nonlinear certificates), ten more of them would not move the bound
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - phi * (b - a)
            fc = evaluate(c)
        else:
            a, c, fc = c, d, fd
            d = a + phi * (b - a)
            fd = evaluate(d)


REFINE_STEPS = 4  # parabolic steps after the walk, at most


WALK_STEP = 0.25  # the hinted walk's step, in grid steps of log alpha


# the stop tolerance of the searches whose solves take seconds (the kinematic channels, docs/theory.md §9): the
# objective is a weighted sum of squared bounds, so 2e-3 is a bound within 0.1 % of the best along alpha; the default
# robot's bound is flat there (2.35 / 2.34 / 2.34 cm at alpha 0.149 / 0.145 / 0.141), and each solve of 1e-5's
# refinement cost about 5 s of a 60 s synthesis for the last 0.01 cm
COSTLY_STOP_REL = 2e-3
# where the walk from the hint has those seconds-long solves (stop_rel COSTLY_STOP_REL), a step that lowers the
# objective by less than this fraction ends it, without the parabolic steps, where the parabola through it and the two
# points before it on the line predicts less than this fraction more too: each further point costs a solve.  The
# default robot's walk at 0.1 rad: 0.1632 / 0.1486 / 0.1353 (|e_y| 2.37 / 2.35 / 2.34 cm), a step of 0.38 % and 0.05 %
# predicted; 0.1232, which it spares, was worse: one solve (~2 s) fewer, the same alpha and gain.  turns alike (0.193 /
# 0.176 / 0.160: 0.67 % and 0.12 %, then 0.146 worse); its step before, 3.6 % with 0.02 % predicted, goes on, where the
# parabola alone would have stopped 0.67 % short.  nonlinear-proof's last step gains 1.4 %: it walks as before
WALK_FLAT = 1e-2


def _parabolic(evaluate: Callable[[float], float], pts: list[tuple[float, float]], predict: bool = False,
               rel: float = HINT_STOP_REL) -> None:
    """Successive parabolic interpolation of ``evaluate`` (log alpha) from bracketing points: near its
    minimum the objective is smooth in log alpha, so the vertex of the parabola through the best point
    and its two neighbours lands on it in a step or two (a golden section needs ten).  Stops when a
    step no longer improves the objective by ``rel`` (HINT_STOP_REL), or when the best point has no finite
    neighbour on a side (then a golden section on its bracket).  With ``predict`` (a bracket a few
    quarter grid steps wide, where the parabola is accurate) it also stops *before* a step whose
    predicted gain is below ``rel``; on the wide bracket of the full scan that prediction let an
    unweighted figure drift by ~1 % along the flat valley (configs/heavy-slip.yaml's e_x)."""
    pts = sorted(pts)
    for _ in range(REFINE_STEPS):
        i = int(np.argmin([f for _, f in pts]))
        if i == 0 or i == len(pts) - 1:  # the minimum sits at an end of the points: no parabola
            if len(pts) > 1:  # between it and its neighbour, as the golden section always did
                j = 1 if i == 0 else len(pts) - 2
                if math.isfinite(pts[j][1]):
                    _golden(evaluate, min(pts[i][0], pts[j][0]), max(pts[i][0], pts[j][0]), rel)
            return
        (x1, f1), (x2, f2), (x3, f3) = pts[i - 1], pts[i], pts[i + 1]
        if not (math.isfinite(f1) and math.isfinite(f3)):
            _golden(evaluate, x1, x3, rel)
            return
        num = (x2 - x1) ** 2 * (f2 - f3) - (x2 - x3) ** 2 * (f2 - f1)
        den = (x2 - x1) * (f2 - f3) - (x2 - x3) * (f2 - f1)
        if den == 0.0:
            return
        x = x2 - 0.5 * num / den
        # the parabola's value at its vertex: a step that cannot gain the tolerance is not taken
        a = ((f3 - f2) / (x3 - x2) - (f2 - f1) / (x2 - x1)) / (x3 - x1)
        if predict and a > 0 and a * (x - x2) ** 2 <= rel * f2:
            return
        # stay strictly inside the bracket, away from the points already solved
        gap = 0.05 * (x3 - x1)
        x = min(max(x, x1 + gap), x3 - gap)
        if min(abs(x - x1), abs(x - x2), abs(x - x3)) < 1e-3 * (x3 - x1):
            return
        f = evaluate(x)
        pts = sorted(pts + [(x, f)])
        if math.isfinite(f) and abs(f2 - f) <= rel * f2:
            return  # the parabola's vertex and the best point agree: the minimum is found to the tolerance


# The refinement of a costly problem stops sooner (issue 51).  Where one solve is estimated at COSTLY_SOLVE_S or more
# (cost.solve_estimate, from the problem's structure: the same on any machine, under any load), the parabolic and
# golden steps after the scan or the walk stop once a step improved the best objective by less than COSTLY_GAIN
# (relative; the objective is a weighted sum of squared bounds, so a bound moves by about half of it: 0.5 %).  On the
# icr default with Ts 0.1 s and tau in [0.02, 0.29] s (d_hi 3, 432 vertices, ~6 s a solve, estimated 5 s) the
# linearized start spent four steps for 3.69 -> 3.66 cm, the last three within 0.01 cm.  No problem of configs/ is
# estimated at COSTLY_SOLVE_S (their largest: 0.99 s, the default's nonlinear ones; docs/theory/06-lmis.md §6j), so
# their refinement, and every committed baseline, is as it was.
COSTLY_SOLVE_S = 3.0  # [s] estimated, one solve


COSTLY_GAIN = 1e-2  # the least relative gain of the objective per refinement step of a costly problem
# Where one solve is estimated at PROVE_FIRST_S or more (cost.solve_estimate), the phase-1 problems go before it: a
# few problems on the vertices that bind (seeded by the linearized start, docs/theory/06-lmis.md §6j) cost less than
# that one solve, and on the large problems where they settle the range the solve would most likely have failed.
# On the icr default with tau in [0.02, 0.29] s (d_hi 3, estimated about 2 min) the first heading bound's solve ended
# in solver_error after 124 s, then its phase-1 problems settled it in 50 s.  No problem of configs/ comes near.
PROVE_FIRST_S = 60.0  # [s] estimated, one solve


class _Enough(Exception):
    """A costly problem's refinement step gained less than COSTLY_GAIN: the refinement stops."""


def _refine(evaluate: Callable[[float], float], pts: list[tuple[float, float]], best: _Best, costly: bool,
            say: Callable[[str], None], **kwargs: Any) -> None:
    """:func:`_parabolic` from ``pts``; where ``costly``, each of its steps must lower ``best`` by COSTLY_GAIN of it,
    else the refinement stops there."""
    if not costly:
        _parabolic(evaluate, pts, **kwargs)
        return

    def step(x: float) -> float:
        before = best.value
        f = evaluate(x)
        if not before - best.value > COSTLY_GAIN * before:
            raise _Enough
        return f

    try:
        _parabolic(step, pts, **kwargs)
    except _Enough:
        say(f"  refined enough: the last step gained less than {100 * COSTLY_GAIN:g} % of the objective")


def _walk(evaluate: Callable[[float], float], x0: float, step: float, lo: float, hi: float,
          rel: float = 0.0, flat: float = 0.0) -> tuple[list[tuple[float, float]], bool]:
    """From x0 (log alpha), one ``step`` at a time in each direction while the objective falls (by more than
    the fraction ``rel``): the points evaluated, which bracket the minimum near x0, and False.  With ``flat``, a step
    that lowers the objective by less than the fraction ``flat`` ends the walk at once where the parabola through it and
    the two points before it on the line (x0's other neighbour first) is convex and its vertex lies less than that
    fraction below it too: the points evaluated and True (the refinement would gain less than that, WALK_FLAT)."""
    pts = [(x0, evaluate(x0))]
    if not math.isfinite(pts[0][1]):
        return pts, False
    for direction in (1.0, -1.0):
        x, f = pts[0]
        line = pts[1::-1] if direction < 0 else pts[:1]  # on the way down, x0's upper neighbour (pts[1]) first
        while True:
            xn = x + direction * step
            if xn < lo - 1e-12 or xn > hi + 1e-12:
                break
            fn = evaluate(xn)
            pts.append((xn, fn))
            line.append((xn, fn))
            if flat and f * (1.0 - flat) <= fn < f and len(line) >= 3 and math.isfinite(line[-3][1]):
                f0, f1, f2 = (v for _, v in line[-3:])
                curv = f0 - 2.0 * f1 + f2
                if curv > 0 and (f2 - f0) ** 2 / (8.0 * curv) - (f1 - f2) < flat * f2:
                    return sorted(pts), True
            if not fn < f * (1.0 - rel):
                break
            x, f = xn, fn
    return sorted(pts), False


def _invariance_builder(s: SynthesisConfig, motor: bool, symmetry: bool) -> Callable[..., Any]:
    """The invariance LMIs of a model (and heading rows), as the runner builds them again for a grown problem."""
    return lambda mdl, rows=None: build_invariance(mdl, s.multiplier, s.margin, _weights(s), motor, s.lyapunov,
                                                   symmetry=symmetry, heading_rows=rows)


def _run_invariance(model: Any, s: SynthesisConfig, search: list, motor: bool,
                    say: Callable[[str], None] = lambda _m: None,
                    alpha_hint: float | None = None, retry: bool | str = True, probe_only: bool = False,
                    give_up: int | None = None,
                    prune: Callable[[list[float]], set[float]] | None = None,
                    stop_rel: float = HINT_STOP_REL, bar: float | None = None,
                    prove: Callable[[], Phase1] | None = None, prove_first: bool = False,
                    gain_rule: bool | None = None, cheaper_hint: Callable[[float | None, Callable[[float], bool]], Relaxed | None] | None = None,
                    rows: frozenset[bytes] | None = None, screen: Callable[[float], bool] | None = None,
                    cuts: tuple[int, ...] = (), cheaper_from: float | None = None,
                    useless: Callable[[float], bool] | None = None) -> tuple[_Best, _Runner]:
    """The alpha line search of the invariance LMIs.  Without a hint: a log grid of alpha_points
    scanned upwards, then parabolic steps around its best point.  With ``alpha_hint`` (the best alpha
    of a cheaper certificate class): walk from the hint in quarter grid steps while the bound falls,
    then parabolic steps in that bracket, stopped once they no longer move the bound (the full scan
    when the hint is not feasible for this class).  ``retry``: when nothing was certified, the scan's failed
    points again, with the fallback chain (True), only the same solver unscaled ('cheap'), or not (False).
    ``prune``: given the scan's alphas that were not
    certified, before the failed ones are retried with the fallback solver, returns those proven
    infeasible otherwise (they are not retried).  ``stop_rel``: the refinement's stop tolerance on the objective
    (COSTLY_STOP_REL where each solve takes seconds; the hinted walk then also stops at smaller gains).  ``bar``
    (with a hint): the objective to beat; when the hint's own solve does not certify below it, the search ends
    there (one solve: is this class worth a search?), else it walks on from the hint (that solve counted).
    ``prove``: phase-1 problems over the whole alpha range (:func:`.phase1.prove_no_set`), asked where the solver
    failed: at the hint (before the full scan, which it then spares when they settle the range) or in a scan that
    certified nothing (before the retries of its failed points); where they settle it, the failed points count as
    infeasible.  Also where the hint's walk ended infeasible and each solve is costly (COSTLY_SOLVE_S): before the
    descent and the scan, which they then spare.  ``prove_first``:
    asked before any solve (a related problem's solves all failed: the hint's would most likely fail too); so they
    are too where one solve is estimated at PROVE_FIRST_S or more.
    ``gain_rule``: the refinement stops at a step that gains less than COSTLY_GAIN (:func:`_refine`): by default where a
    solve is estimated at COSTLY_SOLVE_S or more; True: always (a remedy's quick try).  ``cheaper_hint``: where a
    solve is estimated at COSTLY_SOLVE_S or more (or at ``cheaper_from`` where that is less), given the hint (or
    None), what a relaxation of these LMIs (a subset of the vertices, searched from the hint or scanned: cheaper) gave
    (:class:`Relaxed`; None: the hint or the scan as without it), asked after the phase-1 problems asked before any
    solve (``screen``, ``prove_first``: where they settle the range, no relaxation): its best alpha is walked from instead.  A relaxation's objective is at most this problem's at every
    alpha, so where the solve at its best alpha reaches its best objective (within COSTLY_STOP_REL) no alpha does better
    here, to that search's own tolerance: the search ends there; where its very certificate holds here, without that
    solve; where it settles the search (a start), at that solve once it certifies.
    ``rows``: the heading rows the problem starts with (keys; None: every row), grown by row generation (_Runner);
    ``cuts`` the within-period vertices (Model.with_cuts).  ``screen``: given the hint, whether a phase-1 problem at
    that alpha shows no set there (:func:`_asked_first`).  ``useless`` (a relaxation's search): where a certificate of
    this problem is of no use to the problem it relaxes (no set there: its phase-1 problems); no solve there."""
    w = _weights(s)
    best = _Best()

    def make_cert(vals: dict) -> dict:
        c = _cert_common(model, vals, s.multiplier, s.margin, "ultimate-bound")
        c["alpha"] = float(runner.lp.params["alpha"].value)
        c["beta"] = vals["beta"]
        c["motor_limits_enforced"] = motor
        return c

    build = _invariance_builder(s, motor, s.symmetry == "auto")  # (mirror-invariant where the model allows)
    runner = _Runner(model, None, s.solver, make_cert, full=_invariance_builder(s, motor, False), rows=rows, grown=build)
    # asked to prove first (the last bound's phase-1 problems alone settled it): the problem is built only where they
    # do not settle this one (on the default robot at d_hi = 5 its build took the main process from 0.92 to 1.41 GB,
    # and each later bound's is never solved)
    if prove is not None and prove_first and not probe_only and \
            _settled_by_phase1(runner, prove, search, say, why="failed before"):
        return best, runner
    lp = _build(build, model, rows=rows)
    runner.attach(lp, cuts)
    evaluate = _Evaluator(lp, runner, best, w, search, say, useless=useless)
    est = runner.estimate = 0.0 if probe_only else solve_estimate(lp)
    if screen is not None and est >= COSTLY_SOLVE_S and not probe_only:
        # before each costly solve, each alpha screened once (the hint's too: its screen is asked below)
        screen = evaluate.screen = _once(screen)
    costly = est >= COSTLY_SOLVE_S if gain_rule is None else gain_rule
    if not probe_only:
        say(f"  {lmi_count(lp)} LMIs (the largest {lmi_rows(lp)} rows) per alpha; each point is one solve"
            + (f" (about {_duration(est)} each, estimated from its size)" if est >= 1.0 else "") + ", a failed one is retried")
    elif alpha_hint is not None:  # (no estimate: its patterns take seconds on the largest problems, a probe one solve)
        say(f"  one solve at alpha = {alpha_hint:.4g}: {lmi_count(lp)} LMIs (the largest {lmi_rows(lp)} rows)")
    grid = np.linspace(math.log(ALPHA_RANGE[0]), math.log(ALPHA_RANGE[1]), s.alpha_points)
    # the phase-1 problems where they are asked before any solve (they may settle the range: no relaxation then)
    if not probe_only and _asked_first(runner, prove, screen, est, alpha_hint, bar, search, say):
        return best, runner
    relax_from = COSTLY_SOLVE_S if cheaper_from is None else min(COSTLY_SOLVE_S, cheaper_from)
    if cheaper_hint is not None and est >= relax_from and not probe_only:
        relaxed = runner.relaxed = cheaper_hint(alpha_hint, evaluate.useless_for_whole)
        if relaxed is not None:
            alpha_hint = relaxed.alpha
            ended = _ended_by_relaxation(relaxed, runner, evaluate, best, bar, say)
            if ended is not None:
                return ended, runner
    if probe_only and alpha_hint is not None:  # one solve at the hint (is this class worth a search?)
        evaluate(math.log(alpha_hint))
        return best, runner
    if bar is not None and alpha_hint is not None and not evaluate(math.log(alpha_hint)) < bar:
        return best, runner  # not better at the hint: no search (the walk below would start with this solve)
    if alpha_hint is not None and _from_hint(evaluate, runner, best, grid, alpha_hint, stop_rel, costly, give_up,
                                             prove, search, say):
        return best, runner
    vals, gave_up = _scan(evaluate, grid, give_up, say)
    if best.cert is None and prove is not None and runner.phase1 is None and any(runner.failed_at.values()) and \
            _settled_by_phase1(runner, prove, search, say):
        return best, runner  # (before the retries of the failed points: they would settle nothing the proof does not)
    if retry == "cheap" and runner.primary not in RETRY:  # no cheap retry for this solver
        retry = False
    if best.cert is None and retry:
        _retry_failed(evaluate, grid, vals, retry, prune)
        if gave_up and evaluate.cheap_concluded:
            # the give-up cut the scan where only the primary solver was failing: the unscaled retry concludes
            # there, so the rest of the grid goes to it directly (an exit 3 then rests on every alpha of the scan;
            # a certificate found by the retries is refined from the whole grid)
            say(f"  the retries concluded: the rest of the scan with {RETRY[runner.primary]}")
            _scan_unscaled(evaluate, grid, vals)
    if best.cert is None:
        return best, runner
    on_grid = set(grid)
    # the retried points off the grid (the hint's) where they certified: the parabolic steps start from them too
    extra = [(g, v) for g, v in evaluate.cache.items() if g not in on_grid and math.isfinite(v)]
    # refined by the solver that certified: the unscaled one where the primary failed at every point it tried
    unscaled = best.record is not None and best.record.name == RETRY.get(runner.primary)
    _refine(lambda x: evaluate(x, unscaled_only=unscaled), sorted([(float(g), v) for g, v in zip(grid, vals)] + extra),
            best, costly, say, rel=stop_rel)
    return best, runner


def _ended_by_relaxation(relaxed: Relaxed, runner: _Runner, evaluate: "_Evaluator", best: _Best, bar: float | None,
                         say: Callable[[str], None]) -> _Best | None:
    """_run_invariance after its relaxation (``cheaper_hint``): the search's result where that ends it, else None (the
    walk from the relaxation's alpha follows).  Its certificate holds on every vertex: this problem's optimum, where
    the relaxation's was its own.  Past a certified bound (``bar``) that it does not beat at the hint: nor can this
    problem there (a relaxation's objective is at most this one's).  Else one solve at its alpha, which where the
    relaxation settled (a start) and it certifies is enough, and where it certifies the relaxation's bound no alpha
    does better."""
    if relaxed.whole is not None:
        say("  its certificate holds on every vertex (the numpy re-check): no solve of all")
        runner.stand_in = relaxed.whole[1]
        return relaxed.whole[0]
    if bar is not None and relaxed.value >= bar:
        say("  the relaxation is not better at the hint: nor is this problem there (no solve of all)")
        return best
    at = evaluate(math.log(relaxed.alpha))
    if relaxed.settle and math.isfinite(at):
        say("  certified at the relaxation's alpha: enough (each solve is costly; no walk to a finer alpha)")
        return best
    if at <= relaxed.value * (1.0 + COSTLY_STOP_REL):
        say("  its best alpha certifies the relaxation's bound here too: no alpha does better")
        return best
    return None


def _asked_first(runner: _Runner, prove: Callable[[], Phase1] | None, screen: Callable[[float], bool] | None,
                 est: float, alpha_hint: float | None, bar: float | None, search: list, say: Callable[[str], None]
                 ) -> bool:
    """_run_invariance's phase-1 problems before any solve, where one is costly (``est``, its estimate): where it is
    estimated at PROVE_FIRST_S or more, or at COSTLY_SOLVE_S or more and ``screen`` (given the hint: whether a phase-1
    problem at that alpha on a subset of the vertices shows no set there, :func:`.phase1.screen_at`) shows no set at
    the hint, whose solve would then certify nothing (on such problems it most often fails: the default robot at
    d_hi = 2, 19 s for solver_error).  True where the search ends here: they settled the range, or (past a certified
    bound, ``bar``) the screen shows that the hint cannot beat it, as its solve would have."""
    if prove is None or runner.phase1 is not None:
        return False
    if est >= PROVE_FIRST_S:
        return _settled_by_phase1(runner, prove, search, say, why="costly")
    if screen is None or est < COSTLY_SOLVE_S or alpha_hint is None or not screen(alpha_hint):
        return False
    if bar is not None:  # no set at the hint: it does not beat the bar there, and the search ends as it would
        say("  no set at the hint: not better there (no solve)")
        return True
    return _settled_by_phase1(runner, prove, search, say, why="screened")


def _from_hint(evaluate: "_Evaluator", runner: _Runner, best: _Best, grid: np.ndarray, alpha_hint: float,
               stop_rel: float, costly: bool, give_up: int | None, prove: Callable[[], Phase1] | None, search: list,
               say: Callable[[str], None]) -> bool:
    """_run_invariance's walk from a hint: True where it ended the search (a certificate refined, or the range settled
    by phase-1 problems), False where the hint is not feasible for this class and the full scan follows."""
    lo, hi = float(grid[0]), float(grid[-1])
    # quarter grid steps: the richer classes' best alpha lies within a step or two of the common
    # certificate's (measured on the default robot: 0.219 -> 0.218 / 0.228 / 0.231), and a tight
    # bracket makes the parabola exact enough to stop after one or two solves
    pts, flat = _walk(evaluate, min(max(math.log(alpha_hint), lo), hi), WALK_STEP * float(grid[1] - grid[0]), lo,
                      hi, rel=0.0 if stop_rel == HINT_STOP_REL else stop_rel,
                      flat=WALK_FLAT if stop_rel == COSTLY_STOP_REL else 0.0)
    if best.cert is not None:
        if flat:
            say(f"  flat here: the last step gained less than {100 * WALK_FLAT:g} % of the objective")
        else:
            _refine(evaluate, pts, best, costly, say, predict=True, rel=stop_rel)
        return True
    if prove is not None and runner.phase1 is None and runner.last_kind == "failed" and \
            _settled_by_phase1(runner, prove, search, say):
        return True
    if prove is not None and runner.phase1 is None and runner.last_kind == "infeasible" and costly and \
            _settled_by_phase1(runner, prove, search, say, why="infeasible"):
        return True  # (the walk, the descent and the scan would each cost a costly solve per point)
    if runner.last_kind == "infeasible":  # the feasible interval lies off the hint: below it first
        pts = _descend(evaluate, grid, math.log(alpha_hint), give_up)
        if pts is not None:
            say("  refined below the hint")
            _refine(evaluate, pts, best, costly, say, rel=stop_rel)
            return True
    say("  the hint is not feasible for this class: full scan")
    return False


def _descend(evaluate: "_Evaluator", grid: np.ndarray, hint: float, give_up: int | None
             ) -> list[tuple[float, float]] | None:
    """The grid's points below an infeasible hint (log alpha), downwards, until past the minimum (a certified point
    above the one before it) or the end of the feasible interval (one not certified after one that was), or
    ``give_up`` solver failures in a row with nothing certified: the points evaluated with the hint's, or None
    where none certified (the full scan then finds these in its cache).  On configs/nonlinear-proof.yaml with
    integral action (0.3 rad) the feasible alphas lie at 0.03-0.12, below the linearized start's 0.127: the
    scan from the grid's bottom solved 12 points there."""
    pts = [(hint, evaluate(hint))]
    failures = 0
    for g in sorted((float(x) for x in grid if x < hint - 1e-12), reverse=True):
        v = evaluate(g)
        pts.append((g, v))
        certified = [f for _, f in pts if math.isfinite(f)]
        if certified:
            if not math.isfinite(v) or (len(certified) >= 2 and certified[-1] > certified[-2]):
                break
        else:
            failures = failures + 1 if evaluate.runner.failed_at.get(float(np.exp(g)), False) else 0
            if give_up is not None and failures >= give_up:
                break
    return sorted(pts) if any(math.isfinite(f) for _, f in pts) else None


_WHY_PHASE1 = {  # why the phase-1 problems are asked, as the progress line says it
    "failed": "the solver failed here: phase-1 problems over the alpha range",
    "failed before": "phase-1 problems alone settled the last heading bound (no solve of it concluded): phase-1 "
                     "problems over the alpha range first",
    "infeasible": "infeasible at the hint, and each solve is costly: phase-1 problems over the alpha range before the "
                  "scan",
    "costly": f"each solve is estimated at {PROVE_FIRST_S:g} s or more: phase-1 problems over the alpha range first",
    "screened": f"each solve is estimated at {COSTLY_SOLVE_S:g} s or more, and a phase-1 problem at the hint on the "
                "vertices that bind shows no set there: phase-1 problems over the alpha range first",
}


def _settled_by_phase1(runner: _Runner, prove: Callable[[], Phase1], search: list, say: Callable[[str], None],
                       why: str = "failed") -> bool:
    """Ask the phase-1 problems (``prove``); where they settle the alpha range, the runner's failed points count
    as infeasible (so an exit says 3, with the evidence, not 4).  Whether they did.  ``why`` (_WHY_PHASE1): the
    solver failed here, or at the last heading bound (asked first), or the hint's walk ended infeasible where each
    solve is costly (a few phase-1 problems, most on the vertices that bind, instead of a solve per alpha of the
    descent and the scan)."""
    say(f"  {_WHY_PHASE1[why]} (docs/theory.md §6j)")
    runner.release_compiled()  # the phase-1 problems take their own memory; this problem is compiled again if need be
    proof = prove()
    trim_heap()  # and what theirs held, once they are gone
    runner.phase1 = proof
    say(f"  {proof.summary()}")
    for a, b, t, n, status in proof.intervals:
        search.append({"alpha_interval": [a, b], "status": "infeasible" if settles(t) else "failed",
                       "objective": None, "by": f"phase-1 ({n} vertices)", "t": t})
    if not proof.proven:  # its settled intervals still show no set: the failed points there count as infeasible
        shown = [a for a, failed in runner.failed_at.items() if failed and runner.settled_at(a) is not None]
        for a in shown:
            runner.failed_at[a] = False
        runner.failures -= len(shown)
        return False
    runner.phase1_alone = all(runner.failed_at.values())  # no solve of this problem concluded (or none was made)
    flipped = [a for a, failed in runner.failed_at.items() if failed]
    for a in flipped:
        runner.failed_at[a] = False
    runner.failures -= len(flipped)
    return True


class _Evaluator:
    """The search's objective at one log alpha: one solve of the invariance LMIs there, the weighted sum of the
    squared certified bounds (inf where nothing is certified), kept in ``cache``; the best point in ``best``,
    one entry in ``search`` and one line to ``say`` per solve.  ``last``: the outcome of the latest solve;
    ``position``: where the scan stands, for the lines; ``cheap_concluded``: a retry by the unscaled primary
    concluded (set by :func:`_retry_failed`)."""

    def __init__(self, lp: Any, runner: _Runner, best: _Best, w: np.ndarray, search: list,
                 say: Callable[[str], None], useless: Callable[[float], bool] | None = None) -> None:
        self.lp, self.runner, self.best, self.w, self.search, self.say = lp, runner, best, w, search, say
        self.cache: dict[float, float] = {}
        self.screen: Callable[[float], bool] | None = None  # a phase-1 problem at one alpha, asked before a costly solve
        self.useless = useless  # a relaxation's: where the problem it relaxes has no set
        self.last: Outcome | None = None
        self.position = ""
        self.cheap_concluded = False

    def __call__(self, log_a: float, fallback: bool = False, cheap: bool = False, unscaled_only: bool = False) -> float:
        # The scan uses the primary solver only: a point it cannot solve costs a slow fallback
        # and rarely matters once its neighbours are solved.  Only when no point at all was
        # certified are the failed ones retried (below): fallback, the whole chain; cheap, the
        # primary solver unscaled only; either way not the primary again where it failed on this problem.
        lp, best, w = self.lp, self.best, self.w
        if log_a in self.cache and not (fallback or cheap):
            return self.cache[log_a]
        a = float(np.exp(log_a))
        shown = self.runner.settled_at(a)
        if shown is not None:  # the phase-1 problems show no set here: no solve (Ts 0.05 s, d_hi 2: 4 of a scan's 5)
            lo, hi, t, n = shown
            return self._no_set(log_a, a, f"the phase-1 problem on [{lo:.4g}, {hi:.4g}], t* = {t:.3g}", f"phase-1 ({n} vertices)")
        if self.no_set_here(a):
            # where the phase-1 problems over the range did not settle it, each costly solve is screened first: a phase-1
            # problem at this very alpha has no interval's slack (Ts 0.05 s, d_hi 2 at 0.1 rad: the scan's points failed
            # after 14-20 s each, their retries after about 110 s each)
            return self._no_set(log_a, a, "the phase-1 problem at this alpha", "phase-1 at this alpha")
        if self.useless is not None and self.useless(a):  # a relaxation, at an alpha where the whole has no set
            return self._no_set(log_a, a, "for the problem this one relaxes, shown by its phase-1 problems", "of no use")
        lp.params["alpha"].value = a
        lp.params["one_minus_alpha"].value = 1.0 - a
        out, cert, K, chk = self.runner.run(fallback=fallback, retry=fallback or cheap, again=fallback or cheap,
                                            unscaled_only=unscaled_only)
        self.last = out
        val = math.inf
        if out.kind == "ok":
            ub = chk.figures["ultimate_bound"]
            val = float(w[0] * ub["e_x"] ** 2 + w[1] * ub["e_y"] ** 2 + w[2] * ub["e_theta"] ** 2)
            if val < best.value:
                best.value, best.cert, best.K, best.check, best.record = val, cert, K, chk, out.record
        self.search.append({"alpha": a, "status": out.kind, "objective": None if math.isinf(val) else val})
        what = (f"certified, |e_y| <= {100 * chk.figures['ultimate_bound']['e_y']:.2f} cm" if out.kind == "ok" else out.kind)
        self.say(f"  alpha = {a:.4g}{self.position}: {what} ({_attempts(out)}); best so far "
                 + (f"|e_y| <= {100 * best.check.figures['ultimate_bound']['e_y']:.2f} cm" if best.check is not None else "none"))
        self.cache[log_a] = val
        return val

    def no_set_here(self, a: float) -> bool:
        """Whether the phase-1 problem at ``a`` (``screen``) shows no set of this problem there, asked only where the
        phase-1 problems over the range left it unsettled."""
        ph = self.runner.phase1
        return self.screen is not None and ph is not None and not ph.proven and self.screen(a)

    def useless_for_whole(self, a: float) -> bool:
        """For a relaxation of this problem: whether a certificate of it at ``a`` is of no use here (no set of this
        problem at ``a``: a settled phase-1 interval, or the screen)."""
        return self.runner.settled_at(a) is not None or self.no_set_here(a)

    def _no_set(self, log_a: float, a: float, why: str, by: str) -> float:
        """A point where phase-1 problems show no set (:meth:`_Runner.settled_at`, the screen at that alpha, or, for a
        relaxation, the whole's): not solved, and not certified."""
        self.last = Outcome("infeasible", SolveRecord("phase-1", "infeasible", None, 0.0))
        self.runner.last_kind = "infeasible"
        self.runner.failed_at[a] = False
        self.search.append({"alpha": a, "status": "infeasible", "objective": None, "by": by})
        self.say(f"  alpha = {a:.4g}{self.position}: no set ({why}): no solve")
        self.cache[log_a] = math.inf
        return math.inf


def _once(screen: Callable[[float], bool]) -> Callable[[float], bool]:
    """``screen`` asked at most once per alpha (a phase-1 problem each)."""
    seen: dict[float, bool] = {}

    def ask(a: float) -> bool:
        if a not in seen:
            seen[a] = screen(a)
        return seen[a]

    return ask


def _scan(evaluate: _Evaluator, grid: np.ndarray, give_up: int | None, say: Callable[[str], None]
          ) -> tuple[list[float], bool]:
    """The grid scanned upwards until past the minimum or the end of the feasible interval, or until ``give_up``
    solver failures in a row with nothing certified: the objective at each point scanned, and whether it gave up."""
    runner, best = evaluate.runner, evaluate.best
    vals: list[float] = []
    failures = 0  # solver failures in a row, with nothing certified yet
    gave_up = False
    t_scan = time.perf_counter()
    for i, g in enumerate(grid):
        left = ""
        if i:  # what the rest of the grid costs at most, at the mean time per point so far
            per = (time.perf_counter() - t_scan) / i
            left = f", at most ~{_duration(per * (len(grid) - i))} left in this scan"
        evaluate.position = f" (point {i + 1} of at most {len(grid)}{left})"
        vals.append(evaluate(float(g)))
        evaluate.position = ""
        failures = failures + 1 if best.cert is None and runner.failed_at.get(float(np.exp(g)), False) else 0
        if give_up is not None and failures >= give_up:
            gave_up = True
            # a problem on which every solve fails is usually one that has no solution near it (the kinematic
            # channels at a large heading bound: delay-multi-period spent 16 solves of 19 s each, 5 min)
            say(f"  {failures} solver failures in a row and nothing certified: the scan stops here")
            break
        # Scan upwards; stop once past the minimum (two rises in a row) or at the end of the
        # feasible interval (an infeasible point after a success): the points beyond cost solver
        # time and cannot improve the bound.  A solver *failure* is not the end of the interval (a
        # sweep found one at alpha = 0.007 cut a scan whose minimum lay near 0.15, a bound 13x too
        # large): the scan goes on, and stops only after two failures in a row.
        if len(vals) >= 3 and math.isfinite(vals[-3]) and vals[-1] > vals[-2] > vals[-3]:
            break
        if any(math.isfinite(v) for v in vals[:-1]) and not math.isfinite(vals[-1]):
            failed_last = runner.failed_at.get(float(np.exp(g)), False)
            if not failed_last or (len(vals) >= 2 and not math.isfinite(vals[-2])):
                break
    return vals, gave_up


def _retry_failed(evaluate: _Evaluator, grid: np.ndarray, vals: list[float], retry: bool | str,
                  prune: Callable[[list[float]], set[float]] | None) -> None:
    """Nothing was certified: the points where the solver failed (the scan's and the hint's) solved again, with
    the fallback chain (``retry`` True) or the primary unscaled ('cheap'), less those ``prune`` proves
    infeasible; ``vals`` takes the retried grid points' objectives."""
    runner = evaluate.runner
    grid_points = list(grid)
    on_grid = set(grid_points)
    failed = [g for g, v in zip(grid, vals) if not math.isfinite(v) and runner.failed_at.get(float(np.exp(g)))]
    # the hint's point too, where it failed
    failed = sorted(failed + [g for g in evaluate.cache if g not in on_grid and runner.failed_at.get(float(np.exp(g)))])
    if prune is not None and failed and retry is True:  # told every alpha of the scan that was not certified
        proven = prune([float(np.exp(g)) for g, v in zip(grid, vals) if not math.isfinite(v)])
        for a in (float(np.exp(g)) for g in failed):  # proven infeasible otherwise: no solver failure any more
            if a in proven:
                evaluate.search.append({"alpha": a, "status": "infeasible", "objective": None, "by": "least motor bound"})
                runner.failed_at[a] = False
                runner.failures -= 1  # (the exit-3 texts tell "infeasible" from "solver failed" by these counts)
        failed = [g for g in failed if float(np.exp(g)) not in proven]
    tried: list[float] = []
    for g in failed:
        tried.append(evaluate(float(g), fallback=retry is True, cheap=True))
        # the unscaled retry itself concluded somewhere (not the fallback after it)
        evaluate.cheap_concluded = evaluate.cheap_concluded or (evaluate.last.kind != "failed"
                                                                and evaluate.last.record.name == RETRY.get(runner.primary))
        if g in on_grid:
            vals[grid_points.index(g)] = tried[-1]
        # the scan's stopping rules on the retried points: past the minimum (two rises in a row), or
        # three failures in a row after a success (one more than the scan allows: a retry that fails,
        # fails, then certifies further up was seen in a constructed case) -- Ts = 1e-3 had spent 10
        # fallback solves of 5 s each past its minimum
        if len(tried) >= 3 and math.isfinite(tried[-3]) and tried[-1] > tried[-2] > tried[-3]:
            break
        if len(tried) >= 4 and any(map(math.isfinite, tried[:-3])) and not any(map(math.isfinite, tried[-3:])):
            break


def _scan_unscaled(evaluate: _Evaluator, grid: np.ndarray, vals: list[float]) -> None:
    """The rest of the grid, beyond the points in ``vals``, scanned by the primary solver unscaled (appended to
    ``vals``), with the scan's stopping rules."""
    for g in grid[len(vals):]:
        vals.append(evaluate(float(g), unscaled_only=True))
        if len(vals) >= 3 and math.isfinite(vals[-3]) and vals[-1] > vals[-2] > vals[-3]:
            break  # past the minimum (the scan's rule)
        if any(math.isfinite(v) for v in vals[:-1]) and not math.isfinite(vals[-1]):
            break  # the end of the feasible interval


LEAST_MOTOR_TOL = 1e-4  # relative: a least motor bound this far above the limit proves the limited LMIs infeasible


# the same for a bound the solver returned 'optimal_inaccurate' (its reduced tolerances: gap 5e-5, residuals 1e-4)
LEAST_MOTOR_TOL_INACCURATE = 1e-2


def _least_kind(status: str, solver: str) -> str | None:
    """What a least-motor solve's status is worth: 'proven' (optimal, or infeasible), 'inaccurate' (Clarabel's
    reduced tolerances: usable far from the limit), or None.  An inaccurate SCS point is its iteration cap's best
    guess with no tolerance behind it (a review found such bounds 40 % below Clarabel's optimal ones)."""
    if status in ("optimal", "infeasible"):
        return "proven"
    return "inaccurate" if status == "optimal_inaccurate" and solver.startswith("clarabel") else None


def _least_motor_speeds(model: Any, s: SynthesisConfig, alphas: list[float],
                        say: Callable[[str], None]) -> dict[float, tuple[float | None, bool]]:
    """The least |rho| bound the invariance LMIs allow at each alpha: every LMI of the limited problem,
    with the motor LMIs' bound u^2 (docs/theory.md §6c) a variable that is minimized; |rho| = the
    feedforward's speed + u.  These are the limited problem's constraints (without the mirror reduction
    and the within-period vertices added by constraint generation, so a relaxation), so where the least
    bound exceeds robot.max_motor_speed the limited problem is infeasible at that alpha.  Per alpha:
    (the bound, inf where the LMIs are infeasible whatever the motors, None where nothing came back;
    proven: the solver ended 'optimal' or 'infeasible'; an unproven bound is Clarabel's 'optimal_inaccurate')."""
    import cvxpy as cp

    lp = _build(build_invariance, model, s.multiplier, s.margin, _weights(s), True, s.lyapunov, symmetry=False,
                least_motor=True)
    out: dict[float, tuple[float | None, bool]] = {}
    for a in alphas:
        lp.params["alpha"].value = a
        lp.params["one_minus_alpha"].value = 1.0 - a
        status = solve(lp.problem, s.solver, lambda: True, fallback=False).record.status
        u2 = lp.extra["u2"].value
        r: float | None = None
        if status == cp.INFEASIBLE:  # no invariant set at this alpha, whatever the motors
            r = math.inf
        elif status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) and u2 is not None:
            r = float(model.feedforward_motor_speed + math.sqrt(max(float(u2), 0.0)))
        kind = _least_kind(status, s.solver)
        out[a] = (r if kind else None, kind == "proven")
        what = "unknown" if r is None else ("none (infeasible)" if math.isinf(r) else f"{r:.4g} rad/s")
        say(f"  alpha = {a:.4g}: the least motor bound of these LMIs is {what} ({s.solver} {status})")
    return out


def _motor_pruner(model: Any, s: SynthesisConfig, least: dict[float, float | None] | None = None,
                  say: Callable[[str], None] = lambda _m: None) -> Callable[[list[float]], set[float]]:
    """``_run_invariance``'s prune hook for a motor-limited scan: before the slow fallback retries, the alphas
    where even the least motor bound of these LMIs exceeds the limit (the limited problem is infeasible there;
    a turning model's fallback solves took 8 minutes).  Fills ``least`` (alpha -> bound where proven, else None)."""
    rho_max = model.config.robot.max_motor_speed
    least = {} if least is None else least

    def prune(alphas: list[float]) -> set[float]:
        found = _least_motor_speeds(model, s, alphas, say)
        least.update({a: r if proven else None for a, (r, proven) in found.items()})
        # an 'optimal_inaccurate' bound (the solver's reduced tolerances, ~1e-4) counts only far above the limit
        return {a for a, (r, proven) in found.items()
                if r is not None and r > rho_max * (1.0 + (LEAST_MOTOR_TOL if proven else LEAST_MOTOR_TOL_INACCURATE))}

    return prune
