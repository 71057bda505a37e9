"""Regression on ``configs/``: run every config and compare with ``results/baselines/<name>/summary.json``.

    python -m robustsynth.regression --write   # regenerate the baselines (make baselines)
    python -m robustsynth.regression           # compare (what the test in make test does)

Tolerances: certified figures (bounds, the decay rate, gains: each a claim, the smaller the stronger) no weaker
than the baseline's by more than relative 1e-3, a stronger one is no regression: which points of a scan Clarabel
ends 'optimal_inaccurate' and the numpy re-check accepts varies with the machine's BLAS kernels, and so does the
optimum found (configs/turns.yaml certified |e_x| 0.76 % lower, its decay rate and motor bound 0.1-0.2 % lower, on
a 2-core EPYC with OpenBLAS's Haswell kernels than on the machine its baseline was written on); Monte Carlo maxima
relative 1e-2 either way (they depend on the gain, which solvers reproduce to their accuracy only); statuses,
dimensions and verdicts exact; a linear plant's margins (``plant: kind: lti``) relative 1e-3 or absolute 2e-3
(bisections).
"""

from __future__ import annotations

import json
import math
import sys
import tempfile
from pathlib import Path
from typing import Any

from .objectives import scalar_figures

__all__ = ["run_config", "compare", "write_baselines", "CERTIFIED_REL", "MONTE_CARLO_REL"]

CERTIFIED_REL = 1e-3
MONTE_CARLO_REL = 1e-2
MARGIN_ABS = 2e-3  # a linear plant's margins come from bisections to 1e-3 (margin.tolerance): two steps' worth


def run_config(config_path: Path, outdir: Path) -> dict[str, Any]:
    """``robustsynth run`` without figures; returns the summary (also for infeasible configs)."""
    from .config import is_lti, load_config
    from .errors import RobustSynthError
    from .pipeline import run

    cfg = load_config(config_path)
    if is_lti(cfg) and cfg.controller is None:  # a linear plant without a gain: synthesize and verify one
        from .artifacts.files import atomic_write, json_bytes

        try:
            res = run(cfg, outdir, plots=False, config_path=config_path)  # the same run as the robot's
        except RobustSynthError as exc:
            summary = {"name": cfg.name, "status": "lti-not-certified", "exit_code": exc.exit_code}
        else:
            gd, ver = res.synthesis.gains, res.verification.result
            c = gd["certified"]
            summary = {"name": cfg.name, "status": "lti-certified", "objective": gd["objective"],
                       "verification_passed": ver.passed,
                       "failed_checks": ver.failed_checks,
                       "certified": {"decay_rate": c["decay"], "hinf_gain": c.get("hinf_gain"),
                                     "ultimate_bound": {o["name"]: o["bound"] for o in c.get("outputs") or ()
                                                        if o.get("bound") is not None}},
                       # the synthesized gain's delay margin (synthesize reports it), compared as the margins are
                       "margins": {"delay_max": {f: gd["delay_margin"][f] for f in ("configured", "certified", "exhibited")}}}
        atomic_write(outdir / "summary.json", json_bytes(summary))
        return summary
    if is_lti(cfg):  # a linear plant with a gain: its margins (certified and exhibited) are the summary
        from .artifacts.files import atomic_write, json_bytes
        from .pipeline import margin_stage

        rep = margin_stage(cfg, outdir, config_path=config_path).report
        summary = {"name": cfg.name, "status": "lti-margins",
                   "margins": {m.name: {"configured": m.configured, "certified": m.certified,
                                        "exhibited": m.exhibited} for m in rep.margins}}
        atomic_write(outdir / "summary.json", json_bytes(summary))
        return summary
    try:
        run(cfg, outdir, plots=False, compare=False, diagnose=False)  # comparison and diagnosis are for reading
    except RobustSynthError:
        pass  # run() recorded the status in summary.json
    return json.loads((outdir / "summary.json").read_text())


def _close(a: Any, b: Any, rel: float) -> bool:
    if a is None or b is None:
        return a is b
    return math.isclose(float(a), float(b), rel_tol=rel, abs_tol=0.0)


def _no_weaker(a: Any, b: Any, rel: float) -> bool:
    """Whether the claim ``b`` (a certified figure, the smaller the stronger) is no weaker than ``a`` by more than ``rel``."""
    if a is None or b is None:
        return a is b
    return float(b) <= float(a) or math.isclose(float(a), float(b), rel_tol=rel, abs_tol=0.0)


