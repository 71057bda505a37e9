"""``robustsynth verify`` on a linear plant (``plant: kind: lti``, docs/theory.md §15): the certified
gain's claims tested on the exactly lifted sampled-data loop, independently of the LMIs.

- **frozen delays**: the spectral radius of the exact closed loop for CONSTANT_DELAYS constant delays
  in [tau_min, tau_max] is < 1;
- **the set's boundary**: runs start on ``xi' P xi = 1`` (random directions, and the directions
  that maximize each bounded output and input) and follow random, extreme (constant at either end,
  alternating, random ends) and greedy-adversarial delay sequences (each packet's delay, or its
  loss, chosen from a grid to maximize the next V), with losses up to the cap, and the disturbance
  held over each period at its bound (random directions, or the direction that maximizes the next V);
- the verdict: V never leaves the set (with the disturbance) or shrinks at the certified rate
  (without), and the outputs and inputs stay within their certified bounds, with tolerance TOL.

The simulation is exact for the lifted model (matrix exponentials, in-order delivery), so a failure
is a counterexample to the certificate, not a modelling artefact.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ..core.network import Network, s_tilde_sequence
from ..results import Check, Verdict, all_passed

__all__ = ["verify_lti", "verify_plant", "verify_linear", "certified_gain", "checked_gain", "CONSTANT_DELAYS", "TOL"]

CONSTANT_DELAYS = 201
TOL = 1e-9  # relative: the simulation's own rounding
GREEDY_GRID = 7  # delays per packet the adversary chooses from
HINF_PERIODS, HINF_RUNS = 60, 8  # hinf: the horizon and the delay sequences per family


def _boundary_states(P: np.ndarray, rows: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` random states with xi' P xi = 1, and +-P^-1 r' / sqrt(r P^-1 r') per row r (its maximizer)."""
    n_s = P.shape[0]
    L = np.linalg.cholesky(P)
    z = rng.standard_normal((count, n_s))
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    xi = np.linalg.solve(L.T, z.T).T  # xi' P xi = |z|^2 = 1
    Q = np.linalg.inv(P)
    best = [(Q @ r) / np.sqrt(r @ Q @ r) for r in rows if r @ Q @ r > 0]
    extra = np.array(best + [-b for b in best]).reshape(-1, n_s)
    return np.vstack([xi, extra])


def _reproof(plant: dict, K: np.ndarray, P: np.ndarray, multipliers: Any, pieces: int, figures: dict, Ts: float,
             tau_min: float, tau_max: float, m_lost: int) -> dict[str, Any]:
    """The check "the certificate re-proven in numpy for this config" (failed without multipliers)."""
    from ..certificate.lti import recheck_lti

    name = "the certificate re-proven in numpy for this config"
    if multipliers is None:
        return Check(name, False, 0.0, 1.0,
                     "not re-proven: the certificate's multipliers were not given "
                     "(multipliers=design.certificate['multipliers'])").to_dict()
    gains = {"K": K, "certificate": {"P": P, "multipliers": multipliers, "alpha": figures.get("alpha"), "pieces": pieces},
             "certified": figures}
    proof = recheck_lti(plant, gains, Ts, tau_min, tau_max, m_lost)
    return Check(name, proof.passed, float(proof.passed), 1.0, proof.reason or "verified arithmetic").to_dict()


