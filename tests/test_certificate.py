"""The certificate module's set bounds (docs/theory.md §6i): ``set_max`` bounds the largest |c xi| on
the intersection over the delay vertices of the ellipsoids {xi' S(mu, d)^-1 xi <= level}, for every
slip; checked against points sampled on that intersection's boundary, and against the old bound (the
largest entry over every matrix), which it never exceeds."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from robustsynth.certificate import set_max

SAMPLES = 4000  # boundary points per slip weight draw
ROUND_REL = 1e-12  # round-off in the sampled |c xi|^2 (the bound is rounded up, the samples are not)


def _random_spd(rng, n):
    A = rng.normal(size=(n, n))
    return A @ A.T + 0.1 * np.eye(n)


@given(seed=st.integers(0, 2**32 - 1), n_c=st.integers(1, 4), n_d=st.integers(1, 3))
@settings(max_examples=25, deadline=None)
def test_bound_holds_on_the_intersection_for_every_slip(seed, n_c, n_d):
    rng = np.random.default_rng(seed)
    n, level = 3, 1.7
    S = [_random_spd(rng, n) for _ in range(n_c * n_d)]  # index m * n_d + d, as certificates order them
    c = rng.normal(size=n)
    q = np.array([c @ Sj @ c for Sj in S])
    bound = set_max(q, n_d)
    assert bound <= np.max(q) * (1 + 1e-15)  # never looser than the largest entry
    assert bound <= np.min(q.reshape(n_c, n_d).max(axis=0)) * (1 + 1e-15)  # nor than min over d of max over m
    for _ in range(3):  # a slip: convex weights over the corners
        lam = rng.dirichlet(np.ones(n_c))
        Sd = [sum(lam[m] * S[m * n_d + d] for m in range(n_c)) for d in range(n_d)]
        Pd = [np.linalg.inv(x) for x in Sd]
        X = rng.normal(size=(SAMPLES, n))
        V = np.max([np.einsum("ki,ij,kj->k", X, P, X) for P in Pd], axis=0)
        xi = X * np.sqrt(level / V)[:, None]  # on the boundary of the intersection
        assert np.max((xi @ c) ** 2) <= level * bound * (1 + ROUND_REL)


def test_one_matrix_per_group_is_the_plain_maximum():
    q = np.array([0.3, 2.0, 1.1])
    assert set_max(q, 1) == 2.0


def test_two_ellipsoids_whose_intersection_is_small():
    """Two delay vertices whose ellipsoids are long in different directions: along c = e_1 one allows
    10, the other 1 -- the bound takes the smaller for a single slip corner."""
    q = np.array([10.0, 1.0])
    assert set_max(q, 2) <= 1.0 * (1 + 1e-15)
    # with two slip corners that disagree on which d is small, a mixture beats either unit vector
    q2 = np.array([10.0, 1.0, 1.0, 10.0])  # rows: corner m, columns: delay vertex d
    assert set_max(q2, 2) <= 5.5 * (1 + 1e-12)  # theta = (1/2, 1/2)
    assert np.min(q2.reshape(2, 2).max(axis=0)) == 10.0
