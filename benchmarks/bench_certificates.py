"""Issue 8's targets, measured: for the default robot with each certificate variant (paper model,
slip-aware common Q, slip-dependent, delay- and path-dependent, rate-bounded, integral action), the synthesis time, the
certified |e_y|, and what the nonlinear robot does on >= 1000 Monte Carlo runs plus the extreme runs and the
adversarial search (largest |e_y|, certified / observed, samples outside the certified set, verdict).

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
}


def main() -> dict[str, dict]:
    from robustsynth import build_model, default_config, synthesize
    from robustsynth import verify
    from robustsynth.errors import RobustSynthError
    from robustsynth.artifacts.gains import gains_dict

    out: dict[str, dict] = {}
    print(f"{'variant':48s} {'synth [s]':>9s} {'cert |e_y| [cm]':>15s} {'robot max [cm]':>14s} {'cert/robot':>10s}"
          f" {'steady |e_y*|':>13s} {'V/level':>8s} {'outside':>7s}  verdict")
    for name, over in VARIANTS.items():
        model = build_model(default_config(**over))
        t0 = time.perf_counter()
        try:
            res = synthesize(model)
        except RobustSynthError as exc:
            print(f"{name:48s} exit {exc.exit_code}: {exc}")
            continue
        t_syn = time.perf_counter() - t0
        gd = gains_dict(model, res)
        v = verify(model, gd, runs=RUNS)
        mc = v.monte_carlo
        adv = mc.get("adversarial") or {}
        worst = max(mc["maxima"]["e_y"]["max"], mc["extreme_maxima"]["e_y"], adv.get("max", {}).get("e_y", 0.0))
        cert = res.certified["ultimate_bound"]["e_y"]
        vl = mc["V_over_level"]
        vmax = max(vl["max_in_certified_steps"], adv.get("max_V_over_level", 0.0))
        row = {"synthesis_s": t_syn, "certified_e_y": cert, "robot_max_e_y": worst, "ratio": cert / worst,
               "steady_e_y": mc["steady_state"]["max_abs"]["e_y"], "max_V_over_level": vmax,
               "samples_outside": vl["samples_outside"], "passed": v.passed}
        out[name] = row
        print(f"{name:48s} {t_syn:9.2f} {100 * cert:15.3f} {100 * worst:14.3f} {cert / worst:10.3f}"
              f" {100 * row['steady_e_y']:13.3f} {vmax:8.4f} {vl['samples_outside']:7d}  "
              f"{'passed' if v.passed else 'FAILED'}")
    print(f"({RUNS} Monte Carlo runs + 4 extreme runs + the adversarial search per variant; V/level and 'outside' over the steps"
          " the invariance claim covers)")
    return out


if __name__ == "__main__":
    main()
