"""Issue 24 (part 2): `identify` on simulated logs of known slip, delays and losses.

Measures the time for 10 000 periods, and how close the identified box lies to the true one at
several pose-noise levels (per-sample Gaussian noise on x, y and theta, as the simulator adds it).
Target: 10 000 periods in <= 2 s; the true box within 2 % of its width at the documented noise level.
Both slip models: tracks (closed-loop logs of the Monte Carlo) and icr (open-loop excitation logs of
the kinematic robot, the box of configs/icr-physics.yaml).

    .venv/bin/python benchmarks/run_all.py bench_identify
"""

from __future__ import annotations

import time

TRUTH = {"right": (0.7, 0.95), "left": (0.6, 0.9), "delay": (0.02, 0.07)}


def main() -> dict[str, float]:
    from robustsynth.config import default_config
    from robustsynth.identification import identify
    from robustsynth.model import build_model
    from robustsynth.plants.path import make_path
    from robustsynth.scenarios import draw_scenario, steady_state_start
    from robustsynth.synthesis import synthesize
    from robustsynth.robot_verification.simulate import run_logs, simulate

    over = {"network.delay.min": 0.02, "network.delay.max": 0.07, "slip.right.min": 0.7, "slip.right.max": 0.95,
            "slip.left.min": 0.6, "slip.left.max": 0.9, "network.dropouts.max_consecutive": 2,
            "robot.max_motor_speed": 20.0}
    K = synthesize(build_model(default_config(**over))).K
    out: dict[str, float] = {}
    print("| pose noise (m, rad) | periods | identify | mu_r box (true 0.7-0.95) | mu_l box (true 0.6-0.9) | worst edge "
          "error / width | delay range |")
    print("|---|---|---|---|---|---|---|")
    for pos, head in ((0.0, 0.0), (2e-5, 5e-5), (1e-4, 2e-4), (1e-3, 2e-3)):
        cfg = default_config(**over, **{"verification.noise.position": pos, "verification.noise.heading": head})
        m = build_model(cfg)
        path = make_path(cfg.reference.path, cfg.reference.speed)
        scen = steady_state_start(m, K, path, draw_scenario(m, 40, seed=3, steps=251, path=path))
        logs = run_logs(m, simulate(m, K, path, scen), scen)
        t0 = time.perf_counter()
        ident = identify(logs, cfg.robot.gear_radius, cfg.robot.track_distance, max_motor_speed=20.0)
        dt = time.perf_counter() - t0
        err = max(max(abs(ident.box[s][0] - TRUTH[s][0]), abs(ident.box[s][1] - TRUTH[s][1])) / (TRUTH[s][1] - TRUTH[s][0])
                  for s in ("right", "left"))
        periods = sum(len(lg) - 1 for lg in logs)
        r, l_ = ident.box["right"], ident.box["left"]
        print(f"| {pos:g}, {head:g} | {periods} | {dt:.2f} s | {r[0]:.4f}-{r[1]:.4f} | {l_[0]:.4f}-{l_[1]:.4f} | "
              f"{100 * err:.1f} % | {1000 * ident.delay_range[0]:.1f}-{1000 * ident.delay_range[1]:.1f} ms |")
        out[f"noise_{pos:g}_time_s"], out[f"noise_{pos:g}_edge_error"] = dt, err
    out.update(icr())
    return out


ICR_KEYS = ("right", "left", "yaw", "icr_offset")


def icr() -> dict[str, float]:
    """identify --model icr on 16 open-loop excitation episodes of the kinematic robot (~10 000
    periods) with the box of configs/icr-physics.yaml and the simulator's slip profiles."""
    from pathlib import Path

    from robustsynth.config import config_with, load_config
    from robustsynth.identification import identify
    from robustsynth.model import build_model
    from robustsynth.robot_verification.physics import excitation_slip, excitation_steps, excite

    base = load_config(Path(__file__).resolve().parents[1] / "configs" / "icr-physics.yaml")
    out: dict[str, float] = {}
    print("\n| icr: pose noise (m, rad) | periods | identify | mu_r | mu_l | yaw | x_icr | worst edge error / width "
          "(mu_r, mu_l, yaw, x_icr) |")
    print("|---|---|---|---|---|---|---|---|")
    for pos, head in ((0.0, 0.0), (4e-6, 1e-5), (2e-5, 5e-5)):
        cfg = config_with(base, {"verification.noise.position": pos, "verification.noise.heading": head,
                                 "network.dropouts.max_consecutive": 2})
        m = build_model(cfg)
        logs = excite(m, episodes=16, seed=0, engine="kinematic")
        truth = excitation_slip(m, 16, excitation_steps(m), 0)
        t0 = time.perf_counter()
        ident = identify(logs, cfg.robot.gear_radius, cfg.robot.track_distance, model="icr",
                         max_motor_speed=cfg.robot.max_motor_speed, pose_noise=(pos, head))
        dt = time.perf_counter() - t0
        errs, contains = [], True
        for i, k in enumerate(ICR_KEYS):
            lo, hi = ident.box[k]
            tlo, thi = float(truth[..., i].min()), float(truth[..., i].max())
            contains &= lo <= tlo and hi >= thi
            errs.append(max(abs(lo - tlo), abs(hi - thi)) / (thi - tlo))
        boxes = " | ".join(f"{ident.box[k][0]:.4f}-{ident.box[k][1]:.4f}" for k in ICR_KEYS)
        print(f"| {pos:g}, {head:g} | {ident.slip.mu.shape[0]} | {dt:.2f} s | {boxes} | "
              + ", ".join(f"{100 * e:.1f} %" for e in errs) + ("" if contains else " (TRUTH NOT CONTAINED)") + " |")
        out[f"icr_noise_{pos:g}_time_s"] = dt
        out[f"icr_noise_{pos:g}_edge_error"] = max(errs)
        out[f"icr_noise_{pos:g}_contains_truth"] = float(contains)
    return out


if __name__ == "__main__":
    main()
