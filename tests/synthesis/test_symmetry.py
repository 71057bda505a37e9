"""The robot's left/right mirror symmetry (docs/theory.md §6h): ``Model.mirror`` maps every vertex
onto its mirror image, and the synthesis LMIs that use it (a mirror-invariant certificate, one
condition of each mirrored pair, one "next" matrix Z per left matrix) reach the optimum of the full
problem, while the certificate they return passes the numpy check of *every* condition, the
dropped ones included."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.model import build_model
from robustsynth.synthesis.lmis import _Lyap, build_stability

from ..conftest import ROOT, make_config
from .conftest import invariance_at, invariance_runner

ALPHA = 0.22  # near the best alpha of the default robot
# the two optima agree to the solver's accuracy: at the product's 1e-9 tolerances they differ by up to
# 1.5e-6 (common), at 1e-11 by 1e-8 (measured), so the difference is the solver's, not the symmetry's
OPT_REL = 1e-5
# where a solve ends 'optimal_inaccurate', its objective is Clarabel's "almost optimal" one: gap within 5e-5 relative,
# residuals within reduced_tol_feas = 1e-4 (its defaults), so two optima agree to that only (the full grown problem of
# the within-period test ended so on a 2-core EPYC with OpenBLAS's Haswell kernels: 8.0e-5 below the mirror-invariant
# problem's 'optimal' one)
INACCURATE_REL = 1e-4
MIRROR_TOL = 1e-12  # the vertex data are mirror images up to round-off


def _signs(model):
    m = model.mirror("path-dependent")
    return m, m.t, m.tu


def test_mirror_maps_every_vertex_onto_its_image():
    model = build_model(make_config())
    mirror, t, tu = _signs(model)
    T, Tu = np.diag(t), np.diag(tu)
    assert sorted(mirror.vertex) == list(range(len(model.vertices)))
    for i, v in enumerate(model.vertices):
        w = model.vertices[mirror.vertex[i]]
        assert mirror.vertex[mirror.vertex[i]] == i  # an involution
        np.testing.assert_array_equal(model.corners[int(w.corner)], model.corners[int(v.corner)][::-1])
        np.testing.assert_allclose(w.A, T @ v.A @ T, atol=MIRROR_TOL)
        np.testing.assert_allclose(w.B, T @ v.B @ Tu, atol=MIRROR_TOL)
    # e_y, e_theta and the yaw-rate commands are the odd states
    assert [n for n, s in zip(model.state_names, t) if s < 0] == ["e_y", "e_theta", "omega[k-1]"]


def test_mirror_is_the_exact_maps_symmetry():
    """Independent of the vertices: the exact lifted map at swapped slip is the mirror image."""
    model = build_model(make_config())
    _, t, tu = _signs(model)
    T, Tu = np.diag(t), np.diag(tu)
    rng = np.random.default_rng(0)
    for _ in range(20):
        s = rng.uniform(*model.instant_ranges[0])
        mu = rng.uniform(0.6, 1.0, size=2)
        A, B = model.exact(np.array([s]), mu)
        A2, B2 = model.exact(np.array([s]), mu[::-1])
        np.testing.assert_allclose(A2, T @ A @ T, atol=MIRROR_TOL)
        np.testing.assert_allclose(B2, T @ B @ Tu, atol=MIRROR_TOL)
        c, c2 = model.constant(mu), model.constant(mu[::-1])
        np.testing.assert_allclose(c2, t * c, atol=MIRROR_TOL)


def test_no_mirror_where_the_tracks_differ():
    model = build_model(make_config(**{"slip.left.min": 0.7}))
    assert model.mirror("common") is None


def test_no_mirror_for_the_kinematic_channels():
    """Mirror images too, but the mirrored problem was numerically fragile (Model.mirror): not used."""
    model = build_model(make_config(**{"slip.right.min": 0.8, "slip.left.min": 0.8,
                                       "synthesis.kinematics": "nonlinear"})).with_heading_bound(0.15)
    assert model.mirror("common") is None


@pytest.mark.parametrize("over", [{"synthesis.delay_description": "norm-bounded"}])  # blocks (d1 I2, d2)
def test_vertices_with_uncertainty_channels_are_mirrored_too(over):
    """Channels map with a sign each (their multipliers as S M S); the symmetric problem reaches the
    full optimum and its certificate passes the check of every condition."""
    model = build_model(make_config(**over))
    mirror = model.mirror("common")
    assert mirror is not None and all(v.n_q for v in model.vertices)
    assert all(np.all(np.abs(s) == 1.0) for s in mirror.q_signs)
    lp_full, *_ = _solve(model, "common", symmetry=False)
    lp_sym, K, cert, chk = _solve(model, "common", symmetry=True)
    assert len(lp_sym.problem.constraints) < len(lp_full.problem.constraints)
    assert lp_sym.problem.value == pytest.approx(lp_full.problem.value, rel=OPT_REL)
    assert chk.passed


def _solve(model, lyapunov: str, symmetry: bool):
    return invariance_at(model, lyapunov, ALPHA, symmetry=symmetry)


@pytest.mark.parametrize("lyapunov", ["common", "slip-dependent", "delay-dependent"])
def test_symmetric_problem_reaches_the_full_optimum(lyapunov):
    model = build_model(make_config(**{"synthesis.lyapunov": lyapunov}))
    lp_full, _, _, _ = _solve(model, lyapunov, symmetry=False)
    lp_sym, K, cert, chk = _solve(model, lyapunov, symmetry=True)
    assert len(lp_sym.problem.constraints) < len(lp_full.problem.constraints)
    assert lp_sym.problem.value == pytest.approx(lp_full.problem.value, rel=OPT_REL)
    # the gain and the matrices are mirror-invariant ...
    m = model.mirror(lyapunov)
    np.testing.assert_allclose(m.tu[:, None] * K * m.t, K, atol=1e-9 * np.abs(K).max())
    # ... and the certificate is checked on every vertex condition, not only on the ones posed
    assert chk.passed
    n_all = sum(len(c) for c in model.lyapunov_conditions(lyapunov, model.slip_step))
    names = [c["name"] for c in chk.checks]
    assert any(n.endswith(f" at {n_all} vertex conditions") for n in names), names


def test_one_next_matrix_per_left_is_exact(monkeypatch):
    """The Z split (one LMI per left matrix, Z below every next matrix) against every (left, next)
    pair posed as its own LMI, without symmetry: the same optimum."""
    model = build_model(make_config(**{"synthesis.lyapunov": "delay-dependent"}))
    lp_split, *_ = _solve(model, "delay-dependent", symmetry=False)
    monkeypatch.setattr(_Lyap, "grouped", lambda self, i: (self.conditions(i), []))
    lp_pairs, *_ = _solve(model, "delay-dependent", symmetry=False)
    assert len(lp_split.problem.constraints) != len(lp_pairs.problem.constraints)
    assert lp_split.problem.value == pytest.approx(lp_pairs.problem.value, rel=OPT_REL)


def test_analysis_of_an_asymmetric_gain_uses_no_mirror():
    model = build_model(make_config())
    K = np.array([[-1.0, 0.3, 0.2, -0.1, 0.05], [0.4, -2.0, -3.0, 0.1, -0.2]])  # dV reacts to e_y: not symmetric
    lp = build_stability(model, "structured", 1e-7, "common", K=K)
    assert len(lp.problem.constraints) == len(build_stability(model, "structured", 1e-7, "common", K=K,
                                                              symmetry=False).problem.constraints)


def test_an_infeasible_alpha_is_infeasible_not_a_solver_failure():
    """At alpha = 0.449 the default robot has no invariant set.  Clarabel 0.11 reports an error on the
    mirror-invariant problem there (the full one: 'infeasible'), so a solve that asks for the
    fallback solves the point again without the mirror first: the outcome is 'infeasible' (exit 3
    territory), not 'failed' (exit 4).  Without the fallback, nothing more is tried."""
    lp, runner = invariance_runner(build_model(make_config()), "common", 0.449)
    assert lp.mirrored
    quick, *_ = runner.run(fallback=False)
    assert len(quick.attempts) == 1 and runner.full_retries == 0
    out, *_ = runner.run(fallback=True)
    assert out.kind == "infeasible"
    first = out.attempts[0].status
    assert runner.full_retries == (0 if first == "infeasible" else 1)


def _reference_signs(v, w, t, tu, s_w):
    """_channel_signs as it was written before it compared every channel at once: np.allclose per column."""
    close = lambda a, b: np.allclose(a, b, rtol=1e-10, atol=1e-12)  # noqa: E731
    Bp, Cq, Dq, F = (np.asarray(x, dtype=float) for x in (v.B_p, v.C_q, v.D_q, v.F))
    images = (t[:, None] * Bp, (Cq * t).T, (Dq * tu).T, (F * s_w).T)
    targets = (np.asarray(w.B_p, dtype=float), np.asarray(w.C_q, dtype=float).T, np.asarray(w.D_q, dtype=float).T,
               np.asarray(w.F, dtype=float).T)
    out = np.ones(v.n_q)
    for k in range(v.n_q):
        parts = [(images[:1], targets[:1]), (images[1:], targets[1:])] if v.diagonal else [(images, targets)]
        signs = []
        for ims, tgs in parts:
            ok = [all(close(tg[:, k], s * im[:, k]) for im, tg in zip(ims, tgs)) for s in (1.0, -1.0)]
            if not any(ok):
                return None
            signs.append(1.0 if ok[0] else -1.0)
        out[k] = signs[-1]
    return out


@pytest.mark.parametrize("config", ["norm-bounded", "default"])
def test_every_channel_at_once_gives_the_per_channel_signs(config):
    """The channels' signs compared column by column (np.allclose, the reference) and all at once: the same, on
    every vertex and its mirror image and on random pairs of vertices, of a model with channel blocks and of the
    default's with diagonal kinematic channels (None where a channel maps with neither sign)."""
    from robustsynth.config import load_config
    from robustsynth.model.mirror import _channel_signs

    if config == "default":
        model = build_model(load_config(ROOT / "configs" / "default.yaml")).with_heading_bound(0.1, within_period=True)
    else:
        model = build_model(make_config(**{"synthesis.delay_description": "norm-bounded"}))
    mirror = model.mirror("common")
    assert mirror is not None and any(v.n_q for v in model.vertices)
    rng = np.random.default_rng(0)
    pairs = [(i, mirror.vertex[i]) for i in range(len(model.vertices))]
    pairs += [tuple(int(x) for x in rng.integers(len(model.vertices), size=2)) for _ in range(20)]
    agreed = {"signs": 0, "none": 0}
    for i, j in pairs:
        v, w = model.vertices[i], model.vertices[j]
        if w.n_q != v.n_q or w.diagonal != v.diagonal:
            continue
        tE = mirror.t[:, None] * np.asarray(v.E)
        s_w = np.where(np.all(np.abs(np.asarray(w.E) + tE) <= 1e-12, axis=0), -1.0, 1.0)  # as find_mirror's, near enough
        got, want = _channel_signs(v, w, mirror.t, mirror.tu, s_w), _reference_signs(v, w, mirror.t, mirror.tu, s_w)
        assert (got is None) == (want is None)
        if got is None:
            agreed["none"] += 1
        else:
            np.testing.assert_array_equal(got, want)
            agreed["signs"] += 1
    assert agreed["signs"] >= len(model.vertices) and agreed["none"] > 0


