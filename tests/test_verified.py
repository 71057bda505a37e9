"""Verified positive definiteness (issue 29): Rump's test proves what it says and refuses what it
cannot prove, the assembly radius bounds the rounding of an LMI's assembly (cross-checked against
an evaluation in extended precision), and a certificate whose margin sits below the rounding level
is reported "not proven (rounding)", never certified."""

from __future__ import annotations


import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.certificate import check_certificate
from robustsynth.certificate.lmis import lmi_invariance
from robustsynth.verified import (UNIT_ROUNDOFF, assembly_radius, assembly_radius_batch, is_pd, is_pd_batch,
                                  proves_at_least, proves_at_least_batch, round_up, round_up_array, rump_shift,
                                  rump_shift_batch)

from .conftest import committed_gain



def _random_spd(rng, n: int, lam_min: float, cond: float = 1e3) -> np.ndarray:
    Qm, _ = np.linalg.qr(rng.normal(size=(n, n)))
    lam = np.geomspace(lam_min, lam_min * cond, n)
    A = (Qm * lam) @ Qm.T
    return (A + A.T) / 2.0


@given(n=st.integers(1, 40), seed=st.integers(0, 2**32 - 1), cond=st.sampled_from([1.0, 1e3, 1e8]))
@settings(max_examples=60, deadline=None)
def test_well_conditioned_pd_is_proven_and_indefinite_never(n, seed, cond) -> None:
    rng = np.random.default_rng(seed)
    A = _random_spd(rng, n, 1.0, cond)
    assert is_pd(A)
    B = A.copy()
    B[n - 1, n - 1] = -1e-3 * np.max(np.abs(A))  # a negative diagonal entry: never positive definite
    assert not is_pd(B)
    assert not is_pd(-A)


def test_below_the_rounding_level_is_not_proven_though_eigvalsh_passes() -> None:
    """[[1, 1 - e], [1 - e, 1]] with e = 2^-51 has eigenvalues 2 - e and e ~ 4.4e-16: positive
    definite, and eigvalsh finds its smallest eigenvalue above 1e-16.  A gap that small against a
    unit diagonal lies within the rounding of any Cholesky factorization: the test must refuse it."""
    e = 2.0**-51
    A = np.array([[1.0, 1.0 - e], [1.0 - e, 1.0]])
    t = 1e-16
    assert np.linalg.eigvalsh(A)[0] >= t  # floating point says: passes the threshold
    assert not proves_at_least(A, t)
    assert is_pd(np.array([[1.0, 0.5], [0.5, 1.0]]))
    # a diagonal matrix is scaled entry by entry (exactly, by powers of two): its tiny but exact
    # positive entry is proven, as it should be
    assert proves_at_least(np.diag([1.0, 5e-8 * (1 + 1e-12)]), 5e-8)
    assert not proves_at_least(np.diag([1.0, 5e-8]), 5e-8)  # equality is not "at least" with a proof


def test_the_shift_and_outward_rounding_are_upper_bounds() -> None:
    d = np.array([1.0, 0.25, 0.5])
    c = rump_shift(d)
    assert c >= sum((k + 3) * UNIT_ROUNDOFF * x for k, x in enumerate(d))
    for x in (1.0, 3.0e-7, 123.456):
        assert round_up(x) > x and round_up(x) <= x * (1 + 8 * UNIT_ROUNDOFF)


@pytest.fixture(scope="module")
def default_cert():
    return committed_gain("tracks-box")


