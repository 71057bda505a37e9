"""One function per objective; :func:`synthesize` dispatches and assembles the result."""

from __future__ import annotations

import math
import time
from contextvars import ContextVar
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from ..config import SynthesisConfig
from ..errors import InfeasibleError, InputError, SolverFailure
from ..model.slip import check_physical_feasibility
from ..certificate import CertificateCheck, check_certificate, varying_failures
from .lmis import LMIProblem, build_hinf, build_invariance, build_stability
from .solve import RETRY, Outcome, Rejected, SolveRecord, solve, solver_version

__all__ = ["SynthesisResult", "synthesize"]

MAX_DELAY_VERTICES = 9  # delay-dependent Lyapunov matrices: conditions grow with the square of this
ALPHA_RANGE = (0.005, 0.95)  # line search range of alpha (log-spaced grid, then parabolic steps)
GOLDEN_STEPS = 10  # a golden section where a parabola cannot be fitted (an infeasible neighbour)
GOLDEN_MIN_BRACKET = 0.02  # ... down to a bracket this narrow in log alpha
# the alpha search stops when a step moves the objective by less than this (relative; the objective is a
# weighted sum of squared bounds, so a bound moves by half of it).  1e-4 let the unweighted e_x of
# configs/heavy-slip.yaml drift by 0.9 % along the flat valley; 1e-5 keeps every figure within 0.1 %
HINT_STOP_REL = 1e-5


