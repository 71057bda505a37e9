"""The proof checker of a linear plant's certificate (``plant: kind: lti``; docs/theory.md §14, §15):
the vertex blocks of the over-approximation rebuilt in numpy and proven negative definite in verified
arithmetic, the output bounds and input limits proven on the set, and a gains file re-proven whole."""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from ..results import CertificateCheck
from ..verified import (assembly_radius, assembly_radius_batch, proves_at_least, proves_at_least_batch,
                       round_down_array, round_up)

__all__ = ["lti_multipliers", "lti_vertex_blocks", "LTI_PROOF_MARGIN", "check_lti_certificate", "check_lti_scaled",
           "lti_within", "recheck_lti", "lti_check"]


def lti_multipliers(pw: Any, eps: np.ndarray, n_c: int) -> tuple[np.ndarray, bool] | None:
    """The multipliers of an lti certificate as (n_c, d, 1 + n) and whether they are directional: the
    synthesis' full-block form (n_c, d) (channels E, one multiplier per instant), or the analysis' (n_c, d,
    1 + n) (channels E U_j: per instant the full block, then one per direction of ``pw.dirs``).  None when
    the shape is neither."""
    eps = np.asarray(eps, dtype=float)
    d, n = pw.d_hi, pw.E.shape[1]
    if eps.shape == (n_c, d):
        return np.concatenate([eps[..., None], np.zeros((n_c, d, n))], axis=-1), False
    if eps.shape == (n_c, d, 1 + n) and pw.dirs is not None:
        return eps, True
    return None


