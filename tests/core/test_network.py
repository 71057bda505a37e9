"""The one network model: every delay / loss sequence it draws stays in the delay range and obeys the
cap on commands lost in a row, each generator checked against a plain per-sequence reference."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustsynth.config import load_config
from robustsynth.core.network import Network, cap_runs, gilbert_elliott, longest_burst, max_cyclic_run

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
STAT_TOL = 0.02  # |observed - expected| of a loss fraction over 4e5 packets (its std is about 1e-3)


def _runs(row) -> int:
    """Longest run of True in a sequence (reference: a plain loop)."""
    best = cur = 0
    for x in row:
        cur = cur + 1 if x else 0
        best = max(best, cur)
    return best


def _cyclic_runs(row) -> int:
    """Longest run of True around a period (reference: every rotation as a string)."""
    if all(row):
        return len(row)
    return max(_runs(row[r:] + row[:r]) for r in range(len(row)))


def _in_range(taus: np.ndarray, net: Network) -> bool:
    fin = taus[np.isfinite(taus)]
    return bool(np.all(np.isinf(taus[~np.isfinite(taus)])) and np.all((fin >= net.delay_min) & (fin <= net.delay_max)))


def test_from_config_reads_the_network_of_either_plant() -> None:
    robot = load_config(None)
    net = Network.from_config(robot)
    assert (net.sampling_time, net.delay_min, net.delay_max, net.max_lost) == (
        robot.network.sampling_time, robot.network.delay.min, robot.network.delay.max,
        robot.network.dropouts.max_consecutive)
    assert Network.from_config(robot.network) == net
    linear = load_config(CONFIGS / "dc-motor.yaml")
    assert Network.from_config(linear) == Network(linear.network.sampling_time, linear.network.delay.min,
                                                  linear.network.delay.max, linear.network.dropouts.max_consecutive)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 4), st.floats(0.05, 0.9), st.floats(1.0, 6.0), st.integers(0, 2**31 - 1))
def test_monte_carlo_losses_obey_the_cap_and_the_first_packets_arrive(m, prob, burst, seed) -> None:
    net = Network(0.1, 0.02, 0.17, m)
    rng = np.random.default_rng(seed)
    taus = net.lose(net.uniform(rng, (20, 40)), rng, prob, burst, arrived=3)
    assert _in_range(taus, net)
    lost = np.isinf(taus)
    assert not lost[:, :3].any()
    assert all(_runs(row) <= m for row in lost.tolist())
    if m == 0:
        assert not lost.any()


def test_the_channel_loses_its_stated_fraction_in_bursts_of_its_stated_mean() -> None:
    rng = np.random.default_rng(0)
    lost = gilbert_elliott(rng, (400, 1000), 0.2, 3.0, None)
    assert abs(lost.mean() - 0.2) < STAT_TOL
    flat = np.concatenate([np.append(row, False) for row in lost])  # bursts end at each row's end
    starts = np.count_nonzero(flat[1:] & ~flat[:-1]) + np.count_nonzero(flat[0])
    assert abs(lost.sum() / starts - 3.0) < 3.0 * 5 * STAT_TOL  # mean burst length, uncapped


def test_uncapped_losses_may_exceed_the_cap() -> None:
    net = Network(0.1, 0.02, 0.17, 1)
    rng = np.random.default_rng(1)
    taus = net.lose(net.uniform(rng, (50, 200)), rng, 0.4, 4.0, capped=False)
    assert longest_burst(np.isinf(taus)).max() > 1  # the channel beyond the cap a check of it plays


@settings(max_examples=80, deadline=None)
@given(st.lists(st.lists(st.booleans(), min_size=1, max_size=12), min_size=1, max_size=6).filter(
    lambda rows: len({len(r) for r in rows}) == 1), st.integers(0, 4))
def test_cap_runs_against_a_per_row_reference(rows, cap) -> None:
    got = cap_runs(np.array(rows), cap)
    for row, out in zip(rows, got.tolist()):
        ref, run = [], 0
        for x in row:
            run = run + 1 if x else 0
            if run > cap:
                x, run = False, 0
            ref.append(x)
        assert out == ref
        assert _runs(out) <= cap
    assert longest_burst(np.array(rows)).tolist() == [_runs(r) for r in rows]
    assert max_cyclic_run(np.array(rows)).tolist() == [_cyclic_runs(r) for r in rows]


@pytest.mark.parametrize("m", [0, 1, 2, 3])
@pytest.mark.parametrize("p", [1, 2, 3, 4])
def test_periodic_sequences_are_exactly_the_admissible_ones(m, p) -> None:
    net = Network(0.1, 0.02, 0.17, m)
    grid = net.grid(3)
    got = net.periodic(grid, p)
    alphabet = list(grid) + ([np.inf] if m else [])
    ref = [s for s in itertools.product(alphabet, repeat=p)
           if not m or (_cyclic_runs([np.isinf(x) for x in s]) <= m and not all(np.isinf(s)))]
    assert got.tolist() == [list(s) for s in ref]  # the same sequences, in itertools.product's order


@pytest.mark.parametrize("m", [0, 2])
@pytest.mark.parametrize("p", [2, 3, 4])
def test_canonical_periodic_sequences_are_one_per_class_of_rotations(m, p) -> None:
    net = Network(0.1, 0.02, 0.17, m)
    grid = net.grid(3)
    every, canon = net.periodic(grid, p), net.periodic(grid, p, canonical=True)

    def cls(s):
        return min(tuple(np.roll(s, r).tolist()) for r in range(p))

    classes = [cls(s) for s in canon]
    assert len(set(classes)) == len(classes)  # no two rotations of one sequence
    assert set(classes) == {cls(s) for s in every}  # and every sequence's rotation class is there


def test_bursts_are_the_cap_then_one_or_two_received() -> None:
    net = Network(0.1, 0.02, 0.17, 5)
    one, two = net.bursts(net.grid(3))
    assert one.shape == (3, 6) and two.shape == (9, 7)
    for fam in (one, two):
        lost = np.isinf(fam)
        assert lost[:, :5].all() and not lost[:, 5:].any()
        assert (max_cyclic_run(lost) == 5).all()
    assert Network(0.1, 0.02, 0.17, 0).bursts(net.grid(3)) == []


@pytest.mark.parametrize("m", [0, 2])
def test_the_named_families_stay_in_range_and_obey_the_cap(m) -> None:
    net = Network(0.1, 0.02, 0.17, m)
    fam = net.families(np.random.default_rng(3), 16, 50)
    assert set(fam) == {"random", "constant-min", "constant-max", "alternating", "random-ends"} | (
        {"random-losses", "longest-bursts"} if m else set())
    for name, taus in fam.items():
        assert taus.shape == (16, 50), name
        assert _in_range(taus, net), name
        assert all(_runs(r) <= m for r in np.isinf(taus).tolist()), name
    if m:
        assert longest_burst(np.isinf(fam["longest-bursts"])).min() == m
        assert np.isinf(fam["random-losses"]).any()


def test_patterns_and_the_alternating_phases() -> None:
    net = Network(0.1, 0.02, 0.17)
    alt = net.pattern("alternating", (2, 6))
    assert alt[0].tolist() == [0.02, 0.17] * 3 and alt[1].tolist() == [0.17, 0.02] * 3  # both phases
    assert (net.pattern("alternating", (2, 6), shifted=False)[1] == alt[0]).all()
    assert net.pattern("alternating", (1, 6), period=3)[0].tolist() == [0.02] * 3 + [0.17] * 3
    assert (net.pattern("constant-max", (2, 3)) == 0.17).all()
    with pytest.raises(ValueError, match="unknown delay pattern"):
        net.pattern("sawtooth", (1, 3))


@pytest.mark.parametrize("m", [0, 1, 3])
def test_an_adversary_may_lose_a_packet_only_below_the_cap(m) -> None:
    net = Network(0.1, 0.02, 0.17, m)
    cand = net.candidates(4)
    assert cand.size == 4 + (1 if m else 0) and _in_range(cand[None], net)
    hists = np.array([seq for seq in itertools.product([0.05, np.inf], repeat=4)])
    allowed = net.loss_allowed(hists)
    for h, ok in zip(hists.tolist(), allowed.tolist()):
        tail = 0
        for x in reversed(h):
            if not np.isinf(x):
                break
            tail += 1
        assert ok == (m > 0 and tail < m)
