"""Issue 29: what the verified positive-definiteness test costs. It covers the magnitude of each
LMI's formula, its rounding radius and Rump's floating-point Cholesky. Its cost is put beside the
numpy re-check it extends and beside a whole synthesis, on the default robot and two larger configs.
The synthesis re-checks every point it accepts, so the test is paid once per solve.

Target: the verified test costs <= 10 % of the synthesis time on the default.

    .venv/bin/python benchmarks/run_all.py bench_verified_check
"""

from __future__ import annotations

import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REPEAT = 20


def main() -> dict[str, float]:
    import numpy as np

    import robustsynth.certificate.check as C
    from robustsynth import build_model, load_config, synthesize
    from robustsynth.artifacts.gains import load_gains
    from robustsynth.certificate.objectives import hinf, stability, ultimate_bound

    spent = {"t": 0.0}
    # the proof and the LMIs' magnitudes, where the checker and each objective's rows call them
    homes = {"lmi_stability": stability, "lmi_invariance": ultimate_bound, "lmi_hinf": hinf}
    real_proof, builders = C._proof, {n: getattr(mod, n) for n, mod in homes.items()}

    def timed(fn, only_mag=False):
        def wrap(*a, **k):
            mag = bool(a[-1]) if only_mag and a else False
            if only_mag and not mag:
                return fn(*a, **k)
            t0 = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                spent["t"] += time.perf_counter() - t0
        return wrap

    C._proof = timed(real_proof)
    for n, fn in builders.items():
        setattr(homes[n], n, timed(fn, only_mag=True))
    out: dict[str, float] = {}
    try:
        for name in ("default", "delay-multi-period", "lossy-link"):
            m = build_model(load_config(ROOT / "configs" / f"{name}.yaml"))
            g = load_gains(ROOT / "results" / "baselines" / name / "gains.json")
            K = np.asarray(g["K"], dtype=float)
            spent["t"] = 0.0
            t0 = time.perf_counter()
            for _ in range(REPEAT):
                chk = C.check_certificate(m, K, g["certificate"])
            total = (time.perf_counter() - t0) / REPEAT
            verified = spent["t"] / REPEAT
            allow = max(c.get("rounding_allowance", 0.0) for c in chk.checks)
            print(f"{name}: re-check {1000 * total:.1f} ms, of which the verified test {1000 * verified:.1f} ms "
                  f"({100 * verified / total:.0f} %); all proven: {chk.passed}; largest rounding allowance "
                  f"{allow:.2e} against a threshold of {0.5 * float(g['certificate']['margin']):.1e}")
            out[f"{name}_check_ms"] = 1000 * total
            out[f"{name}_verified_ms"] = 1000 * verified
        m = build_model(load_config(None))
        spent["t"] = 0.0
        t0 = time.perf_counter()
        res = synthesize(m)
        ts = time.perf_counter() - t0
        print(f"default synthesis: {ts:.2f} s, {res.solver['solves']} solves; the verified test took "
              f"{spent['t']:.3f} s of it ({100 * spent['t'] / ts:.1f} %, target <= 10 %)")
        out["synthesis_s"], out["synthesis_verified_s"] = ts, spent["t"]
    finally:
        C._proof = real_proof
        for n, fn in builders.items():
            setattr(homes[n], n, fn)
    return out


if __name__ == "__main__":
    main()
