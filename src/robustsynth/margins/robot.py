"""The tracked robot's margins of a given gain: how far can the delay bound and the slip range be pushed?

For each margin two numbers bracket the truth:

- **certified**: the furthest value at which the gain has a robust-stability certificate (the
  analysis LMIs of :mod:`robustsynth.synthesis.analysis`, K fixed, every accepted point re-checked in
  numpy), found by bisection;
- **exhibited**: the nearest value at which an instability is *shown*: a periodic delay/slip
  sequence whose lifted closed-loop product has spectral radius above 1 (constant delays and slips
  are the period-1 case).  The sequence is returned as the witness.

The truth lies between them; the gap is how conservative the certificate is (or how weak the
search).  The analysis is always done on the slip-aware model (slip multiplies the command, as on
the robot), whatever model the gain was designed on.
"""

from __future__ import annotations

import itertools
import math
import time
from typing import Any, Callable

import numpy as np

from ..config import Config, config_with
from ..core.network import max_cyclic_run
from ..errors import InputError, check_interrupt
from ..model import gain_lifting, pad_gain
from ..results import Margin, MarginReport
from .common import bisect, first_bad

__all__ = ["robot_margin", "find_instability", "witness_delays", "EXHIBIT_TOL"]

EXHIBIT_TOL = 1e-6  # a period product with spectral radius^(1/p) > 1 + this is an exhibited instability
SLIP_FLOOR = 0.05  # smallest slip coefficient searched (M(mu) is singular at 0)
SLIP_TOL = 0.005  # bisection tolerance on mu_min
DELAY_TOL_PERIODS = 0.01  # bisection tolerance on tau_max, in sampling periods
SEARCH_DELAYS = 5  # delay values per period in the switching search (tau_min .. tau_max)
SEARCH_PERIOD = 3  # longest period of the switching sequences searched
# what the robot's certified and exhibited margins are (margin.md)
READING = ("Certified: a robust-stability certificate of the lifted slip-aware model (the robot's linearization; the "
           "analysis LMIs with K fixed), proven in numpy. Exhibited: a destabilizing periodic delay/loss/slip sequence "
           "of the lifted closed loop.")
MAX_SLIP_SEQUENCES = 64  # switching slip sequences per period length at most, else held (the tracks model: 4^3)
ICR_STEP = 0.05  # grid step of the icr parameters' instability walk (yaw factor; x_icr in m)
ICR_TOL = 0.005  # bisection tolerance of the icr parameters' margins
DROPOUT_SEARCH = 6  # the loss margin is searched up to this many losses beyond the configured cap


# ------------------------------------------------------------------------ exhibited instability


def find_instability(model: Any, K: np.ndarray, n_delays: int = SEARCH_DELAYS, max_period: int = SEARCH_PERIOD,
                     tol: float = EXHIBIT_TOL) -> dict[str, Any] | None:
    """Search periodic delay/slip sequences of the lifted closed loop (model's exact map) for one
    whose period product has spectral radius^(1/p) > 1 + tol.  Delays on an ``n_delays`` grid of
    [tau_min, tau_max] and, on a lossy link, lost packets (at most ``network.dropouts.max_consecutive``
    in a row; bursts of that length are searched even when longer than ``max_period``); slips at the
    corners (held constant when ``slip.max_rate`` forbids jumps).  Returns the worst witness
    (``delays`` with null for a lost packet, ``lost``, ``slip``, ``period``, ``spectral_radius``) or None."""
    from ..verification.lifted import periodic_spectral_radius

    net = model.network
    grid = np.unique(net.grid(n_delays))
    corners = np.asarray(model.corners)
    m = net.max_lost
    best: dict[str, Any] | None = None
    families = [net.periodic(grid, p) for p in range(1, max_period + 1)]
    families += net.bursts(grid) if m >= SEARCH_PERIOD else []  # longer than the periods enumerated
    for dseq in families:
        check_interrupt()
        if dseq.size == 0:
            continue
        p = dseq.shape[1]
        if model.rate_bounded or p == 1 or p > max_period or len(corners) ** p > MAX_SLIP_SEQUENCES:
            sseq = np.repeat(corners[:, None, :], p, axis=1)  # (n_c, p, 2): slip held
        else:
            idx = np.array(list(itertools.product(range(len(corners)), repeat=p)))
            sseq = corners[idx]  # (n_c^p, p, 2)
        rho = periodic_spectral_radius(model, K, dseq, sseq)  # (n_seq, n_slipseq)
        i, j = np.unravel_index(int(np.argmax(rho)), rho.shape)
        r = float(rho[i, j])
        if r > 1.0 + tol and (best is None or r > best["spectral_radius"]):
            best = {"delays": [None if np.isinf(x) else float(x) for x in dseq[i]],
                    "lost": [bool(np.isinf(x)) for x in dseq[i]],
                    "slip": [[float(x) for x in c] for c in sseq[j]], "period": p, "spectral_radius": r}
        if best is not None and p == 1:
            break  # a frozen instability is the simplest witness
    return best