def compare(expected: dict[str, Any], got: dict[str, Any]) -> list[str]:
    """Differences between two summaries under the named tolerances (empty when they agree)."""
    diffs: list[str] = []
    em_, gm_ = expected.get("margins") or {}, got.get("margins") or {}  # a linear plant's margins
    for name in sorted(set(em_) | set(gm_)):
        for f in ("configured", "certified", "exhibited"):
            a, b = (em_.get(name) or {}).get(f), (gm_.get(name) or {}).get(f)
            same = a is b if a is None or b is None else math.isclose(float(a), float(b), rel_tol=CERTIFIED_REL,
                                                                        abs_tol=MARGIN_ABS)
            if not same:
                diffs.append(f"margins.{name}.{f}: expected {a}, got {b} (rel {CERTIFIED_REL:g}, abs {MARGIN_ABS:g})")
    for key in ("status", "objective", "dimensions", "verification_passed", "failed_checks"):
        if expected.get(key) != got.get(key):
            diffs.append(f"{key}: expected {expected.get(key)!r}, got {got.get(key)!r}")
    ec, gc = expected.get("certified") or {}, got.get("certified") or {}
    for key in ("robust_stability",):
        if ec.get(key) != gc.get(key):
            diffs.append(f"certified.{key}: expected {ec.get(key)!r}, got {gc.get(key)!r}")
    for key in scalar_figures():
        if not _no_weaker(ec.get(key), gc.get(key), CERTIFIED_REL):
            diffs.append(f"certified.{key}: expected {ec.get(key)} or less, got {gc.get(key)} (rel {CERTIFIED_REL:g})")
    eu, gu = ec.get("ultimate_bound") or {}, gc.get("ultimate_bound") or {}
    for key in sorted(set(eu) | set(gu)):
        if not _no_weaker(eu.get(key), gu.get(key), CERTIFIED_REL):
            diffs.append(f"certified.ultimate_bound.{key}: expected {eu.get(key)} or less, got {gu.get(key)} "
                         f"(rel {CERTIFIED_REL:g})")
    em = (expected.get("monte_carlo") or {}).get("max", {})
    gm = (got.get("monte_carlo") or {}).get("max", {})
    for key in sorted(set(em) | set(gm)):
        if not _close(em.get(key), gm.get(key), MONTE_CARLO_REL):
            diffs.append(f"monte_carlo.max.{key}: expected {em.get(key)}, got {gm.get(key)} (rel {MONTE_CARLO_REL:g})")
    return diffs


def _configs(configs_dir: Path, names: list[str] | None = None) -> list[Path]:
    paths = sorted(configs_dir.glob("*.yaml"))
    if names:
        unknown = sorted(set(names) - {p.stem for p in paths})
        if unknown:
            raise SystemExit(f"no config {', '.join(unknown)} in {configs_dir}")
        paths = [p for p in paths if p.stem in names]
    return paths


def write_baselines(configs_dir: Path, results_dir: Path, names: list[str] | None = None) -> None:
    """Regenerate the baselines of every config (or of those ``names``, e.g. ``default``)."""
    from .artifacts.files import atomic_write

    for cfg_path in _configs(configs_dir, names):
        with tempfile.TemporaryDirectory() as tmp:
            summary = run_config(cfg_path, Path(tmp))
            dest = results_dir / summary["name"]
            dest.mkdir(parents=True, exist_ok=True)
            atomic_write(dest / "summary.json", (Path(tmp) / "summary.json").read_bytes())
            if (Path(tmp) / "gains.json").exists():
                atomic_write(dest / "gains.json", (Path(tmp) / "gains.json").read_bytes())
            elif (dest / "gains.json").exists():
                (dest / "gains.json").unlink()
            print(f"{cfg_path.name}: {summary['status']}"
                  + (f", verification {'passed' if summary.get('verification_passed') else 'FAILED'}"
                     if "verification_passed" in summary else ""))


def check_all(configs_dir: Path, results_dir: Path) -> int:
    bad = 0
    for cfg_path in _configs(configs_dir):
        with tempfile.TemporaryDirectory() as tmp:
            got = run_config(cfg_path, Path(tmp))
        base = results_dir / got["name"] / "summary.json"
        if not base.exists():
            print(f"{cfg_path.name}: no baseline {base} (run make baselines)")
            bad += 1
            continue
        diffs = compare(json.loads(base.read_text()), got)
        print(f"{cfg_path.name}: {'ok' if not diffs else 'DIFFERS'}")
        for d in diffs:
            print(f"  {d}")
        bad += bool(diffs)
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m robustsynth.regression", description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="regenerate results/baselines/<name>/summary.json and gains.json")
    ap.add_argument("--configs", type=Path, default=Path("configs"))
    ap.add_argument("--results", type=Path, default=Path("results") / "baselines")
    ap.add_argument("names", nargs="*", help="with --write: only these configs (file names without .yaml)")
    a = ap.parse_args(argv)
    if a.names and not a.write:
        ap.error("config names go with --write")
    if a.write:
        write_baselines(a.configs, a.results, a.names or None)
        return 0
    return check_all(a.configs, a.results)


if __name__ == "__main__":
    sys.exit(main())
