"""Issue 22, item 4: what certifying a reference that turns along arcs costs (Model.with_turns,
docs/theory.md §10 "Turning along arcs").

Per slip box (nonlinear-proof's [0.8, 1] and the default's [0.6, 1], default robot and network),
kinematics (linearized; nonlinear: the certificate covers the nonlinear robot on its set, heading
bound searched) and per largest reference yaw rate w_bar (arcs of radius V^D / w_bar): the
certified |e_x|, |e_y|, |e_theta| and motor bound (with the feedforward's share), the bound on |e_y(t)|
between samples (on arcs: the exact arcs in the turning frame, docs/theory.md §10), the synthesis time,
and the boundary probe on arcs (the nonlinear robot, one period from 20 000 states on the set's
boundary, slip at a corner, random delays, the yaw rates as ``robot_verification.probe.arc_period`` draws
them: max V+/level), and the same states with each track's slip jumping to the other end of its range at
its own random time within the period (which a common certificate covers, docs/theory.md §10; the
straight-segment one covers it on straight segments only).  w_bar = 0 is the straight-segment certificate;
its probe is run on arcs of the next row's w_bar (it does not cover them).  "none" is exit 3 (Infeasible)
or 4 (SolverFailure).  Then :func:`lossy`: a nonlinear turning certificate on a lossy link (d_hi = 2), verified.

    .venv/bin/python benchmarks/run_all.py bench_turns
"""

from __future__ import annotations

import time

import numpy as np

BOXES = ((0.8, "linearized", (0.0, 0.1, 0.2, 0.35)), (0.6, "linearized", (0.0, 0.05, 0.1)),
         (0.8, "nonlinear", (0.0, 0.1, 0.5 / 3.0, 0.25)))


def _probe(model, K, P, level, wbar, N=20000, seed=1, within=False):
    from robustsynth.scenarios import random_delays, track_changes
    from robustsynth.robot_verification.probe import arc_period

    rng = np.random.default_rng(seed)
    n_e, n_u, d_hi = model.n_e, model.n_u, model.d_hi
    x = rng.normal(size=(N, model.n_s))
    x /= np.sqrt(np.einsum("ni,ij,nj->n", x, P, x) / level)[:, None]
    (rl, rh), (ll, lh) = model.slip_ranges
    mu = np.stack([rng.choice([rl, rh], N), rng.choice([ll, lh], N)], axis=1)
    S = model.s_tilde(random_delays(model, rng, N, 1))[:, 0]
    du = x @ K.T
    turning = model if wbar == getattr(model.turns, "max_yaw_rate", None) else model.with_turns(wbar)
    switch = None
    if within:  # each track to the other end of its range at its own time within the period
        lo, hi = np.array([rl, ll]), np.array([rh, lh])
        switch = track_changes(mu, lo + hi - mu, rng.uniform(0.0, model.Ts, (N, 2)))
    e = arc_period(turning, x[:, :n_e], du, x[:, n_e : n_e + d_hi * n_u].reshape(N, d_hi, n_u), S, mu, rng,
                   switch=switch)
    xi = np.concatenate([e, du, x[:, n_e : n_e + (d_hi - 1) * n_u]], axis=1)
    return float(np.max(np.einsum("ni,ij,nj->n", xi, P, xi) / level))


