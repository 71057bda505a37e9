"""Issue 55, item 1: the slip estimate (monitor.Monitor.slip_estimate, docs/theory/17-the-slip-estimate.md).

For a slip box, a rate bound and a pose noise: Monte Carlo runs of the kinematic robot with its committed gain (slip
moving at the rate within the box, each track changing at its own time within the period, delays in their range),
replayed through the monitor; per period the estimate against the slip the robot had just before t_k.  Printed per
row: the a-priori half-width (slip_estimate_bound, straight at V^D), the half-width at a command's action (plus the
rate over the command's life), the box's; and measured: periods with the true traction outside (must be 0), periods
no traction explains, the median / 90th percentile / largest half-width of mu_r.  The last column is what a
compensated law would see: the traction ratio mu / mu_hat within 1 +- at_action / mu_lo, against the uncompensated
box's 1 +- half / centre.  Then, on the default robot, network and path with slip [0.6, 1] per track at 0.02 and 0.1 /s,
the certificate such a law (not built) would need.

    .venv/bin/python benchmarks/run_all.py bench_slip_estimate
"""

from __future__ import annotations

import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RUNS = 200
ROWS = (  # config, its committed gain, the slip's rate [1/s], the pose noise (sigma: m and rad)
    ("tracks-box", 0.5, 0.0005), ("tracks-box", 0.5, 0.0), ("tracks-box", 0.1, 0.0005), ("tracks-box", 0.1, 0.0),
    ("tracks-box", 0.02, 0.0), ("nonlinear-proof", 0.1, 0.0005), ("nonlinear-proof", 0.02, 0.0),
)


def _row(name: str, rate: float, noise: float) -> dict[str, float]:
    import numpy as np

    from robustsynth.artifacts.gains import controller_description, load_gains
    from robustsynth.config import config_to_dict, load_config
    from robustsynth.model import build_model
    from robustsynth.monitor import slip_estimate_bound
    from robustsynth.plants.path import path_of
    from robustsynth.runtime.replay import monitor_log
    from robustsynth.scenarios import draw_scenario, steady_state_start
    from robustsynth.robot_verification.simulate import run_logs, simulate

    d = config_to_dict(load_config(ROOT / "configs" / f"{name}.yaml"))
    d["slip"]["max_rate"] = rate
    d["verification"]["noise"] = {"position": noise, "heading": noise}
    cfg = load_config(d)
    g = load_gains(ROOT / "results" / "baselines" / name / "gains.json")
    model, K, path = build_model(cfg), np.asarray(g["K"]), path_of(cfg)
    desc = controller_description(g, cfg)
    bound = slip_estimate_bound(desc)
    steps = int(path.duration / model.Ts)
    scen = steady_state_start(model, K, path, draw_scenario(model, RUNS, 7, steps, path, within_period=True))
    logs = run_logs(model, simulate(model, K, path, scen), scen)
    outside = inconsistent = 0
    half = []
    for n, lg in enumerate(logs):
        for k, e in enumerate(monitor_log(lg, desc, estimate=True)["estimates"]):
            if k == 0 or not e["windows"]:
                continue
            if not e["consistent"]:
                inconsistent += 1
                continue
            for i, p in enumerate(("mu_r", "mu_l")):
                lo, hi = e["ranges"][p]
                outside += not lo <= scen.mu[n, k - 1, i] <= hi
            half.append(e["bound"]["mu_r"])
    lo_r, hi_r = cfg.slip.right.min, cfg.slip.right.max
    return {"a_priori": bound["half"]["mu_r"], "at_action": bound["at_action"]["mu_r"], "box": bound["box_half"]["mu_r"],
            "outside": outside, "inconsistent": inconsistent, "periods": len(half), "median": float(np.median(half)),
            "p90": float(np.percentile(half, 90)), "max": float(np.max(half)),
            "ratio_compensated": bound["at_action"]["mu_r"] / lo_r, "ratio_box": (hi_r - lo_r) / (hi_r + lo_r)}


