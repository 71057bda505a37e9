"""Phase-1 problems of the invariance LMIs (synthesis/phase1.py, docs/theory.md §6j): where the solver fails on the
robot proof's LMIs, a problem that always has a solution (maximize t, every vertex LMI >= t I, X <= kappa I) over an
interval of alpha settles it.  Cross-checked against the ordinary solves: never 'proven' where a certificate
exists, and where an interval is proven, no alpha inside it certifies."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from robustsynth.config import mapping_with
from robustsynth.model import build_model
from robustsynth.synthesis.alpha_search import _settled_by_phase1
from robustsynth.synthesis.heading_search import _kinematic
from robustsynth.synthesis.runner import _Runner
from robustsynth.synthesis import lmis, phase1
from robustsynth.synthesis.lmis import build_invariance, heading_row_key
from robustsynth.synthesis.phase1 import (ACTIVE, ACTIVE_ROWS, PHASE1_BOX, T_PROVEN, Active, Phase1, _exact_end_vertices,
                                          prove_no_set, seed)
from robustsynth.synthesis.solve import solve

from ..conftest import committed_gain

ROOT = Path(__file__).resolve().parents[2]
REL = 1e-9  # closed forms against their evaluation in floating point (a handful of roundings of O(1) values)
T_TOL = 1e-7  # t* of two solves compared: Clarabel's tolerances are 1e-9 on the gap and residuals, 'inaccurate' 5e-5 rel.


def _nonlinear_proof(**overrides):
    """configs/nonlinear-proof.yaml with dotted-path overrides: its model and the kinematic channels' settings."""
    cfg = mapping_with(yaml.safe_load((ROOT / "configs" / "nonlinear-proof.yaml").read_text()), **overrides)
    return build_model(cfg), _kinematic(cfg.synthesis)


def test_an_interval_around_a_certified_alpha_is_never_proven() -> None:
    """The committed nonlinear-proof certificate is a solution within the box (its set's |e_x|, |e_y| <= 1 m) at
    its alpha: the phase-1 maximum over any interval holding that alpha is >= 0, so no proof may come out there."""
    m, _, cert = committed_gain("nonlinear-proof")
    Q = np.asarray(cert["Q"], dtype=float)
    assert max(Q[0, 0], Q[1, 1]) <= PHASE1_BOX  # inside the box the phase-1 problems use
    a = float(cert["alpha"])
    _, s = _nonlinear_proof()
    model = m.with_heading_bound(float(cert["heading_bound"]), within_period=True)
    proof = prove_no_set(model, s, bool(cert["motor_limits_enforced"]), (a / 1.1, a * 1.1), intervals=1)
    assert not proof.proven
    assert all(t is not None and t >= -T_PROVEN for _, _, t, _, _ in proof.intervals)
    # tried first on a few vertices (an active set), a relaxation all the same: no proof there either
    few = Active(tuple(range(0, len(model.vertices), 5)))
    proof = prove_no_set(model, s, bool(cert["motor_limits_enforced"]), (a / 1.1, a * 1.1), intervals=1, active=few)
    assert not proof.proven
    assert all(t is not None and t >= -T_PROVEN for _, _, t, _, _ in proof.intervals)


def test_the_vertices_that_bind_are_carried_to_the_next_problems() -> None:
    """The duals of a proof name the vertices that bind (at most ACTIVE); the next interval is settled on them alone,
    in fewer vertices than the end vertices the first proof needed (configs/delay-dlo1.yaml with the nonlinear
    kinematics at 0.3 rad: 36 vertices, 16 end vertices; measured: 8 bind)."""
    cfg = mapping_with(yaml.safe_load((ROOT / "configs" / "delay-dlo1.yaml").read_text()),
                       **{"synthesis.kinematics": "nonlinear"})
    model, s = build_model(cfg).with_heading_bound(0.3, within_period=True), _kinematic(cfg.synthesis)
    active = Active()
    first = prove_no_set(model, s, True, (0.005, 0.0096), intervals=1, active=active)
    assert first.proven and 0 < len(active.indices) <= ACTIVE
    assert all(0 <= i < len(model.vertices) for i in active.indices)
    n_first = first.intervals[0][3]
    again = prove_no_set(model, s, True, (0.0055, 0.0085), intervals=1, active=active)
    assert again.proven, again.summary()
    assert again.intervals[0][3] == len(active.indices) < n_first


def test_the_completion_is_the_delay_vertex_that_binds_most_at_every_slip_corner() -> None:
    """phase1._completion, the step between the active vertices and the end vertices: the active vertices with every
    end vertex whose delay vertex (its instants h_j) is that of the active vertex with the largest dual weight in
    their solved problem: one delay vertex at each slip corner (configs/delay-dlo1.yaml with the nonlinear kinematics
    at 0.3 rad: 36 vertices, 16 end vertices, 4 slip corners).  Nothing where the vertices carry no instants, or where
    no solved problem ranks them."""
    from dataclasses import replace

    cfg = mapping_with(yaml.safe_load((ROOT / "configs" / "delay-dlo1.yaml").read_text()),
                       **{"synthesis.kinematics": "nonlinear"})
    model, s = build_model(cfg).with_heading_bound(0.3, within_period=True), _kinematic(cfg.synthesis)
    ends = _exact_end_vertices(model)
    n_corners = len(model.corners)
    active = tuple(ends[k] for k in (0, 5, 10))  # three end vertices of different delay vertices
    assert len({model.vertices[i].instants for i in active}) == 3
    w = np.array([s.weights.e_x, s.weights.e_y, s.weights.e_theta])
    lp = build_invariance(replace(model, vertices=tuple(model.vertices[i] for i in active)), s.multiplier, s.margin, w,
                          True, s.lyapunov, symmetry=False, phase1=PHASE1_BOX)
    lp.params["one_minus_alpha"].value, lp.params["alpha"].value = 1.0 - 0.005, 0.0096
    assert solve(lp.problem, s.solver, lambda: True, fallback=False).kind == "ok"
    weights = phase1._vertex_weights(lp)
    top = active[int(np.argmax(weights))]
    solved = [(lp, (float(lp.extra["t"].value), "optimal"))]
    got = phase1._completion(model, active, solved, ends)
    same = [i for i in ends if model.vertices[i].instants == model.vertices[top].instants]
    assert got == tuple(sorted(set(active) | set(same)))
    assert len(same) == n_corners == len({model.vertices[i].corner for i in same})  # that delay vertex, every corner
    assert len(active) < len(got) < len(ends)
    bare = replace(model, vertices=tuple(replace(v, instants=()) for v in model.vertices))
    assert phase1._completion(bare, active, solved, ends) is None
    assert phase1._completion(model, active, [], ends) is None
    assert phase1._completion(model, active, [(lp, (None, "solver_error"))], ends) is None  # a failed solve ranks none


