"""Issue 54: the runtime monitor's false alarms in the envelope and what it takes to see a violation.

1. 1000 Monte Carlo runs of the default's committed gain (slip anywhere in its box, changing within periods,
   delays in [tau_min, tau_max]) with pose noise (0.5 mm, 0.5 mrad; the thresholds carry 6 sigma): runs with an
   alarm, alarm periods per cause.
2. 20 episodes on the MuJoCo robot (friction 1.0 and 0.4, 10 each): the same.
3. Injected (one run each, the same noise): a delay beyond tau_max, a loss burst beyond the cap, a traction of
   0.9 and of 0.6 (the box: 0.97-1.04), each from period 150: the period of the first alarm and its cause.
4. Injected on the MuJoCo robot (``validate --inject``, one episode each, from period 150): a delay spike, a loss
   burst, a mud patch (friction 0.3 with drag), a push, a command beyond the motor limit; and a patch of friction
   0.3 and 0.05 without drag (this robot's slip stays in the box there: no violation, no alarm expected).

    .venv/bin/python benchmarks/run_all.py bench_monitor
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NOISE = (0.0005, 0.0005)
K0 = 150


def main() -> dict[str, float]:
    import numpy as np

    from robustsynth.artifacts.gains import controller_description, load_gains
    from robustsynth.config import config_to_dict, load_config
    from robustsynth.model import build_model
    from robustsynth.plants.path import path_of
    from robustsynth.runtime.replay import monitor_log, monitor_logs
    from robustsynth.scenarios import draw_scenario, steady_state_start
    from robustsynth.robot_verification.simulate import run_logs, simulate

    d = config_to_dict(load_config(ROOT / "configs" / "default.yaml"))
    d["verification"]["noise"] = {"position": NOISE[0], "heading": NOISE[1]}
    cfg = load_config(d)
    gains = load_gains(ROOT / "results" / "baselines" / "default" / "gains.json")
    model, K, path = build_model(cfg), np.asarray(gains["K"]), path_of(cfg)
    desc = controller_description(gains, cfg)
    steps = int(path.duration / model.Ts)
    out: dict[str, float] = {}

    def runs(n, seed, **change):
        scen = steady_state_start(model, K, path, draw_scenario(model, n, seed, steps, path, within_period=True))
        for key, fn in change.items():
            scen = replace(scen, **{key: fn(getattr(scen, key).copy())})
        return run_logs(model, simulate(model, K, path, scen), scen)

    t0 = time.perf_counter()
    logs = runs(1000, 11)
    t1 = time.perf_counter()
    res = monitor_logs(logs, desc)
    t2 = time.perf_counter()
    print(f"1000 Monte Carlo runs x {steps} periods (simulated in {t1 - t0:.0f} s, monitored in {t2 - t1:.0f} s): "
          f"{res['runs_with_alarms']} runs with an alarm; alarm periods {res['alarm_periods']}")
    out["mc_runs_with_alarms"] = res["runs_with_alarms"]
    try:
        from robustsynth.robot_verification.physics import validate_physics
    except ImportError:  # the physics extra
        validate_physics = None
    if validate_physics is not None:
        alarmed, total = 0, 0
        for friction in (1.0, 0.4):
            dp = dict(d, physics={"friction": friction})
            m = build_model(load_config(dp))
            val = validate_physics(m, gains, episodes=10, seed=3)["validation"]
            mon = val["monitor"]
            alarmed += mon["runs_with_alarms"]
            total += mon["logs"]
            print(f"physics robot, friction {friction:g}, 10 episodes: {mon['runs_with_alarms']} with an alarm "
                  f"({mon['alarm_periods']})")
        out["physics_runs_with_alarms"] = alarmed
    d_hi = model.d_hi

    def spike(tau):
        tau[:, d_hi + K0] = cfg.network.delay.max + 0.07
        return tau

    def burst(tau):
        tau[:, d_hi + K0: d_hi + K0 + cfg.network.dropouts.max_consecutive + 1] = np.inf
        return tau

    def traction(level):
        def f(mu):
            mu[:, K0:, :2] = level
            return mu
        return f

    for name, change in (("delay 0.07 s beyond tau_max", {"taus": spike}), ("loss burst beyond the cap", {"taus": burst}),
                         ("traction 0.9", {"mu": traction(0.9)}), ("traction 0.6", {"mu": traction(0.6)})):
        r = monitor_log(runs(1, 5, **change)[0], desc)
        first = r["alarms"][0] if r["alarms"] else None
        print(f"{name} from period {K0}: " + (f"first alarm at period {first['period']} ({first['causes']})" if first else "no alarm"))
    if validate_physics is not None:
        from robustsynth.robot_verification.physics import Injection

        for inj in (Injection("delay", K0), Injection("losses", K0), Injection("friction", K0), Injection("push", K0),
                    Injection("command", K0), Injection("friction", K0, 0.3, drag=0.0), Injection("friction", K0, 0.05, drag=0.0)):
            res = validate_physics(model, gains, episodes=1, seed=3, inject=inj)
            r = monitor_log(res["logs"][0], desc)
            first = r["alarms"][0] if r["alarms"] else None
            print(f"physics robot, {inj.describe()}: " + (f"first alarm at period {first['period']} ({first['causes']})"
                                                           if first else "no alarm"))
            out[f"physics {inj.kind}{'' if inj.drag or inj.kind != 'friction' else f' {inj.size:g} no drag'} first alarm"] = (
                first["period"] if first else -1)
    return out


if __name__ == "__main__":
    main()
