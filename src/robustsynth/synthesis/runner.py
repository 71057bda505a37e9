"""One compiled LMI problem solved point by point (:class:`_Runner`): every returned point's certificate
(:func:`_cert_common`) is re-checked by :func:`robustsynth.certificate.check_certificate` before it counts,
within-period vertices that fail are added to the LMIs (constraint generation), and the attempts, counts
and times are kept (:class:`_Split`).  Also a problem's size (its estimated solve time: :mod:`.cost`), and the
words the searches' lines and exit messages share."""

from __future__ import annotations

import math
import time
from contextvars import ContextVar
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ..certificate import CertificateCheck, check_certificate, varying_failures
from ..config import SynthesisConfig
from ..errors import InfeasibleError, SolverFailure
from .lmis import LMIProblem, rows_broken
from .solve import Outcome, Rejected, SolveRecord, solve
from .solver_process import trim_heap

if TYPE_CHECKING:
    from .phase1 import Phase1


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
    """A solved point failed the re-check only at within-period vertices (``indices`` into the family of
    Model.with_cuts)."""

    def __init__(self, indices: list[int]) -> None:
        super().__init__(f"{len(indices)} within-period vertices fail")
        self.indices = indices


class _RowCuts(Rejected):
    """A solved point of a problem posed on a subset of the heading rows breaks rows not posed (``keys``, the worst
    first: :func:`.lmis.rows_broken`)."""

    def __init__(self, keys: list[bytes]) -> None:
        super().__init__(f"{len(keys)} heading rows not posed break it")
        self.keys = keys