def witness_delays(witness: dict[str, Any]) -> np.ndarray:
    """A witness's delays as an array with ``inf`` for lost packets."""
    return np.array([np.inf if d is None else d for d in witness["delays"]], dtype=float)


# ------------------------------------------------------------------------------------ the search



class _Search:
    """One margin's evaluations of a gain on configs differing in one quantity."""

    def __init__(self, config: Config, K: np.ndarray, set_value: Callable[[float], dict[str, Any]],
                 lyapunov: str, say: Callable[[str], None]):
        self.config, self.K, self.set_value, self.lyapunov, self.say = config, K, set_value, lyapunov, say
        self.lifting = gain_lifting(K, config.synthesis.integral_action)
        self.evaluations: list[dict[str, Any]] = []

    def model(self, x: float):
        from ..model import build_model

        cfg = config_with(self.config, {"synthesis.model": "slip-aware", **self.set_value(x)})
        model = build_model(cfg, min_lifting=self.lifting)
        return model, pad_gain(self.K, model)

    def certified(self, x: float) -> bool:
        from ..synthesis.analysis import analyze_stability

        check_interrupt()
        model, K = self.model(x)
        s = self.config.synthesis
        res = analyze_stability(model, K, lyapunov=self.lyapunov, multiplier=s.multiplier, margin=s.margin,
                                solver=s.solver)
        self.evaluations.append({"value": x, "test": "certificate", "result": res.status, "lyapunov": res.lyapunov,
                                 "time_s": round(res.solve_time_s, 3)})
        self.say(f"  {x:.5g}: certificate {res.status}" + (f" ({res.lyapunov})" if res.lyapunov else ""))
        return res.certified

    def unstable(self, x: float) -> dict[str, Any] | None:
        check_interrupt()
        model, K = self.model(x)
        w = find_instability(model, K)
        self.evaluations.append({"value": x, "test": "instability search", "result": "found" if w else "none"})
        return w


def _delay_margin(config: Config, K: np.ndarray, lyapunov: str, say: Callable[[str], None]) -> Margin:
    dl, Ts = config.network.delay, config.network.sampling_time
    from ..config import MAX_D_HI

    # the lifting holds tau_max + m Ts <= MAX_D_HI Ts (m lost commands in a row)
    top = (MAX_D_HI - config.network.dropouts.max_consecutive) * Ts
    search = _Search(config, K, lambda x: {"network.delay.max": float(x)}, lyapunov, say)
    tol = DELAY_TOL_PERIODS * Ts
    say("delay_max: instability search")
    # exhibited: scan tau_max up from tau_min in tenths of a period, then bisect the first bracket
    step = Ts / 10.0
    grid = np.arange(dl.min, top + 1e-12, step)
    witness = first_bad(search.unstable, grid, tol / 4)[1]
    exhibited = None
    if witness is not None:
        exhibited = float(np.max(witness_delays(witness)[~np.isinf(witness_delays(witness))]))  # admissible for tau_max >= this
    say("delay_max: certificate bisection")
    hi = exhibited if exhibited is not None else top
    certified: float | None
    if search.certified(dl.max):
        lo = dl.max
        if hi <= lo or search.certified(hi):
            certified = hi if hi > lo else lo
        else:
            certified = bisect(search.certified, lo, hi, tol)
    elif dl.max > dl.min and search.certified(dl.min):
        certified = bisect(search.certified, dl.min, dl.max, tol)
    else:
        certified = None
    note = ("certified: largest tau_max [s] with a robust-stability certificate (tau_min as configured); "
            "exhibited: smallest tau_max admitting the witness delay sequence")
    if exhibited is None:
        note += f"; no instability found for tau_max up to {top:g} s (the lifting's limit)"
    return Margin("delay_max", "s", "max", float(dl.max), certified, exhibited, witness, (float(dl.min), float(top)),
                  note, tuple(search.evaluations))


