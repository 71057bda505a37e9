"""Issue 55: the slip-compensated law (docs/theory.md §18) on harsh ground, measured end to end.

1. ``configs/harsh-compensated.yaml`` (mu_r, mu_l in [0.6, 1.04], exact poses, the default robot, network and eased
   arcs) at slip rates 0.01, 0.02 and 0.05 /s: the error ``auto`` gives and the ratio box, the synthesis (timed; exit 3
   where no robot proof exists), the certified |e_y| at the samples and for all t, and — where certified — ``verify``'s
   run of the law on the true slip with the estimator in the loop (200 runs): the share of periods the condition held,
   the steps judged and those that left the set, observed / certified on the covered samples, and the slip-jump
   experiment's recovery.
2. The committed gain on the MuJoCo robot (4 episodes): friction 1.0, a friction-0.4 patch and back, a mud patch.

    .venv/bin/python benchmarks/run_all.py bench_compensated
    .venv/bin/python benchmarks/bench_compensated.py physics     # part 2 only
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RATES = (0.01, 0.02, 0.05)


def _config(rate: float):
    from robustsynth.config import config_from_dict, config_to_dict, load_config

    d = config_to_dict(load_config(ROOT / "configs" / "harsh-compensated.yaml"))
    d["slip"]["max_rate"] = rate
    d["name"] = f"harsh-compensated-{rate:g}"
    return config_from_dict(d)


def rates() -> None:
    """Part 1."""
    from robustsynth.errors import InfeasibleError
    from robustsynth.model import build_model
    from robustsynth.pipeline import synthesis_stage, verification_stage

    print("| slip rate [1/s] | error (auto) | ratio box | synthesis | certified \\|e_y\\| (all t) | condition held | "
          "steps judged / left | observed / certified (e_x, e_y) | after a jump: condition back, in the set |")
    print("|---|---|---|---|---|---|---|---|---|")
    for rate in RATES:
        model = build_model(_config(rate))
        comp = model.compensation
        head = f"| {rate:g} | {comp.error:.4f} | 1 ± {comp.ratio[0][1] - 1.0:.4f} |"
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            try:
                ss = synthesis_stage(model, Path(tmp), compare=False, diagnose=False)
            except InfeasibleError as exc:
                print(f"{head} exit 3 in {time.perf_counter() - t0:.0f} s | none: {str(exc)[:160]}… | | | | |")
                continue
            t_syn = time.perf_counter() - t0
            c = ss.gains["certified"]
            vs = verification_stage(model, Path(tmp), plots=False)
            rec = vs.data["monte_carlo"]["compensated"]
            j = rec["jump"]
            print(f"{head} {t_syn:.0f} s | {100 * c['ultimate_bound']['e_y']:.2f} cm "
                  f"({100 * c['ultimate_bound_between_samples']['e_y']:.2f} cm) | {100 * rec['condition_held_share']:.1f} % | "
                  f"{rec['steps_judged']} / {rec['steps_leaving_the_set']} | {rec['ratio_to_certified']['e_x']:.3f}, "
                  f"{rec['ratio_to_certified']['e_y']:.3f} | {j['recovery_periods']['median']:g} (max "
                  f"{j['recovery_periods']['max']}), {j['back_in_the_set_periods']['median']:g} (max "
                  f"{j['back_in_the_set_periods']['max']}) periods; verdict {'passed' if vs.data['passed'] else 'FAILED'} |")


def physics() -> None:
    """Part 2."""
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.config import load_config
    from robustsynth.model import build_model
    from robustsynth.plants.physics import available
    from robustsynth.robot_verification.physics import Injection, validate_physics

    if available():
        print(f"physics: {available()}")
        return
    model = build_model(load_config(ROOT / "configs" / "harsh-compensated.yaml"))
    gains = load_gains(ROOT / "results" / "baselines" / "harsh-compensated" / "gains.json")
    print("| MuJoCo robot (4 episodes) | estimate (median) | condition held | samples judged / outside | "
          "\\|e_y\\| / certified (all t) | monitor alarms | verdict |")
    print("|---|---|---|---|---|---|---|")
    for name, inj in (("friction 1.0", None), ("a friction-0.4 patch (periods 150-249)", Injection("patch", 150, 0.4)),
                      ("mud: friction 0.3 and a drag from period 150", Injection("friction", 150))):
        t0 = time.perf_counter()
        vd = validate_physics(model, gains, episodes=4, seed=0, inject=inj)["validation"]
        c = vd["compensated"]
        alarms = ", ".join(f"{k} {v}" for k, v in vd["monitor"]["alarm_periods"].items() if v) or "none"
        print(f"| {name} | {c['estimate_median'][0]:.3f}, {c['estimate_median'][1]:.3f} | "
              f"{100 * c['condition_held_share']:.1f} % | {c['samples_judged']} / {c['samples_judged_outside_the_set']} | "
              f"{vd['ratio_to_certified']['e_y']:.3f} | {alarms} | {'passed' if vd['passed'] else 'FAILED'} "
              f"({time.perf_counter() - t0:.1f} s) |")


def main() -> None:
    rates()
    physics()


if __name__ == "__main__":
    {"rates": rates, "physics": physics}.get(sys.argv[1] if len(sys.argv) > 1 else "", main)()