def _compensated(rate: float) -> dict[str, float]:
    """What a law that divides each track's command by the estimate (not built) would have to be certified for, on the
    default robot, network and path with slip [0.6, 1] per track (issue 55's harsh ground) moving at ``rate``: the
    robot seeing the traction ratio mu / mu_hat in 1 +- at_action / mu_lo (slip_estimate_bound, exact poses) instead
    of mu, with the motor limit times mu_lo (a command divided by mu_hat >= mu_lo needs up to 1 / mu_lo more), for the
    nonlinear robot.  Returns the certified |e_y| at the samples and for all t [m] (nan: none, exit 3) and the time."""
    import math

    from robustsynth.artifacts.gains import controller_description, load_gains
    from robustsynth.config import config_to_dict, load_config
    from robustsynth.errors import InfeasibleError
    from robustsynth.model import build_model
    from robustsynth.monitor import slip_estimate_bound
    from robustsynth.synthesis import synthesize

    d = config_to_dict(load_config(ROOT / "configs" / "default.yaml"))  # its robot, network and path with turns
    d["slip"] = {"model": "tracks", "right": {"min": 0.6, "max": 1.0}, "left": {"min": 0.6, "max": 1.0}, "max_rate": rate}
    d["verification"]["noise"] = {"position": 0.0, "heading": 0.0}
    # the bound needs a monitor description: any gain with a certified set gives it (it does not depend on the gain)
    bound = slip_estimate_bound(controller_description(load_gains(ROOT / "results" / "baselines" / "default" / "gains.json"),
                                                       load_config(d)))
    lo = min(d["slip"]["right"]["min"], d["slip"]["left"]["min"])
    eps = max(bound["at_action"].values()) / lo
    c = dict(d, name="harsh-compensated")
    c["slip"] = {"model": "tracks", "right": {"min": 1.0 - eps, "max": 1.0 + eps}, "left": {"min": 1.0 - eps, "max": 1.0 + eps}}
    c["robot"] = dict(d["robot"], max_motor_speed=d["robot"]["max_motor_speed"] * lo)
    c["synthesis"] = dict(d["synthesis"], kinematics="nonlinear", heading_bound="auto")
    t0 = time.perf_counter()
    try:
        fig = synthesize(build_model(load_config(c))).certified
        e_y, e_y_all = fig["ultimate_bound"]["e_y"], fig["ultimate_bound_between_samples"]["e_y"]
    except InfeasibleError:
        e_y = e_y_all = math.nan
    return {"ratio": eps, "motor_factor": lo, "e_y": e_y, "e_y_all_t": e_y_all, "seconds": time.perf_counter() - t0}


def main() -> dict[str, float]:
    out: dict[str, float] = {}
    print("| box | rate [1/s] | noise sigma | a priori | at action | box | outside | inconsistent | periods | median | "
          "p90 | largest | mu/mu_hat - 1 compensated | uncompensated |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, rate, noise in ROWS:
        t0 = time.perf_counter()
        r = _row(name, rate, noise)
        print(f"| {name} | {rate:g} | {noise * 1e3:g} mm, {noise * 1e3:g} mrad | {r['a_priori']:.3f} | {r['at_action']:.3f} | "
              f"{r['box']:.3f} | {r['outside']} | {r['inconsistent']} | {r['periods']} | {r['median']:.3f} | {r['p90']:.3f} | "
              f"{r['max']:.3f} | +-{r['ratio_compensated']:.3f} | +-{r['ratio_box']:.3f} |  ({time.perf_counter() - t0:.0f} s)")
        for k, v in r.items():
            out[f"{name} {rate:g} {noise:g} {k}"] = float(v)
    print("\nA compensated law's certificate (not built; the robot sees mu / mu_hat, exact poses), for the nonlinear robot:")
    for rate in (0.02, 0.1):
        r = _compensated(rate)
        got = "none (exit 3)" if r["e_y"] != r["e_y"] else f"|e_y| <= {100 * r['e_y']:.2f} cm ({100 * r['e_y_all_t']:.2f} all t)"
        print(f"slip [0.6, 1] at {rate:g} /s: ratio 1 +- {r['ratio']:.3f}, motors x {r['motor_factor']:g}: {got} "
              f"({r['seconds']:.0f} s)")
        for k, v in r.items():
            out[f"compensated {rate:g} {k}"] = float(v)
    return out


if __name__ == "__main__":
    main()
