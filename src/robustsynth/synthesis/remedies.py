"""Where no proof for the robot exists: each remedy tried, with the figure it gives (issue 49).

When the nonlinear-kinematics search ends without a certificate (exit 3), the remedies its message names are
tried on copies of the config, cheapest first, within a time budget: the slip-compensated law (tracks model with a
rate bound), a slip box half as wide about its centre, a
bound on the slip's rate, half the reference speed, turns of twice the radius.  A remedy that changes the synthesis
settings (the rate bound under one Lyapunov matrix, which no rate bound changes: with a matrix per slip corner) is
named with why, not tried.  Each try is one quick search
(``first_try``, from :mod:`robustsynth.synthesis.heading_search`: the linearized start as a walk from the main search's
alpha, then one solve at its best alpha for each heading bound auto would try, each screened first by a phase-1
problem on a few vertices where the main search needed those; from d_hi = 2 on the end vertices first, carried to
every vertex where the re-check proves it there), so a figure it gives is one that ``synthesize`` with
that change reaches or improves on, and "none at the first try" proves nothing: it says only that this one try
found no set.  This module does not import the search (it is handed ``first_try``): the search calls it.

Where the system forks, the tries run two at a time, each in a process of its own (:mod:`.forked`): a try's largest
solve runs on one core in a solver process while its own process waits, and the other core ran nothing (the default
robot at d_hi = 2: the half-wide box's one solve on its 64 end vertices took 22 s so, and the half speed's try was
then left untried for want of budget).
"""

from __future__ import annotations

import os
import time
from typing import Any, Callable

from .phase1 import PARALLEL

__all__ = ["try_remedies", "candidates", "FirstTry", "REMEDY_BUDGET_S", "RATE_PERIODS"]

REMEDY_BUDGET_S = 60.0  # [s] the tries together; a remedy whose turn comes after it is named, not tried
RATE_PERIODS = 10  # the tried slip rate crosses the slip box in this many periods
# why a remedy that changes the synthesis settings is named, not tried: a quick try is this search's, on a changed
# robot, network or path (the default robot at d_hi = 2 with a rate bound and a Lyapunov matrix per slip corner: its
# start alone took 55 s, its LMIs 2 152 per alpha against 111)
NOT_QUICK = ("a search with a Lyapunov matrix per slip corner, where a rate bound enters, is no quick try; under one "
             "matrix a rate bound changes no LMI: run synthesize with that change")


def candidates(cfg: Any) -> list[tuple[str, dict[str, Any]]]:
    """The remedies that apply to ``cfg``, as (what it is, in words, the config's changed keys as a nested
    mapping): on the tracks model with a rate bound, the slip-compensated law; the slip box half as wide about its
    centre; where slip may jump, a rate that crosses the box in RATE_PERIODS periods (with a Lyapunov matrix per slip
    corner where the config has one matrix: under one, no rate bound changes an LMI); half the reference speed;
    turns of twice the radius (a turning reference)."""
    slip = cfg.slip
    keys = ["right", "left"] + (["yaw", "icr_offset"] if slip.model == "icr" else [])
    half: dict[str, Any] = {}
    for k in keys:
        r = getattr(slip, k)
        c, w = (r.min + r.max) / 2.0, (r.max - r.min) / 4.0
        half[k] = {"min": c - w, "max": c + w}
    box = ", ".join(f"{k} [{half[k]['min']:.4g}, {half[k]['max']:.4g}]" for k in keys)
    out = []
    if slip.model == "tracks" and slip.max_rate is not None and slip.compensation is None:
        # the law divides each track's command by the monitor's estimate: the certificate covers its error only
        out.append(("slip.compensation (the law divides each track's command by the estimated traction; a proof "
                    "conditional on the estimate, docs/theory.md §18)", {"slip": {"compensation": {"error": "auto"}}}))
    out.append((f"slip half as wide ({box})", {"slip": half}))
    if slip.max_rate is None:
        width = max(slip.right.max - slip.right.min, slip.left.max - slip.left.min)
        rate = width / (RATE_PERIODS * cfg.network.sampling_time)
        what = f"slip.max_rate {rate:.3g} /s (the box crossed in {RATE_PERIODS} periods)"
        if cfg.synthesis.lyapunov == "common":  # one Lyapunov matrix covers every slip sequence: the rate changes no
            # LMI of it; it enters with a matrix per slip corner (Model.lyapunov_conditions), which also takes the slip
            # as constant within a period (docs/theory.md §9)
            out.append((f"{what} with synthesis.lyapunov slip-dependent",
                        {"slip": {"max_rate": rate}, "synthesis": {"lyapunov": "slip-dependent"}}))
        else:
            out.append((what, {"slip": {"max_rate": rate}}))
    out.append((f"reference.speed {cfg.reference.speed / 2.0:g} m/s", {"reference": {"speed": cfg.reference.speed / 2.0}}))
    if cfg.reference.turn_radius is not None:
        out.append((f"reference.turn_radius {2.0 * cfg.reference.turn_radius:g} m",
                    {"reference": {"turn_radius": 2.0 * cfg.reference.turn_radius}}))
    return out