def lti_vertex_blocks(pw: Any, P: np.ndarray, eps: np.ndarray, decay: float, verts: tuple,
                      dist: float | None = None, out: np.ndarray | None = None, merge: bool = True
                      ) -> tuple[np.ndarray, np.ndarray, int]:
    """The robust-stability blocks of an lti certificate (docs/theory.md §14), one per vertex, as
    floats, with their magnitudes (the same formula on absolute values) and the number of terms per
    entry: ``-[[M' P M - decay^2 P + sum_j (eps_j0 rho_j^2 + sum_l eps_jl rho_jl^2) F_j' F_j, M' P E~],
    [E~' P M, E~' P E~ - diag_j(eps_j0 I + diag_l eps_jl)]]`` for every vertex of ``verts`` = (combos
    (n_c, d), owner (n_v,), fractions (n_v, d)) (:func:`robustsynth.core.delays.vertex_combinations`);
    E~ = [E U_0, ..., E U_d-1] over the kept directions (:func:`robustsynth.core.delays.kept_directions`; the
    dropped ones by Young's inequality: decay^2 / (1 + YOUNG_DELTA) and a term pbar n_drop / YOUNG_DELTA
    rho_D^2 F' F, pbar a bound on lambda_max(P)); E alone for the full-block multipliers (n_c, d).
    Instants with equal channels share one (:func:`robustsynth.core.delays.channel_groups`; ``merge=False``:
    one per instant): their remainders enter as one sum W = sum_j w_j, and the shared channel's diagonal is
    the parallel sum of their multipliers ``(sum_j (eps_j0 + eps_jl)^-1)^-1`` per direction, rounded down
    (:func:`_parallel_sum_down`), the least that ``sum_j w_j' D_j w_j`` takes over the splits of W: sound for
    any multipliers, and exactly as tight as a channel per instant (without the proof margin, the two blocks
    are negative definite together when every multiplier is positive; docs/theory.md §14).
    With ``dist`` = c, a disturbance d (|d| <= 1) enters the plant's rows too: E~ gains a block E and the
    diagonal c I (docs/theory.md §15: V+ <= decay^2 V + c |d|^2 for every admissible step).  With ``out`` =
    C the top block gains C' C (hinf: V+ - V + |C xi|^2 <= c |d|^2)."""
    P = np.asarray(P, dtype=float)
    combos, owner, frac = verts
    d = pw.d_hi
    n_s, n = pw.E.shape
    lam, directional = lti_multipliers(pw, eps, len(combos))
    if directional:  # the rounding-level directions are no channel: Young's inequality covers them
        from ..core.delays import YOUNG_DELTA, channel_groups, kept_directions

        kept, dropped = kept_directions(pw)
        groups = channel_groups(pw, kept) if merge else [[j] for j in range(d) if len(kept[j])]
        chans = [pw.channels(g[0])[:, kept[g[0]]] for g in groups]
        n_drop = sum(len(kj) < n for kj in kept)
        # V(y + r) <= (1 + delta) V(y) + (1 + 1/delta) pbar |r|^2, |r|^2 <= n_drop sum_j rho_Dj^2 |F_j xi|^2:
        # the kept LMI with decay^2 / (1 + delta) and pbar n_drop / delta rho_Dj^2 F_j' F_j (pbar >= lambda_max(P))
        pbar = round_up(float(np.max(np.sum(np.abs(P), axis=1))), n_s)  # Gershgorin: a row's sum of n_s terms
        penalty = pbar * n_drop / YOUNG_DELTA if n_drop else 0.0
        shrink = 1.0 / (1.0 + YOUNG_DELTA) if n_drop else 1.0
    else:
        kept = [np.arange(n)] * d
        groups = [[j] for j in range(d)]
        chans = [pw.E] * d
        dropped, penalty, shrink = None, 0.0, 1.0
    Et = np.hstack(chans + ([pw.E] if dist is not None else []))  # (n_s, sum of the channels) (+ n)
    Et_abs = np.abs(Et)
    FF = [pw.F[j].T @ pw.F[j] for j in range(d)]
    FF_abs = [np.abs(pw.F[j]).T @ np.abs(pw.F[j]) for j in range(d)]
    low0 = Et.T @ P @ Et
    low0_abs = Et_abs.T @ np.abs(P) @ Et_abs
    blocks, mags = [], []
    for c, end in zip(owner, frac):
        combo = combos[c]
        M, Mabs = pw.vertex(combo, end), pw.vertex(combo, end, absolute=True)
        top = M.T @ P @ M - decay**2 * shrink * P
        top_abs = Mabs.T @ np.abs(P) @ Mabs + decay**2 * shrink * np.abs(P)
        if out is not None:
            top = top + out.T @ out
            top_abs = top_abs + np.abs(out).T @ np.abs(out)
        for j in range(d):
            i = combo[j]
            r2 = lam[c, j, 0] * float(pw.rho[j][i]) ** 2
            if directional:
                r2 = r2 + float(np.dot(lam[c, j, 1 + kept[j]], pw.rho_dir[j][i, kept[j]] ** 2))
                r2 = r2 + penalty * float(dropped[j][i]) ** 2
            top = top + r2 * FF[j]
            top_abs = top_abs + abs(r2) * FF_abs[j]
        # a group's channel carries the sum W of its instants' remainders w_j: every split of W costs at least
        # W' H W, H the parallel sum of their multipliers per direction (a lower bound: the block is then no
        # more negative than the exact one); an instant of its own keeps eps_j0 + eps_jl (the assembly radius)
        diag = [lam[c, g[0], 0] + lam[c, g[0], 1 + kept[g[0]]] if len(g) == 1 else
                _parallel_sum_down(np.stack([np.maximum(round_down_array(lam[c, j, 0] + lam[c, j, 1 + kept[j]]), 0.0)
                                             for j in g], axis=-1)) for g in groups]
        if dist is not None:
            diag.append(np.full(n, dist))
        diag = np.concatenate(diag)
        off = M.T @ P @ Et
        off_abs = Mabs.T @ np.abs(P) @ Et_abs
        low = low0 - np.diag(diag)
        low_abs = low0_abs + np.diag(np.abs(diag))
        X = np.block([[top, off], [off.T, low]])
        Xa = np.block([[top_abs, off_abs], [off_abs.T, low_abs]])
        blocks.append(-(X + X.T) / 2.0)
        mags.append(Xa)
    # the longest sum of products behind an entry, generously: M itself is a sum of d + 1 products,
    # M' P M sums n_s^2 of those, the multiplier terms add d (1 + n) (each a sum of 1 + n products), the
    # symmetrization one (E U_j is exact: E selects rows)
    terms = (n_s * n_s * (2 * d + 3) + 2 * d * (n + 2) + 4 + (2 if dist is not None else 0)
             + (0 if out is None else out.shape[0] + 1))  # C' C: a sum of p products
    return np.array(blocks), np.array(mags), terms


PARALLEL_SUM_RANGE = 1e300  # _parallel_sum_down: terms and results within [1 / this, this] stay normal floats


def _parallel_sum_down(a: np.ndarray) -> np.ndarray:
    """A lower bound of the parallel sum ``H = (sum_j 1 / a_j)^-1`` of the exact values of the floats ``a_j >= 0``
    along the last axis (g of them): the float result less its rounding, g + 1 roundings (g reciprocals, g - 1
    additions of positive terms, the last reciprocal: a relative error below (g + 1) u + O(u^2)).  0, which
    needs no rounding model, where some a_j is 0 (H = 0) or where a term or the result leaves
    [1 / PARALLEL_SUM_RANGE, PARALLEL_SUM_RANGE] (a subnormal reciprocal's error is not relative)."""
    a = np.asarray(a, dtype=float)
    g = a.shape[-1]
    with np.errstate(divide="ignore", over="ignore", under="ignore"):
        h = 1.0 / np.sum(1.0 / a, axis=-1)
    normal = (np.all((a >= 1.0 / PARALLEL_SUM_RANGE) & (a <= PARALLEL_SUM_RANGE), axis=-1)
              & (h >= 1.0 / PARALLEL_SUM_RANGE) & (h <= PARALLEL_SUM_RANGE))
    return np.where(normal, np.maximum(round_down_array(np.where(normal, h, 0.0), g + 1), 0.0), 0.0)


