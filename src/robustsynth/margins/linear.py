"""``robustsynth margin`` on a linear plant (``plant: kind: lti``, docs/theory.md §14): how far can the
delay bound and the loss cap be pushed for the configured gain?

- **certified**: the largest value at which :func:`robustsynth.synthesis.lti.analyze_lti` finds a
  common quadratic Lyapunov function for the guaranteed over-approximation, proven in numpy
  (bisection);
- **exhibited**: the smallest value at which a periodic delay/loss sequence of the exactly lifted
  closed loop has spectral radius^(1/p) > 1 + EXHIBIT_TOL: constant delays on a fine grid, then
  sequences of up to SEARCH_PERIOD packets on a coarser grid (with lost packets: inf) and, for the
  delay bound, the longer switching families SWITCH_FAMILIES (alternating pairs on a fine grid, mixed
  delays over 4 and 6 packets), bisected; the witness is the destabilizing sequence, re-checked on the
  exact periodic product (:func:`check_witness`).  The delay search runs until it finds an
  instability or reaches its cap, EXHIBIT_CAP sampling periods (the lifting's longest delay) or
  ``margin.delay_far`` when that is set, far beyond the configured delay; the result says how far.

A certified value is never above an exhibited one when both are right; the tests check it, and check
the exhibited figures against an independent computation.
"""

from __future__ import annotations

import time
from typing import Any, Callable

import numpy as np

from ..core.network import Network, max_cyclic_run
from ..errors import InputError, check_interrupt
from ..core.delays import lti_depth
from ..results import Margin, MarginReport
from .common import bisect, first_bad

__all__ = ["linear_margin", "lti_margins", "delay_margin", "loss_margin", "find_lti_instability", "spectral_radius", "check_witness", "SEARCH_DELAYS", "SEARCH_PERIOD",
           "SWITCH_FAMILIES", "EXHIBIT_CAP"]

SEARCH_DELAYS = 9  # grid points of [tau_min, tau_max] in the switching search
CONSTANT_DELAYS = 201  # grid points for constant (frozen) delays
SEARCH_PERIOD = 3  # longest periodic sequence searched
# the delay search's further switching sequences, (period, grid points of [tau_min, tau_max]): alternating
# pairs on a fine grid, and delays mixed over 4 and 6 packets (loss-free: the loss search keeps the above)
SWITCH_FAMILIES = ((2, 25), (4, 5), (6, 3))
EXHIBIT_TOL = 1e-9
EXHIBIT_CAP = 20  # sampling periods: the delay search's end without margin.delay_far (config.MAX_D_HI, the lifting's longest)
WITNESS_SAFETY = 1e3  # the witness check's rounding bound: this many times n_s eps times the product of the factors' norms
SCAN = 20  # steps of the outward scan before the bisection
PIECE_STAGES = (1, 2, 4)  # coarse-to-fine pieces of the certificate bisection (then margin.pieces)
MAX_VERTICES = 1024  # a certificate's vertex budget: fewer pieces per instant beyond it, not attempted with one piece beyond it
MAX_COEFFICIENTS = 2e7  # floats of the LMIs' coefficient tensor (vertices x P entries x block^2): ~160 MB
# the interior-point solver's work per iteration: vertices x (k (k + 1) / 2)^2, Clarabel's dense scaling block per
# PSD cone of a k x k block (k: block_size, n channels per distinct range of the instants).  Measured
# with shared channels, 1.4-3.4 s per 1e6 on this 2-core machine under load (the servo at d = 9 with 2 pieces,
# 548 vertices, 4.5e6: 12-20 s a solve, for +0.004 of certified / exhibited): one solve stays within seconds
MAX_SCALING = 2e6
MAX_LOSSES = 3  # the loss margin is searched up to this many losses in a row


