"""A toy objective, added as docs/architecture.md's "How to add an objective" says (the test beside it registers
it): ``toy-decay`` proves one fixed decay rate ``RATE`` (no search: one solve of the decay LMIs at r = RATE).

Its design is this module (``robot`` and ``linear``); its certificate's rows are tests/objectives/toy_rows.py (on
the checker's side: no solver imported there), the decay LMIs' (6a) rows that ``stability`` proves and a figure of
its own, ``toy_half_life``, the periods in which V halves."""

from __future__ import annotations

from typing import Any, Callable

from robustsynth.objectives import Objective
from robustsynth.synthesis.lmis import build_stability
from robustsynth.synthesis.lti import line_search_design
from robustsynth.synthesis.runner import _Best, _build, _cert_common, _raise_no_solution, _Runner

NAME = "toy-decay"
RATE = 0.99  # the decay rate it proves, per period

# the registry line
TOY = Objective(NAME, "decay", "toy_half_life", f"the decay rate {RATE} of the disturbance-free state, one solve",
                design=__name__, check="tests.objectives.toy_rows", figures=("decay_rate", "toy_half_life"),
                label="periods for V to halve")


def robot(model: Any, s: Any, search: list, say: Callable[[str], None]) -> tuple[_Best, _Runner, list[str]]:
    lp = _build(build_stability, model, s.multiplier, s.margin, s.lyapunov, symmetry=False)

    def make_cert(vals: dict) -> dict:
        return dict(_cert_common(model, vals, s.multiplier, s.margin, NAME), r2=RATE * RATE)

    # full: the same LMIs on a model with cuts (the within-period vertices the re-check finds failing)
    runner = _Runner(model, lp, s.solver, make_cert,
                     full=lambda mdl: build_stability(mdl, s.multiplier, s.margin, s.lyapunov, symmetry=False))
    lp.params["r2"].value = RATE * RATE
    out, cert, K, chk = runner.run()
    search.append({"r": RATE, "status": out.kind})
    say(f"{NAME}: {out.kind}")
    if out.kind != "ok":
        _raise_no_solution(runner, NAME, f"{NAME}: no gain decays at {RATE}")
    best = _Best()
    best.value, best.cert, best.K, best.check, best.record = RATE, cert, K, chk, out.record
    return best, runner, []


def linear(job: Any) -> Any:
    from dataclasses import replace

    return line_search_design(replace(job, decay=RATE), dist=False)