def test_the_vertices_that_bind_the_linearized_start_seed_the_first_proof() -> None:
    """Before any phase-1 problem has ranked the vertices, the first starts on those that bind the linearized
    certificate where the search starts (its duals; the nonlinear model has the same vertices in the same order).
    configs/delay-dlo1.yaml at 0.3 rad: unseeded, the first interval needs its 16 end vertices (the test above); seeded
    from the linearized problem's duals at an alpha inside it, fewer settle it.  The linearized problem is posed
    mirror-invariant: a vertex without LMIs of its own stands for its mirror image, which takes its dual weight."""
    cfg = mapping_with(yaml.safe_load((ROOT / "configs" / "delay-dlo1.yaml").read_text()),
                       **{"synthesis.kinematics": "nonlinear"})
    base, s = build_model(cfg), _kinematic(cfg.synthesis)
    lin = base.linearized()
    w = np.array([s.weights.e_x, s.weights.e_y, s.weights.e_theta])
    lp = build_invariance(lin, s.multiplier, s.margin, w, True, "common")
    assert lp.mirrored and len(lp.vertex_lmis) == len(lin.vertices)
    assert any(not cons for cons in lp.vertex_lmis)  # mirrored: some vertices have none of their own
    lp.params["alpha"].value, lp.params["one_minus_alpha"].value = 0.007, 0.993
    assert solve(lp.problem, s.solver, lambda: True, fallback=False).kind == "ok"
    active = Active()
    assert seed(active, lin, lp)
    assert 0 < len(active.seed) <= ACTIVE and active.vertices == len(lin.vertices)
    mirror = lin.mirror("common")
    own = {i for i, cons in enumerate(lp.vertex_lmis) if cons}
    assert set(active.seed) - own, "a mirror image of a vertex that binds is seeded too"
    assert all(i in own or mirror.vertex[i] in own for i in active.seed)
    model = base.with_heading_bound(0.3, within_period=True)
    first = prove_no_set(model, s, True, (0.005, 0.0096), intervals=1, active=active)
    assert first.proven, first.summary()
    assert first.intervals[0][3] == len(active.seed) < len(_exact_end_vertices(model)) == 16
    # a model of another vertex count ignores the seed
    other = Active(seed=active.seed, vertices=len(lin.vertices) + 1)
    again = prove_no_set(model, s, True, (0.005, 0.0096), intervals=1, active=other)
    assert again.intervals[0][3] == 16


def _row_keys(model) -> list[bytes]:
    """The model's distinct heading rows' keys, in the order heading_constraints poses them."""
    keys: list[bytes] = []
    for ch in model.heading_channels:
        for c, d, off in zip(ch.C_h, ch.D_h, ch.heading_offsets):
            if (k := heading_row_key(c, d, off)) not in keys:
                keys.append(k)
    return keys


