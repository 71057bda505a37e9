"""Infeasibility where the solver fails (issue 51): the invariance LMIs as phase-1 problems over intervals of alpha.

On the robot proof's larger problems (three command intervals in a period, wide slip boxes) Clarabel often ends
in a numerical error instead of 'infeasible': the problem has no solution, its infeasibility certificate forms,
and the residuals stall (docs/theory.md §9, §6j).  A phase-1 problem always has a solution: maximize t with every
vertex LMI >= t I and the set's position extents bounded, X_00, X_11 <= kappa (:func:`~.lmis.build_invariance`
with ``phase1``).  Its maximum t* < 0 says that the LMIs have no solution whose set keeps |e_x|, |e_y| <= sqrt(kappa).  With the parameters of an
interval [alpha_lo, alpha_hi] of the line search (``1 - alpha_lo`` before X, ``sum beta <= alpha_hi``) the problem
relaxes the LMIs of every alpha in it, so a few such problems cover the whole search range, not only its grid.
A subset of the vertices is a relaxation too: the vertices that bound the last problems go first (before any, those
that bind the linearized certificate where the search starts, :func:`seed`); an interval they do not settle is
halved, and a half they still do not settle is solved on them with the delay vertex that binds most at every slip
corner, then on the vertices with every uncertain instant at an end of its range (no triangle's tangent point), then
with all of them.  Where the model has the mirror symmetry, each subset is taken with its vertices' mirror images and
posed mirror-invariant (:func:`_mirror_closure`): still a relaxation, and several times cheaper to solve.

Said plainly: t* is the solver's optimum (Clarabel at its tolerances, 'optimal' or 'optimal_inaccurate'), not a
certificate re-checked in numpy; an interval counts only with t* <= -T_PROVEN.
"""

from __future__ import annotations

import gc
import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from . import lmis
from .lmis import build_invariance
from .solve import solve, solve_all
from .solver_process import trim_heap

__all__ = ["Phase1", "Active", "prove_no_set", "screen", "screen_at", "seed", "seed_rows", "settles", "PHASE1_BOX", "T_PROVEN",
           "INTERVALS", "HALVINGS", "halvings_for"]

# X_00, X_11 <= PHASE1_BOX [m^2]: the set {xi' X^-1 xi <= 1} keeps |e_x|, |e_y| <= 1 m (the other states are bounded
# by the heading and motor rows already); a set larger than that is of no use on a path of metre-scale segments
PHASE1_BOX = 1.0
T_PROVEN = 1e-7  # an interval counts as proven only with t* <= -T_PROVEN (far beyond the solver's 1e-9 tolerances)
INTERVALS = 8  # log-spaced intervals over the alpha range, each halved where it does not settle
# how many times an interval is halved before it is solved with every vertex: the default robot at d_hi = 2 leaves
# [0.036, 0.050] unsettled at 0.2 rad after one halving (t* +1.3e-5, the relaxation over the interval's alphas),
# while the single alphas 0.042 and 0.045 have t* -7e-5
HALVINGS = 2
# An interval the active vertices leave unsettled is halved before it is tried on the base (the end vertices), which
# only the intervals halved HALVINGS times meet: two problems on 10 vertices cost a fraction of one on the base, and
# the narrower relaxation is what settles most.  The default robot at d_hi = 2 (icr box, delay max 0.19 s; the active
# set seeded by the linearized start, measured side by side against the base before each halving): 0.2 rad settled
# in 94 s instead of 169 s, 0.3 rad in 88 s instead of 154 s (15 and 14 phase-1 problems against 14 and 13; the
# base's 64-vertex problems took ~45 s each)
PARALLEL = 2  # intervals solved at once, each on its own copy of the problem (this machine's two cores)
# a bound whose intervals all settled at once on the active vertices, every t* at or below -COARSEN_T, has the next
# bound's range cut into half as many intervals (at least PARALLEL; each with one halving more, so the finest is as
# fine): a wider interval's relaxation is looser, and far from any set it settles all the same.  The icr default at
# d_hi = 3 (every bound's t* -1.4e-5 to -8.4e-5): 0.5 and 0.7 rad settled on 2 intervals in 6 s each against 20 s on 8,
# the seven bounds in 91 s against 140 s; at d_hi = 2, bounds nearer a set (t* -5.7e-7 at 0.2 rad) go back to 8
COARSEN_T = 2e-5


def halvings_for(intervals: int) -> int:
    """The halvings that leave the finest interval of a range cut into ``intervals`` as fine as INTERVALS with HALVINGS
    of them."""
    return HALVINGS + max(0, round(math.log2(INTERVALS / intervals)))


