"""Closed forms of the sampled pieces against expm, and the linearization against the nonlinear
error dynamics (eq. 17) by finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.model.kinematics import G_matrix, JHJinv, J_inverse, J_matrix
from robustsynth.model.linearize import Gamma, Gamma_D, Phi, continuous_matrices, van_loan

EXPM_TOL = 1e-12  # closed form vs. Van Loan expm (relative to 1)
FD_TOL = 1e-6  # central finite differences with step 1e-6


@given(V=st.floats(0.05, 5.0), D=st.floats(0.05, 2.0), h=st.floats(0.0, 1.0))
@settings(max_examples=100, deadline=None)
def test_closed_forms_match_van_loan(V: float, D: float, h: float) -> None:
    A, B, B_D = continuous_matrices(V, D)
    E, G = van_loan(A, B, h)
    assert np.allclose(Phi(A, h), E, atol=EXPM_TOL, rtol=0)
    assert np.allclose(Gamma(A, B, h), G, atol=EXPM_TOL, rtol=0)
    _, GD = van_loan(A, B_D, h)
    assert np.allclose(Gamma_D(A, B_D, h), GD, atol=EXPM_TOL, rtol=0)


def test_A_is_nilpotent() -> None:
    A, _, _ = continuous_matrices(0.7, 0.4)
    assert np.all(A @ A == 0)


def test_kinematics_identities() -> None:
    R, D = 0.09, 0.45
    assert np.allclose(J_matrix(R, D) @ J_inverse(R, D), np.eye(2), atol=1e-14)
    mu_r, mu_l = 0.7, 0.9
    direct = J_matrix(R, D) @ np.diag([mu_r, mu_l]) @ J_inverse(R, D)
    assert np.allclose(JHJinv(mu_r, mu_l, D), direct, atol=1e-14)
    assert np.allclose(JHJinv(1.0, 1.0, D), np.eye(2))


def _e_dot(e: np.ndarray, du: np.ndarray, d: np.ndarray, V: float, D: float) -> np.ndarray:
    """Nonlinear error dynamics in frame L (eq. 17) with theta_0 = 0 and q_L^D = [V t, 0, 0]."""
    u_hat = np.array([V, 0.0]) + du
    u = JHJinv(1.0 + d[0], 1.0 + d[1], D) @ u_hat
    return G_matrix(e[2]) @ u - np.array([V, 0.0, 0.0])


@pytest.mark.parametrize("V,D", [(0.5, 0.45), (1.5, 0.3), (0.1, 1.0)])
def test_linearization_matches_finite_differences(V: float, D: float) -> None:
    A, B, B_D = continuous_matrices(V, D)
    h = 1e-6
    z3, z2 = np.zeros(3), np.zeros(2)
    for i in range(3):
        de = np.eye(3)[i] * h
        col = (_e_dot(de, z2, z2, V, D) - _e_dot(-de, z2, z2, V, D)) / (2 * h)
        assert np.allclose(col, A[:, i], atol=FD_TOL)
    for i in range(2):
        du = np.eye(2)[i] * h
        assert np.allclose((_e_dot(z3, du, z2, V, D) - _e_dot(z3, -du, z2, V, D)) / (2 * h), B[:, i], atol=FD_TOL)
        assert np.allclose((_e_dot(z3, z2, du, V, D) - _e_dot(z3, z2, -du, V, D)) / (2 * h), B_D[:, i], atol=FD_TOL)
