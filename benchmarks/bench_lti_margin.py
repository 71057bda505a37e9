"""Issue 28: robustsynth margin on a linear plant, the benchmark of Zhang, Branicky and Phillips
(configs/zbp.yaml, h = 0.5 s; configs/zbp-h1.yaml, h = 1.0 s) with its published gain: time, and the
certified vs exhibited delay bound.  Issue 53: beside it a fast plant with multi-period delays, the DC
servo of tests/data/dc-servo.yaml (a mode at -72.5 rad/s, Ts = 20 ms, delays up to 3 Ts configured),
whose instability lies ten periods out: the exhibited search must reach it (it searches up to 20 Ts); and a
motor with its current as a state (tests/data/fast-current.yaml: an electrical mode at -1000 rad/s, 20 / Ts).

Targets: margin <= 10 s on the benchmark; certified / exhibited >= 0.85 (moonshot 0.95); on the fast plants
certified / exhibited >= 0.8, margin <= 30 s (issue 53).

    .venv/bin/python benchmarks/run_all.py bench_lti_margin
"""

from __future__ import annotations

import time
from pathlib import Path

CONFIGS = ("configs/zbp", "configs/zbp-h1", "tests/data/dc-servo", "tests/data/fast-current")  # bench and test plants


def main() -> dict[str, float]:
    from robustsynth.config import load_config
    from robustsynth.margins.linear import lti_margins
    from robustsynth.model.lti import lti_plant

    root = Path(__file__).resolve().parents[1]
    out: dict[str, float] = {}
    print("| config | h | configured tau_max | certified tau_max | exhibited | witness | ratio | searched up to | "
          "loss cap certified / exhibited | search / certificate / margin time |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in CONFIGS:
        cfg = load_config(root / f"{name}.yaml")
        name = name.split("/")[-1]
        t0 = time.perf_counter()
        mg = lti_margins(cfg, lti_plant(cfg))
        dt = time.perf_counter() - t0
        d, lo = mg["delay_max"], mg["dropouts"]
        ratio = d["ratio"] if d["ratio"] is not None else float("nan")
        num = lambda v: "none" if v is None else f"{v:.4f} s"  # noqa: E731
        w = d["witness"]
        wtxt = (f"period {w['period']}: [{', '.join(f'{x:.4f}' for x in w['delays'])}]" if w else "-")
        print(f"| {name} | {cfg.network.sampling_time:g} s | {cfg.network.delay.max:g} s | {num(d['certified'])} | "
              f"{num(d['exhibited'])} | {wtxt} | {ratio:.3f} | {d['searched_up_to']:g} s ({d['searched_periods']:g} Ts) | "
              f"{'none' if lo['certified'] is None else lo['certified']} / "
              f"{'none' if lo['exhibited'] is None else lo['exhibited']} | "
              f"{d['search_s']:.1f} / {d['certificate_s']:.1f} / {dt:.1f} s |")
        key = name.replace("-", "_")
        out[f"{key}_time_s"], out[f"{key}_ratio"], out[f"{key}_search_s"] = dt, ratio, d["search_s"]
    return out


if __name__ == "__main__":
    main()