def test_within_period_vertices_come_with_their_mirror_images_and_keep_the_symmetry():
    """Constraint generation on the default robot (icr, nonlinear: the interval twists' vertices, docs/theory.md §12):
    each within-period vertex added comes with its mirror image, so the grown problem is posed mirror-invariant and
    reaches the full grown problem's optimum; where the model has no mirror (the tracks model's covering channels) only
    the vertices asked are added."""
    from robustsynth.config import load_config

    from robustsynth.model.mirror import mirror_pairs
    from robustsynth.synthesis.solve import solve

    model = build_model(load_config(ROOT / "configs" / "default.yaml"))
    m = model.mirror("common")
    pairs = mirror_pairs(model.covering_vertices, m.t, m.tu)
    i = next(k for k, j in enumerate(pairs) if j != k)
    grown = model.with_cuts([i])
    assert [v.label for v in grown.vertices[len(model.vertices):]] == \
        [model.covering_vertices[k].label for k in (i, pairs[i])] and grown.mirror("common") is not None
    # as many as a round of constraint generation adds (CUTS_PER_ROUND, and their images): the symmetry stays
    eight = [k for k, j in enumerate(pairs) if j > k][:8]
    assert len(model.with_cuts(eight).vertices) == len(model.vertices) + 16
    assert model.with_cuts(eight).mirror("common") is not None
    values = []
    for symmetry in (False, True):  # the LMIs alone, near the default's best alpha (the runner would grow them)
        lp, _ = invariance_runner(grown, "common", 0.15, symmetry)
        out = solve(lp.problem, "clarabel-unscaled", lambda: True, fallback=False)
        assert out.kind == "ok", out.record
        values.append((len(lp.problem.constraints), lp.problem.value, out.record.status))
    rel = OPT_REL if all(v[2] == "optimal" for v in values) else INACCURATE_REL
    assert values[1][0] < values[0][0] and values[1][1] == pytest.approx(values[0][1], rel=rel), values
    tracks = build_model(make_config(**{"slip.right.min": 0.8, "slip.left.min": 0.8,
                                        "synthesis.kinematics": "nonlinear"})).with_heading_bound(0.15)
    assert len(tracks.with_cuts([0]).vertices) == len(tracks.vertices) + 1


