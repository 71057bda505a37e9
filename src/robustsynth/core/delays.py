"""Any linear plant under the network's time-varying delay (docs/theory.md §14), as mathematics every room may use:
its exact lifted model under time-varying delay and bounded losses, and a *guaranteed* over-approximation of it
(the linear plant of ``plant: kind: lti`` is built from its config in :mod:`robustsynth.model.lti`).

The plant ``x' = A x + B u`` receives the command ``u_k = K xi_k`` sent at t_k through the network;
within a period the commands act from the switching instants ``s~_j`` on (in-order delivery,
:mod:`robustsynth.core.lifting`), so with ``G(theta) = int_0^theta e^{A r} dr B`` (Van Loan)

    x_{k+1} = e^{A Ts} x_k + sum_{j<d_hi} G(Ts - s~_j) (u_{k-j} - u_{k-j-1}) + G(Ts) u_{k-d_hi},

which :func:`robustsynth.core.lifting.lift` assembles into ``xi_{k+1} = A~ xi_k + B~ u_k`` for any A (the robot's
``Gamma`` is the special case A^2 = 0).  A lost command acts for zero time: it takes its
successor's arrival, so with at most m losses in a row every instant lies in the ranges of the
delays [tau_min, tau_max + m Ts] (:func:`robustsynth.core.network.effective_delays`).

**Over-approximation** (a secant on a grid, with bounded remainders; in the spirit of Hetel et al.
2006 / Cloosterman et al. 2009; docs/theory.md §14): split the range of ``theta_j = Ts - s~_j`` into
pieces [theta_i, theta_i + w] (:func:`piece_grid`); on a piece

    G(theta_i + t) = G(theta_i) + C_i + t S_i + R_i(t),   S_i the secant, C_i the centre of its error,

with ``||R_i|| <= rho_i`` (full block) and ``||u_l' R_i|| <= rho_il`` along orthonormal directions u_l
(:func:`_secant_pieces`: sampled, plus a guaranteed bound between samples, a rounding floor and
REMAINDER_INFLATION).  The affine part takes its values at the vertices of the in-order instants'
polytope (:func:`in_order_vertices`).  :func:`coverage_check` tests the containment on random instants.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lifting import instant_ranges, lift

__all__ = [
    "gamma", "exact_lifted", "exact_closed_loop", "Piecewise", "over_approximation", "coverage_check",
    "pad_lti_gain", "check_lti_gain", "disturbance_bound", "lti_depth", "lifted_rows", "vertex_combinations",
    "REMAINDER_INFLATION", "piece_grid", "in_order_vertices", "vertex_count", "kept_directions", "YOUNG_DELTA",
    "channel_groups",
]

REMAINDER_INFLATION = 1e-9  # relative: the remainder bound's own rounding (norms by SVD, expm)
ROUNDING_FLOOR = 64 * float(np.finfo(float).eps)  # the remainder bound never below this relative rounding


def _augmented(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A
    M[:n, n:] = B
    return M


def gamma(A: np.ndarray, B: np.ndarray, theta: np.ndarray | float) -> np.ndarray:
    """G(theta) = int_0^theta e^{A r} dr B, batched over theta (..., n, m) (Van Loan: one block exponential)."""
    from scipy.linalg import expm

    theta = np.asarray(theta, dtype=float)
    n = A.shape[0]
    flat = theta.reshape(-1)
    u, inv = np.unique(flat, return_inverse=True)  # searches repeat grid values: one exponential per value
    E = expm(_augmented(A, B) * u[:, None, None])
    return E[inv, :n, n:].reshape(theta.shape + (n, B.shape[1]))


def _phi(A: np.ndarray, theta: np.ndarray | float) -> np.ndarray:
    from scipy.linalg import expm

    theta = np.asarray(theta, dtype=float)
    u, inv = np.unique(theta.reshape(-1), return_inverse=True)
    return expm(A * u[:, None, None])[inv].reshape(theta.shape + A.shape)


def exact_lifted(A: np.ndarray, B: np.ndarray, Ts: float, s_tilde: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The exactly lifted open loop ``(A~(s~), B~(s~))`` for switching instants ``s_tilde[..., j]``
    (j = 0..d_hi-1), shapes (..., n_s, n_s) and (..., n_s, m) with n_s = n + d_hi m."""
    s_tilde = np.asarray(s_tilde, dtype=float)
    Gs = gamma(A, B, Ts - s_tilde)
    At, Bt, _ = lift(_phi(A, Ts), Gs, gamma(A, B, Ts), np.zeros((A.shape[0], 1)))
    return At, Bt


