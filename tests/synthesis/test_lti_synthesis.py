"""Synthesis for any linear plant (docs/theory.md §15): every claim of a certified design checked by
an independent computation — the exact lifted loop at random admissible instants, an ODE solver
with a continuous disturbance, and the claims' algebra — and the primal checker refusing tampering."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.certificate.lti import check_lti_certificate, check_lti_scaled, lti_within
from robustsynth.errors import InfeasibleError, SolverFailure
from robustsynth.core.lifting import instant_ranges
from robustsynth.core.delays import disturbance_bound, exact_closed_loop, over_approximation
from robustsynth.model.lti import lti_plant_from
from robustsynth.synthesis.lti import _midpoints, synthesize_lti, vertex_combinations

ZBP_A = np.array([[0.0, 1.0], [0.0, -0.1]])
ZBP_B = np.array([[0.0], [0.1]])
ZBP_E = np.array([[0.0], [0.1]])
# 3 states, 2 inputs, open-loop unstable with complex eigenvalues
UNST_A = np.array([[0.1, 1.0, 0.0], [-1.0, 0.1, 0.5], [0.0, 0.0, -0.3]])
UNST_B = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
UNST_E = np.array([[1.0], [0.0], [0.5]])

EXACT_TOL = 1e-9  # V along exact loops, relative: rounding only
ODE_TOL = 1e-7  # the lifted map against solve_ivp at rtol 1e-11 over one period


def _instants(rng, Ts, lo, hi, d, count):
    r = instant_ranges(lo, hi, Ts, d)
    s = r[:, 0] + (r[:, 1] - r[:, 0]) * rng.random((count, d))
    return np.maximum.accumulate(s[:, ::-1], axis=1)[:, ::-1]  # in order: s~_0 >= s~_1 >= ...


def _d(r, pl: dict) -> int:
    """The commands the gain's lifted state keeps (its columns beyond the plant's states, per input)."""
    n, m = pl["B"].shape
    return (r.K.shape[1] - n) // m


@pytest.fixture(scope="module")
def zbp_bound():
    pl = lti_plant_from(ZBP_A, ZBP_B, E=ZBP_E, w_max=0.5, u_max=[20.0])
    return pl, synthesize_lti(pl, 0.5, 0.0, 0.5, 0, "ultimate-bound")


@pytest.fixture(scope="module")
def unstable_lossy():
    pl = lti_plant_from(UNST_A, UNST_B, E=UNST_E, w_max=0.2)
    return pl, synthesize_lti(pl, 0.2, 0.05, 0.15, 1, "ultimate-bound")


def test_stability_design_shrinks_V_on_exact_loops() -> None:
    """V(M xi) <= alpha V(xi) for 5000 exact closed loops at random admissible instants (delays beyond
    one period), each at the direction that makes V(M xi) / V(xi) largest (a generalized eigenproblem)."""
    from scipy.linalg import eigh

    pl = lti_plant_from(UNST_A, UNST_B)
    Ts, lo, hi = 0.2, 0.0, 0.35
    r = synthesize_lti(pl, Ts, lo, hi, 0, "stability", decay=0.97)
    assert r.check.passed and r.plant_kind == "lti" and r.K.shape == (2, 3 + 2 * 2)  # d_hi = 2 commands kept
    s = _instants(np.random.default_rng(3), Ts, lo, hi, 2, 5000)
    M = exact_closed_loop(UNST_A, UNST_B, r.K, Ts, s)
    worst = max(float(eigh(Mi.T @ r.P @ Mi, r.P, eigvals_only=True)[-1]) for Mi in M)
    assert worst <= r.certificate["alpha"] * (1 + EXACT_TOL)
    assert r.certificate["alpha"] == pytest.approx(0.97**2)


@pytest.mark.parametrize("case", ["zbp_bound", "unstable_lossy"])
def test_the_set_is_invariant_under_the_worst_disturbance(case, request) -> None:
    """From 3000 states on the set's boundary, one exact period at random admissible instants (losses
    included) with the lifted disturbance at its bound delta in the direction that increases V most
    to first order (the gradient of V along the plant's rows): V stays <= 1."""
    pl, r = request.getfixturevalue(case)
    assert r.check.passed
    Ts, lo, hi, ml = (0.5, 0.0, 0.5, 0) if case == "zbp_bound" else (0.2, 0.05, 0.15, 1)
    rng = np.random.default_rng(5)
    delta = r.certified["disturbance_step_bound"]
    n = pl["A"].shape[0]
    n_s = r.P.shape[0]
    s = _instants(rng, Ts, lo, hi + ml * Ts, _d(r, pl), 3000)
    M = exact_closed_loop(pl["A"], pl["B"], r.K, Ts, s)
    L = np.linalg.cholesky(r.P)
    z = rng.standard_normal((3000, n_s))
    xi = np.linalg.solve(L.T, (z / np.linalg.norm(z, axis=1, keepdims=True)).T).T  # V = 1
    nxt = np.einsum("rij,rj->ri", M, xi)
    g = (nxt @ r.P)[:, :n]
    nxt[:, :n] += delta * g / np.linalg.norm(g, axis=1, keepdims=True)
    V = np.einsum("ri,ij,rj->r", nxt, r.P, nxt)
    assert np.max(V) <= 1.0 + EXACT_TOL
    assert np.max(V) > 0.5  # the boundary was probed, not the set's centre


def test_the_per_period_disturbance_bound_holds_on_an_ode() -> None:
    """||int e^{A r} E w dr|| <= delta for bang-bang and smooth w with ||w(t)|| <= w_max (solve_ivp)."""
    from scipy.integrate import solve_ivp

    Ts, w_max = 0.2, 0.2
    delta = disturbance_bound(UNST_A, UNST_E, w_max, Ts)
    worst = 0.0
    for k in range(12):
        w = (lambda t, k=k: w_max * np.sign(np.sin(7.0 * (k + 1) * t + k))) if k % 2 else \
            (lambda t, k=k: w_max * np.cos(3.0 * k * t))
        sol = solve_ivp(lambda t, x, w=w: UNST_A @ x + UNST_E[:, 0] * w(t), (0.0, Ts), np.zeros(3), rtol=1e-11, atol=1e-13,
                        max_step=Ts / 200)
        worst = max(worst, float(np.linalg.norm(sol.y[:, -1])))
    assert worst <= delta
    assert worst >= 0.5 * delta  # and it is not loose by orders of magnitude on these signals


def test_output_and_input_claims_follow_from_P(zbp_bound) -> None:
    """|c xi| <= bound on {xi' P xi <= 1} is sqrt(c P^-1 c') <= bound; the same for |K_i xi| <= u_max."""
    pl, r = zbp_bound
    Q = np.linalg.inv(r.P)
    n_s = r.P.shape[0]
    C = np.hstack([pl["C"], np.zeros((2, n_s - 2))])
    for c, o in zip(C, r.certified["outputs"]):
        assert np.sqrt(c @ Q @ c) <= o["bound"]
        assert np.sqrt(c @ Q @ c) >= 0.999 * o["bound"]  # the figure is the set's own extent, not padded
    assert np.sqrt(r.K[0] @ Q @ r.K[0]) <= 20.0


def test_linearity_scales_the_bounds_with_the_disturbance() -> None:
    """Ten times the disturbance bound gives ten times the output bounds (no input limits: the LMIs are
    the same problem in the normalized units)."""
    a = synthesize_lti(lti_plant_from(ZBP_A, ZBP_B, E=ZBP_E, w_max=0.05), 0.5, 0.0, 0.5, 0, "ultimate-bound")
    b = synthesize_lti(lti_plant_from(ZBP_A, ZBP_B, E=ZBP_E, w_max=0.5), 0.5, 0.0, 0.5, 0, "ultimate-bound")
    for oa, ob in zip(a.certified["outputs"], b.certified["outputs"]):
        assert ob["bound"] == pytest.approx(10 * oa["bound"], rel=1e-9)
    assert np.allclose(a.K, b.K)


def test_tighter_input_limits_cost_bound(zbp_bound) -> None:
    """An input limit that binds enlarges the certified bound and is met on the set."""
    pl, loose = zbp_bound
    Q = np.linalg.inv(loose.P)
    peak = float(np.sqrt(loose.K[0] @ Q @ loose.K[0]))
    tight = synthesize_lti(lti_plant_from(ZBP_A, ZBP_B, E=ZBP_E, w_max=0.5, u_max=[0.5 * peak]), 0.5, 0.0, 0.5, 0,
                           "ultimate-bound")
    assert tight.check.passed
    Qt = np.linalg.inv(tight.P)
    assert np.sqrt(tight.K[0] @ Qt @ tight.K[0]) <= 0.5 * peak * (1 + 1e-9)
    assert max(o["bound"] for o in tight.certified["outputs"]) > max(o["bound"] for o in loose.certified["outputs"])


def test_the_primal_check_refuses_a_tampered_gain(zbp_bound) -> None:
    """The certificate proves the gain it was found with, not a neighbour: K scaled by 1.5 fails with
    the same P and multipliers; the original passes."""
    pl, r = zbp_bound
    pw = over_approximation(pl["A"], pl["B"], r.K, 0.5, 0.0, 0.5, _d(r, pl), 2)
    verts = vertex_combinations(pw)
    s = 1.0 / float(np.min(np.linalg.eigvalsh(r.P)))
    c = (1.0 - r.certificate["alpha"]) * r.certified["disturbance_step_bound"] ** -2 * s
    assert check_lti_certificate(pw, s * r.P, s * r.certificate["multipliers"], np.sqrt(r.certificate["alpha"]), verts, c)["ok"]
    bad = over_approximation(pl["A"], pl["B"], 1.5 * r.K, 0.5, 0.0, 0.5, _d(r, pl), 2)
    assert not check_lti_certificate(bad, s * r.P, s * r.certificate["multipliers"], np.sqrt(r.certificate["alpha"]), verts, c)["ok"]
    assert not check_lti_certificate(pw, s * r.P, s * r.certificate["multipliers"], np.sqrt(r.certificate["alpha"]) * 0.9, verts, c)["ok"]
    assert not lti_within(r.P, np.array([[1.0, 0, 0]]), np.array([0.5 * r.certified["outputs"][0]["bound"]])).any()


def test_no_gain_for_an_unstabilizable_plant() -> None:
    """An unstable mode the input cannot reach: infeasible (exit 3), raised as the robot's synthesis raises it."""
    A = np.array([[0.5, 0.0], [0.0, -1.0]])
    B = np.array([[0.0], [1.0]])
    with pytest.raises(InfeasibleError, match="^no certified gain: ") as exc:
        synthesize_lti(lti_plant_from(A, B), 0.1, 0.0, 0.05, 0, "stability")
    assert exc.value.exit_code == 3


def test_hinf_dissipation_on_exact_loops_and_a_tampered_gamma() -> None:
    """V(M xi + E_x d) - V(xi) + |C xi|^2 <= gamma^2 |d|^2 / g^2 on 3000 exact loops with random states
    and disturbance steps (losses included); the primal check refuses gamma / 2."""
    pl = lti_plant_from(UNST_A, UNST_B, E=UNST_E, w_max=0.2, C=[[1.0, 0.0, 0.0]])
    Ts, lo, hi, ml = 0.2, 0.05, 0.15, 1
    r = synthesize_lti(pl, Ts, lo, hi, ml, "hinf")
    assert r.check.passed
    gam, g = r.certified["hinf_gain"], r.certified["per_period_gain"]
    rng = np.random.default_rng(7)
    s = _instants(rng, Ts, lo, hi + ml * Ts, _d(r, pl), 3000)
    M = exact_closed_loop(pl["A"], pl["B"], r.K, Ts, s)
    n_s = r.P.shape[0]
    xi = rng.standard_normal((3000, n_s))
    dd = rng.standard_normal((3000, 3))
    nxt = np.einsum("rij,rj->ri", M, xi)
    nxt[:, :3] += dd
    V = lambda v: np.einsum("ri,ij,rj->r", v, r.P, v)  # noqa: E731
    lhs = V(nxt) - V(xi) + xi[:, 0] ** 2
    rhs = gam**2 * np.sum(dd**2, axis=1) / g**2
    assert np.all(lhs <= rhs + EXACT_TOL * (np.abs(lhs) + rhs))
    pw = over_approximation(pl["A"], pl["B"], r.K, Ts, lo, hi + ml * Ts, _d(r, pl), 2)
    verts = vertex_combinations(pw)
    C = np.zeros((1, n_s))
    C[0, 0] = 1.0
    assert check_lti_scaled(pw, r.P, r.certificate["multipliers"], 1.0, verts, gam**2 / g**2, C)["ok"]  # P of any scale (lambda_min 2e-4)
    assert not check_lti_scaled(pw, r.P, r.certificate["multipliers"], 1.0, verts, (gam / 2) ** 2 / g**2, C)["ok"]


def test_the_gain_does_not_depend_on_how_many_solves_run_at_once(zbp_bound) -> None:
    """The line search visits the same alphas whether one or several solves run at once (threads), and
    each solve is the same arithmetic: the same gain, set and figures, exactly."""
    pl, ref = zbp_bound
    one = synthesize_lti(pl, 0.5, 0.0, 0.5, 0, "ultimate-bound", threads=1)
    three = synthesize_lti(pl, 0.5, 0.0, 0.5, 0, "ultimate-bound", threads=3)
    for r in (one, three):
        assert r.check.passed and r.solver["solves"] == one.solver["solves"] and r.search == one.search
        np.testing.assert_array_equal(r.K, one.K)
        np.testing.assert_array_equal(r.P, one.P)
        assert r.certificate["alpha"] == one.certificate["alpha"] and r.certified == one.certified
    np.testing.assert_array_equal(ref.K, one.K)  # the fixture ran with the machine's default


def test_refinement_halves_towards_both_neighbours() -> None:
    tried = [0.1, 0.9, 0.99, 0.999]
    x = lambda a: np.log(1.0 - a)  # noqa: E731
    got = sorted(x(a) for a in _midpoints(tried, 0.99))
    assert got == pytest.approx(sorted([(x(0.9) + x(0.99)) / 2, (x(0.99) + x(0.999)) / 2]))
    assert _midpoints(tried, 0.999) == [pytest.approx(1 - np.exp((x(0.99) + x(0.999)) / 2))]  # an end: one side
    assert len(_midpoints([0.5], 0.5)) == 0


def test_the_objective_is_checked_and_auto_follows_the_disturbance() -> None:
    from robustsynth.errors import InputError

    with_w = lti_plant_from(ZBP_A, ZBP_B, E=ZBP_E, w_max=0.5)
    with pytest.raises(InputError, match="synthesis.objective: 'Stability' is not one of"):
        synthesize_lti(with_w, 0.5, 0.0, 0.5, 0, "Stability")
    assert synthesize_lti(with_w, 0.5, 0.0, 0.5, 0, "auto", threads=1).objective == "ultimate-bound"
    assert synthesize_lti(lti_plant_from(ZBP_A, ZBP_B), 0.5, 0.0, 0.5, 0, "auto").objective == "stability"


def test_an_uncontrollable_plants_refusal_says_so() -> None:
    with pytest.raises(InfeasibleError, match="not controllable"):
        synthesize_lti(lti_plant_from(np.diag([0.0, 0.1]), np.array([[0.1], [0.0]])), 0.1, 0.0, 0.05, 0, "stability")


def test_a_too_fast_decay_is_told_to_come_closer_to_one() -> None:
    """decay is the factor sqrt(V) shrinks by per period: a smaller one asks more (the hint said the
    opposite), and a stability design's input limits never make it infeasible (not blamed).  Infeasible is said
    only where a solver of the chain concluded it: at these tiny alphas Clarabel's solve often ends in an error and
    the fallback's in 'inaccurate', and which of them concludes depends on the machine (an AMD EPYC: decay 0.05
    and 0.1 end in a solver failure, 0.01, 0.02, 0.2 and 0.3 infeasible), so each outcome is judged by its steps."""
    for decay in (0.01, 0.05, 0.1, 0.3):
        steps: list[str] = []
        with pytest.raises((InfeasibleError, SolverFailure), match="closer to 1") as exc:
            synthesize_lti(lti_plant_from(np.array([[0.5]]), np.array([[1.0]]), u_max=[0.5]), 0.1, 0.0, 0.1, 0,
                           "stability", decay=decay, say=steps.append)
        assert "input limits" not in str(exc.value)
        concluded = [st for st in steps if st.endswith(": infeasible")]
        if isinstance(exc.value, InfeasibleError):
            assert concluded and concluded == steps[-1:], (decay, steps)  # the chain's last solver said so
        else:  # a failure of every solver tried is never called infeasible (it used to be, on the failure alone)
            assert not concluded and steps[-1].startswith(f"alpha {decay ** 2:.4f}: failed"), (decay, steps)
            assert "the fallback solver" in " ".join(steps), (decay, steps)


def test_synthesize_and_verify_take_a_linear_plant(zbp_bound) -> None:
    """robustsynth.synthesize and robustsynth.verify on a LinearPlant: the same gain as synthesize_lti's (the same
    objective's design, so the same solves: equal to the last digit), verified as verify_lti verifies it; a
    setting that shapes the plant, a bad override and a robot's gain are one-line refusals."""
    import robustsynth
    from robustsynth.errors import InputError
    from robustsynth.verification.lti import verify_lti

    pl, ref = zbp_bound
    plant = robustsynth.LinearPlant(pl, robustsynth.Network(0.5, 0.0, 0.5, 0), 2, "zbp")
    design = robustsynth.synthesize(plant, objective="ultimate-bound")
    assert design.check.passed and np.array_equal(design.K, ref.K) and design.certified == ref.certified
    data = robustsynth.verify(plant, design, runs=8)
    direct = verify_lti(pl, ref.K, ref.P, 0.5, 0.0, 0.5, 0, ref.certified, runs=8, seed=0,
                        multipliers=ref.certificate["multipliers"], pieces=2)
    # a Verdict: passed, checks and failed_checks as the robot's VerificationResult has them; to_dict is verify_lti's
    assert data.passed and data.failed_checks == [] and [(c["name"], c["passed"], c["value"]) for c in data.checks] == \
        [(c["name"], c["passed"], c["value"]) for c in direct["checks"]]
    assert set(data.to_dict()) == set(direct) and data.to_dict()["families"] == direct["families"]
    with pytest.raises(InputError, match=r"^synthesis.objective: H2 \(overridden: --objective\): synthesis.objective: "
                                         "Input should be 'auto', 'ultimate-bound', 'stability' or 'hinf'"):
        robustsynth.synthesize(plant, objective="H2")
    with pytest.raises(InputError, match="synthesis.pieces: 3 differs from the 2"):
        robustsynth.synthesize(plant, pieces=3)
    with pytest.raises(InputError, match="a linear plant's gain is the SynthesisResult"):
        robustsynth.verify(plant, ref.K)


def test_the_old_top_level_names_warn_and_are_the_same_functions() -> None:
    import robustsynth
    from robustsynth.synthesis import lti
    from robustsynth.verification import lti as vlti

    with pytest.warns(DeprecationWarning, match=r"robustsynth.synthesize\(LinearPlant"):
        assert robustsynth.synthesize_lti is lti.synthesize_lti
    with pytest.warns(DeprecationWarning, match=r"robustsynth.verify\(LinearPlant"):
        assert robustsynth.verify_lti is vlti.verify_lti


def test_a_linear_plants_own_settings_are_the_default() -> None:
    """synthesize(plant) without settings: the config's the plant came from, else the defaults at the plant's own
    pieces (a plant of 3 pieces is not refused for the default's 2); a robot's settings are one line."""
    import robustsynth
    from robustsynth.config import SynthesisConfig
    from robustsynth.errors import InputError

    pl = lti_plant_from(ZBP_A, ZBP_B)
    plant = robustsynth.LinearPlant(pl, robustsynth.Network(0.5, 0.0, 0.5, 0), 3, "zbp")
    design = robustsynth.synthesize(plant, threads=1)
    assert design.check.passed and design.objective == "stability"
    with pytest.raises(InputError, match="a linear plant's settings are an LtiSynthesisConfig"):
        robustsynth.synthesize(plant, SynthesisConfig())


def test_the_robots_calls_on_a_linear_config_point_to_the_plant_and_the_route_works() -> None:
    """build_model and synthesize refuse a linear plant's config in one line that names what to call instead;
    what it names (LinearPlant.from_config, then robustsynth.synthesize) certifies a gain."""
    from pathlib import Path

    import robustsynth
    from robustsynth.errors import InputError

    root = Path(__file__).resolve().parents[2]
    cfg = robustsynth.load_config(root / "configs" / "dc-motor.yaml")
    for call in (robustsynth.build_model, robustsynth.synthesize, lambda c: robustsynth.verify(c, np.zeros((2, 5)))):
        with pytest.raises(InputError, match=r"linear plant's \(plant: kind: lti\): its plant is "
                                             r"robustsynth.LinearPlant.from_config\(config\)"):
            call(cfg)
    assert robustsynth.synthesize(robustsynth.LinearPlant.from_config(cfg, str(root / "configs"))).check.passed