def verify_lti(plant: dict, K: np.ndarray, P: np.ndarray, Ts: float, tau_min: float, tau_max: float, m_lost: int,
               figures: dict, runs: int = 64, periods: int = 150, seed: int = 0, *,
               multipliers: np.ndarray | None = None, pieces: int = 2) -> dict[str, Any]:
    """The checks of the module docstring; returns {"passed", "checks": [...], "families": {...}}.

    The first check re-proves the certificate (P, ``multipliers``, ``figures["alpha"]`` and ``pieces``:
    a linear plant's :class:`~robustsynth.synthesis.SynthesisResult`'s ``certificate``, or a gains file's) in numpy for *this* plant and network (:func:`robustsynth.certificate.lti.recheck_lti`).
    Without the multipliers it cannot, and the verdict is failed: simulations alone prove nothing.

    Parameters
    ----------
    plant : dict
        The plant's arrays (:func:`~robustsynth.model.lti.lti_plant`).
    K, P : numpy.ndarray
        The gain and its certificate's matrix.
    Ts, tau_min, tau_max : float
        Sampling period and delay bounds [s].
    m_lost : int
        Commands lost in a row at most.
    figures : dict
        The certified figures (with ``alpha``).
    runs, periods, seed : int
        Simulated delay sequences, their length, their seed.
    multipliers : numpy.ndarray or None
        The certificate's multipliers (above).
    pieces : int
        The over-approximation's pieces the certificate was made with.

    Returns
    -------
    dict
        ``passed``, ``checks`` and ``families``.
    """
    K, P, d = _checked_certificate(plant, K, P, Ts, tau_max, m_lost)
    rng = np.random.default_rng(seed)
    checks: list[dict[str, Any]] = [_reproof(plant, K, P, multipliers, pieces, figures, Ts, tau_min, tau_max, m_lost)]
    frozen_check, frozen = _frozen_check(plant, K, Ts, tau_min, tau_max, m_lost)
    checks.append(frozen_check)
    traces: dict[str, Any] = {"frozen": frozen, "V": {}}
    if figures.get("hinf_gain") is not None:
        checks.append(_l2_gain_check(plant, K, Ts, tau_min, tau_max, m_lost, d, float(figures["hinf_gain"]), rng))
        return {"passed": all_passed(checks), "checks": checks, "families": {}, "starts": 0,
                "periods": HINF_PERIODS, "lifting": d, "traces": traces}
    boundary = _BoundaryRuns(plant, K, P, Ts, figures, runs, rng, traces)
    _fixed_sequences(boundary, plant, K, Ts, tau_min, tau_max, m_lost, d, periods, rng)
    _greedy_adversary(boundary, plant, K, Ts, tau_min, tau_max, d, periods)
    checks += boundary.checks()
    traces["alpha"], traces["set"] = boundary.alpha, bool(boundary.dist)
    return {"passed": all_passed(checks), "checks": checks, "families": boundary.families,
            "starts": boundary.R, "periods": periods, "lifting": d, "traces": traces}


def _checked_certificate(plant: dict, K: np.ndarray, P: np.ndarray, Ts: float, tau_max: float, m_lost: int
                         ) -> tuple[np.ndarray, np.ndarray, int]:
    """The gain padded to the lifting (the delay bound's, or the gain's own when longer), the certificate's
    matrix symmetrized, and the lifting d; InputError where P does not fit the lifted state, K or P is not
    finite, or P is not positive definite (the certified set must be an ellipsoid)."""
    from ..errors import InputError
    from ..core.delays import lti_depth, pad_lti_gain

    n, m = plant["B"].shape
    d = max(lti_depth(tau_max, m_lost, Ts), (K.shape[1] - n) // m)
    K = pad_lti_gain(np.asarray(K, dtype=float), n, m, d)
    n_s = n + d * m
    P = np.asarray(P, dtype=float)
    if P.shape != (n_s, n_s):
        raise InputError(f"P: the certified set's matrix is {P.shape[0]} x {P.shape[1]}, the lifted state has {n_s}")
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(K))):
        raise InputError("P, K: must be finite (a certificate with non-finite entries proves nothing)")
    P = (P + P.T) / 2.0
    if np.min(np.linalg.eigvalsh(P)) <= 0:
        raise InputError("P: must be positive definite (the certified set {xi' P xi <= 1} is an ellipsoid)")
    return K, P, d