def _certified_end(search: "_Search", configured: float, far: float, start: float, tol: float,
                   beyond: Callable[[float, float], bool]) -> float | None:
    """The furthest value with a certificate, searched from the configured one towards ``far`` (the
    exhibited instability, or the search's end; ``beyond(a, b)``: a lies further out than b).  When the
    configured value has none, the bisection runs between the other end of the range (``start``) and
    it; None when neither has one."""
    if search.certified(configured):
        if not beyond(far, configured):
            return configured
        if search.certified(far):
            return far
        return bisect(search.certified, configured, far, tol)
    if beyond(configured, start) and search.certified(start):
        return bisect(search.certified, start, configured, tol)
    return None


def _slip_margin(config: Config, K: np.ndarray, lyapunov: str, say: Callable[[str], None]) -> Margin:
    sl = config.slip
    mu_hi = min(sl.right.max, sl.left.max)
    configured = min(sl.right.min, sl.left.min)
    search = _Search(config, K, lambda x: {"slip.right.min": float(x), "slip.left.min": float(x)}, lyapunov, say)
    say("slip_min: instability search")
    grid = np.arange(mu_hi, SLIP_FLOOR - 1e-12, -0.05)
    witness = first_bad(search.unstable, grid, SLIP_TOL / 4)[1]
    exhibited = None
    if witness is not None:
        exhibited = min(min(s[:2]) for s in witness["slip"])  # admissible for any mu_min <= this
    say("slip_min: certificate bisection")
    lo = exhibited if exhibited is not None else SLIP_FLOOR
    certified = _certified_end(search, configured, lo, mu_hi, SLIP_TOL, lambda a, b: a < b)
    note = ("certified: smallest mu_min (both tracks, mu_max as configured) with a robust-stability certificate; "
            "exhibited: largest mu_min admitting the witness slip sequence")
    if sl.right.min != sl.left.min:
        note += f"; the configured mins differ ({sl.right.min:g}, {sl.left.min:g}): configured = the smaller"
    if exhibited is None:
        note += f"; no instability found for mu_min down to {SLIP_FLOOR:g}"
    return Margin("slip_min", "", "min", float(configured), certified, exhibited, witness,
                  (float(SLIP_FLOOR), float(mu_hi)), note, tuple(search.evaluations))


def _icr_margin(config: Config, K: np.ndarray, lyapunov: str, say: Callable[[str], None], name: str) -> Margin:
    """The icr model's other slip parameters, one at a time, the rest as configured: ``yaw_min`` (how
    little of the commanded yaw rate the robot may get; slip.yaw.min lowered) and ``icr_offset_max``
    (how far ahead the ICR may sit; slip.icr_offset.max raised).  Certified: the furthest value with a
    robust-stability certificate; exhibited: the nearest at which periodic delay/slip sequences are
    unstable (the witness's own extreme parameter value)."""
    sl = config.slip
    if name == "yaw_min":
        key, index, direction, configured, start, end = "slip.yaw.min", 2, "min", sl.yaw.min, sl.yaw.max, ICR_STEP
    else:
        key, index, direction, configured, start, end = "slip.icr_offset.max", 3, "max", sl.icr_offset.max, \
            sl.icr_offset.min, 1.0
    search = _Search(config, K, lambda x: {key: float(x)}, lyapunov, say)
    say(f"{name}: instability search")
    step = -ICR_STEP if direction == "min" else ICR_STEP
    grid = np.arange(configured, end + step / 2 if direction == "max" else end - 1e-12, step)
    witness = first_bad(search.unstable, grid, ICR_TOL / 4)[1]
    exhibited = None
    if witness is not None:
        vals = [c[index] for c in witness["slip"]]
        exhibited = min(vals) if direction == "min" else max(vals)
    say(f"{name}: certificate bisection")
    far = exhibited if exhibited is not None else float(end)
    certified = _certified_end(search, configured, far, start, ICR_TOL,
                               (lambda a, b: a < b) if direction == "min" else (lambda a, b: a > b))
    what = "yaw factor's minimum" if name == "yaw_min" else "ICR offset's maximum [m]"
    note = (f"certified: the furthest {what} with a robust-stability certificate (the other parameters as "
            f"configured); exhibited: the witness slip sequence's own extreme value")
    if exhibited is None:
        note += f"; no instability found up to {end:g}"
    lo_hi = (float(min(configured, end)), float(max(configured, end)))
    return Margin(name, "m" if name == "icr_offset_max" else "", direction, float(configured), certified, exhibited,
                  witness, lo_hi, note, tuple(search.evaluations))