LTI_PROOF_MARGIN = 1e-8  # every vertex block is proven <= -this (I): room for the data's own rounding


def check_lti_certificate(pw: Any, P: np.ndarray, eps: np.ndarray, decay: float, verts: tuple,
                          dist: float | None = None, out: np.ndarray | None = None, merge: bool = True) -> dict[str, Any]:
    """The lti certificate re-checked in numpy: P proven positive definite and every vertex block
    proven <= -LTI_PROOF_MARGIN I in verified arithmetic (Rump's test, with the blocks' assembly error
    as a radius); the multipliers >= 0 and of a shape :func:`lti_multipliers` reads.  The data (the
    pieces from expm, the remainder bounds, the directions' orthonormality) are taken as computed: the
    margin, not a proof, covers their rounding (docs/theory.md §14).  ``merge``: instants with equal channels
    share one (:func:`lti_vertex_blocks`; False: a channel per instant, the check before issue 53's grouping).
    Returns {"ok", "failing", "vertices", "min_eig"}."""
    P = np.asarray(P, dtype=float)
    P = (P + P.T) / 2.0
    eps = np.asarray(eps, dtype=float)
    if dist is not None and not (math.isfinite(dist) and dist > 0):
        return {"ok": False, "failing": -1, "vertices": 0, "min_eig": float("nan")}
    if (not np.all(np.isfinite(P)) or not np.all(np.isfinite(eps)) or np.any(eps < 0)
            or lti_multipliers(pw, eps, len(verts[0])) is None):
        return {"ok": False, "failing": -1, "vertices": 0, "min_eig": float("nan")}
    if not proves_at_least(P, 0.0, assembly_radius(np.abs(P), 1)):
        return {"ok": False, "failing": -1, "vertices": 0, "min_eig": float(np.min(np.linalg.eigvalsh(P)))}
    blocks, mags, terms = lti_vertex_blocks(pw, P, eps, decay, verts, dist, out, merge)
    radius = assembly_radius_batch(mags, terms)
    ok = proves_at_least_batch(blocks, LTI_PROOF_MARGIN, radius)
    failing = np.flatnonzero(~ok)
    return {"ok": bool(ok.all()), "failing": int(failing[0]) if failing.size else None, "vertices": int(len(blocks)),
            "min_eig": float(np.min(np.linalg.eigvalsh(blocks)))}


def check_lti_scaled(pw: Any, P: np.ndarray, eps: np.ndarray, decay: float, verts: tuple,
                     dist: float | None = None, out: np.ndarray | None = None) -> dict[str, Any]:
    """:func:`check_lti_certificate` of a certificate of any scale: ``V+ <= decay^2 V + c |d|^2 (- |C xi|^2)``
    is homogeneous in (P, eps, c, C'C), so it is checked for s P with s = 1 / lambda_min(P) (P >= I, the
    scale the proof margin is meant for), which proves it for P."""
    P = np.asarray(P, dtype=float)
    lam = float(np.min(np.linalg.eigvalsh((P + P.T) / 2.0))) if np.all(np.isfinite(P)) else float("nan")
    if not lam > 0:
        return {"ok": False, "failing": -1, "vertices": 0, "min_eig": lam}
    s = 1.0 / lam
    return check_lti_certificate(pw, s * P, s * np.asarray(eps, dtype=float), decay, verts,
                                 None if dist is None else s * dist, None if out is None else np.sqrt(s) * out)


