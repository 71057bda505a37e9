#!/usr/bin/env python3
"""Behaviour-identical harness for robustsynth refactors (issue 52): every committed config run by two
trees (say, main before a refactor in a clone, and after it), their outputs compared exactly.

Usage
-----
  PY=.venv/bin/python
  $PY tools/behaviour.py run TREE OUT [--only NAME ...] [--cheap-from OLD_OUT [--under 60]] [--python PY]
  $PY tools/behaviour.py compare OLD_OUT NEW_OUT [--common] [--quiet]

run
  Every committed ``TREE/configs/*.yaml`` (sorted; ``configs/sweeps/`` is not a run config) goes through
  ``robustsynth.regression.run_config(config_path, OUT/<config-stem>)`` -- what ``make test-slow``'s
  ``tests/test_regression.py`` calls -- one config at a time, each in its own subprocess with
  ``PYTHONPATH=TREE/src``, cwd ``TREE`` and the Makefile's TESTENV (OMP/OPENBLAS/MKL_NUM_THREADS=1).  The child
  drops every other ``robustsynth`` source directory from ``sys.path`` (the venv's editable install points at
  its own checkout) and refuses to run unless ``robustsynth`` is imported from ``TREE/src``.
  Unlike the test, the default and harsh-compensated configs are run too (the test skips them as slow).
  Every file the runner writes stays in OUT/<config-stem>/; the child's stdout+stderr go to OUT/_logs/<stem>.log;
  OUT/index.json records per config the wall time (s, of the subprocess), the exit status, the summary's
  status and verification_passed, the files written, and the tree, its commit and the python used.  ``--only`` restricts to the named configs;
  ``--cheap-from OLD_OUT`` to those whose run in OLD_OUT/index.json took less than ``--under`` seconds (60).
  The output directory of a config is emptied first.

compare
  Config directories present in either OUT (``--common``: in both) are compared (``_logs`` and index.json are
  not); a config or file present on one side only is a difference.  Strings have the run's own output directory and tree replaced by <OUT> and
  <TREE> first (both recorded in index.json), so the two runs may live in different places.
  * ``*.json``: recursive comparison, exact equality of every value (types too, int 1 != float 1.0; lists
    element-wise with their lengths; dict key sets), except the excluded keys below.  Each difference is printed
    as its key path with the old and new value and, for two numbers, the relative difference
    |new - old| / max(|old|, |new|).
  * ``*.mat`` (scipy savemat; the header carries a creation date): compared as their variables, exactly.
  * other files (report.md, synthesis.md, verification.md, model.md, margin.md; exports if a runner writes any):
    byte for byte, line by line, after masking the wall-clock number on the lines of TIMING_LINE (the number
    becomes <T>, the rest of the line is still compared; no line is dropped whole):
      synthesis.md (robot configs):  "... N solves in all, <T> s solving; fallback used: ..."
      synthesis.md, report.md (linear-plant gains, **Proof.** line): "... N solves, <T> s."
  Exit 0 when identical, 1 otherwise.

Excluded JSON keys (all of them; wall-clock durations of the computation, found by listing every key of a full
run of 78f88d4 whose name suggests a time and checking each against the time.perf_counter calls in src/):
  gains.json   solver.solve_time_s              robot gains: summed wall time of the synthesis' solver calls
  gains.json   solver.time_s                    linear-plant gains (dc-motor): wall time of the solves
  gains.json   delay_margin.search_s            linear-plant gains: wall time of the delay-margin search
  gains.json   delay_margin.certificate_s       ... and of its certificate (margins/linear.py, rounded to ms)
  gains.mat    lti_gains_json.<same three>      the .mat carries the linear-plant gains.json as a string
  margin.json  [margins.]<m>.search_s / .certificate_s / .time_s   lti-margins configs (zbp, zbp-h1; margins. before 2026-12-05)
Not excluded although the name looks like a time (simulated or configured times, deterministic):
  sampling_time, physics.timestep, monitor.clock_tol, window_s, transient_s, duration_s (simulated horizon),
  t_switch_s, segment_duration_s, time_to_reenter_s, max_time_to_reenter_s, longest_above_limit_s,
  slip_change_times, dimensions.n_s (a state dimension).  Exclusion is by exact place (EXCLUDED_PATHS), never
  by a substring of the name, so a real change in one of these is reported.
Not masked: gains_id (sha256 of config, K and certificate only: deterministic) and the .mat header's date
(the header is not compared).

Known load-dependent code paths (not excluded; if one fires, compare reports it): heading_search/remedies stop
trying heading bounds at a wall-clock deadline (REMEDY_BUDGET_S); none of the committed configs reached that code
in the reference run (no "not tried" in any output).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

DEFAULT_PYTHON = sys.executable  # a python with robustsynth's dependencies (the venv)
TESTENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
LOGS = "_logs"

# Excluded (wall-clock) keys: (regex, why), each matched (re.fullmatch) against "<file name>:<dotted key path>"
# (list indices as [i]; in gains.mat the gain's JSON string lti_gains_json is compared as JSON under its name).
# Found in a full run of 78f88d4 (every key whose value is a duration of the computation, checked against the
# time.perf_counter calls in src/robustsynth); nothing else is excluded.
EXCLUDED_PATHS: list[tuple[str, str]] = [
    (r"gains\.json:solver\.solve_time_s",
     "robot gain: wall time of all the synthesis' solver calls (synthesis/design.py, solve.py perf_counter)"),
    (r"gains\.(json:|mat:lti_gains_json\.)solver\.time_s",
     "linear-plant gain: wall time of its solves (synthesis/lti.py perf_counter; artifacts/gains.py)"),
    (r"gains\.(json:|mat:lti_gains_json\.)delay_margin\.(search_s|certificate_s)",
     "linear-plant gain: wall time of the delay-margin search / its certificate (margins/linear.py perf_counter)"),
    (r"margin\.json:(margins\.)?[^.\[]+\.(search_s|certificate_s|time_s)",
     "lti-margins configs: wall time of each margin's search / certificate (margins/linear.py perf_counter)"),
]

# Non-JSON text: (regex, why).  On a line where the regex matches, only its group "t" (the wall-clock number) is
# replaced by <T>; the rest of the line is still compared byte for byte.  No line is dropped whole.
TIMING_LINE: list[tuple[str, str]] = [
    (r"\d+ solves in all, (?P<t>[0-9.]+) s solving;",
     "synthesis.md of robot configs, the solver line (report/synthesis.py: solver solve_time_s)"),
    (r"\d+ solves, (?P<t>[0-9.]+) s\.$",
     "synthesis.md and report.md of linear-plant gains, end of the **Proof.** line (report/synthesis.py lti_synthesis_markdown: solver time_s)"),
]

CHILD = r"""
import sys, os, json
tree_src = os.path.realpath(sys.argv[1])
# keep TREE/src, drop every other directory holding a robustsynth package (the editable install's .pth)
sys.path[:] = [p for p in sys.path
               if os.path.realpath(p or '.') == tree_src or not os.path.isdir(os.path.join(p or '.', 'robustsynth'))]
