"""synthesize on the default config: end-to-end process time with its split (imports, problem
build, solves), and the per-solve time reusing one compiled problem (cvxpy Parameters, DPP)
against building and compiling the problem anew for every solve."""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SOLVES = 15


def _end_to_end() -> float:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "robustsynth", "synthesize", "-o", str(Path(tmp) / "s")], check=True,
                       capture_output=True)
        return time.perf_counter() - t0


def main() -> dict[str, float]:
    out: dict[str, float] = {}
    out["process_s"] = _end_to_end()
    probe = ("import time; t = time.perf_counter(); import cvxpy, robustsynth.synthesis, robustsynth.model;"
             " print(time.perf_counter() - t)")
    out["imports_s"] = float(subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True,
                                            text=True).stdout)  # in a fresh process: nothing cached
    from robustsynth import build_model, load_config
    from robustsynth.synthesis import lmis
    from robustsynth.synthesis.design import synthesize
    from robustsynth.synthesis.solve import solver_options

    model = build_model(load_config())
    s = model.config.synthesis
    import numpy as np

    w = np.array([s.weights.e_x, s.weights.e_y, s.weights.e_theta])
    t0 = time.perf_counter()
    lp = lmis.build_invariance(model, s.multiplier, s.margin, w, True)
    out["build_s"] = time.perf_counter() - t0
    alphas = np.linspace(0.05, 0.35, SOLVES)  # feasible for the default robot (0.4 is not; the mirrored problem then errors)
    opts = solver_options("clarabel")
    reuse = []
    for a in alphas:
        lp.params["alpha"].value = a
        lp.params["one_minus_alpha"].value = 1 - a
        t0 = time.perf_counter()
        lp.problem.solve(**opts)
        reuse.append(time.perf_counter() - t0)
    rebuild = []
    for a in alphas:
        t0 = time.perf_counter()
        lp2 = lmis.build_invariance(model, s.multiplier, s.margin, w, True)
        lp2.params["alpha"].value = a
        lp2.params["one_minus_alpha"].value = 1 - a
        lp2.problem.solve(**opts)
        rebuild.append(time.perf_counter() - t0)
    out["per_solve_reuse_s"] = statistics.median(reuse[1:])  # the first solve compiles
    out["first_solve_s"] = reuse[0]
    out["per_solve_rebuild_s"] = statistics.median(rebuild)
    t0 = time.perf_counter()
    res = synthesize(model)
    out["synthesize_api_s"] = time.perf_counter() - t0
    out["solver_s"] = res.solver["solve_time_s"]
    print("synthesize, default config (ultimate-bound)")
    print(f"  whole process (python -m robustsynth synthesize) {out['process_s']:8.3f} s")
    print(f"  imports (cvxpy + robustsynth)                    {out['imports_s']:8.3f} s")
    print(f"  problem build                                     {out['build_s']:8.3f} s")
    print(f"  synthesize() in-process                           {out['synthesize_api_s']:8.3f} s "
          f"({res.solver['solves']} solves, {out['solver_s']:.3f} s in solver calls incl. fallbacks)")
    print(f"  first solve (compiles)                            {out['first_solve_s'] * 1000:8.1f} ms")
    print(f"  per solve, compiled problem reused (median)       {out['per_solve_reuse_s'] * 1000:8.1f} ms")
    print(f"  per solve, rebuilt every time (median)            {out['per_solve_rebuild_s'] * 1000:8.1f} ms")
    print(f"  ratio rebuild / reuse                             {out['per_solve_rebuild_s'] / out['per_solve_reuse_s']:8.2f}")
    return out


if __name__ == "__main__":
    main()