def test_fewer_heading_rows_are_a_relaxation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Posed as linear rows (beyond LIFT_ROWS: here forced), a phase-1 problem on a subset of the heading rows has a
    maximum t* at least the one on every row (a relaxation: a proof on it is one) and poses exactly those rows (the
    certificate's LMIs on a subset are a relaxation too, whose solution is taken only where it holds every row:
    test_row_generation_...)."""
    monkeypatch.setattr(lmis, "LIFT_ROWS", 0)
    m, s = _nonlinear_proof(**{"synthesis.integral_action": True})
    model = m.with_heading_bound(0.2, within_period=True)
    keys = _row_keys(model)
    some = frozenset(keys[::4])
    w = np.array([1.0, 1.0, 1.0])
    t = {}
    for name, rows in (("all", None), ("some", some)):
        lp = build_invariance(model, s.multiplier, s.margin, w, True, s.lyapunov, symmetry=False, phase1=PHASE1_BOX,
                              heading_rows=rows)
        assert set(lp.extra["heading_keys"]) == (set(keys) if rows is None else some)
        lp.params["one_minus_alpha"].value, lp.params["alpha"].value = 1.0 - 0.005, 0.0096
        out = solve(lp.problem, s.solver, lambda: True, fallback=False, retry=True)
        assert out.kind == "ok"
        t[name] = float(lp.extra["t"].value)
        vals = lp.values()  # its variables' values, the posed rows' keys and constraints left out
        assert float(vals["t"]) == t[name] and vals["beta"].shape == lp.extra["beta"].shape
        assert "heading_keys" not in vals and "heading_rows" not in vals
    assert t["all"] <= -T_PROVEN  # (the interval test_a_proven_interval_has_no_certifiable_alpha_inside proves)
    assert t["some"] >= t["all"] - T_TOL, t


def test_the_heading_rows_that_bind_are_carried_to_the_next_problems(monkeypatch: pytest.MonkeyPatch) -> None:
    """Posed as linear rows, the duals of a proof also name the heading rows that bind (at most ACTIVE_ROWS, fewer
    than all); the next interval is tried first on the active vertices with those rows alone, and settles there
    (configs/delay-dlo1.yaml with the nonlinear kinematics at 0.3 rad, as for the vertices)."""
    monkeypatch.setattr(lmis, "LIFT_ROWS", 0)
    cfg = mapping_with(yaml.safe_load((ROOT / "configs" / "delay-dlo1.yaml").read_text()),
                       **{"synthesis.kinematics": "nonlinear"})
    model, s = build_model(cfg).with_heading_bound(0.3, within_period=True), _kinematic(cfg.synthesis)
    active = Active()
    assert prove_no_set(model, s, True, (0.005, 0.0096), intervals=1, active=active).proven
    assert active.rows is not None and 0 < len(active.rows) <= min(ACTIVE_ROWS, len(_row_keys(model)) - 1)
    said: list[str] = []
    again = prove_no_set(model, s, True, (0.0055, 0.0085), intervals=1, active=active, say=said.append)
    assert again.proven, again.summary()
    first = said[0]  # the first try: the active vertices, the active rows only, and it settled the interval
    assert f"({len(active.indices)} vertices, " in first and " heading rows)" in first, said
    assert len(said) == 1, said


def test_a_proven_interval_has_no_certifiable_alpha_inside() -> None:
    """Integral action at heading bound 0.2 rad has no set at small alphas: the phase-1 problem over [0.005, 0.0096]
    proves it (t* < 0), and the ordinary LMIs at alphas inside the interval are not solvable either."""
    m, s = _nonlinear_proof(**{"synthesis.integral_action": True})
    model = m.with_heading_bound(0.2, within_period=True)
    proof = prove_no_set(model, s, True, (0.005, 0.0096), intervals=1)
    assert proof.proven, proof.summary()
    lp = build_invariance(model, s.multiplier, s.margin, np.array([1.0, 1.0, 1.0]), True, s.lyapunov, symmetry=False)
    for a in (0.005, 0.007, 0.0096):
        lp.params["alpha"].value = a
        lp.params["one_minus_alpha"].value = 1.0 - a
        out = solve(lp.problem, s.solver, lambda: True, fallback=False, retry=True)
        assert out.kind != "ok", a


def test_a_proof_turns_the_failed_points_into_infeasible_ones() -> None:
    """The search's bookkeeping: where the phase-1 problems settle the range, the alphas at which the solver failed
    count as infeasible (the exit is 3 with the evidence, not 4); where they do not, only those in an interval they
    settled do (0.05 in [0.005, 0.1]), and the others stay failed."""
    m, s = _nonlinear_proof()
    runner = _Runner(m, None, s.solver, lambda vals: {})  # (the problem is not solved here)
    for proven in (False, True):
        runner.failed_at, runner.failures, runner.phase1 = {0.05: True, 0.1: False, 0.2: True}, 2, None
        proof = Phase1(0.005, 0.95, [(0.005, 0.1, -1e-3, 8, "optimal"), (0.1, 0.95, -2e-3 if proven else 1e-4, 8, "optimal")])
        search: list = []
        assert _settled_by_phase1(runner, lambda p=proof: p, search, lambda _m: None) is proven
        assert runner.phase1 is proof
        assert [e["status"] for e in search] == ["infeasible", "infeasible" if proven else "failed"]
        if proven:
            assert runner.failed_at == {0.05: False, 0.1: False, 0.2: False} and runner.failures == 0
        else:
            assert runner.failed_at == {0.05: False, 0.1: False, 0.2: True} and runner.failures == 1
            assert runner.settled_at(0.05) == (0.005, 0.1, -1e-3, 8) and runner.settled_at(0.2) is None


def test_a_point_the_phase_1_problems_show_has_no_set_is_not_solved() -> None:
    """Where the phase-1 problems settled part of the range, the search solves no alpha of a settled interval (it is
    infeasible there, with the evidence in the search record) and solves the others as before: the interval that did
    not settle, and any alpha once no phase-1 problem was asked."""
    from robustsynth.synthesis.alpha_search import _Evaluator
    from robustsynth.synthesis.runner import _Best, _weights

    from .conftest import invariance_runner

    m, s = _nonlinear_proof()
    lp, runner = invariance_runner(m, "common", 0.1)
    evaluate = _Evaluator(lp, runner, _Best(), _weights(s), search := [], lambda _m: None)
    runner.phase1 = Phase1(0.005, 0.95, [(0.005, 0.05, -1e-3, 8, "optimal"), (0.05, 0.95, 1e-4, 8, "optimal")])
    assert evaluate(float(np.log(0.02))) == np.inf and runner.solves == 0
    assert search[-1] == {"alpha": 0.02, "status": "infeasible", "objective": None, "by": "phase-1 (8 vertices)"}
    assert evaluate.last.kind == "infeasible" and runner.failed_at[0.02] is False and runner.failures == 0
    evaluate(float(np.log(0.1)))  # in the interval that did not settle: solved, whatever it gives
    assert runner.solves == 1 and abs(search[-1]["alpha"] - 0.1) <= 1e-12 and "by" not in search[-1]
    runner.phase1 = None
    evaluate(float(np.log(0.03)))
    assert runner.solves == 2 and "by" not in search[-1]
    # a screen (a phase-1 problem at one alpha) is asked before a solve only where the range was left unsettled
    asked: list[float] = []
    evaluate.screen = lambda a: asked.append(a) or abs(a - 0.3) <= 1e-12
    evaluate(float(np.log(0.4)))  # no phase-1 problems over the range were asked: no screen
    assert not asked and runner.solves == 3
    runner.phase1 = Phase1(0.005, 0.95, [(0.005, 0.05, -1e-3, 8, "optimal"), (0.05, 0.95, 1e-4, 8, "optimal")])
    assert evaluate(float(np.log(0.3))) == np.inf and runner.solves == 3 and len(asked) == 1
    assert search[-1]["status"] == "infeasible" and search[-1]["by"] == "phase-1 at this alpha"
    evaluate(float(np.log(0.5)))  # the screen shows a set there: solved
    assert len(asked) == 2 and runner.solves == 4
    # what a relaxation of this problem is told: its certificate is of no use where this one has no set
    assert evaluate.useless_for_whole(0.02) and evaluate.useless_for_whole(0.3) and not evaluate.useless_for_whole(0.5)
    evaluate.useless = lambda a: abs(a - 0.6) <= 1e-12  # (as a relaxation's search: no solve where the whole has none)
    assert evaluate(float(np.log(0.6))) == np.inf and runner.solves == 4 and search[-1]["by"] == "of no use"


def test_a_runner_that_released_its_compiled_problem_solves_it_again_to_the_same_bits() -> None:
    """Before the phase-1 problems, the search's runner drops its problems' compiled data (issue 51: memory); a
    solve after that compiles them again and gives what the first solve gave, bit for bit (Clarabel from scratch is
    deterministic), and nothing of the runner's records is lost."""
    from robustsynth.synthesis.solve import SOLVER_OPTIONS

    from .conftest import invariance_runner

    model, _ = _nonlinear_proof()
    assert SOLVER_OPTIONS["clarabel"]["warm_start"] is False  # else the second solve could start from the first
    lp, runner = invariance_runner(model, "common", 0.1)
    first, _, K1, chk1 = runner.run(fallback=False)
    assert first.kind == "ok" and chk1.passed
    assert lp.problem._cache.param_prog is not None  # compiled (the test sees the release)
    runner.release_compiled()
    assert lp.problem._cache.param_prog is None and runner.solves == 1
    again, _, K2, chk2 = runner.run(fallback=False)
    assert again.kind == "ok" and chk2.passed and np.array_equal(K1, K2) and runner.solves == 2


def _proofs_at(heading: float):
    """configs/nonlinear-proof.yaml's model at ``heading`` with its settings, and two stand-in phase-1 answers over
    the whole range, one proven (t* -1e-3) and one not (+1e-3): (t*, prove, the list each call of prove appends to)."""
    m, s = _nonlinear_proof()
    cases = []
    for t in (-1e-3, 1e-3):
        asked: list[int] = []

        def prove(t=t, asked=asked) -> Phase1:
            asked.append(1)
            return Phase1(0.005, 0.95, [(0.005, 0.95, t, 8, "optimal")])

        cases.append((t, prove, asked))
    return m.with_heading_bound(heading, within_period=True), s, cases


def test_asked_first_the_phase1_problems_spare_every_solve_or_are_asked_once() -> None:
    """After a heading bound that only phase-1 problems settled, the next bound asks them before any solve
    (``prove_first``): proven, no solve is made, nor the problem built (at d_hi = 5 ~0.5 GB), and the next bound
    will ask first too; not proven, the hinted search runs as without them, and they are not asked a second time where
    its solves fail."""
    from robustsynth.synthesis.alpha_search import _run_invariance

    model, s, cases = _proofs_at(0.2)
    for t, prove, asked in cases:
        best, runner = _run_invariance(model, s, [], True, alpha_hint=0.2, retry=False, prove=prove, prove_first=True)
        assert len(asked) == 1
        if t < 0:
            assert best.cert is None and runner.solves == 0 and runner.phase1_alone and runner.lp is None
        else:
            assert runner.solves > 0 and best.cert is not None  # (the committed certificate's class: it certifies)
            assert runner.lp is not None


