"""Long delays (issue 51): certified |e_y|, synthesis time, LMI count and peak memory against d_hi = 1..5, for
the default robot at Ts 0.1 s and 0.05 s, linearized and nonlinear kinematics, with the in-order delay vertices
(``polytopic``) and the product of the triangles (``polytopic-product``) side by side where they differ.

Each synthesis runs as its own `robustsynth synthesize --no-diagnose` process (peak memory from its rusage),
capped at CAP_S; a run past the cap is reported as "no conclusion in CAP_S".  The delay range for d_hi = d is
tau in [0.2 Ts, (d - 0.1) Ts].

    .venv/bin/python benchmarks/run_all.py bench_long_delays        (linearized, d_hi 1..5, both Ts: about an hour)
    .venv/bin/python benchmarks/bench_long_delays.py --kinematics nonlinear --d-max 3 --cap 900      (the robot proof)
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
CAP_S = 900.0


def _config(base: dict, Ts: float, d: int, kinematics: str, description: str) -> dict:
    cfg = json.loads(json.dumps(base))
    cfg["name"] = f"long-{Ts:g}-{d}-{kinematics}-{description}"
    net = cfg.setdefault("network", {})
    net["sampling_time"] = Ts
    net["delay"] = {"min": round(0.2 * Ts, 6), "max": round((d - 0.1) * Ts, 6)}
    syn = cfg.setdefault("synthesis", {})
    syn["kinematics"] = kinematics
    syn["delay_description"] = description
    return cfg


def _vertex_counts(cfg_path: Path) -> tuple[int, int, str]:
    """(delay vertices, vertices, cover) of the model, built in this process (cheap against the synthesis)."""
    from robustsynth.config import load_config
    from robustsynth.model import build_model

    m = build_model(load_config(cfg_path))
    return len(m.delay_combos) or 1, len(m.vertices), m.delay_cover


def _session_rss_mb(sid: int) -> float:
    """Resident memory [MB] of every process of session ``sid`` (Linux /proc)."""
    total = 0
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            if int(fields[3]) != sid:  # field 6 of stat: the session id
                continue
            for line in (d / "status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    total += int(line.split()[1])
        except (OSError, ValueError, IndexError):
            continue
    return total / 1024.0


def _run(cfg_path: Path, out: Path, cap: float) -> dict:
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, "-m", "robustsynth", "synthesize", str(cfg_path), "-o", str(out), "-q",
                          "--no-diagnose"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    import threading

    peak = [0.0]
    done = threading.Event()

    def watch() -> None:  # the largest sum of resident sets over the run's session (its solver child included)
        while not done.wait(0.2):
            peak[0] = max(peak[0], _session_rss_mb(p.pid))

    w = threading.Thread(target=watch, daemon=True)
    w.start()
    try:
        _, err = p.communicate(timeout=cap)
        timed_out = False
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        _, err = p.communicate()
        timed_out = True
    finally:  # this benchmark stopped (Ctrl-C, SIGTERM): its run and the run's solver child with it
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    done.set()
    w.join()
    wall = time.perf_counter() - t0
    row = {"wall_s": wall, "exit": None if timed_out else p.returncode, "peak_mb": peak[0]}
    gains = out / "gains.json"
    if not timed_out and p.returncode == 0 and gains.exists():
        g = json.loads(gains.read_text())
        ub = g["certified"].get("ultimate_bound") or {}
        row["e_y_cm"] = 100.0 * float(ub["e_y"]) if ub.get("e_y") is not None else None
        import re

        md = (out / "synthesis.md").read_text() if (out / "synthesis.md").exists() else ""
        m = re.search(r"In all: (\d+) LMIs", md)
        row["lmis"] = int(m.group(1)) if m else None
        row["solver_s"] = g["solver"].get("solve_time_s")
    else:
        row["error"] = (err.strip().splitlines() or [""])[-1][:160] if not timed_out else f"no conclusion in {cap:g} s"
    return row


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser()
    ap.add_argument("--kinematics", choices=["linearized", "nonlinear", "both"], default="linearized")
    ap.add_argument("--d-min", type=int, default=1)
    ap.add_argument("--d-max", type=int, default=5)
    ap.add_argument("--ts", type=float, nargs="*", default=[0.1, 0.05])
    ap.add_argument("--cap", type=float, default=CAP_S)
    args = ap.parse_args(argv if argv is not None else [])
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # unwinds through _run's cleanup
    base = yaml.safe_load((ROOT / "configs" / "default.yaml").read_text())
    kins = ["linearized", "nonlinear"] if args.kinematics == "both" else [args.kinematics]
    rows = []
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        for Ts in args.ts:
            for kin in kins:
                for d in range(args.d_min, args.d_max + 1):
                    seen = None
                    for desc in ("polytopic", "polytopic-product"):
                        cfg = _config(base, Ts, d, kin, desc)
                        path = tmp / f"{cfg['name']}.yaml"
                        path.write_text(yaml.safe_dump(cfg))
                        n_d, n_v, cover = _vertex_counts(path)
                        if desc == "polytopic-product" and seen == (n_d, n_v):
                            continue  # the in-order vertices are the product here: the same problem
                        seen = (n_d, n_v)
                        row = {"Ts": Ts, "d_hi": d, "kinematics": kin, "description": desc, "cover": cover,
                               "delay_vertices": n_d, "vertices": n_v, **_run(path, tmp / cfg["name"], args.cap)}
                        rows.append(row)
                        fig = f"|e_y| <= {row['e_y_cm']:.2f} cm" if row.get("e_y_cm") is not None else row.get("error", "")
                        print(f"  Ts {Ts:g} d_hi {d} {kin:10s} {desc:17s} ({cover}): {n_d:4d} delay vertices, {n_v:5d} "
                              f"vertices, {row.get('lmis')} LMIs, {row['wall_s']:7.1f} s, exit {row['exit']}, peak {row['peak_mb']:.0f} MB: {fig}",
                              flush=True)
    return rows


if __name__ == "__main__":
    main(sys.argv[1:])
