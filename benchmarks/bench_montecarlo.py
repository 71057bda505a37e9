"""Monte Carlo throughput of the vectorized nonlinear simulator in robot-steps per second, its
ratio to the per-run solve_ivp reference on the same scenarios (measured side by side), and the
wall time of `robustsynth verify` with 200 runs on the default config."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REF_RUNS = 3  # solve_ivp runs timed (it is slow); its per-step cost is what is compared


def main() -> dict[str, float]:

    from robustsynth import build_model, load_config
    from robustsynth.synthesis import synthesize
    from robustsynth.plants.reference import simulate_run
    from robustsynth.plants.path import make_path
    from robustsynth.scenarios import draw_scenario
    from robustsynth.robot_verification.simulate import simulate

    model = build_model(load_config())
    K = synthesize(model).K
    vc = model.config.verification
    path = make_path(model.config.reference.path, model.V)
    steps = int(path.duration / model.Ts)
    out: dict[str, float] = {}
    for runs in (200, 2000):
        scen = draw_scenario(model, runs, 0, steps, path)
        simulate(model, K, path, scen)  # warm up
        t0 = time.perf_counter()
        simulate(model, K, path, scen, vc.transient)
        dt = time.perf_counter() - t0
        out[f"vectorized_{runs}_steps_per_s"] = runs * steps / dt
    scen = draw_scenario(model, REF_RUNS, 0, steps, path)
    t0 = time.perf_counter()
    for n in range(REF_RUNS):
        simulate_run(model, K, path, scen, n, integrator="ivp")
    ivp = REF_RUNS * steps / (time.perf_counter() - t0)
    t0 = time.perf_counter()
    for n in range(REF_RUNS):
        simulate_run(model, K, path, scen, n, integrator="arc")
    loop = REF_RUNS * steps / (time.perf_counter() - t0)
    out["per_run_ivp_steps_per_s"] = ivp
    out["per_run_arc_steps_per_s"] = loop
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        subprocess.run([sys.executable, "-m", "robustsynth", "synthesize", "-o", str(d)], check=True, capture_output=True)
        for plots in (False, True):
            t0 = time.perf_counter()
            args = [sys.executable, "-m", "robustsynth", "verify", "-o", str(d), "--runs", "200"] + ([] if plots else ["--no-plots"])
            subprocess.run(args, check=True, capture_output=True)
            out[f"verify_200_{'plots' if plots else 'noplots'}_s"] = time.perf_counter() - t0
        v = json.loads((d / "verification.json").read_text())
    v200 = out["vectorized_200_steps_per_s"]
    print(f"Monte Carlo, default config ({steps} steps per run)")
    print(f"  vectorized, 200 runs            {v200:12,.0f} robot-steps/s")
    print(f"  vectorized, 2000 runs           {out['vectorized_2000_steps_per_s']:12,.0f} robot-steps/s")
    print(f"  per-run loop, exact arcs        {loop:12,.0f} robot-steps/s   (vectorized is {v200 / loop:,.0f}x)")
    print(f"  per-run loop, solve_ivp         {ivp:12,.0f} robot-steps/s   (vectorized is {v200 / ivp:,.0f}x)")
    print(f"  robustsynth verify, 200 runs    {out['verify_200_noplots_s']:8.2f} s without figures, "
          f"{out['verify_200_plots_s']:.2f} s with figures (whole process)")
    print(f"  verdict {'passed' if v['passed'] else 'FAILED'}; maxima vs certified: "
          + ", ".join(f"{k} {r:.3f}" for k, r in v['monte_carlo']['ratio_to_certified'].items()))
    out["ratio_vs_ivp"] = v200 / ivp
    return out


if __name__ == "__main__":
    main()
