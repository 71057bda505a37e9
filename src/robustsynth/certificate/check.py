"""Independent, numpy-only re-check of an LMI certificate (docs/theory.md §6).

The LMIs are rebuilt at every vertex of the model from the certificate's values (``Q`` or
``G, S_m``, the multipliers ``M_i``, ``beta``, ``alpha`` / ``r2`` / ``gamma2``) and the gain ``K``
*as written* (``Y = K Q`` or ``Y = K G``), never from the solver's internal variables; each must
be proven ``>= threshold I`` in verified arithmetic (:mod:`robustsynth.verified`).
The certified figures (decay rate, ellipsoid bounds in m and rad, motor-speed bound in rad/s,
l2 gain) are computed here from the same values, so every number written as certified has
passed this check; they are rounded outwards.

What each objective proves is a module of :mod:`.objectives` (its ``rows``, named by the objective's descriptor
in :mod:`robustsynth.objectives`); this module rebuilds what they share and gives the verdict.  The rooms beside
it: the LMIs at a vertex (:mod:`.lmis`), the model a certificate is written on
(:mod:`.rebuild`), the figures on the set and between the samples (:mod:`.bounds`), the Lyapunov
function the judges evaluate (:mod:`.lyapunov`), the bounds through waypoint turns (:mod:`.turns`)
and a linear plant's certificate (:mod:`.lti`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..results import CertificateCheck
from ..verified import (assembly_radius, assembly_radius_batch, proves_at_least, proves_at_least_batch, rump_shift,
                        rump_shift_batch)
from ..objectives import certified_keys
from .lmis import _AbsVertex, _stacks, _sym, dense_multiplier, multiplier_structure_error
from .rebuild import model_of_certificate

__all__ = [
    "CHECK_FRACTION",
    "VARYING_FAILURES",
    "varying_failures",
    "CertificateCheck",
    "check_certificate",
    "recheck_gains",
]

# A certificate passes when every LMI satisfies  lambda_min >= CHECK_FRACTION * margin,
# i.e. it keeps at least this fraction of the margin it was solved with.
CHECK_FRACTION = 0.5
# the key of the within-period family's item that lists its failing vertices (indices into the family of
# Model.with_cuts: covering_vertices or varying)
VARYING_FAILURES = "failing_vertices"
SYMMETRY_TOL = 1e-9  # relative asymmetry allowed in Q and M read from a file


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
    rows = _rows_of(objective)
    if rows is None:
        return _fail(f"unknown objective {objective!r}")
    K = _arr(K, "K")
    n_s, n_u = model.n_s, model.n_u
    made_for = cert.get("model", "paper")
    if made_for != model.kind:
        return _fail(f"the certificate was made for the {made_for!r} model, the config asks for {model.kind!r} "
                     "(synthesis.model)")
    if K.shape != (n_u, n_s):
        return _fail(f"K has shape {K.shape}, expected {(n_u, n_s)}")
    model = model_of_certificate(model, cert, objective)
    if isinstance(model, str):
        return _fail(model)
    parts = _lyapunov_parts(model, cert, n_s)
    if isinstance(parts, str):
        return _fail(parts)
    lyap, X, conds, mats = parts
    Ms = _multipliers(model, cert["multipliers"])
    if isinstance(Ms, str):
        return _fail(Ms)
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
    checks = _positivity(model, lyap, mats, Ms, threshold)
    # slip changing within a period (docs/theory.md §11): a common certificate must also hold at the
    # vertices that cover every slip history; the others state that they assume it constant
    varying, varying_reason = model.slip_variation(lyap, objective)
    group_multipliers = _group_multipliers(model, varying, Ms)
    if group_multipliers is None:
        return _fail("the within-period vertices' channels have no multiplier (no vertex of their group)", checks)
    family = _Family(model, Ms, conds, K @ X, np.abs(K) @ np.abs(X),  # Y's magnitude: Y = K X is computed, not given
                     threshold, X.shape[0] * (K.shape[0] + 1) + len(mats), varying, group_multipliers)
    figures: dict[str, Any] = dict.fromkeys(certified_keys(), None)  # each objective's figures, None until proven
    figures["robust_stability"] = False
    within = "covered" if varying else f"assumed constant: {varying_reason}"
    failed = rows(cert, family, K, X, lyap, mats, checks, figures)
    if failed is not None:
        return failed
    return _verdict(checks, figures, within)


def _multipliers(model: Any, mult: Mapping[str, Any]) -> list[np.ndarray] | str:
    """The certificate's multipliers, one per vertex (symmetrized), or why they do not fit (a string)."""
    n_v = len(model.vertices)
    raw = mult["M"]
    if len(raw) != n_v:
        return f"multipliers.M has {len(raw)} entries, expected one per vertex ({n_v})"
    Ms = []
    for i, (x, v) in enumerate(zip(raw, model.vertices)):
        M = _arr(dense_multiplier(x), f"multipliers.M[{i}]")
        if M.size != v.n_q * v.n_q:
            return (f"multipliers.M[{i}] has {M.size} entries, expected {v.n_q} x {v.n_q} (the vertex's uncertainty "
                    "channels): the certificate was made for other channels")
        M = M.reshape(v.n_q, v.n_q)
        err = _symmetric(M, f"multipliers.M[{i}]") or multiplier_structure_error(
            M, v.n_q // 3, mult.get("kind", "structured"), v.diagonal)
        if err:
            return err
        Ms.append(_sym(M))
    return Ms


def _lmin(L: np.ndarray) -> float:
    """The smallest eigenvalue of L (floating point)."""
    return float(np.linalg.eigvalsh(L)[0])


def _positivity(model: Any, lyap: str, mats: list[np.ndarray], Ms: list[np.ndarray], threshold: float
                ) -> list[dict[str, Any]]:
    """The items that the Lyapunov matrices and the multipliers are >= threshold I."""
    checks = []
    for m, Sm in enumerate(mats):
        nm = "Q > 0" if lyap == "common" else f"S[{m}] > 0"
        ok, allow = _proof(Sm, None, 0, threshold)
        checks.append(_item(nm, _lmin(Sm), threshold, verified=ok, allowance=allow, unproven="" if ok else nm))
    if any(v.n_q for v in model.vertices):
        idx = [i for i, v in enumerate(model.vertices) if v.n_q]
        worst = min((_lmin(Ms[i]), i) for i in idx)
        proofs = [(_proof(Ms[i], None, 0, threshold), i) for i in idx]
        bad = [model.vertices[i].label for (ok, _), i in proofs if not ok]
        checks.append(_item(f"M_i > 0 (multipliers, {len(idx)} vertices)", worst[0], threshold,
                            model.vertices[worst[1]].label, verified=not bad,
                            allowance=max(a for (_, a), _ in proofs), unproven=bad[0] if bad else ""))
    return checks


def _group_multipliers(model: Any, varying: tuple, Ms: list[np.ndarray]) -> np.ndarray | None:
    """The within-period vertices' multipliers: with channels (§9) each takes the multiplier of its group's
    first vertex (None when a group has no vertex); an empty (0, 0) without."""
    group_multipliers = np.zeros((0, 0))
    if varying and varying[0].n_q:
        first: dict[int, int] = {}
        for i, v in enumerate(model.vertices):
            if v.group >= 0:
                first.setdefault(v.group, i)
        if any(v.group not in first for v in varying):
            return None
        group_multipliers = np.stack([Ms[first[v.group]] for v in varying])
    return group_multipliers


@dataclass(frozen=True)
class _Family:
    """What every vertex condition of one certificate is assembled and proven from: the model, the
    multipliers, the Lyapunov conditions per vertex (:func:`_lyapunov_parts`), Y = K X and its magnitude,
    the threshold, the products per entry besides the matrix's own (``base``), the within-period
    vertices and their multipliers."""

    model: Any
    Ms: list[np.ndarray]
    conds: list
    Y: np.ndarray
    aY: np.ndarray
    threshold: float
    base: int
    varying: tuple
    group_multipliers: np.ndarray

    def terms(self, k: int) -> int:
        """The products per entry of a k x k condition."""
        return 2 * k + self.base

    def items(self, name: str, build) -> list[dict[str, Any]]:
        """Every vertex condition: its smallest eigenvalue (floating point) and its verified proof
        (``build(v, M, left, right, Y, mag)`` assembles the matrix, or its magnitude); one item per
        family of vertices."""
        items = [self._at_vertices(name, build)]
        if self.varying:
            items.append(self._within_period(name, build))
        return items

    def _at_vertices(self, name: str, build) -> dict[str, Any]:
        worst_val, worst_lab, count, allowance, unproven = np.inf, "", 0, 0.0, ""
        for i, v in enumerate(self.model.vertices):
            av, aM = _AbsVertex(v), np.abs(self.Ms[i])
            for left, right, lab, aleft, aright in self.conds[i]:
                L = build(v, self.Ms[i], left, right, self.Y, False)
                val = _lmin(L)
                count += 1
                if val < worst_val:
                    worst_val = val
                    worst_lab = v.label + lab
                mag = build(av, aM, aleft, aright, self.aY, True)
                ok, allow = _proof(L, mag, self.terms(L.shape[0]), self.threshold)
                allowance = max(allowance, allow)
                if not ok and not unproven:
                    unproven = v.label + lab
        return _item(f"{name} at {count} vertex condition{'s' if count != 1 else ''}", worst_val, self.threshold,
                     worst_lab, verified=not unproven, allowance=allowance, unproven=unproven)

    def _within_period(self, name: str, build) -> dict[str, Any]:
        """One stack: the common certificate's single condition at every within-period vertex (§11)."""
        varying, threshold = self.varying, self.threshold
        left, right, _, aleft, aright = self.conds[0][0]
        stack, abs_stack = _stacks(varying)
        Mv = self.group_multipliers
        L = build(stack, Mv, left, right, self.Y, False)
        vals = np.linalg.eigvalsh(L)[:, 0]
        radius = assembly_radius_batch(build(abs_stack, np.abs(Mv), aleft, aright, self.aY, True), self.terms(L.shape[-1]))
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
        return item


def _rows_of(name: Any) -> Any:
    """The ``rows`` of the objective ``name``'s certificate (its descriptor's ``check`` module), or None."""
    import importlib

    from ..objectives import OBJECTIVES

    obj = OBJECTIVES.get(name) if isinstance(name, str) else None
    if obj is None or obj.check is None:
        return None
    try:
        rows = importlib.import_module(obj.check).rows
    except (ImportError, AttributeError) as exc:  # a defect of the registry: one line, not a traceback
        raise RuntimeError(f"objective {name}: its certificate's rows ({obj.check}.rows) are missing ({exc})") from None
    return rows


def _verdict(checks: list[dict[str, Any]], figures: dict[str, Any], within: str) -> CertificateCheck:
    """The check of every condition: passed when all hold (else the figures are withdrawn), and the reason."""
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
