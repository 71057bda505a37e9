"""``verify``: every check of a gain against a config, independent of how the gain was made.

Pass/fail rules (also in the README):

- certificate: the LMIs rebuilt in numpy from the file keep half their margin;
- frozen delays: spectral radius < 1 on the grid, and <= the certified decay rate + 1e-6;
- lifted model, time-varying delays (random, alternating, greedy worst case): V decreases as
  certified and states that start in the certified ellipsoid never leave it (relative 1e-9);
- nonlinear Monte Carlo: every run finite; after the transients, the largest |e_x|, |e_y|,
  |e_theta| and commanded motor speed over all runs stay within ``nonlinear_slack`` x the
  certified bound (for objectives without bounds: |e_y| <= 1 m, i.e. no divergence).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..errors import InputError
from .certificate import CertificateCheck, check_certificate
from .lifted import (
    alternating_delays,
    closed_loop_run,
    frozen_instant_grid,
    frozen_spectral_radius,
    greedy_worst_case,
    random_delays,
    slip_vertices,
)
from .simulate import SimResult, draw_scenario, make_path, simulate

__all__ = ["VerificationResult", "verify", "load_gains", "SPECTRAL_TOL", "LEVEL_TOL", "DIVERGENCE_LIMIT"]

SPECTRAL_TOL = 1e-6  # frozen spectral radius may exceed the certified rate by round-off only
LEVEL_TOL = 1e-9  # relative round-off allowed on V in the lifted-model checks
DIVERGENCE_LIMIT = 1.0  # m: |e_y| beyond this after the transients is divergence (no-bound objectives)
MAX_GAINS_BYTES = 8 << 20


@dataclass(frozen=True)
class VerificationResult:
    passed: bool
    checks: tuple[dict[str, Any], ...]
    certificate: CertificateCheck
    monte_carlo: dict[str, Any]
    lifted: dict[str, Any]
    frozen: dict[str, Any]
    sim: SimResult | None = field(default=None, repr=False)
    extreme_sim: SimResult | None = field(default=None, repr=False)
    scenario: Any = field(default=None, repr=False)
    lifted_traces: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    K: np.ndarray | None = field(default=None, repr=False)
    gains: dict[str, Any] = field(default_factory=dict, repr=False)
    nonlinear_V_over_level: np.ndarray | None = field(default=None, repr=False)

    @property
    def failed_checks(self) -> list[str]:
        return [c["name"] for c in self.checks if not c["passed"]]


def _mat_scalar(v: Any) -> Any:
    a = np.asarray(v)
    if a.dtype.kind in "US":
        return str(a.reshape(-1)[0]) if a.size else ""
    a = a.astype(float).reshape(-1)
    return None if a.size == 0 or not np.isfinite(a[0]) else float(a[0])


def _load_mat(p: Path) -> dict[str, Any]:
    """A gains.mat (ours, or any .mat with a matrix K) as the gains.json mapping.  The certificate
    is rebuilt when its parts (objective, Q, M, margin, ...) are present."""
    from scipy.io import loadmat

    try:
        m = loadmat(p, squeeze_me=False)
    except Exception as exc:  # scipy raises several types for a damaged file
        raise InputError(f"{p}: not a readable MATLAB .mat file ({exc})") from None
    if "K" not in m:
        raise InputError(f"{p}: K: required variable is missing")
    data: dict[str, Any] = {"K": m["K"]}  # validated by load_gains like a JSON K
    if all(k in m for k in ("objective", "Q", "M", "margin")):
        Q = np.asarray(m["Q"], dtype=float)
        M = np.asarray(m["M"], dtype=float)
        beta = np.asarray(m.get("beta", np.nan), dtype=float).reshape(-1)
        data["certificate"] = {
            "objective": _mat_scalar(m["objective"]),
            "Q": Q,
            "P": np.asarray(m["P"], dtype=float) if "P" in m else np.linalg.inv(Q),
            "multipliers": {"kind": _mat_scalar(m.get("multiplier", "structured")), "M": M.reshape(M.shape if M.size else (0, 0))},
            "alpha": _mat_scalar(m.get("alpha", np.nan)),
            "beta": None if beta.size == 0 or not np.all(np.isfinite(beta)) else beta,
            "r2": _mat_scalar(m.get("r2", np.nan)),
            "gamma2": _mat_scalar(m.get("gamma2", np.nan)),
            "motor_limits_enforced": bool(_mat_scalar(m.get("motor_limits_enforced", 0.0))),
            "margin": _mat_scalar(m["margin"]),
        }
    return data


def load_gains(path: str | Path) -> dict[str, Any]:
    """Read a gains.json (or a .mat with a matrix K); InputError with the key path on anything
    malformed."""
    p = Path(path)
    try:
        if p.stat().st_size > MAX_GAINS_BYTES:
            raise InputError(f"{p}: file is larger than 8 MiB")
        data = _load_mat(p) if p.suffix.lower() == ".mat" else json.loads(p.read_text(encoding="utf-8"))
    except InputError:
        raise
    except FileNotFoundError:
        raise InputError(f"{p}: gains file not found (run `robustsynth synthesize` first or pass --gains)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{p}: cannot read ({exc})") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{p}: invalid JSON at line {exc.lineno}: {exc.msg}") from None
    if not isinstance(data, dict):
        raise InputError(f"{p}: must be a JSON object")
    if "K" not in data:
        raise InputError(f"{p}: K: required key is missing")
    try:
        K = np.asarray(data["K"], dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{p}: K: must be a matrix of numbers (list of rows)") from None
    if K.ndim != 2 or not np.all(np.isfinite(K)):
        raise InputError(f"{p}: K: must be a finite matrix (list of rows)")
    return data


def _check(name: str, passed: bool, value: Any, threshold: Any, detail: str) -> dict[str, Any]:
    return {"name": name, "passed": bool(passed), "value": value, "threshold": threshold, "detail": detail}


def _V(xi: np.ndarray, P: np.ndarray) -> np.ndarray:
    return np.einsum("...i,ij,...j->...", xi, P, xi)


def _frozen(model, K, cert_rate: float | None) -> tuple[list[dict], dict]:
    n = model.config.verification.frozen_grid
    s = frozen_instant_grid(model, n)
    rho = frozen_spectral_radius(model, K, s)
    # constant delays tau: the physically frozen sweep used in the figure
    dl = model.config.network.delay
    taus = np.linspace(dl.min, dl.max, max(n, 2))
    s_tau = model.s_tilde(np.repeat(taus[:, None], model.d_hi + 1, axis=1))[:, 0, :]
    rho_tau = frozen_spectral_radius(model, K, s_tau)
    worst = float(np.max(rho))
    checks = [_check("frozen delays: spectral radius < 1", worst < 1.0, worst, 1.0,
                     f"{s.shape[0]} frozen switching-instant vectors over the admissible ranges")]
    if cert_rate is not None:
        checks.append(_check("frozen delays: spectral radius <= certified decay rate", worst <= cert_rate + SPECTRAL_TOL,
                             worst, cert_rate, f"tolerance {SPECTRAL_TOL:g}"))
    return checks, {"grid_points": int(s.shape[0]), "max_spectral_radius": worst,
                    "tau": taus, "spectral_radius_vs_tau": rho_tau}


def _lifted(model, K, cert: CertificateCheck, gains: dict) -> tuple[list[dict], dict, dict]:
    vc = model.config.verification
    rng = np.random.default_rng(vc.seed + 1)
    N, steps = vc.lifted_runs, vc.lifted_steps
    if not cert.passed:
        # no valid certificate: only look for divergence under the patterns
        xi0 = rng.normal(scale=0.05, size=(N, model.n_s))
        d = slip_vertices(model)[rng.integers(0, 4, size=(N, steps))]
        xi = closed_loop_run(model, K, random_delays(model, rng, N, steps), d, xi0)
        with np.errstate(all="ignore"):
            grow = float(np.nanmax(np.abs(xi[:, -1])) / max(np.max(np.abs(xi0)), 1e-12))
        return ([_check("lifted model: no certificate to test against", False, grow, None,
                        "the certificate check failed, so V and the ellipsoid are not available; "
                        f"value = growth of max|xi| over {steps} steps under random delays")],
                {"growth": grow}, {})
    c = gains["certificate"]
    P = np.asarray(c["P"], dtype=float)
    objective = c["objective"]
    corners = slip_vertices(model)
    traces: dict[str, np.ndarray] = {}
    summary: dict[str, Any] = {"runs": N, "steps": steps}
    checks = []
    if objective == "ultimate-bound":
        level = float(cert.figures["ellipsoid_level"])
        alpha = float(c["alpha"])
        beta = np.asarray(c["beta"], dtype=float)
        # starting points: on the ellipsoid's boundary, and far outside it (decay towards it)
        z = rng.normal(size=(N, model.n_s))
        z /= np.sqrt(_V(z, P))[:, None]
        xi_in = z * math.sqrt(level)
        xi_out = z * math.sqrt(level) * 5.0
        d = corners[rng.integers(0, 4, size=(N, steps))]
        patterns = {
            "random": random_delays(model, rng, N, steps),
            "alternating": alternating_delays(model, N, steps),
        }
        worst_ratio, worst_dec = 0.0, -np.inf
        for name, taus in patterns.items():
            for start_name, xi0 in (("boundary", xi_in), ("outside", xi_out)):
                xi = closed_loop_run(model, K, taus, d, xi0)
                V = _V(xi, P)
                w = model.slip.coordinates(d)  # d = W w, |w_i| <= 1
                rhs = (1 - alpha) * V[:, :-1] + (w**2) @ beta
                worst_dec = max(worst_dec, float(np.max((V[:, 1:] - rhs) / np.maximum(V[:, :-1], level))))
                if start_name == "boundary":
                    worst_ratio = max(worst_ratio, float(np.max(V) / level))
                traces[f"{name}/{start_name}"] = V
        xg, _, _ = greedy_worst_case(model, K, P, xi_in[: min(N, 50)], min(steps, 100))
        Vg = _V(xg, P)
        traces["greedy/boundary"] = Vg
        worst_ratio = max(worst_ratio, float(np.max(Vg) / level))
        checks.append(_check("lifted model: V(xi+) <= (1-alpha) V(xi) + sum beta_i w_i^2", worst_dec <= LEVEL_TOL,
                             worst_dec, LEVEL_TOL, "largest excess relative to max(V, level); random and alternating delays, slip corners"))
        checks.append(_check("lifted model: states stay in the certified ellipsoid", worst_ratio <= 1 + LEVEL_TOL,
                             worst_ratio, 1.0, "max V/level from the boundary; random, alternating, greedy worst case"))
        summary.update({"ellipsoid_level": level, "max_V_over_level": worst_ratio, "max_decrease_excess": worst_dec})
    else:
        r2 = float(cert.figures["decay_rate"]) ** 2 if cert.figures.get("decay_rate") else 1.0
        xi0 = rng.normal(size=(N, model.n_s))
        zero = np.zeros((N, steps, 2))
        worst = -np.inf
        for name, taus in (("random", random_delays(model, rng, N, steps)), ("alternating", alternating_delays(model, N, steps))):
            xi = closed_loop_run(model, K, taus, zero, xi0)
            V = _V(xi, P)
            traces[f"{name}/no slip"] = V
            worst = max(worst, float(np.max(V[:, 1:] / V[:, :-1])))
        xg, _, _ = greedy_worst_case(model, K, P, xi0[: min(N, 50)], min(steps, 100), slip=False)
        Vg = _V(xg, P)
        traces["greedy/no slip"] = Vg
        worst = max(worst, float(np.max(Vg[:, 1:] / Vg[:, :-1])))
        thr = r2 if objective == "stability" else 1.0
        checks.append(_check("lifted model: V(xi+) <= r^2 V(xi) without slip", worst <= thr * (1 + LEVEL_TOL),
                             worst, thr, "largest V ratio per step; random, alternating, greedy worst case"))
        summary.update({"max_V_ratio": worst})
    return checks, summary, traces


def _maxima(sim: SimResult) -> dict[str, np.ndarray]:
    st = sim.settled
    e = np.abs(sim.e[:, st]) if np.any(st) else np.zeros((sim.e.shape[0], 1, 3))
    rho_st = st[:-1]
    rho = np.abs(sim.rho[:, rho_st]) if np.any(rho_st) else np.zeros((sim.rho.shape[0], 1, 2))
    return {
        "e_x": np.max(e[..., 0], axis=1),
        "e_y": np.max(e[..., 1], axis=1),
        "e_theta": np.max(e[..., 2], axis=1),
        "motor_speed": np.max(rho, axis=(1, 2)),
        "motor_speed_all": np.max(np.abs(sim.rho), axis=(1, 2)),
    }


def _stats(x: np.ndarray) -> dict[str, float]:
    return {"max": float(np.max(x)), "p95": float(np.percentile(x, 95)), "mean": float(np.mean(x)),
            "worst_run": int(np.argmax(x))}


def _nonlinear(model, K, cert: CertificateCheck, P: np.ndarray | None, runs: int, seed: int, progress):
    vc = model.config.verification
    path = make_path(vc.path, model.V)
    steps = max(1, int(math.floor(path.duration / model.Ts + 1e-9)))
    scen = draw_scenario(model, runs, seed, steps, path)
    sim = simulate(model, K, path, scen, vc.transient, progress)
    ext_scen = draw_scenario(model, 4, seed + 2, steps, path, delays="alternating", slip="steps")
    ext = simulate(model, K, path, ext_scen, vc.transient)
    mx = _maxima(sim)
    mx_ext = _maxima(ext)
    finite = bool(np.all(np.isfinite(sim.q)) and np.all(np.isfinite(ext.q)))
    ub = cert.figures.get("ultimate_bound") if cert.passed else None
    slack = vc.nonlinear_slack
    checks = [_check("nonlinear: every run finite", finite, None, None, f"{runs} Monte Carlo runs + 4 extreme-switching runs")]
    n_settled = int(np.sum(sim.settled))
    if n_settled == 0:  # otherwise every maximum below would be vacuous
        checks.append(_check("nonlinear: steps after the transients exist", False, 0, 1,
                             "no sampling instant lies outside the transients: lengthen verification.path or "
                             "shorten verification.transient"))
    mc: dict[str, Any] = {
        "runs": runs, "seed": seed, "steps": steps, "duration_s": steps * model.Ts, "transient_s": vc.transient,
        "settled_steps": int(np.sum(sim.settled)),
        "slip_profiles": {p: int(sum(1 for x in scen.profiles if x == p)) for p in sorted(set(scen.profiles))},
        "delays": "uniform iid in [tau_min, tau_max]; plus 4 runs alternating min/max with step slip",
        "maxima": {k: _stats(v) for k, v in mx.items()},
        "extreme_maxima": {k: float(np.max(v)) for k, v in mx_ext.items()},
        "certified": {},
        "ratio_to_certified": {},
        "nonlinear_slack": slack,
    }
    both = {k: np.concatenate([mx[k], mx_ext[k]]) for k in mx}
    v_ratio = None
    if ub and P is not None:
        # Lyapunov function of the nonlinear robot's true lifted state, relative to the invariant level:
        # <= 1 means inside the certified ellipsoid (reported, not a pass/fail rule)
        xi_true = np.concatenate([sim.e[:, :-1], sim.xi[:, :, model.n_e :]], axis=2)
        v_ratio = _V(xi_true, P) / float(cert.figures["ellipsoid_level"])
        st = sim.settled[:-1]
        if np.any(st):
            mc["V_over_level"] = {
                "max_after_transients": float(np.max(v_ratio[:, st])),
                "fraction_of_settled_steps_outside": float(np.mean(v_ratio[:, st] > 1.0)),
            }
    if ub:
        for key, unit in (("e_x", "m"), ("e_y", "m"), ("e_theta", "rad")):
            worst = float(np.max(both[key]))
            ratio = worst / ub[key]
            mc["certified"][key] = ub[key]
            mc["ratio_to_certified"][key] = ratio
            checks.append(_check(f"nonlinear: max |{key}| after transients <= {slack:g} x certified", ratio <= slack,
                                 worst, slack * ub[key], f"ratio to the linear certificate {ratio:.3f} ({unit})"))
        msb = cert.figures.get("motor_speed_bound")
        if msb is not None:
            worst = float(np.max(both["motor_speed"]))
            ratio = worst / msb
            mc["certified"]["motor_speed"] = msb
            mc["ratio_to_certified"]["motor_speed"] = ratio
            checks.append(_check(f"nonlinear: max |rho| after transients <= {slack:g} x certified", ratio <= slack,
                                 worst, slack * msb, f"ratio {ratio:.3f} (rad/s); max over whole runs {float(np.max(both['motor_speed_all'])):.3f} rad/s"))
    else:
        worst = float(np.max(both["e_y"]))
        checks.append(_check("nonlinear: no divergence (max |e_y| after transients)", finite and worst <= DIVERGENCE_LIMIT,
                             worst, DIVERGENCE_LIMIT, "no certified bound to compare with; divergence limit in m"))
    return checks, mc, sim, ext, scen, v_ratio


def verify(model, gains: dict[str, Any], runs: int | None = None, seed: int | None = None,
           progress: Callable[[int, int], None] | None = None) -> VerificationResult:
    """Run every check of ``gains`` (a gains.json mapping) against ``model``."""
    vc = model.config.verification
    runs = vc.runs if runs is None else runs
    seed = vc.seed if seed is None else seed
    if runs < 1:
        raise InputError(f"--runs: must be >= 1 (got {runs})")
    K = np.asarray(gains["K"], dtype=float)
    if K.shape != (model.n_u, model.n_s):
        raise InputError(f"K: has shape {K.shape}, the config's model needs {(model.n_u, model.n_s)} "
                         f"(d_hi = {model.d_hi}); was the gain made for another delay range?")
    cert_data = gains.get("certificate")
    if isinstance(cert_data, dict):
        cert = check_certificate(model, K, cert_data)
    else:
        cert = CertificateCheck(False, (), {}, "no certificate in the gains file")
    checks = [_check("certificate: LMIs re-checked in numpy", cert.passed,
                     None if not cert.checks else cert.min_eig_margin,
                     None if not cert.checks else 0.5 * float(cert_data.get("margin", float("nan"))),
                     cert.reason or f"{len(cert.checks)} conditions, smallest margin found {cert.min_eig_margin:.3g}")]
    claimed = gains.get("certified") or {}
    if cert.passed and isinstance(claimed, dict):
        mism = [k for k in ("decay_rate", "motor_speed_bound", "hinf_gain")
                if claimed.get(k) is not None and cert.figures.get(k) is not None
                and not math.isclose(float(claimed[k]), float(cert.figures[k]), rel_tol=1e-6)]
        ubc, ubf = claimed.get("ultimate_bound"), cert.figures.get("ultimate_bound")
        if ubc and ubf:
            mism += [f"ultimate_bound.{k}" for k in ubf if not math.isclose(float(ubc.get(k, float("nan"))), ubf[k], rel_tol=1e-6)]
        checks.append(_check("certificate: figures in the file match the re-check", not mism, None, None,
                             "mismatch: " + ", ".join(mism) if mism else "all certified figures reproduced (rel 1e-6)"))
    cert_rate = cert.figures.get("decay_rate") if cert.passed else None
    fchecks, frozen = _frozen(model, K, cert_rate)
    lchecks, lifted, traces = _lifted(model, K, cert, gains)
    P = np.asarray(cert_data["P"], dtype=float) if cert.passed else None
    nchecks, mc, sim, ext, scen, v_ratio = _nonlinear(model, K, cert, P, runs, seed, progress)
    checks += fchecks + lchecks + nchecks
    passed = all(c["passed"] for c in checks)
    return VerificationResult(passed, tuple(checks), cert, mc, lifted, frozen, sim, ext, scen, traces, K, dict(gains),
                              v_ratio)
