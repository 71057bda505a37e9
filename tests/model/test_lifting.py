"""The lifted one-step map (eq. 25) against an independent piecewise-exact integration of the
continuous error dynamics, with inputs delivered in order at their absolute arrival times."""

from __future__ import annotations

import numpy as np
import pytest

from robustsynth.model import build_model
from robustsynth.core.network import s_tilde_sequence
from robustsynth.core.lifting import delay_indices
from robustsynth.model.linearize import van_loan

from ..conftest import make_config

LIFT_TOL = 1e-9  # issue 2: lifted map vs. independent integration


def _integrate_reference(model, taus, dus, d, e0):
    """e(t_k) for k = 0..K by integrating e_dot = A e + B u(t) + B_D d exactly (Van Loan) between
    actuation events.  Packet i (sent at t_{i-d_hi}) arrives at max over packets <= i of t + tau."""
    Ts, d_hi = model.Ts, model.d_hi
    n_pk = taus.shape[0]
    send = (np.arange(n_pk) - d_hi) * Ts
    # in-order delivery of the packets that are not lost (delay inf): a packet is delivered at the
    # latest arrival among itself and the received packets sent before it; a lost one never arrives
    arrive = np.full(n_pk, np.inf)
    latest = -np.inf
    for i in range(n_pk):
        if np.isfinite(taus[i]):
            latest = max(latest, send[i] + taus[i])
            arrive[i] = latest
    K = n_pk - d_hi
    A, B, BD = np.asarray(model.A_c), np.asarray(model.B_c), np.asarray(model.B_D_c)
    Bfull = np.hstack([B, BD])
    e = e0.copy()
    out = [e.copy()]
    for k in range(K):
        t0, t1 = k * Ts, (k + 1) * Ts
        events = sorted({t0, t1, *[a for a in arrive if t0 < a < t1]})
        for a, b in zip(events[:-1], events[1:]):
            # newest packet arrived by time a (packets sent at or before a)
            arrived = np.nonzero(arrive <= a + 1e-15)[0]
            u = dus[arrived[-1]] if arrived.size else np.zeros(2)
            E, G = van_loan(A, Bfull, b - a)
            e = E @ e + G @ np.concatenate([u, d[k]])
        out.append(e.copy())
    return np.array(out)


def _lifted_run(model, taus, dus, d, e0):
    s = model.s_tilde(taus)  # (K, d_hi)
    A_ex, B_ex = model.exact(s)
    d_hi, n_e = model.d_hi, model.n_e
    xi = np.concatenate([e0] + [dus[d_hi - j] for j in range(1, d_hi + 1)])
    out = [xi[:n_e].copy()]
    for k in range(s.shape[0]):
        xi = A_ex[k] @ xi + B_ex[k] @ dus[k + d_hi] + model.B_d @ d[k]
        out.append(xi[:n_e].copy())
    return np.array(out)


CASES = {
    "paper (tau_max < Ts)": (0.01, 0.08),
    "tau_max = Ts": (0.0, 0.1),
    "two periods": (0.03, 0.17),
    "three periods": (0.0, 0.3),
    "d_lo >= 1": (0.12, 0.25),
    "d_lo = 2": (0.21, 0.29),
    "constant delay": (0.05, 0.05),
}


@pytest.mark.parametrize("tau", list(CASES.values()), ids=list(CASES))
def test_lifted_map_matches_integration(tau) -> None:
    cfg = make_config(**{"network.delay.min": tau[0], "network.delay.max": tau[1], "network.sampling_time": 0.1})
    model = build_model(cfg)
    rng = np.random.default_rng(7)
    for _ in range(5):
        K = 25
        taus = rng.uniform(tau[0], tau[1], size=K + model.d_hi)
        # sprinkle in the extremes
        taus[rng.random(taus.size) < 0.3] = tau[0]
        taus[rng.random(taus.size) < 0.3] = tau[1]
        dus = rng.normal(scale=0.3, size=(K + model.d_hi, 2))
        d = rng.uniform(-0.4, 0.0, size=(K, 2))
        e0 = rng.normal(scale=0.1, size=3)
        ref = _integrate_reference(model, taus, dus, d, e0)
        got = _lifted_run(model, taus, dus, d, e0)
        assert np.max(np.abs(ref - got)) <= LIFT_TOL


