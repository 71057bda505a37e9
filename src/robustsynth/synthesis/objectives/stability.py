"""``stability``: the best decay rate r of the disturbance-free state, ``V(xi+) <= r^2 V(xi)`` for every admissible
delay and slip (docs/theory.md §6a); a bisection on r.  A linear plant's: the decay ``synthesis.decay`` (with input
limits, the largest ball at rest inside the set)."""

from __future__ import annotations

from typing import Any, Callable

from ...config import SynthesisConfig
from ...errors import InfeasibleError, SolverFailure
from ..lmis import build_stability
from ..runner import _attempts, _Best, _build, _cert_common, _delay_text, _Runner, _wider_turns

__all__ = ["robot", "linear"]


def robot(model: Any, s: SynthesisConfig, search: list, say: Callable[[str], None]) -> tuple[_Best, _Runner, list[str]]:
    """The bisection on the decay rate (the first point, r ~ 1, decides feasibility)."""
    say(f"{s.objective}: bisection on the decay rate ({model.kind} model, {len(model.vertices)} vertices)")
    return (*_run(model, s, search, say), [])


def linear(job: Any) -> Any:
    """The linear plant's decay at ``synthesis.decay`` (one alpha of the line search, no disturbance)."""
    from ..lti import line_search_design

    return line_search_design(job, dist=False)


def _run(model: Any, s: SynthesisConfig, search: list, say: Callable[[str], None]) -> tuple[_Best, _Runner]:
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


