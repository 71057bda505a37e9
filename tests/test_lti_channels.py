"""Issue 53: instants of a linear plant whose ranges are equal share one remainder channel
(``core.delays.channel_groups``).  Their remainders w_j enter the plant's rows as one sum W; the numpy check
bounds W by the parallel sum H of the instants' multipliers D_j, the least ``sum_j w_j' D_j w_j`` takes over
the splits of W (``certificate.lti.lti_vertex_blocks``, rounded down by ``_parallel_sum_down``), and the solver
gives a group's instants equal multipliers (``synthesis.lti.analyze_lti``, diagonal -a / g: linear).

Tested: the rounding never above the exact parallel sum (hypothesis, exact rationals); the grouped block
equals the per-instant one at the worst split and is above it at any other; both blocks are negative definite
together (and the checks' verdicts agree) on random certificates; the groups hold bit-identical pieces; and a
certificate of the grouped LMIs makes V shrink on 10 000 exactly lifted closed loops."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.certificate.lti import LTI_PROOF_MARGIN, _parallel_sum_down, check_lti_certificate, lti_vertex_blocks
from robustsynth.margins.linear import spectral_radius
from robustsynth.core.lifting import instant_ranges
from robustsynth.core.delays import channel_groups, exact_closed_loop, kept_directions, lti_depth, over_approximation, pad_lti_gain, vertex_combinations
from robustsynth.model.lti import lti_plant_from
from robustsynth.synthesis.lti import DECAY, analyze_lti
from robustsynth.verified import UNIT_ROUNDOFF, round_down_array, round_up_array

SERVO = (np.array([[0.0, 1.0], [0.0, -72.5]]), np.array([[0.0], [75.3]]), -np.array([[7.27, 0.14]]), 0.02)
CURRENT = (np.array([[0.0, 1.0, 0.0], [0.0, -5.0, 50.0], [0.0, -10.0, -1000.0]]), np.array([[0.0], [0.0], [1000.0]]),
           np.array([[-0.94, -0.115, -0.0057]]), 0.02)  # tests/data/fast-current.yaml: two kept directions
FRACTION = 0.8  # of the first destabilizing constant delay: issue 53's target for certified / exhibited
IDENTITY_REL = 1e-9  # relative to the blocks' magnitude: the grouped and per-instant forms at the worst split
SIGN_BAND = 1e-9  # relative to the block's norm: eigenvalues this close to 0 say nothing about the sign
VERDICT_BAND = 10 * LTI_PROOF_MARGIN  # the checks' verdicts are compared where the per-instant blocks' least
# eigenvalue of -X lies beyond g times this, or below -SIGN_BAND (in between the factor g may decide)
SAMPLES = 10_000  # exactly lifted closed loops per plant


def _exact_h(a: list[float]) -> Fraction:
    """The parallel sum of the floats a_j in exact rationals (0 when some a_j is 0)."""
    if any(x == 0.0 for x in a):
        return Fraction(0)
    return 1 / sum(1 / Fraction(x) for x in a)


_wide = st.floats(min_value=0.0, max_value=1.7e308, allow_nan=False, allow_infinity=False)
_moderate = st.floats(min_value=1e-200, max_value=1e200)


@given(a=st.lists(st.one_of(_wide, _moderate, st.sampled_from([0.0, 5e-324, 1e-300, 1e300, 1.0])), min_size=1,
                  max_size=12))
@settings(max_examples=400, deadline=None)
def test_the_parallel_sum_is_rounded_down_never_above_the_exact_one(a) -> None:
    """_parallel_sum_down(a) <= (sum_j 1 / a_j)^-1 in exact arithmetic, for any nonnegative floats (zeros,
    subnormals, the largest); and within (3 g + 7) u of it (g + 1 roundings, the rounding down's own 2 (g + 2) u
    and an ulp) where every a_j and the result lie in the normal range, so the bound is not vacuous there."""
    g = len(a)
    got = float(_parallel_sum_down(np.array([a]))[0])
    exact = _exact_h(a)
    assert got >= 0.0 and Fraction(got) <= exact
    if all(1e-300 <= x <= 1e300 for x in a) and Fraction(1, 10**300) <= exact <= 10**300:
        assert Fraction(got) >= exact * (1 - Fraction((3 * g + 7) * UNIT_ROUNDOFF))


@given(x=st.floats(min_value=-1e150, max_value=1e150, allow_nan=False),
       y=st.floats(min_value=1e-150, max_value=1e150),
       terms=st.lists(st.floats(min_value=0.0, max_value=1e250), min_size=2, max_size=9))
@settings(max_examples=400, deadline=None)
def test_round_down_and_up_bracket_products_quotients_and_positive_sums(x, y, terms) -> None:
    """round_down_array(r, ops) <= exact <= round_up_array(r, ops) for a product and a quotient (one rounding)
    and a sum of k nonnegative terms (k - 1 roundings), r the float result: the relative-error model
    _parallel_sum_down relies on."""
    for r, exact, ops in ((x * y, Fraction(x) * Fraction(y), 1), (x / y, Fraction(x) / Fraction(y), 1),
                          (sum(terms), sum(Fraction(t) for t in terms), len(terms) - 1)):
        lo, hi = float(round_down_array(np.array([r]), ops)[0]), float(round_up_array(np.array([r]), ops)[0])
        assert Fraction(lo) <= exact <= Fraction(hi)


def _plant_pw(plant: tuple, fraction: float = FRACTION, pieces: int = 1):
    """The over-approximation of a plant at ``fraction`` of its first destabilizing constant delay (a scan
    of the exact lifted loop: independent of the margin search)."""
    A, B, K, Ts = plant
    grid = np.linspace(0.0, 20 * Ts, 801)
    first = float(grid[np.argmax(spectral_radius(lti_plant_from(A, B, K=K), Ts, grid[:, None]) > 1.0)])
    tau = fraction * first
    d = lti_depth(tau, 0, Ts)
    n, m = B.shape
    return over_approximation(A, B, pad_lti_gain(K, n, m, d), Ts, 0.0, tau, d, pieces), tau


@pytest.fixture(scope="module", params=["servo", "current"])
def grouped(request):
    """(plant, pw, tau, the grouped LMIs' analysis) near each fast plant's certified bound."""
    plant = SERVO if request.param == "servo" else CURRENT
    pw, tau = _plant_pw(plant)
    return plant, pw, tau, analyze_lti(pw)


def test_instants_on_equal_ranges_share_bit_identical_pieces_and_channels(grouped) -> None:
    """The groups are the instants on equal ranges (those with a channel): every instant of a group has the
    same pieces, bounds and channel matrix bit for bit; with multi-period delays most instants share one."""
    plant, pw, tau, _ = grouped
    kept, _ = kept_directions(pw)
    groups = channel_groups(pw, kept)
    assert sorted(j for g in groups for j in g) == [j for j in range(pw.d_hi) if len(kept[j])]
    key = lambda j: (pw.theta[j].tobytes(), pw.width[j].tobytes())  # noqa: E731
    for g in groups:
        for j in g[1:]:
            assert key(j) == key(g[0])
            for field in (pw.base, pw.slope, pw.rho, pw.rho_dir, pw.dirs):
                assert np.array_equal(field[j], field[g[0]])
            assert np.array_equal(pw.channels(j)[:, kept[j]], pw.channels(g[0])[:, kept[g[0]]])
    assert len({key(g[0]) for g in groups}) == len(groups)  # one group per distinct range
    assert max(len(g) for g in groups) >= pw.d_hi - 2  # the middle instants all range over [0, Ts]


def _random_multipliers(rng: np.random.Generator, pw, n_c: int) -> np.ndarray:
    """Positive multipliers in the analysis layout (n_c, d, 1 + n), different for every instant."""
    return np.exp(rng.normal(size=(n_c, pw.d_hi, 1 + pw.E.shape[1])))


def _layouts(pw):
    """(groups, per-instant coordinates of each group's channel) of the merged and the per-instant blocks."""
    kept, _ = kept_directions(pw)
    groups = channel_groups(pw, kept)
    n_s = pw.E.shape[0]
    own, pos = {}, n_s
    for j in range(pw.d_hi):
        own[j] = np.arange(pos, pos + len(kept[j]))
        pos += len(kept[j])
    return kept, groups, own


def test_the_grouped_block_is_the_per_instant_one_at_its_worst_split(grouped) -> None:
    """For random positive multipliers and random (xi, W): the grouped quadratic form equals the per-instant
    form at the split w_j = D_j^-1 H W (its maximum over splits, to IDENTITY_REL) and is never below it at a
    random split of the same W (the check's lower bound on the multipliers' cost holds for every split)."""
    _, pw, _, _ = grouped
    rng = np.random.default_rng(0)
    verts = vertex_combinations(pw)
    combos, owner, _ = verts
    n_s = pw.E.shape[0]
    kept, groups, own = _layouts(pw)
    P = np.eye(n_s) + 0.1 * np.diag(rng.random(n_s))
    eps = _random_multipliers(rng, pw, len(combos))
    Xg, Mg, _ = lti_vertex_blocks(pw, P, eps, DECAY, verts, merge=True)
    Xu, Mu, _ = lti_vertex_blocks(pw, P, eps, DECAY, verts, merge=False)
    for v in range(len(owner)):
        c = owner[v]
        for _ in range(20):
            zg = rng.normal(size=Xg.shape[-1])
            zu, zr = np.zeros(Xu.shape[-1]), np.zeros(Xu.shape[-1])
            zu[:n_s] = zr[:n_s] = zg[:n_s]
            at = n_s
            for g in groups:
                W = zg[at:at + len(kept[g[0]])]
                at += len(W)
                D = np.array([eps[c, j, 0] + eps[c, j, 1 + kept[j]] for j in g])  # (|g|, directions)
                H = 1.0 / np.sum(1.0 / D, axis=0)
                split = rng.dirichlet(np.ones(len(g)))
                for i, j in enumerate(g):
                    zu[own[j]] = H / D[i] * W  # the worst split
                    zr[own[j]] = split[i] * W + (rng.normal(size=W.size) if i < len(g) - 1 else 0.0)
                zr[own[g[-1]]] = W - sum(zr[own[j]] for j in g[:-1])  # any split of the same W
            scale = IDENTITY_REL * (np.abs(zg) @ Mg[v] @ np.abs(zg) + np.abs(zu) @ Mu[v] @ np.abs(zu)
                                    + np.abs(zr) @ Mu[v] @ np.abs(zr))
            # the blocks are -X: the per-instant form is at most the grouped one, equal at the worst split
            assert zg @ Xg[v] @ zg == pytest.approx(zu @ Xu[v] @ zu, abs=scale)
            assert zr @ Xu[v] @ zr >= zg @ Xg[v] @ zg - scale


def test_grouped_and_per_instant_blocks_are_negative_definite_together(grouped) -> None:
    """Random certificates around the solver's (multipliers scaled by random factors per entry, P perturbed):
    the grouped and the per-instant blocks are negative definite together (with positive multipliers both
    state V+ < decay^2 V), their largest eigenvalues within the factor g of each other, and the checks'
    verdicts agree (outside a band of the proof margin, which the factor g can move)."""
    _, pw, _, res = grouped
    assert res.certified
    rng = np.random.default_rng(1)
    verts = vertex_combinations(pw)
    kept, groups, _ = _layouts(pw)
    g = max(len(gr) for gr in groups)
    verdicts = set()
    for i in range(60):
        s = rng.uniform(0.0, 2.0)
        eps = res.certificate["multipliers"] * np.exp(s * rng.normal(size=res.certificate["multipliers"].shape)) + 1e-3 * (res.certificate["multipliers"] == 0)
        P = res.P * (1.0 + 0.02 * s * rng.normal())
        Xg = lti_vertex_blocks(pw, P, eps, DECAY, verts, merge=True)[0]
        Xu = lti_vertex_blocks(pw, P, eps, DECAY, verts, merge=False)[0]
        lg, lu = np.linalg.eigvalsh(Xg)[:, 0], np.linalg.eigvalsh(Xu)[:, 0]  # -lambda_max(X)
        band = SIGN_BAND * np.maximum(np.linalg.norm(Xg, 2, axis=(-2, -1)), np.linalg.norm(Xu, 2, axis=(-2, -1)))
        clear = (np.abs(lg) > band) & (np.abs(lu) > band)
        assert np.array_equal(lg[clear] > 0, lu[clear] > 0)
        pos = clear & (lu > 0)  # X_u <= -m I gives X_g <= -(m / g) I; lambda_max(X_u) = t > 0 gives X_g's >= t / g
        neg = clear & (lu < 0)
        assert np.all(lg[pos] >= lu[pos] / g - band[pos]) and np.all(lg[neg] <= lu[neg] / g + band[neg])
        okg = check_lti_certificate(pw, P, eps, DECAY, verts, merge=True)["ok"]
        oku = check_lti_certificate(pw, P, eps, DECAY, verts, merge=False)["ok"]
        if np.min(lu) > g * VERDICT_BAND or np.any(lu < -band):
            assert okg == oku
            verdicts.add(okg)
    assert verdicts == {True, False}  # both verdicts occur: the agreement is not that of a constant


def test_the_grouped_solver_gives_a_groups_instants_equal_multipliers_and_the_old_check_accepts_them(grouped) -> None:
    """The solver's multipliers are equal across each group's instants (the linear form of the parallel sum);
    its certificate passes the per-instant check too, which computes no parallel sum at all."""
    _, pw, _, res = grouped
    assert res.certified
    kept, groups, _ = _layouts(pw)
    for g in groups:
        for j in g[1:]:
            assert np.array_equal(res.certificate["multipliers"][:, j, [0, *(1 + kept[j])]], res.certificate["multipliers"][:, g[0], [0, *(1 + kept[g[0]])]])
    assert check_lti_certificate(pw, res.P, res.certificate["multipliers"], DECAY, vertex_combinations(pw), merge=False)["ok"]


def test_a_grouped_certificate_makes_V_shrink_on_exactly_lifted_loops(grouped) -> None:
    """Coverage of the grouped channel, end to end: the certified P makes V shrink by decay^2 on SAMPLES
    exactly lifted closed loops at random in-order instants of the certified range, and at its extremes."""
    plant, pw, tau, res = grouped
    assert res.certified
    A, B, K, Ts = plant
    n, m = B.shape
    d = pw.d_hi
    rng = np.random.default_rng(2)
    r = instant_ranges(0.0, tau, Ts, d)
    s = r[:, 0] + (r[:, 1] - r[:, 0]) * rng.random((SAMPLES, d))
    s = np.concatenate([s, r[:, 0][None], r[:, 1][None], np.where(rng.random((64, d)) < 0.5, r[:, 0], r[:, 1])])
    s = np.maximum.accumulate(s[:, ::-1], axis=1)[:, ::-1]  # in order
    M = exact_closed_loop(A, B, pad_lti_gain(K, n, m, d), Ts, s)
    L = np.linalg.cholesky(res.P)
    Li = np.linalg.inv(L)
    # V(M xi) <= decay^2 V(xi) for all xi iff the spectral norm of L' M L^-T is at most decay
    Mt = np.einsum("ab,vbc,cd->vad", L.T, M, Li.T)
    assert np.max(np.linalg.norm(Mt, 2, axis=(-2, -1))) < DECAY


@pytest.mark.parametrize("plant,fractions,m_lost", [(SERVO, (0.1, 0.35, 0.6, 0.9), 0), (CURRENT, (0.2, 0.5, 0.9), 0),
                                                    (CURRENT, (0.3,), 2)])
def test_the_budgets_block_size_is_the_grouped_lmis_or_more(plant, fractions, m_lost) -> None:
    """margins.linear.block_size, which sets the pieces before anything is built, is never below the size of the
    grouped LMIs' blocks (the lifted state and every group's kept directions), and counts fewer channels than
    one per instant once the delays span several periods."""
    from robustsynth.margins.linear import block_size

    A, B, K, Ts = plant
    n, m = B.shape
    for f in fractions:
        pw, tau = _plant_pw(plant, f)
        d = lti_depth(tau, m_lost, Ts)
        pw = over_approximation(A, B, pad_lti_gain(K, n, m, d), Ts, 0.0, tau + m_lost * Ts, d, 2)
        kept, groups, _ = _layouts(pw)
        actual = n + d * m + sum(len(kept[g[0]]) for g in groups)
        estimate = block_size(n, m, d, 0.0, tau + m_lost * Ts, Ts)
        assert actual <= estimate
        if d >= 4:
            assert estimate < n + d * m + d * n