def _one_blas_thread() -> Any:
    """BLAS on one thread while the searches run (threadpoolctl restores it after): they compute thousands of
    exponentials and products of matrices of size n + d m, where OpenBLAS's threads only contend (on this
    2-core machine, under load, ZBP's search took 21 s instead of 0.9 s).  The figures come out the same either
    way (the servo's certified and exhibited bounds to the last digit); only the time differs."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def spectral_radius(plant: dict, Ts: float, dseq: np.ndarray, m_lost: int = 0) -> np.ndarray:
    """rho(product over one period)^(1/p) of the exactly lifted closed loop for periodic packet
    delays ``dseq`` (n, p) (inf: lost), per row: the robot's instability search's radius
    (:func:`robustsynth.verification.lifted.periodic_spectral_radius`) on the plant as a
    :class:`~robustsynth.plants.linear.LinearPlant`, lifted as deep as the longest delay and the gain need."""
    from ..plants.linear import LinearPlant
    from ..verification.lifted import periodic_spectral_radius

    dseq = np.atleast_2d(np.asarray(dseq, dtype=float))
    finite = dseq[np.isfinite(dseq)]
    top = float(finite.max()) if finite.size else 0.0
    lin = LinearPlant(plant, Network(Ts, 0.0, top, m_lost))  # a link as long as the longest delay searched
    return periodic_spectral_radius(lin, lin.padded_gain(plant["K"]), dseq)[:, 0]


def find_lti_instability(plant: dict, Ts: float, tau_min: float, tau_max: float, m_lost: int = 0,
                         switching: bool = False) -> dict | None:
    """The worst destabilizing periodic sequence with delays in [tau_min, tau_max] and at most m_lost
    losses in a row, or None.  Periods up to SEARCH_PERIOD, and up to m_lost + 1 (a burst of m_lost
    and one received packet) on a coarser grid; with ``switching`` (and no losses) also the
    SWITCH_FAMILIES."""
    best = None
    net = Network(Ts, tau_min, tau_max, m_lost)
    families = [net.grid(CONSTANT_DELAYS)[:, None]]
    # one sequence per class of rotations (a rotated period has the same spectrum)
    families += [net.periodic(np.unique(net.grid(SEARCH_DELAYS)), p, canonical=True) for p in range(1, SEARCH_PERIOD + 1)]
    coarse = np.unique(net.grid(3))
    families += [net.periodic(coarse, p, canonical=True) for p in range(SEARCH_PERIOD + 1, m_lost + 2)]
    if switching and m_lost == 0:
        families += [net.periodic(np.unique(net.grid(g)), p, canonical=True) for p, g in SWITCH_FAMILIES]
    for dseq in families:
        check_interrupt()
        if dseq.size == 0:
            continue
        r = spectral_radius(plant, Ts, dseq, m_lost)
        i = int(np.argmax(r))
        if r[i] > 1.0 + EXHIBIT_TOL and (best is None or r[i] > best["spectral_radius"]):
            best = {"delays": [None if np.isinf(x) else float(x) for x in dseq[i]], "period": int(dseq.shape[1]),
                    "spectral_radius": float(r[i])}
        if best is not None and dseq.shape[1] == 1:
            break  # a frozen instability is the simplest witness
    return best


def check_witness(plant: dict, Ts: float, witness: dict, m_lost: int = 0) -> dict:
    """Re-check a witness on the exact lifted matrices, independently of the batched search: the periodic
    product of :func:`robustsynth.core.delays.exact_closed_loop` at the witness's own switching instants,
    its spectral radius^(1/p), and a first-order bound on that eigenvalue's rounding error, the
    eigenvalue's condition number times WITNESS_SAFETY n_s eps prod_k ||M_k||.  ``ok``: the radius,
    less that bound, exceeds 1 + EXHIBIT_TOL (the stated margin).  A first-order bound, not verified
    arithmetic."""
    from scipy.linalg import eig

    from ..core.network import s_tilde_sequence
    from ..core.delays import exact_closed_loop, pad_lti_gain

    A, B, K = plant["A"], plant["B"], plant["K"]
    n, m = B.shape
    dseq = np.array([np.inf if x is None else x for x in witness["delays"]], dtype=float)
    p = dseq.size
    finite = dseq[np.isfinite(dseq)]
    d = max(lti_depth(float(finite.max()) if finite.size else 0.0, m_lost, Ts), (K.shape[1] - n) // m)
    cols = np.arange(-d, p + m_lost + 1) % p  # the packets sent before the period, then the period's own
    s = s_tilde_sequence(dseq[None, cols], Ts, d)[0, :p]
    Ms = exact_closed_loop(A, B, pad_lti_gain(K, n, m, d), Ts, s)
    prod = np.eye(Ms.shape[-1])
    for Mk in Ms:  # the packets of one period in the order sent
        prod = Mk @ prod
    w, vl, vr = eig(prod, left=True, right=True)
    i = int(np.argmax(np.abs(w)))
    x, y = vr[:, i] / np.linalg.norm(vr[:, i]), vl[:, i] / np.linalg.norm(vl[:, i])
    cond = 1.0 / max(abs(np.vdot(y, x)), 1e-300)
    scale = float(np.prod([np.linalg.norm(Mk, 2) for Mk in Ms]))
    err = cond * WITNESS_SAFETY * prod.shape[0] * float(np.finfo(float).eps) * scale
    rho = float(abs(w[i]))
    lower = max(rho - err, 0.0) ** (1.0 / p)
    return {"spectral_radius": rho ** (1.0 / p), "lower_bound": float(lower), "rounding_bound": float(err),
            "margin": EXHIBIT_TOL, "ok": bool(lower > 1.0 + EXHIBIT_TOL)}


def _certify(plant: dict, Ts: float, tau_min: float, tau_max: float, m_lost: int, pieces: int) -> Any:
    """The certificate at delays [tau_min, tau_max] with m_lost losses in a row (:func:`lti_certificate`'s
    analysis)."""
    return lti_certificate(plant, Ts, tau_min, tau_max, m_lost, pieces)[0]


def block_size(n: int, m: int, d: int, tau_min: float, tau_hi: float, Ts: float) -> int:
    """The analysis LMIs' vertex block size, estimated before the over-approximation is built: the lifted state
    and n channels per distinct range of the instants (instants on equal ranges share theirs,
    :func:`robustsynth.core.delays.channel_groups`; an instant on a point has a rounding-level remainder, no
    channel, :func:`robustsynth.core.delays.kept_directions`, unless every remainder is at that level)."""
    from ..core.delays import piece_grid

    ranges = {(th.tobytes(), w.tobytes()) for th, w in zip(*piece_grid(tau_min, tau_hi, Ts, d, 1)) if np.any(w > 0)}
    return n + d * m + n * max(len(ranges), 1)


def budget_pieces(plant: dict, Ts: float, tau_min: float, tau_max: float, m_lost: int, pieces: int
                  ) -> tuple[int, int, int, int]:
    """(d_hi, the pieces per instant within the budget, their vertices, the budget): ``pieces`` reduced while
    the vertices (:func:`robustsynth.core.delays.vertex_count`) exceed MAX_VERTICES or what MAX_COEFFICIENTS
    or MAX_SCALING allow for blocks of :func:`block_size` (one piece is kept, vertices above the budget then
    say it is beyond it)."""
    from ..core.delays import vertex_count

    n, m = plant["B"].shape
    d = max(lti_depth(tau_max, m_lost, Ts), (plant["K"].shape[1] - n) // m)
    k = block_size(n, m, d, tau_min, tau_max + m_lost * Ts, Ts)
    n_p = (n + d * m) * (n + d * m + 1) // 2
    budget = min(MAX_VERTICES, int(MAX_COEFFICIENTS // (n_p * k * k)), int(MAX_SCALING // (k * (k + 1) // 2) ** 2))
    vertices = vertex_count(tau_min, tau_max + m_lost * Ts, Ts, d, pieces, budget)
    while pieces > 1 and vertices > budget:  # long delay ranges: fewer pieces per instant
        pieces -= 1
        vertices = vertex_count(tau_min, tau_max + m_lost * Ts, Ts, d, pieces, budget)
    return d, pieces, vertices, budget


def lti_certificate(plant: dict, Ts: float, tau_min: float, tau_max: float, m_lost: int, pieces: int
                    ) -> tuple[Any, np.ndarray, int]:
    """(the analysis of ``plant["K"]``'s certificate at delays [tau_min, tau_max] with m_lost losses in a
    row, K padded to the lifting, the pieces used): the pieces within the budget (:func:`budget_pieces`); a
    problem beyond it even with one piece is not attempted (certified False, status 'budget')."""
    from ..core.delays import over_approximation, pad_lti_gain
    from ..synthesis.lti import analyze_lti

    n, m = plant["B"].shape
    d, pieces, vertices, budget = budget_pieces(plant, Ts, tau_min, tau_max, m_lost, pieces)
    K = pad_lti_gain(plant["K"], n, m, d)
    if vertices > budget:
        return _NotAttempted(vertices), K, pieces
    try:
        pw = over_approximation(plant["A"], plant["B"], K, Ts, tau_min, tau_max + m_lost * Ts, d, pieces)
    except ValueError as exc:
        raise InputError(f"plant: {exc} (delays up to {tau_max + m_lost * Ts:g} s)") from None
    return analyze_lti(pw), K, pieces


class _NotAttempted:
    """A certificate beyond the vertex or memory budget: not attempted, so not certified."""

    certified = False
    status = "budget"

    def __init__(self, vertices: int) -> None:
        self.vertices = vertices


def _last_good(good: Callable[[float], bool], lo: float, hi: float, tol: float) -> float | None:
    """Largest value in [lo, hi] where ``good`` holds (bisection; ``good`` assumed monotone)."""
    if not good(lo):
        return None
    if good(hi):
        return hi
    return bisect(good, lo, hi, tol)


def _exhibited_delay(plant: dict, Ts: float, t_lo: float, far: float, m_lost: int, tol: float) -> tuple[float | None, Any]:
    """The smallest delay bound with a destabilizing sequence: the frozen delays on a fine grid of
    [t_lo, far] first (one batch), then the switching search
    below the first frozen instability.  A sequence counts only once :func:`check_witness` confirms it
    on the exact periodic product (its check is in the witness)."""
    grid = np.linspace(t_lo, far, 4 * CONSTANT_DELAYS)
    r = spectral_radius(plant, Ts, grid[:, None], m_lost) if m_lost == 0 else np.zeros(grid.size)
    unstable = np.flatnonzero(r > 1.0 + EXHIBIT_TOL)
    top = float(grid[unstable[0]]) if unstable.size else far

    def bad(x: float) -> dict | None:
        w = find_lti_instability(plant, Ts, t_lo, x, m_lost, switching=True)
        if w is None:
            return None
        check = check_witness(plant, Ts, w, m_lost)
        return dict(w, check=check) if check["ok"] else None

    return first_bad(bad, np.linspace(t_lo, top, SCAN + 1)[1:], tol, clean=t_lo)


def _gallop(good: Callable[[float], bool], lo: float, hi: float, step: float, tol: float) -> float:
    """From ``lo`` (known good) towards ``hi`` (known bad): steps that double while ``good`` holds,
    then a bisection of the last bracket to ``tol``; the largest value found good (lo if none)."""
    bad = hi
    while lo + step < bad and step > 0:
        x = lo + step
        if good(x):
            lo, step = x, 2.0 * step
        else:
            bad = x
            break
    return bisect(good, lo, bad, tol)


def _certified_delay(plant: dict, Ts: float, t_lo: float, top: float, m_lost: int, pieces: int, tol: float
                     ) -> tuple[float | None, int]:
    """The largest certified delay bound in [t_lo, top) (``top``: the exhibited bound, where no
    certificate can hold): a bisection with the coarsest pieces, then with finer and finer pieces
    (PIECE_STAGES, then ``pieces``) galloping up from the last proven value, first by twice what
    the previous refinement gained.  Every value returned is proven by its own certificate.
    Returns (value, solves)."""
    solves = 0
    seen: dict = {}

    def ok(x: float, N: int) -> bool:  # a stage whose pieces the budget cuts back solves what an earlier one did
        nonlocal solves
        key = (x, budget_pieces(plant, Ts, t_lo, x, m_lost, N)[1])
        if key not in seen:
            solves += 1
            seen[key] = bool(_certify(plant, Ts, t_lo, x, m_lost, N).certified)
        return seen[key]

    stages = [N for N in PIECE_STAGES if N < pieces] + [pieces]
    lo = _last_good(lambda x: ok(x, stages[0]), t_lo, top, tol)
    if lo is None:
        return None, solves
    gained = max(top - lo, tol) / 4.0
    for prev, N in zip(stages, stages[1:]):
        if budget_pieces(plant, Ts, t_lo, lo, m_lost, N)[1] <= budget_pieces(plant, Ts, t_lo, lo, m_lost, prev)[1]:
            continue  # the budget allows no finer pieces here: the stage would solve what the last one did
        before = lo
        lo = _gallop(lambda x, N=N: ok(x, N), lo, top, max(2.0 * gained, tol), tol)
        gained = max(lo - before, tol)
    return lo, solves


def delay_margin(network: Network, settings: Any, plant: dict, say: Callable[[str], None] = lambda s: None
                 ) -> dict[str, Any]:
    """The delay margin (delay.max) of the gain ``plant["K"]`` on ``network``: certified (bisection of the analysis
    LMIs, ``settings.pieces`` and ``settings.tolerance``) and exhibited (the instability search, up to
    ``settings.delay_far``), their ratio, the witness, how far it searched and the time.  The record that
    ``synthesize`` keeps in a linear plant's gains.json (``delay_margin``); :func:`linear_margin` reads the
    same record as a :class:`~robustsynth.margins.Margin`."""
    Ts, t_lo, t_hi, m0 = network.sampling_time, network.delay_min, network.delay_max, network.max_lost
    pieces, tol = settings.pieces, settings.tolerance
    from ..config import MAX_D_HI

    if settings.delay_far is not None and settings.delay_far <= t_hi:
        # the margin is how much more delay the gain takes: a search ending at or below the configured delay
        # reported "certified at least 0.1 s" against 0.5 s configured (review)
        raise InputError(f"margin.delay_far: {settings.delay_far:g} s does not reach beyond network.delay.max = "
                         f"{t_hi:g} s, where the margin search starts to matter; raise it or leave it out (default "
                         f"{max(t_lo + 4 * Ts, t_hi + Ts):g} s)")
    given = settings.delay_far
    # the certificate's bisection ends at the exhibited bound, else where it always did (delay_far, else
    # max(tau_min + 4 Ts, tau_max + Ts)); the instability search goes on to delay_far, else EXHIBIT_CAP periods
    far = given if given is not None else max(t_lo + 4 * Ts, t_hi + Ts)
    capped = far > MAX_D_HI * Ts
    far = min(far, MAX_D_HI * Ts)  # the lifting's longest delay
    ex_far = given if given is not None else min(EXHIBIT_CAP, MAX_D_HI) * Ts
    ex_far = max(min(ex_far, MAX_D_HI * Ts), far)
    t0 = time.perf_counter()
    say(f"delay_max: instability search up to {ex_far:.6g} s")
    with _one_blas_thread():
        ex, witness = _exhibited_delay(plant, Ts, t_lo, ex_far, m0, tol)
    t1 = time.perf_counter()
    say("delay_max: certificate bisection")
    cert_top = ex if ex is not None else far
    with _one_blas_thread():  # the LMIs' coefficients and their numpy proof: small matrices too
        cert, solves = _certified_delay(plant, Ts, t_lo, cert_top, m0, pieces, tol)
    ratio = cert / ex if cert is not None and ex else None
    families = (f"constant delays and periodic switching sequences of up to "
                f"{max(p for p, _ in SWITCH_FAMILIES) if m0 == 0 else max(SEARCH_PERIOD, m0 + 1)} packets"
                + (f", up to {m0} lost in a row" if m0 else ""))
    out: dict[str, Any] = {"configured": t_hi, "certified": cert, "exhibited": ex, "witness": witness, "unit": "s",
                           "ratio": ratio, "searched_up_to": round(ex_far, 12),
                           "searched_periods": round(ex_far / Ts, 9), "searched": families,
                           "certificate_searched_up_to": round(cert_top, 12), "search_s": round(t1 - t0, 3),
                           "certificate_s": round(time.perf_counter() - t1, 3), "solves": solves}
    # nothing destabilizes within the search: a certified end at the certificate search's end is a lower bound
    out["at_least"] = ex is None and cert is not None and cert >= far - tol
    if ex is None:
        end = ("margin.delay_far" if given is not None else
               f"{ex_far / Ts:.3g} Ts" + (", the lifting's longest delay" if ex_far >= MAX_D_HI * Ts - 1e-12 else ""))
        further = (f"the lifting's longest delay, {MAX_D_HI} periods" if capped else "margin.delay_far searches further")
        note = f"no instability found up to {ex_far:.6g} s ({end}; {families})"
        if out["at_least"]:
            note += f"; certified up to the certificate search's end, {far:.6g} s: the margin is at least this ({further})"
    else:
        note = (f"certified / exhibited {ratio:.3f}; " if ratio is not None else "") + (
            f"the first instability upwards from {t_lo:.6g} s, searched up to {ex_far:.6g} s at most "
            f"({ex_far / Ts:.3g} Ts; {families})")
    out["note"] = note
    return out


def loss_margin(network: Network, settings: Any, plant: dict, say: Callable[[str], None] = lambda s: None
                ) -> dict[str, Any]:
    """The loss margin (dropouts.max_consecutive) of the gain ``plant["K"]`` on ``network``: the shortest burst of
    lost commands a periodic sequence destabilizes with (exhibited), the longest run with a certificate
    (certified, up to MAX_LOSSES), the witness and the time."""
    Ts, t_lo, t_hi, m0 = network.sampling_time, network.delay_min, network.delay_max, network.max_lost
    pieces = settings.pieces
    t0 = time.perf_counter()
    say("dropouts: instability and certificate search")
    m_ex, m_w, m_cert = None, None, None
    for m in range(0, MAX_LOSSES + 1):
        with _one_blas_thread():
            w = find_lti_instability(plant, Ts, t_lo, t_hi, m)
        if w is not None:  # the witness's own longest run of losses (around its period) is what it exhibits
            m_ex, m_w = int(max_cyclic_run(np.array([[x is None for x in w["delays"]]]))[0]), w
            break
    for m in range(0, (m_ex if m_ex is not None else MAX_LOSSES + 1)):  # coarse pieces first: the first proof counts
        if any(_certify(plant, Ts, t_lo, t_hi, m, N).certified for N in [*(N for N in PIECE_STAGES if N < pieces), pieces]):
            m_cert = m
        else:
            break
    out = {"configured": m0, "certified": m_cert, "exhibited": m_ex, "witness": m_w, "searched_up_to": MAX_LOSSES,
           "unit": "commands in a row", "time_s": round(time.perf_counter() - t0, 3)}
    out["at_least"] = m_ex is None and m_cert == MAX_LOSSES
    if m_ex is None:
        out["note"] = (f"no instability found up to {MAX_LOSSES} lost in a row" + (
            "; certified up to the search's end: the margin is at least this" if out["at_least"] else ""))
    return out


def lti_margins(cfg: Any, plant: dict, say: Callable[[str], None] = lambda s: None) -> dict[str, Any]:
    """The records of a linear plant's delay and loss margins (deprecated at the top level: use
    ``robustsynth.margin(LinearPlant.from_config(cfg), K)``, which returns the same margins as the one
    ``MarginReport`` of every plant; ``Margin.from_record`` reads each record as a margin).

    Parameters
    ----------
    cfg : LtiConfig
        A linear plant's config: its network and ``margin:`` settings.
    plant : dict
        The plant's arrays with the gain ``K`` (:func:`~robustsynth.model.lti.lti_plant`).
    say : callable
        Receives progress lines.

    Returns
    -------
    dict
        ``delay_max`` and ``dropouts``: the records of ``delay_margin`` and ``loss_margin`` (configured,
        certified, exhibited, witness, how far each search went, the times).
    """
    net = Network.from_config(cfg)
    return {"delay_max": delay_margin(net, cfg.margin, plant, say), "dropouts": loss_margin(net, cfg.margin, plant, say)}


def linear_margin(plant: Any, K: Any, settings: Any, say: Callable[[str], None]) -> MarginReport:
    """A linear plant's margins (:func:`robustsynth.margins.margin` on a
    :class:`~robustsynth.plants.linear.LinearPlant`): delay_max and dropouts of the gain ``K`` on the plant's
    network, with ``settings`` (``LtiMarginConfig``: pieces, tolerance, delay_far)."""
    from ..core.delays import check_lti_gain
    from ..model.lti import UNCONTROLLABLE_WARNING
    from ..report.markdown import LINEAR_READING

    try:
        arrays = dict(plant.arrays, K=np.asarray(K, dtype=float))
    except (TypeError, ValueError):
        raise InputError("K: must be a matrix of numbers") from None
    n, m = plant.B.shape
    check_lti_gain(arrays["K"], n, m, "K")
    net = plant.network
    margins = (Margin.from_record("delay_max", delay_margin(net, settings, arrays, say), net.delay_min),
               Margin.from_record("dropouts", loss_margin(net, settings, arrays, say)))
    meta = {"plant": {"kind": "lti", "n": int(n), "m": int(m), "states": plant.arrays["states"],
                      "units": plant.arrays["units"], "controllable": plant.arrays["controllable"]},
            "gain": arrays["K"].tolist(),
            "network": {"sampling_time": net.sampling_time, "delay": [net.delay_min, net.delay_max],
                        "max_consecutive": net.max_lost},
            "lyapunov": "common", "pieces": int(settings.pieces), "exhibit_tol": EXHIBIT_TOL, "reading": LINEAR_READING}
    warnings = () if plant.arrays["controllable"] else (UNCONTROLLABLE_WARNING,)
    return MarginReport(margins, meta, (), warnings)
