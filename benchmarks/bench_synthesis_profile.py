"""Issue 26, item 1: where a certificate's synthesis spends its time, per Lyapunov class on the
default robot. For each class it measures:
- model build;
- LMI problem build (cvxpy expressions);
- the first solve at one alpha (canonicalization and compile, plus the solver);
- a second solve at another alpha (the compiled problem reused: cvxpy overhead plus the solver),
  split into cvxpy's own time and the solver's time (Clarabel's solve_time);
- one numpy re-check of the certificate;
- the number of vertex conditions and the size of the LMI problem.
The number of solves a whole synthesis makes is the `solves` of `synthesize` (the alpha scan, then
golden section): it multiplies the per-solve figures.

    .venv/bin/python benchmarks/run_all.py bench_synthesis_profile
"""

from __future__ import annotations

import time

CLASSES = ("common", "slip-dependent", "delay-dependent", "path-dependent")


def main() -> dict[str, dict[str, float]]:
    import numpy as np

    from robustsynth import build_model, default_config
    from robustsynth.certificate import check_certificate
    from robustsynth.synthesis.runner import _cert_common, _weights
    from robustsynth.synthesis.lmis import build_invariance
    from robustsynth.synthesis.solve import solver_options

    out: dict[str, dict[str, float]] = {}
    print("| class | conditions | LMI rows (sum) | model build | problem build | 1st solve: cvxpy + solver | "
          "2nd solve: cvxpy + solver | numpy re-check |")
    print("|---|---|---|---|---|---|---|---|")
    for kind in CLASSES:
        t0 = time.perf_counter()
        m = build_model(default_config(**{"synthesis.lyapunov": kind}))
        t_model = time.perf_counter() - t0
        s = m.config.synthesis
        t0 = time.perf_counter()
        lp = build_invariance(m, s.multiplier, s.margin, _weights(s), True, kind)
        t_build = time.perf_counter() - t0
        rows = sum(c.shape[0] for c in lp.problem.constraints if hasattr(c, "shape") and len(c.shape) == 2)
        n_cond = sum(len(c) for c in m.lyapunov_conditions(kind, None)) if kind != "common" else len(m.vertices)
        solves = []
        for a in (0.22, 0.25):
            lp.params["alpha"].value = a
            lp.params["one_minus_alpha"].value = 1.0 - a
            t0 = time.perf_counter()
            lp.problem.solve(**solver_options("clarabel"))
            total = time.perf_counter() - t0
            solver = float(lp.problem.solver_stats.solve_time or 0.0)
            solves.append((total - solver, solver))
        vals = lp.values()
        X = vals["Q"] if "Q" in vals else vals["G"]
        K = np.linalg.solve(X.T, vals["Y"].T).T
        cert = _cert_common(m, vals, s.multiplier, s.margin, "ultimate-bound")
        cert.update(alpha=0.25, beta=vals["beta"], motor_limits_enforced=True)
        t0 = time.perf_counter()
        chk = check_certificate(m, K, cert)
        t_check = time.perf_counter() - t0
        (c1, s1), (c2, s2) = solves
        print(f"| {kind} | {n_cond} | {rows} | {t_model:.2f} s | {t_build:.2f} s | {c1:.2f} + {s1:.2f} s | "
              f"{c2:.2f} + {s2:.2f} s | {1000 * t_check:.0f} ms ({'certified' if chk.passed else chk.reason[:40]}) |")
        out[kind] = {"conditions": n_cond, "model_s": t_model, "build_s": t_build, "first_cvxpy_s": c1,
                     "first_solver_s": s1, "cvxpy_s": c2, "solver_s": s2, "check_s": t_check}
    return out


if __name__ == "__main__":
    main()
