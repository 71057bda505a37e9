"""Slip that changes within a period (docs/theory.md §11): the slip averages of a command interval lie
in the parallelogram (the lens lemma), the closed-form switched map agrees with a piecewise matrix
exponential, and the within-period vertices contain the exact lifted map of every slip history --
checked by a linear program on histories whose tracks jump independently, several times a period,
and refused for a slip outside the box (the negative control)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm
from scipy.optimize import linprog

from robustsynth.config import load_config
from robustsynth.model import build_model
from robustsynth.model.slip import slip_matrix
from robustsynth.model.vertices import SLIP_AVERAGE_PARALLELOGRAM

from ..conftest import ROOT

CONFIGS = ROOT / "configs"

EXPM_TOL = 1e-12  # closed form vs matrix exponential: round-off only
HULL_TOL = 1e-9  # the LP's equality residual (HiGHS' own feasibility tolerance is 1e-7 on scaled rows)
LENS_TOL = 1e-12


def _model(name: str):
    return build_model(load_config(CONFIGS / f"{name}.yaml"))


@pytest.fixture(scope="module")
def models():
    return {n: _model(n) for n in ("tracks-box", "lossy-link", "delay-full-period")}


def _in_parallelogram(u: float, v: float) -> bool:
    return -LENS_TOL <= v <= 1 + LENS_TOL and 2 * u - 1 - LENS_TOL <= v <= 2 * u + LENS_TOL


@settings(max_examples=300, deadline=None)
@given(st.floats(0.0, 0.1), st.floats(0.0, 1.0), st.lists(st.floats(0.0, 1.0), min_size=1, max_size=7),
       st.lists(st.booleans(), min_size=8, max_size=8))
def test_slip_averages_of_any_interval_lie_in_the_parallelogram(a: float, frac: float, cuts: list[float],
                                                               on: list[bool]) -> None:
    """phi in [0, 1] piecewise constant on [a, b] within [0, Ts]: (uniform mean, (Ts - t)-weighted mean)
    is in the parallelogram (0,0), (1/2,1), (1,1), (1/2,0) -- the vertices are the claim of §11."""
    Ts = 0.1
    b = a + frac * (Ts - a)
    if b - a < 1e-9:
        return
    pts = np.concatenate([[a], np.sort(a + np.array(cuts) * (b - a)), [b]])
    F = lambda t: Ts * t - t * t / 2.0  # noqa: E731
    L = W = u = v = 0.0
    for i in range(len(pts) - 1):
        t0, t1 = pts[i], pts[i + 1]
        phi = 1.0 if on[i] else 0.0
        L += t1 - t0
        W += F(t1) - F(t0)
        u += phi * (t1 - t0)
        v += phi * (F(t1) - F(t0))
    assert _in_parallelogram(u / L, v / W)
    assert set(SLIP_AVERAGE_PARALLELOGRAM) == {(0.0, 0.0), (0.5, 1.0), (1.0, 1.0), (0.5, 0.0)}


def _command_index(S: np.ndarray, t: float) -> int:
    """i with du_{k-i} acting at time t (s~_i <= t < s~_{i-1})."""
    return int(np.count_nonzero(S > t))


def _error_rows_by_expm(model, xi: np.ndarray, du: np.ndarray, S: np.ndarray, jumps: list[tuple[float, int, float]],
                        mu0: np.ndarray) -> np.ndarray:
    """e(t_{k+1}) of the linearized error, e' = A_c e + B_c (M(mu(t)) (u^D + du(t)) - u^D), through the
    matrix exponential of each piece where the command and the slip are constant.  ``jumps``: (time,
    track, new value) -- the tracks jump independently."""
    Ts, V, D = model.Ts, model.V, model.config.robot.track_distance
    n_e = model.n_e
    cmds = [du] + [xi[n_e + 2 * j : n_e + 2 * j + 2] for j in range(model.d_hi)]
    uD = np.array([V, 0.0])
    times = sorted({0.0, Ts, *[float(s) for s in S], *[t for t, _, _ in jumps]})
    e, mu = xi[:n_e].copy(), mu0.copy()
    for t0, t1 in zip(times[:-1], times[1:]):
        for t, track, val in jumps:
            if t == t0:
                mu[track] = val
        if t1 <= t0:
            continue
        u = uD + cmds[_command_index(S, t0)]
        b = np.asarray(model.B_c) @ (slip_matrix(mu, D) @ u - uD)
        aug = np.zeros((n_e + 1, n_e + 1))
        aug[:n_e, :n_e], aug[:n_e, n_e] = model.A_c, b
        e = (expm(aug * (t1 - t0)) @ np.concatenate([e, [1.0]]))[:n_e]
    return e


def _map_by_expm(model, S, jumps, mu0):
    """The affine map (A, B, c) of the error rows under this slip history, column by column."""
    n_s, n_u = model.n_s, model.n_u
    c = _error_rows_by_expm(model, np.zeros(n_s), np.zeros(n_u), S, jumps, mu0)
    A = np.stack([_error_rows_by_expm(model, np.eye(n_s)[i], np.zeros(n_u), S, jumps, mu0) - c for i in range(n_s)], 1)
    B = np.stack([_error_rows_by_expm(model, np.zeros(n_s), np.eye(n_u)[i], S, jumps, mu0) - c for i in range(n_u)], 1)
    return A, B, c


def test_switched_map_agrees_with_the_matrix_exponential(models) -> None:
    m = models["tracks-box"]
    rng = np.random.default_rng(0)
    for _ in range(20):
        S = np.array([rng.uniform(0.01, 0.08)])
        mu, after, t = rng.uniform(0.6, 1.0, 2), rng.uniform(0.6, 1.0, 2), rng.uniform(0.0, m.Ts)
        A, B, c = m.switched_exact(S, mu, t, after)
        Ae, Be, ce = _map_by_expm(m, S, [(t, 0, after[0]), (t, 1, after[1])], mu)
        n_e = m.n_e
        assert np.max(np.abs(A[:n_e] - Ae)) <= EXPM_TOL
        assert np.max(np.abs(B[:n_e] - Be)) <= EXPM_TOL
        assert np.max(np.abs(c[:n_e] - ce)) <= EXPM_TOL
    # each track at its own time (t_switch (2,), as the Monte Carlo and the boundary probe draw them)
    for _ in range(20):
        S = np.array([rng.uniform(0.01, 0.08)])
        mu, after, t = rng.uniform(0.6, 1.0, 2), rng.uniform(0.6, 1.0, 2), rng.uniform(0.0, m.Ts, 2)
        A, B, c = m.switched_exact(S, mu, t, after, per_track=True)
        Ae, Be, ce = _map_by_expm(m, S, [(t[0], 0, after[0]), (t[1], 1, after[1])], mu)
        n_e = m.n_e
        assert max(np.max(np.abs(A[:n_e] - Ae)), np.max(np.abs(B[:n_e] - Be)), np.max(np.abs(c[:n_e] - ce))) <= EXPM_TOL
        one = m.switched_exact(S, mu, t[0], after)[2]  # both at the first time: another map
        assert np.max(np.abs(one[:n_e] - c[:n_e])) > 100 * EXPM_TOL or abs(t[0] - t[1]) < 1e-3
    # no jump: the constant-slip map the certificate has always used
    A0, B0 = m.robot_exact(S, mu)
    A1, B1, c1 = m.switched_exact(S, mu, m.Ts, after)
    assert np.array_equal(A0, A1) and np.array_equal(B0, B1)
    assert np.max(np.abs(c1 - m.constant(mu))) <= EXPM_TOL


def _in_hull(model, A, B, c) -> tuple[bool, float]:
    """Is the error-row map (A, B, c) a convex combination of the within-period vertices'?  (LP)"""
    n_e = model.n_e
    verts = model.varying
    cols = np.array([np.concatenate([v.A[:n_e].ravel(), v.B[:n_e].ravel(), v.E[:n_e, 0]]) for v in verts]).T
    target = np.concatenate([A.ravel(), B.ravel(), c])
    scale = np.maximum(np.max(np.abs(cols), axis=1), 1e-12)  # row scaling: the LP's tolerances are absolute
    eq = np.vstack([cols / scale[:, None], np.ones((1, len(verts)))])
    res = linprog(np.zeros(len(verts)), A_eq=eq, b_eq=np.concatenate([target / scale, [1.0]]), bounds=(0, None),
                  method="highs")
    if res.status != 0:
        return False, np.inf
    return True, float(np.max(np.abs(cols @ res.x - target)))