def main() -> dict:
    from robustsynth import build_model, load_config
    from robustsynth.errors import InfeasibleError, SolverFailure
    from robustsynth.synthesis import synthesize

    out = {}
    print("| slip box | kinematics | w_bar [rad/s] (arc radius) | \\|e_x\\| | \\|e_y\\| | \\|e_theta\\| | motor bound "
          "[rad/s] | \\|e_y(t)\\| for all t | synthesis | boundary probe on arcs: max V+/level | the same, slip "
          "jumping within the period | slip within a period |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for lo, kin, wbars in BOXES:
        cfg = load_config(None)
        cfg = cfg.model_copy(update={
            "slip": cfg.slip.model_copy(update={"right": cfg.slip.right.model_copy(update={"min": lo}),
                                                "left": cfg.slip.left.model_copy(update={"min": lo})}),
            "synthesis": cfg.synthesis.model_copy(update={"delay_description": "polytopic", "kinematics": kin})})
        base = build_model(cfg)
        for i, wbar in enumerate(wbars):
            model = base.with_turns(wbar) if wbar > 0 else base
            t0 = time.perf_counter()
            try:
                r = synthesize(model)
            except (InfeasibleError, SolverFailure) as exc:
                print(f"| [{lo:g}, 1] | {kin} | {wbar:.3g} | none ({type(exc).__name__}) | | | | | {time.perf_counter() - t0:.1f} s | | | |",
                      flush=True)
                continue
            dt = time.perf_counter() - t0
            f = r.check.figures
            ub = f["ultimate_bound"]
            probe_w = wbar if wbar > 0 else (wbars[i + 1] if i + 1 < len(wbars) else 0.0)
            probe = _probe(model, r.K, np.asarray(r.certificate["P"]), f["ellipsoid_level"], probe_w)
            jumps = _probe(model, r.K, np.asarray(r.certificate["P"]), f["ellipsoid_level"], probe_w, within=True)
            radius = "straight" if wbar == 0 else f"{model.V / wbar:.3g} m"
            print(f"| [{lo:g}, 1] | {kin} | {wbar:.3g} ({radius}) | {100 * ub['e_x']:.2f} cm | {100 * ub['e_y']:.2f} cm | "
                  f"{ub['e_theta']:.3f} rad | {f['motor_speed_bound']:.2f} | "
                  f"{100 * f['ultimate_bound_between_samples']['e_y']:.2f} cm | {dt:.1f} s | "
                  f"{probe:.3f} (w_bar {probe_w:g}) | {jumps:.3f} | {f.get('slip_within_period', '')} |", flush=True)
            out[f"{lo}/{kin}/{wbar:.4g}"] = {"e_y": ub["e_y"], "probe": probe, "probe_jumps": jumps, "time_s": dt}
    out["lossy"] = lossy()
    return out


LOSSY = {"slip.right.min": 0.9, "slip.left.min": 0.9, "reference.turn_radius": 5.0,
         "network.dropouts.max_consecutive": 1}


def lossy() -> dict:
    """A nonlinear turning certificate on a lossy link (d_hi = 2): configs/nonlinear-proof.yaml with LOSSY (slip
    [0.9, 1], 5 m arcs, one lost command in a row at most), synthesized and verified (its 200 runs): the
    certified bounds, the synthesis time and verify's boundary probes, adversary and between-samples ratio."""
    from pathlib import Path

    from robustsynth import build_model, load_config
    from robustsynth.config import config_with
    from robustsynth.synthesis import synthesize
    from robustsynth.verification import verify

    cfg = config_with(load_config(Path(__file__).resolve().parents[1] / "configs" / "nonlinear-proof.yaml"), LOSSY)
    model = build_model(cfg)
    t0 = time.perf_counter()
    r = synthesize(model)
    dt = time.perf_counter() - t0
    res = verify(model, r)
    f = r.check.figures
    ub = f["ultimate_bound"]
    ratio = {c["name"].split(": ", 1)[1][:40]: c["value"] for c in res.checks if c["name"].startswith("nonlinear: ")
             and isinstance(c["value"], float) and c["threshold"] == 1.0}
    print(f"\nlossy link, nonlinear, 5 m arcs, slip [0.9, 1] (d_hi = {model.d_hi}): |e_x| {100 * ub['e_x']:.2f} cm, "
          f"|e_y| {100 * ub['e_y']:.2f} cm, |e_theta| {ub['e_theta']:.3f} rad, motor {f['motor_speed_bound']:.2f} rad/s, "
          f"heading bound {r.certificate['heading_bound']:g} rad, synthesis {dt:.0f} s, verify "
          f"{'passed' if res.passed else 'FAILED'}; " + ", ".join(f"{k}: {v:.3f}" for k, v in ratio.items()), flush=True)
    return {"e_y": ub["e_y"], "time_s": dt, "passed": res.passed, **ratio}


if __name__ == "__main__":
    main()