def test_paper_case_matches_eq_LTI_error2(default_config) -> None:
    """d_hi = 1: e+ = Phi e + Gamma(Ts - tau) du_k + [Gamma(Ts) - Gamma(Ts - tau)] du_{k-1} + Gamma_D d."""
    from robustsynth.model.linearize import Gamma

    m = build_model(default_config)
    tau = 0.043
    A, B = m.exact(np.array([tau]))
    Ac, Bc = np.asarray(m.A_c), np.asarray(m.B_c)
    assert np.allclose(B[:3], Gamma(Ac, Bc, m.Ts - tau), atol=1e-15)
    assert np.allclose(A[:3, 3:], Gamma(Ac, Bc, m.Ts) - Gamma(Ac, Bc, m.Ts - tau), atol=1e-15)
    assert np.allclose(A[3:], 0) and np.allclose(B[3:], np.eye(2))


@pytest.mark.parametrize(
    "tmin,tmax,Ts,expected",
    [(0.01, 0.08, 0.1, (0, 1)), (0.0, 0.1, 0.1, (0, 1)), (0.0, 0.2, 0.1, (0, 2)), (0.1, 0.3, 0.1, (1, 3)),
     (0.0, 0.0, 0.1, (0, 1)), (0.3, 0.3, 0.1, (3, 3)), (0.0, 0.25, 0.1, (0, 3))],
)
def test_delay_indices_are_robust_to_round_off(tmin, tmax, Ts, expected) -> None:
    assert delay_indices(tmin, tmax, Ts) == expected


def test_s_tilde_is_monotone_and_in_range() -> None:
    rng = np.random.default_rng(1)
    Ts, d_hi = 0.1, 3
    taus = rng.uniform(0.02, 0.27, size=(50, 40 + d_hi))
    s = s_tilde_sequence(taus, Ts, d_hi)
    assert np.all(np.diff(s, axis=-1) <= 0)
    assert np.all((s >= 0) & (s <= Ts))


LOSS_CASES = {  # (tau_min, tau_max, max_consecutive losses)
    "one lost, tau_max < Ts": (0.01, 0.08, 1),
    "bursts of 3": (0.01, 0.08, 3),
    "two periods of delay, bursts of 2": (0.03, 0.17, 2),
    "d_lo = 1, one lost": (0.12, 0.25, 1),
}


@pytest.mark.parametrize("case", list(LOSS_CASES.values()), ids=list(LOSS_CASES))
def test_lossy_link_matches_integration(case) -> None:
    """Random delays and bursty losses (at most m in a row): a lost command never acts, the actuator
    holds the last one received; the lifted model with the effective delays matches an integration
    that knows nothing of effective delays (its packets simply never arrive)."""
    from robustsynth.core.network import gilbert_elliott, longest_burst, with_losses

    tmin, tmax, m = case
    cfg = make_config(**{"network.delay.min": tmin, "network.delay.max": tmax, "network.dropouts.max_consecutive": m})
    model = build_model(cfg)
    assert model.d_hi == delay_indices(tmin, tmax + m * model.Ts, model.Ts)[1]
    rng = np.random.default_rng(11)
    bursts = []
    for _ in range(8):
        K = 40
        n = K + model.d_hi
        taus = rng.uniform(tmin, tmax, size=n)
        lost = gilbert_elliott(rng, (1, n), 0.4, 2.0, m)[0]
        lost[0] = False  # the lifted state starts with packet 0 in force (it holds no older command)
        bursts.append(int(longest_burst(lost)[0]))
        taus = with_losses(taus, lost)
        dus = rng.normal(scale=0.3, size=(n, 2))
        d = rng.uniform(-0.4, 0.0, size=(K, 2))
        e0 = rng.normal(scale=0.1, size=3)
        ref = _integrate_reference(model, taus, dus, d, e0)
        got = _lifted_run(model, taus, dus, d, e0)
        assert np.max(np.abs(ref - got)) <= LIFT_TOL
    assert max(bursts) == m  # the longest admissible burst was exercised


def test_loss_channel_statistics() -> None:
    """Gilbert-Elliott: long-run loss fraction and mean burst length as configured, bursts capped."""
    from robustsynth.core.network import gilbert_elliott, longest_burst

    STAT_TOL = 0.03  # relative, on 400 x 2000 packets
    rng = np.random.default_rng(0)
    lost = gilbert_elliott(rng, (400, 2000), 0.2, 3.0, None)
    assert lost.mean() == pytest.approx(0.2, rel=STAT_TOL)
    starts = lost[:, 1:] & ~lost[:, :-1]
    assert lost[:, 1:].sum() / starts.sum() == pytest.approx(3.0, rel=STAT_TOL)
    capped = gilbert_elliott(rng, (400, 2000), 0.2, 3.0, 2)
    assert longest_burst(capped).max() == 2
    assert not gilbert_elliott(rng, (5, 50), 0.5, 2.0, 0).any()