def lti_within(P: np.ndarray, rows: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Per row r_i: proven ``|r_i xi| <= bounds[i]`` on {xi' P xi <= 1}, i.e. ``P - r_i' r_i / b_i^2 >= 0``
    in verified arithmetic (the bound's square and quotient rounded with the assembly)."""
    P = (np.asarray(P, dtype=float) + np.asarray(P, dtype=float).T) / 2.0
    out = []
    for r, b in zip(np.atleast_2d(rows), np.asarray(bounds, dtype=float)):
        if not (math.isfinite(b) and b > 0):
            out.append(False)
            continue
        R = np.outer(r, r) / (b * b)
        L = P - R
        out.append(proves_at_least(L, 0.0, assembly_radius(np.abs(P) + np.abs(R), 3)))
    return np.array(out, dtype=bool)


def recheck_lti(plant: dict, gains: Mapping[str, Any], Ts: float, tau_min: float, tau_max: float,
                m_lost: int) -> CertificateCheck:
    """A linear plant's gains file re-proven from its own numbers (K, P, multipliers, alpha, figures)
    against this plant and network: the vertex blocks of the over-approximation built for K (with
    the disturbance or the l2 gain's terms) and every output bound and input limit on the set.
    Returns the CertificateCheck every plant's certificate check is: failed with the reason where the file is
    malformed or for another lifting, where a vertex block or a figure is not proven."""
    from ..core.delays import disturbance_bound, lifted_rows, lti_depth, over_approximation, vertex_combinations

    try:
        K = np.asarray(gains["K"], dtype=float)
        cert, figs = gains["certificate"], gains["certified"]
        P = np.asarray(cert["P"], dtype=float)
        eps = np.asarray(cert["multipliers"], dtype=float)
        alpha = float(cert["alpha"])
        pieces = int(cert["pieces"])
    except (KeyError, TypeError, ValueError) as exc:
        return CertificateCheck(False, (), {}, f"malformed certificate ({exc})")
    A, B = plant["A"], plant["B"]
    n, m = B.shape
    d = (K.shape[1] - n) // m
    if d < lti_depth(tau_max, m_lost, Ts) or P.shape != (K.shape[1],) * 2:
        return CertificateCheck(False, (), {}, f"the gain keeps {d} commands; delays up to {tau_max + m_lost * Ts:g} s "
                                                f"need {lti_depth(tau_max, m_lost, Ts)}")
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(K)) and np.all(np.isfinite(eps))):
        return CertificateCheck(False, (), {}, "non-finite entries")
    if not float(np.min(np.linalg.eigvalsh((P + P.T) / 2.0))) > 0:
        return CertificateCheck(False, (), {}, "P is not positive definite")
    C = lifted_rows(plant["C"], K.shape[1])
    dist = out = None
    if figs.get("hinf_gain") is not None:
        dist, out = float(figs["hinf_gain"]) ** 2 / disturbance_bound(A, plant["E"], 1.0, Ts) ** 2, C
    elif figs.get("disturbance_step_bound") is not None:
        dist = (1.0 - alpha) / disturbance_bound(A, plant["E"], plant["w_max"], Ts) ** 2
    pw = over_approximation(A, B, K, Ts, tau_min, tau_max + m_lost * Ts, d, pieces)
    verts = vertex_combinations(pw)
    if lti_multipliers(pw, eps, len(verts[0])) is None:
        n_c, n = len(verts[0]), B.shape[0]
        return CertificateCheck(False, (), {}, f"multipliers {eps.shape}, the vertices need ({n_c}, {d}) or ({n_c}, {d}, "
                                                f"{1 + n})")
    chk = lti_check(check_lti_scaled(pw, P, eps, float(np.sqrt(alpha)), verts, dist, out), figs)
    if not chk.passed:
        return CertificateCheck(False, chk.checks, {}, f"{chk.reason} (min eigenvalue {chk.checks[0]['margin_found']:.3g})")
    outs = [o for o in figs.get("outputs") or () if o.get("bound") is not None]
    if outs and not lti_within(P, C, np.array([o["bound"] for o in outs])).all():
        return CertificateCheck(False, (), {}, "an output bound is not proven on the set")
    if figs.get("inputs") and not lti_within(P, K, np.array([u["limit"] for u in figs["inputs"]])).all():
        return CertificateCheck(False, (), {}, "an input limit is not proven on the set")
    return chk


def lti_check(record: Mapping[str, Any], figures: Mapping[str, Any]) -> CertificateCheck:
    """:func:`check_lti_certificate`'s record ({"ok", "failing", "vertices", "min_eig"}) as the certificate check
    every plant's result holds: one family, the vertex blocks proven >= LTI_PROOF_MARGIN I in verified arithmetic
    (the smallest eigenvalue over the blocks is its margin found), with the figures the design proved beside it
    (the output bounds, the rest ball and the input limits are proven on the set before a design is certified)."""
    from .check import _item

    ok, failing = bool(record.get("ok")), record.get("failing")
    item = _item(f"V+ <= alpha V (+ 1 - alpha) at the {int(record.get('vertices') or 0)} vertex blocks of the "
                 "over-approximation", float(record.get("min_eig", float("nan"))), LTI_PROOF_MARGIN,
                 f"vertex block {failing}" if failing is not None and failing >= 0 else "", verified=ok)
    reason = "" if ok else (f"vertex block {failing} not proven" if failing is not None and failing >= 0
                            else "the certificate is malformed or P is not positive definite")
    return CertificateCheck(ok and item["passed"], (item,), dict(figures), reason)
