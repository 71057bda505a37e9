"""The network between controller and plant, and every delay / loss sequence the tool draws on it.

One model for every plant: the sampling period, the delay range [tau_min, tau_max] and the cap on
commands lost in a row.  A packet's delay is a number in that range, or ``inf`` when it is lost
(:func:`effective_delays` reads it so); :func:`s_tilde_sequence` turns delays into the switching
instants of each period, what the lifted maps take.  Every sequence a check, a margin
search or an adversary plays comes from here:

- :meth:`Network.uniform`, :meth:`Network.pattern`, :meth:`Network.lose`: the Monte Carlo draws and
  the fixed extremes (constant at either end, alternating), with bursty losses from a
  Gilbert-Elliott channel (:func:`gilbert_elliott`);
- :meth:`Network.families`: the named fixed families a linear plant's verification runs;
- :meth:`Network.periodic`, :meth:`Network.bursts`: the periodic sequences the instability searches
  (margins) enumerate;
- :meth:`Network.candidates`, :meth:`Network.loss_allowed`: what an adversary may pick each period.

Every sequence obeys the cap: at most ``max_lost`` lost in a row (around the period for periodic
ones), the one rule the conformance tests hold each generator to (tests/core/test_network.py).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Network", "gilbert_elliott", "with_losses", "longest_burst", "cap_runs", "max_cyclic_run", "effective_delays",
           "s_tilde_sequence"]

PATTERNS = ("constant-min", "constant-max", "alternating")


@dataclass(frozen=True)
class Network:
    """The link a command crosses: sampled every ``sampling_time`` [s], delayed by a time in
    [``delay_min``, ``delay_max``] [s], at most ``max_lost`` commands lost in a row (0: none lost)."""

    sampling_time: float
    delay_min: float
    delay_max: float
    max_lost: int = 0

    @classmethod
    def from_config(cls, config: Any) -> Network:
        """The ``network:`` section of any plant's config (or the section itself)."""
        net = getattr(config, "network", config)
        return cls(float(net.sampling_time), float(net.delay.min), float(net.delay.max),
                   int(net.dropouts.max_consecutive))

    # ---------------------------------------------------------------- delays
    def grid(self, n: int) -> np.ndarray:
        """``n`` delays evenly over [delay_min, delay_max]."""
        return np.linspace(self.delay_min, self.delay_max, n)

    def uniform(self, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
        """Independent delays, uniform on the range (``rng.uniform``: one draw per packet)."""
        return rng.uniform(self.delay_min, self.delay_max, size=shape)

    def pattern(self, kind: str, shape: tuple[int, int], period: int = 1, shifted: bool = True) -> np.ndarray:
        """A fixed extreme (runs, packets): ``constant-min``, ``constant-max``, or ``alternating``
        between the ends every ``period`` packets (with ``shifted``, run n starts n packets later, so
        that both phases are played)."""
        runs, n = shape
        if kind in ("constant-min", "constant-max"):
            return np.full(shape, self.delay_min if kind == "constant-min" else self.delay_max)
        if kind == "alternating":
            i = np.arange(n)[None, :] + (np.arange(runs)[:, None] if shifted else 0)
            return np.where((i // period) % 2 == 0, self.delay_min, self.delay_max) * np.ones((runs, 1))
        raise ValueError(f"unknown delay pattern {kind!r} (one of {', '.join(PATTERNS)})")

    # ---------------------------------------------------------------- losses
    def lose(self, taus: np.ndarray, rng: np.random.Generator, probability: float, mean_burst: float, *,
             capped: bool = True, arrived: int = 0) -> np.ndarray:
        """``taus`` with packets lost (``inf``) on a Gilbert-Elliott channel (long-run loss fraction
        ``probability``, bursts of mean length ``mean_burst``), bursts cut at ``max_lost`` (not cut
        with ``capped=False``: a channel beyond the cap); the first ``arrived`` packets of each row
        arrive.  A link without losses (``max_lost`` 0) returns ``taus`` unchanged and draws nothing."""
        if not self.max_lost:
            return taus
        lost = gilbert_elliott(rng, taus.shape, probability, mean_burst, self.max_lost if capped else None)
        lost[:, :arrived] = False
        return with_losses(taus, lost)

    def families(self, rng: np.random.Generator, runs: int, length: int, loss_fraction: float = 0.4
                 ) -> dict[str, np.ndarray]:
        """Named packet-delay families (runs, length): ``random`` (uniform), both constants, ``alternating``
        (one phase), ``random-ends`` (each packet at either end); on a lossy link also ``random-losses``
        (independent losses of probability ``loss_fraction``, runs cut at the cap) and ``longest-bursts``
        (``max_lost`` lost, one received at delay_max, repeated)."""
        lo, hi, m = self.delay_min, self.delay_max, self.max_lost
        # lo + (hi - lo) rng.random, not rng.uniform (:meth:`uniform`): the draws these families always made
        fam = {"random": lo + (hi - lo) * rng.random((runs, length)),
               "constant-min": self.pattern("constant-min", (runs, length)),
               "constant-max": self.pattern("constant-max", (runs, length)),
               "alternating": self.pattern("alternating", (runs, length), shifted=False),
               "random-ends": np.where(rng.random((runs, length)) < 0.5, lo, hi)}
        if m:
            lossy = lo + (hi - lo) * rng.random((runs, length))
            lost = cap_runs(rng.random((runs, length)) < loss_fraction, m)
            fam["random-losses"] = np.where(lost, np.inf, lossy)
            fam["longest-bursts"] = np.where(np.arange(length) % (m + 1) < m, np.inf, hi) * np.ones((runs, 1))
        return fam

    # ---------------------------------------------------------------- periodic sequences (margins)
    def periodic(self, grid: np.ndarray, p: int, canonical: bool = False) -> np.ndarray:
        """Every periodic sequence (n, p) of ``grid`` delays and, on a lossy link, lost packets with at
        most ``max_lost`` in a row around the period and at least one received, in the order of
        ``itertools.product``.  With ``canonical`` one per class of rotations (the smallest code): a
        rotated period is a cyclic shift of the same product, with the same spectrum."""
        alphabet = np.append(grid, np.inf) if self.max_lost else np.asarray(grid, dtype=float)
        idx = np.array(list(itertools.product(range(alphabet.size), repeat=p)), dtype=np.int64).reshape(-1, p)
        if canonical and p > 1:
            weights = alphabet.size ** np.arange(p - 1, -1, -1, dtype=np.int64)
            code = idx @ weights
            idx = idx[np.all([code <= np.roll(idx, r, axis=1) @ weights for r in range(1, p)], axis=0)]
        seqs = alphabet[idx]
        if self.max_lost:
            lost = np.isinf(seqs)
            seqs = seqs[(max_cyclic_run(lost) <= self.max_lost) & ~np.all(lost, axis=1)]
        return seqs

    def bursts(self, grid: np.ndarray) -> list[np.ndarray]:
        """A burst of ``max_lost`` lost packets then one, or two, received on ``grid``: the periods a
        loss margin needs when the burst is longer than the periods enumerated."""
        if not self.max_lost:
            return []
        burst = np.full(self.max_lost, np.inf)
        one = np.array([np.append(burst, g) for g in grid])
        two = np.array([np.append(burst, [a, b]) for a in grid for b in grid])
        return [one, two]

    # ---------------------------------------------------------------- an adversary's choices
    def candidates(self, n: int) -> np.ndarray:
        """The newest packet's delays an adversary may pick: an ``n`` grid of the range, and ``inf``
        (lost) on a lossy link."""
        grid = self.grid(n)
        return np.append(grid, np.inf) if self.max_lost else grid

    def loss_allowed(self, hist: np.ndarray) -> np.ndarray:
        """(N,) whether the next packet may be lost after the delays ``hist`` (N, k): fewer than
        ``max_lost`` losses end it."""
        m = self.max_lost
        if not m:
            return np.zeros(hist.shape[0], dtype=bool)
        tail = hist[:, -m:] if hist.shape[1] >= m else hist
        return ~np.all(np.isinf(tail), axis=1) | (tail.shape[1] < m)


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


def cap_runs(lost: np.ndarray, cap: int) -> np.ndarray:
    """Loss flags (N, n) with every run cut after ``cap`` losses (the next packet is delivered, and
    the count starts again); a copy."""
    lost = np.array(lost, dtype=bool)
    run = np.zeros(lost.shape[0], dtype=int)
    for k in range(lost.shape[1]):
        run = np.where(lost[:, k], run + 1, 0)
        over = run > cap
        lost[over, k] = False
        run[over] = 0
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


def max_cyclic_run(lost: np.ndarray) -> np.ndarray:
    """Longest run of losses per row counted around the period (rows are periodic), at most the period."""
    lost = np.atleast_2d(lost)
    return np.minimum(longest_burst(np.concatenate([lost, lost], axis=1)), lost.shape[1])


def effective_delays(taus: np.ndarray, Ts: float) -> np.ndarray:
    """Lost packets (delay ``inf``) as delays: a lost command is superseded at the instant its
    successor arrives, so it takes the successor's arrival, ``tau_i = tau_{i+1} + Ts`` (chained
    through a burst), and acts for zero time.  Lost packets with no received successor in the
    array stay ``inf`` (they never act within it).  With at most m losses in a row the effective
    delay lies in [tau_min, tau_max + m Ts] (docs/theory.md, packet loss)."""
    taus = np.array(taus, dtype=float)
    lost = np.isinf(taus)
    if not lost.any():
        return taus
    for i in range(taus.shape[-1] - 2, -1, -1):
        taus[..., i] = np.where(lost[..., i], taus[..., i + 1] + Ts, taus[..., i])
    return taus


def s_tilde_sequence(taus: np.ndarray, Ts: float, d_hi: int) -> np.ndarray:
    """Switching instants ``s~[..., k, j]`` (j = 0..d_hi-1) from packet delays.

    ``taus[..., i]`` is the delay of the packet sent at ``t_{i - d_hi}``: the first ``d_hi`` entries
    are the packets sent before ``t_0``, so the result has ``taus.shape[-1] - d_hi`` steps.
    In-order delivery: ``s~_{j-1} = max(s_{j-1}, s~_j)``, ``s~_{d_hi} = 0``.  A lost packet has
    delay ``inf`` (see :func:`effective_delays`).
    """
    taus = effective_delays(taus, Ts)
    K = taus.shape[-1] - d_hi
    if K < 0:
        raise ValueError(f"need at least d_hi = {d_hi} delays of packets sent before t_0")
    s = np.zeros(taus.shape[:-1] + (K, d_hi + 1))
    for j in range(d_hi):
        # packet k - j is taus[..., k - j + d_hi]
        s[..., j] = np.clip(taus[..., d_hi - j : d_hi - j + K] - j * Ts, 0.0, Ts)
    for j in range(d_hi - 1, -1, -1):
        s[..., j] = np.maximum(s[..., j], s[..., j + 1])
    return s[..., :d_hi]