@dataclass(frozen=True)
class SynthesisResult:
    """A certified gain with its certificate, the figures it proves, and how it was found."""

    K: np.ndarray
    objective: str
    multiplier: str
    certificate: dict[str, Any]
    check: CertificateCheck
    solver: dict[str, Any]
    search: tuple[dict[str, Any], ...]
    timings: dict[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    settings: Any = None  # the SynthesisConfig it was made with (the config's, with any overrides applied)

    @property
    def certified(self) -> dict[str, Any]:
        return dict(self.check.figures)

    def save(self, model: Any, outdir: Any) -> list[Any]:
        """Write gains.json and gains.mat of this result for ``model`` into ``outdir`` (atomically,
        gains.json last): what ``robustsynth synthesize`` writes, without the report."""
        from ..artifacts.files import commit_files, json_bytes, mat_bytes
        from ..artifacts.gains import gains_dict, gains_mat_vars

        gd = gains_dict(model, self)
        return commit_files(outdir, {"gains.mat": mat_bytes(gains_mat_vars(gd)), "gains.json": json_bytes(gd)},
                            primary="gains.json")


@dataclass
class _Split:
    """Where a synthesis spends its time (``SynthesisResult.timings``), over every solve it makes, the
    cheaper certificate that gives the alpha hint included."""

    build_s: float = 0.0  # writing the LMIs (cvxpy expressions)
    call_s: float = 0.0  # solver calls: cvxpy's canonicalization / parameter update / unpacking and the solver
    solver_s: float = 0.0  # the solver's own time, as it reports it
    check_s: float = 0.0  # the numpy (verified) re-check of the returned points
    solves: int = 0

    def add(self, rec: SolveRecord) -> None:
        self.call_s += rec.solve_time_s
        self.solver_s += rec.solver_time_s if rec.solver_time_s is not None else rec.solve_time_s
        self.solves += 1


_SPLIT: ContextVar[_Split | None] = ContextVar("robustsynth_synthesis_split", default=None)


def _build(fn: Callable[..., LMIProblem], *args: Any, **kwargs: Any) -> LMIProblem:
    t0 = time.perf_counter()
    lp = fn(*args, **kwargs)
    split = _SPLIT.get()
    if split is not None:
        split.build_s += time.perf_counter() - t0
    return lp


@dataclass
class _Best:
    value: float = math.inf
    cert: dict[str, Any] | None = None
    K: np.ndarray | None = None
    check: CertificateCheck | None = None
    record: SolveRecord | None = None


class _Cuts(Rejected):
    """A solved point failed the re-check only at within-period vertices (``indices`` into Model.varying)."""

    def __init__(self, indices: list[int]) -> None:
        super().__init__(f"{len(indices)} within-period vertices fail")
        self.indices = indices


MAX_CUT_ROUNDS = 6  # constraint generation: rounds of within-period vertices added to the LMIs
CUTS_PER_ROUND = 8  # the worst failing within-period vertices added per round


class _Runner:
    """Solves one compiled problem repeatedly; remembers attempts, counts and times.

    ``full(model)`` builds the same problem for a model without the mirror symmetry.  Clarabel 0.11
    reports an error on a mirror-invariant problem where the full problem reports 'infeasible'
    (measured at the default robot's infeasible alphas).  A search point that fails counts as not
    certified either way, so only a solve that asks for the fallback or the cheap retry (the retries
    when nothing was certified, the first decay rate) first solves the point again on the full
    problem: then infeasibility is still told from a solver failure (exit 3, not 4), and the search
    itself does not pay for a full solve at every infeasible alpha (the lossy link: 6 s instead of 10 s).

    Slip changing within a period (docs/theory.md §11) is covered by constraint generation: the LMIs
    hold the model's own vertices; the re-check proves the certificate at every within-period vertex
    too, and when a point fails only there, the worst of those vertices are added to the LMIs
    (``Model.with_cuts``, built by ``full``) and the point is solved again, up to MAX_CUT_ROUNDS times.
    The search goes on with the grown problem (``self.active``); its parameters are set on ``lp``."""

    def __init__(self, model: Any, lp: LMIProblem, primary: str, make_cert: Callable[[dict], dict],
                 full: Callable[[Any], LMIProblem] | None = None):
        self.model, self.lp, self.primary, self.make_cert = model, lp, primary, make_cert
        self._builder = full
        self._full: LMIProblem | None = None
        self.active = lp  # lp, or the problem with the within-period vertices added so far
        self.cuts: list[int] = []
        self.records: list[SolveRecord] = []
        self.fallbacks = 0
        self.solves = 0
        self.failures = 0
        self.full_retries = 0
        self.failed_at: dict[float, bool] = {}  # alpha -> the solver failed (not: infeasible)
        self._failed_first: dict[tuple, list[LMIProblem]] = {}  # parameters -> problems the primary solver failed on
        self.last_kind = ""

    def _set_params(self, target: LMIProblem) -> None:
        if target is not self.lp:
            for name, par in self.lp.params.items():
                target.params[name].value = par.value

    def run(self, fallback: bool = True, retry: bool | None = None, again: bool = False,
            unscaled_only: bool = False) -> tuple[Outcome, dict | None, np.ndarray | None, CertificateCheck | None]:
        """One point: ``fallback`` as :func:`solve`'s, ``retry`` its cheap retry (by default with the fallback).
        ``again``: a point solved before; where the primary solver failed on this very problem (the same
        parameters and the same constraints), it is not run again (Clarabel from scratch is deterministic:
        the same problem fails the same way).  ``unscaled_only``: skip the primary solver in any case (the
        rest of a scan whose primary solves all failed and whose retries concluded)."""
        retry = (fallback if retry is None else retry) or unscaled_only
        spent: list[SolveRecord] = []
        rounds = 0
        while True:
            skip = unscaled_only or (again and any(p is self.active for p in self._failed_first.get(self._key(), ())))
            try:
                out, res = self._run_mirrored(fallback, retry, skip, force=unscaled_only)
                out = replace(out, attempts=spent + out.attempts)
                break
            except _Cuts as c:
                spent += c.attempts
                unscaled_only = False  # the grown problem (constraint generation) from its first solver
                new = [i for i in c.indices if i not in self.cuts][:CUTS_PER_ROUND]
                if rounds >= MAX_CUT_ROUNDS or not new or self._builder is None:
                    # not a solver failure: the point fails the re-check within the period after the
                    # rounds (or at vertices already in the LMIs: the solver's accuracy); not certified
                    why = ("within-period vertices already in the LMIs still fail (solver accuracy)" if not new else
                           f"constraint generation did not converge in {rounds} rounds")
                    last = replace(spent[-1], status=f"{spent[-1].status}; {why}")
                    out, res = Outcome("failed", last, spent[:-1] + [last]), (None, None, None)
                    break
                rounds += 1
                self.cuts += new
                self.active = _build(self._builder, self.model.with_cuts(self.cuts))
                self._full = None
        self.last_kind = out.kind
        if out.kind == "failed":
            self.failures += 1
        alpha = self.lp.params.get("alpha")
        if alpha is not None:
            self.failed_at[float(alpha.value)] = out.kind == "failed"
        return (out, *res)

    def _key(self) -> tuple:
        return tuple((name, float(p.value)) for name, p in sorted(self.lp.params.items()))

    def _run_mirrored(self, fallback: bool, retry: bool, skip: bool = False, force: bool = False
                      ) -> tuple[Outcome, tuple]:
        """``skip``: not the primary solver on the active problem; ``force``: not on the full one either."""
        self._set_params(self.active)
        if not (self.active.mirrored and self._builder is not None) or not (fallback or retry):
            return self._run_on(self.active, fallback, retry, skip)
        if skip:  # the mirrored problem failed before: straight to the full one
            out, res = Outcome("failed", SolveRecord(self.primary, "failed before", None, 0.0), [], 1), (None, None, None)
        else:
            out, res = self._run_on(self.active, False, False)
        if out.kind == "failed":
            if self._full is None:
                self._full = _build(self._builder, self.model)
            self._set_params(self._full)
            self.full_retries += 1
            first = out.attempts
            skipped = out.skipped
            out, res = self._run_on(self._full, fallback, retry, skip=force)
            out = replace(out, attempts=first + out.attempts, skipped=skipped + out.skipped)
        return out, res

    def _count(self, attempts: list[SolveRecord]) -> None:
        split = _SPLIT.get()
        if split is not None:
            for rec in attempts:
                split.add(rec)
        self.solves += len(attempts)
        self.records.extend(attempts)

    def _run_on(self, lp: LMIProblem, fallback: bool, retry: bool, skip: bool = False) -> tuple[Outcome, tuple]:
        holder: dict[str, Any] = {}

        split = _SPLIT.get()

        def accept() -> bool:
            t0 = time.perf_counter()
            try:
                return _accept()
            finally:
                if split is not None:
                    split.check_s += time.perf_counter() - t0

        def _accept() -> bool:
            vals = lp.values()
            try:
                X = vals["Q"] if "Q" in vals else vals["G"]
                K = np.linalg.solve(X.T, vals["Y"].T).T  # K = Y Q^-1 (or Y G^-1)
                cert = self.make_cert(vals)  # computes P = Q^-1 (or S_m^-1)
            except np.linalg.LinAlgError:
                return False
            chk = check_certificate(self.model, K, cert)
            holder.update(cert=cert, K=K, check=chk)
            failing = varying_failures(chk)
            if failing:
                raise _Cuts(failing)
            return chk.passed

        try:
            out = solve(lp.problem, self.primary, accept, fallback=fallback, retry=retry, skip_first=skip)
        except _Cuts as exc:
            self._count(exc.attempts)
            raise
        self._count(out.attempts)
        if not skip and out.attempts and (out.kind == "failed" or len(out.attempts) > 1):  # the primary failed here
            self._failed_first.setdefault(self._key(), []).append(lp)
        if out.fallback_used:
            self.fallbacks += 1
        if out.kind == "ok":
            return out, (holder["cert"], holder["K"], holder["check"])
        return out, (None, None, None)


def multiplier_used(model: Any, kind: str) -> str:
    """The S-procedure multiplier the LMIs of ``model`` take: ``kind`` (synthesis.multiplier) where a vertex
    has the norm-bounded delay description's Delta blocks; 'diagonal' where only the kinematic channels
    have one (one scalar per channel, whatever ``kind`` says, §9); 'none' where no vertex has a Delta
    (delay vertices: the setting has no effect)."""
    if any(v.n_q and not v.diagonal for v in model.vertices):
        return kind
    return "diagonal" if any(v.n_q for v in model.vertices) else "none"


def _cert_common(model: Any, vals: dict, kind: str, margin: float, objective: str) -> dict[str, Any]:
    out: dict[str, Any] = {"objective": objective, "model": model.kind, "vertices": len(model.vertices)}
    if "Q" in vals:
        out.update(lyapunov="common", Q=vals["Q"], P=np.linalg.inv(vals["Q"]))
    else:
        out.update(lyapunov=vals["lyapunov"], G=vals["G"], S=vals["S"], P=[np.linalg.inv(S) for S in vals["S"]],
                   slip_step=model.slip_step if model.rate_bounded else None)
    # one multiplier per vertex of ``model``: an LMI that also held within-period vertices (Model.with_cuts,
    # appended last) keeps none for those (without channels they have none; with the kinematic channels
    # they share their delay vertex's, which is stored with its own vertices: Vertex.group)
    out["multipliers"] = {"kind": multiplier_used(model, kind), "M": list(vals["M"])[: len(model.vertices)], "blocks": [i.j for i in model.instants]
                          if model.n_q and any(v.n_q for v in model.vertices) else []}
    out["margin"] = margin
    out["kinematics"] = model.kinematics
    if model.heading_bound is not None:
        out["heading_bound"] = float(model.heading_bound)
    if model.covering_vertices:  # the channels hold for slip changing within a period (§9, §10)
        out["within_period_channels"] = True
    if getattr(model, "turns", None) is not None:  # the reference yaw rates the vertices cover (model/arcs.py)
        out["turns"] = {"max_yaw_rate": model.turns.max_yaw_rate, "max_step": model.turns.max_step}
    return out


def _weights(settings: SynthesisConfig) -> np.ndarray:
    w = settings.weights
    return np.array([w.e_x, w.e_y, w.e_theta])


def _delay_text(model: Any) -> str:
    m = model.config.network.dropouts.max_consecutive
    return f"delays up to {model.config.network.delay.max:g} s" + (f" and {m} lost commands in a row" if m else "")


def _wider_turns(model: Any, sep: str = ", ") -> str:
    """The remedy a turning model adds to an exit-3 message: gentler arcs (a smaller yaw rate and feedforward).
    The radius is the model's own, V^D / max_yaw_rate (a model turned by ``Model.with_turns`` may have none in its
    config)."""
    if getattr(model, "turns", None) is None:
        return ""
    return f"{sep}widen reference.turn_radius (now {model.V / model.turns.max_yaw_rate:.3g} m)"


def _lmi_sizes(lp: LMIProblem) -> list[int]:
    """The rows of each matrix inequality of a problem (its PSD constraints; scalar ones not counted)."""
    import cvxpy as cp

    return [int(c.args[0].shape[0]) for c in lp.problem.constraints if isinstance(c, cp.constraints.PSD)]


def lmi_count(lp: LMIProblem) -> int:
    """The matrix inequalities of a problem."""
    return len(_lmi_sizes(lp))


def lmi_rows(lp: LMIProblem) -> int:
    return max(_lmi_sizes(lp), default=0)


# Clarabel's time per iteration grows with the dense blocks its PSD cones put in the KKT system, sum over
# the LMIs of (r(r+1)/2)^2 for r rows: measured 2.6 s per iteration at 1.23e8 (108 vertices of 45 and 22 rows,
# d_hi = 3) and 0.81 s at 4.5e7 (40 such vertices), one core busy beside it; ~30 iterations per solve
SECONDS_PER_KKT_ENTRY = 2e-8
ITERATIONS_PER_SOLVE = 30


def solve_estimate(lp: LMIProblem) -> float:
    """A rough time [s] of one Clarabel solve of ``lp`` on a machine like the one the constants were measured on,
    from its size alone (shown before the first solve: issue 51)."""
    kkt = sum((r * (r + 1) // 2) ** 2 for r in _lmi_sizes(lp))
    return SECONDS_PER_KKT_ENTRY * kkt * ITERATIONS_PER_SOLVE


def _duration(sec: float) -> str:
    return f"{sec:.0f} s" if sec < 90 else f"{sec / 60:.0f} min"


def _attempts(out: Any) -> str:
    return ", ".join(f"{a.name} {a.status} {a.solve_time_s:.2f} s" for a in out.attempts)


def _run_stability(model: Any, s: SynthesisConfig, search: list, say: Callable[[str], None]) -> tuple[_Best, _Runner]:
    lp = _build(build_stability, model, s.multiplier, s.margin, s.lyapunov, symmetry=s.symmetry == "auto")
    full = lambda mdl: build_stability(mdl, s.multiplier, s.margin, s.lyapunov, symmetry=False)  # noqa: E731
    best = _Best()

    def make_cert(vals: dict) -> dict:
        c = _cert_common(model, vals, s.multiplier, s.margin, "stability")
        c["r2"] = float(lp.params["r2"].value)
        return c

    runner = _Runner(model, lp, s.solver, make_cert, full=full)

    def feasible(r: float, fallback: bool = False) -> bool:
        # bisection points use the primary solver only (a failure counts as 'not certified', which
        # is conservative); the first point, r ~ 1, is retried with the fallback when it fails
        lp.params["r2"].value = r * r
        out, cert, K, chk = runner.run(fallback=fallback, again=fallback)  # (fallback: r ~ 1 again, after it failed)
        search.append({"r": r, "status": out.kind})
        say(f"  decay rate r = {r:.6f}: {'certified' if out.kind == 'ok' else out.kind} ({_attempts(out)})")
        if out.kind == "ok":
            best.value, best.cert, best.K, best.check, best.record = r, cert, K, chk, out.record
            return True
        return False

    hi = 1.0 - 1e-6
    if not feasible(hi) and not (runner.last_kind == "failed" and feasible(hi, fallback=True)):
        if runner.last_kind == "failed":
            raise SolverFailure(f"stability: the solvers failed ({runner.records[-1].status})")
        raise InfeasibleError(
            f"stability: no gain robustly stabilizes the robot for {_delay_text(model)}: "
            f"narrow network.delay{_wider_turns(model)} or lower reference.speed"
        )
    lo = 0.0
    while hi - lo > s.bisection_tol:
        mid = (lo + hi) / 2.0
        if feasible(mid):
            hi = mid
        else:
            lo = mid
    return best, runner


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


def _walk(evaluate: Callable[[float], float], x0: float, step: float, lo: float, hi: float,
          rel: float = 0.0) -> list[tuple[float, float]]:
    """From x0 (log alpha), one ``step`` at a time in each direction while the objective falls (by more than
    the fraction ``rel``): the points evaluated, which bracket the minimum near x0."""
    pts = [(x0, evaluate(x0))]
    if not math.isfinite(pts[0][1]):
        return pts
    for direction in (1.0, -1.0):
        x, f = pts[0]
        while True:
            xn = x + direction * step
            if xn < lo - 1e-12 or xn > hi + 1e-12:
                break
            fn = evaluate(xn)
            pts.append((xn, fn))
            if not fn < f * (1.0 - rel):
                break
            x, f = xn, fn
    return sorted(pts)


def _run_invariance(model: Any, s: SynthesisConfig, search: list, motor: bool,
                    say: Callable[[str], None] = lambda _m: None,
                    alpha_hint: float | None = None, retry: bool | str = True, probe_only: bool = False,
                    give_up: int | None = None,
                    prune: Callable[[list[float]], set[float]] | None = None,
                    stop_rel: float = HINT_STOP_REL) -> tuple[_Best, _Runner]:
    """The alpha line search of the invariance LMIs.  Without a hint: a log grid of alpha_points
    scanned upwards, then parabolic steps around its best point.  With ``alpha_hint`` (the best alpha
    of a cheaper certificate class): walk from the hint in quarter grid steps while the bound falls,
    then parabolic steps in that bracket, stopped once they no longer move the bound (the full scan
    when the hint is not feasible for this class).  ``retry``: when nothing was certified, the scan's failed
    points again, with the fallback chain (True), only the same solver unscaled ('cheap'), or not (False).
    ``prune``: given the scan's alphas that were not
    certified, before the failed ones are retried with the fallback solver, returns those proven
    infeasible otherwise (they are not retried).  ``stop_rel``: the refinement's stop tolerance on the objective
    (COSTLY_STOP_REL where each solve takes seconds; the hinted walk then also stops at smaller gains)."""
    lp = _build(build_invariance, model, s.multiplier, s.margin, _weights(s), motor, s.lyapunov,
                symmetry=s.symmetry == "auto")
    full = lambda mdl: build_invariance(mdl, s.multiplier, s.margin, _weights(s), motor, s.lyapunov,  # noqa: E731
                                        symmetry=False)
    w = _weights(s)
    best = _Best()

    def make_cert(vals: dict) -> dict:
        c = _cert_common(model, vals, s.multiplier, s.margin, "ultimate-bound")
        c["alpha"] = float(lp.params["alpha"].value)
        c["beta"] = vals["beta"]
        c["motor_limits_enforced"] = motor
        return c

    runner = _Runner(model, lp, s.solver, make_cert, full=full)
    cache: dict[float, float] = {}
    last: list[Outcome] = []  # the outcome of evaluate's latest solve
    if not probe_only:
        est = solve_estimate(lp)
        say(f"  {lmi_count(lp)} LMIs (the largest {lmi_rows(lp)} rows) per alpha; each point is one solve"
            + (f" (about {_duration(est)} each, estimated from its size)" if est >= 1.0 else "") + ", a failed one is retried")
    position = [""]  # where the scan stands, for the lines below (set by the grid loop)

    def evaluate(log_a: float, fallback: bool = False, cheap: bool = False, unscaled_only: bool = False) -> float:
        # The scan uses the primary solver only: a point it cannot solve costs a slow fallback
        # and rarely matters once its neighbours are solved.  Only when no point at all was
        # certified are the failed ones retried (below): fallback, the whole chain; cheap, the
        # primary solver unscaled only; either way not the primary again where it failed on this problem.
        if log_a in cache and not (fallback or cheap):
            return cache[log_a]
        a = float(np.exp(log_a))
        lp.params["alpha"].value = a
        lp.params["one_minus_alpha"].value = 1.0 - a
        out, cert, K, chk = runner.run(fallback=fallback, retry=fallback or cheap, again=fallback or cheap,
                                       unscaled_only=unscaled_only)
        last[:] = [out]
        val = math.inf
        if out.kind == "ok":
            ub = chk.figures["ultimate_bound"]
            val = float(w[0] * ub["e_x"] ** 2 + w[1] * ub["e_y"] ** 2 + w[2] * ub["e_theta"] ** 2)
            if val < best.value:
                best.value, best.cert, best.K, best.check, best.record = val, cert, K, chk, out.record
        search.append({"alpha": a, "status": out.kind, "objective": None if math.isinf(val) else val})
        what = (f"certified, |e_y| <= {100 * chk.figures['ultimate_bound']['e_y']:.2f} cm" if out.kind == "ok" else out.kind)
        say(f"  alpha = {a:.4g}{position[0]}: {what} ({_attempts(out)}); best so far "
            + (f"|e_y| <= {100 * best.check.figures['ultimate_bound']['e_y']:.2f} cm" if best.check is not None else "none"))
        cache[log_a] = val
        return val

    grid = np.linspace(math.log(ALPHA_RANGE[0]), math.log(ALPHA_RANGE[1]), s.alpha_points)
    if probe_only and alpha_hint is not None:  # one solve at the hint (is this class worth a search?)
        evaluate(math.log(alpha_hint))
        return best, runner
    if alpha_hint is not None:
        lo, hi = float(grid[0]), float(grid[-1])
        # quarter grid steps: the richer classes' best alpha lies within a step or two of the common
        # certificate's (measured on the default robot: 0.219 -> 0.218 / 0.228 / 0.231), and a tight
        # bracket makes the parabola exact enough to stop after one or two solves
        pts = _walk(evaluate, min(max(math.log(alpha_hint), lo), hi), WALK_STEP * float(grid[1] - grid[0]), lo, hi,
                    rel=0.0 if stop_rel == HINT_STOP_REL else stop_rel)
        if best.cert is not None:
            _parabolic(evaluate, pts, predict=True, rel=stop_rel)
            return best, runner
        say("  the hint is not feasible for this class: full scan")
    vals: list[float] = []
    failures = 0  # solver failures in a row, with nothing certified yet
    gave_up = False
    t_scan = time.perf_counter()
    for i, g in enumerate(grid):
        left = ""
        if i:  # what the rest of the grid costs at most, at the mean time per point so far
            per = (time.perf_counter() - t_scan) / i
            left = f", at most ~{_duration(per * (len(grid) - i))} left in this scan"
        position[0] = f" (point {i + 1} of at most {len(grid)}{left})"
        vals.append(evaluate(float(g)))
        position[0] = ""
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
    if retry == "cheap" and runner.primary not in RETRY:  # no cheap retry for this solver
        retry = False
    grid_points = list(grid)
    on_grid = set(grid_points)
    if best.cert is None and retry:
        failed = [g for g, v in zip(grid, vals) if not math.isfinite(v) and runner.failed_at.get(float(np.exp(g)))]
        # the hint's point too, where it failed
        failed = sorted(failed + [g for g in cache if g not in on_grid and runner.failed_at.get(float(np.exp(g)))])
        if prune is not None and failed and retry is True:  # told every alpha of the scan that was not certified
            proven = prune([float(np.exp(g)) for g, v in zip(grid, vals) if not math.isfinite(v)])
            for a in (float(np.exp(g)) for g in failed):  # proven infeasible otherwise: no solver failure any more
                if a in proven:
                    search.append({"alpha": a, "status": "infeasible", "objective": None, "by": "least motor bound"})
                    runner.failed_at[a] = False
                    runner.failures -= 1  # (the exit-3 texts tell "infeasible" from "solver failed" by these counts)
            failed = [g for g in failed if float(np.exp(g)) not in proven]
        tried: list[float] = []
        cheap_concluded = False  # the unscaled retry itself concluded somewhere (not the fallback after it)
        for g in failed:
            tried.append(evaluate(float(g), fallback=retry is True, cheap=True))
            cheap_concluded = cheap_concluded or (last[0].kind != "failed"
                                                  and last[0].record.name == RETRY.get(runner.primary))
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
        if gave_up and cheap_concluded:
            # the give-up cut the scan where only the primary solver was failing: the unscaled retry concludes
            # there, so the rest of the grid goes to it directly (an exit 3 then rests on every alpha of the scan;
            # a certificate found by the retries is refined from the whole grid)
            say(f"  the retries concluded: the rest of the scan with {RETRY[runner.primary]}")
            for g in grid[len(vals):]:
                vals.append(evaluate(float(g), unscaled_only=True))
                if len(vals) >= 3 and math.isfinite(vals[-3]) and vals[-1] > vals[-2] > vals[-3]:
                    break  # past the minimum (the scan's rule)
                if any(math.isfinite(v) for v in vals[:-1]) and not math.isfinite(vals[-1]):
                    break  # the end of the feasible interval
    if best.cert is None:
        return best, runner
    # the retried points off the grid (the hint's) where they certified: the parabolic steps start from them too
    extra = [(g, v) for g, v in cache.items() if g not in on_grid and math.isfinite(v)]
    # refined by the solver that certified: the unscaled one where the primary failed at every point it tried
    unscaled = best.record is not None and best.record.name == RETRY.get(runner.primary)
    _parabolic(lambda x: evaluate(x, unscaled_only=unscaled), sorted([(float(g), v) for g, v in zip(grid, vals)] + extra),
               rel=stop_rel)
    return best, runner


def _run_hinf(model: Any, s: SynthesisConfig, search: list, say: Callable[[str], None]) -> tuple[_Best, _Runner]:
    lp = _build(build_hinf, model, s.multiplier, s.margin, _weights(s))
    best = _Best()

    def make_cert(vals: dict) -> dict:
        c = _cert_common(model, vals, s.multiplier, s.margin, "hinf")
        # certify a gamma^2 a hair above the optimum so the numpy check keeps its headroom
        c["gamma2"] = float(vals["gamma2"]) * (1.0 + 1e-6) + s.margin
        return c

    runner = _Runner(model, lp, s.solver, make_cert,
                     full=lambda mdl: build_hinf(mdl, s.multiplier, s.margin, _weights(s)))
    out, cert, K, chk = runner.run()
    search.append({"status": out.kind})
    say(f"  hinf: {'certified' if out.kind == 'ok' else out.kind} ({_attempts(out)})")
    if out.kind == "ok":
        best.value, best.cert, best.K, best.check, best.record = cert["gamma2"], cert, K, chk, out.record
    return best, runner


CLI_OVERRIDES = ("objective", "solver", "multiplier")  # the settings `robustsynth synthesize` overrides by option
MODEL_SETTINGS = ("model", "delay_description", "kinematics", "integral_action")  # build_model reads them


def synthesize(model: Any, settings: SynthesisConfig | None = None, *, on_step: Callable[[str], None] | None = None,
               **overrides: Any) -> SynthesisResult:
    """Design and certify ``du_k = K xi_k`` for ``model``.

    ``settings`` defaults to ``model.config.synthesis``; keyword ``overrides`` (``objective``,
    ``solver``, ``multiplier``, ...) replace single settings.  Raises :class:`~robustsynth.errors.InfeasibleError`
    (exit 3) when the LMIs have no solution and :class:`~robustsynth.errors.SolverFailure` (exit 4) when the solvers
    fail or no returned point passes the certificate check.  ``on_step`` receives one line per
    solve (the alpha scan, the decay-rate bisection): what was tried, by which solver, how long.

    Parameters
    ----------
    model : Model
        The model to design for (:func:`~robustsynth.model.build_model`).
    settings : SynthesisConfig or None
        The synthesis settings (default: the model's config's).
    on_step : callable or None
        Receives one line per solve.
    **overrides : Any
        Single settings replaced (``objective``, ``solver``, ``multiplier``, ...).

    Returns
    -------
    SynthesisResult
        The gain ``K``, its certificate and the figures the numpy re-check proves (``certified``).

    Raises
    ------
    InfeasibleError
        No gain meets the guarantee (exit 3).
    SolverFailure
        No solve concluded, or none passed the certificate check (exit 4).
    """
    token = _SPLIT.set(_Split())
    try:
        return _synthesize(model, settings, on_step, overrides)
    finally:
        _SPLIT.reset(token)


def _timings(total: float, solve: float) -> dict[str, float]:
    """total_s and solve_s (the chosen search's solver calls), and the split of the whole synthesis:
    build_s (writing the LMIs), cvxpy_s (canonicalization and unpacking), solver_s (the solver's own),
    check_s (the numpy re-check), other_s (the rest: model checks, search logic), solves (all)."""
    out = {"total_s": total, "solve_s": solve}
    split = _SPLIT.get()
    if split is not None:
        out.update(build_s=split.build_s, cvxpy_s=max(split.call_s - split.solver_s, 0.0), solver_s=split.solver_s,
                   check_s=split.check_s, other_s=max(total - split.build_s - split.call_s - split.check_s, 0.0),
                   solves=float(split.solves))
    return out


def _synthesize(model: Any, settings: SynthesisConfig | None, on_step: Callable[[str], None] | None,
                overrides: dict[str, Any]) -> SynthesisResult:
    from ..config import refuse_lti

    refuse_lti(model, "synthesize")
    if not hasattr(model, "vertices"):
        raise InputError(f"synthesize: takes a model (robustsynth.build_model(config)), got {type(model).__name__}")
    say = on_step if on_step is not None else (lambda _m: None)
    s = settings if settings is not None else model.config.synthesis
    if overrides:
        # validated as strictly as the config file and the CLI: an unknown key or value is an error
        from pydantic import ValidationError

        from ..config import SynthesisSection, _format_validation_error

        given = {k: v for k, v in overrides.items() if v is not None}
        data = s.model_dump()
        data.update(given)
        try:  # inside a section, so that every problem is named by its synthesis.<key> path
            s = SynthesisSection.model_validate({"synthesis": data}).synthesis
        except ValidationError as exc:
            # name the override (the command line's option, or synthesize()'s keyword) and the setting it replaced
            said = ", ".join(f"synthesis.{k}: {v} (overridden{': --' + k if k in CLI_OVERRIDES else ''})"
                             for k, v in given.items())
            raise InputError(f"{said}: {_format_validation_error(exc)}") from None
    built = model.config.synthesis  # the settings the model's structure comes from: an override cannot change it
    fixed = [k for k in MODEL_SETTINGS if getattr(s, k) != getattr(built, k)
             and not (k == "delay_description" and s.delay_description == model.delay_description)]  # auto's own
    if fixed:  # review, stop 47: they were ignored, and the gains file recorded them as made with
        k = fixed[0]
        raise InputError(f"synthesis.{k}: {getattr(s, k)} differs from the {getattr(built, k)} the model was built with; "
                         "it shapes the model, not only the solve: set it in the config and build the model again "
                         "(robustsynth.build_model(config))")
    t0 = time.perf_counter()
    search: list[dict[str, Any]] = []
    notes: list[str] = []
    cfg = model.config
    if s.lyapunov != "common" and (model.kind != "slip-aware" or s.objective == "hinf"):
        raise InputError(f"synthesis.lyapunov: {s.lyapunov} needs synthesis.model: slip-aware and the "
                         "ultimate-bound or stability objective")
    if s.lyapunov in ("delay-dependent", "path-dependent") and not 1 < model.delay_vertex_count <= MAX_DELAY_VERTICES:
        raise InputError(f"synthesis.lyapunov: {s.lyapunov} needs 2 to {MAX_DELAY_VERTICES} delay vertices per slip "
                         f"corner; this model has {model.delay_vertex_count} ({model.delay_description} delays, "
                         f"d_hi = {model.d_hi}): use slip-dependent")
    if s.objective == "hinf" and getattr(model, "turns", None) is not None:
        raise InputError("synthesis.objective: hinf bounds the slip input only; a turning reference "
                         "(reference.turn_radius) needs ultimate-bound or stability")
    check_physical_feasibility(cfg)  # physics first: no LMI can beat a motor that is too slow
    if s.objective == "stability":
        say(f"{s.objective}: bisection on the decay rate ({model.kind} model, {len(model.vertices)} vertices)")
        best, runner = _run_stability(model, s, search, say)
    elif s.objective == "hinf":
        say(f"{s.objective}: one solve ({model.kind} model, {len(model.vertices)} vertices)")
        best, runner = _run_hinf(model, s, search, say)
        if best.cert is None:
            _raise_no_solution(runner, "hinf", f"hinf: no gain gives a finite l2 gain for {_delay_text(model)}: "
                               "narrow network.delay or lower reference.speed")
    else:
        if all(not np.any(np.asarray(v.E)) for v in model.vertices):
            raise InputError(
                "slip: every slip range has zero width and centre 1, so the ultimate bound is 0; "
                "use synthesis.objective: stability"
            )
        rho_max = cfg.robot.max_motor_speed
        motor = bool(s.motor_limits and rho_max is not None)
        if motor and rho_max <= model.feedforward_motor_speed:
            turning = getattr(model, "turns", None) is not None
            raise InfeasibleError(
                f"ultimate-bound: robot.max_motor_speed = {rho_max:g} rad/s is below "
                f"{'V^D/R + max_yaw_rate D/(2R)' if turning else 'V^D/R'} = {model.feedforward_motor_speed:.4g} rad/s "
                f"needed to follow the path: raise robot.max_motor_speed{_wider_turns(model)} or lower reference.speed"
            )
        if model.heading_bound is not None:
            best, runner = _run_nonlinear(model, s, search, motor, say)
        else:
            best, runner = _run_linearized(model, s, search, motor, say)
        if not motor and rho_max is not None and s.motor_limits is False:
            notes.append("motor limits not enforced (synthesis.motor_limits: false)")
    rec = best.record
    if best.check is not None:
        notes += validity_notes(model, best.check.figures, best.cert or {})
    used = multiplier_used(model, s.multiplier)
    if s.multiplier == "full" and used != "full":  # asked for explicitly (structured is the default): say it was moot
        why = ("one scalar multiplier per kinematic or arc channel" if used == "diagonal"
               else "its delay vertices have no norm-bounded Delta")
        notes.append(f"synthesis.multiplier: full has no effect on this model ({why}; it applies to delay_description: "
                     "norm-bounded)")
    if runner.fallbacks and rec is not None:
        notes.append(f"fallback solver used in {runner.fallbacks} of {len(search)} solves; the accepted K is "
                     f"from {rec.name}")
    if best.cert is None or best.check is None or not best.check.passed or rec is None:
        raise SolverFailure(f"{s.objective}: no certified point")  # unreachable: each branch above raised
    cert = dict(best.cert)
    cert["min_eig_margin_found"] = best.check.min_eig_margin
    solver = {
        "name": rec.name,
        "version": solver_version(rec.name),
        "status": rec.status,
        "iterations": rec.iterations,
        "solve_time_s": float(sum(r.solve_time_s for r in runner.records)),
        "fallback_used": bool(runner.fallbacks),
        "solves": runner.solves,
    }
    return SynthesisResult(
        K=best.K,
        objective=s.objective,
        multiplier=used,
        certificate=cert,
        check=best.check,
        solver=solver,
        search=tuple(search),
        timings=_timings(time.perf_counter() - t0, solver["solve_time_s"]),
        notes=tuple(notes),
        settings=s,
    )


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


def _run_linearized(model: Any, s: SynthesisConfig, search: list, motor: bool,
                    say: Callable[[str], None]) -> tuple[_Best, _Runner]:
    """The ultimate-bound search on the linearized kinematics (docs/theory.md §6b); raises when no
    gain is certified."""
    cfg = model.config
    rho_max = cfg.robot.max_motor_speed
    hint = None
    if s.lyapunov != "common":
        # the common certificate is cheap (one Lyapunov matrix) and its best alpha lies near the
        # richer classes' (measured: within a grid step on every class of the default robot)
        sc = s.model_copy(update={"lyapunov": "common"})
        say(f"the common certificate first: its best alpha starts the {s.lyapunov} search ({len(model.vertices)} vertices)")
        common, _ = _run_invariance(model, sc, [], motor, say, prune=_motor_pruner(model, sc, say=say) if motor else None)
        hint = float(common.cert["alpha"]) if common.cert is not None else None
    how = (f"walk of alpha from the common certificate's {hint:.4g}" if hint is not None
           else f"scan of alpha over {s.alpha_points} points")
    say(f"{s.objective}: {how}, then parabolic steps ({model.kind} model, {len(model.vertices)} vertices, "
        f"motor limits {'on' if motor else 'off'})")
    least: dict[float, float | None] = {}  # alpha -> the least motor bound, where proven (else None)
    best, runner = _run_invariance(model, s, search, motor, say, alpha_hint=hint,
                                   prune=_motor_pruner(model, s, least, say) if motor else None)
    if best.cert is None:
        if runner.failures and runner.failures == len(search):
            raise SolverFailure("ultimate-bound: every solve failed, also retried (unscaled) and with the fallback solver")
        if motor:
            probe, _ = _run_invariance(model, s.model_copy(update={"alpha_points": 5}), [], False)
            if probe.cert is not None:
                known = [r for r in least.values() if r is not None]
                need = ""
                if known and rho_max < min(known) < math.inf:  # a figure at or below the limit would say nothing
                    need = (f"; these LMIs need at least {min(known):.4g} rad/s"
                            + (" at every alpha of the scan" if len(known) == len(least) else
                               f" at the {len(known)} of the scan's {len(least)} alphas where that was solved"))
                raise InfeasibleError(
                    f"ultimate-bound: no gain keeps |rho| <= {rho_max:g} rad/s for {_delay_text(model)}"
                    + (f" (the feedforward alone takes {model.feedforward_motor_speed:.3g} rad/s of it, the turning "
                       "reference's included)" if getattr(model, "turns", None) is not None else "")
                    + f"{need}: raise robot.max_motor_speed{_wider_turns(model)} or lower reference.speed"
                )
        raise InfeasibleError(
            f"ultimate-bound: no gain makes an ellipsoid invariant for {_delay_text(model)} and slip in "
            f"[{cfg.slip.right.min:g}, {cfg.slip.right.max:g}] x [{cfg.slip.left.min:g}, {cfg.slip.left.max:g}]"
            + (f" (yaw [{cfg.slip.yaw.min:g}, {cfg.slip.yaw.max:g}], x_icr [{cfg.slip.icr_offset.min:g}, "
               f"{cfg.slip.icr_offset.max:g}] m)" if cfg.slip.model == "icr" else "") + ": "
            f"narrow network.delay or slip{_wider_turns(model)}, or lower reference.speed"
        )
    return best, runner


HEADING_GRID = (0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.7)  # heading_bound: auto tries these [rad]
# auto's heading bound binds when the certified set's heading within a period reaches this fraction of it; below,
# larger bounds are not tried (they widen every channel's interval and loosen only rows that do not bind: for each
# alpha the LMIs are convex, so their optimum is the one without the heading rows, over channels that only widen) and
# a smaller one is, just above the set's heading (HEADING_ROOM): the default robot's 0.1 rad left its set at 0.078 rad
HEADING_SLACK = 0.95
HEADING_ROOM = 1.03  # the smaller bound tried: this times the set's heading within a period (rounded up to 1e-3 rad)
HEADING_TIGHTEN = 2  # smaller bounds tried at most, each one solve at the best alpha
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
    given = s
    # the channels' searches below (the linearized start keeps the configured solver: on configs/turns.yaml's arc
    # channels the scaled one took 1.4 s a point against 2.0 s unscaled, both optimal)
    s = _kinematic(s)
    if common.cert is None and s.lyapunov == "common":
        _stop_if_the_start_is_infeasible(model, crunner, least, motor)
    hint = float(common.cert["alpha"]) if common.cert is not None else None
    auto = s.heading_bound == "auto"
    bounds = _auto_bounds(common) if auto else (float(s.heading_bound),)
    best, runner, tried, below = _Best(), None, [], None
    tried_at: dict[float, tuple[int, int]] = {}  # heading bound -> (alphas solved, of which the solver failed)
    for j, tb in enumerate(bounds):
        # the channels for slip changing within a period only where the certificate is proven at the
        # within-period vertices: a common Lyapunov matrix (Model.slip_variation)
        m = model.with_heading_bound(tb, within_period=s.lyapunov == "common")
        say(f"{s.objective}, nonlinear kinematics with |e_theta(t)| <= {tb:g} rad"
            + (f" (heading bound {j + 1} of at most {len(bounds)}: {', '.join(f'{b:g}' for b in bounds)} rad)" if auto else "")
            + ": alpha "
            + (f"walk from {hint:.4g}" if hint is not None else f"scan over {s.alpha_points} points")
            + f" ({len(m.vertices)} vertices, {m.vertices[0].n_q} kinematic channels each)")
        try:
            if best.cert is not None:  # one solve at the best alpha first: a larger bound that is worse there stops
                pb, _ = _run_invariance(m, s, search, motor, say, alpha_hint=float(best.cert["alpha"]), retry=False,
                                        probe_only=True)
                if pb.cert is None or pb.value >= best.value:
                    tried.append((tb, "not better at the best alpha"))
                    break
            b, r = _run_invariance(m, s, search, motor, say, alpha_hint=hint, retry="cheap" if auto else True,
                                   give_up=NONLINEAR_GIVE_UP,
                                   prune=_motor_pruner(m, s, say=say) if motor else None, stop_rel=COSTLY_STOP_REL)
        except InfeasibleError as exc:  # the heading bound is below the slip's own turn
            say(f"  {exc}")
            tried.append((tb, "below the slip's own turn within a period"))
            below = str(exc)
            continue
        # per alpha, its final outcome (after any fallback): failed everywhere is a solver failure, not a proof
        solver_failed = b.cert is None and bool(r.failed_at) and all(r.failed_at.values())
        tried.append((tb, "certified" if b.cert is not None else ("solver failed" if solver_failed else "infeasible")))
        tried_at[tb] = (len(r.failed_at), sum(r.failed_at.values()))
        if runner is None:
            runner = r
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
        for _ in range(HEADING_TIGHTEN):
            tb0, h = float(best.check.figures["heading_bound"]), _heading_room(best)
            tb = math.ceil(HEADING_ROOM * h * 1e3) / 1e3
            if not tb < 0.9 * tb0:
                break
            say(f"{s.objective}, nonlinear kinematics with |e_theta(t)| <= {tb:g} rad (the set's heading within a period "
                f"at {tb0:g} rad was {h:.3g}): one solve at the best alpha")
            try:
                pb, pr = _run_invariance(model.with_heading_bound(tb, within_period=s.lyapunov == "common"), s, search,
                                         motor, say, alpha_hint=float(best.cert["alpha"]), retry=False, probe_only=True)
            except InfeasibleError as exc:  # below the slip's own turn within a period
                say(f"  {exc}")
                break
            tried.append((tb, "certified" if pb.cert is not None else "not certified at the best alpha"))
            if pb.cert is None or pb.value >= best.value:
                break
            best, runner = pb, pr
    if best.cert is None:
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

        tries = try_remedies(model, lambda m: _first_try(m, given, motor), say)
        raise InfeasibleError(_nonlinear_infeasible(model, common, tried, tried_at, auto)
                              + (". Tried (" + "; ".join(tries) + ")" if tries else ""))
    return best, runner


def _kinematic(s: SynthesisConfig) -> SynthesisConfig:
    """The settings of the kinematic channels' solves: the configured solver's KINEMATIC_PRIMARY."""
    return s.model_copy(update={"solver": KINEMATIC_PRIMARY.get(s.solver, s.solver)})


def _start(model: Any, s: SynthesisConfig, motor: bool, say: Callable[[str], None]
           ) -> tuple[_Best, _Runner, dict[float, float | None]]:
    """The linearized common certificate where a nonlinear search starts (its alpha and heading), the runner of
    its scan, and its least motor bounds per alpha where proven."""
    lin = model.linearized()
    if model.icr and model.covering_vertices:
        # the icr model's linearized certificate with the covering channels (and the arcs') costs as much as the
        # nonlinear one (48 vertices of 40 channels: minutes); its alpha and heading only start the search, which
        # the straight constant-slip one (no channels, seconds) does about as well
        lin = replace(lin, vertices=model.base_vertices, turns=None, covering_vertices=(), channels=_straight_channels(model))
    sc = s.model_copy(update={"lyapunov": "common", "kinematics": "linearized"})
    say(f"the linearized common certificate, where the search starts ({len(lin.vertices)} vertices)")
    least: dict[float, float | None] = {}  # alpha -> the linearized LMIs' least motor bound, where proven
    common, crunner = _run_invariance(lin, sc, [], motor, say, prune=_motor_pruner(lin, sc, least, say=say) if motor else None)
    return common, crunner, least


def _auto_bounds(common: _Best) -> tuple[float, ...]:
    """heading_bound: auto's bounds, upwards from about the linearized set's own heading (a smaller bound rarely
    helps; the search tightens a certified one afterwards)."""
    start = 0.9 * float(common.check.figures.get("heading_within_period", 0.0)) if common.check is not None else 0.0
    return tuple(b for b in HEADING_GRID if b >= start) or HEADING_GRID[-1:]


def _first_try(model: Any, s: SynthesisConfig, motor: bool) -> dict[str, Any] | None:
    """A quick search of the nonlinear certificate (remedies): the linearized start, then one solve at its best
    alpha for each heading bound auto would try, upwards; the certified figures of the first that certifies (a
    bound the full search reaches or improves on), or None."""
    common, _, _ = _start(model, s, motor, lambda _m: None)
    if common.cert is None:
        return None
    s = _kinematic(s).model_copy(update={"heading_bound": "auto"})
    for tb in _auto_bounds(common):
        try:
            b, _ = _run_invariance(model.with_heading_bound(tb, within_period=s.lyapunov == "common"), s, [], motor,
                                   alpha_hint=float(common.cert["alpha"]), retry=False, probe_only=True)
        except InfeasibleError:  # below the slip's own turn within a period
            continue
        if b.cert is not None:
            return dict(b.check.figures)
    return None


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
        from ..certificate_bounds import sup_on_set
        from ..model.slip import slip_matrix

        f = common.check.figures
        S = list(lyapunov_of(model.linearized(), common.cert).S)
        K = np.asarray(common.K)
        uD = np.array([model.V, 0.0])
        speed = 0.0  # the largest forward-speed deviation a on the set, at every slip corner
        for mu in model.corners:
            M = slip_matrix(mu, model.config.robot.track_distance)
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
                    "upwards from 0.9 times that heading")
    else:  # review, stop 47: a turning config too tight even for the linearized set ended without any remedy
        msg += (". The linearized common certificate, where the search starts, gave none either: narrow slip, lower "
                "reference.speed" + _wider_turns(model))
    if model.covering and model.config.synthesis.lyapunov == "common":
        msg += (". These channels cover slip changing at any time within a period; with synthesis.lyapunov "
                "slip-dependent (or delay-, path-dependent) they assume it constant within each period, which costs "
                "less and is stated with the certificate (docs/theory.md §9)")
    return msg


LINEARIZATION_HEADING = 0.5  # [rad]: beyond it sin e_theta differs from e_theta by more than 4 %


def validity_notes(model: Any, figures: dict[str, Any], cert: dict[str, Any]) -> list[str]:
    """Certified bounds that leave the region where the model they are proven for holds, in words:
    a heading beyond what the linearization covers (a nonlinear certificate covers its own heading
    bound), errors larger than half the shortest path segment (the segment frames stop meaning much)."""
    ub = figures.get("ultimate_bound") or {}
    out = []
    th = ub.get("e_theta")
    if th is not None and cert.get("kinematics", "linearized") == "linearized" and th > LINEARIZATION_HEADING:
        out.append(f"certified |e_theta| <= {th:.3g} rad lies beyond where the linearization holds (~{LINEARIZATION_HEADING:g} "
                   "rad: sin e_theta ~ e_theta); the bound is proven for the linearization only "
                   "(synthesis.kinematics: nonlinear proves its own heading bound)")
    wp = np.asarray(model.config.reference.path, dtype=float)
    seg = float(np.min(np.hypot(*np.diff(wp, axis=0).T))) if wp.shape[0] > 1 else math.inf
    big = max((ub.get(k) or 0.0) for k in ("e_x", "e_y")) if ub else 0.0
    if big > seg / 2:
        out.append(f"a certified position bound ({100 * big:.3g} cm) exceeds half the shortest path segment "
                   f"({seg / 2:.3g} m): the robot may be nearer another segment than its own")
    return out


def _raise_no_solution(runner: _Runner, objective: str, infeasible_msg: str) -> None:
    if runner.failures:
        raise SolverFailure(f"{objective}: the solvers failed, also with the fallback ({runner.records[-1].status})")
    raise InfeasibleError(infeasible_msg)
