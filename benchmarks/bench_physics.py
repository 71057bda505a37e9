"""Issue 25: the physics-engine robot's speed: 20 closed-loop episodes x 20 s of the default gain on
the default config (the deployed law, the emulated network, MuJoCo at 2 ms) on one process, and the
same with 5 episodes (the cost per episode).  Target: 20 x 20 s in <= 30 s on this 2-core machine.

    .venv/bin/python benchmarks/run_all.py bench_physics
"""

from __future__ import annotations

import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> dict[str, float]:
    from robustsynth import build_model, load_config
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.plants.physics import available
    from robustsynth.robot_verification.physics import validate_physics

    if available():
        print(f"skipped: {available()}")
        return {}
    cfg = load_config(ROOT / "configs" / "default.yaml")
    # a 20 s path: one straight 10 m segment at 0.5 m/s
    cfg = cfg.model_copy(update={"reference": cfg.reference.model_copy(update={"path": ((0.0, 0.0), (10.0, 0.0))})})
    model = build_model(cfg)
    gains = load_gains(ROOT / "results" / "baselines" / "default" / "gains.json")
    out = {}
    for n in (5, 20):
        t0 = time.perf_counter()
        r = validate_physics(model, gains, episodes=n, seed=0)
        dt = time.perf_counter() - t0
        sim_s = r["validation"]["duration_s"]
        out[f"{n}_episodes_s"] = dt
        print(f"{n} episodes x {sim_s:g} s simulated: {dt:.1f} s wall ({n * sim_s / dt:.0f}x real time)")
    return out


if __name__ == "__main__":
    main()