def _frozen_check(plant: dict, K: np.ndarray, Ts: float, tau_min: float, tau_max: float, m_lost: int
                  ) -> tuple[dict[str, Any], dict[str, list]]:
    """The check "frozen-delay spectral radius": the exact closed loop's spectral radius at CONSTANT_DELAYS
    constant delays in [tau_min, tau_max] (with the losses) is below 1; and its trace (delay, radius).
    The radius is the robot's frozen check's (:func:`~robustsynth.verification.lifted.frozen_spectral_radius`,
    on the plant's exact lifted map)."""
    from ..core.delays import lti_depth, pad_lti_gain
    from .lifted import frozen_spectral_radius

    n, m = plant["B"].shape
    d = max(lti_depth(tau_max, m_lost, Ts), (K.shape[1] - n) // m)  # a gain may keep more commands than the delays need
    Kp = pad_lti_gain(K, n, m, d)
    taus = Network(Ts, tau_min, tau_max, m_lost).grid(CONSTANT_DELAYS)
    s = s_tilde_sequence(np.repeat(taus[:, None], d + 1, axis=1), Ts, d)[:, 0]
    rho = frozen_spectral_radius(_ExactLoop(plant["A"], plant["B"], Ts), Kp, s)
    trace = {"delay": taus.tolist(), "spectral_radius": rho.tolist()}
    i = int(np.argmax(rho))
    return (Check("frozen-delay spectral radius", bool(rho[i] < 1.0), float(rho[i]), 1.0,
                  f"worst at constant delay {taus[i]:.6g} s").to_dict(), trace)


class _ExactLoop:
    """A linear plant's exact lifted map, as the Plant protocol's judges read it (no uncertain parameter)."""

    def __init__(self, A: np.ndarray, B: np.ndarray, Ts: float) -> None:
        self.A, self.B, self.Ts = A, B, Ts

    def parameter_corners(self) -> np.ndarray:
        return np.zeros((1, 0))

    def lifted(self, s_tilde: np.ndarray, theta: Any = None) -> tuple[np.ndarray, np.ndarray]:
        from ..core.delays import exact_lifted

        return exact_lifted(self.A, self.B, self.Ts, s_tilde)


class _BoundaryRuns:
    """The runs from the certified set's boundary: their starts (random, and each output's and input's
    maximizer), one step of the lifted loop with the disturbance held at its bound, and what each family of
    delay sequences reached (the worst V, decay, output and input ratios; the worst run's V as a trace)."""

    def __init__(self, plant: dict, K: np.ndarray, P: np.ndarray, Ts: float, figures: dict, runs: int,
                 rng: np.random.Generator, traces: dict[str, Any]) -> None:
        from ..core.delays import gamma, lifted_rows

        self.P, self.K, self.rng, self.traces = P, K, rng, traces
        self.n = plant["B"].shape[0]
        self.dist = figures.get("disturbance_step_bound") is not None
        self.Gw = gamma(plant["A"], plant["E"], Ts) if self.dist else None  # the disturbance held over a period
        self.w_max = float(plant["w_max"]) if self.dist else 0.0
        self.C = lifted_rows(plant["C"], P.shape[0])
        self.out_bounds = np.array([o["bound"] for o in figures.get("outputs", [])]) if self.dist else None
        self.u_max = plant.get("u_max")
        self.alpha = float(figures["alpha"])
        self.x0 = _boundary_states(P, np.array([*self.C] + [*K]), runs, rng)
        self.R = len(self.x0)
        self.worst = {"V": 0.0, "decay": 0.0, "outputs": 0.0, "inputs": 0.0}
        self.families: dict[str, dict[str, float]] = {}

    def V(self, xi: np.ndarray) -> np.ndarray:
        return np.einsum("ri,ij,rj->r", xi, self.P, xi)

    def step(self, xi_next: np.ndarray, worst_dir: bool) -> np.ndarray:
        """The next states with the disturbance held over the period at its bound: in the direction that
        maximizes the next V (``worst_dir``), else a random one (none without a disturbance)."""
        if not self.dist:
            return xi_next
        Gw, n = self.Gw, self.n
        q = Gw.shape[1]
        if worst_dir:
            g = (self.P[:, :n] @ Gw).T @ xi_next.T  # (q, R): the gradient of V along w, up to 2
            w = (g / np.maximum(np.linalg.norm(g, axis=0, keepdims=True), 1e-300)).T
        else:
            w = self.rng.standard_normal((len(xi_next), q))
            w /= np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-300)
        out = xi_next.copy()
        out[:, :n] += self.w_max * w @ Gw.T
        return out

    def record(self, name: str, Vs: np.ndarray, xs: np.ndarray, V0: np.ndarray) -> None:
        """V after the first step (the starts are on the boundary by construction); the outputs and
        inputs from the start on (the starts include each one's maximizer on the set).  NaN counts
        as a violation."""
        worst, dist = self.worst, self.dist
        k = np.arange(1, Vs.shape[1])
        if dist:
            vmax = float(np.max(Vs[:, 1:]))
            worst["V"] = max(worst["V"], vmax) if np.isfinite(vmax) else np.inf
        else:
            ratio = float(np.max(Vs[:, 1:] / (self.alpha ** k[None, :] * V0[:, None])))
            worst["decay"] = max(worst["decay"], ratio) if np.isfinite(ratio) else np.inf
            vmax = ratio
        rep = {"max_V_ratio": vmax}
        shown = Vs if dist else Vs / V0[:, None]  # V (set: V <= 1) or V_k / V_0 (against alpha^k)
        self.traces["V"][name] = shown[int(np.argmax(np.max(shown[:, 1:], axis=1)))].tolist()  # the worst run
        inside = Vs <= 1.0 + TOL
        for key, rows, lim in (("outputs", self.C, self.out_bounds), ("inputs", self.K, self.u_max)):
            if lim is None:
                continue
            r = np.where(inside[..., None], np.abs(np.einsum("ij,rkj->rki", rows, xs)) / lim, 0.0)
            start, later = float(np.max(r[:, 0])), float(np.max(r[:, 1:]))  # the starts: each one's maximizer
            o = max(start, later)
            worst[key] = max(worst[key], o) if np.isfinite(o) else np.inf
            worst[key + "_later"] = max(worst.get(key + "_later", 0.0), later)
            rep[f"max_{key[:-1]}_ratio"] = later  # after the first step: how close the runs come
        self.families[name] = rep

    def checks(self) -> list[dict[str, Any]]:
        """The verdict's checks on what the runs reached: the set invariant (with the disturbance) or V
        shrinking at the certified rate (without), the outputs and the inputs within their bounds."""
        worst, out = self.worst, []
        if self.dist:
            out.append(Check("the set is invariant (max V from its boundary)", worst["V"] <= 1.0 + TOL, worst["V"], 1.0,
                             f"{self.R} starts x {len(self.families)} families"))
        else:
            out.append(Check("V shrinks at the certified rate (max V_k / (alpha^k V_0))", worst["decay"] <= 1.0 + TOL,
                             worst["decay"], 1.0, f"alpha = {self.alpha:.6g}"))
        if self.out_bounds is not None:
            out.append(Check("outputs within their certified bounds (max |y| / bound)", worst["outputs"] <= 1.0 + TOL,
                             worst["outputs"], 1.0,
                             f"inside the set; at the maximizing starts, then {worst['outputs_later']:.4g} after a period"))
        if self.u_max is not None:
            out.append(Check("inputs within their limits on the set (max |u| / limit)", worst["inputs"] <= 1.0 + TOL,
                             worst["inputs"], 1.0,
                             f"inside the set; at the maximizing starts, then {worst['inputs_later']:.4g} after a period"))
        return [c.to_dict() for c in out]


