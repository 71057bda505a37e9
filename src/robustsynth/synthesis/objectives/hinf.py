"""``hinf``: the smallest l2 gain from the disturbance to the weighted outputs, for every admissible delay sequence
(docs/theory.md §6d; a linear plant's: §15); one solve."""

from __future__ import annotations

import time
from typing import Any, Callable

import cvxpy as cp
import numpy as np

from ...config import SynthesisConfig
from ..lmis import LMIProblem, _Lyap, _multipliers, _sym, _vertex_parts
from ..runner import _attempts, _Best, _build, _cert_common, _delay_text, _raise_no_solution, _Runner, _weights

__all__ = ["robot", "linear", "build_hinf"]


def robot(model: Any, s: SynthesisConfig, search: list, say: Callable[[str], None]) -> tuple[_Best, _Runner, list[str]]:
    """One solve of the bounded-real LMIs over the robot's vertices (common Lyapunov matrix)."""
    say(f"{s.objective}: one solve ({model.kind} model, {len(model.vertices)} vertices)")
    best, runner = _run(model, s, search, say)
    if best.cert is None:
        _raise_no_solution(runner, "hinf", f"hinf: no gain gives a finite l2 gain for {_delay_text(model)}: "
                           "narrow network.delay or lower reference.speed")
    return best, runner, []


def _run(model: Any, s: SynthesisConfig, search: list, say: Callable[[str], None]) -> tuple[_Best, _Runner]:
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


def linear(job: Any) -> Any:
    """The linear plant's: the smallest gamma with ``V+ - V + |C x|^2 <= gamma^2 |d|^2 / g^2`` for every admissible
    step, g = int_0^Ts ||e^{A r} E|| dr (so |d_k| <= g sup_{period k} ||w||): summed from x = 0,
    ``sum_k |C x_k|^2 <= gamma^2 sum_k sup_{period k} ||w(t)||^2`` for any disturbance and delay sequence
    (docs/theory.md §15).  One solve: maximize mu = g^2 / gamma^2, linear in the LMIs."""
    from ...verified import round_up
    from ..lti import _Candidate, _prove, _vertex_lmis
    from ..solve import solve

    plant, V, C, Ts, say = job.plant, job.V, job.C, job.Ts, job.say
    m, n_s, d, nv = V.m, V.n_s, job.d, job.nv
    g = job.per_period_gain()
    mu = cp.Variable(nonneg=True)  # g^2 / gamma^2
    q, y, eps, _, _, basis, cons = _vertex_lmis(V, True, mu, 1.0, C)
    prob = cp.Problem(cp.Maximize(mu), cons)
    held: dict = {}

    def accept() -> bool:
        if q.value is None or y.value is None or eps.value is None or mu.value is None or float(mu.value) <= 0:
            return False
        gamma = g / float(np.sqrt(float(mu.value))) * (1.0 + 1e-6)  # rounded up: room for the proof
        Qv = np.einsum("i,iab->ab", np.asarray(q.value, dtype=float), basis)
        chk, K, P, eta = _prove(plant, V, Ts, job.tau_min, job.tau_hi, job.pieces, Qv, np.asarray(y.value).reshape(m, n_s),
                                np.maximum(np.asarray(eps.value), 0.0), 1.0, gamma**2 / g**2, C)
        held["last"] = (chk, K, P, eta, gamma)
        return bool(chk["ok"])

    out = solve(prob, job.solver, accept, fallback=False)  # as analyze_lti
    dt = time.perf_counter() - job.t0
    if out.kind != "ok":
        last = held.get("last")
        status = "infeasible" if out.kind == "infeasible" else ("rejected" if last is not None else "failed")
        return _Candidate(False, status, "hinf", None, None, None, None, {}, last[0] if last else {}, d, nv,
                          len(out.attempts), dt, f"no proven l2 gain ({out.record.status})", ({"status": out.kind},))
    chk, K, P, eta, gamma = held["last"]
    say(f"hinf: l2 gain {gamma:.6g} (proven)")
    figures = {"alpha": 1.0, "decay": 1.0, "hinf_gain": round_up(gamma, 2), "per_period_gain": g,
               "outputs": [{"name": nm, "unit": un} for nm, un in zip(plant["outputs"], plant["output_units"])]}
    return _Candidate(True, "certified", "hinf", K, P, eta, 1.0, figures, chk, d, nv, len(out.attempts), dt,
                      search=({"status": out.kind},))


def build_hinf(model: Any, kind: str, margin: float, weights: np.ndarray) -> LMIProblem:
    """l2 gain gamma from the slip deviation d to z = diag(weights) e (docs/theory.md §6d), common Q over
    the vertices; minimizes gamma^2."""
    model = model.linearized()
    lv = _Lyap(model, "common")
    Q = lv.Q
    n_s = model.n_s
    Bd = np.asarray(model.B_d)
    n_d = Bd.shape[1]
    Cz = np.zeros((3, n_s))
    Cz[:, :3] = np.diag(weights)
    n_z = 3
    g = cp.Variable(nonneg=True, name="gamma2")
    CzQ = Cz @ Q
    Z = np.zeros
    Ms, cons = _multipliers(model, kind, margin)
    for v, M in zip(model.vertices, Ms):
        AX, CX = _vertex_parts(v, lv)
        Bp = np.asarray(v.B_p)
        rows = [
            [Q, Z((n_s, n_d)), AX.T, CzQ.T],
            [Z((n_d, n_s)), g * np.eye(n_d), Bd.T, Z((n_d, n_z))],
            [AX, Bd, Q - (Bp @ M @ Bp.T if v.n_q else 0), Z((n_s, n_z))],
            [CzQ, Z((n_z, n_d)), Z((n_z, n_s)), np.eye(n_z)],
        ]
        if v.n_q:
            rows[0].append(CX.T)
            rows[1].append(Z((n_d, v.n_q)))
            rows[2].append(Z((n_s, v.n_q)))
            rows[3].append(Z((n_z, v.n_q)))
            rows.append([CX, Z((v.n_q, n_d)), Z((v.n_q, n_s)), Z((v.n_q, n_z)), M])
        L = cp.bmat(rows)
        cons.append(_sym(L) >> margin * np.eye(L.shape[0]))
    cons += lv.scale(margin)
    prob = cp.Problem(cp.Minimize(g), cons)
    return LMIProblem(prob, M=Ms, extra={"gamma2": g}, **lv.problem_kwargs())
