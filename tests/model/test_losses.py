"""The exact description of a lossy link (lossy-polytopic): its vertices reproduce the lifted map of
every loss/delay history, they lie inside the longer-delay description (so it can only certify
less conservatively), and instants a lossy link cannot produce are refused."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.errors import ConfigError
from robustsynth.model import build_model, coverage_check
from robustsynth.model.vertices import loss_hull_coordinates, loss_vertex_gammas

from ..conftest import make_config

BARY_TOL = 1e-12  # barycentric coordinates may dip this far below 0 from round-off


@pytest.mark.parametrize("m", [1, 2, 3])
def test_vertices_cover_every_loss_history(m) -> None:
    model = build_model(make_config(**{"network.dropouts.max_consecutive": m}))
    assert model.delay_description == "lossy-polytopic"  # auto picks it on a lossy link with tau_max <= Ts
    cov = coverage_check(model)
    assert cov["passed"], cov


@pytest.mark.parametrize("m", [1, 2, 3])
def test_the_exact_hull_lies_inside_the_longer_delay_hull(m) -> None:
    """Each tight vertex, per instant j, has (h_j, q_j) inside the triangle of the longer-delay
    polytopic description (whose hull is the product of those triangles)."""
    cfg = make_config(**{"network.dropouts.max_consecutive": m})
    model = build_model(cfg)
    Ts, dl = model.Ts, cfg.network.delay
    A_c, B_c = np.asarray(model.A_c), np.asarray(model.B_c)
    _, gam = loss_vertex_gammas(A_c, B_c, Ts, dl.min, dl.max, m, model.d_hi, 1e-12)
    # recover (h, q) from Gamma = h B + q A B (B and A B are independent columns here)
    basis = np.stack([B_c.reshape(-1), (A_c @ B_c).reshape(-1)], axis=1)
    for v in gam:
        for j, G in enumerate(v):
            (h, q), *_ = np.linalg.lstsq(basis, G.reshape(-1), rcond=None)
            lo, hi = model.instant_ranges[j]
            h_min, h_max = Ts - hi, Ts - lo
            if h_max - h_min <= 1e-12:
                assert h == pytest.approx(h_max) and q == pytest.approx(h_max**2 / 2)
                continue
            # inside the triangle (h_min, h_min^2/2), (h_max, h_max^2/2), ((h_min+h_max)/2, h_min h_max/2)
            P = np.array([[h_min, h_max, (h_min + h_max) / 2], [h_min**2 / 2, h_max**2 / 2, h_min * h_max / 2],
                          [1.0, 1.0, 1.0]])
            bary = np.linalg.solve(P, [h, q, 1.0])
            assert np.all(bary >= -BARY_TOL), (j, h, q, bary)


def test_instants_a_lossy_link_cannot_produce_are_refused() -> None:
    cfg = make_config(**{"network.dropouts.max_consecutive": 1})
    dl = cfg.network.delay
    # packet k-1 arriving half-way through period k: only possible with a delay of 0.15 s > tau_max
    with pytest.raises(ValueError, match="not reachable"):
        loss_hull_coordinates(np.array([0.1, 0.05]), 0.1, dl.min, dl.max, 1, 2, 1e-12)
    w = loss_hull_coordinates(np.array([[0.05, 0.05], [0.1, 0.0], [0.03, 0.0]]), 0.1, dl.min, dl.max, 1, 2, 1e-12)
    np.testing.assert_allclose(w.sum(axis=-1), 1.0)
    assert np.all(w >= -BARY_TOL)


def test_lossy_polytopic_needs_tau_max_within_a_period() -> None:
    cfg = make_config(**{"network.dropouts.max_consecutive": 1, "network.delay.max": 0.15,
                         "synthesis.delay_description": "lossy-polytopic"})
    with pytest.raises(ConfigError, match="synthesis.delay_description: lossy-polytopic needs network.delay.max"):
        build_model(cfg)
    auto = build_model(make_config(**{"network.dropouts.max_consecutive": 1, "network.delay.max": 0.15}))
    assert auto.delay_description == "norm-bounded"  # the longer-delay description
