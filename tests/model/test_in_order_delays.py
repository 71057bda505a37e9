"""In-order delay vertices (model/vertices.py, issue 51): the combinations of the instants' triangles that
in-order delivery needs, their explicit weights, and the coverage of the exact lifted map."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.config import load_config
from robustsynth.model import build_model, coverage_check
from robustsynth.core.network import s_tilde_sequence
from robustsynth.core.lifting import instant_ranges
from robustsynth.model.vertices import (HIGH, LOW, MID, delay_cover_ranges, in_order_combinations, in_order_weights,
                                        triangle, triangle_coordinates)

EXACT = 1e-12  # marginals and recombined points: rounding only
ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6])
def test_instants_on_one_range_need_quadratically_many_combinations(n: int) -> None:
    combos = in_order_combinations(np.tile([0.0, 0.1], (n, 1)), 1e-12)
    assert len(combos) == (n + 1) * (n + 2) // 2
    for c in combos:  # the patterns low..., tangents..., high...
        order = {LOW: 0, MID: 1, HIGH: 2}
        assert all(order[a] <= order[b] for a, b in zip(c, c[1:])), c


def test_instants_on_different_ranges_keep_every_combination() -> None:
    cover = np.array([[0.0, 0.03], [0.0, 0.05], [0.01, 0.05]])
    assert len(in_order_combinations(cover, 1e-12)) == 27
    # the two that share a range are restricted among themselves: 3 x 6
    cover = np.array([[0.0, 0.03], [0.0, 0.05], [0.0, 0.05]])
    assert len(in_order_combinations(cover, 1e-12)) == 18


@given(n=st.integers(1, 5), tmin=st.floats(0.0, 0.3), span=st.floats(0.01, 0.4), common=st.booleans(),
       seed=st.integers(0, 2**31 - 1))
@settings(max_examples=60, deadline=None)
def test_the_weights_reproduce_every_instant_exactly(n: int, tmin: float, span: float, common: bool, seed: int) -> None:
    """For delays the config allows, the switching instants of in-order delivery (s_tilde_sequence) get
    weights >= 0 summing to 1 whose marginals are each instant's triangle coordinates, so the recombined
    (h_j, h_j^2/2) is the exact one for every instant."""
    Ts = 0.1
    d_hi = max(1, int(np.ceil((tmin + span) / Ts)))
    ranges = instant_ranges(tmin, tmin + span, Ts, d_hi)
    unc, cover = delay_cover_ranges(Ts, ranges, 1e-9, "in-order-common" if common else "in-order")
    if not unc:
        return
    combos = in_order_combinations(cover, 1e-9)
    rng = np.random.default_rng(seed)
    taus = rng.uniform(tmin, tmin + span, size=(50, 30 + d_hi))
    taus[0] = tmin
    taus[1] = tmin + span
    s = s_tilde_sequence(taus, Ts, d_hi).reshape(-1, d_hi)
    h = Ts - s[:, unc]
    w = in_order_weights(h, cover, combos)
    assert w.min() >= 0.0
    assert np.max(np.abs(w.sum(axis=1) - 1.0)) <= EXACT
    C = np.array(combos)
    for k in range(len(unc)):
        tri = triangle(*cover[k])
        got = w @ tri[C[:, k]]  # (N, 2): the recombined (h_k, h_k^2/2)
        assert np.max(np.abs(got - np.stack([h[:, k], h[:, k] ** 2 / 2.0], axis=1))) <= EXACT
        marg = np.stack([w[:, C[:, k] == v].sum(axis=1) for v in range(3)], axis=1)
        assert np.max(np.abs(marg - triangle_coordinates(h[:, k], *cover[k]))) <= EXACT


def test_instants_out_of_order_are_refused() -> None:
    cover = np.tile([0.0, 0.1], (2, 1))
    combos = in_order_combinations(cover, 1e-12)
    in_order_weights(np.array([0.03, 0.07]), cover, combos)  # in order: fine
    with pytest.raises(ValueError, match="not in order"):
        in_order_weights(np.array([0.07, 0.03]), cover, combos)


def test_every_combination_is_needed_somewhere() -> None:
    """None of the (n+1)(n+2)/2 combinations can be dropped: each carries weight at some in-order point."""
    cover = np.tile([0.0, 0.1], (3, 1))
    combos = in_order_combinations(cover, 1e-12)
    grid = np.linspace(0.0, 0.1, 21)
    h = np.array([p for p in itertools.product(grid, repeat=3) if p[0] <= p[1] <= p[2]])
    w = in_order_weights(h, cover, combos)
    assert np.all(w.max(axis=0) > 0.0)


def _config(description: str, tau_max: float):
    cfg = load_config(ROOT / "configs" / "delay-multi-period.yaml")  # Ts 0.1 s, tau from 0.01 s
    net = cfg.network.model_copy(update={"delay": cfg.network.delay.model_copy(update={"max": tau_max})})
    return cfg.model_copy(update={"network": net,
                                  "synthesis": cfg.synthesis.model_copy(update={"delay_description": description})})


@pytest.mark.parametrize("description,tau_max,count,cover", [
    ("polytopic", 0.25, 27, "product"),  # three instants on three ranges: the product itself
    ("polytopic", 0.35, 54, "in-order"),  # four, two of them on [0, Ts]: 3 x 6 x 3 of 81
    pytest.param("polytopic", 0.45, 90, "in-order", marks=pytest.mark.slow),  # five, three on [0, Ts]: 3 x 10 x 3 of 243
    ("in-order-common", 0.25, 10, "in-order-common"),
])
def test_the_exact_lifted_map_is_inside_the_in_order_vertices(description: str, tau_max: float, count: int,
                                                              cover: str) -> None:
    """The model's coverage check (20 000 admissible sequences' exact matrices rebuilt from the vertices with
    explicit weights, the in-order corners of the instant ranges, every slip corner)."""
    model = build_model(_config(description, tau_max))
    assert (len(model.delay_combos), model.delay_cover) == (count, cover)
    assert len(model.vertices) == 4 * count  # per slip corner
    r = coverage_check(model)
    assert r["samples"] >= 20_000
    assert r["passed"], r


def test_the_product_is_still_there_for_comparison() -> None:
    model = build_model(_config("polytopic-product", 0.35))
    assert (len(model.delay_combos), model.delay_cover) == (81, "product")