def _fixed_sequences(boundary: _BoundaryRuns, plant: dict, K: np.ndarray, Ts: float, tau_min: float, tau_max: float,
                     m_lost: int, d: int, periods: int, rng: np.random.Generator) -> None:
    """The runs along delay sequences fixed in advance (:meth:`robustsynth.core.network.Network.families`), ``periods`` each, with the
    disturbance in a random direction (the random family) or the worst one (the others)."""
    from ..core.delays import exact_closed_loop

    for name, seq in Network(Ts, tau_min, tau_max, m_lost).families(rng, boundary.R, periods + d + m_lost + 1).items():
        s = s_tilde_sequence(seq, Ts, d)[:, :periods]
        M = exact_closed_loop(plant["A"], plant["B"], K, Ts, s)  # (R, periods, n_s, n_s)
        xi = boundary.x0.copy()
        xs, Vs = [xi], [boundary.V(xi)]
        for k in range(periods):
            xi = boundary.step(np.einsum("rij,rj->ri", M[:, k], xi), worst_dir=(name != "random"))
            xs.append(xi)
            Vs.append(boundary.V(xi))
        boundary.record(name, np.array(Vs).T, np.array(xs).transpose(1, 0, 2), Vs[0])


def _greedy_adversary(boundary: _BoundaryRuns, plant: dict, K: np.ndarray, Ts: float, tau_min: float, tau_max: float,
                      d: int, periods: int) -> None:
    """The greedy adversary, up to 60 periods: each packet's delay chosen from a grid of GREEDY_GRID to
    maximize the next V, the disturbance in its worst direction (losses are left to the families: a lost
    packet's effect depends on its successor's delay, not chosen yet)."""
    from ..core.delays import exact_closed_loop

    A, B, R = plant["A"], plant["B"], boundary.R
    grid = np.unique(Network(Ts, tau_min, tau_max).grid(GREEDY_GRID))
    past = np.full((R, d), tau_max)  # the packets sent before t_0
    xi = boundary.x0.copy()
    xs, Vs = [xi], [boundary.V(xi)]
    for _ in range(min(periods, 60)):
        best_V = np.full(R, -np.inf)
        best_xi, best_tau = xi.copy(), np.zeros(R)
        for tau in grid:
            s_k = s_tilde_sequence(np.concatenate([past, np.full((R, 1), tau)], axis=1), Ts, d)[:, 0]
            nxt = boundary.step(np.einsum("rij,rj->ri", exact_closed_loop(A, B, K, Ts, s_k), xi), worst_dir=True)
            Vn = boundary.V(nxt)
            better = Vn > best_V
            best_V = np.where(better, Vn, best_V)
            best_xi = np.where(better[:, None], nxt, best_xi)
            best_tau = np.where(better, tau, best_tau)
        past = np.concatenate([past[:, 1:], best_tau[:, None]], axis=1)
        xi = best_xi
        xs.append(xi)
        Vs.append(best_V)
    boundary.record("greedy-adversary", np.array(Vs).T, np.array(xs).transpose(1, 0, 2), Vs[0])


