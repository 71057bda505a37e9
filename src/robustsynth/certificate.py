"""Independent, numpy-only re-check of an LMI certificate (docs/theory.md §6).

The LMIs are rebuilt at every vertex of the model from the certificate's values (``Q`` or
``G, S_m``, the multipliers ``M_i``, ``beta``, ``alpha`` / ``r2`` / ``gamma2``) and the gain ``K``
*as written* (``Y = K Q`` or ``Y = K G``), never from the solver's internal variables; each must
be proven ``>= threshold I`` in verified arithmetic (:mod:`robustsynth.verified`).
The certified figures (decay rate, ellipsoid bounds in m and rad, motor-speed bound in rad/s,
l2 gain) are computed here from the same values, so every number written as certified has
passed this check; they are rounded outwards.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from .verified import (assembly_radius, assembly_radius_batch, gamma, proves_at_least, proves_at_least_batch, round_down_array,
                       round_up, rump_shift, rump_shift_batch)

__all__ = [
    "CHECK_FRACTION",
    "VARYING_FAILURES",
    "varying_failures",
    "CertificateCheck",
    "check_certificate",
    "recheck_gains",
    "lmi_stability",
    "lmi_invariance",
    "lmi_hinf",
    "multiplier_structure_error",
    "Lyapunov",
    "lyapunov_of",
    "heading_within_period",
    "between_samples",
    "sup_on_set",
    "set_max",
    "turn_bounds",
    "TURN_REENTRY",
]

# A certificate passes when every LMI satisfies  lambda_min >= CHECK_FRACTION * margin,
# i.e. it keeps at least this fraction of the margin it was solved with.
CHECK_FRACTION = 0.5
# the key of the within-period family's item that lists its failing vertices (indices into Model.varying)
VARYING_FAILURES = "failing_vertices"
SYMMETRY_TOL = 1e-9  # relative asymmetry allowed in Q and M read from a file


@dataclass(frozen=True)
class CertificateCheck:
    passed: bool
    checks: tuple[dict[str, Any], ...]
    figures: dict[str, Any] = field(default_factory=dict)
    reason: str = ""

    @property
    def min_eig_margin(self) -> float:
        """Smallest margin lambda_min(L) over the LMIs (the margin actually found)."""
        vals = [c["margin_found"] for c in self.checks if c.get("margin_found") is not None]
        return float(min(vals)) if vals else float("nan")


def _T(X: np.ndarray) -> np.ndarray:
    """Transpose of a matrix or of every matrix of a stack."""
    return np.swapaxes(X, -1, -2)


def _sym(X: np.ndarray) -> np.ndarray:
    return (X + _T(X)) / 2.0


def _block(rows: list[list[Any]]) -> np.ndarray:
    """``np.block`` for blocks that may be stacks (..., r, c): the others are broadcast to the stack."""
    batch = np.broadcast_shapes(*[np.shape(b)[:-2] for row in rows for b in row])
    if not batch:
        return np.block(rows)
    full = lambda b: np.broadcast_to(b, batch + np.shape(b)[-2:])  # noqa: E731
    return np.concatenate([np.concatenate([full(b) for b in row], axis=-1) for row in rows], axis=-2)


def _minus(a, b, mag: bool):
    """a - b, or a + b for the magnitude of a formula (see :func:`robustsynth.verified.assembly_radius`)."""
    return a + b if mag else a - b


# The LMIs below take one vertex and its multiplier, or a stack of vertices and of their multipliers
# (their matrices (n, ., .)); they return the matrix, or the stack of matrices, to prove >= threshold I.


def lmi_stability(v, X, left, right, Y, M, r2, mag: bool = False):
    """Vertex v: [[r2 left, (A X + B Y)', (C_q X + D_q Y)'], [A X + B Y, right - B_p M B_p', 0],
    [C_q X + D_q Y, 0, M]] (>= 0 certifies V(xi+) <= r^2 V(xi) at the vertex; docs/theory.md §6a).
    ``mag``: the inputs are absolute values and the subtraction is an addition (the magnitude)."""
    AX = v.A @ X + v.B @ Y
    n_s, n_q = X.shape[0], v.B_p.shape[-1]
    if n_q == 0:
        return _sym(_block([[r2 * left, _T(AX)], [AX, right]]))
    CX = v.C_q @ X + v.D_q @ Y
    Z = np.zeros((n_s, n_q))
    return _sym(_block([[r2 * left, _T(AX), _T(CX)], [AX, _minus(right, v.B_p @ M @ _T(v.B_p), mag), Z], [CX, Z.T, M]]))


def lmi_invariance(v, X, left, right, Y, M, beta, alpha, mag: bool = False):
    """Vertex v: V(xi+) <= (1-alpha) V(xi) + sum beta_i w_i^2 for all |Delta| <= 1 (docs/theory.md §6b), as

    [[(1-alpha) left, 0, (AX+BY)', (C_qX+D_qY)'], [0, diag(beta), E', F_q'],
     [AX+BY, E, right - B_p M B_p', 0], [C_qX+D_qY, F_q, 0, M]] >= 0."""
    AX = v.A @ X + v.B @ Y
    n_s, n_q, n_w = X.shape[0], v.B_p.shape[-1], v.E.shape[-1]
    Zsw = np.zeros((n_s, n_w))
    rows = [
        [(1.0 - alpha) * left, Zsw, _T(AX)],
        [Zsw.T, np.diag(beta), _T(v.E)],
        [AX, v.E, _minus(right, v.B_p @ M @ _T(v.B_p), mag) if n_q else right],
    ]
    if n_q:
        CX = v.C_q @ X + v.D_q @ Y
        F = v.F  # q = C_q xi + D_q du + F_q w
        rows[0].append(_T(CX))
        rows[1].append(_T(F))
        rows[2].append(np.zeros((n_s, n_q)))
        rows.append([CX, F, np.zeros((n_q, n_s)), M])
    return _sym(_block(rows))


def lmi_hinf(v, Bd, Cz, Q, Y, M, gamma2, mag: bool = False):
    """Bounded-real LMI at vertex v (docs/theory.md §6d):
    [[Q, 0, (AQ+BY)', (Cz Q)', (C_qQ+D_qY)'], [0, g I, Bd', 0, 0],
     [AQ+BY, Bd, Q - B_p M B_p', 0, 0], [Cz Q, 0, 0, I, 0], [C_qQ+D_qY, 0, 0, 0, M]] >= 0."""
    AQ = v.A @ Q + v.B @ Y
    CzQ = Cz @ Q
    n_s, n_q, n_d, n_z = Q.shape[0], v.B_p.shape[-1], Bd.shape[1], Cz.shape[0]
    Z = np.zeros
    rows = [
        [Q, Z((n_s, n_d)), _T(AQ), CzQ.T],
        [Z((n_d, n_s)), gamma2 * np.eye(n_d), Bd.T, Z((n_d, n_z))],
        [AQ, Bd, _minus(Q, v.B_p @ M @ v.B_p.T, mag) if n_q else Q, Z((n_s, n_z))],
        [CzQ, Z((n_z, n_d)), Z((n_z, n_s)), np.eye(n_z)],
    ]
    if n_q:
        CQ = v.C_q @ Q + v.D_q @ Y
        rows[0].append(CQ.T)
        rows[1].append(Z((n_d, n_q)))
        rows[2].append(Z((n_s, n_q)))
        rows[3].append(Z((n_z, n_q)))
        rows.append([CQ, Z((n_q, n_d)), Z((n_q, n_s)), Z((n_q, n_z)), M])
    return _sym(_block(rows))


def multiplier_structure_error(M: np.ndarray, n_blocks: int, kind: str, diagonal: bool = False) -> str:
    """'' when M has the structure the S-procedure needs for Delta = blockdiag(d1 I2, d2, ...), or for a
    diagonal Delta of independent scalars (``diagonal``: M must be diagonal)."""
    if diagonal:
        if M.ndim != 2 or M.shape[0] != M.shape[1]:
            return f"multiplier has shape {M.shape}, expected a square diagonal matrix"
        if np.any(M[~np.eye(M.shape[0], dtype=bool)] != 0.0):
            return "multiplier of independent scalar channels must be diagonal (the S-procedure would not hold)"
        return ""
    n = 3 * n_blocks
    if M.shape != (n, n):
        return f"multiplier has shape {M.shape}, expected {(n, n)}"
    allowed = np.zeros((n, n), dtype=bool)
    for b in range(n_blocks):
        allowed[3 * b : 3 * b + 2, 3 * b : 3 * b + 2] = True
        allowed[3 * b + 2, 3 * b + 2] = True
    if np.any(M[~allowed] != 0.0):
        return "multiplier has entries outside the blocks of Delta (the S-procedure would not hold)"
    if kind == "full" and n and not np.allclose(M, M[0, 0] * np.eye(n), rtol=0, atol=0):
        return "a 'full' multiplier must be mu * I"
    return ""


def _arr(x: Any, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"certificate.{name} has non-finite entries")
    return a


def _symmetric(X: np.ndarray, name: str) -> str:
    scale = max(1.0, float(np.max(np.abs(X), initial=0.0)))
    if X.ndim != 2 or X.shape[0] != X.shape[1]:
        return f"{name} is not square"
    if np.max(np.abs(X - X.T), initial=0.0) > SYMMETRY_TOL * scale:
        return f"{name} is not symmetric"
    return ""


def _item(name: str, lam_min: float, threshold: float, worst: str = "", verified: bool = True,
          allowance: float = 0.0, unproven: str = "") -> dict[str, Any]:
    """One family of conditions 'lambda_min(L) >= threshold' (reported in the 'largest eigenvalue of
    -L' form).  ``lam_min`` is the floating-point judgement (eigvalsh, the smallest over the family);
    ``verified`` whether every member was proven in verified arithmetic (:func:`robustsynth.verified.
    proves_at_least`), ``allowance`` the largest rounding allowance it had to add to the threshold,
    ``unproven`` the first member that passed in floating point but could not be proven."""
    float_ok = bool(lam_min >= threshold)
    out = {
        "name": name,
        "max_eig": float(-lam_min),
        "threshold": float(-threshold),
        "margin_found": float(lam_min),
        "passed": bool(float_ok and verified),
        "verified": bool(verified),
        "test": VERIFIED_TEST,
        "rounding_allowance": float(allowance),
    }
    if worst:
        out["worst"] = worst
    if float_ok and not verified:
        out["status"] = "not proven (rounding)"
        out["unproven"] = unproven
    return out


VERIFIED_TEST = ("floating-point Cholesky of L - (threshold + assembly radius + Rump shift) I (Rump, BIT 46, 2006)")


def _proof(L: np.ndarray, mag: np.ndarray | None, terms: int, threshold: float) -> tuple[bool, float]:
    """(proven, allowance): L >= threshold I for the exactly assembled matrix, whose float version
    is L with the magnitude ``mag`` of its formula (None: L is data, no assembly error)."""
    if mag is None and np.any(L != L.T):  # data read from a file may be symmetric to SYMMETRY_TOL only:
        L, mag, terms = _sym(L), np.abs(L), 1  # prove its symmetric part (the part a quadratic form sees)
    radius = 0.0 if mag is None else assembly_radius(mag, terms)
    return proves_at_least(L, threshold, radius), radius + rump_shift(np.maximum(np.abs(np.diag(L)), 1e-300))


def recheck_gains(model: Any, gains: Mapping[str, Any]) -> CertificateCheck:
    """A gains mapping's certificate re-checked for ``model`` (failed, with its reason, when the mapping has
    none or K does not fit the model): what ``validate`` judges against and what ``export`` calls certified,
    rather than the figures a file states."""
    K = np.asarray(gains["K"], dtype=float)
    if K.shape != (model.n_u, model.n_s):
        return CertificateCheck(False, (), {}, f"K has shape {K.shape}, this config's model needs {(model.n_u, model.n_s)}")
    cert = gains.get("certificate")
    if not isinstance(cert, Mapping):
        return CertificateCheck(False, (), {}, "the gains file has no certificate (a bare K): nothing certified to "
                                "validate against; robustsynth verify searches one for a fixed K")
    chk = check_certificate(model, K, cert)
    return chk if chk.passed else CertificateCheck(False, chk.checks, chk.figures,
                                                   chk.reason or "the certificate does not hold for this config")


def check_certificate(model: Any, K: np.ndarray, cert: Mapping[str, Any]) -> CertificateCheck:
    """Re-check ``cert`` for gain ``K`` on ``model``; never raises on a bad certificate.

    Parameters
    ----------
    model : Model
        The model the certificate is claimed for.
    K : numpy.ndarray
        The gain.
    cert : Mapping
        The certificate (``gains.json``'s ``certificate``, or a ``SynthesisResult``'s).

    Returns
    -------
    CertificateCheck
        Whether every LMI holds with half its margin, each check, and the figures it proves.
    """
    try:
        return _check(model, K, cert)
    except (KeyError, ValueError, TypeError, IndexError, np.linalg.LinAlgError) as exc:
        return CertificateCheck(False, (), {}, f"certificate unreadable: {exc}")


def _fail(reason: str, checks=(), figures=None) -> CertificateCheck:
    return CertificateCheck(False, tuple(checks), figures or {}, reason)


def _lyapunov_parts(model: Any, cert: Mapping[str, Any], n_s: int):
    """(kind, X, conditions, mats) from the certificate, or a reason string: ``conditions[i]`` lists
    vertex i's (left block, right block, label, |left| magnitude, |right| magnitude)
    (``Model.lyapunov_conditions``; the magnitudes bound the blocks' own rounding), ``mats`` the
    Lyapunov matrices."""
    kind = cert.get("lyapunov", "common")
    if kind == "common":
        Q = _arr(cert["Q"], "Q")
        if Q.shape != (n_s, n_s):
            return f"Q has shape {Q.shape}, expected {(n_s, n_s)}"
        err = _symmetric(Q, "Q")
        if err:
            return err
        Q = _sym(Q)  # within SYMMETRY_TOL: proven as its symmetric part, in every block (A X + B Y too)
        conds = [[(Q, Q, "", np.abs(Q), np.abs(Q))] for _ in model.vertices]
        return kind, Q, conds, [Q]
    if kind not in ("slip-dependent", "delay-dependent", "path-dependent"):
        return f"unknown lyapunov kind {kind!r}"
    G = _arr(cert["G"], "G")
    S = [_arr(x, f"S[{m}]") for m, x in enumerate(cert["S"])]
    if G.shape != (n_s, n_s):
        return f"G has shape {G.shape}, expected {(n_s, n_s)}"
    want = model.lyapunov_count(kind)
    if len(S) != want:
        per = {"slip-dependent": "slip corner", "delay-dependent": "slip corner and delay vertex"}.get(
            kind, "slip corner and pair of delay vertices")
        return f"S has {len(S)} matrices, expected one per {per} ({want})"
    for m, Sm in enumerate(S):
        if Sm.shape != (n_s, n_s):
            return f"S[{m}] has shape {Sm.shape}, expected {(n_s, n_s)}"
        err = _symmetric(Sm, f"S[{m}]")
        if err:
            return err
        S[m] = _sym(Sm)
    # the certificate holds for slip changes up to its slip_step per period (None: any change); it
    # covers the config when the config allows no more than that
    cert_step = cert.get("slip_step")
    config_step = model.slip_step if model.rate_bounded else None
    if cert_step is not None and (config_step is None or config_step > float(cert_step) * (1 + 1e-12)):
        allowed = "any change (slip.max_rate: null)" if config_step is None else f"{config_step:g}"
        return (f"the certificate assumes slip changes of at most {float(cert_step):g} per period; the config allows "
                f"{allowed}")
    table = model.lyapunov_conditions(kind, None if cert_step is None else float(cert_step))
    aG, aS = np.abs(G), [np.abs(x) for x in S]
    conds = [[(G + G.T - S[j], sum(w * S[n] for w, n in right), lab,
               aG + aG.T + aS[j], sum(abs(w) * aS[n] for w, n in right)) for j, right, lab in row] for row in table]
    return kind, G, conds, S


def _check(model: Any, K: np.ndarray, cert: Mapping[str, Any]) -> CertificateCheck:
    objective = cert["objective"]
    K = _arr(K, "K")
    n_s, n_u = model.n_s, model.n_u
    made_for = cert.get("model", "paper")
    if made_for != model.kind:
        return _fail(f"the certificate was made for the {made_for!r} model, the config asks for {model.kind!r} "
                     "(synthesis.model)")
    if K.shape != (n_u, n_s):
        return _fail(f"K has shape {K.shape}, expected {(n_u, n_s)}")
    kin = cert.get("kinematics", "linearized")
    if objective in ("stability", "hinf") and kin == "linearized":
        # these LMIs are written on the linearization (synthesis.lmis.build_stability / build_hinf),
        # also when the config asks for nonlinear kinematics (robust stability of a fixed K: margins)
        model = model.linearized()
    if kin != model.kinematics:
        return _fail(f"the certificate is for {kin} kinematics, the config asks for {model.kinematics} "
                     "(synthesis.kinematics)")
    if kin == "nonlinear":  # the kinematic channels of the certificate's own heading bound
        hb = cert.get("heading_bound")
        if isinstance(hb, bool) or not isinstance(hb, (int, float)) or not 0.0 < float(hb) <= 1.0:
            return _fail(f"certificate.heading_bound: nonlinear kinematics need a number in (0, 1] rad (got {hb!r})")
        hb = float(hb)
        within = bool(cert.get("within_period_channels", False))  # for slip changing within a period (§9)
        if within and not model.covering:
            return _fail("the certificate's kinematic channels are for slip changing within a period, which this "
                         f"config's model does not cover ({model.varying_reason})")
        if hb != model.heading_bound or within != bool(model.covering_vertices):
            model = model.with_heading_bound(hb, within_period=within)
    turns, have = cert.get("turns"), getattr(model, "turns", None)
    if turns is not None:  # the vertices of the certificate's own turning reference (model/arcs.py)
        want = (float(turns["max_yaw_rate"]), float(turns["max_step"]))
        if have is not None and not (want[0] >= have.max_yaw_rate and want[1] >= have.max_step):
            return _fail(f"the certificate covers reference yaw rates up to {want[0]:.4g} rad/s (steps {want[1]:.4g}), "
                         f"the model asks for {have.max_yaw_rate:.4g} (steps {have.max_step:.4g}): "
                         "reference.turn_radius is smaller than the one the gain was certified for")
        if have is None:
            return _fail(f"the certificate is for a reference turning along arcs (yaw rates up to {want[0]:.4g} rad/s), "
                         "the config's path jumps at its waypoints (reference.turn_radius is null): set "
                         "reference.turn_radius to the gain's radius or wider")
        # the turning vertices of the certificate's own yaw rates, for slip changing within a period where its
        # channels are (within_period_channels; a certificate made before they existed assumes it constant)
        within = bool(cert.get("within_period_channels", False))
        if within and not model.covering:
            return _fail("the certificate's channels are for slip changing within a period, which this config's "
                         f"model does not cover ({model.varying_reason})")
        from .errors import InputError

        try:
            if (have.max_yaw_rate, have.max_step) != want or within != bool(model.covering_vertices):
                model = model.with_turns(*want, within_period=within)
            size = _multiplier_size(cert)
            if not within and size not in (None, model.vertices[0].n_q ** 2):
                # made before the arc channels were merged (docs/theory.md §10): their own layout, if it fits
                legacy = model.with_turns(*want, within_period=False, merged=False)
                if size == legacy.vertices[0].n_q ** 2:
                    model = legacy
        except InputError as exc:
            return _fail(f"the certificate is for a turning reference, which this model cannot carry: {exc}")
    elif have is not None:
        return _fail("the certificate is for straight segments, the model for a turning reference")
    parts = _lyapunov_parts(model, cert, n_s)
    if isinstance(parts, str):
        return _fail(parts)
    lyap, X, conds, mats = parts
    mult = cert["multipliers"]
    n_v = len(model.vertices)
    raw = mult["M"]
    if len(raw) != n_v:
        return _fail(f"multipliers.M has {len(raw)} entries, expected one per vertex ({n_v})")
    Ms = []
    for i, (x, v) in enumerate(zip(raw, model.vertices)):
        M = _arr(x, f"multipliers.M[{i}]")
        if M.size != v.n_q * v.n_q:
            return _fail(f"multipliers.M[{i}] has {M.size} entries, expected {v.n_q} x {v.n_q} (the vertex's uncertainty "
                         "channels): the certificate was made for other channels")
        M = M.reshape(v.n_q, v.n_q)
        err = _symmetric(M, f"multipliers.M[{i}]") or multiplier_structure_error(
            M, v.n_q // 3, mult.get("kind", "structured"), v.diagonal)
        if err:
            return _fail(err)
        Ms.append(_sym(M))
    margin = float(cert["margin"])
    if not margin > 0:
        return _fail("margin must be > 0")
    if "P" in cert and cert["P"] is not None:
        Ps = [cert["P"]] if lyap == "common" else cert["P"]
        for Pm, Sm in zip(Ps, mats):
            Pm = _arr(Pm, "P")
            if Pm.shape != Sm.shape or np.max(np.abs(Pm @ Sm - np.eye(n_s))) > 1e-6:
                return _fail("P is not the inverse of the Lyapunov matrix")
    threshold = CHECK_FRACTION * margin
    Y = K @ X
    aX, aY = np.abs(X), np.abs(K) @ np.abs(X)  # Y's magnitude: Y = K X is computed, not given
    lmin = lambda L: float(np.linalg.eigvalsh(L)[0])  # noqa: E731
    checks = []
    for m, Sm in enumerate(mats):
        nm = "Q > 0" if lyap == "common" else f"S[{m}] > 0"
        ok, allow = _proof(Sm, None, 0, threshold)
        checks.append(_item(nm, lmin(Sm), threshold, verified=ok, allowance=allow, unproven="" if ok else nm))
    if any(v.n_q for v in model.vertices):
        idx = [i for i, v in enumerate(model.vertices) if v.n_q]
        worst = min((lmin(Ms[i]), i) for i in idx)
        proofs = [(_proof(Ms[i], None, 0, threshold), i) for i in idx]
        bad = [model.vertices[i].label for (ok, _), i in proofs if not ok]
        checks.append(_item(f"M_i > 0 (multipliers, {len(idx)} vertices)", worst[0], threshold,
                            model.vertices[worst[1]].label, verified=not bad,
                            allowance=max(a for (_, a), _ in proofs), unproven=bad[0] if bad else ""))
    # slip changing within a period (docs/theory.md §11): a common certificate must also hold at the
    # vertices that cover every slip history; the others state that they assume it constant
    varying, varying_reason = model.slip_variation(lyap, objective)
    group_multipliers = np.zeros((0, 0))
    if varying and varying[0].n_q:  # with channels (§9): each takes the multiplier of its group's first vertex
        first: dict[int, int] = {}
        for i, v in enumerate(model.vertices):
            if v.group >= 0:
                first.setdefault(v.group, i)
        if any(v.group not in first for v in varying):
            return _fail("the within-period vertices' channels have no multiplier (no vertex of their group)", checks)
        group_multipliers = np.stack([Ms[first[v.group]] for v in varying])
    terms = lambda k: 2 * k + X.shape[0] * (K.shape[0] + 1) + len(mats)  # noqa: E731  (products per entry)

    def vertex_family(name: str, build) -> list[dict[str, Any]]:
        """Every vertex condition: its smallest eigenvalue (floating point) and its verified proof
        (``build(v, M, left, right, Y, mag)`` assembles the matrix, or its magnitude); one item per
        family of vertices."""
        worst_val, worst_lab, count, allowance, unproven = np.inf, "", 0, 0.0, ""
        for i, v in enumerate(model.vertices):
            av, aM = _AbsVertex(v), np.abs(Ms[i])
            for left, right, lab, aleft, aright in conds[i]:
                L = build(v, Ms[i], left, right, Y, False)
                val = lmin(L)
                count += 1
                if val < worst_val:
                    worst_val = val
                    worst_lab = v.label + lab
                mag = build(av, aM, aleft, aright, aY, True)
                ok, allow = _proof(L, mag, terms(L.shape[0]), threshold)
                allowance = max(allowance, allow)
                if not ok and not unproven:
                    unproven = v.label + lab
        items = [_item(f"{name} at {count} vertex condition{'s' if count != 1 else ''}", worst_val, threshold, worst_lab,
                       verified=not unproven, allowance=allowance, unproven=unproven)]
        if varying:  # one stack: the common certificate's single condition at every vertex (§11)
            left, right, _, aleft, aright = conds[0][0]
            stack, abs_stack = _stacks(varying)
            Mv = group_multipliers
            L = build(stack, Mv, left, right, Y, False)
            vals = np.linalg.eigvalsh(L)[:, 0]
            radius = assembly_radius_batch(build(abs_stack, np.abs(Mv), aleft, aright, aY, True), terms(L.shape[-1]))
            proven = proves_at_least_batch(L, threshold, radius)
            allow = radius + rump_shift_batch(np.maximum(np.abs(np.diagonal(L, axis1=-2, axis2=-1)), 1e-300))
            worst = int(np.argmin(vals))
            bad = np.flatnonzero(~proven)
            item = _item(f"{name} at {len(varying)} vertex conditions, slip changing within a period",
                         float(vals[worst]), threshold, varying[worst].label, verified=not bad.size,
                         allowance=float(np.max(allow)), unproven=varying[bad[0]].label if bad.size else "")
            # the vertices that fail, worst first (synthesis adds them to its LMIs: Model.with_cuts)
            failing = np.flatnonzero((vals < threshold) | ~proven)
            item[VARYING_FAILURES] = [int(i) for i in failing[np.argsort(vals[failing], kind="stable")]]
            items.append(item)
        return items

    figures: dict[str, Any] = {"robust_stability": False, "decay_rate": None, "ultimate_bound": None,
                               "motor_speed_bound": None, "hinf_gain": None}
    within = "covered" if varying else f"assumed constant: {varying_reason}"
    cfg = model.config
    if objective == "stability":
        r2 = float(cert["r2"])
        if not 0 < r2 < 1:
            return _fail("r2 must be in (0, 1)", checks, figures)
        checks.extend(vertex_family("decay LMI (6a)", lambda v, M, lf, rt, y, mag: lmi_stability(
            v, aX if mag else X, lf, rt, y, M, r2, mag)))
        figures["decay_rate"] = round_up(np.sqrt(r2), 2)
    elif objective == "ultimate-bound":
        alpha = float(cert["alpha"])
        beta = _arr(cert["beta"], "beta").reshape(-1)
        if beta.shape != (model.n_w,):
            return _fail(f"beta has {beta.size} entries, expected {model.n_w}", checks, figures)
        if not 0 < alpha < 1:
            return _fail("alpha must be in (0, 1)", checks, figures)
        if np.any(beta <= 0):
            return _fail("beta must be > 0", checks, figures)
        checks.extend(vertex_family("invariance LMI (6b)", lambda v, M, lf, rt, y, mag: lmi_invariance(
            v, aX if mag else X, lf, rt, y, M, np.abs(beta) if mag else beta, alpha, mag)))
        # the figures are claimed as bounds: rounded outwards (any level >= sum beta / alpha is invariant)
        level = round_up(float(np.sum(beta) / alpha), beta.size + 1)  # {xi' P xi <= level}: invariant, attracting
        figures["decay_rate"] = round_up(np.sqrt(1.0 - alpha), 2)
        figures["ellipsoid_level"] = level
        # per bounded figure the largest value the set allows over every slip (and previous delay), the
        # smallest over the delay vertices V takes its maximum over (set_max; docs/theory.md §6i)
        inner = model.delay_vertex_count if lyap in ("delay-dependent", "path-dependent") else 1
        diags = np.array([np.diag(Sm) for Sm in mats])
        figures["ultimate_bound"] = {
            name: round_up(np.sqrt(level * set_max(diags[:, k], inner)), 2)
            for k, name in enumerate(("e_x", "e_y", "e_theta"))
        }
        J_inv = np.asarray(model.J_inv)
        # c S c' with c = J^-1 K, bounded above with its rounding: + gamma |c| |S| |c|'
        g = gamma(2 * n_s + 2 * n_u + 4)
        aJK = np.abs(J_inv) @ np.abs(K)
        devs = np.array([np.einsum("ij,jk,ik->i", J_inv, K @ Sm @ K.T, J_inv)
                         + g * (1 + g) * np.einsum("ij,jk,ik->i", aJK, np.abs(Sm), aJK) for Sm in mats])
        dev = max(set_max(devs[:, i], inner) for i in range(devs.shape[1]))
        figures["motor_speed_bound"] = round_up(model.feedforward_motor_speed + np.sqrt(max(round_up(level * dev), 0.0)), 3)
        # |e_theta(t)| on the set and the errors between samples (docs/theory.md §9; on arcs against the
        # turning reference, §10)
        if model.channels:
            figures["heading_within_period"] = heading_within_period(model, K, mats, level, inner)
        figures["ultimate_bound_between_samples"] = between_samples(
            model, K, mats, level, figures["ultimate_bound"], figures.get("heading_within_period"), inner,
            within_period=bool(varying))
        if model.heading_bound is not None:
            figures["heading_bound"] = model.heading_bound
            checks.append({
                "name": "|e_theta(t)| within every period on the set <= heading bound [rad]",
                "max_eig": None,
                "threshold": float(model.heading_bound),
                "margin_found": None,
                "value": figures["heading_within_period"],
                "passed": bool(figures["heading_within_period"] <= model.heading_bound),
            })
        rho_max = cfg.robot.max_motor_speed
        if rho_max is not None and cert.get("motor_limits_enforced", False):
            checks.append({
                "name": "motor speed on the invariant set (6c) [rad/s]",
                "max_eig": None,
                "threshold": float(rho_max),
                "margin_found": None,
                "value": figures["motor_speed_bound"],
                "passed": bool(figures["motor_speed_bound"] <= rho_max),
            })
    elif objective == "hinf":
        if lyap != "common":
            return _fail("hinf certificates use a common Lyapunov matrix")
        g = float(cert["gamma2"])
        w = cfg.synthesis.weights
        Cz = np.zeros((3, n_s))
        Cz[:3, :3] = np.diag([w.e_x, w.e_y, w.e_theta])
        Bd = np.asarray(model.B_d)
        checks.extend(vertex_family("bounded-real LMI (6d)", lambda v, M, lf, rt, y, mag: lmi_hinf(
            v, np.abs(Bd) if mag else Bd, np.abs(Cz) if mag else Cz, aX if mag else X, y, M, g, mag)))
        figures["hinf_gain"] = round_up(np.sqrt(g), 2)
    else:
        return _fail(f"unknown objective {objective!r}")
    passed = all(c["passed"] for c in checks)
    figures["robust_stability"] = passed
    if not passed:
        figures = {k: (False if k == "robust_stability" else None) for k in figures}
    figures["slip_within_period"] = within
    unproven = [c for c in checks if c.get("status") == "not proven (rounding)"]
    reason = "" if passed else (
        f"not proven (rounding): {unproven[0]['name']} passes in floating point (smallest eigenvalue "
        f"{unproven[0]['margin_found']:.3g} >= {-unproven[0]['threshold']:.3g}) but the verified test does not"
        + (f" (first at {unproven[0]['unproven']})" if unproven[0].get("unproven") else "")
        if unproven and all(c["passed"] or c.get("status") for c in checks) else _failed_reason(checks))
    return CertificateCheck(passed, tuple(checks), figures, reason)


def varying_failures(check: CertificateCheck) -> list[int] | None:
    """The within-period vertices (indices into ``Model.varying``) a check failed on, when nothing else
    failed; None otherwise (passed, or some other condition failed too)."""
    if check.passed:
        return None
    failed = [c for c in check.checks if not c["passed"]]
    if failed and all(VARYING_FAILURES in c for c in failed):
        return list(dict.fromkeys(i for c in failed for i in c[VARYING_FAILURES]))
    return None


def _failed_reason(checks: list[dict[str, Any]]) -> str:
    """The first failed condition in words: what was found against what is required."""
    bad = [c for c in checks if not c["passed"]]
    if not bad:
        return "an LMI fails the margin check"
    c = bad[0]
    if c.get("margin_found") is not None:
        return (f"{c['name']} fails: smallest eigenvalue {c['margin_found']:.3g}, required >= {-c['threshold']:.3g}"
                + (f" (at {c['worst']})" if c.get("worst") else ""))
    return f"{c['name']} fails: {c.get('value')} against {c.get('threshold')}"


def heading_within_period(model: Any, K: np.ndarray, mats: list[np.ndarray], level: float, inner: int = 1) -> float:
    """An upper bound on |e_theta(t)| for t in every period, over the set {V <= level}: e_theta is
    piecewise linear in t, so its extremes are at the break points, ``r xi + g`` (r = C_h + D_h K) at
    each vertex; the supremum over the set is ``|g| + sqrt(level r S r')`` (its rounding bound added),
    convex in (r, g), so the vertices' largest covers every delay and slip.  On a turning model the rows
    also carry the reference's yaw-rate coordinates (``F_h``, each in [-1, 1]: model/arcs.turning_heading),
    which add ``sum |F_h|``, convex in them too."""
    n = K.shape[0] + 2 * model.n_s + 4
    g = gamma(n)
    out = 0.0
    for ch in model.heading_channels:
        R = ch.C_h + ch.D_h @ K
        aR = np.abs(ch.C_h) + np.abs(ch.D_h) @ np.abs(K)
        q = np.array([_form_upper(R, aR, S, g) for S in mats])  # (n_mats, n_rows)
        off = ch.heading_offsets  # |g|, plus a turning reference's sum |F_h|
        for i in range(q.shape[1]):
            val = float(off[i]) * (1 + g) + np.sqrt(max(level * set_max(q[:, i], inner), 0.0))
            out = max(out, float(val))
    return round_up(out, 8)  # the product with level, the square root and the sum


def _form_upper(R: np.ndarray, aR: np.ndarray, S: np.ndarray, g: float) -> np.ndarray:
    """r S r' for every row r of R, plus its rounding bound g (1 + g) |r| |S| |r|' (aR: the rows'
    magnitudes, which bound their own rounding when they were computed)."""
    return np.einsum("ij,jk,ik->i", R, S, R) + g * (1 + g) * np.einsum("ij,jk,ik->i", aR, np.abs(S), aR)


def set_max(q: np.ndarray, inner: int = 1) -> float:
    """An upper bound on ``max c S(mu, ...) c'`` that the set {V <= level} allows, from ``q[j]`` >= c S_j c'
    (one per Lyapunov matrix, in the certificate's order), ``|c xi|^2 <= level * set_max(q)`` on it
    (docs/theory.md §6i).

    ``inner``: how many consecutive matrices V takes its maximum over (the delay vertices d of a
    delay- or path-dependent certificate, 1 otherwise).  On the set, ``xi' S(mu, d)^-1 xi <= level`` for
    every d, so ``|c xi|^2 <= level sum_d theta_d c S(mu, d) c'`` for any convex weights theta, and
    ``c S(mu, d) c'`` is a convex combination of the corners' (and previous delay vertices') values: the
    bound is ``min_theta max_outer sum_d theta_d q[outer, d]`` (a small linear program), never above
    ``min_d max_outer q`` nor the largest q.  Any theta gives a valid bound, so the program's accuracy
    only decides how tight it is; the value is evaluated at its theta and rounded up."""
    q = np.maximum(np.asarray(q, dtype=float).reshape(-1, inner), 0.0)
    best = float(np.min(np.max(q, axis=0)))  # theta a unit vector: min over d of max over the rest
    if inner > 1 and q.shape[0] > 1:
        from scipy.optimize import linprog

        n_o = q.shape[0]
        # min s  s.t.  q theta - s <= 0, sum theta = 1, theta >= 0
        res = linprog(np.r_[np.zeros(inner), 1.0], A_ub=np.c_[q, -np.ones(n_o)], b_ub=np.zeros(n_o),
                      A_eq=np.r_[np.ones(inner), 0.0][None, :], b_eq=[1.0],
                      bounds=[(0, None)] * inner + [(None, None)], method="highs")
        if res.status == 0:
            theta = np.maximum(res.x[:inner], 0.0)
            total = float(np.sum(theta))
            if total > 0:
                # sum(theta q) / sum(theta): weights that sum to one whatever the rounding of theta
                val = round_up(float(np.max(q @ theta)) / total, 2 * inner + 2)  # dot products, sum, division
                best = min(best, val)
    return best


def sup_on_set(rows: np.ndarray, mats: list[np.ndarray], level: float, inner: int = 1) -> float:
    """max over the rows r of the largest |r xi| on the set, sqrt(level * set_max(r S r')), with the
    rounding of r S r' added (``inner``: :func:`set_max`)."""
    g = gamma(2 * rows.shape[1] + 4)
    q = np.array([_form_upper(rows, np.abs(rows), S, g) for S in mats])  # (n_mats, n_rows)
    top = max(set_max(q[:, i], inner) for i in range(q.shape[1]))
    return float(np.sqrt(max(round_up(level * top), 0.0)))


def between_samples(model: Any, K: np.ndarray, mats: list[np.ndarray], level: float, sampled: dict[str, float],
                    heading: float | None, inner: int = 1, within_period: bool = False) -> dict[str, float | None]:
    """Bounds on |e_x(t)|, |e_y(t)|, |e_theta(t)| for every t, not only at the sampling instants
    (docs/theory.md §9).  Both ends of a period lie in the set, so within it each error is at most
    its sampled bound plus its distance from the chord between the ends, which is at most
    ``Ts^2/8 sup|f''| + Ts/4 sum |jumps of f'|`` (the Green's function of f'' on [0, Ts] lies in
    [0, Ts/4] and integrates to at most Ts^2/8).  On the exact arcs ``e_y' = v sin e_theta`` and
    ``e_x' = v cos e_theta - V`` (``f'' = +-v omega cos/sin``, jumps ``|dv|`` times sin / cos at the d_hi
    switching instants); on the linearization ``e_y' = V e_theta`` (``f'' = V omega``, no jumps) and
    ``e_x' = a`` (only jumps); with the icr slip model e_y' also holds v_y, whose jumps add to e_y's.
    v, omega and the jumps dv of the commands in flight are bounded on the set at every slip corner
    (multi-affine in the slip).  e_theta(t): :func:`heading_within_period`.

    ``within_period``: slip may also change within the period (docs/theory.md §11).  Then e_x' = a(t)
    jumps wherever the slip does, and the chord distance is bounded by ``Ts/4 (sup a - inf a)`` over
    the period instead (for f' in [m, M]: |f(t) - chord(t)| <= t (Ts - t) / Ts (M - m)): the largest
    difference of a between any two slip corners and any two commands in flight, on the set.  e_y'' =
    V omega(t) is bounded pointwise, whatever the slip does.  On the exact arcs (a nonlinear
    certificate) e_y' = V sin e_theta + a sin e_theta: the first part has a bounded f'', the second
    (a jumps with the slip) is bounded by its range; e_x' likewise."""
    from .model.slip import lateral_row

    n_s, n_e, n_u, d_hi = model.n_s, model.n_e, model.n_u, model.d_hi
    Ts, V = model.Ts, model.V
    cmds = [np.asarray(K, dtype=float)]
    for j in range(1, d_hi + 1):
        E = np.zeros((n_u, n_s))
        E[:, n_e + (j - 1) * n_u : n_e + j * n_u] = np.eye(n_u)
        cmds.append(E)
    if getattr(model, "turns", None) is not None:
        return _between_samples_on_arcs(model, cmds, mats, level, sampled, heading, inner, within_period)
    vbar, wbar, dvbar, abar = _speeds_on_set(model, cmds, mats, level, inner)
    if model.heading_bound is not None:
        s = float(np.sin(min(float(heading), np.pi / 2)))
        ey = Ts * Ts / 8 * vbar * wbar + Ts / 4 * d_hi * dvbar * s
        ex = Ts * Ts / 8 * vbar * wbar * s + Ts / 4 * d_hi * dvbar
    else:
        ey = Ts * Ts / 8 * V * wbar
        ex = Ts / 4 * d_hi * dvbar
    if within_period:
        osc = _forward_oscillation(model, cmds, mats, level, inner)
        ex = Ts / 4 * osc
        if model.heading_bound is not None:
            # the exact arcs, split so that only the parts in which a = v - V (which jumps with the slip)
            # appears are bounded by their ranges: e_y' = V sin e_theta + a sin e_theta, the first with
            # |f''| = |V cos e_theta omega| <= V wbar, the second in +-abar s; e_x' = a - V (1 - cos e_theta)
            # - a (1 - cos e_theta): a ranges over osc, the second has |f''| <= V s wbar, the third is in
            # +-abar (1 - cos)
            h = min(float(heading), np.pi / 2)
            s, one_minus_cos = float(np.sin(h)), 2.0 * float(np.sin(h / 2.0)) ** 2
            ey = Ts * Ts / 8 * V * wbar + Ts / 4 * 2.0 * abar * s
            ex = Ts / 4 * osc + Ts * Ts / 8 * V * s * wbar + Ts / 4 * 2.0 * abar * one_minus_cos
    if model.icr and (within_period or model.heading_bound is not None):
        # the lateral velocity v_y = row(p) u (docs/theory.md §12): e_y' gets v_y cos e_theta, e_x' -v_y sin e_theta;
        # slip changing within the period (or a heading that turns it) makes it jump at any time, so each part is
        # bounded by its range: |f - chord| <= Ts/4 (sup f' - inf f') <= Ts/4 2 vy_bar (times sin for e_x)
        vy = _lateral_on_set(model, cmds, mats, level, inner)
        h = min(float(heading if heading is not None else 0.0), np.pi / 2)
        ey += Ts / 4 * 2.0 * vy
        ex += Ts / 4 * 2.0 * vy * float(np.sin(h))
    elif model.icr:  # e_y' also holds the lateral velocity v_y = row(p) u: its jumps at the switching instants
        D = model.config.robot.track_distance
        dvy = max(sup_on_set(np.array([lateral_row(mu, D) @ (cmds[j] - cmds[j + 1]) for j in range(d_hi)]), mats,
                             level, inner) for mu in np.asarray(model.corners))
        ey += Ts / 4 * d_hi * dvy
    return {"e_x": round_up(sampled["e_x"] + ex, 12), "e_y": round_up(sampled["e_y"] + ey, 12),
            "e_theta": heading}


def _lateral_on_set(model: Any, cmds: list[np.ndarray], mats: list[np.ndarray], level: float, inner: int,
                    yaw_rate: float = 0.0) -> float:
    """The largest |v_y| of the icr slip model on the set, over every slip corner (v_y is multi-affine in the
    parameters: its extremes over the box, and over any average of slips, are at the corners) and every
    command in flight, with a turning reference's feedforward (0, w), |w| <= ``yaw_rate``."""
    from .model.slip import lateral_row

    uD = np.array([model.V, 0.0])
    D = model.config.robot.track_distance
    out = 0.0
    for mu in np.asarray(model.corners):
        row = lateral_row(mu, D)
        out = max(out, abs(float(row @ uD)) + abs(float(row @ model.turn_feedforward)) * yaw_rate
                  + sup_on_set(np.array([row @ c for c in cmds]), mats, level, inner))
    return out


def _multiplier_size(cert: Mapping[str, Any]) -> int | None:
    """The number of entries of the certificate's first multiplier, or None when it has none readable."""
    try:
        return int(np.asarray(cert["multipliers"]["M"][0], dtype=float).size)
    except (KeyError, IndexError, TypeError, ValueError):
        return None


def _forward_oscillation(model: Any, cmds: list[np.ndarray], mats: list[np.ndarray], level: float, inner: int,
                         yaw_rate: float = 0.0) -> float:
    """The largest difference of the forward speed a = v - V^D between any two instants of a period on the
    set, slip changing at any time: between any two slip corners and any two commands in flight (``cmds``),
    with a turning reference's feedforward (0, w), |w| <= ``yaw_rate``, in each."""
    from .model.slip import slip_matrix

    uD = np.array([model.V, 0.0])
    g = model.turn_feedforward  # the feedforward command per rad/s of yaw rate ((0, 1): M[0, 1])
    Ms = [slip_matrix(mu, model.config.robot.track_distance) for mu in np.asarray(model.corners)]
    osc = 0.0
    for Ma in Ms:
        for Mb in Ms:
            const = abs(float((Ma[0] - Mb[0]) @ uD)) + (abs(float(Ma[0] @ g)) + abs(float(Mb[0] @ g))) * yaw_rate
            for ca in cmds:
                rows = np.array([Ma[0] @ ca - Mb[0] @ cb for cb in cmds])
                osc = max(osc, const + sup_on_set(rows, mats, level, inner))
    return osc


def _speeds_on_set(model: Any, cmds: list[np.ndarray], mats: list[np.ndarray], level: float, inner: int,
                   yaw_rate: float = 0.0, yaw_step: float = 0.0) -> tuple[float, float, float, float]:
    """Bounds on the set, over every slip corner and command in flight (``cmds``: the rows that give
    each command from xi), on the forward speed |v|, the turn rate |omega|, the jump |dv| between
    consecutive commands and the forward-speed deviation |a| = |v - V^D|; with a turning reference's
    feedforward (0, w), |w| <= ``yaw_rate`` and steps <= ``yaw_step``, in every command."""
    from .model.slip import slip_matrix

    uD = np.array([model.V, 0.0])
    g = model.turn_feedforward  # the feedforward command per rad/s of yaw rate ((0, 1): M[., 1])
    vbar = wbar = dvbar = abar = 0.0
    for mu in np.asarray(model.corners):
        M = slip_matrix(mu, model.config.robot.track_distance)
        forward = sup_on_set(np.array([M[0] @ c for c in cmds]), mats, level, inner)
        ff_v = abs(float(M[0] @ g)) * yaw_rate  # the feedforward's share of v (asymmetric slip)
        vbar = max(vbar, abs(float(M[0] @ uD)) + ff_v + forward)
        abar = max(abar, abs(float(M[0] @ uD) - model.V) + ff_v + forward)
        wbar = max(wbar, abs(float(M[1] @ uD)) + abs(float(M[1] @ g)) * yaw_rate
                   + sup_on_set(np.array([M[1] @ c for c in cmds]), mats, level, inner))
        dvbar = max(dvbar, abs(float(M[0] @ g)) * yaw_step
                    + sup_on_set(np.array([M[0] @ (cmds[j] - cmds[j + 1]) for j in range(model.d_hi)]), mats, level,
                                 inner))
    return vbar, wbar, dvbar, abar


def _between_samples_on_arcs(model: Any, cmds: list[np.ndarray], mats: list[np.ndarray], level: float,
                              sampled: dict[str, float], heading: float, inner: int,
                              within_period: bool = False) -> dict[str, float | None]:
    """:func:`between_samples` for a reference turning along arcs (docs/theory.md §10), on the exact arcs
    (for either kinematics: the linearization's own flow is not the robot's).  In the frame F_k of the
    reference at t_k, with p the robot's position and p_r the reference's (heading psi = w_k s), the error
    at time s is ``R(-psi) (p - p_r)`` and ``e_theta = eta``.  Each component f of ``p - p_r`` is within
    ``max(|f(0)|, |f(Ts)|)`` of its chord plus ``Ts^2/8 sup|f''| + Ts/4 sum|jumps of f'|``: ``f(0)`` is
    e(t_k), ``f(Ts)`` is ``R(-phi) e(t_{k+1})`` (both in the set: ``|p_y - p_ry| <= B_y + sin phi_bar B_x`` at
    the ends); ``(p_y - p_ry)'' = v omega cos theta - V w cos psi``, ``(p_x - p_rx)'' = -v omega sin theta + V w
    sin psi`` (theta = psi + eta, |theta| <= phi_bar + |eta|), jumps ``|dv|`` (times sin theta for y) at
    the d_hi switching instants.  v, omega (the turning feedforward (0, w_{k-j}) included) and the jumps
    dv (steps of w included) are bounded on the set at every slip corner.  Then ``|e_y| <= P_y + sin phi_bar
    P_x`` and ``|e_x| <= P_x + sin phi_bar P_y``, P the bounds on |p - p_r| over the period.

    ``within_period``: slip may also change within the period, so v jumps wherever it does.  As on straight
    segments (:func:`between_samples`) only the parts in which a = v - V^D appears are bounded by their
    ranges: ``(p_y - p_ry)' = V (sin theta - sin psi) + a sin theta``, the first with ``|f''| <= V (omega_bar +
    w_bar)``, the second in ``+-abar sin theta_hat``; ``(p_x - p_rx)' = a + V (cos theta - cos psi) + a (cos theta
    - 1)``: a ranges over its oscillation, the second has ``|f''| <= V (omega_bar sin theta_hat + w_bar sin
    phi_bar)``, the third is in ``+-abar (1 - cos theta_hat)`` (theta_hat = phi_bar + |eta|)."""
    turns = model.turns
    Ts, V, d_hi = model.Ts, model.V, model.d_hi
    w_r = float(turns.max_yaw_rate)
    phi = w_r * Ts
    sp = float(np.sin(phi))
    vbar, wbar, dvbar, abar = _speeds_on_set(model, cmds, mats, level, inner, w_r, float(turns.max_step))
    top = phi + float(heading)  # |theta| <= phi_bar + |eta|: sin grows up to pi/2, 1 - cos up to pi
    s, one_minus_cos = float(np.sin(min(top, np.pi / 2))), 2.0 * float(np.sin(min(top, np.pi) / 2.0)) ** 2
    Bx, By = float(sampled["e_x"]), float(sampled["e_y"])
    if within_period:
        osc = _forward_oscillation(model, cmds, mats, level, inner, w_r)
        Py = By + sp * Bx + Ts * Ts / 8 * V * (wbar + w_r) + Ts / 4 * 2.0 * abar * s
        Px = (Bx + sp * By + Ts / 4 * osc + Ts * Ts / 8 * V * (wbar * s + w_r * sp)
              + Ts / 4 * 2.0 * abar * one_minus_cos)
    else:
        Py = By + sp * Bx + Ts * Ts / 8 * (vbar * wbar + V * w_r) + Ts / 4 * d_hi * dvbar * s
        Px = Bx + sp * By + Ts * Ts / 8 * (vbar * wbar * s + V * w_r * sp) + Ts / 4 * d_hi * dvbar
    if model.icr:  # the lateral velocity: (p_y - p_ry)' gets v_y cos theta, (p_x - p_rx)' -v_y sin theta, each
        # bounded by its range (it jumps wherever the slip or a command does): Ts/4 2 vy_bar (times sin theta_hat)
        vy = _lateral_on_set(model, cmds, mats, level, inner, w_r)
        Py += Ts / 4 * 2.0 * vy
        Px += Ts / 4 * 2.0 * vy * s
    return {"e_x": round_up(Px + sp * Py, 16), "e_y": round_up(Py + sp * Px, 16), "e_theta": heading}


class _Stack:
    """Vertices as one stack: each matrix (n, ., .) (their absolute values with ``absolute``, for the
    magnitude of a formula); their channels must have one shape."""

    def __init__(self, verts: Any, absolute: bool = False) -> None:
        f = np.abs if absolute else np.asarray
        for name in ("A", "B", "E", "B_p", "C_q", "D_q", "F"):
            setattr(self, name, f(np.stack([np.asarray(getattr(v, name)) for v in verts])))


_STACKED: list[tuple[Any, _Stack, _Stack]] = []  # the last model's within-period vertices, stacked


def _stacks(verts: tuple) -> tuple[_Stack, _Stack]:
    """:class:`_Stack` of ``verts`` and of their absolute values, kept for the next check of the same
    model (a synthesis re-checks every point it solves; stacking 768 vertices costs about 4 ms)."""
    hit = _STACKED[0] if _STACKED else None
    if hit is None or hit[0] is not verts:
        hit = (verts, _Stack(verts), _Stack(verts, absolute=True))
        _STACKED[:] = [hit]
    return hit[1], hit[2]


class _AbsVertex:
    """A vertex with every matrix replaced by its absolute value (for the magnitude of a formula)."""

    def __init__(self, v: Any) -> None:
        for name in ("A", "B", "E", "B_p", "C_q", "D_q"):
            setattr(self, name, np.abs(np.asarray(getattr(v, name))))
        self.F = np.abs(np.asarray(v.F))
        self.label = v.label


@dataclass(frozen=True)
class Lyapunov:
    """V(xi, mu) of a certificate: ``xi' S(mu)^-1 xi`` with S(mu) = Q (common) or the convex
    combination sum_m lambda_m(mu) S_m of the slip-corner matrices (slip-dependent), lambda the
    model's corner weights; delay-dependent: ``max_d xi' S(mu, d)^-1 xi`` over the delay vertices d,
    S(mu, d) = sum_m lambda_m(mu) S_(m, d) -- a piecewise-quadratic function that needs no delay;
    path-dependent: ``max_b xi' S(mu, prev, b)^-1 xi`` with ``prev`` the previous period's delay
    weights (``Model.delay_weights``), the largest over the previous delay vertices where it is not
    known (NaN) -- an upper bound (``Model.lyapunov_conditions``).  ``V_max`` is the largest value
    over every matrix (an upper bound for any mu and delays)."""

    model: Any
    S: tuple[np.ndarray, ...]
    P: tuple[np.ndarray, ...]
    slip_step: float | None = None  # a rate-bounded certificate: the slip moves at most this per period
    delay_vertices: int = 1  # delay-dependent: S_(m, d) at index m * n_d + d; path-dependent: S_(m, a, b)
    path: bool = False  # at (m * n_d + a) * n_d + b, a the previous period's delay vertex

    @property
    def any_next_slip(self) -> bool:
        """True when the LMIs hold for every next slip and delay (common Q, or slip may jump and the
        matrices do not depend on a past delay): then from one step on the state lies in the set of
        every slip, and ``V_max`` <= level."""
        return len(self.S) == 1 or (self.slip_step is None and not self.path)

    def V(self, xi: np.ndarray, mu: np.ndarray | None = None, prev: np.ndarray | None = None) -> np.ndarray:
        """``prev`` (..., n_d): the previous period's delay weights (path-dependent only; None or NaN
        rows: unknown, the largest value over the previous delay vertices)."""
        xi = np.asarray(xi, dtype=float)
        if len(self.S) == 1 or mu is None:
            return self.V_max(xi)
        lam = self.model.corner_weights(np.asarray(mu, dtype=float))
        n_d = self.delay_vertices
        n = self.S[0].shape[0]
        if not self.path:
            return self._max_over_d(xi, lam, np.array(self.S).reshape((-1, n_d, n, n)))
        allS = np.array(self.S).reshape((-1, n_d, n_d, n, n))  # (n_c, a, b, n, n)
        batch = xi.shape[:-1]
        lam = np.broadcast_to(lam, batch + lam.shape[-1:])
        prev = np.full(batch + (n_d,), np.nan) if prev is None else np.broadcast_to(np.asarray(prev, dtype=float), batch + (n_d,))
        known = np.all(np.isfinite(prev), axis=-1)
        out = np.empty(batch)
        if np.any(known):  # S(mu, prev, b) for the known previous weights
            out[known] = self._max_over_d(xi[known], lam[known], np.einsum("ka,mabij->kmbij", prev[known], allS))
        if not np.all(known):  # the largest over the previous delay vertex a
            u = ~known
            out[u] = np.max([self._max_over_d(xi[u], lam[u], allS[:, a]) for a in range(n_d)], axis=0)
        return out

    @staticmethod
    def _max_over_d(xi, lam, mats):
        """max_d xi' (sum_m lam_m mats[..., m, d])^-1 xi; ``mats`` (n_c, n_d, n, n) or per sample."""
        out = None
        for d in range(mats.shape[-3]):
            S = np.einsum("...m,...mij->...ij", lam, mats[..., d, :, :])
            sol = np.linalg.solve(S, xi[..., None])[..., 0]
            val = np.einsum("...i,...i->...", xi, sol)
            out = val if out is None else np.maximum(out, val)
        return out

    def V_max(self, xi: np.ndarray) -> np.ndarray:
        xi = np.asarray(xi, dtype=float)
        vals = [np.sum((xi @ P) * xi, axis=-1) for P in self.P]
        return np.max(vals, axis=0)


def lyapunov_of(model: Any, cert: Mapping[str, Any]) -> Lyapunov:
    """The Lyapunov function of a (checked) certificate."""
    step = None
    kind = cert.get("lyapunov", "common")
    n_d = 1
    if kind in ("slip-dependent", "delay-dependent", "path-dependent"):
        S = tuple(_sym(np.asarray(x, dtype=float)) for x in cert["S"])
        step = None if cert.get("slip_step") is None else float(cert["slip_step"])
        n_d = model.delay_vertex_count if kind != "slip-dependent" else 1
    else:
        S = (_sym(np.asarray(cert["Q"], dtype=float)),)
    return Lyapunov(model, S, tuple(np.linalg.inv(x) for x in S), step, n_d, kind == "path-dependent")


TURN_REENTRY = 1.05  # a turn ends, for the bound, when V is back below this multiple of the level
TURN_LINEARIZATION_HEADING = 0.5  # [rad]: beyond it the linearization's turn bound says little about the robot


def turn_bounds(model: Any, K: np.ndarray, cert: Mapping[str, Any], figures: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Bounds through each waypoint turn of ``reference.path`` from an ultimate-bound certificate
    (docs/theory.md §10).

    The law switches to segment i at the first sample t_k >= t_switch, delta = t_k - t_switch in
    [0, Ts): the errors change frame, ``xi' = J xi + o(delta)``, J rotating (e_x, e_y) by the turn
    angle d, ``o = (R(d) - I) [V^D delta, 0]`` on (e_x, e_y) and ``-d`` on e_theta; the stored commands
    and integrators are unchanged (as the law keeps them).  From {V <= c level} (c = 1 for the first
    turn, then what the previous turn left at this switch), ``V(xi') <= r level`` with
    ``sqrt(r level) = max_(j,k) sqrt(c level lambda_max(L_j' J' P_k J L_j)) + max_delta sqrt(o' P_k o)``
    (the triangle inequality in each P_k-norm, S_j = L_j L_j', every pair of the certificate's matrices:
    V is at most the largest over them; sqrt(o' P o) is convex in delta, so delta = 0 and Ts cover
    every sampling offset).  A straight-through waypoint (d = 0) leaves the state as it is: r = c.
    The decrease ``V+ <= (1 - alpha) V + alpha level`` then gives ``V_k <= level + (1 - alpha)^k (r - 1)
    level``: the errors stay within sqrt(r) times the set's bounds through the turn, and V is back
    below TURN_REENTRY * level after k periods.  Those are statements about the model the
    certificate is for; a turn is reported **not certified**, with the reason, when its motor peak
    exceeds robot.max_motor_speed (the commands saturate, outside every model), when its heading
    peak within a period exceeds a nonlinear certificate's heading bound (outside its channels), or
    when the next waypoint comes before the re-entry.  Floating point, not verified arithmetic."""
    ub = figures.get("ultimate_bound")
    wp = np.asarray(model.config.reference.path, dtype=float)
    if not ub or wp.shape[0] < 3 or "alpha" not in cert:
        return []
    if getattr(model, "turns", None) is not None:
        return _arc_turns(model, figures)
    lyap = lyapunov_of(model, cert)
    level = float(figures["ellipsoid_level"])
    alpha = float(cert["alpha"])
    cfg = model.config
    V, R, Ts = cfg.reference.speed, cfg.robot.gear_radius, model.Ts
    rho_max = cfg.robot.max_motor_speed
    seg = np.diff(wp, axis=0)
    headings = np.arctan2(seg[:, 1], seg[:, 0])
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    t_switch = np.cumsum(lengths)[:-1] / V
    chol = [np.linalg.cholesky(S) for S in lyap.S]
    heading_bound = figures.get("heading_bound")
    heading = float(figures.get("heading_within_period") or ub["e_theta"])  # |e_theta(t)| within a period
    out = []
    c_start = 1.0  # V at the switch <= c_start * level
    for i in range(1, headings.size):
        d = float(np.angle(np.exp(1j * (headings[i] - headings[i - 1]))))
        if d == 0.0:
            r = c_start
        else:
            cd, sd = np.cos(d), np.sin(d)
            Rd = np.array([[cd, sd], [-sd, cd]])
            J = np.eye(model.n_s)
            J[:2, :2] = Rd
            offsets = []
            for delta in (0.0, Ts):
                o = np.zeros(model.n_s)
                o[:2] = (Rd - np.eye(2)) @ np.array([V * delta, 0.0])
                o[2] = -d
                offsets.append(o)
            root = max(np.sqrt(c_start * level * max(float(np.linalg.eigvalsh(L.T @ J.T @ P @ J @ L)[-1]), 0.0))
                       + max(np.sqrt(max(float(o @ P @ o), 0.0)) for o in offsets)
                       for L in chol for P in lyap.P)
            r = round_up(root * root / level, 4)
        scale = float(np.sqrt(max(r, 1.0)))
        peak = {k: round_up(scale * float(ub[k]), 2) for k in ("e_x", "e_y", "e_theta")}
        motor = figures.get("motor_speed_bound")
        motor_peak = None if motor is None else round_up(V / R + scale * (float(motor) - V / R), 3)
        periods = 0 if r <= TURN_REENTRY else int(np.ceil(np.log((TURN_REENTRY - 1.0) / (r - 1.0)) / np.log(1.0 - alpha)))
        reentry = periods * Ts
        next_switch = float(lengths[i] / V)
        why = []
        if motor_peak is not None and rho_max is not None and motor_peak > rho_max:
            why.append(f"its motor peak {motor_peak:.3g} rad/s exceeds robot.max_motor_speed {rho_max:g}: the commands "
                       "saturate, outside the model")
        heading_peak = round_up(scale * heading, 2)
        if heading_bound is not None and heading_peak > float(heading_bound):
            why.append(f"its heading peak {heading_peak:.3g} rad within a period exceeds the certificate's heading bound "
                       f"{float(heading_bound):g} rad")
        if i < headings.size - 1 and reentry > next_switch:
            why.append(f"the next waypoint comes after {next_switch:.3g} s, before the re-entry after {reentry:.3g} s")
        note = ""
        if not why and heading_bound is None and peak["e_theta"] > TURN_LINEARIZATION_HEADING:
            note = (f"its heading peak {peak['e_theta']:.3g} rad lies beyond where the linearization holds "
                    f"(~{TURN_LINEARIZATION_HEADING:g} rad): a bound for the linearization only")
        out.append({"waypoint": i, "t_switch_s": float(t_switch[i - 1]), "turn_rad": d,
                    "V_over_level_at_switch": r, "peak": peak, "motor_speed_peak": motor_peak,
                    "periods_to_reenter": periods, "time_to_reenter_s": reentry, "certified": not why,
                    "reason": "; ".join(why), "note": note})
        # what this turn leaves at the next switch: at least floor(segment / Ts) - 1 periods of decay
        k_next = max(int(np.floor(next_switch / Ts)) - 1, 0)
        c_start = round_up(1.0 + (1.0 - alpha) ** k_next * max(r - 1.0, 0.0), 4)
    return out


def _arc_turns(model: Any, figures: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Each corner of a path rounded by arcs (reference.turn_radius): no frame jump, the reference
    turns at |w_k| <= V^D / r, which the certificate's vertices cover (model/arcs.py), so the certified
    set and its bounds hold through the turn: peak = the set's bounds for all t (``ultimate_bound_between_samples``,
    e_theta within the period), where the certificate states them (else at the samples), no re-entry."""
    from .law import PathTable

    cfg = model.config
    r = float(cfg.reference.turn_radius)
    table = PathTable(cfg.reference.path, cfg.reference.speed, r, cfg.network.sampling_time, cfg.reference.turn_ramp)
    ub = dict(figures["ultimate_bound"])
    for k, v in (figures.get("ultimate_bound_between_samples") or {}).items():
        if v is not None and k in ub:  # review, stop 47: the table showed the sampled bound as the turn's peak
            ub[k] = max(float(ub[k]), float(v))
    wbar = float(model.turns.max_yaw_rate)
    out = []
    for i, (d, t_arc) in enumerate(table.arcs, start=1):
        out.append({"waypoint": i, "t_switch_s": t_arc, "turn_rad": d, "V_over_level_at_switch": 1.0,
                    "peak": {k: float(ub[k]) for k in ("e_x", "e_y", "e_theta")},
                    "motor_speed_peak": figures.get("motor_speed_bound"), "periods_to_reenter": 0,
                    "time_to_reenter_s": 0.0, "certified": True, "reason": "",
                    "note": (f"along an arc of radius {r:g} m (reference yaw rate up to {wbar:.3g} rad/s, which the "
                             f"certificate covers): no frame jump, the certified set holds through the turn")})
    return out


# ------------------------------------------------------------------ any linear plant (plant: kind: lti)


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
    (n_c, d), owner (n_v,), fractions (n_v, d)) (:func:`robustsynth.model.lti.vertex_combinations`);
    E~ = [E U_0, ..., E U_d-1] over the kept directions (:func:`robustsynth.model.lti.kept_directions`; the
    dropped ones by Young's inequality: decay^2 / (1 + YOUNG_DELTA) and a term pbar n_drop / YOUNG_DELTA
    rho_D^2 F' F, pbar a bound on lambda_max(P)); E alone for the full-block multipliers (n_c, d).
    Instants with equal channels share one (:func:`robustsynth.model.lti.channel_groups`; ``merge=False``:
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
        from .model.lti import YOUNG_DELTA, channel_groups, kept_directions

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
                m_lost: int) -> dict[str, Any]:
    """A linear plant's gains file re-proven from its own numbers (K, P, multipliers, alpha, figures)
    against this plant and network: the vertex blocks of the over-approximation built for K (with
    the disturbance or the l2 gain's terms) and every output bound and input limit on the set.
    Returns {"ok", "reason"}."""
    from .model.lti import disturbance_bound, lifted_rows, lti_depth, over_approximation, vertex_combinations

    try:
        K = np.asarray(gains["K"], dtype=float)
        cert, figs = gains["certificate"], gains["certified"]
        P = np.asarray(cert["P"], dtype=float)
        eps = np.asarray(cert["multipliers"], dtype=float)
        alpha = float(cert["alpha"])
        pieces = int(cert["pieces"])
    except (KeyError, TypeError, ValueError) as exc:
        return {"ok": False, "reason": f"malformed certificate ({exc})"}
    A, B = plant["A"], plant["B"]
    n, m = B.shape
    d = (K.shape[1] - n) // m
    if d < lti_depth(tau_max, m_lost, Ts) or P.shape != (K.shape[1],) * 2:
        return {"ok": False, "reason": f"the gain keeps {d} commands; delays up to {tau_max + m_lost * Ts:g} s need "
                                       f"{lti_depth(tau_max, m_lost, Ts)}"}
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(K)) and np.all(np.isfinite(eps))):
        return {"ok": False, "reason": "non-finite entries"}
    if not float(np.min(np.linalg.eigvalsh((P + P.T) / 2.0))) > 0:
        return {"ok": False, "reason": "P is not positive definite"}
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
        return {"ok": False, "reason": f"multipliers {eps.shape}, the vertices need ({n_c}, {d}) or ({n_c}, {d}, {1 + n})"}
    chk = check_lti_scaled(pw, P, eps, float(np.sqrt(alpha)), verts, dist, out)
    if not chk["ok"]:
        return {"ok": False, "reason": f"vertex block {chk['failing']} not proven (min eigenvalue {chk['min_eig']:.3g})"}
    outs = [o for o in figs.get("outputs") or () if o.get("bound") is not None]
    if outs and not lti_within(P, C, np.array([o["bound"] for o in outs])).all():
        return {"ok": False, "reason": "an output bound is not proven on the set"}
    if figs.get("inputs") and not lti_within(P, K, np.array([u["limit"] for u in figs["inputs"]])).all():
        return {"ok": False, "reason": "an input limit is not proven on the set"}
    return {"ok": True, "reason": ""}
