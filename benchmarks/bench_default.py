"""Issue 49: the default scenario, proven for the robot, measured end to end.

1. The slip box from the physics robot: ``validate --excite --episodes 4`` on the MuJoCo robot at ground friction
   1.0, 0.4 and with a 10 kg payload 0.15 m forward, each read by ``identify --model icr --settle 1``; the union
   of the three boxes beside the default config's (which must contain it).
2. The default's synthesis (timed), its certified figures (at the samples and for all t, through the turns).
3. Its verification (``verify``'s 200 runs, probe, adversaries): verdict, the probe's and the adversary's
   largest V/level from the boundary, observed / certified per figure and certified / robot maximum on |e_y|.
4. The physics robot (4 episodes each) at friction 1.0, 0.4 and with the payload: observed / certified per figure
   over the whole path (the certificate covers the turns).
5. Per committed robot config, synthesized, verified and validated in this run (issue 49 item 7): the
   certificate's kind, its |e_y| at the samples and for all t, the boundary probe and the adversary from the
   boundary, certified / robot maximum on |e_y|, physics observed / certified |e_y|, verdict, synthesis and
   verification times (about 10 minutes for all).

    .venv/bin/python benchmarks/run_all.py bench_default
    .venv/bin/python benchmarks/bench_default.py box            # part 1 only
    .venv/bin/python benchmarks/bench_default.py configs turns  # part 5 for the named configs
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PHYSICS = (("friction 1.0", {"friction": 1.0}), ("friction 0.4", {"friction": 0.4}),
           ("friction 1.0, 10 kg 0.15 m forward", {"friction": 1.0, "payload_mass": 10.0, "payload_x": 0.15}))
KEYS = ("right", "left", "yaw", "icr_offset")


def _config(physics: dict | None = None):
    import yaml

    from robustsynth.config import load_config

    d = yaml.safe_load((ROOT / "configs" / "default.yaml").read_text())
    if physics:
        d["physics"] = dict(physics)
    return load_config(d)


def box() -> dict:
    """Part 1: the icr box the shipped recipe reads off the physics robot, per condition and their union."""
    from robustsynth.identification import identify
    from robustsynth.model import build_model
    from robustsynth.robot_verification.physics import excite

    rows, union = [], {}
    for name, phys in PHYSICS:
        cfg = _config(phys)
        t0 = time.perf_counter()
        logs = excite(build_model(cfg), episodes=4, seed=0, engine="physics")
        ident = identify(logs, cfg.robot.gear_radius, cfg.robot.track_distance, model="icr",
                         max_motor_speed=cfg.robot.max_motor_speed, pose_noise=(0.0, 0.0), settle=1.0)
        rows.append((name, ident.box, time.perf_counter() - t0))
        for k in KEYS:
            lo, hi = ident.box[k]
            union[k] = (min(lo, union.get(k, (lo, hi))[0]), max(hi, union.get(k, (lo, hi))[1]))
    cfg = _config()
    have = {"right": cfg.slip.right, "left": cfg.slip.left, "yaw": cfg.slip.yaw, "icr_offset": cfg.slip.icr_offset}
    print("| physics | mu_r | mu_l | yaw | x_icr [m] | excite + identify |")
    print("|---|---|---|---|---|---|")
    for name, b, dt in rows:
        print(f"| {name} | " + " | ".join(f"[{b[k][0]:.3f}, {b[k][1]:.3f}]" for k in KEYS) + f" | {dt:.1f} s |")
    print("| union | " + " | ".join(f"[{union[k][0]:.3f}, {union[k][1]:.3f}]" for k in KEYS) + " | |")
    print("| configs/default.yaml | " + " | ".join(f"[{have[k].min:g}, {have[k].max:g}]" for k in KEYS) + " | |")
    inside = all(have[k].min <= union[k][0] and union[k][1] <= have[k].max for k in KEYS)
    print(f"the default's box contains the union: {inside}")
    return union


def _synthesized_and_verified(model, out: Path) -> dict:
    """``synthesize`` then ``verify`` (no figures) into ``out``: the stages' results, their times, the boundary
    probe's largest V/level (straight and on arcs) and the adversary's from the boundary (None without)."""
    from robustsynth.pipeline import synthesis_stage, verification_stage

    t0 = time.perf_counter()
    ss = synthesis_stage(model, out, compare=False)
    t_syn = time.perf_counter() - t0
    t0 = time.perf_counter()
    vs = verification_stage(model, out, plots=False)
    mc = vs.data["monte_carlo"]
    bp = mc.get("boundary_probe") or {}
    return {"ss": ss, "vs": vs, "mc": mc, "t_syn": t_syn, "t_ver": time.perf_counter() - t0,
            "probe": max(bp.get("max_V_over_level_nonlinear", 0.0), (bp.get("arcs") or {}).get("max_V_over_level_nonlinear", 0.0)),
            "adv": (bp.get("adversary") or {}).get("max_V_over_level")}


def default() -> None:
    """Parts 2-4."""
    from robustsynth.model import build_model
    from robustsynth.pipeline import validation_stage

    cfg = _config()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        model = build_model(cfg)
        r = _synthesized_and_verified(model, out)
        ss, vs, t_syn, t_ver, probe, adv = r["ss"], r["vs"], r["t_syn"], r["t_ver"], r["probe"], r["adv"]
        c = ss.gains["certified"]
        ub, allt = c["ultimate_bound"], c.get("ultimate_bound_between_samples") or {}
        print(f"synthesis {t_syn:.0f} s: |e_y| <= {100 * ub['e_y']:.2f} cm at the samples, {100 * allt.get('e_y', float('nan')):.2f} cm "
              f"for all t (through the turns); |e_x| <= {100 * ub['e_x']:.2f} cm, |e_theta| <= {ub['e_theta']:.3f} rad, "
              f"|rho| <= {c['motor_speed_bound']:.2f} rad/s; heading bound {ss.gains['certificate'].get('heading_bound')}")
        ratios = r["mc"]["ratio_to_certified"]
        print(f"verification {t_ver:.0f} s: {'passed' if vs.data['passed'] else 'FAILED'}; probe V/level {probe:.3f}, "
              f"adversary from the boundary {adv:.3f}; observed / certified " + ", ".join(f"{k} {v:.3f}" for k, v in ratios.items())
              + f"; certified / robot maximum |e_y| {1.0 / ratios['e_y']:.2f}")
        print("| physics (4 episodes) | e_x | e_y | e_theta | torque-saturated |")
        print("|---|---|---|---|---|")
        for name, phys in PHYSICS:
            m = build_model(_config(phys))
            t0 = time.perf_counter()
            vd = validation_stage(m, out / "gains.json", out / f"val-{len(name)}", episodes=4, plots=False)
            rt = vd["ratio_to_certified"]
            print(f"| {name} | " + " | ".join(f"{rt[k]:.3f}" for k in ("e_x", "e_y", "e_theta"))
                  + f" | {vd['torque_saturated_s']:.1f} s ({time.perf_counter() - t0:.0f} s, {'passed' if vd['passed'] else 'FAILED'}) |")


def configs(names: list[str] | None = None) -> None:
    """Part 5: every committed robot config (or ``names``) synthesized, verified and run on the physics robot in
    this run: the certificate's kind, its |e_y| at the samples and for all t, the boundary probe and the adversary
    from the boundary (max V/level; the robot's claim is <= 1), certified / robot maximum on |e_y| (the Monte Carlo
    and the adversary from the steady states), the physics robot's observed / certified |e_y| (4 episodes, friction
    1.0), the verdict and the times."""
    import yaml

    from robustsynth.errors import RobustSynthError
    from robustsynth.config import load_config
    from robustsynth.model import build_model
    from robustsynth.pipeline import validation_stage

    print("| config | kinematics | slip | d_hi | certified \\|e_y\\| (all t) | probe | adversary from the boundary | "
          "certified / robot max \\|e_y\\| | physics observed / certified \\|e_y\\| | verdict | synthesis / verify |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for p in sorted((ROOT / "configs").glob("*.yaml")):
        d = yaml.safe_load(p.read_text())
        if d.get("plant") or (names and p.stem not in names):
            continue
        kin = (d.get("synthesis") or {}).get("kinematics", "linearized")
        cfg = load_config(p)
        model = build_model(cfg)
        row = f"| {p.stem} | {kin} | {cfg.slip.model} | {model.d_hi} | "
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp)
            t0 = time.perf_counter()
            try:
                r = _synthesized_and_verified(model, out)
            except RobustSynthError as exc:
                print(row + f"exit {exc.exit_code} ({time.perf_counter() - t0:.0f} s) | | | | | | |")
                continue
            vs, t_syn, t_ver, probe, adv = r["vs"], r["t_syn"], r["t_ver"], r["probe"], r["adv"]
            c = r["ss"].gains["certified"]
            ub, allt = c["ultimate_bound"], c.get("ultimate_bound_between_samples") or {}
            ey = r["mc"]["ratio_to_certified"]["e_y"]
            try:
                vd = validation_stage(model, out / "gains.json", out / "val", episodes=4, plots=False)
                phys = f"{vd['ratio_to_certified']['e_y']:.2g}"
            except RobustSynthError as exc:
                phys = f"exit {exc.exit_code}"
            bound = f"{100 * ub['e_y']:.2f} cm" + (f" ({100 * allt['e_y']:.2f})" if allt.get("e_y") else "")
            print(row + f"{bound} | {probe:.3f} | {'—' if adv is None else f'{adv:.3f}'} | {1.0 / ey:.2f} | {phys} | "
                  f"{'passed' if vs.data['passed'] else 'FAILED'} | {t_syn:.0f} s / {t_ver:.0f} s |")


def main() -> None:
    parts = sys.argv[1:] if __name__ == "__main__" else []
    if not parts or "box" in parts:
        box()
    if not parts or "default" in parts:
        default()
    if not parts or "configs" in parts:
        configs([p for p in parts if p not in ("box", "default", "configs")] or None)


if __name__ == "__main__":
    main()
