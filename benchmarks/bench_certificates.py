"""Issue 8's targets, measured: for the default robot with each certificate variant (paper model,
slip-aware common Q, slip-dependent, delay- and path-dependent, rate-bounded, integral action), the synthesis time, the
certified |e_y|, and what the nonlinear robot does on >= 1000 Monte Carlo runs plus the extreme runs and the
adversarial search (largest |e_y|, certified / observed, samples outside the certified set, verdict).

Issue 26's figures, side by side in the same run: each variant is synthesized twice, with
``synthesis.symmetry: off`` (every vertex condition posed) and ``auto`` (the mirror-invariant
certificate, docs/theory.md §6h); the second line gives where the time goes (``SynthesisResult.timings``:
writing the LMIs, cvxpy, the solver, the numpy re-check; solves) and the certified |e_y| against the
bound the same certificate gave before §6i (the largest entry over every Lyapunov matrix).

    .venv/bin/python benchmarks/run_all.py bench_certificates
"""

from __future__ import annotations

import time

RUNS = 1000

VARIANTS = {
    "paper model (reproduction)": {"synthesis.model": "paper"},
    "slip-aware, common Q (default)": {},
    "slip-aware, slip-dependent Lyapunov": {"synthesis.lyapunov": "slip-dependent"},
    "slip-aware, delay-dependent Lyapunov": {"synthesis.lyapunov": "delay-dependent"},
    "slip-aware, path-dependent Lyapunov": {"synthesis.lyapunov": "path-dependent"},
    "slip-aware, slip-dependent, slip.max_rate 0.5": {"synthesis.lyapunov": "slip-dependent", "slip.max_rate": 0.5},
    "slip-aware, integral action, rho_max 20": {"synthesis.integral_action": True, "robot.max_motor_speed": 20.0},
    "integral, rho_max 20, max_rate 0.5, delay-dep.": {"synthesis.integral_action": True, "robot.max_motor_speed": 20.0,
                                                       "slip.max_rate": 0.5, "synthesis.lyapunov": "delay-dependent"},
    "slip-aware, dropouts max_consecutive 2": {"network.dropouts.max_consecutive": 2},
}


def _old_bound(res) -> float:
    """|e_y| as certificates bounded it before docs/theory.md §6i: the largest (2,2) entry over every matrix."""
    import numpy as np

    c = res.certificate
    mats = c["S"] if "S" in c else [c["Q"]]
    return float(np.sqrt(res.check.figures["ellipsoid_level"] * max(float(np.asarray(m)[1, 1]) for m in mats)))


def main() -> dict[str, dict]:
    from robustsynth import build_model, default_config, synthesize
    from robustsynth import verify
    from robustsynth.errors import RobustSynthError
    from robustsynth.artifacts.gains import gains_dict

    out: dict[str, dict] = {}
    print(f"{'variant':48s} {'synth [s]':>9s} {'cert |e_y| [cm]':>15s} {'robot max [cm]':>14s} {'cert/robot':>10s}"
          f" {'steady |e_y*|':>13s} {'V/level':>8s} {'outside':>7s}  verdict")
    for name, over in VARIANTS.items():
        t_off = None
        try:
            m_off = build_model(default_config(**over, **{"synthesis.symmetry": "off"}))
            t0 = time.perf_counter()
            r_off = synthesize(m_off)
            t_off = time.perf_counter() - t0
        except RobustSynthError:
            r_off = None
        model = build_model(default_config(**over))
        t0 = time.perf_counter()
        try:
            res = synthesize(model)
        except RobustSynthError as exc:
            print(f"{name:48s} exit {exc.exit_code}: {exc}")
            continue
        t_syn = time.perf_counter() - t0
        tm = res.timings
        split = (f"    symmetry off {t_off:.2f} s" if t_off is not None else "    symmetry off: failed") + (
            f" ({100 * r_off.certified['ultimate_bound']['e_y']:.3f} cm)" if r_off is not None and r_off.check.figures.get("ultimate_bound") else "")
        split += (f" | auto {t_syn:.2f} s: build {tm['build_s']:.2f} + cvxpy {tm['cvxpy_s']:.2f} + solver {tm['solver_s']:.2f}"
                  f" + re-check {tm['check_s']:.2f} s, {int(tm['solves'])} solves")
        if res.check.figures.get("ultimate_bound"):
            split += f" | |e_y| {100 * res.certified['ultimate_bound']['e_y']:.3f} cm (max over every S: {100 * _old_bound(res):.3f})"
        gd = gains_dict(model, res)
        v = verify(model, gd, runs=RUNS)
        mc = v.monte_carlo
        adv = mc.get("adversarial") or {}
        worst = max(mc["maxima"]["e_y"]["max"], mc["extreme_maxima"]["e_y"], adv.get("max", {}).get("e_y", 0.0))
        cert = res.certified["ultimate_bound"]["e_y"]
        vl = mc["V_over_level"]
        vmax = max(vl["max_in_certified_steps"], adv.get("max_V_over_level", 0.0))
        row = {"synthesis_s": t_syn, "synthesis_symmetry_off_s": t_off, "timings": dict(tm), "certified_e_y": cert,
               "certified_e_y_max_over_S": _old_bound(res), "robot_max_e_y": worst, "ratio": cert / worst,
               "steady_e_y": mc["steady_state"]["max_abs"]["e_y"], "max_V_over_level": vmax,
               "samples_outside": vl["samples_outside"], "passed": v.passed}
        out[name] = row
        print(f"{name:48s} {t_syn:9.2f} {100 * cert:15.3f} {100 * worst:14.3f} {cert / worst:10.3f}"
              f" {100 * row['steady_e_y']:13.3f} {vmax:8.4f} {vl['samples_outside']:7d}  "
              f"{'passed' if v.passed else 'FAILED'}")
        print(split)
    print(f"({RUNS} Monte Carlo runs + 4 extreme runs + the adversarial search per variant; V/level and 'outside' over the steps"
          " the invariance claim covers)")
    return out


if __name__ == "__main__":
    main()
