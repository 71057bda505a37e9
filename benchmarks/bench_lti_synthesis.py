"""Issue 28: robustsynth synthesize on a linear plant.

- a 6-state, 2-input plant (three masses on springs, forces on the outer two) sampled at 0.1 s with
  delays up to two periods (d_hi = 2): synthesis time for `stability` and `ultimate-bound` (target
  <= 10 s), its certified figures, and the verification's worst ratios; `ultimate-bound` twice, side
  by side: its line search one solve at a time (threads 1) and as many at once as the machine gives
  (threads auto), which must give the same gain;
- the benchmark of Zhang, Branicky and Phillips (configs/zbp*.yaml): a gain of its own (stability,
  decay 0.98 per period) and its delay margin beside the published gain's.

    .venv/bin/python benchmarks/run_all.py bench_lti_synthesis
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np


def three_masses() -> dict:
    from robustsynth.model.lti import lti_plant_from

    k, c = 1.0, 0.05
    A = np.zeros((6, 6))
    A[:3, 3:] = np.eye(3)
    A[3:, :3] = np.array([[-2 * k, k, 0], [k, -2 * k, k], [0, k, -2 * k]])
    A[3:, 3:] = -c * np.eye(3)
    B = np.zeros((6, 2))
    B[3, 0] = B[5, 1] = 1.0
    E = np.vstack([np.zeros((3, 1)), np.ones((3, 1))])
    return lti_plant_from(A, B, E=E, w_max=0.1, u_max=[5.0, 5.0], C=np.eye(3, 6))


def main() -> dict[str, float]:
    from robustsynth.config import load_config
    from robustsynth.margins.linear import lti_margins
    from robustsynth.model.lti import lti_plant
    from robustsynth.synthesis.lti import auto_threads, synthesize_lti
    from robustsynth.verification.lti import verify_lti

    out: dict[str, float] = {}
    pl = three_masses()
    print("| 6-state plant, d_hi = 2 | threads | time | solves | vertices | certified | verify: worst / certified |")
    print("|---|---|---|---|---|---|---|")
    gains = {}
    for obj, threads in (("stability", None), ("ultimate-bound", 1), ("ultimate-bound", None)):
        t0 = time.perf_counter()
        r = synthesize_lti(pl, 0.1, 0.0, 0.2, 0, obj, decay=0.99, threads=threads)
        dt = time.perf_counter() - t0
        v = verify_lti(pl, r.K, r.P, 0.1, 0.0, 0.2, 0, r.certified, runs=32, periods=100, multipliers=r.certificate["multipliers"])
        figs = (", ".join(f"|{o['name']}| <= {o['bound']:.4g}" for o in r.certified["outputs"]) if obj == "ultimate-bound"
                else f"decay {r.certified['decay']:.4f}, ball at rest {r.certified['rest_radius']:.4g}")
        worst = ", ".join(f"{c['name'].split(' (')[0]} {c['value']:.3f}" for c in v["checks"])
        label = f"auto ({auto_threads()})" if threads is None else str(threads)
        print(f"| {obj} | {label} | {dt:.1f} s | {r.solver['solves']} | {r.certificate['vertices']} | {figs} | {worst} |")
        out[f"six_state_{obj}_threads_{'auto' if threads is None else threads}_s"] = dt
        gains.setdefault(obj, []).append(r.K)
    same = all(np.array_equal(k, gains["ultimate-bound"][0]) for k in gains["ultimate-bound"])
    print(f"\nultimate-bound: the same gain with threads 1 and auto: {same}")

    root = Path(__file__).resolve().parents[1]
    print("\n| benchmark | gain | time | delay margin certified / exhibited | loss margin certified / exhibited |")
    print("|---|---|---|---|---|")
    for name in ("zbp", "zbp-h1"):
        cfg = load_config(root / "configs" / f"{name}.yaml")
        plant = lti_plant(cfg)
        net = cfg.network
        t0 = time.perf_counter()
        r = synthesize_lti(plant, net.sampling_time, net.delay.min, net.delay.max, 0, "stability")
        dt = time.perf_counter() - t0
        t1 = time.perf_counter()
        mg = lti_margins(cfg, dict(plant, K=r.K))
        dm = time.perf_counter() - t1
        d, lo = mg["delay_max"], mg["dropouts"]
        print(f"| {name} | own: {np.round(r.K, 3).tolist()} | synthesis {dt:.1f} s, margin {dm:.0f} s | "
              f"{d['certified']} / {d['exhibited']} | {lo['certified']} / {lo['exhibited']} |")
        out[f"{name}_synthesis_s"] = dt
    return out


if __name__ == "__main__":
    main()