# -------------------------------------------------------------------------- phase-1 problems posed mirror-invariant

T_TOL = 1e-7  # t* of two solves compared (test_phase1's): Clarabel's 'inaccurate' statuses are 5e-5 relative


def _phase1_t(model, idx, mirror, s, alpha=(0.02, 0.03)):
    from dataclasses import replace

    from robustsynth.synthesis.phase1 import PHASE1_BOX
    from robustsynth.synthesis.lmis import build_invariance
    from robustsynth.synthesis.solve import solve

    w = np.array([s.weights.e_x, s.weights.e_y, s.weights.e_theta])
    sub = replace(model, vertices=tuple(model.vertices[i] for i in idx))
    lp = build_invariance(sub, s.multiplier, s.margin, w, True, s.lyapunov, symmetry=mirror is not None, mirror=mirror,
                          phase1=PHASE1_BOX)
    lp.params["one_minus_alpha"].value, lp.params["alpha"].value = 1.0 - alpha[0], alpha[1]
    out = solve(lp.problem, s.solver, lambda: True, fallback=False)
    assert out.kind == "ok", out.record
    return float(lp.extra["t"].value), lp


def test_a_vertex_subset_closed_under_the_mirror_keeps_it_exactly_and_proves_more():
    """phase1 poses its problems on a vertex subset with the subset's mirror images, mirror-invariant
    (``Model.mirror_on``, docs/theory.md §6j).  On the default robot (icr, nonlinear at 0.1 rad): the closure holds
    each vertex's image, its symmetry maps within it; posed mirror-invariant it has the t* of the same vertices posed
    as they are (no loss: the average of a solution and its image), with one LMI of each pair, and at most the t* of
    the subset alone (more vertices, a stronger relaxation).  Not closed, or one vertex's data off by one ulp: no
    symmetry (a proof may not rest on images that are not exact)."""
    from dataclasses import replace

    from robustsynth.config import load_config
    from robustsynth.model.mirror import restrict
    from robustsynth.synthesis.heading_search import _kinematic

    cfg = load_config(ROOT / "configs" / "default.yaml")
    model = build_model(cfg).with_heading_bound(0.1, within_period=True)
    s = _kinematic(cfg.synthesis)
    full = model.mirror(s.lyapunov)
    assert full is not None
    subset = (13, 17, 21)  # three vertices of asymmetric slip corners (no two of them images of each other)
    closed, mirror = model.mirror_on(subset, full)
    assert set(subset) < set(closed) and all(full.vertex[i] in closed for i in closed) and mirror is not None
    assert all(closed[mirror.vertex[k]] == full.vertex[i] for k, i in enumerate(closed))
    t_mirrored, lp = _phase1_t(model, closed, mirror, s)
    t_plain, lp_plain = _phase1_t(model, closed, None, s)
    t_subset, _ = _phase1_t(model, subset, None, s)
    assert lp.mirrored and sum(map(bool, lp.vertex_lmis)) < sum(map(bool, lp_plain.vertex_lmis))
    assert t_mirrored == pytest.approx(t_plain, abs=T_TOL)
    assert t_mirrored <= t_subset + T_TOL
    assert model.mirror_on(subset, None) == (tuple(sorted(subset)), None)
    assert restrict(full, model.vertices, subset) is None  # not closed
    v = model.vertices[subset[0]]  # (its image is another vertex)
    A = np.array(v.A, dtype=float)
    A[0, 0] = np.nextafter(A[0, 0], np.inf)
    off = list(model.vertices)
    off[subset[0]] = replace(v, A=A)
    assert restrict(full, off, closed) is None


