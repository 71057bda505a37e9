"""Issue 22: the certificate for the nonlinear robot against the linearized one, per committed config.

Per config in configs/ with a certified gain in results/baselines/ (or those named on the command
line): the committed gain's certified |e_y| and |e_theta(t)| between samples, and its boundary probe
(verify's seed and sample count; one period on the exact lifted map and on the nonlinear robot,
max V+/level).  Then both certificates are synthesized side by side in this run, with the config's
own settings and ``synthesis.kinematics`` linearized / nonlinear (heading bound searched): their
|e_y|, the ratio, the nonlinear one's heading bound and its boundary probe on the nonlinear robot
(its claim: <= 1; for a turning config also on arcs), and both synthesis times.  "none" is exit 3 or 4 (InfeasibleError, SolverFailure: every solve failed, also unscaled): no heading bound gave a certificate.
The probes judge the runs with slip changing within the period too when the certificate covers it.
Then the default robot and network with slip boxes [lo, 1] per track: linearized and nonlinear |e_y|.
Then the configs a new user would try (issue 22's targets): ``configs/nonlinear-proof.yaml`` with short,
full-period and multi-period delays, a lossy link, asymmetric slip, a slip rate bound, a slip-dependent
Lyapunov matrix, integral action and a faster reference, each synthesized with nonlinear kinematics and
verified as ``robustsynth verify --runs 1000`` does, plus a probe of 200 000 boundary states with the local
search from its 1024 worst (another seed): verdict, max V/level of the Monte Carlo, samples outside, the
adversaries, both probes, and observed / certified |e_y|.

    .venv/bin/python benchmarks/run_all.py bench_nonlinear_proof
    .venv/bin/python benchmarks/bench_nonlinear_proof.py default nonlinear-proof   # a subset
    .venv/bin/python -c "import sys; sys.path.insert(0, 'benchmarks'); import bench_nonlinear_proof as b; b.new_user_variants()"
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _synth(cfg, kinematics: str):
    from robustsynth import build_model
    from robustsynth.errors import InfeasibleError, SolverFailure
    from robustsynth.synthesis import synthesize

    from pydantic import ValidationError

    c = cfg.model_copy(update={"synthesis": cfg.synthesis.model_copy(update={"kinematics": kinematics})})
    try:  # model_copy does not validate: a combination the config refuses (icr with nonlinear kinematics) is skipped
        c = type(cfg).model_validate(c.model_dump())
    except ValidationError as exc:
        return None, None, 0.0, "refused by the config: " + exc.errors()[0]["msg"].split(", ", 1)[-1].replace("@field:", "")
    m = build_model(c)
    t0 = time.perf_counter()
    try:
        r = synthesize(m)
    except (InfeasibleError, SolverFailure) as exc:
        return m, None, time.perf_counter() - t0, type(exc).__name__
    return m, r, time.perf_counter() - t0, ""


def main(names: list[str] | None = None) -> dict[str, dict[str, float]]:
    import numpy as np

    from robustsynth import build_model, load_config
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.certificate import check_certificate, lyapunov_of
    from robustsynth.robot_verification.nonlinear_checks import PROBE_REFINE, PROBE_SAMPLES
    from robustsynth.robot_verification.probe import boundary_probe

    out: dict[str, dict[str, float]] = {}
    print("| config | committed gain: \\|e_y\\| sampled / for all t, \\|e_theta(t)\\| | its probe: nonlinear max V+/level | "
          "linearized \\|e_y\\| (synthesis time) | nonlinear \\|e_y\\| (synthesis time) | ratio | heading bound | "
          "nonlinear gain's probe: max V+/level |")
    print("|---|---|---|---|---|---|---|---|")
    for cfg_path in sorted((ROOT / "configs").glob("*.yaml")):
        if names and cfg_path.stem not in names:
            continue
        gains_path = ROOT / "results" / "baselines" / cfg_path.stem / "gains.json"
        if not gains_path.exists():
            continue  # infeasible: nothing certified
        cfg = load_config(cfg_path)
        if cfg.synthesis.objective != "ultimate-bound" or cfg.synthesis.model != "slip-aware":
            continue
        m = build_model(cfg)
        g = load_gains(gains_path)
        K = np.asarray(g["K"], dtype=float)
        chk = check_certificate(m, K, g["certificate"])
        r0 = boundary_probe(m, K, lyapunov_of(m, g["certificate"]), float(chk.figures["ellipsoid_level"]),
                            samples=PROBE_SAMPLES, seed=cfg.verification.seed,
                            within_period=chk.figures.get("slip_within_period") == "covered", refine=PROBE_REFINE)
        lin_cfg = cfg.model_copy(update={"synthesis": cfg.synthesis.model_copy(update={"kinematics": "linearized"})})
        _, rl, tl, el = _synth(lin_cfg, "linearized")
        mn, rn, tn, en = _synth(cfg, "nonlinear")
        ey_l = rl.certified["ultimate_bound"]["e_y"] if rl else float("nan")
        row = {"committed_e_y": chk.figures["ultimate_bound"]["e_y"], "committed_probe": r0["max_V_over_level_nonlinear"],
               "linear_e_y": ey_l, "linear_s": tl, "nonlinear_s": tn}
        if rn is not None:
            mm = mn.with_heading_bound(rn.certificate["heading_bound"])
            rp = boundary_probe(mm, rn.K, lyapunov_of(mm, rn.certificate), float(rn.check.figures["ellipsoid_level"]),
                                samples=PROBE_SAMPLES, seed=cfg.verification.seed,
                                within_period=rn.check.figures.get("slip_within_period") == "covered", refine=PROBE_REFINE)
            ey_n = rn.certified["ultimate_bound"]["e_y"]
            row.update(nonlinear_e_y=ey_n, heading_bound=rn.certificate["heading_bound"],
                       nonlinear_probe=rp["max_V_over_level_nonlinear"])
            ey_t = rn.certified["ultimate_bound_between_samples"]["e_y"]
            nl = f"{100 * ey_n:.2f} cm, for all t {100 * ey_t:.2f} cm ({tn:.1f} s) | {ey_n / ey_l:.2f} | " \
                 f"{rn.certificate['heading_bound']:g} rad | " \
                 f"{rp['max_V_over_level_nonlinear']:.4f}"
        else:
            nl = f"none, {en} ({tn:.1f} s) | | | "
        def arcs(r):  # a turning certificate's probe on arcs beside its straight one
            return f" (arcs {r['arcs']['max_V_over_level_nonlinear']:.4f})" if r.get("arcs") else ""

        if rn is not None:
            nl += arcs(rp)
        hw = chk.figures.get("heading_within_period")
        hw = "—" if hw is None else f"{hw:.3f} rad"  # norm-bounded delays: no break points to bound
        cont = chk.figures["ultimate_bound_between_samples"]["e_y"]
        print(f"| {cfg_path.stem} | {100 * row['committed_e_y']:.2f} / {100 * cont:.2f} cm, {hw} | {row['committed_probe']:.4f}{arcs(r0)} | "
              f"{100 * ey_l:.2f} cm ({tl:.1f} s) | {nl} |", flush=True)
        out[cfg_path.stem] = row
    if not names:
        out.update(slip_boxes())
        out.update(new_user_variants())
    return out


# configs/nonlinear-proof.yaml with one change each (top-level sections replaced whole)
VARIANTS = {
    "delays [0, 20] ms": {"network": {"sampling_time": 0.1, "delay": {"min": 0.0, "max": 0.02}}},
    "delays [0, 100] ms": {"network": {"sampling_time": 0.1, "delay": {"min": 0.0, "max": 0.1}}},
    "delays [50, 180] ms": {"network": {"sampling_time": 0.1, "delay": {"min": 0.05, "max": 0.18}}},
    "1 loss in a row, slip [0.9, 1]": {
        "network": {"sampling_time": 0.1, "delay": {"min": 0.01, "max": 0.08}, "dropouts": {"max_consecutive": 1}},
        "slip": {"right": {"min": 0.9, "max": 1.0}, "left": {"min": 0.9, "max": 1.0}}},
    "slip right [0.85, 1], left [0.75, 0.95]": {"slip": {"right": {"min": 0.85, "max": 1.0}, "left": {"min": 0.75, "max": 0.95}}},
    "slip.max_rate 0.5 /s": {"slip": {"right": {"min": 0.8, "max": 1.0}, "left": {"min": 0.8, "max": 1.0}, "max_rate": 0.5}},
    "slip [0.7, 1], slip-dependent": {
        "slip": {"right": {"min": 0.7, "max": 1.0}, "left": {"min": 0.7, "max": 1.0}},
        "synthesis": {"objective": "ultimate-bound", "kinematics": "nonlinear", "lyapunov": "slip-dependent"}},
    "integral action": {"synthesis": {"objective": "ultimate-bound", "kinematics": "nonlinear", "integral_action": True}},
    "V^D 0.8 m/s, slip [0.9, 1]": {"reference": {"speed": 0.8},
                                   "slip": {"right": {"min": 0.9, "max": 1.0}, "left": {"min": 0.9, "max": 1.0}}},
}
STRONG_PROBE = (200_000, 1024, 100)  # samples, searched starts, seed


def new_user_variants(runs: int = 1000) -> dict[str, dict[str, float]]:
    """Each of :data:`VARIANTS`: nonlinear synthesis, verify with ``runs`` Monte Carlo runs, and a
    stronger boundary probe than verify's."""
    import yaml

    from robustsynth import build_model
    from robustsynth.certificate import lyapunov_of
    from robustsynth.config import parse_config
    from robustsynth.verification.checks import verify
    from robustsynth.robot_verification.probe import boundary_probe

    base = yaml.safe_load((ROOT / "configs" / "nonlinear-proof.yaml").read_text())
    out: dict[str, dict[str, float]] = {}
    print(f"\n| variant of nonlinear-proof | \\|e_y\\| (heading bound, slip within a period; synthesis time) | verify, {runs} runs | "
          "Monte Carlo max V/level on the certified steps (samples outside) | adversary max V/level: from steady states / from the boundary | "
          f"probe max V+/level: verify's / {STRONG_PROBE[0]} states + {STRONG_PROBE[1]} searched | observed / certified \\|e_y\\| |")
    print("|---|---|---|---|---|---|---|")
    for name, over in VARIANTS.items():
        cfg = parse_config(yaml.safe_dump({**base, **over}))
        _, r, t, err = _synth(cfg, "nonlinear")
        if r is None:
            print(f"| {name} | none, {err} ({t:.0f} s) | | | | | |", flush=True)
            out[name] = {"nonlinear_s": t}
            continue
        m = build_model(cfg)
        res = verify(m, r, runs=runs)
        mc = res.monte_carlo
        bp = mc["boundary_probe"]
        mm = m.with_heading_bound(r.certificate["heading_bound"],
                                  within_period=bool(r.certificate.get("within_period_channels", False)))
        samples, refine, seed = STRONG_PROBE
        sp = boundary_probe(mm, r.K, lyapunov_of(mm, r.certificate), float(r.check.figures["ellipsoid_level"]),
                            samples=samples, seed=seed,
                            within_period=r.check.figures.get("slip_within_period") == "covered", refine=refine)
        ey = r.certified["ultimate_bound"]["e_y"]
        seen = mc["ratio_to_certified"]["e_y"]
        row = {"e_y": ey, "nonlinear_s": t, "passed": float(res.passed),
               "mc_max_V": mc["V_over_level"]["max_in_certified_steps"], "samples_outside": mc["V_over_level"]["samples_outside"],
               "adversary": mc["adversarial"]["max_V_over_level"], "adversary_boundary": bp["adversary"]["max_V_over_level"],
               "probe": bp["max_V_over_level_nonlinear"], "strong_probe": sp["max_V_over_level_nonlinear"], "seen_e_y": seen}
        print(f"| {name} | {100 * ey:.2f} cm ({r.certificate['heading_bound']:g} rad, "
              f"{r.check.figures.get('slip_within_period', '')[:7]}; {t:.0f} s) | {'passed' if res.passed else 'FAILED'} | "
              f"{row['mc_max_V']:.6f} ({row['samples_outside']}) | {row['adversary']:.4f} / {row['adversary_boundary']:.4f} | "
              f"{row['probe']:.4f} / {row['strong_probe']:.4f} | {seen:.3f} |", flush=True)
        out[name] = row
    return out