def exact_closed_loop(A: np.ndarray, B: np.ndarray, K: np.ndarray, Ts: float, s_tilde: np.ndarray) -> np.ndarray:
    """The exactly lifted closed loop ``A~(s~) + B~(s~) K`` (:func:`exact_lifted`); K is (m, n_s)."""
    At, Bt = exact_lifted(A, B, Ts, s_tilde)
    return At + Bt @ K


@dataclass(frozen=True)
class Piecewise:
    """The over-approximation of ``G(Ts - s~_j)`` for each instant j: on piece i, ``base[j][i] +
    t slope[j][i]`` for t in [0, width[j][i]], plus a remainder R with ``||R|| <= rho[j][i]`` (the
    full block) and ``||u_l' R|| <= rho_dir[j][i, l]`` along each column u_l of the orthonormal
    ``dirs[j]`` (the directional bounds); and the lifted closed loop's pieces: ``A~ + B~ K = M0 +
    sum_j E G_j F_j``."""

    theta: list[np.ndarray]  # per instant: the pieces' starts (N_j,)
    width: list[np.ndarray]  # (N_j,)
    base: list[np.ndarray]  # (N_j, n, m): G(theta_i) + the secant error's centre
    slope: list[np.ndarray]  # (N_j, n, m): the secant (G(theta_i + w) - G(theta_i)) / w
    rho: list[np.ndarray]  # (N_j,): the remainder's bound on the piece (spectral norm)
    M0: np.ndarray  # (n_s, n_s): the closed loop without the instants' terms
    E: np.ndarray  # (n_s, n): the uncertain terms enter the plant's rows
    F: list[np.ndarray]  # per instant (m, n_s): G_j multiplies F_j xi
    dirs: list[np.ndarray] | None = None  # per instant (n, n): orthonormal directions of the remainder
    rho_dir: list[np.ndarray] | None = None  # per instant (N_j, n): the bound along each direction

    @property
    def d_hi(self) -> int:
        return len(self.theta)

    def channels(self, j: int) -> np.ndarray:
        """The remainder of instant j enters as ``E dirs[j] w`` (n_s, n): one column per direction."""
        return self.E if self.dirs is None else self.E @ self.dirs[j]

    def vertex(self, combo, end, absolute: bool = False) -> np.ndarray:
        """The closed loop at a vertex: piece ``combo[j]`` of each instant j at the fraction ``end[j]`` in
        [0, 1] of its width, ``M0 + sum_j E (base + end width slope) F_j``; ``absolute``: the same formula
        on absolute values (the magnitude a verified check bounds the rounding by)."""
        f = np.abs if absolute else (lambda x: x)
        M = f(self.M0).copy()
        for j in range(self.d_hi):
            i = combo[j]
            G = f(self.base[j][i]) + end[j] * self.width[j][i] * f(self.slope[j][i])
            M = M + f(self.E) @ G @ f(self.F[j])
        return M


GRID_SNAP = 1e-12  # relative to Ts: a range's end this close to 0 or Ts is widened to it (equal ranges share a grid)
REMAINDER_SAMPLES = 32  # intervals per piece on which the secant's error is sampled and bounded


