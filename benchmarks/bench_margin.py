"""robustsynth margin on the default gain: time, and the certified vs exhibited delay bound (the
honesty figure), with a common Lyapunov matrix (the default) and with --lyapunov auto.

Targets (issue 9): <= 30 s; certified tau_max within 15 % of the exhibited one."""

from __future__ import annotations

import time


def main() -> dict[str, float]:
    from robustsynth import build_model, load_config
    from robustsynth.margins import margin
    from robustsynth.synthesis import synthesize

    cfg = load_config(None)
    K = synthesize(build_model(cfg)).K
    out: dict[str, float] = {}
    for lyap in ("common", "auto"):
        t0 = time.perf_counter()
        rep = margin(cfg, K, lyapunov=lyap)
        dt = time.perf_counter() - t0
        d, s = rep.delay_max, rep.slip_min
        out[f"{lyap}_s"] = dt
        out[f"{lyap}_gap"] = d.gap if d.gap is not None else float("nan")
        print(f"margin, default gain, lyapunov {lyap}: {dt:.1f} s (target <= 30 s)")
        print(f"  {d.line()}")
        print(f"    witness: delays {[round(x, 4) for x in d.witness['delays']]}, slip {d.witness['slip']}, "
              f"spectral radius {d.witness['spectral_radius']:.6f}" if d.witness else "    no witness")
        print(f"  {s.line()}")
        n_cert = sum(1 for e in d.evaluations + s.evaluations if e['test'] == 'certificate')
        print(f"  {n_cert} analysis LMIs, {len(d.evaluations) + len(s.evaluations) - n_cert} instability searches")
    return out


if __name__ == "__main__":
    main()