def _dropout_margin(config: Config, K: np.ndarray, lyapunov: str, say: Callable[[str], None]) -> Margin:
    """Largest certified number of consecutive lost commands, and the smallest at which periodic
    loss/delay/slip sequences exhibit an instability (both searched up to the lifting's limit)."""
    from ..config import MAX_D_HI

    Ts = config.network.sampling_time
    configured = config.network.dropouts.max_consecutive
    top = int(MAX_D_HI - math.ceil(config.network.delay.max / Ts - 1e-9))
    top = min(top, configured + DROPOUT_SEARCH)
    search = _Search(config, K, lambda x: {"network.dropouts.max_consecutive": int(round(x))}, lyapunov, say)
    say("dropouts: instability search")
    witness, exhibited = None, None
    for m in range(0, top + 1):
        w = search.unstable(float(m))
        if w is not None:
            witness = w
            lost = np.asarray(w["lost"], dtype=bool)
            exhibited = int(max_cyclic_run(lost[None, :])[0])  # admissible for any cap >= this
            break
    say("dropouts: certificates")
    certified: int | None = None
    hi = exhibited - 1 if exhibited is not None else top
    for m in range(0, hi + 1):  # upwards: each certificate covers every smaller cap
        if not search.certified(float(m)):
            break
        certified = m
    note = (f"certified: the largest max_consecutive with a robust-stability certificate (searched up to {hi}); "
            "exhibited: the longest burst in the witness (a periodic loss/delay/slip sequence)")
    if exhibited is None:
        note += f"; no instability found for bursts up to {top}"
    return Margin("dropouts", "packets", "max", float(configured), None if certified is None else float(certified),
                  None if exhibited is None else float(exhibited), witness, (0.0, float(top)), note,
                  tuple(search.evaluations))


def robot_margin(config: Config, K: np.ndarray, lyapunov: str | None, say: Callable[[str], None]) -> MarginReport:
    """The tracked robot's margins (:func:`robustsynth.margins.margin` on its config): delay_max, slip_min (and
    the icr model's yaw_min, icr_offset_max), dropouts."""
    lyapunov = lyapunov or config.synthesis.lyapunov
    if lyapunov not in ("common", "slip-dependent", "delay-dependent", "path-dependent", "auto"):
        raise InputError(f"lyapunov: must be common, slip-dependent, delay-dependent, path-dependent or auto "
                         f"(got {lyapunov!r})")
    K = np.asarray(K, dtype=float)
    gain_lifting(K, config.synthesis.integral_action)  # a gain of the wrong shape fails here, not mid-search
    t0 = time.perf_counter()
    d = _delay_margin(config, K, lyapunov, say)
    t1 = time.perf_counter()
    s = _slip_margin(config, K, lyapunov, say)
    t2 = time.perf_counter()
    drop = _dropout_margin(config, K, lyapunov, say)
    t3 = time.perf_counter()
    extra = tuple(_icr_margin(config, K, lyapunov, say, n) for n in ("yaw_min", "icr_offset_max")) \
        if config.slip.model == "icr" else ()
    t4 = time.perf_counter()
    # certified: robust stability of the lifted model, i.e. of the robot's linearization, whatever kinematics the
    # gain's own certificate has (synthesis.analysis); exhibited: the lifted model's instability
    meta = {"model": "slip-aware", "kinematics": "linearized", "lyapunov": lyapunov, "exhibit_tol": EXHIBIT_TOL,
            "reading": READING,
            "search": {"delays_per_period": SEARCH_DELAYS, "longest_period": SEARCH_PERIOD,
                       "slip": "corners, held constant" if config.slip.max_rate is not None else "corners, switching"},
            "time_s": {"delay_max": round(t1 - t0, 3), "slip_min": round(t2 - t1, 3), "dropouts": round(t3 - t2, 3),
                       **({"slip_parameters": round(t4 - t3, 3)} if extra else {}), "total": round(t4 - t0, 3)}}
    return MarginReport((d, s, *extra, drop), meta)
