"""Issue 22: how far is each committed gain's certificate from a proof for the nonlinear robot?

Per config in configs/ with a certified gain in results/baselines/: the certified |e_y| (proven for
the linearization) and the boundary probe that `verify` runs. The probe takes states on V = level
(the verify's seed and sample count) and runs one period on the exact lifted map and on the
nonlinear robot. It reports max V+/level for each, the fraction of states that leave the set, and
the largest per-period difference between the two in e_x and e_y. A nonlinear certificate, with its
|e_y|, continuous-time figures and synthesis time, is still open, so those columns are not here yet.

    .venv/bin/python benchmarks/run_all.py bench_nonlinear_proof
"""

from __future__ import annotations

import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> dict[str, dict[str, float]]:
    import numpy as np

    from robustsynth import build_model, load_config
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.certificate import check_certificate, lyapunov_of
    from robustsynth.verification.checks import PROBE_SAMPLES
    from robustsynth.verification.probe import boundary_probe

    out: dict[str, dict[str, float]] = {}
    print("| config | certified |e_y| (linearization) | probed states | lifted map: max V+/level | nonlinear robot: max "
          "V+/level | states leaving | per-period gap e_x / e_y | probe time |")
    print("|---|---|---|---|---|---|---|---|")
    for cfg_path in sorted((ROOT / "configs").glob("*.yaml")):
        gains_path = ROOT / "results" / "baselines" / cfg_path.stem / "gains.json"
        if not gains_path.exists():
            continue  # infeasible: nothing certified
        cfg = load_config(cfg_path)
        m = build_model(cfg)
        g = load_gains(gains_path)
        K = np.asarray(g["K"], dtype=float)
        chk = check_certificate(m, K, g["certificate"])
        if not chk.passed or "ellipsoid_level" not in chk.figures:
            print(f"| {cfg_path.stem} | no invariant set certified | | | | | | |")
            continue
        t0 = time.perf_counter()
        r = boundary_probe(m, K, lyapunov_of(m, g["certificate"]), float(chk.figures["ellipsoid_level"]),
                           samples=PROBE_SAMPLES, seed=cfg.verification.seed)
        dt = time.perf_counter() - t0
        gap = r["max_period_gap"]
        e_y = chk.figures["ultimate_bound"]["e_y"]
        print(f"| {cfg_path.stem} | {100 * e_y:.2f} cm | {r['samples']} | {r['max_V_over_level_linear']:.4f} | "
              f"{r['max_V_over_level_nonlinear']:.4f} | {100 * r['fraction_outside_nonlinear']:.3f} % | "
              f"{1000 * gap['e_x']:.1f} / {1000 * gap['e_y']:.1f} mm | {dt:.2f} s |")
        out[cfg_path.stem] = {"e_y": e_y, "linear": r["max_V_over_level_linear"],
                              "nonlinear": r["max_V_over_level_nonlinear"], "time_s": dt}
    return out


if __name__ == "__main__":
    main()