def test_assembly_radius_bounds_the_rounding_of_an_lmi(default_cert) -> None:
    """The invariance LMI of each vertex assembled in double precision, against the same formula
    evaluated in extended precision (numpy longdouble): the difference stays within the radius."""
    m, K, cert = default_cert
    if np.finfo(np.longdouble).eps >= np.finfo(float).eps:
        pytest.skip("this platform's longdouble is double precision: no independent reference")
    Q = np.asarray(cert["Q"], dtype=float)
    beta = np.asarray(cert["beta"], dtype=float)
    alpha = float(cert["alpha"])
    worst = 0.0
    for v in m.vertices:
        M = np.zeros((0, 0))
        L = lmi_invariance(v, Q, Q, Q, K @ Q, M, beta, alpha)
        ld = lambda a: np.asarray(a, dtype=np.longdouble)  # noqa: E731
        vl = type("V", (), {k: ld(getattr(v, k)) for k in ("A", "B", "E", "B_p", "C_q", "D_q")})
        Lx = lmi_invariance(vl, ld(Q), ld(Q), ld(Q), ld(K) @ ld(Q), ld(M), ld(beta), np.longdouble(alpha))
        av = type("V", (), {k: np.abs(getattr(v, k)) for k in ("A", "B", "E", "B_p", "C_q", "D_q")})
        mag = lmi_invariance(av, np.abs(Q), np.abs(Q), np.abs(Q), np.abs(K) @ np.abs(Q), M, beta, alpha, mag=True)
        radius = assembly_radius(mag, 2 * L.shape[0] + Q.shape[0] * 3)
        err = float(np.max(np.sum(np.abs(L.astype(np.longdouble) - Lx), axis=1)))
        assert err <= radius
        worst = max(worst, err / radius)
    assert worst > 1e-4  # the radius is a bound, not a wild overestimate


def test_a_margin_below_the_rounding_level_is_not_proven(default_cert) -> None:
    """The certificate's own threshold moved to just below its smallest eigenvalue, closer than the
    rounding allowance: eigvalsh passes, the verified test cannot, and the verdict says so."""
    m, K, cert = default_cert
    ok = check_certificate(m, K, cert)
    assert ok.passed and all(c["verified"] for c in ok.checks if "verified" in c)
    fam = next(c for c in ok.checks if c["name"].startswith("invariance LMI"))
    found, allowance = fam["margin_found"], fam["rounding_allowance"]
    tight = dict(cert, margin=2.0 * (found - 0.01 * allowance))  # threshold = margin / 2
    res = check_certificate(m, K, tight)
    fam = next(c for c in res.checks if c["name"].startswith("invariance LMI"))
    assert fam["margin_found"] >= -fam["threshold"]  # floating point alone would pass it
    assert fam["status"] == "not proven (rounding)" and not fam["passed"]
    assert not res.passed and res.reason.startswith("not proven (rounding)")
    assert res.figures["ultimate_bound"] is None  # nothing is claimed


@given(n=st.integers(1, 12), seed=st.integers(0, 2**32 - 1))
@settings(max_examples=40, deadline=None)
def test_the_batched_tests_decide_as_the_one_matrix_tests(n, seed) -> None:
    """The stack versions (the within-period vertices are proven as one stack) give, matrix by matrix,
    exactly the one-matrix results: PD, indefinite, at the rounding level, asymmetric, a zero or
    negative diagonal, a non-finite entry, and the empty matrix."""
    rng = np.random.default_rng(seed)
    mats = [_random_spd(rng, n, 1.0), _random_spd(rng, n, 1e-3, 1e8), _random_spd(rng, n, 1.0) - 2.0 * np.eye(n),
            _random_spd(rng, n, 8 * n * UNIT_ROUNDOFF, 1.0), _random_spd(rng, n, 1.0) * 1e-200]
    asym = _random_spd(rng, n, 1.0)
    asym[0, -1] += 1e-3 if n > 1 else 0.0
    zero_diag = _random_spd(rng, n, 1.0)
    zero_diag[0, 0] = 0.0
    nan = _random_spd(rng, n, 1.0)
    nan[-1, -1] = np.nan
    stack = np.array(mats + [asym, zero_diag, nan])
    assert is_pd_batch(stack).tolist() == [is_pd(A) for A in stack]
    radius = rng.uniform(0.0, 1e-6, stack.shape[0])
    for t in (0.0, 1e-9, 0.5):
        assert proves_at_least_batch(stack, t, radius).tolist() == [proves_at_least(A, t, r) for A, r in zip(stack, radius)]
    finite = stack[:5]
    assert np.array_equal(assembly_radius_batch(finite, 17), [assembly_radius(A, 17) for A in finite])
    diags = np.abs(np.diagonal(finite, axis1=-2, axis2=-1)) + 1e-300
    assert np.array_equal(rump_shift_batch(diags), [rump_shift(d) for d in diags])
    xs = np.array([0.0, 1.0, -3.5, 1e-300, np.inf])
    assert np.array_equal(round_up_array(xs, 4), [round_up(x, 4) for x in xs])
    assert is_pd_batch(np.zeros((3, 0, 0))).tolist() == [True] * 3

