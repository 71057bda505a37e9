"""Issue 28: robustsynth margin on a linear plant, the benchmark of Zhang, Branicky and Phillips
(configs/zbp.yaml, h = 0.5 s; configs/zbp-h1.yaml, h = 1.0 s) with its published gain: time, and the
certified vs exhibited delay bound.

Targets: margin <= 10 s; certified / exhibited >= 0.85 (moonshot 0.95).

    .venv/bin/python benchmarks/run_all.py bench_lti_margin
"""

from __future__ import annotations

import time
from pathlib import Path


def main() -> dict[str, float]:
    from robustsynth.config import load_config
    from robustsynth.margins_lti import lti_margins
    from robustsynth.model.lti import lti_plant

    root = Path(__file__).resolve().parents[1]
    out: dict[str, float] = {}
    print("| config | h | certified tau_max | exhibited | ratio | loss cap certified / exhibited | margin time |")
    print("|---|---|---|---|---|---|---|")
    for name in ("zbp", "zbp-h1"):
        cfg = load_config(root / "configs" / f"{name}.yaml")
        t0 = time.perf_counter()
        mg = lti_margins(cfg, lti_plant(cfg))
        dt = time.perf_counter() - t0
        d, lo = mg["delay_max"], mg["dropouts"]
        ratio = d["certified"] / d["exhibited"] if d["certified"] and d["exhibited"] else float("nan")
        print(f"| {name} | {cfg.network.sampling_time:g} s | {d['certified']:.4f} s | {d['exhibited']:.4f} s | "
              f"{ratio:.3f} | {lo['certified']} / {lo['exhibited']} | {dt:.1f} s |")
        out[f"{name}_time_s"], out[f"{name}_ratio"] = dt, ratio
    return out


if __name__ == "__main__":
    main()