def test_where_one_solve_would_cost_a_minute_the_phase1_problems_go_first(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where one solve is estimated at PROVE_FIRST_S or more (the icr default at d_hi 3: about 2 min, where it ended in
    solver_error after 124 s), the phase-1 problems are asked before any solve, as after a bound the solver failed on:
    proven, no solve is made; not proven, the search runs as without them and certifies.  Below it (every committed
    config), not before a solve."""
    from robustsynth.synthesis import alpha_search
    from robustsynth.synthesis.alpha_search import _run_invariance
    from robustsynth.synthesis.cost import solve_estimate

    model, s, cases = _proofs_at(0.2)
    est = solve_estimate(build_invariance(model, s.multiplier, s.margin, np.ones(3), True, s.lyapunov,
                                          symmetry=s.symmetry == "auto"))
    assert est < alpha_search.PROVE_FIRST_S  # this problem is a cheap one: the threshold is lowered below its estimate
    monkeypatch.setattr(alpha_search, "PROVE_FIRST_S", est / 2)
    for t, prove, asked in cases:
        lines: list[str] = []
        best, runner = _run_invariance(model, s, [], True, say=lines.append, alpha_hint=0.2, retry=False, prove=prove)
        assert len(asked) == 1 and "phase-1 problems over the alpha range first" in lines[1], lines[:3]
        if t < 0:
            assert best.cert is None and runner.solves == 0
        else:
            assert runner.solves > 0 and best.cert is not None
    monkeypatch.setattr(alpha_search, "PROVE_FIRST_S", est * 2)
    _, _, again = _proofs_at(0.2)
    t, prove, asked = again[0]
    best, runner = _run_invariance(model, s, [], True, alpha_hint=0.2, retry=False, prove=prove)
    assert not asked and best.cert is not None  # certified at the hint: no phase-1 problem asked


def test_where_a_solve_is_costly_a_screen_at_the_hint_that_shows_no_set_sends_the_phase1_problems_first(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Where one solve is estimated at COSTLY_SOLVE_S or more (the icr default at d_hi 2: 11 s, where the hint's solve
    ended in solver_error after 19 s), a phase-1 problem at the hint (``screen``) is asked before the hint's solve:
    where it shows no set there, the phase-1 problems over the range go first (proven: no solve at all); where it shows
    one, the search solves at the hint as without it and certifies.  Below the threshold (every committed config) the
    screen is not asked.  Where the phase-1 problems leave the range unsettled, each later costly solve is screened at
    its own alpha first (here the screen shows no set at the hint only: the search then certifies as before)."""
    from robustsynth.synthesis import alpha_search
    from robustsynth.synthesis.alpha_search import _run_invariance
    from robustsynth.synthesis.cost import solve_estimate

    model, s, cases = _proofs_at(0.2)
    est = solve_estimate(build_invariance(model, s.multiplier, s.margin, np.ones(3), True, s.lyapunov,
                                          symmetry=s.symmetry == "auto"))
    assert est < alpha_search.COSTLY_SOLVE_S  # a cheap problem: the threshold is lowered below its estimate
    monkeypatch.setattr(alpha_search, "COSTLY_SOLVE_S", est / 2)
    for none_there in (True, False):
        # (a set at the hint: the stand-in proof's answer is never asked, one case tells it)
        for t, prove, asked in _proofs_at(0.2)[2][: 2 if none_there else 1]:
            screened: list[float] = []
            lines: list[str] = []
            best, runner = _run_invariance(model, s, [], True, say=lines.append, alpha_hint=0.2, retry=False,
                                           prove=prove, screen=lambda a: screened.append(a) or (none_there and a == 0.2))
            assert screened[0] == 0.2 and len(set(screened)) == len(screened)  # each alpha screened once
            # past an unsettled range every costly solve is screened first; else only the hint is
            assert (len(screened) > 1) == (none_there and t > 0), screened
            if none_there:
                assert len(asked) == 1 and "shows no set there" in lines[1], lines[:3]
            else:  # a set at the hint: the search as without the screen, whose hint certifies
                assert not asked
            if none_there and t < 0:
                assert best.cert is None and runner.solves == 0 and runner.phase1_alone
            else:  # (the committed certificate's class at the hint: it certifies)
                assert runner.solves > 0 and best.cert is not None
    # past a certified heading bound (``bar``): no set at the hint ends the search there, as its solve would have
    t, prove, asked = _proofs_at(0.2)[2][0]
    best, runner = _run_invariance(model, s, [], True, alpha_hint=0.2, retry=False, prove=prove, bar=1.0,
                                   screen=lambda a: True)
    assert best.cert is None and runner.solves == 0 and not asked
    monkeypatch.setattr(alpha_search, "COSTLY_SOLVE_S", est * 2)
    screened = []
    best, runner = _run_invariance(model, s, [], True, alpha_hint=0.2, retry=False, prove=cases[0][1],
                                   screen=lambda a: screened.append(a) or True)
    assert not screened and best.cert is not None


def test_the_screen_at_a_certified_alpha_shows_a_set_and_without_known_vertices_solves_nothing() -> None:
    """phase1.screen_at on the vertices that bind the committed certificate of configs/nonlinear-proof.yaml, at its
    own alpha and heading bound: a subset of the vertices is a relaxation, so where the whole certifies it cannot show
    'no set' (t* > 0 on them).  An Active of another model's vertex count, or with none, asks no solve."""
    m, K, cert = committed_gain("nonlinear-proof")
    _, s = _nonlinear_proof()
    model = m.with_heading_bound(float(cert["heading_bound"]), within_period=bool(m.covering_vertices))
    lp = build_invariance(model, s.multiplier, s.margin, np.ones(3), True, s.lyapunov, symmetry=False)
    lp.params["alpha"].value = float(cert["alpha"])
    lp.params["one_minus_alpha"].value = 1.0 - float(cert["alpha"])
    assert solve(lp.problem, s.solver, lambda: True).kind == "ok"
    active = Active()
    assert seed(active, model, lp) and active.seed
    said: list[str] = []
    assert not phase1.screen_at(model, s, True, float(cert["alpha"]), active, said.append)
    assert said and "t* = " in said[0] and active.indices
    for other in (Active(vertices=len(model.vertices) + 1, seed=(0,)), Active(vertices=len(model.vertices))):
        assert not phase1.screen_at(model, s, True, float(cert["alpha"]), other, said.append)
    assert len(said) == 1
    # where an interval is proven (integral action at 0.2 rad, alpha in [0.005, 0.0096]: the test below), the screen at
    # an alpha inside it shows no set: a single alpha's problem is tighter than the interval's
    mi, si = _nonlinear_proof(**{"synthesis.integral_action": True})
    mi = mi.with_heading_bound(0.2, within_period=True)
    assert prove_no_set(mi, si, True, (0.005, 0.0096), intervals=1).proven
    every = Active(indices=tuple(range(len(mi.vertices))), vertices=len(mi.vertices))
    assert phase1.screen_at(mi, si, True, 0.007, every, said.append)


def test_an_infeasible_hint_where_solves_are_costly_asks_the_phase1_problems_before_the_scan() -> None:
    """Where each solve is costly (``gain_rule``: as where one is estimated at COSTLY_SOLVE_S or more; the icr default
    at d_hi 2 takes 15-90 s a solve) and the hint's solve ends infeasible, the phase-1 problems are asked before the
    descent and the scan: proven, that one solve is all (the search of the heading bound ends there); not proven,
    the search descends and scans as without them, and finds the certificate below the hint."""
    from robustsynth.synthesis.alpha_search import _run_invariance

    model, s, cases = _proofs_at(0.2)
    for t, prove, asked in cases:
        lines: list[str] = []
        best, runner = _run_invariance(model, s, [], True, say=lines.append, alpha_hint=0.9, retry=False, prove=prove,
                                       gain_rule=True)
        assert len(asked) == 1 and lines[1].startswith("  alpha = 0.9: infeasible"), lines[:3]
        assert "infeasible at the hint, and each solve is costly" in lines[2]
        if t < 0:
            assert best.cert is None and runner.solves == 1 and not runner.phase1_alone
        else:
            assert runner.solves > 1 and best.cert is not None


def test_the_synthesis_report_lists_the_phase1_intervals_among_the_alphas() -> None:
    """synthesis.md's search table holds the phase-1 intervals beside the solved alphas, in alpha order, each with
    its t* (a KeyError on them once broke `synthesize` of configs/nonlinear-proof.yaml after the search)."""
    from types import SimpleNamespace

    from robustsynth.report.synthesis import _search_markdown

    search = [{"alpha": 0.2, "status": "ok", "objective": 1e-3},
              {"alpha_interval": [0.005, 0.0096], "status": "infeasible", "objective": None, "by": "phase-1 (8 vertices)",
               "t": -1e-3},
              {"alpha_interval": [0.0096, 0.0186], "status": "failed", "objective": None, "by": "phase-1 (12 vertices)",
               "t": None}]
    text = _search_markdown(SimpleNamespace(search=search))
    rows = [line for line in text.splitlines() if line.startswith("| ") and "alpha" not in line]
    assert [r.split("|")[1].strip() for r in rows] == ["[0.005, 0.0096]", "[0.0096, 0.0186]", "0.2"]
    assert "t* = -0.001" in rows[0] and "the solver failed" in rows[1]


@pytest.mark.slow
def test_below_an_infeasible_hint_the_search_descends_and_finds_the_full_scans_bound() -> None:
    """Integral action at 0.3 rad: the linearized start's alpha (~0.127) is infeasible and the feasible alphas lie
    below it.  The search descends the grid from the hint (alpha_search._descend) instead of scanning it from its
    bottom: fewer solves, every one at or below the hint, and the bound of the full scan (both refined to
    COSTLY_STOP_REL's 0.1 % on the bound)."""
    from robustsynth.synthesis.alpha_search import COSTLY_STOP_REL, _run_invariance

    m, s = _nonlinear_proof(**{"synthesis.integral_action": True})
    model = m.with_heading_bound(0.3, within_period=True)
    hint = 0.1267
    down: list = []
    b1, r1 = _run_invariance(model, s, down, True, alpha_hint=hint, retry=False, stop_rel=COSTLY_STOP_REL)
    full: list = []
    b2, r2 = _run_invariance(model, s, full, True, retry=False, stop_rel=COSTLY_STOP_REL)
    assert b1.cert is not None and b2.cert is not None
    assert all(p["alpha"] <= hint * (1 + 1e-12) for p in down)
    assert r1.solves < r2.solves, (r1.solves, r2.solves)
    BOUND_REL = 2e-3  # both refinements stop within 0.1 % of the bound along alpha
    e1, e2 = (b.check.figures["ultimate_bound"]["e_y"] for b in (b1, b2))
    assert e1 <= e2 * (1 + BOUND_REL), (e1, e2)


def test_the_rows_nearest_their_bound_on_the_start_s_set_seed_the_first_problems(monkeypatch: pytest.MonkeyPatch) -> None:
    """Before any problem has ranked the heading rows, seed_rows picks the ACTIVE_ROWS rows that the set of a gain
    reaches farthest against their room: a row r xi + d du reaches sqrt(z Q z') with z = r + d K on {xi' Q^-1 xi <= 1},
    cross-checked here against the largest |z xi| over points of that set's boundary (xi = L u, Q = L L', u on the unit
    sphere).  Only where the rows are posed as linear rows (beyond LIFT_ROWS: here forced), never over rows of the model
    ranked already, and again where the rows held are another model's.  On configs/nonlinear-proof.yaml at 0.2 rad (its
    committed gain's set) the few rows nearest their bound settle the interval that every row settles, and the same
    number of the farthest rows does not: the ranking is what makes the first problems' subset a proof."""
    monkeypatch.setattr(lmis, "LIFT_ROWS", 0)
    monkeypatch.setattr(phase1, "ACTIVE_ROWS", 4)
    m, K, cert = committed_gain("nonlinear-proof")
    _, s = _nonlinear_proof()
    model = m.with_heading_bound(0.2, within_period=True)
    Q = np.asarray(cert["Q"], dtype=float)
    rows, keys = lmis.heading_rows(model)
    assert keys == _row_keys(model) and len(rows) > 2 * phase1.ACTIVE_ROWS
    # the reach, closed form, against the set's boundary: 20 000 random points of it never exceed it, and each row's
    # maximizer xi* = L u*, u* = L' z' / |L' z'| (on the boundary) attains it
    L = np.linalg.cholesky(Q)
    u = np.random.default_rng(0).normal(size=(20000, model.n_s))
    xi = (u / np.linalg.norm(u, axis=1, keepdims=True)) @ L.T
    Z = np.array([c + d @ K for c, d, _ in rows])
    reach = np.sqrt(np.einsum("ia,ab,ib->i", Z, Q, Z))
    assert np.all(np.abs(xi @ Z.T).max(axis=0) <= reach * (1 + REL))
    top = Z @ L
    best = (top / np.linalg.norm(top, axis=1, keepdims=True)) @ L.T  # (rows, n_s): each row's maximizer
    assert np.allclose(np.einsum("ia,ab,ib->i", best, np.linalg.inv(Q), best), 1.0, rtol=REL)
    assert np.allclose(np.einsum("ia,ia->i", best, Z), reach, rtol=REL)
    ratio = reach / np.array([room for _, _, room in rows])
    active = Active()
    assert phase1.seed_rows(active, model, Q, K)
    assert list(active.rows) == [keys[i] for i in np.argsort(-ratio, kind="stable")[:4]]
    assert not phase1.seed_rows(active, model, Q, K)  # ranked already: kept
    other = Active(rows=(b"another model's row",))
    assert phase1.seed_rows(other, model, Q, K) and other.rows == active.rows
    monkeypatch.setattr(lmis, "LIFT_ROWS", len(rows))  # posed as LMIs (the rows others imply left out): no subset
    assert not phase1.seed_rows(Active(), model, Q, K)
    monkeypatch.setattr(lmis, "LIFT_ROWS", 0)
    # the nearest rows settle the interval every row settles (test_fewer_heading_rows_..., t* -T_PROVEN or below);
    # the farthest do not
    w = np.array([1.0, 1.0, 1.0])
    far = frozenset(keys[i] for i in np.argsort(ratio, kind="stable")[:4])
    t = {}
    for name, subset in (("nearest", frozenset(active.rows)), ("farthest", far)):
        lp = build_invariance(model, s.multiplier, s.margin, w, True, s.lyapunov, symmetry=False, phase1=PHASE1_BOX,
                              heading_rows=subset)
        lp.params["one_minus_alpha"].value, lp.params["alpha"].value = 1.0 - 0.005, 0.0096
        assert solve(lp.problem, s.solver, lambda: True, fallback=False, retry=True).kind == "ok"
        t[name] = float(lp.extra["t"].value)
    assert t["nearest"] <= -T_PROVEN < t["farthest"], t


def test_a_remedy_s_screen_poses_the_rows_its_own_start_ranks(monkeypatch: pytest.MonkeyPatch) -> None:
    """A remedy's quick try screens each heading bound by a phase-1 problem on the main search's active vertices; the
    rows the main search ranked are its own model's (keys naming none of the remedy's rows: posed, they would select
    none, and every row would be posed: 60 281 on the icr default at d_hi = 3), so the screen poses the ACTIVE_ROWS rows
    seeded from the remedy's own start instead (configs/nonlinear-proof.yaml, rows posed as linear rows: forced)."""
    from robustsynth.synthesis import heading_search

    monkeypatch.setattr(lmis, "LIFT_ROWS", 0)
    monkeypatch.setattr(phase1, "ACTIVE_ROWS", 4)
    cfg = mapping_with(yaml.safe_load((ROOT / "configs" / "nonlinear-proof.yaml").read_text()))
    model = build_model(cfg)
    posed: list[tuple[frozenset[bytes] | None, frozenset[bytes]]] = []
    build = phase1.build_invariance

    def recording(m, *args, heading_rows=None, **kwargs):
        posed.append((heading_rows, frozenset(lmis.heading_rows(m)[1])))
        return build(m, *args, heading_rows=heading_rows, **kwargs)

    monkeypatch.setattr(phase1, "build_invariance", recording)
    _, _, cert = committed_gain("nonlinear-proof")
    n = len(model.with_heading_bound(0.2, within_period=True).vertices)
    active = Active(indices=tuple(range(0, n, 2))[:ACTIVE], vertices=n, rows=(b"another model's row",))
    heading_search._first_try(model, cfg.synthesis, True, hint=float(cert["alpha"]), active=active)
    assert posed, "the screen ran"
    for rows, keys in posed:
        assert rows is not None and len(rows) == 4 and rows <= keys


def test_far_from_any_set_the_next_bound_cuts_the_range_into_fewer_intervals() -> None:
    """Phase1.next_layout: a proof whose intervals all settled at once on the active vertices with t* <= -COARSEN_T has
    the next bound cut the range into half as many (at least PARALLEL); settled unhalved nearer 0, or on more vertices,
    as many; halved or unsettled, twice as many (at most INTERVALS).  halvings_for keeps the finest interval as fine."""
    far, near = -2 * phase1.COARSEN_T, -phase1.COARSEN_T / 2

    def proof(ts, n=ACTIVE):
        return Phase1(0.005, 0.95, [(0.0, 1.0, t, n, "optimal") for t in ts])

    assert proof([far] * 8).next_layout(8, ACTIVE) == 4
    assert proof([far] * 2).next_layout(2, ACTIVE) == phase1.PARALLEL == 2
    assert proof([far] * 7 + [near]).next_layout(8, ACTIVE) == 8
    assert proof([far] * 4, n=ACTIVE + 6).next_layout(4, ACTIVE) == 4  # settled on the end vertices: not coarser
    assert proof([far] * 5).next_layout(4, ACTIVE) == 8  # one of the four halved
    assert proof([far] * 3 + [None]).next_layout(4, ACTIVE) == 8  # unsettled
    assert proof([near] * 9).next_layout(8, ACTIVE) == phase1.INTERVALS == 8
    for n in (8, 4, 2, 1):
        assert n * 2 ** phase1.halvings_for(n) == phase1.INTERVALS * 2 ** phase1.HALVINGS


def test_the_row_table_is_the_row_by_row_enumeration() -> None:
    """lmis.heading_row_table (numpy, one pass) holds the rows heading_constraints poses, in its order, with the keys
    and coefficients of the row-by-row enumeration (_row_keys); ``indices`` finds exactly the rows of the keys it is
    given and none for a key of another width or of no row; rooms are theta_bar - offset and a bound below an offset
    is refused (configs/nonlinear-proof.yaml with integral action at 0.2 rad, configs/turns.yaml at 0.3 rad)."""
    from robustsynth.errors import InfeasibleError

    for name, tb, extra in (("nonlinear-proof", 0.2, {"synthesis.integral_action": True}), ("turns", 0.3, {})):
        cfg = mapping_with(yaml.safe_load((ROOT / "configs" / f"{name}.yaml").read_text()),
                           **{"synthesis.kinematics": "nonlinear", **extra})
        model = build_model(cfg).with_heading_bound(tb, within_period=True)
        table = lmis.heading_row_table(model)
        keys = _row_keys(model)
        assert table.keys() == keys and len(table) == len(keys)
        rows, _ = lmis.heading_rows(model)
        for (c, d, room), v, off in zip(rows, table.V, table.offsets):
            assert np.array_equal(np.concatenate([c, d]), v) and room == tb - off
        some = keys[1::3]
        assert list(table.indices(some + [b"no row" * 8, keys[0][:-8]])) == list(range(1, len(keys), 3))
        assert len(table.indices([])) == 0
        with pytest.raises(InfeasibleError, match="smaller than the turn"):
            table.rooms(model.with_heading_bound(float(table.offsets.max()) / 2, within_period=True))


def _farthest(model, Q, K, n: int) -> frozenset[bytes]:
    """The ``n`` heading rows farthest from their bound on the set of (Q, K): a subset whose problems break others."""
    table = lmis.heading_row_table(model)
    IK = np.vstack([np.eye(model.n_s), K])
    ratio = lmis.row_ratios(table, table.rooms(model), [IK @ Q @ IK.T])
    return frozenset(table.keys(np.argsort(ratio, kind="stable")[:n]))


def test_row_generation_names_exactly_the_rows_whose_lmi_the_solution_breaks(monkeypatch: pytest.MonkeyPatch) -> None:
    """rows_broken, on a certificate's LMIs solved with a few heading rows (the farthest from their bound: rows posed
    as linear rows, forced), names the rows not posed whose own LMI [[room^2 (1 - 1e-6), z R], [R' z', Q]] >= 0 the
    solution breaks: each is checked here by that LMI's least eigenvalue (numpy), an independent test of the closed
    form sqrt(z W z') / room it ranks by; the worst first, at most ROW_BATCH; none where every row was posed
    (configs/nonlinear-proof.yaml at 0.15 rad, where rows bind, alpha 0.2)."""
    monkeypatch.setattr(lmis, "LIFT_ROWS", 0)
    m, K, cert = committed_gain("nonlinear-proof")
    _, s = _nonlinear_proof()
    model = m.with_heading_bound(0.15, within_period=True)
    table = lmis.heading_row_table(model)
    rooms = table.rooms(model)
    posed = _farthest(model, np.asarray(cert["Q"], dtype=float), K, 4)
    lp = build_invariance(model, s.multiplier, s.margin, np.array([1.0, 1.0, 1.0]), True, s.lyapunov, symmetry=False,
                          heading_rows=posed)
    lp.params["alpha"].value, lp.params["one_minus_alpha"].value = GEN_ALPHA, 1.0 - GEN_ALPHA
    assert solve(lp.problem, s.solver, lambda: True, fallback=False, retry=True).kind == "ok"
    monkeypatch.setattr(lmis, "ROW_BATCH", 10**6)
    named = lmis.rows_broken(model, lp, posed)
    Q, Y = np.asarray(lp.Q.value), np.asarray(lp.Y.value)
    R = np.vstack([Q, Y])
    held = set(table.indices(posed).tolist())
    least = np.array([np.linalg.eigvalsh(np.block([[np.array([[rooms[i] ** 2 * (1 - 1e-6)]]), (table.V[i] @ R)[None]],
                                                   [(table.V[i] @ R)[:, None], Q]]))[0] for i in range(len(table))])
    EIG_REL = 1e-9  # an LMI's least eigenvalue against its size: rounding of a handful of products
    scale = rooms**2 + np.linalg.norm(Q, 2)
    breaks = {i for i in range(len(table)) if i not in held and least[i] < -EIG_REL * scale[i]}
    holds = {i for i in range(len(table)) if i not in held and least[i] > EIG_REL * scale[i]}
    idx = set(table.indices(named).tolist())
    assert breaks and breaks <= idx and not (idx & holds), (len(breaks), len(idx), len(holds))
    ratio = lmis.row_ratios(table, rooms, lmis.heading_weights(lp))
    order = [float(ratio[table.indices([k])[0]]) for k in named]
    assert order == sorted(order, reverse=True)  # the worst first
    monkeypatch.setattr(lmis, "ROW_BATCH", 2)
    assert lmis.rows_broken(model, lp, posed) == named[:2]
    assert lmis.rows_broken(model, lp, None) is None  # every row posed: nothing to generate
    assert lmis.rows_broken(model, lp, frozenset([b"another model's row"])) is None  # (so were they here)


GEN_ALPHA = 0.2  # configs/nonlinear-proof.yaml at 0.15 rad: certified with every row, and 4 rows leave 3 broken


def test_row_generation_ends_where_every_row_holds(monkeypatch: pytest.MonkeyPatch) -> None:
    """The search's runner started on the 4 farthest heading rows adds the rows its solutions break until one holds
    every row: the certificate is the one the problem with every row gives (the same bound to the search's tolerance,
    and it passes the re-check on the whole set), and its rows grew; phase-1 problems do the same (prove_no_set's
    every-row tries): t* over an interval with a certificate inside is the one of every row, never a false proof
    (configs/nonlinear-proof.yaml at 0.16 rad, where rows bind, alpha 0.11; rows posed as linear rows, forced)."""
    from robustsynth.synthesis.alpha_search import _run_invariance

    monkeypatch.setattr(lmis, "LIFT_ROWS", 0)
    monkeypatch.setattr(lmis, "GENERATE_ROWS", 0)
    m, K, cert = committed_gain("nonlinear-proof")
    _, s = _nonlinear_proof()
    model = m.with_heading_bound(0.16, within_period=True)
    posed = _farthest(model, np.asarray(cert["Q"], dtype=float), K, 4)
    a = 0.11  # certified with every row there, and 4 rows leave one broken
    got = {}
    for name, rows in (("few", posed), ("all", None)):
        b, r = _run_invariance(model, s, [], True, alpha_hint=a, retry=False, probe_only=True, rows=rows)
        assert b.cert is not None and b.check.passed
        got[name] = (b.check.figures["ultimate_bound"]["e_y"], r)
    assert len(got["few"][1].rows) > len(posed)
    BOUND_REL = 1e-3  # two problems with one optimum (the rows that bind), each solved to Clarabel's tolerances
    assert got["few"][0] == pytest.approx(got["all"][0], rel=BOUND_REL)
    said: list[str] = []
    few = Active(rows=tuple(posed))
    gen = prove_no_set(model, s, True, (a / 1.1, a * 1.1), intervals=1, active=few, halvings=0, say=said.append)
    every = prove_no_set(model, s, True, (a / 1.1, a * 1.1), intervals=1, active=Active(), halvings=0)
    assert not gen.proven and not every.proven
    assert any("break the solution" in line for line in said), said
    (*_, t_gen, _, _), = gen.intervals
    (*_, t_all, _, _), = every.intervals
    assert t_gen == pytest.approx(t_all, abs=T_TOL), (t_gen, t_all)


def test_between_the_lifted_rows_and_generation_an_every_row_try_solves_again_only_where_rows_break(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the rows are posed as linear rows but too few to be generated in the main problems (the default robot at
    d_hi 2: 2 601, between LIFT_ROWS and GENERATE_ROWS), prove_no_set's every-row try starts from the active rows: the
    last solution on them is checked against every row, and solved again only with the rows it breaks.  Its t* is the
    one every row posed at once gives (configs/nonlinear-proof.yaml at 0.16 rad, where rows bind; forced sizes)."""
    monkeypatch.setattr(lmis, "LIFT_ROWS", 0)
    monkeypatch.setattr(lmis, "GENERATE_ROWS", 10**9)
    m, K, cert = committed_gain("nonlinear-proof")
    _, s = _nonlinear_proof()
    model = m.with_heading_bound(0.16, within_period=True)
    a = 0.11
    n_rows = len(lmis.heading_row_table(model))
    for posed in (_farthest(model, np.asarray(cert["Q"], dtype=float), K, 4),
                  lmis.heading_row_table(model).keys(np.arange(n_rows))):
        said: list[str] = []
        said_all: list[str] = []
        gen = prove_no_set(model, s, True, (a / 1.1, a * 1.1), intervals=1, active=Active(rows=tuple(posed)),
                           halvings=0, say=said.append)
        every = prove_no_set(model, s, True, (a / 1.1, a * 1.1), intervals=1, active=Active(), halvings=0,
                             say=said_all.append)
        (*_, t_gen, _, _), = gen.intervals
        (*_, t_all, _, _), = every.intervals
        assert not gen.proven and t_gen == pytest.approx(t_all, abs=T_TOL), (t_gen, t_all)
        solves = sum("phase-1 on alpha" in line for line in said)
        if len(posed) < n_rows:  # 4 rows leave rows broken: solved again with them
            assert any("break the solution" in line for line in said), said
        else:  # every row posed already: each solution is checked, found to hold every row, and not solved again
            assert not any("break the solution" in line for line in said), said
            assert solves == sum("phase-1 on alpha" in line for line in said_all), (said, said_all)


@pytest.mark.parametrize("how", ["values say nothing", "no round"])
def test_between_the_lifted_rows_and_generation_an_inconclusive_every_row_try_poses_every_row(
        monkeypatch: pytest.MonkeyPatch, how: str) -> None:
    """Where the rows are few enough to pose at once (below GENERATE_ROWS) and the every-row try's generation cannot
    conclude (rows_broken says nothing, or no round is left), the interval is solved with every row at once: its t* is
    every row's (configs/nonlinear-proof.yaml at 0.16 rad, 4 rows active; forced sizes)."""
    monkeypatch.setattr(lmis, "LIFT_ROWS", 0)
    monkeypatch.setattr(lmis, "GENERATE_ROWS", 10**9)
    if how == "values say nothing":
        monkeypatch.setattr(lmis, "rows_broken", lambda *_a, **_k: None)
    else:
        monkeypatch.setattr(phase1, "ROW_ROUNDS", 0)
    m, K, cert = committed_gain("nonlinear-proof")
    _, s = _nonlinear_proof()
    model = m.with_heading_bound(0.16, within_period=True)
    a = 0.11
    posed = _farthest(model, np.asarray(cert["Q"], dtype=float), K, 4)
    said: list[str] = []
    gen = prove_no_set(model, s, True, (a / 1.1, a * 1.1), intervals=1, active=Active(rows=tuple(posed)), halvings=0,
                       say=said.append)
    every = prove_no_set(model, s, True, (a / 1.1, a * 1.1), intervals=1, active=Active(), halvings=0)
    (*_, t_gen, _, _), = gen.intervals
    (*_, t_all, _, _), = every.intervals
    assert t_gen == pytest.approx(t_all, abs=T_TOL), (t_gen, t_all)
    assert any("phase-1 on alpha" in line and "heading rows" not in line for line in said), said  # every row posed


def test_the_completion_step_runs_between_the_active_and_the_end_vertices(monkeypatch: pytest.MonkeyPatch) -> None:
    """prove_no_set asks _completion once the active vertices leave an interval unsettled at depth 0, with the active
    vertices and their solved problems, and tries the vertices it returns before the end vertices; the proof is the
    one the end vertices give (configs/delay-dlo1.yaml with the nonlinear kinematics at 0.3 rad, alpha in [0.005,
    0.0096], proven on the end vertices; two end vertices active)."""
    cfg = mapping_with(yaml.safe_load((ROOT / "configs" / "delay-dlo1.yaml").read_text()),
                       **{"synthesis.kinematics": "nonlinear"})
    model, s = build_model(cfg).with_heading_bound(0.3, within_period=True), _kinematic(cfg.synthesis)
    ends = _exact_end_vertices(model)
    calls: list[tuple] = []
    real = phase1._completion

    def spy(m, active, solved, base):
        got = real(m, active, solved, base)
        calls.append((active, len(solved), base, got))
        return got

    monkeypatch.setattr(phase1, "_completion", spy)
    active = Active(indices=(ends[0], ends[1]), vertices=len(model.vertices))
    said: list[str] = []
    proof = prove_no_set(model, s, True, (0.005, 0.0096), intervals=1, active=active, halvings=0, say=said.append)
    assert proof.proven, proof.summary()
    tried = [line for line in said if "phase-1 on alpha" in line]
    assert "(2 vertices" in tried[0], tried
    if proof.intervals[0][3] == 2:  # the two settled it: nothing more asked
        assert not calls
        return
    assert len(calls) == 1, calls
    first, n_solved, base, got = calls[0]
    assert first == (ends[0], ends[1]) and n_solved == 1 and base == ends
    sizes = [int(line.split("(")[1].split(" vertices")[0]) for line in tried]
    assert sizes[-1] == proof.intervals[0][3]  # the interval is recorded with the vertices that settled it
    if got is not None:  # tried after the two, before any end-vertex problem
        assert len(got) in sizes and sizes.index(len(got)) < (sizes.index(len(ends)) if len(ends) in sizes else len(sizes))


def _label_instants(label: str) -> dict[int, float]:
    """The switching instants a delay vertex's label names (``s{j}={value}``, vertices.delay_vertex_gammas)."""
    import re

    return {int(j): float(x) for j, x in re.findall(r"\bs(\d+)=([-0-9.e]+)", label)}


@pytest.mark.parametrize("cfg", [
    pytest.param(lambda: mapping_with(yaml.safe_load((ROOT / "configs" / "delay-dlo1.yaml").read_text()),
                                      **{"synthesis.kinematics": "nonlinear"}), id="delay-dlo1"),
    pytest.param(lambda: mapping_with(yaml.safe_load((ROOT / "configs" / "default.yaml").read_text()),
                                      **{"network.delay": {"min": 0.02, "max": 0.29}}), id="default-d_hi-3"),
])
def test_the_same_end_vertices_are_the_delay_s_constant_extremes(cfg) -> None:
    """_same_end_vertices (the long-delay start's first relaxation) keeps the end vertices whose instants all sit at
    the same end, read two ways: from the instants the vertices carry (h_j) and from their labels (s~_j = Ts - h_j).
    Per slip corner exactly two delay vertices: the instants all at their least s~ and all at their largest."""
    model = build_model(cfg())
    lin = model.linearized()
    kept = phase1._same_end_vertices(lin)
    ends = _exact_end_vertices(lin) or tuple(range(len(lin.vertices)))
    assert kept is not None and set(kept) < set(ends)
    Ts = model.config.network.sampling_time
    s = {i: _label_instants(lin.vertices[i].label) for i in ends}
    for i in ends:  # the two routes agree on every end vertex
        h = lin.vertices[i].instants
        assert sorted(s[i]) == list(range(len(h)))
        assert all(abs(s[i][j] - (Ts - h[j])) <= 1e-9 for j in range(len(h))), (lin.vertices[i].label, h)
    n = len(next(iter(s.values())))
    lo = [min(s[i][j] for i in ends) for j in range(n)]
    hi = [max(s[i][j] for i in ends) for j in range(n)]
    varying = [j for j in range(n) if hi[j] - lo[j] > 1e-9]
    assert varying
    by_label = {i for i in ends if all(abs(s[i][j] - lo[j]) <= 1e-9 for j in varying)
                or all(abs(s[i][j] - hi[j]) <= 1e-9 for j in varying)}
    assert set(kept) == by_label
    corners = {lin.vertices[i].corner for i in ends}
    assert len(kept) == 2 * len(corners)
