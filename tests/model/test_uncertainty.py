"""Coverage of the norm-bounded embedding (eqs. 31-33): every admissible delay sequence is
reproduced exactly by some Delta with |Delta| <= 1, and Delta = 0 gives the nominal model."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.model import build_model, coverage_check

from ..conftest import make_config

EMBED_TOL = 1e-12  # exact vs. embedded matrices (issue 2)
NORM_TOL = 1e-12  # |Delta_ii| <= 1 up to round-off


def _embedded(model, dlt):
    A = model.A + np.einsum("ij,nj,jk->nik", model.B_p, dlt, model.C_q)
    B = model.B + np.einsum("ij,nj,jk->nik", model.B_p, dlt, model.D_q)
    return A, B


@pytest.mark.parametrize("tau", [(0.01, 0.08), (0.0, 0.1), (0.0, 0.25), (0.12, 0.25), (0.05, 0.29)])
def test_coverage_on_1000_random_sequences(tau) -> None:
    m = build_model(make_config(**{"network.delay.min": tau[0], "network.delay.max": tau[1]}))
    rng = np.random.default_rng(3)
    taus = rng.uniform(*tau, size=(1000, 12 + m.d_hi))
    s = m.s_tilde(taus).reshape(-1, m.d_hi)
    dlt = m.delta(s)
    assert np.max(np.abs(dlt)) <= 1 + NORM_TOL
    A_ex, B_ex = m.exact(s)
    A_em, B_em = _embedded(m, dlt)
    assert np.max(np.abs(A_ex - A_em)) <= EMBED_TOL
    assert np.max(np.abs(B_ex - B_em)) <= EMBED_TOL
    # Delta is block structured: diag(d1, d1, d2) per instant
    assert np.array_equal(dlt[:, 0::3], dlt[:, 1::3])


def test_delta_zero_gives_nominal(default_config) -> None:
    m = build_model(default_config)
    A, B = _embedded(m, np.zeros((1, m.n_q)))
    assert np.array_equal(A[0], m.A) and np.array_equal(B[0], m.B)


def test_box_centre_is_tighter_than_mid_instant(default_config) -> None:
    """alpha2 of the box centre is (h_max - h_min)^2 / 8 below math.md's mid-range instant."""
    m = build_model(default_config)
    (inst,) = m.instants
    h_min, h_max = inst.h_range
    w = (h_max - h_min) / 2
    mid_alpha2 = inst.h_c * w + w * w / 2
    assert inst.alpha2 == pytest.approx(mid_alpha2 - (h_max - h_min) ** 2 / 8, rel=1e-12)


@given(
    Ts=st.floats(0.01, 0.5),
    lo=st.floats(0.0, 3.0),
    width=st.floats(0.0, 3.0),
    V=st.floats(0.05, 5.0),
    D=st.floats(0.05, 2.0),
)
@settings(max_examples=60, deadline=None)
def test_coverage_property_over_random_configs(Ts, lo, width, V, D) -> None:
    cfg = make_config(
        **{
            "network.sampling_time": Ts,
            "network.delay.min": lo * Ts,
            "network.delay.max": (lo + width) * Ts,
            "reference.speed": V,
            "robot.track_distance": D,
        }
    )
    m = build_model(cfg)
    assert m.n_s == 3 + 2 * m.d_hi
    assert m.d_hi - m.d_lo >= len(m.instants)
    cov = coverage_check(m, n_sequences=50, steps=8)
    assert cov["max_abs_delta"] <= 1 + NORM_TOL
    # residual relative to the matrices' scale (Ts up to 0.5 s, V up to 5 m/s)
    assert cov["max_residual"] <= EMBED_TOL * max(1.0, V * Ts)


def test_slip_box_reproduces_range() -> None:
    m = build_model(make_config(**{"slip.right.min": 0.5, "slip.right.max": 1.1}))
    W = m.slip.W
    corners = np.array(np.meshgrid(*([[-1.0, 1.0]] * W.shape[1]))).reshape(W.shape[1], -1)
    if "centre" in m.slip.labels:
        corners[m.slip.labels.index("centre")] = 1.0
    d = W @ corners
    assert np.allclose(d.min(axis=1), m.slip.d_min) and np.allclose(d.max(axis=1), m.slip.d_max)


def test_slip_coordinates_invert_W() -> None:
    m = build_model(make_config(**{"slip.right.min": 0.5, "slip.right.max": 1.1}))
    rng = np.random.default_rng(0)
    d = rng.uniform(m.slip.d_min, m.slip.d_max, size=(100, 2))
    w = m.slip.coordinates(d)
    assert np.allclose(w @ np.asarray(m.slip.W).T, d, atol=1e-14)
    assert np.all(np.abs(w) <= 1 + 1e-12)