def settles(t: float | None) -> bool:
    """Whether a phase-1 maximum t* (None: the solver failed) shows its interval has no set: t* <= -T_PROVEN."""
    return t is not None and t <= -T_PROVEN


@dataclass
class Phase1:
    """What the phase-1 problems showed over [alpha_lo, alpha_hi]: per interval (lo, hi, t*, vertices used, status);
    ``proven``: every interval has t* <= -T_PROVEN."""

    alpha_lo: float
    alpha_hi: float
    intervals: list[tuple[float, float, float | None, int, str]] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def proven(self) -> bool:
        return bool(self.intervals) and all(settles(t) for _, _, t, _, _ in self.intervals)

    def settled_at(self, alpha: float) -> tuple[float, float, float, int] | None:
        """The interval (lo, hi, t*, vertices) that shows no set at ``alpha`` (t* <= -T_PROVEN: every LMI of its
        relaxation has no solution there, so neither has the problem, which holds them all), or None."""
        for lo, hi, t, n, _ in self.intervals:
            if lo <= alpha <= hi and settles(t):
                return float(lo), float(hi), float(t), int(n)
        return None

    def next_layout(self, intervals: int, active: int) -> int:
        """How many intervals the next heading bound's range is cut into, after this proof over ``intervals`` of them
        (``active``: how many vertices the active set holds): half as many (at least PARALLEL) where every one settled
        at once on the active vertices with t* <= -COARSEN_T; as many where all settled unhalved; else twice as many
        (at most INTERVALS)."""
        unhalved = self.proven and len(self.intervals) == intervals
        if unhalved and all(t <= -COARSEN_T and n <= active for _, _, t, n, _ in self.intervals):
            return max(PARALLEL, intervals // 2)
        return intervals if unhalved else min(INTERVALS, 2 * intervals)

    def summary(self) -> str:
        if not self.proven:
            return f"phase-1 over [{self.alpha_lo:.3g}, {self.alpha_hi:.3g}]: not settled ({self._unsettled()})"
        worst = max(float(t) for _, _, t, _, _ in self.intervals)
        return (f"no set with |e_x|, |e_y| <= {math.sqrt(PHASE1_BOX):g} m at any alpha in [{self.alpha_lo:.3g}, {self.alpha_hi:.3g}] "
                f"({len(self.intervals)} phase-1 problems, largest t* {worst:.3g}, {self.seconds:.0f} s)")

    def _unsettled(self) -> str:
        bad = [(a, b, t) for a, b, t, _, _ in self.intervals if not settles(t)]
        return ", ".join(f"[{a:.3g}, {b:.3g}]: " + ("the solver failed" if t is None else f"t* {t:.3g}") for a, b, t in bad)


def _exact_end_vertices(model: Any) -> tuple[int, ...] | None:
    """The indices of the vertices whose uncertain instants all sit at an end of their range, or None when that is
    every vertex (or none)."""
    keep = tuple(i for i, v in enumerate(model.vertices) if not v.tangent)
    if not keep or len(keep) == len(model.vertices):
        return None
    return keep


def _same_end_vertices(model: Any) -> tuple[int, ...] | None:
    """The indices of the end vertices (:func:`_exact_end_vertices`) whose uncertain instants all sit at the same end
    of their ranges: every h_j at its least, or every one at its largest (the delay's constant extremes; 32 of the 256
    end vertices of the default robot at d_hi = 5).  None where the vertices carry no instants (``Vertex.instants``),
    or that is every end vertex (or none).  The relaxation the linearized start of a long delay is scanned on first
    (heading_search._end_vertices_hint): any subset of the vertices is a relaxation, so this choice bears on the
    time a search takes, never on what it proves."""
    ends = tuple(i for i, v in enumerate(model.vertices) if not v.tangent)
    if not ends:
        return None
    H = [model.vertices[i].instants for i in ends]
    if not H[0] or any(len(h) != len(H[0]) for h in H):
        return None
    H = np.asarray(H, dtype=float)
    lo, hi = H.min(axis=0), H.max(axis=0)
    tol = 1e-9 * max(float(np.abs(H).max()), 1e-300)
    varies = hi - lo > tol
    at_lo = np.all(np.abs(H - lo)[:, varies] <= tol, axis=1)
    at_hi = np.all(np.abs(H - hi)[:, varies] <= tol, axis=1)
    keep = tuple(ends[k] for k in np.flatnonzero(at_lo | at_hi))
    return keep if varies.any() and 0 < len(keep) < len(ends) else None


@dataclass
class Active:
    """The vertices (indices into the model's) whose LMIs bound the last phase-1 problems: those with the largest
    dual weight (the trace of the LMI's dual matrix), at most ACTIVE.  Carried from one interval to the next and from
    one heading bound to the next (the same vertex order), they are tried first: a subset of the vertices is a
    relaxation, so a t* < 0 on them is a proof, and a problem on a few vertices is solved in a fraction of the time."""

    indices: tuple[int, ...] = ()
    vertices: int = 0  # how many vertices the models had whose indices these are (a model of another count: none apply)
    # the heading rows that bound the last problems posed in the lifted form (their keys, lmis.heading_row_key): the
    # first try on the active vertices poses only these, a further relaxation (None: every row)
    rows: tuple[bytes, ...] | None = None  # (in rank order: a run does not depend on the hash seed)
    # the vertices that bind the certificate where the search starts (:func:`seed`), of a model with ``vertices``
    # vertices: the first phase-1 problems begin with them when no phase-1 problem has ranked any yet
    seed: tuple[int, ...] = ()
    # the within-period vertices the last solved problem of the search held (constraint generation, runner._Runner.cuts:
    # indices into the family of Model.with_cuts, the same at every heading bound): the next bound's problem poses them
    # from its first solve, a relaxation like any other choice of them
    cuts: tuple[int, ...] = ()

    def row_set(self) -> frozenset[bytes] | None:
        return frozenset(self.rows) if self.rows is not None else None


# the vertices kept in the active set: on the d_hi = 3 user robot of issue 51 (32 end vertices, alpha in [0.069, 0.133])
# the 8 with the largest duals gave t* = -3.8e-5 against -4.4e-5 on all 32, in 2.8 s against 6.5 s; 4 gave +1.3e-5
ACTIVE = 10
DUAL_FLOOR = 1e-3  # a vertex whose dual weight is below this fraction of the largest does not bind: not kept
# the heading rows kept in the active set (those whose linear row's dual is at least DUAL_FLOOR of the largest, at
# most this many): on the icr default at d_hi = 3 (60 281 rows) a 10-vertex phase-1 problem at 0.15 rad took 13.2 s
# with every row and 5.0 s with 2 000 of them drawn at random, t* -3.745e-5 and -3.743e-5 (without any: +4.2e-3);
# two rows bind there, and the phase-1 search at 0.1, 0.15 and 0.2 rad took 203, 31 and 27 s against 281, 105 and
# 89 s with every row, every t* the same to 1e-10 (measured side by side, the active set carried across the bounds)
ACTIVE_ROWS = 500
# rounds of row generation in prove_no_set's every-row tries (_every_row); an interval they do not conclude stays unsettled
# where the rows are generated (beyond lmis.GENERATE_ROWS), and is solved with every row at once where they are fewer
ROW_ROUNDS = 8
EVERY = frozenset({b"every heading row"})  # settle's marker: the interval with every heading row (run_all_rows)


def _accept(lp: Any) -> Callable[[], bool]:
    return lambda: lp.extra["t"].value is not None and math.isfinite(float(lp.extra["t"].value))


def _t_stars(lps: list[Any], intervals: list[tuple[float, float]], solver: str) -> list[tuple[float | None, str]]:
    """t* of each interval, on its own copy of the problem (``lps``, one per interval), solved at once
    (:func:`~.solve.solve_all`: two copies on two cores take the time of one); a copy whose solver failed is solved
    again with the other Clarabel (its retry)."""
    for lp, (lo, hi) in zip(lps, intervals):
        lp.params["one_minus_alpha"].value = 1.0 - lo
        lp.params["alpha"].value = hi
    outs = solve_all([lp.problem for lp in lps], solver, [_accept(lp) for lp in lps])
    res = []
    for lp, out in zip(lps, outs):
        if out.kind != "ok":
            out = solve(lp.problem, solver, _accept(lp), fallback=False, retry=True, skip_first=True)
        res.append((float(lp.extra["t"].value), out.record.status) if out.kind == "ok" else (None, out.record.status))
    return res


def _every_row(model: Any, active: Active, idx: tuple[int, ...], ivs: list[tuple[float, float]],
               run: Callable[..., Any], latest: dict[str, Any], say: Callable[[str], None]
               ) -> list[tuple[float | None, str]]:
    """prove_no_set's t* of ``ivs`` on the vertices ``idx`` with every heading row (``run`` its solve of intervals on
    a vertex subset and heading rows, ``latest`` the last run's problems by interval): by row generation where the rows
    are posed as linear rows (more than LIFT_ROWS) and some are ranked (:func:`seed_rows`, :func:`_rank_rows`): the
    active rows first, or the last run's solutions where it posed them on these vertices; an interval left unsettled
    whose solution breaks rows not posed is solved again with the worst of them added, :func:`lmis.rows_broken`, until
    its solution holds every row, whose t* is then the one of every row.  Every row posed at once where they are few.
    Where the rows are many they are never all posed at once (2.2 million at d_hi = 5: 3.9 GB of coefficients): an
    interval whose solve failed, or whose rounds (ROW_ROUNDS) did not conclude, stays unsettled.  Between LIFT_ROWS
    and lmis.GENERATE_ROWS rows (the default robot at d_hi = 2: 2 601) an unsettled interval's solution on the active
    rows most often holds every row already (its t* is then the one of every row, with no solve more): there, an
    interval whose solve on a subset failed, whose values say nothing (:func:`lmis.rows_broken` None) or whose rounds
    did not conclude is solved with every row at once."""
    rows = active.row_set() if active.rows is not None and lmis.lifts_rows(model) else None
    if rows is None:
        return run(idx, ivs)
    known = latest["by"] if latest["key"] == (idx, rows) else {}
    fresh = [iv for iv in ivs if iv not in known]
    if fresh:
        run(idx, fresh, rows)
    solved = {iv: known.get(iv) or latest["by"][iv] for iv in ivs}  # (its problem, its t* and status)
    lps, out = {iv: s[0] for iv, s in solved.items()}, {iv: s[1] for iv, s in solved.items()}
    todo, whole = list(ivs), []  # whole: the intervals to solve with every row at once (where the rows are few)
    for _ in range(ROW_ROUNDS):
        new: set[bytes] = set()
        again = []
        for iv in todo:
            t, _ = out[iv]
            # (a failed solve, or values that say nothing, stay as they are: unsettled, no proof claimed)
            broken = lmis.rows_broken(model, lps[iv], rows) if t is not None and not settles(t) else None
            if broken:
                new.update(broken)
                again.append(iv)
            elif t is None or (broken is None and not settles(t)):  # failed, or its values say nothing
                whole.append(iv)
        if not again:
            todo = []
            break
        rows = rows | new
        say(f"  {len(new)} heading rows not posed break the solution: posed too")
        out.update(zip(again, run(idx, again, rows)))
        lps.update({iv: latest["by"][iv][0] for iv in again})
        todo = again
    whole += [iv for iv in todo if not settles(out[iv][0])]  # (rounds that did not conclude; a settled one is a proof)
    if whole and not lmis.generates_rows(model):  # few enough to pose at once
        out.update(zip(whole, run(idx, whole)))
    return [out[iv] for iv in ivs]  # (where the rows are many, rounds that did not conclude leave their intervals unsettled)


COMPLETE = ("the active vertices completed",)  # settle's marker: the step _completion resolves


def _completion(model: Any, active: tuple[int, ...], solved: list[tuple[Any, tuple[float | None, str]]],
                base: tuple[int, ...]) -> tuple[int, ...] | None:
    """The active vertices (indices of ``model``'s) with the base vertices whose delay vertex (``Vertex.instants``) is
    that of the active vertex with the largest dual weight in the problems ``solved`` (on the active vertices: each with
    its (t*, status); one whose solve failed keeps an earlier solve's duals, and is passed over): that delay vertex at
    every slip corner.  None where the vertices carry no instants, no dual ranks them, the completion adds no vertex
    (the top vertex a tangent one, or its delay vertex's end vertices active already), or it would hold as many
    vertices as the base.  A subset of the vertices is a relaxation, so this choice
    bears on the time a proof takes, never on what it proves.  On the default robot at d_hi = 2 (0.2 rad, alpha in
    [0.0358, 0.0496]) the 10 active vertices left t* +4.1e-6 and +1.5e-6; 16 more, one delay vertex at the 16 slip
    corners, gave -3.31e-5 and -2.78e-5 in 11 s, as the 64 end vertices do in 32 s (two intervals at once)."""
    weights = [0.0] * len(active)
    for lp, (t, _) in solved:
        if t is None:
            continue
        w = _vertex_weights(lp)
        if len(w) == len(active):
            weights = [max(a, b) for a, b in zip(weights, w)]
    if not any(x > 0 for x in weights):
        return None
    top = active[max(range(len(active)), key=lambda k: (weights[k], -k))]
    h = model.vertices[top].instants
    if not h:
        return None
    same = {i for i in base if model.vertices[i].instants == h}
    out = tuple(sorted(set(active) | same))
    return out if len(out) < len(base) and len(out) > len(active) else None


def prove_no_set(model: Any, s: Any, motor: bool, alpha_range: tuple[float, float],
                 say: Callable[[str], None] = lambda _m: None, intervals: int = INTERVALS,
                 active: Active | None = None, halvings: int = HALVINGS) -> Phase1:
    """Phase-1 problems of the invariance LMIs of ``model`` (settings ``s``: multiplier, weights, Lyapunov kind,
    solver) over ``intervals`` log-spaced intervals of ``alpha_range``, PARALLEL at a time.  Each interval is tried on
    the vertices of ``active`` first (those that bound the last problems, :class:`Active`; updated here); an interval
    they leave unsettled is halved (``halvings`` times over); a half still unsettled is tried on the active vertices
    completed by the delay vertex that binds them most at every slip corner (:func:`_completion`), then on the vertices
    with their instants at the ends of their ranges, then with every vertex.  Stops at the first interval left
    unsettled (no proof can come out any more)."""
    t0 = time.perf_counter()
    lo, hi = alpha_range
    edges = np.exp(np.linspace(math.log(lo), math.log(hi), intervals + 1))
    w = np.array([s.weights.e_x, s.weights.e_y, s.weights.e_theta])
    active = active if active is not None else Active()
    n_all = len(model.vertices)
    if not active.indices and active.seed and active.vertices == n_all:
        active.indices = active.seed
    active.vertices = n_all
    ends = _exact_end_vertices(model)
    # per vertex subset and heading rows, its compiled copies (one per interval at once)
    copies: dict[tuple[tuple[int, ...], frozenset[bytes] | None], list[Any]] = {}
    result = Phase1(float(lo), float(hi))
    closed = _mirror_closure(model, s)  # every vertex subset with its mirror images, posed mirror-invariant

    def build(idx: tuple[int, ...], rows: frozenset[bytes] | None) -> Any:
        idx, mirror = closed(idx)
        m = model if len(idx) == n_all else replace(model, vertices=tuple(model.vertices[i] for i in idx))
        return build_invariance(m, s.multiplier, s.margin, w, motor, s.lyapunov, symmetry=mirror is not None,
                                mirror=mirror, phase1=PHASE1_BOX, heading_rows=rows)

    # the last run's problems, by interval (their values are that solve's until their copies are solved again)
    latest: dict[str, Any] = {"key": None, "by": {}}

    def run(idx: tuple[int, ...], ivs: list[tuple[float, float]],
            rows: frozenset[bytes] | None = None) -> list[tuple[float | None, str]]:
        idx = closed(idx)[0]
        have = copies.setdefault((idx, rows), [])
        while len(have) < len(ivs):
            have.append(build(idx, rows))
        ts = _t_stars(have[: len(ivs)], ivs, s.solver)
        posed = len(have[0].extra.get("heading_keys", ()))
        for (a, b), (t, status) in zip(ivs, ts):
            say(f"  phase-1 on alpha in [{a:.4g}, {b:.4g}] ({len(idx)} vertices"
                + (f", {posed} heading rows" if rows is not None else "") + "): "
                + ("the solver failed" if t is None else f"t* = {t:.3g}") + f" ({status})")
        _rank(active, idx, have[: len(ivs)], ts)
        latest.update(key=(idx, rows), by=dict(zip(ivs, zip(have, ts))))
        return ts

    def run_all_rows(idx: tuple[int, ...], ivs: list[tuple[float, float]]) -> list[tuple[float | None, str]]:
        return _every_row(model, active, idx, ivs, run, latest, say)

    everyone = tuple(range(n_all))
    base = closed(ends)[0] if ends is not None else everyone  # the vertices an interval is settled on before the halving

    def settle(ivs: list[tuple[float, float]], depth: int) -> bool:
        """Settle ``ivs`` (PARALLEL at a time): on the active vertices, then (at ``depth`` 0, or with no active
        vertices) on their completion (:func:`_completion`) and on ``base``; an interval still unsettled is halved
        (``depth`` > 0), else solved on every vertex.  False at the first interval left unsettled."""
        for k in range(0, len(ivs), PARALLEL):
            chunk = ivs[k : k + PARALLEL]
            last: dict[tuple[float, float], tuple[float | None, str, int] | None] = {iv: None for iv in chunk}
            own = closed(active.indices)[0] if active.indices else ()
            first = [own] if own and len(own) < len(base) else []
            # the active vertices with only the active heading rows first, then with every row, then the base: only
            # where the interval is halved no more, or where no vertex is active yet (see HALVINGS).  Every row on the
            # active vertices only there too, where the active rows go first: in 52 such retries of an unsettled
            # interval (the default robot at d_hi = 2 and 3) none settled it, every t* the same, while each one on
            # every row costs what a few on the active rows do (at d_hi = 3 ~20 s and ~400 MB a copy)
            tries = [(first[0], active.row_set())] if first and active.rows is not None else []
            every = first if depth == 0 or not tries else []
            # before the base, the active vertices with the delay vertex that binds them most at every slip corner
            # (_completion: resolved once the active vertices' problems are solved, from their duals)
            complete = [COMPLETE] if depth == 0 and first else []
            wider = [base] if depth == 0 or not first else []
            for idx, rows in tries + [(idx, EVERY) for idx in every + complete + wider]:
                todo = [iv for iv in chunk if last[iv] is None or not settles(last[iv][0])]
                if todo and idx is COMPLETE:
                    on_active = latest["key"] is not None and latest["key"][0] == first[0]  # the last run's vertices
                    idx = _completion(model, first[0], [latest["by"][iv] for iv in todo if on_active and iv in latest["by"]],
                                      base)
                    if idx is None:
                        continue
                got = (run_all_rows(idx, todo) if rows is EVERY else run(idx, todo, rows)) if todo else []
                for iv, (t, status) in zip(todo, got):
                    last[iv] = (t, status, len(idx))
            for iv in chunk:
                t, status, n = last[iv]
                if not settles(t) and depth > 0:
                    a, b = iv
                    mid = math.sqrt(a * b)
                    if not settle([(a, mid), (mid, b)], depth - 1):
                        return False
                    continue
                if not settles(t) and base != everyone:
                    (t, status), = run_all_rows(everyone, [iv])
                    n = n_all
                result.intervals.append((iv[0], iv[1], t, n, status))
                if not settles(t):
                    return False
        return True

    settle([(float(a), float(b)) for a, b in zip(edges[:-1], edges[1:])], halvings)
    # the copies and their compiled data go back to the system now, not when the collector next finds their cycles: on
    # the icr default at d_hi = 3 the first bound's left 470 MB in the process (240 MB in cycles, 230 MB in the heap)
    copies.clear()
    gc.collect()
    trim_heap()
    result.seconds = time.perf_counter() - t0
    return result


def screen(models: list[Any], s: Any, motor: bool, alpha: float, active: Active) -> list[float | None]:
    """The phase-1 problem at the single alpha ``alpha`` (the interval [alpha, alpha]) of each of ``models`` (one per
    heading bound, each with ``active.vertices`` vertices in the order of those that ranked them), on the vertices of
    ``active`` only, PARALLEL at a time: t* per model (None where the solver failed).  A subset of the vertices is a
    relaxation, so a t* <= -T_PROVEN says that the model's LMIs at ``alpha`` have no set with |e_x|, |e_y| <=
    sqrt(PHASE1_BOX): a solve of them there would certify nothing of use (the remedies' quick tries then spare it,
    :func:`~.heading_search._first_try`).  ``active`` is updated from the duals, as by :func:`prove_no_set`."""
    w = np.array([s.weights.e_x, s.weights.e_y, s.weights.e_theta])
    out: list[float | None] = []
    for k in range(0, len(models), PARALLEL):
        posed = [(m,) + _mirror_closure(m, s)(active.indices) for m in models[k : k + PARALLEL]]
        lps = [build_invariance(replace(m, vertices=tuple(m.vertices[i] for i in idx)), s.multiplier, s.margin, w, motor,
                                s.lyapunov, symmetry=mirror is not None, mirror=mirror, phase1=PHASE1_BOX,
                                heading_rows=active.row_set())
               for m, idx, mirror in posed]
        ts = _t_stars(lps, [(alpha, alpha)] * len(lps), s.solver)
        for idx in dict.fromkeys(idx for _, idx, _ in posed):  # (one ranking where every model posed the same vertices)
            _rank(active, idx, [lp for (_, i, _), lp in zip(posed, lps) if i == idx],
                  [t for (_, i, _), t in zip(posed, ts) if i == idx])
        out += [t for t, _ in ts]
    return out


def screen_at(model: Any, s: Any, motor: bool, alpha: float, active: Active, say: Callable[[str], None]) -> bool:
    """Whether the phase-1 problem of ``model`` at the single alpha ``alpha`` on the vertices of ``active`` (those that
    bound the last phase-1 problems, or before any, those that bind the start: :func:`seed`) shows no set there
    (:func:`screen`, t* <= -T_PROVEN).  False where no vertex of a model like this one is known, or where the rows are
    generated and none is ranked yet (the screen would pose every one).  Never a proof by itself: it only decides
    whether the phase-1 problems over the range go before a costly solve."""
    if active.vertices != len(model.vertices) or not (active.indices or active.seed):
        return False
    if active.rows is None and lmis.generates_rows(model):  # it would pose every row (2.2 million at d_hi = 5)
        return False
    if not active.indices:
        active.indices = active.seed
    n = len(active.indices)  # (screen ranks them anew)
    t = screen([model], s, motor, alpha, active)[0]
    trim_heap()  # what its problem held goes back before the problems that may follow
    say(f"  phase-1 at alpha {alpha:.4g}, on {n} vertices: " + ("the solver failed" if t is None else f"t* = {t:.3g}"))
    return settles(t)


def _lp_weights(model: Any, lp: Any) -> list[float] | None:
    """Per vertex of ``model`` the dual weight of its LMIs in ``lp`` (solved, on ``model``; a mirror-invariant problem's
    vertex stands for its mirror image too: :func:`_vertex_weights`), or None where they do not match."""
    w = _vertex_weights(lp)
    return w if len(w) == len(model.vertices) else None


def seed(active: Active, model: Any, lp: Any, within: tuple[Any, tuple[int, ...]] | None = None) -> bool:
    """Seed ``active`` from ``lp``, a solved problem of the invariance LMIs on ``model`` (the linearized certificate
    where a nonlinear search starts, :func:`~.heading_search._start`): the vertices whose LMIs bind there (dual weight
    at least DUAL_FLOOR of the largest; a mirror-invariant problem's vertex stands for its mirror image too), at most
    ACTIVE.  The kinematic channels' models have the same vertices in the same order, covered (docs/theory.md §6j):
    on the default robot at d_hi = 2 (0.1 rad, alpha in [0.005, 0.0096]) the 10 vertices that bind the linearized
    certificate gave t* -1.64e-3 in 7.1 s where the 64 end vertices gave -1.72e-3 in ~48 s.  ``within`` (sub, index):
    ``lp`` is on ``sub``, whose vertices are the model's at ``index`` (a relaxation whose certificate held on every
    vertex).  Whether it seeded."""
    n = len(model.vertices)
    if within is None:
        w = _lp_weights(model, lp)
    else:
        sub, index = within
        ws = _lp_weights(sub, lp)
        if ws is None or len(index) != len(ws):
            return False
        w = [0.0] * n
        for i, x in zip(index, ws):
            w[i] = x
    if w is None or len(w) != n or not any(x > 0 for x in w):
        return False
    weight: dict[int, float] = {}
    _binding(weight, range(n), w)
    active.seed = tuple(sorted(sorted(weight, key=lambda i: (-weight[i], i))[:ACTIVE]))
    active.vertices = n
    return bool(active.seed)


def seed_rows(active: Active, model: Any, Q: np.ndarray, K: np.ndarray) -> bool:
    """Seed ``active.rows`` with the heading rows of ``model`` (one with a heading bound) nearest their bound on the set
    {xi' Q^-1 xi <= 1} of the gain ``K`` (the linearized certificate where the search starts), unless rows of this
    model are ranked there already: a row r xi + d du reaches ``sqrt((r + d K) Q (r + d K)')`` on that set, and the
    ACTIVE_ROWS rows with the largest reach against their room go first.  Only where the rows are posed as linear rows
    (more than LIFT_ROWS of them): the first phase-1 problems of a long delay then pose ACTIVE_ROWS rows, not every row
    (60 281 on the icr default at d_hi = 3), and so do a remedy's (another slip box: rows of other keys, none ranked).
    A subset of the rows is a relaxation, as the ranked ones are: where it settles nothing, the same interval is solved
    with every row (:func:`prove_no_set`; by row generation where they are many).  Whether it seeded."""
    table = lmis.heading_row_table(model)
    Q, K = np.asarray(Q, dtype=float), np.asarray(K, dtype=float)
    if len(table) <= lmis.LIFT_ROWS or Q.shape != (model.n_s, model.n_s) or K.shape != (model.n_u, model.n_s):
        return False
    if active.rows is not None and len(table.indices(active.rows)):
        return False  # ranked by the problems' duals already
    reach = lmis.row_ratios(table, table.rooms(model), [lmis.set_weight(Q, K)])
    order = np.argsort(-reach, kind="stable")[:ACTIVE_ROWS]
    active.rows = tuple(table.keys(order))
    return True


def _rank(active: Active, idx: tuple[int, ...], lps: list[Any], ts: list[tuple[float | None, str]]) -> None:
    """Update ``active`` from the duals of the problems just solved on the vertices ``idx``: the union of what it held
    and the vertices that bind here, at most ACTIVE (the largest dual weights)."""
    weight: dict[int, float] = {}
    for lp, (t, _) in zip(lps, ts):
        if t is None:
            continue
        _binding(weight, idx, _vertex_weights(lp))
    _rank_rows(active, lps, ts)
    if not weight:
        return
    keep = sorted(weight, key=lambda i: -weight[i])[:ACTIVE]
    old = [i for i in active.indices if i not in keep]
    active.indices = tuple(sorted(keep + old[: max(0, ACTIVE - len(keep))]))


def _vertex_weights(lp: Any) -> list[float]:
    """Per vertex of ``lp`` (solved) the dual weight of its LMIs: the traces of their dual matrices (0: none); posed
    mirror-invariant, a vertex and its mirror image take the larger of their weights (one's LMIs stand for both)."""
    w = [sum(float(np.trace(c.dual_value)) for c in cons if c.dual_value is not None) for cons in lp.vertex_lmis]
    images = getattr(lp, "images", ())
    return [max(x, w[images[i]]) for i, x in enumerate(w)] if len(images) == len(w) else w


def _mirror_closure(model: Any, s: Any) -> Callable[[tuple[int, ...]], tuple[tuple[int, ...], Any]]:
    """For a vertex subset of ``model``: the subset with its mirror images, and the model's symmetry on it (None: the
    model has none for the Lyapunov kind of ``s``, or its images are not exact, ``Model.mirror_on``; the subset is
    then itself, sorted).  A phase-1 problem on the closure, posed mirror-invariant, proves what the subset proves and
    more: where the LMIs of every vertex have a solution with margin t, its mirror image has one too (the model is
    symmetric), so their average is a mirror-invariant one with margin t, which holds at the closure's vertices; a
    maximum t* <= -T_PROVEN on the closure thus shows that every vertex has none (docs/theory.md §6j).  One of each
    pair of conditions is posed (each is the other's congruence), on the structured variables: on the default robot
    at d_hi = 2 (0.2 rad) 7 vertices took 0.58 s posed so against 2.95 s as they were, the same t*."""
    if not hasattr(model, "mirror_on"):  # a plant without the robot's mirror: every subset as it is
        return lambda idx: (tuple(sorted(idx)), None)
    mirror = model.mirror(s.lyapunov) if s.lyapunov == "common" else None
    cache: dict[tuple[int, ...], tuple[tuple[int, ...], Any]] = {}

    def closed(idx: tuple[int, ...]) -> tuple[tuple[int, ...], Any]:
        key = tuple(idx)
        if key not in cache:
            cache[key] = model.mirror_on(key, mirror)
        return cache[key]

    return closed


def _binding(weight: dict[Any, float], names: Any, w: list[float]) -> None:
    """Into ``weight``: each of ``names`` whose dual weight in ``w`` is at least DUAL_FLOOR of the largest, with its
    fraction of the largest (the larger where a name is there already)."""
    top = max(w, default=0.0)
    for name, x in zip(names, w):
        if top > 0 and x >= DUAL_FLOOR * top:
            weight[name] = max(weight.get(name, 0.0), x / top)


def _rank_rows(active: Active, lps: list[Any], ts: list[tuple[float | None, str]]) -> None:
    """Update ``active.rows`` from the duals of the heading rows of the problems just solved (those posed as linear
    rows, ``extra['heading_rows']``): the rows whose dual is at least DUAL_FLOOR of the largest, with the rows held
    before, at most ACTIVE_ROWS (the largest duals first)."""
    weight: dict[bytes, float] = {}
    for lp, (t, _) in zip(lps, ts):
        cons, keys = lp.extra.get("heading_rows"), lp.extra.get("heading_keys")
        if t is None or not cons or not keys:
            continue
        duals = [np.asarray(c.dual_value, dtype=float).ravel() for c in cons if c.dual_value is not None]
        if not duals:
            continue
        _binding(weight, keys, [float(x) for x in np.sum(duals, axis=0)])
    if not weight:
        return
    keep = sorted(weight, key=lambda k: -weight[k])[:ACTIVE_ROWS]
    old = [k for k in (active.rows or ()) if k not in weight]
    active.rows = tuple(keep + old[: max(0, ACTIVE_ROWS - len(keep))])
