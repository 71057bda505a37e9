"""The heading rows of the robot proof (docs/theory.md §9, issues 49 and 51): an LMI per row kept (after the rows the
others imply are left out) against every row as a linear row on one lifted matrix (``lmis._lifted_heading_rows``),
side by side in one run, on the default robot at d_hi = 1, 2 and 3 (tau_max 0.08, 0.19, 0.29 s; icr slip,
nonlinear kinematics): the distinct rows, the time to build the problem (the LPs that leave rows out included) and
of one solve at a heading bound and alpha where the d_hi = 2 robot's search spends its time, with its status.

The LMI per row is not solved at d_hi = 3 (60 281 rows: building them alone took 22 s, and the LPs did not end in
5 minutes at stop 75); ``--solve-all`` asks for it anyway.

    .venv/bin/python benchmarks/run_all.py bench_heading_rows
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = ((0.08, 0.081, 0.135), (0.19, 0.2, 0.042), (0.29, 0.1, 0.05))  # (tau_max [s], heading bound [rad], alpha)


def _one(model, s, weights, alpha: float, lift: bool, solve_it: bool) -> dict:
    from robustsynth.synthesis import lmis
    from robustsynth.synthesis.lmis import build_invariance
    from robustsynth.synthesis.solve import solve

    saved = lmis.LIFT_ROWS
    lmis.LIFT_ROWS = 0 if lift else 10**9
    lmis._KEPT.clear()
    try:
        t0 = time.perf_counter()
        lp = build_invariance(model, s.multiplier, s.margin, weights, True, s.lyapunov, symmetry=True)
        out = {"build_s": time.perf_counter() - t0}
    finally:
        lmis.LIFT_ROWS = saved
    if solve_it:
        lp.params["alpha"].value = alpha
        lp.params["one_minus_alpha"].value = 1.0 - alpha
        t0 = time.perf_counter()
        res = solve(lp.problem, s.solver, lambda: True, fallback=False, retry=False)
        out.update(solve_s=time.perf_counter() - t0, status=res.record.status)
    return out


def main(argv: list[str] | None = None) -> list[dict]:
    import numpy as np

    from robustsynth import build_model, load_config
    from robustsynth.synthesis.heading_search import _kinematic

    argv = sys.argv[1:] if argv is None else argv
    solve_all = "--solve-all" in argv
    rows_out = []
    base = load_config(ROOT / "configs" / "default.yaml")
    for tau_max, bound, alpha in CASES:
        raw = base.model_dump()
        raw["network"]["delay"]["max"] = tau_max
        cfg = type(base).model_validate(raw)
        s = _kinematic(cfg.synthesis)
        model = build_model(cfg).with_heading_bound(bound)
        distinct = {np.concatenate([c, d, [o]]).tobytes() for ch in model.heading_channels
                    for c, d, o in zip(ch.C_h, ch.D_h, ch.heading_offsets)}
        w = np.array([s.weights.e_x, s.weights.e_y, s.weights.e_theta])
        line = (f"d_hi {model.d_hi}: {len(model.vertices)} vertices, {len(distinct):,} distinct heading rows at "
                f"{bound:g} rad, alpha {alpha:g}")
        row = {"d_hi": model.d_hi, "rows": len(distinct)}
        for lift in (False, True):
            r = _one(model, s, w, alpha, lift, solve_it=lift or solve_all or len(distinct) < 10_000)
            tag = "lifted" if lift else "per-row"
            row[tag] = r
            line += f"; {tag}: built in {r['build_s']:.1f} s"
            if "solve_s" in r:
                line += f", solved in {r['solve_s']:.1f} s ({r['status']})"
            else:
                line += ", not solved"
        print(line, flush=True)
        rows_out.append(row)
    return rows_out


if __name__ == "__main__":
    main()