def test_prove_no_set_poses_mirror_invariant_problems_where_the_model_has_a_mirror(monkeypatch):
    """prove_no_set builds every problem on the closure of its vertices, mirror-invariant, on the default robot; on
    the tracks model of nonlinear-proof (no mirror for its per-track channels) as before, on the vertices asked."""
    from robustsynth.config import load_config
    from robustsynth.synthesis import phase1
    from robustsynth.synthesis.heading_search import _kinematic

    built = []
    real = phase1.build_invariance

    def spy(model, *args, **kwargs):
        built.append((len(model.vertices), kwargs.get("mirror") is not None, kwargs.get("symmetry")))
        return real(model, *args, **kwargs)

    monkeypatch.setattr(phase1, "build_invariance", spy)
    for name, mirrored, asked in (("default", True, (13, 17, 21)), ("nonlinear-proof", False, (0, 1, 2))):
        cfg = load_config(ROOT / "configs" / f"{name}.yaml")
        model = build_model(cfg).with_heading_bound(0.1, within_period=True)
        s = _kinematic(cfg.synthesis)
        active = phase1.Active(asked)
        built.clear()
        phase1.prove_no_set(model, s, True, (0.005, 0.0096), intervals=1, halvings=0, active=active)
        assert built and all(m == mirrored and sym == mirrored for _, m, sym in built), (name, built)
        if mirrored:
            assert built[0][0] > 3  # the three asked and their images
            assert set(active.indices) == {model.mirror(s.lyapunov).vertex[i] for i in active.indices}