SLIP_BOXES = (0.9, 0.8, 0.7, 0.6)  # the lower end of each track's slip range (the upper is 1)


def slip_boxes() -> dict[str, dict[str, float]]:
    """The default robot and network with each track's slip in [lo, 1]: the linearized and the
    nonlinear certificate's |e_y| and the nonlinear one's heading bound and slip coverage."""
    from robustsynth import load_config

    base = load_config()  # the embedded default
    out: dict[str, dict[str, float]] = {}
    print("\n| slip box per track | linearized \\|e_y\\| | nonlinear \\|e_y\\| | ratio | heading bound | slip within a period |")
    print("|---|---|---|---|---|---|")
    for lo in SLIP_BOXES:
        box = {"min": lo, "max": 1.0}
        cfg = base.model_copy(update={"slip": base.slip.model_copy(update={
            "right": base.slip.right.model_copy(update=box), "left": base.slip.left.model_copy(update=box)})})
        _, rl, _, _ = _synth(cfg, "linearized")
        _, rn, tn, en = _synth(cfg, "nonlinear")
        ey_l = rl.certified["ultimate_bound"]["e_y"]
        if rn is None:
            print(f"| [{lo:g}, 1] | {100 * ey_l:.2f} cm | none ({en}, {tn:.0f} s) | | | |", flush=True)
            out[f"slip [{lo:g}, 1]"] = {"linear_e_y": ey_l}
            continue
        ey_n = rn.certified["ultimate_bound"]["e_y"]
        print(f"| [{lo:g}, 1] | {100 * ey_l:.2f} cm | {100 * ey_n:.2f} cm ({tn:.0f} s) | {ey_n / ey_l:.2f} | "
              f"{rn.certificate['heading_bound']:g} rad | {rn.check.figures.get('slip_within_period', '')[:7]} |", flush=True)
        out[f"slip [{lo:g}, 1]"] = {"linear_e_y": ey_l, "nonlinear_e_y": ey_n, "nonlinear_s": tn}
    return out


if __name__ == "__main__":
    main(sys.argv[1:] or None)
