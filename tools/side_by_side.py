#!/usr/bin/env python3
"""Side-by-side timings of the paths the plant-generic refactor (issue 52) touches, old tree against
new, alternating in one run so that the machine's load falls on both alike.

Usage
-----
  .venv/bin/python tools/side_by_side.py OLD_TREE NEW_TREE [--rounds 3]

Each round runs one subprocess per tree (``PYTHONPATH=TREE/src``, one BLAS thread; every other
``robustsynth`` source directory dropped from ``sys.path``) that times, after one untimed warm-up call
(imports, first compilations):

- ``find_instability`` on the default config's committed gain at delay.max 0.1 s (the whole search,
  no witness) and 0.3 s (a witness at period 1);
- ``lti_margins`` of configs/zbp.yaml (periodic sequences per rotation class, the periodic radius);
- ``draw_scenario`` of configs/lossy-link.yaml, 200 runs x 300 steps, 20 seeds (the network's draws);
- ``synthesize`` of configs/paper-model.yaml (the robot's design, through its objective's module) and
  ``synthesize_lti`` of configs/dc-motor.yaml (the linear plant's), with the figures they certify.

It prints, per path, the medians over the rounds and new / old, and whether the figures each path
computes (the witness's radius, the exhibited delay margin) are identical.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

CHILD = r"""
import json, os, sys, time
from pathlib import Path
tree = Path(sys.argv[1]).resolve()
src = os.path.realpath(tree / "src")
sys.path[:] = [p for p in sys.path
               if os.path.realpath(p or '.') == src or not os.path.isdir(os.path.join(p or '.', 'robustsynth'))]
import numpy as np
import robustsynth
assert os.path.realpath(robustsynth.__file__).startswith(src + os.sep), robustsynth.__file__
from robustsynth.config import config_with, load_config
from robustsynth.margins import find_instability
try:
    from robustsynth.margins.linear import lti_margins
except ImportError:  # a tree before margins/ was a package
    from robustsynth.margins_lti import lti_margins
from robustsynth.model import build_model, pad_gain
from robustsynth.model.lti import lti_plant
from robustsynth.plants.path import make_path
from robustsynth.scenarios import draw_scenario

def timed(f):
    f()  # warm-up: imports and first calls
    t = time.perf_counter()
    out = f()
    return time.perf_counter() - t, out

res = {}
g = json.loads((tree / "results/baselines/default/gains.json").read_text())
cfg = load_config(tree / "configs/default.yaml")
for dm, key in ((0.1, "find_instability_full_s"), (0.3, "find_instability_witness_s")):
    m = build_model(config_with(cfg, {"network.delay.max": dm}), min_lifting=1)
    K = pad_gain(np.asarray(g["K"], dtype=float), m)
    res[key], w = timed(lambda: find_instability(m, K))
    res[key.replace("_s", "_radius")] = None if w is None else w["spectral_radius"]
zc = load_config(tree / "configs/zbp.yaml")
pl = lti_plant(zc, str(tree / "configs"))
t = time.perf_counter()
r = lti_margins(zc, pl)
res["lti_margins_zbp_s"] = time.perf_counter() - t
res["lti_margins_zbp_exhibited"] = r["delay_max"]["exhibited"]
lm = build_model(load_config(tree / "configs/lossy-link.yaml"))
path = make_path(lm.config.reference.path, lm.V)
res["draw_scenario_x20_s"], _ = timed(lambda: [draw_scenario(lm, 200, s, 300, path) for s in range(20)])
from robustsynth.synthesis import synthesize
from robustsynth.synthesis.lti import synthesize_lti
pm = build_model(load_config(tree / "configs/paper-model.yaml"))
res["synthesize_paper_model_s"], sr = timed(lambda: synthesize(pm))
res["synthesize_paper_model_e_y"] = sr.certified["ultimate_bound"]["e_y"]
dc = load_config(tree / "configs/dc-motor.yaml")
dp, n = lti_plant(dc, str(tree / "configs")), dc.network
res["synthesize_dc_motor_s"], ld = timed(lambda: synthesize_lti(dp, n.sampling_time, n.delay.min, n.delay.max,
                                                               n.dropouts.max_consecutive, dc.objective))
res["synthesize_dc_motor_K"] = np.asarray(ld.K).tolist()
print(json.dumps(res))
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args(argv)
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    runs: dict[str, list[dict]] = {"old": [], "new": []}
    for _ in range(a.rounds):
        for name, tree in (("old", a.old), ("new", a.new)):
            e = dict(env, PYTHONPATH=os.path.join(tree, "src"))
            out = subprocess.run([sys.executable, "-c", CHILD, tree], env=e, cwd=tree, capture_output=True, text=True)
            if out.returncode:
                print(f"{name} ({tree}) failed:\n{out.stderr[-3000:]}", file=sys.stderr)
                return 1
            runs[name].append(json.loads(out.stdout.strip().splitlines()[-1]))
    same = True
    for key in runs["old"][0]:
        o, n = [r[key] for r in runs["old"]], [r[key] for r in runs["new"]]
        if key.endswith("_s"):
            mo, mn = statistics.median(o), statistics.median(n)
            print(f"{key}: old {mo:.4f} s, new {mn:.4f} s, new / old {mn / mo:.3f} (medians of {a.rounds})")
        else:
            same &= o[0] == n[0]
            print(f"{key}: old {o[0]!r}, new {n[0]!r}, {'identical' if o[0] == n[0] else 'DIFFERENT'}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
