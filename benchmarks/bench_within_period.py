"""Issue 22, item 2: what covering slip that changes within a period costs (docs/theory.md §11).

Per config, side by side in one run: the number of within-period vertices, the numpy re-check of the
committed gain with and without them, and a whole synthesis (the config's objective, and the
stability objective, which needs constraint-generation rounds) with and without them: its time, the
certified figure and how many within-period vertices joined the LMIs.  "Without" is the same model
with ``varying`` emptied: the certificate then assumes slip constant within a period.

    .venv/bin/python benchmarks/run_all.py bench_within_period
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ("default", "heavy-slip", "delay-full-period", "lossy-link")
REPEAT = 10


def main() -> dict[str, float]:
    import numpy as np

    from robustsynth import build_model, load_config, synthesize
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.certificate import check_certificate

    cuts = {"n": 0}
    out: dict[str, float] = {}
    for name in CONFIGS:
        m = build_model(load_config(ROOT / "configs" / f"{name}.yaml"))
        without = replace(m, varying=(), varying_reason="benchmark: without the within-period vertices")
        g = load_gains(ROOT / "results" / "baselines" / name / "gains.json")
        K = np.asarray(g["K"], dtype=float)
        times = {}
        for label, model in (("with", m), ("without", without)):
            t0 = time.perf_counter()
            for _ in range(REPEAT):
                chk = check_certificate(model, K, g["certificate"])
            times[label] = (time.perf_counter() - t0) / REPEAT
            assert chk.passed, chk.reason
        print(f"{name}: {len(m.varying)} within-period vertices; re-check {1000 * times['with']:.1f} ms with them, "
              f"{1000 * times['without']:.1f} ms without")
        out[f"{name}_recheck_ratio"] = times["with"] / times["without"]
        for objective in (m.config.synthesis.objective, "stability"):
            row = {}
            for label, model in (("with", m), ("without", without)):
                cuts["n"] = 0
                orig = type(model).with_cuts

                def counting(self, idx, orig=orig):
                    cuts["n"] = max(cuts["n"], len(idx))
                    return orig(self, idx)

                type(model).with_cuts = counting
                try:
                    t0 = time.perf_counter()
                    res = synthesize(model, objective=objective)
                    dt = time.perf_counter() - t0
                finally:
                    type(model).with_cuts = orig
                f = res.certified
                fig = (f"|e_y| <= {100 * f['ultimate_bound']['e_y']:.3f} cm" if f.get("ultimate_bound")
                       else f"decay rate {f['decay_rate']:.4f}")
                row[label] = dt
                print(f"  {objective}, {label}: {dt:.2f} s, {fig}, within-period vertices added to the LMIs: "
                      f"{cuts['n']}, slip within a period: {f['slip_within_period']}")
            out[f"{name}_{objective}_time_ratio"] = row["with"] / row["without"]
            print(f"  {objective}: synthesis time with / without = {row['with'] / row['without']:.2f}")
    return out


if __name__ == "__main__":
    main()
