"""The tracked robot's verdict: every check of a gain against a config, independent of how the gain was made
(:func:`verify_robot`, which :func:`robustsynth.verification.verify` hands a robot's model to).

Pass/fail rules (also in docs/reference/verification.md):

- certificate: the LMIs rebuilt in numpy from the file keep half their margin;
- frozen delays: spectral radius < 1 on the grid, and <= the certified decay rate + 1e-6;
- lifted model of the gain's kind, time-varying delays and slip (random, alternating, greedy worst
  case; for a turning certificate also random delays along arcs, on the kinematics linearized about
  them): V decreases as certified and states that start in the certified set never leave it
  (relative 1e-9);
- the nonlinear robot (Monte Carlo from steady states, extreme switching, a beam-search
  adversary): every run finite; it re-enters the certified set after every waypoint; on the steps
  the invariance claim covers (from the start, and after each waypoint from the re-entry on) its
  true lifted state stays in the certified set and |e_x|, |e_y|, |e_theta| and the commanded motor
  speed stay within the certified bounds themselves (``nonlinear_slack`` is fixed at 1); the motors
  saturate at rho_max in the simulation (``verification.motor_saturation``).  A gain without a
  certificate gets one searched for its fixed K (analysis LMIs, re-checked in numpy); either way it
  is judged after fixed transients: no divergence (|e_y| <= 1 m), commanded |rho| <= rho_max.

The rooms it uses: the form of a check and the tolerances (:mod:`robustsynth.verification.verdict`), the frozen-delay
and lifted-model checks (:mod:`robustsynth.verification.lifted_checks`), the checks on the nonlinear robot
(:mod:`.nonlinear_checks`) and the slip-compensated law's (:mod:`.compensated`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..artifacts.gains import as_gains
from ..certificate import CertificateCheck, check_certificate
from ..errors import InfeasibleError, InputError
from ..results import failed_names
from ..verification.checks import claimed_beyond
from ..verification.lifted_checks import _frozen, _lifted
from ..verification.verdict import _check
from .nonlinear_checks import _nonlinear, beside_on_one_core
from .simulate import SimResult

__all__ = ["VerificationResult", "verify_robot"]


@dataclass(frozen=True)
class VerificationResult:
    """The tracked robot's verdict: ``passed``, ``checks`` and ``failed_checks`` as every plant's
    :class:`~robustsynth.results.Verdict` has them, ``details`` (the certificate's re-check, the Monte Carlo, lifted
    and frozen-delay records) and ``to_dict()`` (the verdict with its details, plain data); the simulations behind
    it for the figures and the logs."""

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
    mask: np.ndarray | None = field(default=None, repr=False)  # (N, steps): steps the verdict covers
    # a slip-compensated law: its runs with the estimator in the loop on the true slip (robot_verification/compensated.py)
    compensated: Any = field(default=None, repr=False)
    config: Any = field(default=None, repr=False)  # the config it was verified against (the model's)

    @property
    def failed_checks(self) -> list[str]:
        return failed_names(self.checks)

    @property
    def details(self) -> dict[str, Any]:
        """How the checks were run: the certificate's numpy re-check and the Monte Carlo, lifted-model and
        frozen-delay records (a linear plant's Verdict has its delay families, starts and traces here)."""
        return {"certificate": self.certificate.to_dict(), "monte_carlo": self.monte_carlo, "lifted": self.lifted,
                "frozen": self.frozen}

    def to_dict(self) -> dict[str, Any]:
        """``passed``, ``checks`` and the details as plain data, as a Verdict's ``to_dict`` (verification.json adds
        the config, the gain's id and the figures' summaries)."""
        from ..artifacts.files import to_jsonable

        return to_jsonable({"passed": bool(self.passed), "checks": list(self.checks), **self.details})

    def lines(self, config: Any = None) -> list[str]:
        """What the CLI prints: each failed check (an Err, for stderr), the verdict with the worst Monte Carlo ratios,
        where the robot leaves its certified set and whom that blames (from the synthesis settings of ``config``,
        default the config it was verified against), the compensated law's runs, the turns."""
        from .lines import verdict_lines

        return verdict_lines(self, config if config is not None else self.config)


def _provenance(model: Any, gains: dict[str, Any]) -> str:
    """'the gain was made for config NAME, which differs in: key a -> b, ...' ('' when the gains file
    holds no config or the same design settings)."""
    from ..artifacts.gains import stored_config
    from ..config import config_to_dict

    try:
        made = stored_config(gains)
    except InputError:
        return "the config stored in the gains file is not valid"
    if made is None:
        return ""

    def flat(d: Any, pre: str = "") -> dict[str, Any]:
        out: dict[str, Any] = {}
        for k, v in d.items():
            key = f"{pre}{k}"
            if isinstance(v, dict):
                out.update(flat(v, key + "."))
            else:
                out[key] = v
        return out

    a, b = flat(config_to_dict(made)), flat(config_to_dict(model.user_config))
    # the path (reference.path, once verification.path) and the verification and physics settings make no gain
    keys = [k for k in sorted(set(a) | set(b)) if k not in ("name", "reference.path")
            and not k.startswith(("verification.", "physics.")) and a.get(k) != b.get(k)]
    if not keys:
        return ""
    shown = ", ".join(f"{k} {a.get(k)!r} -> {b.get(k)!r}" for k in keys[:6]) + (f" and {len(keys) - 6} more" if len(keys) > 6 else "")
    return f"the gain was made for config {made.name!r}, which differs from this one in: {shown}"



def verify_robot(model, gains: Any, runs: int | None = None, seed: int | None = None,
                 progress: Callable[[int, int], None] | None = None) -> VerificationResult:
    """Every check of ``gains`` against the tracked robot's ``model`` (:func:`robustsynth.verification.verify`'s for
    a :class:`~robustsynth.model.Model`): a gains.json mapping, the result of
    :func:`~robustsynth.synthesis.synthesize`, or a bare matrix K; ``runs`` / ``seed`` default to the config's
    ``verification`` settings, ``progress`` is called with (runs done, runs in all)."""
    from ..config import refuse_lti

    refuse_lti(model, "verify")
    gains = as_gains(model, gains)
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
    source = "gains file"
    if isinstance(cert_data, dict):
        cert = check_certificate(model, K, cert_data)
    else:
        # a gain from elsewhere: search a robust-stability certificate for this fixed K (the analysis
        # LMIs of `robustsynth margin`); it counts only once re-checked in numpy, like any other
        from ..synthesis.analysis import STABILITY_R, analyze_stability

        ana = analyze_stability(model, K, lyapunov="auto")
        if ana.certified:  # then the best decay rate it certifies (bisection, 6 steps: to 1/64 of the range)
            lo, hi = 0.0, STABILITY_R
            for _ in range(6):
                mid = (lo + hi) / 2.0
                faster = analyze_stability(model, K, lyapunov=ana.lyapunov, r=mid)
                if faster.certified:
                    hi, ana = mid, faster
                else:
                    lo = mid
            cert, cert_data, source = ana.check, ana.certificate, f"analysis of the fixed K ({ana.lyapunov} Lyapunov)"
            gains = dict(gains, certificate=cert_data)
        else:
            cert = CertificateCheck(False, (), {}, "no certificate in the gains file, and none found for the fixed K "
                                    f"by the analysis LMIs ({'; '.join(ana.attempts)})")
            source = None
    if not cert.passed and source == "gains file":  # say what the gain was made for, and what differs
        made_for = _provenance(model, gains)
        if made_for:
            cert = CertificateCheck(False, cert.checks, cert.figures, f"{cert.reason}; {made_for}")
    checks = [_check("certificate: LMIs re-checked in numpy", cert.passed,
                     None if not cert.checks else cert.min_eig_margin,
                     None if not cert.checks else 0.5 * float(cert_data.get("margin", float("nan"))),
                     cert.reason or f"{len(cert.checks)} conditions, smallest margin found {cert.min_eig_margin:.3g}, every "
                     "LMI proven in verified arithmetic (largest rounding allowance "
                     f"{max((c.get('rounding_allowance') or 0.0) for c in cert.checks):.1e})"
                     + ("" if source == "gains file" else f"; certificate from the {source}: robust stability with "
                        f"decay rate {cert.figures.get('decay_rate', float('nan')):.4g}, no error bounds"))]
    claimed = gains.get("certified") or {}
    if cert.passed and isinstance(claimed, dict):
        mism = claimed_beyond(claimed, cert.figures)
        checks.append(_check("certificate: figures in the file match the re-check", not mism, None, None,
                             "claims more than the re-check proves: " + ", ".join(mism) if mism else
                             "every certified figure reproduced, or claimed weaker than the re-check proves (rel 1e-6)"))
    try:  # a config no controller can follow (a motor too slow for its slip) is named as such
        model.check_physical_feasibility()
    except InfeasibleError as exc:
        checks.append(_check("physics: the config's slip can be compensated within the motor limit", False, None, None,
                             str(exc)))
    cert_rate = cert.figures.get("decay_rate") if cert.passed else None
    fchecks, frozen = _frozen(model, K, cert_rate)
    # the lifted model's checks run on one core beside the nonlinear robot's (the same whenever they run)
    with beside_on_one_core(lambda: _lifted(model, K, cert, gains)) as lifted_job:
        nchecks, mc, sim, ext, scen, v_ratio, mask = _nonlinear(model, K, cert, gains, runs, seed, progress)
        lchecks, lifted, traces = lifted_job.result()
    checks += fchecks + lchecks + nchecks
    comp_runs = None
    if model.compensation is not None:  # the runs above keep the certificate's condition; these close the loop
        from .compensated import compensated_checks  # on the true slip with the estimator (docs/theory.md §18)

        cchecks, mc["compensated"], comp_runs = compensated_checks(model, K, cert, gains, runs, seed)
        checks += cchecks
    passed = all(c["passed"] for c in checks)
    mc["certificate_source"] = source
    return VerificationResult(passed, tuple(checks), cert, mc, lifted, frozen, sim, ext, scen, traces, K, dict(gains),
                              v_ratio, mask, comp_runs, model.config)