def _l2_gain_check(plant: dict, K: np.ndarray, Ts: float, tau_min: float, tau_max: float, m_lost: int, d: int,
                   gamma: float, rng: np.random.Generator) -> dict[str, Any]:
    """hinf: for each delay sequence of the families, the exact finite-horizon l2 gain from the
    disturbance held over each period (w_k) to z_k = C x_k, from rest: the largest singular value
    of the map (w_0..w_{N-1}) -> (z_1..z_N), which must be <= gamma (the certificate covers any w(t)
    with sup over period k of ||w|| in place of |w_k|)."""
    from ..core.delays import exact_closed_loop, gamma as gamma_fn, lifted_rows

    A, B = plant["A"], plant["B"]
    n = A.shape[0]
    n_s = K.shape[1]
    C = lifted_rows(plant["C"], n_s)
    p = C.shape[0]
    D = np.zeros((n_s, plant["E"].shape[1]))
    D[:n] = gamma_fn(A, plant["E"], Ts)
    q = D.shape[1]
    N = HINF_PERIODS
    worst, where = 0.0, ""
    for name, seq in Network(Ts, tau_min, tau_max, m_lost).families(rng, HINF_RUNS, N + d + m_lost + 1).items():
        M = exact_closed_loop(A, B, K, Ts, s_tilde_sequence(seq, Ts, d)[:, :N])
        for r in range(HINF_RUNS):
            T = np.zeros((N * p, N * q))
            resp = np.zeros((N, n_s, q))  # resp[j]: the state response to w_j, propagated
            for k in range(N):  # x_{k+1} = M_k x_k + D w_k
                resp[:k] = M[r, k] @ resp[:k]
                resp[k] = D
                T[k * p : (k + 1) * p, : (k + 1) * q] = (C @ resp[: k + 1]).transpose(1, 0, 2).reshape(p, -1)
            g = float(np.linalg.norm(T, 2)) if np.all(np.isfinite(T)) else np.inf
            if g > worst:
                worst, where = g, name
    return Check("l2 gain of the exact loop (max over delay sequences / certified)", worst <= gamma * (1.0 + TOL),
                 worst / gamma, 1.0, f"worst {worst:.6g} ({where}) vs certified {gamma:.6g}; {N} periods from rest").to_dict()


def checked_gain(plant: Any, gains: Any, where: str = "gains") -> np.ndarray:
    """K of a linear plant's gains mapping (``kind: lti``, or a K of one's own with no certificate), checked for
    ``plant``: one InputError line naming ``where`` for the robot's gains, a gain made for a plant of other sizes,
    or a K that is not an m x n or m x (n + d m) matrix of numbers."""
    from ..artifacts.gains import same_plant
    from ..core.delays import check_lti_gain
    from ..errors import InputError

    if gains.get("kind") != "lti" and (gains.get("kind") is not None or gains.get("certificate") is not None):
        raise InputError(f"{where}: not a linear plant's gains file (kind: lti, with certificate.P; its certificate is "
                         "another kind's): run `robustsynth synthesize` on this config, or give a gains file with K only")
    same_plant(dict(gains), plant.n_x, plant.n_u, where)
    try:
        K = np.asarray(gains["K"], dtype=float)
    except (TypeError, ValueError, KeyError) as exc:
        raise InputError(f"{where}: K: missing or not a matrix of numbers ({exc})") from None
    check_lti_gain(K, plant.n_x, plant.n_u, f"{where}: K")
    return K