import robustsynth
got = os.path.realpath(robustsynth.__file__)
if not got.startswith(tree_src + os.sep):
    sys.exit(f'robustsynth imported from {got}, not from {tree_src}')
print('robustsynth from', got, flush=True)
from pathlib import Path
from robustsynth.regression import run_config
summary = run_config(Path(sys.argv[2]), Path(sys.argv[3]))
print('STATUS', json.dumps(summary.get('status')), flush=True)
"""


# ----------------------------------------------------------------------------------------------- run
def _commit(tree: Path) -> str | None:
    try:
        return subprocess.run(["git", "-C", str(tree), "rev-parse", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def _dirty(tree: Path) -> list[str] | None:
    try:
        out = subprocess.run(["git", "-C", str(tree), "status", "--porcelain"], capture_output=True, text=True,
                             check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    return [line for line in out.splitlines() if line.strip()]


def cmd_run(a: argparse.Namespace) -> int:
    tree, out = Path(a.tree).resolve(), Path(a.out).resolve()
    if not (tree / "src" / "robustsynth").is_dir():
        sys.exit(f"{tree}: no src/robustsynth")
    configs = sorted((tree / "configs").glob("*.yaml"))
    if a.only:
        unknown = sorted(set(a.only) - {p.stem for p in configs})
        if unknown:
            sys.exit(f"no config {', '.join(unknown)} in {tree / 'configs'}")
        configs = [p for p in configs if p.stem in a.only]
    if a.cheap_from:
        old = json.loads((Path(a.cheap_from) / "index.json").read_text())["configs"]
        configs = [p for p in configs if p.stem in old and old[p.stem]["seconds"] < a.under]
    out.mkdir(parents=True, exist_ok=True)
    (out / LOGS).mkdir(exist_ok=True)
    index_path = out / "index.json"
    index: dict[str, Any] = json.loads(index_path.read_text()) if index_path.exists() else {}
    index.update({"tree": str(tree), "out": str(out), "commit": _commit(tree), "dirty_before": _dirty(tree),
                  "python": a.python, "env": TESTENV, "runner": "robustsynth.regression.run_config"})
    index.setdefault("configs", {})
    env = dict(os.environ, PYTHONPATH=str(tree / "src"), **TESTENV)
    env.pop("PYTHONSTARTUP", None)
    for cfg in configs:
        dest = out / cfg.stem
        if dest.exists():
            shutil.rmtree(dest)
        dest.mkdir()
        log = out / LOGS / f"{cfg.stem}.log"
        print(f"{cfg.name} ...", end=" ", flush=True)
        t0 = time.perf_counter()
        with open(log, "wb") as fh:
            rc = subprocess.run([a.python, "-c", CHILD, str(tree / "src"), str(cfg), str(dest)], cwd=tree, env=env,
                                stdout=fh, stderr=subprocess.STDOUT).returncode
        dt = time.perf_counter() - t0
        status = None
        for line in log.read_text(errors="replace").splitlines():
            if line.startswith("STATUS "):
                status = json.loads(line[7:])
        files = sorted(str(p.relative_to(dest)) for p in dest.rglob("*") if p.is_file())
        try:
            verdict = json.loads((dest / "summary.json").read_text()).get("verification_passed")
        except (OSError, ValueError):
            verdict = None
        index["configs"][cfg.stem] = {"config": str(cfg.relative_to(tree)), "seconds": round(dt, 2),
                                      "exit_status": rc, "status": status, "verification_passed": verdict,
                                      "files": files}
        index["dirty_after"] = _dirty(tree)
        index_path.write_text(json.dumps(index, indent=2) + "\n")
        print(f"exit {rc}, {status}, {dt:.1f} s, {len(files)} files", flush=True)
    bad = [k for k, v in index["configs"].items() if v["exit_status"] != 0]
    if index["dirty_after"] != index["dirty_before"]:
        print(f"WARNING: the tree changed during the runs: {index['dirty_after']}")
    return 1 if bad else 0


# ------------------------------------------------------------------------------------------- compare
def _excluded(fpath: str) -> str | None:
    f, _, path = fpath.partition(":")  # "<config>/<file>:<path>" -> "<file>:<path>"
    fpath = f"{f.rsplit('/', 1)[-1]}:{path}"
    for rx, why in EXCLUDED_PATHS:
        if re.fullmatch(rx, fpath):
            return why
    return None


def _norm(s: str, subs: list[tuple[str, str]]) -> str:
    for old, new in subs:
        s = s.replace(old, new)
    return s


def _num(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _rel(a: float, b: float) -> float:
    if a == b:
        return 0.0
    if not (math.isfinite(a) and math.isfinite(b)):
        return math.inf
    return abs(b - a) / max(abs(a), abs(b))


def _show(x: Any, width: int = 200) -> str:
    s = json.dumps(x) if not isinstance(x, float) else repr(x)
    return s if len(s) <= width else s[:width] + f"... ({len(s)} chars)"


def diff_json(a: Any, b: Any, path: str, fname: str, subs_a, subs_b, out: list[str], skipped: set[str]) -> None:
    why = _excluded(f"{fname}:{path}")
    if why is not None:
        skipped.add(re.sub(r"\[\d+\]", "[*]", f"{fname}:{path}"))
        return
    if isinstance(a, dict) and isinstance(b, dict):
        for k in list(a) + [k for k in b if k not in a]:
            p = f"{path}.{k}" if path else k
            if k not in b:
                if _excluded(f"{fname}:{p}") is None:
                    out.append(f"{fname}:{p}: only in old: {_show(a[k])}")
            elif k not in a:
                if _excluded(f"{fname}:{p}") is None:
                    out.append(f"{fname}:{p}: only in new: {_show(b[k])}")
            else:
                diff_json(a[k], b[k], p, fname, subs_a, subs_b, out, skipped)
        return
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{fname}:{path}: list length old {len(a)}, new {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            diff_json(x, y, f"{path}[{i}]", fname, subs_a, subs_b, out, skipped)
        return
    if isinstance(a, str) and isinstance(b, str):
        if _norm(a, subs_a) != _norm(b, subs_b):
            out.append(f"{fname}:{path}: old {_show(a)}, new {_show(b)}")
        return
    if _num(a) and _num(b):
        if type(a) is not type(b) or not (a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b))):
            out.append(f"{fname}:{path}: old {a!r}, new {b!r}, rel {_rel(float(a), float(b)):.3g}")
        return
    if type(a) is not type(b) or a != b:
        out.append(f"{fname}:{path}: old {_show(a)}, new {_show(b)}")


def _mask_timings(line: str) -> str:
    for rx, _ in TIMING_LINE:
        m = re.search(rx, line)
        if m:
            line = line[:m.start("t")] + "<T>" + line[m.end("t"):]
    return line


def diff_text(a: bytes, b: bytes, fname: str, subs_a, subs_b, out: list[str]) -> None:
    la = [_mask_timings(l) for l in _norm(a.decode("utf-8", "surrogateescape"), subs_a).splitlines(keepends=True)]
    lb = [_mask_timings(l) for l in _norm(b.decode("utf-8", "surrogateescape"), subs_b).splitlines(keepends=True)]
    if la == lb:
        return
    import difflib

    d = list(difflib.unified_diff(la, lb, f"old/{fname}", f"new/{fname}", n=0))
    out.append(f"{fname}: text differs ({sum(1 for l in d if l[:1] in '+-' and l[:3] not in ('+++', '---'))} lines)")
    out.extend("    " + l.rstrip("\n") for l in d[:40])
    if len(d) > 40:
        out.append(f"    ... {len(d) - 40} more diff lines")


def _mat_plain(x: Any) -> Any:
    """loadmat(simplify_cells=True) values as JSON-like data: arrays as (nested) lists with their dtype and shape
    kept visible, strings as str."""
    import numpy as np

    if isinstance(x, dict):
        return {k: _mat_plain(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        if x.dtype.kind in "US":
            return [_mat_plain(v) for v in x.ravel().tolist()] if x.size != 1 else str(x.ravel()[0])
        if x.dtype == object:
            return {"shape": list(x.shape), "items": [_mat_plain(v) for v in x.ravel()]}
        return {"dtype": str(x.dtype), "shape": list(x.shape), "values": x.ravel().tolist()}
    if isinstance(x, (list, tuple)):
        return [_mat_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


def diff_mat(pa: Path, pb: Path, fname: str, subs_a, subs_b, out: list[str], skipped: set[str]) -> None:
    """The variables of two .mat files (the header, with its creation date, is left out), exactly; a string
    variable named *_json is parsed and compared as JSON (so its timing keys are excluded as in the .json files)."""
    from scipy.io import loadmat

    def load(p: Path) -> dict[str, Any]:
        d = {k: _mat_plain(v) for k, v in loadmat(p, simplify_cells=True).items() if not k.startswith("__")}
        for k, v in d.items():
            if k.endswith("_json") and isinstance(v, str):
                d[k] = json.loads(v)
        return d

    diff_json(load(pa), load(pb), "", fname, subs_a, subs_b, out, skipped)


def _subs(root: Path, name: str) -> list[tuple[str, str]]:
    idx = root / "index.json"
    meta = json.loads(idx.read_text()) if idx.exists() else {}
    subs = [(str((root / name).resolve()), "<OUT>"), (str(root.resolve()), "<OUTROOT>")]
    if meta.get("tree"):
        subs.append((meta["tree"], "<TREE>"))
    return subs


def compare_dirs(old: Path, new: Path, common: bool = False) -> tuple[list[str], set[str]]:
    out: list[str] = []
    skipped: set[str] = set()
    sides = [{p.name for p in r.iterdir() if p.is_dir() and p.name != LOGS} for r in (old, new)]
    names = sorted(sides[0] & sides[1] if common else sides[0] | sides[1])
    if common and sides[0] ^ sides[1]:
        print(f"(--common: not compared, in one side only: {', '.join(sorted(sides[0] ^ sides[1]))})")
    for name in names:
        da, db = old / name, new / name
        if not da.is_dir() or not db.is_dir():
            out.append(f"{name}/: only in {'old' if da.is_dir() else 'new'}")
            continue
        sa, sb = _subs(old, name), _subs(new, name)
        fa = {str(p.relative_to(da)) for p in da.rglob("*") if p.is_file()}
        fb = {str(p.relative_to(db)) for p in db.rglob("*") if p.is_file()}
        for f in sorted(fa ^ fb):
            out.append(f"{name}/{f}: only in {'old' if f in fa else 'new'}")
        for f in sorted(fa & fb):
            fname = f"{name}/{f}"
            pa, pb = da / f, db / f
            if f.endswith(".json"):
                diff_json(json.loads(pa.read_text()), json.loads(pb.read_text()), "", fname, sa, sb, out, skipped)
            elif f.endswith(".mat"):
                diff_mat(pa, pb, fname, sa, sb, out, skipped)
            else:
                diff_text(pa.read_bytes(), pb.read_bytes(), fname, sa, sb, out)
    return out, skipped


def cmd_compare(a: argparse.Namespace) -> int:
    old, new = Path(a.old).resolve(), Path(a.new).resolve()
    diffs, skipped = compare_dirs(old, new, a.common)
    for d in diffs:
        print(d)
    if not a.quiet and skipped:
        print("(excluded timing keys met: " + ", ".join(sorted(skipped)) + ")")
    n = sum(1 for d in diffs if not d.startswith("    "))
    print(f"{'IDENTICAL' if not diffs else f'{n} DIFFERENCES'} ({old} vs {new})")
    return 0 if not diffs else 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="run every configs/*.yaml of TREE into OUT/<name>/")
    r.add_argument("tree")
    r.add_argument("out")
    r.add_argument("--only", nargs="+", metavar="NAME")
    r.add_argument("--cheap-from", metavar="OLD_OUT")
    r.add_argument("--under", type=float, default=60.0)
    r.add_argument("--python", default=DEFAULT_PYTHON)
    c = sub.add_parser("compare", help="diff two OUT directories; exit 0 if identical, 1 otherwise")
    c.add_argument("old")
    c.add_argument("new")
    c.add_argument("--common", action="store_true", help="only the configs present in both (e.g. a --cheap-from rerun)")
    c.add_argument("--quiet", action="store_true", help="do not list the excluded timing keys met")
    a = ap.parse_args(argv)
    return cmd_run(a) if a.cmd == "run" else cmd_compare(a)


if __name__ == "__main__":
    sys.exit(main())