def piece_grid(tau_min: float, tau_max: float, Ts: float, d_hi: int, pieces: int) -> tuple[list, list]:
    """(starts, widths) per instant: ``pieces`` equal pieces of the range of ``theta_j = Ts - s~_j``
    (one where the range is a point); ends within GRID_SNAP Ts of 0 or Ts are widened to them, so
    that instants on equal ranges share one grid (and take their pieces in order)."""
    thetas, widths = [], []
    for lo, hi in instant_ranges(tau_min, tau_max, Ts, d_hi):
        t_lo, t_hi = Ts - hi, Ts - lo
        t_lo = 0.0 if t_lo <= GRID_SNAP * Ts else t_lo
        t_hi = Ts if t_hi >= Ts * (1.0 - GRID_SNAP) else t_hi
        N = 1 if t_hi - t_lo <= 0.0 else pieces
        thetas.append(t_lo + (t_hi - t_lo) * np.arange(N) / N)
        widths.append(np.full(N, (t_hi - t_lo) / N))
    return thetas, widths


def _chain_box_points(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Points of ``{a <= theta <= b, theta_0 <= theta_1 <= ...}`` among which lie all its vertices (n_pts, d).

    A vertex has d independent tight constraints; the tight ``theta_j = theta_j+1`` split it into runs of
    equal values, and each run needs a tight bound of its own: the run's value is its largest lower bound
    or its smallest upper bound.  Every run partition with either value, in order, is enumerated (memoized
    on the run's start and the previous value)."""
    d = len(a)
    memo: dict = {}

    def rest(j: int, prev: float) -> list[tuple]:
        if j == d:
            return [()]
        key = (j, prev)
        if key in memo:
            return memo[key]
        out: set = set()
        L, U = -np.inf, np.inf
        for e in range(j, d):  # the run j..e
            L, U = max(L, float(a[e])), min(U, float(b[e]))
            if L > U:
                break
            for v in {L, U}:
                if v >= prev:
                    out.update((v,) * (e - j + 1) + tail for tail in rest(e + 1, v))
        memo[key] = sorted(out)
        return memo[key]

    pts = rest(0, -np.inf)
    return np.array(pts, dtype=float).reshape(-1, d)


def in_order_vertices(theta: list[np.ndarray], width: list[np.ndarray], limit: int | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(piece combinations (n_c, d), the combination of each vertex (n_v,), the vertices' positions as
    fractions of their pieces (n_v, d) in [0, 1]).

    Delivery is in order, so ``s~_0 >= s~_1 >= ...``, i.e. ``theta_0 <= theta_1 <= ...``: the instants of a
    combination lie in the box of its pieces cut by that chain, and the LMIs are convex in the affine part,
    so the vertices of that polytope suffice (:func:`_chain_box_points`; d + 1 when every instant is on one
    piece, instead of the box's 2^d).  Combinations without admissible instants are left out, and instants
    on one grid take their pieces in order (a later piece first meets the earlier only at a shared end,
    which the in-order combination holds).  With ``limit``, the enumeration stops once the vertices exceed
    it (a count above the limit, not the whole list: :func:`vertex_count`'s budget test)."""
    d = len(theta)
    shared = [j > 0 and theta[j].size == theta[j - 1].size and np.array_equal(theta[j], theta[j - 1])
              and np.array_equal(width[j], width[j - 1]) for j in range(d)]
    combos: list[tuple] = []

    def walk(j: int, low: float, chosen: tuple) -> None:
        if j == d:
            combos.append(chosen)
            return
        for i in range(theta[j].size):
            if shared[j] and i < chosen[-1]:
                continue
            a, b = float(theta[j][i]), float(theta[j][i] + width[j][i])
            if max(a, low) <= b:
                walk(j + 1, max(a, low), chosen + (i,))

    walk(0, -np.inf, ())
    owner, frac = [], []
    for c, combo in enumerate(combos):
        a = np.array([theta[j][i] for j, i in enumerate(combo)])
        w = np.array([width[j][i] for j, i in enumerate(combo)])
        pts = _chain_box_points(a, a + w)
        f = np.where(w > 0, (pts - a) / np.where(w > 0, w, 1.0), 0.0)
        owner.extend([c] * len(f))
        frac.append(np.clip(f, 0.0, 1.0))
        if limit is not None and len(owner) > limit:
            break
    return (np.array(combos, dtype=int).reshape(-1, d), np.array(owner, dtype=int),
            np.concatenate(frac).reshape(-1, d) if frac else np.zeros((0, d)))


def vertex_count(tau_min: float, tau_max: float, Ts: float, d_hi: int, pieces: int, limit: int | None = None) -> int:
    """The vertices of the over-approximation with ``pieces`` pieces per instant (:func:`in_order_vertices`),
    without building it; with ``limit``, any count above it stands for all counts above it."""
    return len(in_order_vertices(*piece_grid(tau_min, tau_max, Ts, d_hi, pieces), limit=limit)[1])


def vertex_combinations(pw) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`in_order_vertices` of the over-approximation ``pw``: (combos, owner, fractions)."""
    return in_order_vertices(pw.theta, pw.width)


def _interval_sup(a: np.ndarray, D: np.ndarray, L: np.ndarray, h: float) -> np.ndarray:
    """A bound on ``sup ||f||`` over each run of sampled intervals, from the samples' norms ``a`` (..., K + 1)
    and bounds on each interval's ``sup ||f''||`` ``D`` and ``sup ||f'||`` ``L`` (..., K), spacing h:
    per interval the smaller of ``max(a_k, a_k+1) + h^2/8 D_k`` (the chord's error) and
    ``(a_k + a_k+1)/2 + h/2 L_k`` (Lipschitz from both ends); the max over the intervals (...)."""
    lo, hi = a[..., :-1], a[..., 1:]
    chord = np.maximum(lo, hi) + h * h / 8.0 * D
    lip = 0.5 * (lo + hi) + 0.5 * h * L
    return np.max(np.minimum(chord, lip), axis=-1)


def _secant_pieces(A: np.ndarray, B: np.ndarray, th: np.ndarray, w: np.ndarray, mu: float):
    """One instant's pieces [th_i, th_i + w_i]: (base, slope, rho, dirs, rho_dir) of docs/theory.md §14.

    ``G(th_i + t) = base_i + t slope_i + R_i(t)``: slope the secant, base ``G(th_i)`` plus the centre of
    the secant's error ``e_i(t)`` (zero at both ends) along each direction.  The directions: the left
    singular vectors of every sampled ``e_i`` of the instant (a plant with one fast real mode has its
    remainder along one).  The bounds: from ``f = u' R`` at REMAINDER_SAMPLES + 1 points per piece and
    ``f' = u' (e^{A s} B - slope)``, ``f'' = u' A e^{A s} B`` between them (:func:`_interval_sup`, with
    ``||u' A e^{A (s + r)} B|| <= ||u' A e^{A s} B|| + r e^{mu r} ||u' A^2|| ||e^{A s} B||``), plus a
    rounding floor, times 1 + REMAINDER_INFLATION."""
    n, m = B.shape
    N, K = th.size, REMAINDER_SAMPLES
    h = w / K  # (N,)
    t = w[:, None] * np.arange(K + 1)[None] / K  # (N, K + 1)
    s = th[:, None] + t
    G = gamma(A, B, s)  # (N, K + 1, n, m)
    eB = _phi(A, s) @ B
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = np.where(w[:, None, None] > 0, (G[:, -1] - G[:, 0]) / np.where(w > 0, w, 1.0)[:, None, None], eB[:, 0])
    e = G - G[:, :1] - t[..., None, None] * slope[:, None]
    U = np.linalg.svd(e.transpose(2, 0, 1, 3).reshape(n, -1), full_matrices=True)[0]  # (n, n)
    eU = np.einsum("al,nkam->nklm", U, e)  # the error along each direction: rows u_l' e
    centre = 0.5 * (eU.max(axis=1) + eU.min(axis=1))  # (N, n, m)
    RU = eU - centre[:, None]
    base = G[:, 0] + np.einsum("al,nlm->nam", U, centre)
    # per direction and interval: sup ||f''|| and sup ||f'||
    UA, UA2 = U.T @ A, U.T @ A @ A
    grow = np.exp(mu * h)[:, None]  # e^{mu r} <= e^{mu h} on an interval
    eBn = np.linalg.norm(eB, 2, axis=(-2, -1))[:, :-1]  # (N, K)
    dirB = np.linalg.norm(np.einsum("la,nkam->nklm", U.T, eB), axis=-1)[:, :-1]  # (N, K, n): ||u_l' e^{A s} B||
    dirAB = np.linalg.norm(np.einsum("la,nkam->nklm", UA, eB), axis=-1)[:, :-1]
    D = dirAB + (h[:, None] * grow * eBn)[..., None] * np.linalg.norm(UA2, axis=1)
    Ldir = np.minimum(dirB + h[:, None, None] * D, (grow * eBn)[..., None])
    Ldir = Ldir + np.linalg.norm(np.einsum("la,nam->nlm", U.T, slope), axis=-1)[:, None]
    a_dir = np.linalg.norm(RU, axis=-1)  # (N, K + 1, n)
    rho_dir = np.stack([_interval_sup(a_dir[..., l], D[..., l], Ldir[..., l], h[:, None]) for l in range(n)], axis=-1)
    # the full block: the same with u' dropped
    R = np.einsum("al,nklm->nkam", U, RU)
    a_full = np.linalg.norm(R, 2, axis=(-2, -1))
    D_full = np.linalg.norm(A @ eB, 2, axis=(-2, -1))[:, :-1] + h[:, None] * grow * eBn * np.linalg.norm(A @ A, 2)
    L_full = np.minimum(eBn + h[:, None] * D_full, grow * eBn) + np.linalg.norm(slope, 2, axis=(-2, -1))[:, None]
    rho = np.minimum(_interval_sup(a_full, D_full, L_full, h[:, None]), np.sqrt(np.sum(rho_dir**2, axis=-1)))
    # a floor for rounding: with A B = 0 (an integrator chain fed directly) G is affine and the bounds are 0,
    # while the computed G and its affine part still differ by rounding; the floor is the size of that rounding
    floor = ROUNDING_FLOOR * (np.max(np.linalg.norm(G, 2, axis=(-2, -1)), axis=1) + w * np.max(eBn, axis=1)
                              + max(float(np.linalg.norm(B, 2)), 1e-300) * (th + w))
    rho = (rho + floor) * (1.0 + REMAINDER_INFLATION)
    rho_dir = (rho_dir + floor[:, None]) * (1.0 + REMAINDER_INFLATION)
    return base, slope, rho, U, rho_dir


DROP_REL = 1e-8  # a direction whose bound is below this fraction of the largest is not a channel of its own
YOUNG_DELTA = 1e-9  # the dropped directions' share: V(y + r) <= (1 + delta) V(y) + (1 + 1/delta) V(r)


def kept_directions(pw: Piecewise) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """(per instant the directions that are channels of the analysis LMIs, per instant and piece the dropped
    ones' bound rho_D with ``||U_D' R|| <= rho_D``): directions whose bound is at most DROP_REL times the
    largest of all (rounding-level: a remainder along fewer directions than n, or an instant on a point)
    are no channel; :func:`robustsynth.certificate.lti.lti_vertex_blocks` covers them by Young's inequality.
    Halving the channels divides the solver's work per vertex by about four."""
    top = max(float(np.max(r)) for r in pw.rho_dir)
    kept, dropped = [], []
    for r in pw.rho_dir:
        keep = np.max(r, axis=0) > DROP_REL * top
        kept.append(np.flatnonzero(keep))
        dropped.append(np.sqrt(np.sum(r[:, ~keep] ** 2, axis=1)))
    return kept, dropped


def channel_groups(pw: Piecewise, kept: list[np.ndarray]) -> list[list[int]]:
    """The instants with a channel (kept directions), grouped by equal channels ``E dirs[j][:, kept[j]]``:
    instants whose kept directions and ``dirs`` are bit for bit the same (instants on equal ranges:
    :func:`over_approximation` computes their pieces once).  Their remainders enter the plant's rows as one
    sum ``E U W``, W = sum_j w_j, so the LMIs need one channel per group (docs/theory.md §14; the numpy check,
    :func:`robustsynth.certificate.lti.lti_vertex_blocks`, bounds W by the parallel sum of the instants'
    multipliers, which holds for any split of W).  Equality of the channel matrices is all the soundness needs."""
    groups: list[list[int]] = []
    for j in range(pw.d_hi):
        if not len(kept[j]):
            continue
        for g in groups:
            i = g[0]
            if np.array_equal(kept[i], kept[j]) and (pw.dirs is None or np.array_equal(pw.dirs[i], pw.dirs[j])):
                g.append(j)
                break
        else:
            groups.append([j])
    return groups


def over_approximation(A: np.ndarray, B: np.ndarray, K: np.ndarray, Ts: float, tau_min: float, tau_max: float,
                       d_hi: int, pieces: int) -> Piecewise:
    """The pieces of every instant's range (:func:`piece_grid`), their secants and remainder bounds
    (:func:`_secant_pieces`), and the closed loop's decomposition; ``tau_max`` includes the losses
    (tau_max + m Ts)."""
    A, B, K = (np.asarray(x, dtype=float) for x in (A, B, K))
    if not tau_min <= tau_max:
        raise ValueError(f"over_approximation: tau_min {tau_min:g} > tau_max {tau_max:g}")
    n, m = B.shape
    n_s = n + d_hi * m
    mu = max(float(np.max(np.linalg.eigvalsh((A + A.T) / 2.0))), 0.0)  # the logarithmic norm's positive part
    thetas, widths = piece_grid(tau_min, tau_max, Ts, d_hi, pieces)
    bases, slopes, rhos, dirs, rho_dirs = [], [], [], [], []
    done: dict = {}  # instants on equal ranges share their pieces, bit for bit (channel_groups merges them)
    with np.errstate(over="ignore", invalid="ignore"):
        for th, w in zip(thetas, widths):
            key = (th.tobytes(), w.tobytes())
            if key not in done:
                done[key] = _secant_pieces(A, B, th, w, mu)
            base, slope, rho, U, rho_dir = done[key]
            if not (np.all(np.isfinite(rho)) and np.all(np.isfinite(rho_dir)) and np.all(np.isfinite(base))):
                raise ValueError("over_approximation: the remainder bound overflows (a stiff plant over a long range)")
            bases.append(base)
            slopes.append(slope)
            rhos.append(rho)
            dirs.append(U)
            rho_dirs.append(rho_dir)
    # the closed loop with every G_j = 0: e^{A Ts}, G(Ts) on the oldest command, the shift register
    M0 = exact_closed_loop(A, B, K, Ts, np.full(d_hi, Ts))  # s~ = Ts: G(0) = 0 for every instant
    E = np.zeros((n_s, n))
    E[:n] = np.eye(n)
    F = []
    for j in range(d_hi):  # G_j multiplies u_{k-j} - u_{k-j-1}; u_k = K xi
        Fj = np.zeros((m, n_s))
        Fj += K if j == 0 else 0.0
        if j >= 1:
            Fj[:, n + (j - 1) * m : n + j * m] += np.eye(m)
        Fj[:, n + j * m : n + (j + 1) * m] -= np.eye(m)
        F.append(Fj)
    return Piecewise(thetas, widths, bases, slopes, rhos, M0, E, F, dirs, rho_dirs)


def coverage_check(A: np.ndarray, B: np.ndarray, K: np.ndarray, Ts: float, tau_min: float, tau_max: float, d_hi: int,
                   pw: Piecewise, samples: int = 10_000, seed: int = 0) -> dict[str, float]:
    """Random in-order instants in their ranges: the exact closed loop is ``M0 + sum_j E (affine_j + R_j) F_j``
    with ``||R_j|| <= rho`` and ``||u_l' R_j|| <= rho_dir`` of its piece; returns the worst remainder / bound
    (full block, and over the directions) and the worst reconstruction residual (the decomposition itself)."""
    rng = np.random.default_rng(seed)
    ranges = instant_ranges(tau_min, tau_max, Ts, d_hi)
    s = ranges[:, 0] + (ranges[:, 1] - ranges[:, 0]) * rng.random((samples, d_hi))
    s = np.maximum.accumulate(s[:, ::-1], axis=1)[:, ::-1]  # in order: s~_0 >= s~_1 >= ...
    exact = exact_closed_loop(A, B, K, Ts, s)
    recon = np.broadcast_to(pw.M0, exact.shape).copy()
    worst, worst_dir = 0.0, 0.0

    def ratio(r: np.ndarray, bound: np.ndarray) -> float:
        with np.errstate(divide="ignore", invalid="ignore"):
            q = np.where(bound > 0, r / np.maximum(bound, 1e-300), np.where(r > 0, np.inf, 0.0))
        return float(np.max(q)) if q.size else 0.0

    for j in range(d_hi):
        theta = Ts - s[:, j]
        i = np.clip(np.searchsorted(pw.theta[j], theta, side="right") - 1, 0, pw.theta[j].size - 1)
        t = np.clip(theta - pw.theta[j][i], 0.0, pw.width[j][i])
        G = gamma(A, B, theta)
        R = G - (pw.base[j][i] + t[:, None, None] * pw.slope[j][i])
        worst = max(worst, ratio(np.linalg.norm(R, 2, axis=(-2, -1)), pw.rho[j][i]))
        if pw.dirs is not None:
            rd = np.linalg.norm(np.einsum("la,sam->slm", pw.dirs[j].T, R), axis=-1)
            worst_dir = max(worst_dir, ratio(rd, pw.rho_dir[j][i]))
        recon += pw.E @ G @ pw.F[j]
    return {"samples": float(samples), "remainder_ratio": worst, "direction_ratio": worst_dir,
            "reconstruction": float(np.max(np.abs(recon - exact)))}


def lifted_rows(C: np.ndarray, n_s: int) -> np.ndarray:
    """Rows on the plant's state (p, n) as rows on the lifted state [x; u_{k-1}; ...] (p, n_s): zeros
    for the stored commands."""
    C = np.asarray(C, dtype=float)
    return np.hstack([C, np.zeros((C.shape[0], n_s - C.shape[1]))])


def lti_depth(tau_max: float, m_lost: int, Ts: float) -> int:
    """d_hi: the commands the lifted state keeps for delays up to tau_max and m_lost losses in a row."""
    from .lifting import delay_indices

    return delay_indices(0.0, tau_max + m_lost * Ts, Ts)[1]


def check_lti_gain(K: np.ndarray, n: int, m: int, where: str) -> None:
    """InputError unless K is m x n (u_k = K x_k) or m x (n + d m) on the lifted state."""
    from ..errors import InputError

    if K.ndim != 2 or K.shape[0] != m or K.shape[1] < n or (K.shape[1] - n) % m or not np.all(np.isfinite(K)):
        shape = " x ".join(str(x) for x in K.shape)
        raise InputError(f"{where}: must be a finite m x n = {m} x {n} matrix (u_k = K x_k) or m x (n + d m) on the "
                         f"lifted state (got {shape})")


def disturbance_bound(A: np.ndarray, E: np.ndarray, w_max: float, Ts: float, steps: int = 256) -> float:
    """A guaranteed bound on ``||int_0^Ts e^{A r} E w(t_k + Ts - r) dr||_2`` for ``||w(t)|| <= w_max``:
    ``w_max int_0^Ts ||e^{A r} E|| dr`` with ``||e^{A r} E|| <= ||e^{A r_i} E|| e^{mu (r - r_i)}`` on
    each of ``steps`` equal pieces [r_i, r_i + h] (mu the logarithmic norm's positive part)."""
    h = Ts / steps
    mu = max(float(np.max(np.linalg.eigvalsh((A + A.T) / 2.0))), 0.0)
    r = h * np.arange(steps)
    norms = np.linalg.norm(_phi(A, r) @ E, 2, axis=(-2, -1))
    piece = h if mu * h < 1e-12 else float(np.expm1(mu * h) / mu)
    return float(w_max * np.sum(norms) * piece * (1.0 + 1e-9))


def pad_lti_gain(K: np.ndarray, n: int, m: int, d_hi: int) -> np.ndarray:
    """K on the lifted state of d_hi stored commands (zeros for the commands it does not use); a K on
    more stored commands than d_hi keeps them all (the lifting must then be that long)."""
    width = n + d_hi * m
    if K.shape[1] >= width:
        return K
    return np.hstack([K, np.zeros((K.shape[0], width - K.shape[1]))])