def certified_gain(plant: Any, gains: Any, where: str = "gains") -> tuple[np.ndarray, np.ndarray, Any, dict, int]:
    """(K, P, the multipliers, the figures, the pieces) of a linear plant's certified gain, from the
    :class:`~robustsynth.synthesis.SynthesisResult` ``robustsynth.synthesize(plant)`` returns or from its gains
    mapping (``kind: lti``, :func:`checked_gain`).  One InputError line naming ``where`` for anything else: a
    malformed certificate, a certificate for a disturbance or outputs the plant does not have, or a gain without
    its certificate (``robustsynth verify CONFIG --gains FILE`` searches one for it)."""
    from collections.abc import Mapping

    from ..errors import InputError

    arrays = plant.arrays
    if getattr(gains, "plant_kind", None) == "lti":
        cert = gains.certificate
        return gains.K, gains.P, cert["multipliers"], gains.certified, int(cert["pieces"])
    if not isinstance(gains, Mapping):
        raise InputError(f"verify: a linear plant's gain is the SynthesisResult robustsynth.synthesize(plant) returns, "
                         f"or its gains mapping (kind: lti); got {type(gains).__name__}")
    K = checked_gain(plant, gains, where)
    cert = gains.get("certificate")
    if cert is None:
        raise InputError(f"{where}: a gain without its certificate: `robustsynth verify CONFIG --gains FILE` searches "
                         "one for it (robustsynth.verify takes a certified gain)")
    try:
        P = np.asarray(cert["P"], dtype=float)
        figures = dict(gains["certified"])
        float(figures["alpha"])
        eps, pieces = np.asarray(cert["multipliers"], dtype=float), int(cert["pieces"])
    except (TypeError, ValueError, KeyError) as exc:
        raise InputError(f"{where}: certificate: malformed ({exc})") from None
    if (figures.get("disturbance_step_bound") is not None or figures.get("hinf_gain") is not None) \
            and arrays.get("E") is None:
        raise InputError("plant.disturbance: the gain's certificate is for a disturbance input (ultimate-bound or "
                         "hinf); this config has none")
    outs = [o.get("name") for o in figures.get("outputs") or ()]
    if outs and outs != list(arrays["outputs"]):
        raise InputError(f"plant.outputs: {list(arrays['outputs'])} differ from the outputs the gain was certified "
                         f"for ({outs})")
    return K, P, eps, figures, pieces


def verify_plant(plant: Any, gains: Any, runs: int | None = None, seed: int | None = None, where: str = "gains"
                 ) -> Verdict:
    """``robustsynth.verify`` on a LinearPlant: the certified gain (:func:`certified_gain`, its problems naming
    ``where``) checked on the exactly lifted loop (:func:`verify_lti`; ``runs`` per family, default 64; ``seed``
    default 0)."""
    K, P, eps, figures, pieces = certified_gain(plant, gains, where)
    net = plant.network
    return Verdict.from_dict(verify_lti(plant.arrays, K, P, net.sampling_time, net.delay_min, net.delay_max,
                                        net.max_lost, figures, runs=64 if runs is None else runs,
                                        seed=0 if seed is None else seed, multipliers=eps, pieces=pieces))


def verify_linear(plant: Any, gains: Any, runs: int | None = None, seed: int | None = None,
                  progress: Callable[[int, int], None] | None = None) -> Verdict:
    """The linear plant's verifier (``robustsynth.verify``'s, :data:`robustsynth.verification.checks.VERIFIERS`): a
    design, a gains mapping or a gains file (read here, named in its problems), verified by :func:`verify_plant`."""
    from pathlib import Path

    from ..artifacts.gains import load_gains

    if isinstance(gains, (str, Path)):
        return verify_plant(plant, load_gains(gains), runs, seed, where=str(gains))
    return verify_plant(plant, gains, runs, seed)