MAX_CUT_ROUNDS = 6  # constraint generation: rounds of within-period vertices added to the LMIs
MAX_ROW_ROUNDS = 8  # row generation: rounds of heading rows added to the LMIs


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
    The search goes on with the grown problem (``self.active``); its parameters are set on ``lp``.

    Heading rows the same way (row generation, issue 51): ``rows`` (keys, :func:`.lmis.heading_row_key`) are the rows
    ``lp`` was built with, a subset of the model's many (2.2 million on the default robot at d_hi = 5); where a solved
    point breaks rows not posed, the worst are added (``full(model, rows)``) and the point solved again, up to
    MAX_ROW_ROUNDS times.  A point is accepted only where its solution holds every row (and then passes the
    certificate's re-check, which bounds the heading on the whole set by itself)."""

    def __init__(self, model: Any, lp: LMIProblem | None, primary: str, make_cert: Callable[[dict], dict],
                 full: Callable[..., LMIProblem] | None = None, rows: frozenset[bytes] | None = None,
                 grown: Callable[..., LMIProblem] | None = None):
        self.model, self.lp, self.primary, self.make_cert = model, lp, primary, make_cert
        self.rows = rows
        self._builder = full
        # the builder of the grown problem (within-period vertices and heading rows added): ``full``, or one that keeps
        # the mirror symmetry where the grown model has it (Model.with_cuts adds each vertex with its mirror image)
        self._grown = grown
        self._full: LMIProblem | None = None
        self.active = lp  # lp, or the problem with the within-period vertices added so far (None: not built yet)
        self.cuts: list[int] = []
        self.records: list[SolveRecord] = []
        self.fallbacks = 0
        self.solves = 0
        self.failures = 0
        self.full_retries = 0
        self.failed_at: dict[float, bool] = {}  # alpha -> the solver failed (not: infeasible)
        self.phase1: Phase1 | None = None  # the phase-1 problems asked where the solver failed (_settled_by_phase1)
        self.phase1_alone = False  # they settled a problem on which no solve had concluded
        self._failed_first: dict[tuple, list[LMIProblem]] = {}  # parameters -> problems the primary solver failed on
        self.last_kind = ""
        # the runner of a relaxation on a subset of this model's vertices (their indices) whose certificate holds on
        # every vertex, taken instead of a solve here (alpha_search's cheaper_hint): its duals seed the active vertices
        self.stand_in: tuple[_Runner, tuple[int, ...]] | None = None
        self.estimate = 0.0  # [s] one solve of its problem, estimated (cost.solve_estimate; 0: not estimated)
        self.relaxed: Any = None  # what the relaxation its search started from gave (alpha_search.Relaxed), if any

    def made_by(self) -> list["_Runner"]:
        """This runner and the relaxations whose certificate it took (``stand_in``, each in turn): the solves that made
        its certificate."""
        out: list[_Runner] = [self]
        while out[-1].stand_in is not None and all(r is not out[-1].stand_in[0] for r in out):
            out.append(out[-1].stand_in[0])
        return out

    def attach(self, lp: LMIProblem, cuts: tuple[int, ...] = ()) -> None:
        """The problem of a runner made before it (``lp`` None: phase-1 problems asked first, which may spare it), with
        the within-period vertices ``cuts`` (an earlier search's, same family) posed from its first solve."""
        self.lp = self.active = lp
        if cuts and self.model.covering_vertices and max(cuts) < len(self.model.covering_vertices):
            self.cuts = self.model.with_mirrors(list(cuts))
            self.active = self._build_active()

    def release_compiled(self) -> None:
        """Drop the compiled form of this runner's problems (cvxpy's canonical data, built again at their next solve)
        and give its memory back to the system, before other problems take their own (the phase-1 problems: issue
        51; at d_hi = 3 the full problem's compiled data held 440 MB of the main process's 1.75 GB there).  The
        problems themselves, their parameters and this runner's records stay."""
        held = [self.lp, self.active, self._full] + [p for ps in self._failed_first.values() for p in ps]
        for lp in {id(p): p for p in held if p is not None}.values():
            cache = getattr(lp.problem, "_cache", None)  # cvxpy's compilation cache (cvxpy 1.4 and later)
            if cache is not None and hasattr(cache, "invalidate"):
                cache.invalidate()
        trim_heap()

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
        rounds = row_rounds = 0
        while True:
            skip = unscaled_only or (again and any(p is self.active for p in self._failed_first.get(self._key(), ())))
            try:
                out, res = self._run_mirrored(fallback, retry, skip, force=unscaled_only)
                out = replace(out, attempts=spent + out.attempts)
                break
            except _RowCuts as c:
                spent += c.attempts
                unscaled_only = False
                if row_rounds >= MAX_ROW_ROUNDS or self._builder is None:
                    last = replace(spent[-1], status=f"{spent[-1].status}; heading rows not posed still break it "
                                                     f"after {row_rounds} rounds of row generation")
                    out, res = Outcome("failed", last, spent[:-1] + [last]), (None, None, None)
                    break
                row_rounds += 1
                self.rows = self.rows | frozenset(c.keys)
                self.active = self._build_active()
                self._full = None
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
                self.cuts = self.model.with_mirrors(self.cuts + new)  # (what Model.with_cuts poses)
                self.active = self._build_active()
                self._full = None
        self.last_kind = out.kind
        if out.kind == "failed":
            self.failures += 1
        alpha = self.lp.params.get("alpha")
        if alpha is not None:
            self.failed_at[float(alpha.value)] = out.kind == "failed"
        return (out, *res)

    def settled_at(self, alpha: float) -> tuple[float, float, float, int] | None:
        """Where this problem's phase-1 problems were asked (``phase1``), the interval of theirs that shows no set at
        ``alpha`` (:meth:`.phase1.Phase1.settled_at`), else None.  A search that goes on where they did not settle the
        whole range solves no point of such an interval."""
        return None if self.phase1 is None else self.phase1.settled_at(alpha)

    def _build_active(self) -> LMIProblem:
        """The problem with the within-period vertices and the heading rows added so far (the full builder's)."""
        model = self.model.with_cuts(self.cuts) if self.cuts else self.model
        build = self._grown or self._builder
        return _build(build, model, rows=self.rows) if self.rows is not None else _build(build, model)

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
            if self._full is None:  # (the grown model's, where vertices were added)
                model = self.model.with_cuts(self.cuts) if self.cuts else self.model
                self._full = (_build(self._builder, model, rows=self.rows) if self.rows is not None else
                              _build(self._builder, model))
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
            if self.rows is not None:
                broken = rows_broken(self.model, lp, self.rows)
                if broken:
                    raise _RowCuts(broken)
            chk = check_certificate(self.model, K, cert)
            holder.update(cert=cert, K=K, check=chk)
            failing = varying_failures(chk)
            if failing:
                raise _Cuts(failing)
            return chk.passed

        try:
            out = solve(lp.problem, self.primary, accept, fallback=fallback, retry=retry, skip_first=skip)
        except (_Cuts, _RowCuts) as exc:
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


def _duration(sec: float) -> str:
    return f"{sec:.0f} s" if sec < 90 else f"{sec / 60:.0f} min"


def _attempts(out: Any) -> str:
    return ", ".join(f"{a.name} {a.status} {a.solve_time_s:.2f} s" for a in out.attempts)


def _raise_no_solution(runner: _Runner, objective: str, infeasible_msg: str) -> None:
    """SolverFailure when the solvers failed (also with the fallback), else InfeasibleError(``infeasible_msg``)."""
    if runner.failures:
        raise SolverFailure(f"{objective}: the solvers failed, also with the fallback ({runner.records[-1].status})")
    raise InfeasibleError(infeasible_msg)
