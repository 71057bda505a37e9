"""Issue 26: the alpha search started from the common certificate's alpha (a walk in half grid steps,
then golden section stopped once it no longer moves the bound) against the full scan (a log grid of
alpha_points, then 10 golden steps), side by side in one run, per certificate class on the default
robot: synthesis time, number of solves and the certified |e_y| (the target: within 0.5 %).

    .venv/bin/python benchmarks/run_all.py bench_alpha_search
"""

from __future__ import annotations

import time

VARIANTS = [
    ("slip-dependent", {"synthesis.lyapunov": "slip-dependent"}),
    ("delay-dependent", {"synthesis.lyapunov": "delay-dependent"}),
    ("integral, rho 20, rate 0.5, delay-dependent", {"synthesis.lyapunov": "delay-dependent",
                                                     "synthesis.integral_action": True, "robot.max_motor_speed": 20.0,
                                                     "slip.max_rate": 0.5}),
    ("path-dependent", {"synthesis.lyapunov": "path-dependent"}),
]


def main() -> dict[str, dict[str, float]]:
    from robustsynth import build_model, default_config
    from robustsynth.synthesis import design, heading_search
    from robustsynth.synthesis.objectives import ultimate_bound

    real = ultimate_bound._run_invariance

    def full_scan(*a, alpha_hint=None, **k):  # the search as it was: no hint
        return real(*a, **k)

    out: dict[str, dict[str, float]] = {}
    print("| certificate | full scan: time, solves, \\|e_y\\| | from the common alpha: time, solves, \\|e_y\\| | "
          "speed-up | \\|e_y\\| change |")
    print("|---|---|---|---|---|")
    for name, over in VARIANTS:
        model = build_model(default_config(**over))
        row = {}
        for label, fn in (("full", full_scan), ("hint", real)):
            ultimate_bound._run_invariance = heading_search._run_invariance = fn  # the linearized and the nonlinear searches
            try:
                t0 = time.perf_counter()
                res = design.synthesize(model)
                row[label] = (time.perf_counter() - t0, res.solver["solves"], res.certified["ultimate_bound"]["e_y"])
            finally:
                ultimate_bound._run_invariance = heading_search._run_invariance = real
        (tf, nf, ef), (th, nh, eh) = row["full"], row["hint"]
        print(f"| {name} | {tf:.1f} s, {nf}, {100 * ef:.3f} cm | {th:.1f} s, {nh}, {100 * eh:.3f} cm | {tf / th:.2f}x | "
              f"{100 * (eh - ef) / ef:+.3f} % |", flush=True)
        out[name] = {"full_s": tf, "hint_s": th, "full_e_y": ef, "hint_e_y": eh}
    return out


if __name__ == "__main__":
    main()
