"""A 12 x 12 sweep (delay bound x left-track slip) on the default robot: serial against 2 local
worker processes, side by side in one run, and the per-point cost of the serial sweep against bare
``synthesize()`` calls on the same configs in this (warm) process.

Targets (issue 9): 2 workers >= 1.7x faster than serial on 2 cores; per-point cost within 1.2x of
a bare synthesize()."""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

SPEC = """axes:
  network.delay.max: {linspace: [0.02, 0.1, 12]}
  slip.left.min: {linspace: [0.55, 0.95, 12]}
"""


def main() -> dict[str, float]:
    from robustsynth.config import config_with
    from robustsynth.errors import RobustSynthError
    from robustsynth.model import build_model
    from robustsynth.sweeps import parse_sweep, sweep
    from robustsynth.synthesis import synthesize

    spec = parse_sweep(SPEC, "bench")
    points = spec.points()
    out: dict[str, float] = {"points": len(points), "cores": os.cpu_count() or 1}
    synthesize(build_model(spec.base))  # warm: imports and first compilation are not per point
    t0 = time.perf_counter()
    for p in points:
        try:
            synthesize(build_model(config_with(spec.base, p)))
        except RobustSynthError:
            pass
    out["bare_s"] = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        s1 = sweep(spec, Path(tmp) / "serial", workers=1)
        out["serial_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        s2 = sweep(spec, Path(tmp) / "local", workers=2)
        out["local2_s"] = time.perf_counter() - t0
    same = [{k: v for k, v in r.items() if k != "time_s"} for r in s1.rows] == \
           [{k: v for k, v in r.items() if k != "time_s"} for r in s2.rows]
    out["speedup"] = out["serial_s"] / out["local2_s"]
    out["per_point_ratio"] = out["serial_s"] / out["bare_s"]
    print(f"sweep 12 x 12 = {len(points)} points on the default robot ({s1.counts}), {out['cores']} cores")
    print(f"  bare synthesize() loop, warm process        {out['bare_s']:8.1f} s ({out['bare_s'] / len(points):.3f} s/point)")
    print(f"  sweep, serial (--workers 1)                 {out['serial_s']:8.1f} s ({out['serial_s'] / len(points):.3f} s/point)")
    print(f"  sweep, 2 local workers                      {out['local2_s']:8.1f} s")
    print(f"  speedup 2 workers / serial                  {out['speedup']:8.2f}   (target >= 1.7)")
    print(f"  per-point cost sweep / bare synthesize()    {out['per_point_ratio']:8.2f}   (target <= 1.2)")
    print(f"  rows identical serial vs 2 workers          {same}")
    return out


if __name__ == "__main__":
    main()
