"""What the world may do to the loop: the slip, delay and loss sequences the checks draw, and the
starts of their runs.

Used by both judges of a gain: the lifted linear model (:mod:`robustsynth.verification.lifted`) and
the robot in closed loop (:mod:`robustsynth.robot_verification.simulate`).  A :class:`Scenario` is
everything random about N runs, drawn up front, so that any implementation can replay it;
:func:`slip_profiles` and :func:`random_delays` are the random sequences (the delays and losses from
the one network model, :class:`robustsynth.core.network.Network`, on the config's loss channel);
:func:`slip_candidates` is the slip an adversary may pick each period (its delays:
``model.network.candidates`` and ``loss_allowed``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .model.slip import slip_changes
from .plants.path import PathGeometry, pose_from_error

__all__ = [
    "Scenario",
    "SLIP_PROFILES",
    "slip_profiles",
    "draw_scenario",
    "steady_state_start",
    "split_state",
    "random_delays",
    "slip_vertices",
    "slip_candidates",
    "rate_limited_slip",
    "track_changes",
]

SLIP_PROFILES = ("constant", "random-walk", "steps", "corners")


@dataclass(frozen=True)
class Scenario:
    """Everything random about N runs, drawn up front (so any implementation can replay it)."""

    taus: np.ndarray  # (N, steps + d_hi): delay of the packet sent at t_{i - d_hi}
    mu: np.ndarray  # (N, steps, 2): (mu_r, mu_l) on [t_k, t_k+1) (from t_k + mu_switch[k] on, with mu_switch)
    noise: np.ndarray  # (N, steps, 3): measurement noise on (x, y, theta)
    q0: np.ndarray  # (N, 3): initial pose
    profiles: tuple[str, ...]  # slip profile of each run
    du0: np.ndarray | None = None  # (N, d_hi, 2): stored commands du_{-1}, ..., du_{-d_hi} (None: zero)
    z0: np.ndarray | None = None  # (N, 2): integrator states at t_0 (None: zero)
    # (N, steps, 2): within period k >= 1 track i's slip is mu[k-1, i] until t_k + mu_switch[k, i] and
    # mu[k, i] after it (each track changes at its own time); None: slip changes at the instants only
    mu_switch: np.ndarray | None = None

    @property
    def runs(self) -> int:
        return self.taus.shape[0]

    @property
    def steps(self) -> int:
        return self.mu.shape[1]

    def slip_in_period(self, k: int) -> tuple[np.ndarray, list | None]:
        """The slip of every run at the start of period k (N, n_p) and its changes within the period,
        ``[(t1, mu_1), (t2, mu_2)]`` in time order (t (N,) after t_k: the earlier and the later of the
        two tracks' times, mu_1 with only the earlier track changed), or None (constant over it)."""
        if self.mu_switch is None or k == 0:
            return self.mu[:, k], None
        return self.mu[:, k - 1], track_changes(self.mu[:, k - 1], self.mu[:, k], self.mu_switch[:, k])


def track_changes(before: np.ndarray, after: np.ndarray, t: np.ndarray) -> list:
    """Each track's slip going from ``before`` to ``after`` (..., n_p) at its own time ``t`` (..., 2) within
    a period, as the robot's list of changes in time order (:func:`~.model.slip.slip_changes`)."""
    return slip_changes(before, after, t)


def _rate_limit(target: np.ndarray, start: np.ndarray, max_step: float | None) -> np.ndarray:
    """Follow ``target`` (N, steps, 2) from ``start`` (N, 2) with |mu_{k+1} - mu_k| <= max_step."""
    if max_step is None:
        return target
    out = np.empty_like(target)
    cur = start.copy()
    for k in range(target.shape[1]):
        cur = cur + np.clip(target[:, k] - cur, -max_step, max_step)
        out[:, k] = cur
    return out


def slip_profiles(rng: np.random.Generator, kinds: list[str], steps: int, lo: np.ndarray, hi: np.ndarray, Ts: float,
                   max_rate: float | None = None):
    """Slip (N, steps, n_p) per profile: constant; random walk (std 5 % of the range per sqrt(s),
    reflected at the bounds); steps (a new random level every ~3 s); corners (a random corner of
    the box held 1-5 periods).  With ``max_rate`` every profile moves at most max_rate * Ts per
    period (steps and corners become ramps at the largest rate)."""
    N = len(kinds)
    P = np.asarray(lo).size  # slip parameters: 2 (tracks) or 4 (icr; the rate bound is the tracks')
    mu = np.empty((N, steps, P))
    kinds_arr = np.array(kinds)
    width = hi - lo
    max_step = None if max_rate is None else (max_rate * Ts if P == 2 else
                                               np.array([max_rate * Ts] * 2 + [np.inf] * (P - 2)))
    # constant
    start = lo + width * rng.random((N, P))
    mu[:] = start[:, None, :]
    # random walk: std 5% of the range per sqrt(s), reflected at the bounds
    scale = 0.05 * math.sqrt(Ts) * width
    inc = rng.normal(size=(N, steps, P)) * scale
    if max_step is not None:
        inc = np.clip(inc, -max_step, max_step)
    walk = start[:, None, :] + np.cumsum(inc, axis=1)
    span = np.where(width > 0, width, 1.0)
    x = np.mod(walk - lo, 2 * span)
    walk = lo + np.where(x > span, 2 * span - x, x)
    walk = np.where(width > 0, walk, lo)
    sel = kinds_arr == "random-walk"
    mu[sel] = walk[sel]
    # steps: a new random level every ~3 s (geometric holding times)
    p = min(1.0, Ts / 3.0)
    jumps = rng.random((N, steps)) < p
    jumps[:, 0] = True
    levels = lo + width * rng.random((N, steps, P))
    idx = np.maximum.accumulate(np.where(jumps, np.arange(steps)[None, :], 0), axis=1)
    stepped = np.take_along_axis(levels, idx[:, :, None].repeat(P, axis=2), axis=1)
    stepped[:, 0] = start
    sel = kinds_arr == "steps"
    mu[sel] = _rate_limit(stepped, start, max_step)[sel]
    # corners: a random corner held for 1-5 periods (the switching the certificate allows)
    hold = rng.integers(1, 6, size=(N, steps))
    switch = np.zeros((N, steps), dtype=bool)
    nxt = np.zeros(N, dtype=int)
    for k in range(steps):
        on = nxt == k
        switch[on, k] = True
        nxt[on] = k + hold[on, k]
    pick = rng.integers(0, 2, size=(N, steps, P))
    corner = np.where(pick == 0, lo, hi)
    idx = np.maximum.accumulate(np.where(switch, np.arange(steps)[None, :], 0), axis=1)
    cornered = np.take_along_axis(corner, idx[:, :, None].repeat(P, axis=2), axis=1)
    sel = kinds_arr == "corners"
    c0 = cornered[:, 0].copy()
    mu[sel] = _rate_limit(cornered, c0, max_step)[sel]
    start = np.where((kinds_arr == "corners")[:, None], c0, start)
    return mu


def draw_scenario(model, runs: int, seed: int, steps: int, path: PathGeometry, delays: str = "random",
                  slip: str | None = None, losses: bool | str = True, within_period: bool = False) -> Scenario:
    """Seeded random scenario. ``delays``: 'random' (uniform iid), 'alternating' (min/max),
    'constant-min', 'constant-max'.  ``slip``: a profile for every run, or None to cycle through
    SLIP_PROFILES; 'none' for mu = 1.  With ``network.dropouts.max_consecutive`` > 0 commands are lost
    on the configured Gilbert-Elliott channel (``verification.dropouts``; delay ``inf``), bursts cut
    at the cap (``losses='uncapped'``: not cut; False: no losses).  Runs start at the pose of the config's initial offset with no
    stored commands; :func:`steady_state_start` moves them to the steady state of their first slip.
    ``within_period`` (tracks model): each period's change of each track's slip happens at a uniform
    random time within the period (in every other run both tracks at one time, in the others each at
    its own) instead of at the sampling instant
    (``Scenario.mu_switch``, from a stream of its own: the other draws are unchanged); with
    ``slip.max_rate`` at one random time per run and track, the same in every period, so that the
    changes stay a period apart and each within the rate bound."""
    cfg = model.config
    vc = cfg.verification
    rng = np.random.default_rng(seed)
    net = model.network
    n_pk = steps + model.d_hi
    taus = net.uniform(rng, (runs, n_pk)) if delays == "random" else net.pattern(delays, (runs, n_pk))
    if losses:  # bursty losses from their own stream: the other draws do not depend on them
        # commands sent before t_0 arrived (the run starts in their steady state)
        taus = net.lose(taus, np.random.default_rng([seed, 1]), vc.dropouts.probability, vc.dropouts.mean_burst,
                        capped=losses != "uncapped", arrived=model.d_hi)
    lo = np.array([r[0] for r in model.slip_ranges])
    hi = np.array([r[1] for r in model.slip_ranges])
    if slip == "none":
        kinds = ["none"] * runs
        mu = np.tile(model.nominal_slip, (runs, steps, 1))
    else:
        kinds = [slip] * runs if slip else [SLIP_PROFILES[n % len(SLIP_PROFILES)] for n in range(runs)]
        mu = slip_profiles(rng, kinds, steps, lo, hi, model.Ts, cfg.slip.max_rate)
    sd = np.array([vc.noise.position, vc.noise.position, vc.noise.heading])
    noise = rng.normal(size=(runs, steps, 3)) * sd if np.any(sd > 0) else np.zeros((runs, steps, 3))
    off = vc.initial_offset
    e_off = np.array([off.x, off.y, off.theta])
    q0 = np.tile(pose_from_error(path, e_off), (runs, 1))
    mu_switch = None
    if within_period and slip != "none":
        draw = np.random.default_rng([seed, 2]).uniform(0.0, model.Ts, size=(runs, steps, 2))
        draw[::2, :, 1] = draw[::2, :, 0]  # every other run: both tracks at one time (a corner jump)
        mu_switch = draw if model.slip_step is None else np.repeat(draw[:, :1], steps, axis=1)
        mu_switch[:, 0] = 0.0
    return Scenario(taus, mu, noise, q0, tuple(kinds), mu_switch=mu_switch)


def steady_state_start(model, K: np.ndarray, path: PathGeometry, scen: Scenario) -> Scenario:
    """The same scenario started at the steady state xi*(mu_0) of each run's first slip (plus the
    config's initial offset): error e*, stored commands du* and integrators z* of the robot's
    slip-aware lifted closed loop under that constant slip.  A gain without a steady state (e.g.
    K = 0) leaves the scenario as it was."""
    try:
        xi = model.equilibrium(K, scen.mu[:, 0])  # (N, n_s)
    except np.linalg.LinAlgError:
        return scen  # no steady state for this gain (I - A - B K singular): runs start on the path
    if not np.all(np.isfinite(xi)):
        return scen
    off = model.config.verification.initial_offset
    e, du0, z0 = split_state(model, xi)
    return replace(scen, q0=pose_from_error(path, e + np.array([off.x, off.y, off.theta])), du0=du0, z0=z0)


def split_state(model, xi: np.ndarray):
    """(e, stored commands (N, d_hi, 2), integrators or None) of lifted states xi (N, n_s)."""
    n_e, n_u = model.n_e, model.n_u
    du = xi[:, n_e : n_e + model.d_hi * n_u].reshape(-1, model.d_hi, n_u)
    return xi[:, :n_e], du, (xi[:, model.n_s - model.n_z :] if model.n_z else None)


def random_delays(model, rng: np.random.Generator, N: int, steps: int) -> np.ndarray:
    """Uniform iid delays; with ``network.dropouts`` also bursts of lost packets (``inf``) from the
    configured channel, capped at ``max_consecutive``."""
    net, ch = model.network, model.config.verification.dropouts
    return net.lose(net.uniform(rng, (N, steps + model.d_hi)), rng, ch.probability, ch.mean_burst, arrived=model.d_hi)


def slip_vertices(model) -> np.ndarray:
    """The corners (mu_r, mu_l) of the slip box, shape (n_c, 2)."""
    return np.asarray(model.corners)


def slip_candidates(model, mu_prev: np.ndarray) -> np.ndarray:
    """Slips (N, n_c, n_p) an adversary may pick next: the corners, or with ``slip.max_rate`` the
    largest admissible moves towards them (the rate bounds the tracks' factors; the icr model's yaw
    factor and x_icr may jump to any corner)."""
    corners = slip_vertices(model)
    step = model.slip_step
    if step is None:
        return np.broadcast_to(corners, mu_prev.shape[:-1] + corners.shape)
    if corners.shape[-1] > 2:
        step = np.array([step, step] + [np.inf] * (corners.shape[-1] - 2))
    return mu_prev[..., None, :] + np.clip(corners - mu_prev[..., None, :], -step, step)


def rate_limited_slip(model, rng: np.random.Generator, N: int, steps: int) -> np.ndarray:
    """Slip sequences (N, steps, 2): random corners held 1-5 periods, approached at the largest rate
    ``slip.max_rate`` allows (jumps when there is no rate bound): the simulator's 'corners' profile."""
    lo = np.array([r[0] for r in model.slip_ranges])
    hi = np.array([r[1] for r in model.slip_ranges])
    return slip_profiles(rng, ["corners"] * N, steps, lo, hi, model.Ts, model.config.slip.max_rate)