def _merged(base: dict[str, Any], change: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in change.items():
        out[k] = _merged(base.get(k) or {}, v) if isinstance(v, dict) else v
    return out


FirstTry = Callable[[Any, float, Callable[[str], None]], tuple[dict[str, Any] | None, tuple[float, ...]]]


def try_remedies(model: Any, first_try: FirstTry, say: Callable[[str], None], budget_s: float = REMEDY_BUDGET_S,
                 skip: str | None = None, workers: int | None = None) -> list[str]:
    """One line per remedy of :func:`candidates`: the certified |e_y| the quick search found for the robot with it
    (``first_try(model, deadline, say)``: the certified figures or None, and the heading bounds it left untried at the
    deadline), "none at the first try", why it could not be tried (the config refuses the change, the model cannot be
    built), or "not tried" once ``budget_s`` is spent.  Each try's deadline is its share of what is left of the budget
    (what is left over the remedies still to try or running): a try that is slow, or a machine that is busy, leaves
    the later remedies their turn; a try checks it before each heading bound but its first.  A try is started only
    where what is left of the budget holds one as long as the longest so far (on the default robot at
    d_hi = 2 the first try took 33 s, proven with |e_y| <= 4.05 cm; two more were started before, each stopped after
    its first pair of heading bounds).  ``skip``: why no try is started here (each remedy is then named with it, a
    refused one as refused).  A refused remedy, and one no quick try makes (:data:`NOT_QUICK`), is named at no cost,
    and takes no share.

    ``workers``: tries run at once, each in a forked process of its own (:mod:`.forked`; default PARALLEL where the
    system forks and has as many cores, and at least two tries are to run; 1: one after the other in this process),
    each with the share of the budget it would have one after the other; a try still running at the budget's end is
    stopped there.  The lines keep the candidates' order whatever order the tries end in."""
    from ..config import config_to_dict, load_config
    from ..errors import RobustSynthError

    cfg = model.user_config  # a compensated law's remedies change the user's config, not its certificate's
    base = config_to_dict(cfg)
    # each remedy's changed config, or the line that names it untried: a refusal, or a change no quick try makes (a
    # try's share of the budget is then split among the remedies that will be tried)
    plan: list[tuple[str, Any, str | None]] = []
    for what, change in candidates(cfg):
        try:  # the changed config first: a refusal costs nothing (its model and its search do)
            changed = load_config(_merged(base, change))
        except RobustSynthError as exc:
            plan.append((what, None, f"{what}: refused ({exc})"))
            continue
        if skip is not None:
            plan.append((what, None, f"{what}: not tried ({skip})"))
            skip = "the same"  # (said once)
        elif "synthesis" in change:  # a quick try searches with this search's own synthesis settings
            plan.append((what, None, f"{what}: not tried ({NOT_QUICK})"))
        else:
            plan.append((what, changed, None))
    lines = {k: named for k, (_, _, named) in enumerate(plan) if named is not None}
    todo = [k for k, (_, _, named) in enumerate(plan) if named is None]
    from .. import forked

    if workers is None:  # (one core: two tries at once would each get half of it)
        workers = min(PARALLEL, os.cpu_count() or 1) if forked.AVAILABLE else 1
    run = _in_turn if workers <= 1 or len(todo) <= 1 else _at_once
    run(_Tries(model, plan, first_try, say, budget_s, max(1, workers), time.perf_counter()), todo, lines)
    return [lines[k] for k in range(len(plan))]


class _Tries:
    """What the tries share: the plan, the budget and its start, the longest try so far."""

    def __init__(self, model: Any, plan: list, first_try: FirstTry, say: Callable[[str], None], budget_s: float,
                 workers: int, t0: float) -> None:
        self.model, self.plan, self.first_try, self.say = model, plan, first_try, say
        self.budget_s, self.workers, self.t0 = budget_s, workers, t0
        self.longest = 0.0  # [s] the longest try so far

    def refusal(self, k: int) -> str | None:
        """Why remedy ``k`` is not started now (the budget spent, or too little of it left), or None."""
        what = self.plan[k][0]
        left = self.left()
        if left <= 0:
            return f"{what}: not tried (the tries' {self.budget_s:.0f} s were spent)"
        if self.longest > left:
            return (f"{what}: not tried (a try took up to {self.longest:.0f} s here; {left:.0f} s of the tries' "
                    f"{self.budget_s:.0f} s were left)")
        return None

    def left(self) -> float:
        return self.budget_s - (time.perf_counter() - self.t0)

    def deadline(self, to_try: int, running: int) -> float:
        """The deadline of a try started now: what is left, over the tries still to run (this one, those after it,
        and those running).  Tries that run at once get the shares they would get one after the other: they end
        sooner, not later (each may pass its deadline to finish its first heading bound)."""
        return time.perf_counter() + self.left() / (to_try + running)

    def line(self, k: int, outcome: tuple[dict[str, Any] | None, tuple[float, ...]] | str) -> str:
        """Remedy ``k``'s line from its try's (figures, untried bounds), or from why it gave none (a string)."""
        what = self.plan[k][0]
        if isinstance(outcome, str):
            return f"{what}: {outcome}"
        figures, untried = outcome
        if figures is None:
            return f"{what}: none at the first try" + (
                f" (heading bounds {', '.join(f'{b:g}' for b in untried)} rad not tried: its share of the "
                f"{self.budget_s:.0f} s was spent)" if untried else "")
        ub = figures["ultimate_bound"]
        return (f"{what}: proven for the robot, |e_y| <= {100 * ub['e_y']:.2f} cm at the first try "
                f"(heading bound {figures['heading_bound']:g} rad)")


def _in_turn(tries: _Tries, todo: list[int], lines: dict[int, str]) -> None:
    """The tries one after the other, in this process."""
    from ..errors import RobustSynthError

    for n, k in enumerate(todo):
        refused = tries.refusal(k)
        if refused is not None:
            lines[k] = refused
            continue
        what, changed, _ = tries.plan[k]
        tries.say(f"remedy: {what}, a quick search")
        started = time.perf_counter()
        try:
            lines[k] = tries.line(k, tries.first_try(tries.model.rebuilt(changed), tries.deadline(len(todo) - n, 0),
                                                     tries.say))
        except RobustSynthError as exc:  # the model refuses the change, or the search finds it infeasible at once
            lines[k] = tries.line(k, f"refused ({exc})")
        finally:
            tries.longest = max(tries.longest, time.perf_counter() - started)


def _at_once(tries: _Tries, todo: list[int], lines: dict[int, str]) -> None:
    """The tries ``tries.workers`` at a time, each in a forked process; this one waits for them (a signal's handler
    runs meanwhile, and the children it leaves are killed)."""
    from ..errors import RobustSynthError, check_interrupt
    from .. import forked

    queue = list(todo)
    running: dict[Any, int] = {}
    try:
        while queue or running:
            while queue and len(running) < tries.workers:
                k = queue.pop(0)
                refused = tries.refusal(k)
                if refused is not None:
                    lines[k] = refused
                    continue
                what, changed, _ = tries.plan[k]
                n = todo.index(k) + 1
                tries.say(f"remedy {n}: {what}, a quick search ({tries.workers} at a time, each in a process of its own)")
                deadline = tries.deadline(len(queue) + 1, len(running))
                say = tries.say

                def one(changed: Any = changed, deadline: float = deadline, n: int = n) -> Any:
                    return tries.first_try(tries.model.rebuilt(changed), deadline, lambda m: say(f"[remedy {n}] {m}"))

                try:
                    running[forked.Forked(one, expected=(RobustSynthError,))] = k
                except OSError as exc:  # no process for it (fork: EAGAIN, ENOMEM)
                    lines[k] = tries.line(k, f"not tried (no process for it: {exc.strerror or exc})")
            if not running:
                break
            done = forked.wait_any(list(running), until=tries.t0 + tries.budget_s)
            if done is None:  # the budget's end: a try still running is stopped (a process can be)
                for child, k in running.items():
                    child.kill()
                    lines[k] = tries.line(k, f"not concluded (stopped at the end of the tries' {tries.budget_s:.0f} s)")
                running.clear()
                continue
            k = running.pop(done)
            try:
                lines[k] = tries.line(k, done.result())
            except forked.Raised as exc:
                lines[k] = tries.line(k, f"refused ({exc})")
            except forked.ChildError as exc:
                lines[k] = tries.line(k, f"not concluded (its process: {exc})")
            finally:
                tries.longest = max(tries.longest, time.perf_counter() - done.started)
            check_interrupt()
    finally:
        for child in running:
            child.kill()
