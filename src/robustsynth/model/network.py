"""Packet loss on the command link: a Gilbert-Elliott (bursty) channel and the encoding of a lost
command as an infinite delay (see :func:`robustsynth.model.lifting.effective_delays`)."""

from __future__ import annotations

import numpy as np

__all__ = ["gilbert_elliott", "with_losses", "longest_burst"]


def gilbert_elliott(rng: np.random.Generator, shape: tuple[int, int], probability: float, mean_burst: float,
                    cap: int | None) -> np.ndarray:
    """Loss flags (N, n) of a two-state channel: 'good' delivers, 'bad' loses.  Leaving 'bad' has
    probability 1/mean_burst (bursts are geometric with that mean); entering it is set so that the
    long-run loss fraction is ``probability``.  With ``cap`` a burst is cut after ``cap`` losses
    (the next packet is delivered): the model's ``max_consecutive``; ``cap=0`` loses nothing."""
    N, n = shape
    lost = np.zeros((N, n), dtype=bool)
    if probability <= 0.0 or cap == 0 or n == 0:
        return lost
    p_bg = 1.0 / mean_burst
    p_gb = min(1.0, probability * p_bg / max(1.0 - probability, 1e-12))
    bad = rng.random(N) < probability  # start in the stationary distribution
    run = np.zeros(N, dtype=int)
    u = rng.random((N, n))
    for i in range(n):
        if cap is not None:
            bad &= run < cap
        lost[:, i] = bad
        run = np.where(bad, run + 1, 0)
        bad = np.where(bad, u[:, i] >= p_bg, u[:, i] < p_gb)
    return lost


def with_losses(taus: np.ndarray, lost: np.ndarray) -> np.ndarray:
    """Delays with lost packets marked as ``inf``."""
    return np.where(lost, np.inf, np.asarray(taus, dtype=float))


def longest_burst(lost: np.ndarray) -> np.ndarray:
    """Longest run of consecutive losses per row."""
    lost = np.atleast_2d(lost)
    best = np.zeros(lost.shape[0], dtype=int)
    run = np.zeros(lost.shape[0], dtype=int)
    for i in range(lost.shape[1]):
        run = np.where(lost[:, i], run + 1, 0)
        best = np.maximum(best, run)
    return best