def _random_history(model, rng, n_jumps: int):
    (rl, rh), (ll, lh) = model.slip_ranges
    lo, hi = np.array([rl, ll]), np.array([rh, lh])
    mu0 = rng.choice([0, 1], 2) * (hi - lo) + lo if rng.random() < 0.5 else rng.uniform(lo, hi)
    jumps = []
    for _ in range(n_jumps):  # bang-bang and interior values, each track on its own
        track = int(rng.integers(0, 2))
        val = lo[track] + (hi[track] - lo[track]) * (rng.integers(0, 2) if rng.random() < 0.7 else rng.random())
        jumps.append((float(rng.uniform(0.0, model.Ts)), track, float(val)))
    return mu0, sorted(jumps)


@pytest.mark.parametrize("name", ["tracks-box", "lossy-link", "delay-full-period"])
def test_within_period_vertices_contain_every_slip_history(models, name: str) -> None:
    m = models[name]
    n_e = m.n_e
    # the rows below the error rows (the stored commands) are the same at every vertex and exact
    ref = m.varying[0]
    assert all(np.array_equal(v.A[n_e:], ref.A[n_e:]) and np.array_equal(v.B[n_e:], ref.B[n_e:]) for v in m.varying)
    rng = np.random.default_rng(1)
    inst = m.reachable_instants(6)
    for k in range(40):
        if inst is not None:
            S = inst[rng.integers(0, inst.shape[0])]
        else:
            dl = m.config.network.delay
            S = m.s_tilde(rng.uniform(dl.min, dl.max, (1, 1 + m.d_hi)))[0, 0]
        mu0, jumps = _random_history(m, rng, n_jumps=k % 5)
        A, B, c = _map_by_expm(m, S, jumps, mu0)
        ok, resid = _in_hull(m, A, B, c)
        assert ok and resid <= HULL_TOL, (name, S, mu0, jumps, resid)
    # the constant-slip vertices are among them
    for v in m.vertices[:: max(1, len(m.vertices) // 6)]:
        assert any(np.array_equal(v.A, w.A) and np.array_equal(v.B, w.B) and np.allclose(v.E, w.E, atol=1e-15)
                   for w in m.varying)


def test_a_slip_outside_the_box_is_outside_the_hull(models) -> None:
    """The negative control: the LP can say no."""
    m = models["tracks-box"]
    (rl, _), (ll, _) = m.slip_ranges
    S = np.array([0.05])
    A, B, c = _map_by_expm(m, S, [(0.03, 0, rl - 0.1)], np.array([rl, ll]))
    ok, _ = _in_hull(m, A, B, c)
    assert not ok


def test_which_models_cover_slip_changing_within_a_period() -> None:
    m = _model("tracks-box")
    assert len(m.varying) == 3 * 16 * 16  # 3 delay vertices x (4 x 4 per track pair) per command interval
    assert m.slip_variation("common") == (m.varying, "")
    verts, why = m.slip_variation("slip-dependent")
    assert verts == () and "slip at the sampling instants" in why
    nb = _model("delay-multi-period")
    assert nb.delay_description == "norm-bounded" and nb.slip_variation()[0] == ()
    assert "norm-bounded" in nb.slip_variation()[1]
    nl = _model("nonlinear-proof")
    # the kinematic channels for slip changing within a period (theory §9): the within-period vertices
    # carry their delay vertex's channels and share its multiplier
    verts, why = nl.slip_variation()
    assert why == "" and len(verts) == len(nl.varying) and verts == nl.covering_vertices
    assert all(v.n_q == nl.vertices[0].n_q and v.group == t for v, t in zip(verts, nl.varying_delay))
    const = nl.with_heading_bound(nl.heading_bound, within_period=False)
    assert const.slip_variation()[0] == () and "kinematic channels" in const.slip_variation()[1]
    assert nl.linearized().slip_variation()[0]  # its linearization is covered
    # a slip-dependent Lyapunov matrix is not proven at the within-period vertices: its nonlinear
    # model keeps the constant-slip channels (the deviation channels would cost and cover nothing)
    cfg = load_config(CONFIGS / "nonlinear-proof.yaml")
    sd = build_model(cfg.model_copy(update={"synthesis": cfg.synthesis.model_copy(update={"lyapunov": "slip-dependent"})}))
    assert sd.heading_bound is not None and sd.covering_vertices == ()
    assert sd.vertices[0].n_q == const.vertices[0].n_q < nl.vertices[0].n_q
